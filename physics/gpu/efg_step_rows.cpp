// EfgStep's copy of the model on the GPU: the element rows (neighbours, shape values and
// gradients, volumes, rest gradients), each node's incidences and the surface's embedding rows,
// in fixed-stride layouts with headroom; after a cut only the batches of rows that differ from
// the host's shadow copy go up (efg_step_impl.hpp).
#include "physics/gpu/efg_step_impl.hpp"

#include <algorithm>
#include <cmath>

namespace incise::physics::gpu {

void EfgStep::Impl::allocate_rows() {
  const long long slots = static_cast<long long>(elements) * stride_capacity;
  allocate_ints(neighbours, slots);
  allocate_reals(gradients, 3 * slots);
  allocate_reals(values, slots);
  allocate_ints(lengths, elements);
  allocate_reals(volumes, elements);
  allocate_reals(rest_gradients, 9LL * elements);
}

void EfgStep::Impl::upload_element_rows(const CorotationalEfg& model, int first, int last) {
  const int stride = model.row_stride();
  const int rows = last - first;
  const auto& rest_x = model.rest_positions();
  ints.assign(static_cast<size_t>(rows) * stride_capacity, 0);
  reals.assign(static_cast<size_t>(rows) * stride_capacity * 3, 0.0);
  std::vector<double> phi(static_cast<size_t>(rows) * stride_capacity, 0.0);
  std::vector<double> g0(9 * static_cast<size_t>(rows), 0.0);
  std::vector<double> volume(static_cast<size_t>(rows));
  std::vector<int> length(static_cast<size_t>(rows));
  for (int e = first; e < last; ++e) {
    const size_t row = static_cast<size_t>(e - first);
    const size_t base = static_cast<size_t>(e) * stride;
    const int count = model.row_lengths()[e];
    length[row] = count;
    volume[row] = model.element_volumes()[e];
    const int n0 = model.neighbours()[base];
    Mat3 rest_gradient = Mat3::Zero();
    for (int k = 0; k < count; ++k) {
      const int n = model.neighbours()[base + k];
      const Vec3& g = model.shape_gradients()[base + k];
      ints[row * stride_capacity + k] = n;
      phi[row * stride_capacity + k] = model.shape_values()[base + k];
      for (int c = 0; c < 3; ++c) reals[3 * (row * stride_capacity + k) + c] = g[c];
      rest_gradient += (rest_x.segment<3>(3 * n) - rest_x.segment<3>(3 * n0)) * g.transpose();
    }
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) g0[9 * row + 3 * i + j] = rest_gradient(i, j);
  }
  const long long slot = static_cast<long long>(first) * stride_capacity;
  long long bytes = upload_ints(neighbours, slot, ints.data(), static_cast<long long>(ints.size()));
  bytes += upload_reals(gradients, 3 * slot, reals.data(), static_cast<long long>(reals.size()));
  bytes += upload_reals(values, slot, phi.data(), static_cast<long long>(phi.size()));
  bytes += upload_ints(lengths, first, length.data(), rows);
  bytes += upload_reals(volumes, first, volume.data(), rows);
  bytes += upload_reals(rest_gradients, 9LL * first, g0.data(), 9LL * rows);
  counters->row_bytes += bytes;
  counters->row_batches++;
  counters->element_batches++;
}

void EfgStep::Impl::sync_rows(const CorotationalEfg& model) {
  const int stride = model.row_stride();
  const int batch = settings->batch_rows;
  bool everything = false;
  if (stride > stride_capacity) {
    stride_capacity = stride + settings->row_headroom;
    allocate_rows();
    counters->reallocations++;
    everything = true;
  }
  if (shadow_stride < 0) everything = true;
  const auto& row_lengths = model.row_lengths();
  std::vector<std::uint8_t> dirty(static_cast<size_t>(elements), everything ? 1 : 0);
  bool any = everything;
  if (!everything) {
    // Row by row, each in its own layout: a restride of the model (a longer row somewhere)
    // that still fits the GPU's capacity moves no other row there.
    for (int e = 0; e < elements; ++e) {
      const size_t base = static_cast<size_t>(e) * stride;
      const size_t shadow_base = static_cast<size_t>(e) * shadow_stride;
      const int count = row_lengths[e];
      bool same = shadow_lengths[e] == count && shadow_volumes[e] == model.element_volumes()[e] &&
                  std::equal(model.neighbours().begin() + base, model.neighbours().begin() + base + count,
                             shadow_neighbours.begin() + shadow_base) &&
                  std::equal(model.shape_values().begin() + base, model.shape_values().begin() + base + count,
                             shadow_values.begin() + shadow_base);
      for (int k = 0; same && k < count; ++k)
        for (int c = 0; c < 3; ++c)
          same = same && shadow_gradients[3 * (shadow_base + k) + c] == model.shape_gradients()[base + k][c];
      if (!same) dirty[e] = 1, any = true;
    }
  }
  if (!any && incidence_uploaded) return;
  for (int first = 0; first < elements; first += batch) {
    const int last = std::min(elements, first + batch);
    if (std::find(dirty.begin() + first, dirty.begin() + last, 1) != dirty.begin() + last)
      upload_element_rows(model, first, last);
  }
  shadow_stride = stride;
  shadow_lengths = row_lengths;
  shadow_volumes = model.element_volumes();
  shadow_neighbours = model.neighbours();
  shadow_values = model.shape_values();
  shadow_gradients.resize(model.shape_gradients().size() * 3);
  for (size_t s = 0; s < model.shape_gradients().size(); ++s)
    for (int c = 0; c < 3; ++c) shadow_gradients[3 * s + c] = model.shape_gradients()[s][c];
  sync_incidence(model, everything);
}

void EfgStep::Impl::sync_incidence(const CorotationalEfg& model, bool everything) {
  const int stride = model.row_stride();
  std::vector<int> counts(static_cast<size_t>(nodes), 0);
  for (int e = 0; e < elements; ++e)
    for (int k = 0; k < model.row_lengths()[e]; ++k) ++counts[model.neighbours()[static_cast<size_t>(e) * stride + k]];
  const int longest = counts.empty() ? 0 : *std::max_element(counts.begin(), counts.end());
  if (longest > incidence_capacity) {
    incidence_capacity = longest + std::max(incidence_headroom, longest / 4);
    allocate_ints(incidence, static_cast<long long>(nodes) * incidence_capacity);
    allocate_ints(incidence_lengths, nodes);
    if (incidence_uploaded) counters->reallocations++;
    everything = true;
  }
  std::vector<int> table(static_cast<size_t>(nodes) * incidence_capacity, 0);
  std::fill(counts.begin(), counts.end(), 0);
  for (int e = 0; e < elements; ++e) {
    for (int k = 0; k < model.row_lengths()[e]; ++k) {
      const int n = model.neighbours()[static_cast<size_t>(e) * stride + k];
      table[static_cast<size_t>(n) * incidence_capacity + counts[n]++] = e * stride_capacity + k;
    }
  }
  if (!incidence_uploaded || host_incidence.size() != table.size()) everything = true;
  const int batch = settings->batch_rows;
  for (int first = 0; first < nodes; first += batch) {
    const int last = std::min(nodes, first + batch);
    const size_t from = static_cast<size_t>(first) * incidence_capacity;
    const size_t to = static_cast<size_t>(last) * incidence_capacity;
    const bool changed = everything ||
                         !std::equal(counts.begin() + first, counts.begin() + last, host_incidence_lengths.begin() + first) ||
                         !std::equal(table.begin() + from, table.begin() + to, host_incidence.begin() + from);
    if (!changed) continue;
    long long bytes = upload_ints(incidence, static_cast<long long>(from), table.data() + from, static_cast<long long>(to - from));
    bytes += upload_ints(incidence_lengths, first, counts.data() + first, last - first);
    counters->row_bytes += bytes;
    counters->row_batches++;
    counters->incidence_batches++;
  }
  host_incidence.swap(table);
  host_incidence_lengths.swap(counts);
  incidence_uploaded = true;
}

void EfgStep::Impl::sync_surface(const SurfaceEmbedding& embedding) {
  const int vertices = embedding.vertex_count();
  const int stride = embedding.stride;
  bool everything = surface_shadow_stride < 0;
  if (vertices > surface_capacity || stride > surface_stride_capacity) {
    surface_capacity = std::max(surface_capacity,
                                static_cast<int>(std::ceil(vertices * settings->surface_headroom)));
    surface_capacity = std::max(surface_capacity, vertices);
    surface_stride_capacity = std::max(surface_stride_capacity, stride + settings->row_headroom);
    const long long slots = static_cast<long long>(surface_capacity) * surface_stride_capacity;
    allocate_ints(surface_particles, slots);
    allocate_reals(surface_weights, slots);
    allocate_ints(surface_lengths, surface_capacity);
    allocate_reals(surface_out, 3LL * surface_capacity);
    if (surface_shadow_stride >= 0) counters->reallocations++;
    everything = true;
  }
  const int batch = settings->batch_rows;
  for (int first = 0; first < vertices; first += batch) {
    const int last = std::min(vertices, first + batch);
    bool changed = everything || last > surface_vertices;
    for (int v = first; v < last && !changed; ++v) {
      const int count = embedding.row_lengths[v];
      const size_t row = static_cast<size_t>(v) * stride, shadow_row = static_cast<size_t>(v) * surface_shadow_stride;
      changed = surface_shadow_lengths[v] != count ||
                !std::equal(embedding.particles.begin() + row, embedding.particles.begin() + row + count,
                            surface_shadow_particles.begin() + shadow_row) ||
                !std::equal(embedding.weights.begin() + row, embedding.weights.begin() + row + count,
                            surface_shadow_weights.begin() + shadow_row);
    }
    if (!changed) continue;
    const int rows = last - first;
    ints.assign(static_cast<size_t>(rows) * surface_stride_capacity, 0);
    reals.assign(static_cast<size_t>(rows) * surface_stride_capacity, 0.0);
    for (int v = first; v < last; ++v) {
      for (int k = 0; k < embedding.row_lengths[v]; ++k) {
        ints[static_cast<size_t>(v - first) * surface_stride_capacity + k] = embedding.particles[static_cast<size_t>(v) * stride + k];
        reals[static_cast<size_t>(v - first) * surface_stride_capacity + k] = embedding.weights[static_cast<size_t>(v) * stride + k];
      }
    }
    const long long slot = static_cast<long long>(first) * surface_stride_capacity;
    long long bytes = upload_ints(surface_particles, slot, ints.data(), static_cast<long long>(ints.size()));
    bytes += upload_reals(surface_weights, slot, reals.data(), static_cast<long long>(reals.size()));
    bytes += upload_ints(surface_lengths, first, embedding.row_lengths.data() + first, rows);
    counters->row_bytes += bytes;
    counters->row_batches++;
    counters->surface_batches++;
  }
  surface_shadow_stride = stride;
  surface_shadow_lengths = embedding.row_lengths;
  surface_shadow_particles = embedding.particles;
  surface_shadow_weights = embedding.weights;
  surface_vertices = vertices;
}

}  // namespace incise::physics::gpu
