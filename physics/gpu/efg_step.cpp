#include "physics/gpu/efg_step.hpp"

#include "physics/fem/material.hpp"
#include "physics/gpu/efg_kernels.hpp"
#include "physics/gpu/gl.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <initializer_list>
#include <map>
#include <stdexcept>
#include <utility>

namespace incise::physics::gpu {

std::string precision_name(Precision precision) {
  return precision == Precision::single ? "single" : "double";
}

namespace {

using Index = Eigen::Index;
using Clock = std::chrono::steady_clock;

// Fixed binding points (efg_kernels.cpp).
enum Binding : GLuint {
  neighbours_binding = 0, gradients_binding, values_binding, lengths_binding, volumes_binding,
  rest_gradients_binding, rotations_binding, stresses_binding, incidence_binding,
  incidence_lengths_binding, rest_binding, masses_binding, free_binding, spring_index_binding,
  spring_force_binding, spring_stiffness_binding, parameters_binding, scalars_binding,
  partials_binding, a_binding, b_binding, c_binding, d_binding, e_binding, f_binding, orientations_binding,
  flags_binding
};

// Scalars: 0 p.Ap, 1 r.r, 2 and 3 r.z (old and new in turn), 4 b.b, 5 and 6 the guess's
// scale, 7 (tolerance |b|)^2 (efg_kernels.cpp's THRESHOLD_SLOT).
constexpr int curvature_slot = 0, residual_slot = 1, rz_slot = 2, rhs_slot = 4, guess_slot = 5, threshold_slot = 7;


// Incidence rows get this many slots (at least; a quarter of the longest row if more)
// beyond the longest at (re)allocation: re-selection after cuts adds particles beyond the
// cell, so interior particles gain incidences.
constexpr int incidence_headroom = 8;

struct Buffer {
  GLuint id = 0;
  long long bytes = 0;
};

void check_gl(const char* where) {
  const GLenum error = glGetError();
  if (error == GL_NO_ERROR) return;
  while (glGetError() != GL_NO_ERROR) {
  }
  char code[16];
  std::snprintf(code, sizeof code, "0x%04X", error);
  throw std::runtime_error(std::string("GPU backend: OpenGL error ") + code + " in " + where);
}

GLuint compile(Kernel kernel, bool double_precision) {
  const std::string source = kernel_source(kernel, double_precision);
  const char* text = source.c_str();
  const GLuint shader = glCreateShader(GL_COMPUTE_SHADER);
  glShaderSource(shader, 1, &text, nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  std::string log(4096, '\0');
  if (!ok) {
    GLsizei length = 0;
    glGetShaderInfoLog(shader, static_cast<GLsizei>(log.size()), &length, log.data());
    glDeleteShader(shader);
    throw ComputeUnavailable(std::string("GPU backend: kernel ") + kernel_name(kernel) +
                             " does not compile: " + log.substr(0, static_cast<size_t>(length)));
  }
  const GLuint program = glCreateProgram();
  glAttachShader(program, shader);
  glLinkProgram(program);
  glDeleteShader(shader);
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    GLsizei length = 0;
    glGetProgramInfoLog(program, static_cast<GLsizei>(log.size()), &length, log.data());
    glDeleteProgram(program);
    throw ComputeUnavailable(std::string("GPU backend: kernel ") + kernel_name(kernel) +
                             " does not link: " + log.substr(0, static_cast<size_t>(length)));
  }
  return program;
}

}  // namespace

struct EfgStep::Impl {
  bool double_precision = false;
  int real_bytes = 4;
  GpuCounters* counters = nullptr;
  const GpuSettings* settings = nullptr;

  struct Program {
    GLuint id = 0;
    GLint count = -1, stride = -1, incidence_stride = -1, mode = -1, slot0 = -1, slot1 = -1, cg_gate = -1, limit = -1;
  };
  std::array<Program, static_cast<size_t>(Kernel::count)> programs{};

  int elements = 0, nodes = 0;
  int stride_capacity = 0, incidence_capacity = 0;
  int surface_capacity = 0, surface_stride_capacity = 0;

  // Rows.
  Buffer neighbours, gradients, values, lengths, volumes, rest_gradients;
  Buffer incidence, incidence_lengths;
  Buffer surface_particles, surface_weights, surface_lengths, surface_out, points_out;
  // Per step.
  Buffer rotations, stresses, rest, masses, free, spring_index, spring_force, spring_stiffness;
  Buffer parameters, scalars, partials, orientations, flags;
  Buffer u, v, u_next, v_next, external, forces, stiffness_velocity, rhs, dv, r, z, p, product,
      inverse_diagonal;

  // What the GPU holds, in the model's layout (to find the changed rows).
  int shadow_stride = -1;
  std::vector<int> shadow_neighbours, shadow_lengths;
  std::vector<double> shadow_values, shadow_gradients, shadow_volumes;
  std::vector<int> host_incidence, host_incidence_lengths;  // in the GPU layout
  bool incidence_uploaded = false;
  std::vector<double> shadow_masses;
  std::vector<std::uint8_t> shadow_fixed;
  bool springs_uploaded = false;
  int spring_capacity = 0;
  int surface_shadow_stride = -1;
  std::vector<int> surface_shadow_particles, surface_shadow_lengths;
  std::vector<double> surface_shadow_weights;
  int surface_vertices = 0;

  // Staging for conversions.
  std::vector<unsigned char> staging;
  std::vector<double> reals;
  std::vector<int> ints;

  ~Impl() {
    print_profile();
    for (auto& program : programs)
      if (program.id) glDeleteProgram(program.id);
    for (Buffer* b : all_buffers())
      if (b->id) glDeleteBuffers(1, &b->id);
  }

  std::vector<Buffer*> all_buffers() {
    return {&neighbours, &gradients, &values, &lengths, &volumes, &rest_gradients, &incidence,
            &incidence_lengths, &surface_particles, &surface_weights, &surface_lengths,
            &surface_out, &points_out, &rotations, &stresses, &rest, &masses, &free,
            &spring_index, &spring_force, &spring_stiffness, &parameters, &scalars, &partials, &orientations, &flags,
            &u, &v, &u_next, &v_next, &external, &forces, &stiffness_velocity, &rhs, &dv, &r,
            &z, &p, &product, &inverse_diagonal};
  }

  void allocate(Buffer& buffer, long long bytes) {
    bytes = std::max<long long>(bytes, 16);
    if (!buffer.id) glCreateBuffers(1, &buffer.id);
    glNamedBufferData(buffer.id, bytes, nullptr, GL_DYNAMIC_DRAW);
    buffer.bytes = bytes;
    check_gl("allocating a buffer");
  }
  void allocate_reals(Buffer& buffer, long long count) { allocate(buffer, count * real_bytes); }
  void allocate_ints(Buffer& buffer, long long count) { allocate(buffer, count * 4); }

  // Uploads count reals from data at entry `first`; returns the bytes sent.
  long long upload_reals(Buffer& buffer, long long first, const double* data, long long count) {
    if (count <= 0) return 0;
    const long long bytes = count * real_bytes;
    const auto start = Clock::now();
    if (double_precision) {
      glNamedBufferSubData(buffer.id, first * 8, bytes, data);
    } else {
      staging.resize(static_cast<size_t>(bytes));
      float* out = reinterpret_cast<float*>(staging.data());
      for (long long i = 0; i < count; ++i) out[i] = static_cast<float>(data[i]);
      glNamedBufferSubData(buffer.id, first * 4, bytes, staging.data());
    }
    counters->ms_upload += std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    return bytes;
  }
  long long upload_ints(Buffer& buffer, long long first, const int* data, long long count) {
    if (count <= 0) return 0;
    const auto start = Clock::now();
    glNamedBufferSubData(buffer.id, first * 4, count * 4, data);
    counters->ms_upload += std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    return count * 4;
  }
  void download_reals(const Buffer& buffer, long long count, double* out) {
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    if (double_precision) {
      glGetNamedBufferSubData(buffer.id, 0, count * 8, out);
      return;
    }
    staging.resize(static_cast<size_t>(count * 4));
    glGetNamedBufferSubData(buffer.id, 0, count * 4, staging.data());
    const float* in = reinterpret_cast<const float*>(staging.data());
    for (long long i = 0; i < count; ++i) out[i] = in[i];
  }
  std::array<double, 2> read_scalars(int first) {
    std::array<double, 2> values{};
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    if (double_precision) {
      glGetNamedBufferSubData(scalars.id, first * 8, 16, values.data());
    } else {
      float v[2];
      glGetNamedBufferSubData(scalars.id, first * 4, 8, v);
      values = {v[0], v[1]};
    }
    return values;
  }

  void build_programs() {
    for (int k = 0; k < static_cast<int>(Kernel::count); ++k) {
      Program& program = programs[static_cast<size_t>(k)];
      program.id = compile(static_cast<Kernel>(k), double_precision);
      program.count = glGetUniformLocation(program.id, "count");
      program.stride = glGetUniformLocation(program.id, "stride");
      program.incidence_stride = glGetUniformLocation(program.id, "incidence_stride");
      program.mode = glGetUniformLocation(program.id, "mode");
      program.slot0 = glGetUniformLocation(program.id, "slot0");
      program.slot1 = glGetUniformLocation(program.id, "slot1");
      program.cg_gate = glGetUniformLocation(program.id, "cg_gate");
      program.limit = glGetUniformLocation(program.id, "limit");
    }
  }

  void bind(GLuint binding, const Buffer& buffer) { glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding, buffer.id); }

  void bind_fixed() {
    bind(neighbours_binding, neighbours);
    bind(gradients_binding, gradients);
    bind(values_binding, values);
    bind(lengths_binding, lengths);
    bind(volumes_binding, volumes);
    bind(rest_gradients_binding, rest_gradients);
    bind(rotations_binding, rotations);
    bind(stresses_binding, stresses);
    bind(incidence_binding, incidence);
    bind(incidence_lengths_binding, incidence_lengths);
    bind(rest_binding, rest);
    bind(masses_binding, masses);
    bind(free_binding, free);
    bind(spring_index_binding, spring_index);
    bind(spring_force_binding, spring_force);
    bind(spring_stiffness_binding, spring_stiffness);
    bind(parameters_binding, parameters);
    bind(scalars_binding, scalars);
    bind(partials_binding, partials);
    bind(orientations_binding, orientations);
    bind(flags_binding, flags);
  }

  void run(Kernel kernel, int count, std::initializer_list<std::pair<GLuint, const Buffer*>> vectors,
           int mode = 0, int slot0 = 0, int slot1 = 0, int stride = -1) {
    const Program& program = programs[static_cast<size_t>(kernel)];
    glUseProgram(program.id);
    if (program.count >= 0) glUniform1i(program.count, count);
    if (program.stride >= 0) glUniform1i(program.stride, stride >= 0 ? stride : stride_capacity);
    if (program.incidence_stride >= 0) glUniform1i(program.incidence_stride, incidence_capacity);
    if (program.mode >= 0) glUniform1i(program.mode, mode);
    if (program.slot0 >= 0) glUniform1i(program.slot0, slot0);
    if (program.slot1 >= 0) glUniform1i(program.slot1, slot1);
    if (program.cg_gate >= 0) glUniform1i(program.cg_gate, cg_gate);
    if (program.limit >= 0) glUniform1i(program.limit, cg_limit);
    for (const auto& [binding, buffer] : vectors) bind(binding, *buffer);
    GLuint groups = 0;
    if (kernel == Kernel::dot_partial) groups = kReduceGroups;
    else if (kernel == Kernel::dot_final) groups = 1;
    else groups = static_cast<GLuint>((count + kGroupSize - 1) / kGroupSize);
    const auto start = profile ? Clock::now() : Clock::time_point{};
    if (groups > 0) glDispatchCompute(groups, 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    if (profile) {
      glFinish();
      kernel_ms[static_cast<size_t>(kernel)] += std::chrono::duration<double, std::milli>(Clock::now() - start).count();
      kernel_runs[static_cast<size_t>(kernel)]++;
    }
  }

  // Inside CG's loop: the loop's kernels stop once flags[1] is set (efg_kernels.cpp, CG_DONE).
  int cg_gate = 0;
  int cg_limit = 0;

  // INCISE_GPU_PROFILE=1: glFinish after every dispatch and the time per kernel on stderr
  // when the step is destroyed (a measurement aid; it serialises the pipeline).
  bool profile = false;
  std::array<double, static_cast<size_t>(Kernel::count)> kernel_ms{};
  std::array<long, static_cast<size_t>(Kernel::count)> kernel_runs{};
  void print_profile() const {
    if (!profile) return;
    for (int k = 0; k < static_cast<int>(Kernel::count); ++k)
      if (kernel_runs[static_cast<size_t>(k)] > 0)
        std::fprintf(stderr, "gpu kernel %-20s %8ld runs %10.2f ms %8.4f ms/run\n", kernel_name(static_cast<Kernel>(k)),
                     kernel_runs[static_cast<size_t>(k)], kernel_ms[static_cast<size_t>(k)],
                     kernel_ms[static_cast<size_t>(k)] / kernel_runs[static_cast<size_t>(k)]);
  }

  // Two dot products a.b -> scalars[slot0] and (c.d -> scalars[slot1] when c is given).
  void dot(int count, const Buffer& a, const Buffer& b, int slot0, const Buffer* c = nullptr,
           const Buffer* d = nullptr, int slot1 = 0) {
    const int mode = c ? 2 : 1;
    if (c) {
      run(Kernel::dot_partial, count, {{a_binding, &a}, {b_binding, &b}, {c_binding, c}, {d_binding, d}}, mode);
    } else {
      run(Kernel::dot_partial, count, {{a_binding, &a}, {b_binding, &b}}, mode);
    }
    run(Kernel::dot_final, count, {}, mode, slot0, slot1);
  }

  // out = A p (mode 2), K p (mode 1) for p in `in`.
  void product_of(const Buffer& in, const Buffer& out, int mode) {
    run(Kernel::element_stress, elements, {{a_binding, &in}}, 1);
    run(Kernel::node_gather, nodes, {{a_binding, &in}, {c_binding, &out}}, mode);
  }

  long long element_row_bytes() const {
    return static_cast<long long>(stride_capacity) * (4 + 4LL * real_bytes) + 4 + 10LL * real_bytes;
  }
  long long incidence_row_bytes() const { return static_cast<long long>(incidence_capacity) * 4 + 4; }
  long long surface_row_bytes() const {
    return static_cast<long long>(surface_stride_capacity) * (4 + real_bytes) + 4;
  }

  void allocate_rows() {
    const long long slots = static_cast<long long>(elements) * stride_capacity;
    allocate_ints(neighbours, slots);
    allocate_reals(gradients, 3 * slots);
    allocate_reals(values, slots);
    allocate_ints(lengths, elements);
    allocate_reals(volumes, elements);
    allocate_reals(rest_gradients, 9LL * elements);
  }

  // Uploads rows [first, last) of the element arrays in the GPU layout.
  void upload_element_rows(const CorotationalEfg& model, int first, int last) {
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

  // Element rows and incidences: the batches that differ from the GPU's copy go up.
  void sync_rows(const CorotationalEfg& model) {
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

  // Each node's (element, slot) pairs in element order, as slots of the GPU layout.
  void sync_incidence(const CorotationalEfg& model, bool everything) {
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

  void sync_surface(const SurfaceEmbedding& embedding) {
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

  long long state_upload(Buffer& buffer, const double* data, long long count) {
    const long long bytes = upload_reals(buffer, 0, data, count);
    counters->state_bytes += bytes;
    return bytes;
  }
};

EfgStep::EfgStep(const CorotationalEfg& model, const GpuSettings& settings) : settings_(settings) {
  if (settings.batch_rows < 1)
    throw std::invalid_argument("gpu batch_rows must be at least 1, got " + std::to_string(settings.batch_rows));
  if (settings.cg_iterations_per_check < 1)
    throw std::invalid_argument("gpu cg_iterations_per_check must be at least 1, got " +
                                std::to_string(settings.cg_iterations_per_check));
  if (settings.row_headroom < 0)
    throw std::invalid_argument("gpu row_headroom must not be negative, got " + std::to_string(settings.row_headroom));
  if (!(settings.surface_headroom >= 1) || !std::isfinite(settings.surface_headroom))
    throw std::invalid_argument("gpu surface_headroom must be at least 1, got " + std::to_string(settings.surface_headroom));
  context_ = ComputeContext::create(settings.required);
  CurrentScope current(*context_);
  const bool want_double = settings.precision == Precision::double_precision;
  if (want_double && !context_->double_precision()) {
    throw ComputeUnavailable("GPU backend: double precision needs GL_ARB_gpu_shader_fp64, which OpenGL " +
                             context_->version() + " on '" + context_->renderer() + "' does not offer");
  }
  GLint bindings = 0, blocks = 0;
  glGetIntegerv(GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS, &bindings);
  glGetIntegerv(GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS, &blocks);
  if (bindings < 27 || blocks < 13) {
    throw ComputeUnavailable("GPU backend: the kernels need 27 storage buffer bindings and 13 blocks per compute "
                             "shader; OpenGL " + context_->version() + " on '" + context_->renderer() + "' has " +
                             std::to_string(bindings) + " and " + std::to_string(blocks));
  }
  impl_ = std::make_unique<Impl>();
  Impl& s = *impl_;
  s.double_precision = want_double;
  const char* profile = std::getenv("INCISE_GPU_PROFILE");
  s.profile = profile && std::strcmp(profile, "1") == 0;
  s.real_bytes = want_double ? 8 : 4;
  s.counters = &counters_;
  s.settings = &settings_;
  s.build_programs();
  s.elements = model.element_count();
  s.nodes = model.node_count();
  s.stride_capacity = model.row_stride() + settings.row_headroom;
  s.allocate_rows();
  const long long dofs = 3LL * s.nodes;
  s.allocate_reals(s.rotations, 9LL * s.elements);
  s.allocate_reals(s.stresses, 9LL * s.elements);
  s.allocate_reals(s.rest, dofs);
  s.allocate_reals(s.masses, s.nodes);
  s.allocate_reals(s.free, s.nodes);
  s.allocate_ints(s.spring_index, s.nodes);
  s.allocate_reals(s.spring_force, 3);
  s.allocate_reals(s.spring_stiffness, 9);
  s.allocate_reals(s.parameters, 8);
  s.allocate_reals(s.scalars, 8);
  s.allocate_reals(s.partials, 2 * kReduceGroups * kGroupSize);
  for (Buffer* b : {&s.u, &s.v, &s.u_next, &s.v_next, &s.external, &s.forces, &s.stiffness_velocity,
                    &s.rhs, &s.dv, &s.r, &s.z, &s.p, &s.product, &s.inverse_diagonal})
    s.allocate_reals(*b, dofs);
  s.allocate_reals(s.points_out, 3LL * s.elements);
  s.allocate_reals(s.orientations, 4LL * s.elements);
  s.allocate_ints(s.flags, 4);
  {
    std::vector<double> identity(4 * static_cast<size_t>(s.elements), 0.0);
    for (int e = 0; e < s.elements; ++e) identity[4 * static_cast<size_t>(e) + 3] = 1.0;
    s.state_upload(s.orientations, identity.data(), static_cast<long long>(identity.size()));
  }
  const std::vector<int> no_springs(static_cast<size_t>(s.nodes), -1);
  counters_.state_bytes += s.upload_ints(s.spring_index, 0, no_springs.data(), s.nodes);
  const std::vector<double> zeros(static_cast<size_t>(dofs), 0.0);
  s.state_upload(s.u, zeros.data(), dofs);
  counters_.row_bytes += s.upload_reals(s.rest, 0, model.rest_positions().data(), dofs);
  s.sync_rows(model);
  check_gl("uploading the model");
}

EfgStep::~EfgStep() {
  if (!context_) return;
  try {
    CurrentScope current(*context_);
    impl_.reset();
  } catch (...) {
    // The objects go with the context.
  }
}

bool EfgStep::rotations_on_gpu(const CorotationalEfg& model) const {
  return settings_.rotations_on_gpu && model.settings().rotation == EfgRotation::deformation_gradient;
}

int EfgStep::row_capacity() const { return impl_->stride_capacity; }
int EfgStep::incidence_capacity() const { return impl_->incidence_capacity; }
int EfgStep::surface_row_capacity() const { return impl_->surface_stride_capacity; }
int EfgStep::surface_capacity() const { return impl_->surface_capacity; }

long long EfgStep::full_row_bytes() const {
  const Impl& s = *impl_;
  return s.elements * s.element_row_bytes() + s.nodes * s.incidence_row_bytes() +
         static_cast<long long>(s.surface_vertices) * s.surface_row_bytes();
}

void EfgStep::check_arguments(const CorotationalEfg& model, const State& state, const std::vector<uint8_t>& fixed_nodes,
                              const Vector& external_forces, std::span<const NodalSpring> springs,
                              const ImplicitEulerSettings& settings) const {
  const Impl& s = *impl_;
  const int nodes = model.node_count();
  const Index size = 3 * static_cast<Index>(nodes);
  if (nodes != s.nodes || model.element_count() != s.elements)
    throw std::invalid_argument("EfgStep::step: the model has " + std::to_string(nodes) + " particles and " +
                                std::to_string(model.element_count()) + " elements, the GPU copy " +
                                std::to_string(s.nodes) + " and " + std::to_string(s.elements));
  if (state.positions.size() != size || state.velocities.size() != size || external_forces.size() != size)
    throw std::invalid_argument("EfgStep::step: state or external forces do not have " + std::to_string(size) + " entries");
  if (!fixed_nodes.empty() && static_cast<int>(fixed_nodes.size()) != nodes)
    throw std::invalid_argument("EfgStep::step: fixed_nodes has " + std::to_string(fixed_nodes.size()) +
                                " entries, expected " + std::to_string(nodes));
  for (const NodalSpring& spring : springs)
    if (spring.node < 0 || spring.node >= nodes)
      throw std::invalid_argument("EfgStep::step: spring node " + std::to_string(spring.node) + " outside [0, " +
                                  std::to_string(nodes) + ")");
  if (!(settings.dt > 0.0)) throw std::invalid_argument("EfgStep::step: dt must be positive");
}

StepReport EfgStep::step(CorotationalEfg& model, State& state, const std::vector<uint8_t>& fixed_nodes,
                         const Vector& external_forces, std::span<const NodalSpring> springs,
                         const ImplicitEulerSettings& settings, Vector* velocity_change_guess) {
  check_arguments(model, state, fixed_nodes, external_forces, springs, settings);
  CurrentScope current(*context_);
  StepReport report;
  std::vector<std::uint8_t> fixed = fixed_nodes;
  fixed.resize(static_cast<size_t>(model.node_count()), 0);
  upload_step(model, state, fixed, external_forces, springs, settings, velocity_change_guess);
  if (!solve_velocity_change(settings, report.cg) || !integrate(model, state, fixed, velocity_change_guess)) {
    report.nonfinite = true;
    return report;
  }
  report.elastic_energy = model.elastic_energy(state.positions);
  report.kinetic_energy = kinetic_energy(model.lumped_masses(), state.velocities);
  return report;
}

void EfgStep::upload_cpu_rotations(CorotationalEfg& model, const State& state) {
  Impl& s = *impl_;
  model.update_rotations(state.positions);
  const auto& rotations = model.rotations();
  std::vector<double> offsets(9 * static_cast<size_t>(s.elements));
  for (int e = 0; e < s.elements; ++e)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) offsets[9 * static_cast<size_t>(e) + 3 * i + j] = rotations[e](i, j) - (i == j ? 1.0 : 0.0);
  counters_.rotation_bytes += s.state_upload(s.rotations, offsets.data(), static_cast<long long>(offsets.size()));
}

// Springs summed per node (several contact springs may share a particle), in order.
void EfgStep::upload_springs(std::span<const NodalSpring> springs) {
  Impl& s = *impl_;
  if (springs.empty() && !s.springs_uploaded) return;
  std::map<int, int> slot_of;
  for (const NodalSpring& spring : springs) slot_of.emplace(spring.node, static_cast<int>(slot_of.size()));
  const int count = static_cast<int>(slot_of.size());
  std::vector<double> force(3 * static_cast<size_t>(std::max(count, 1)), 0.0), stiffness(9 * static_cast<size_t>(std::max(count, 1)), 0.0);
  for (const NodalSpring& spring : springs) {
    const int slot = slot_of[spring.node];
    for (int i = 0; i < 3; ++i) {
      force[3 * slot + i] += spring.force[i];
      for (int j = 0; j < 3; ++j) stiffness[9 * slot + 3 * i + j] += spring.stiffness(i, j);
    }
  }
  std::vector<int> index(static_cast<size_t>(s.nodes), -1);
  for (const auto& [node, slot] : slot_of) index[node] = slot;
  if (count > s.spring_capacity) {
    s.spring_capacity = 2 * count;
    s.allocate_reals(s.spring_force, 3LL * s.spring_capacity);
    s.allocate_reals(s.spring_stiffness, 9LL * s.spring_capacity);
    s.bind(spring_force_binding, s.spring_force);
    s.bind(spring_stiffness_binding, s.spring_stiffness);
  }
  counters_.state_bytes += s.upload_ints(s.spring_index, 0, index.data(), s.nodes);
  s.state_upload(s.spring_force, force.data(), 3LL * count);
  s.state_upload(s.spring_stiffness, stiffness.data(), 9LL * count);
  s.springs_uploaded = !springs.empty();
}

void EfgStep::upload_rotations(CorotationalEfg& model, const State& state) {
  Impl& s = *impl_;
  const int clear = 0;
  counters_.state_bytes += s.upload_ints(s.flags, 0, &clear, 1);
  s.run(Kernel::element_rotation, s.elements, {{a_binding, &s.u}});
  int unsettled = 0;
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  glGetNamedBufferSubData(s.flags.id, 0, 4, &unsettled);
  if (unsettled != 0) {
    // An element's Newton steps did not settle (a strongly inverted or degenerate one):
    // this step takes the CPU's rotations, which fall back to the SVD polar.
    counters_.rotation_fallbacks++;
    upload_cpu_rotations(model, state);
  }
}

void EfgStep::upload_step(CorotationalEfg& model, const State& state, const std::vector<uint8_t>& fixed,
                          const Vector& external_forces, std::span<const NodalSpring> springs,
                          const ImplicitEulerSettings& settings, const Vector* velocity_change_guess) {
  Impl& s = *impl_;
  const int nodes = model.node_count();
  const Index size = 3 * static_cast<Index>(nodes);
  const double dt = settings.dt, alpha = settings.rayleigh_mass, beta = settings.rayleigh_stiffness;
  // Topology (only the changed batches), then this step's state.
  s.sync_rows(model);
  s.bind_fixed();
  const bool gpu_rotations = rotations_on_gpu(model);
  if (!gpu_rotations) upload_cpu_rotations(model, state);
  const double parameters[8] = {lame_lambda(model.material()), lame_mu(model.material()), dt, alpha, beta,
                                1.0 + dt * alpha, dt * beta + dt * dt, 0};
  s.state_upload(s.parameters, parameters, 8);
  if (s.shadow_masses.size() != static_cast<size_t>(nodes) ||
      !std::equal(s.shadow_masses.begin(), s.shadow_masses.end(), model.lumped_masses().data())) {
    s.state_upload(s.masses, model.lumped_masses().data(), nodes);
    s.shadow_masses.assign(model.lumped_masses().data(), model.lumped_masses().data() + nodes);
  }
  if (fixed != s.shadow_fixed) {
    std::vector<double> free(static_cast<size_t>(nodes));
    for (int n = 0; n < nodes; ++n) free[n] = fixed[n] ? 0.0 : 1.0;
    s.state_upload(s.free, free.data(), nodes);
    s.shadow_fixed = fixed;
  }
  upload_springs(springs);
  Vector displacement = state.positions - model.rest_positions();
  s.state_upload(s.u, displacement.data(), size);
  s.state_upload(s.v, state.velocities.data(), size);
  s.state_upload(s.external, external_forces.data(), size);
  Vector guess = Vector::Zero(size);
  if (velocity_change_guess && velocity_change_guess->size() == size && velocity_change_guess->allFinite())
    guess = *velocity_change_guess;
  for (int n = 0; n < nodes; ++n)
    if (fixed[n]) guess.segment<3>(3 * n).setZero();
  s.state_upload(s.dv, guess.data(), size);
  check_gl("uploading the state");
  if (gpu_rotations) upload_rotations(model, state);
}

bool EfgStep::solve_velocity_change(const ImplicitEulerSettings& settings, CgResult& cg) {
  Impl& s = *impl_;
  const int nodes = s.nodes;
  const Index size = 3 * static_cast<Index>(nodes);
  // Right-hand side dt [f(x) - (dt + beta) K v - alpha M v], free entries only.
  s.run(Kernel::element_stress, s.elements, {{a_binding, &s.u}}, 0);
  s.run(Kernel::node_gather, nodes, {{a_binding, &s.u}, {b_binding, &s.external}, {c_binding, &s.forces}}, 0);
  s.product_of(s.v, s.stiffness_velocity, 1);
  s.run(Kernel::right_hand_side, static_cast<int>(size),
        {{a_binding, &s.forces}, {b_binding, &s.stiffness_velocity}, {c_binding, &s.v}, {d_binding, &s.rhs}});
  s.run(Kernel::diagonal, nodes, {{c_binding, &s.inverse_diagonal}});

  // CG (cg.cpp's algorithm; the same stops).
  const int dofs = static_cast<int>(size);
  s.dot(dofs, s.rhs, s.rhs, rhs_slot);
  const double b_norm = std::sqrt(s.read_scalars(rhs_slot)[0]);
  bool solved = false;
  if (!std::isfinite(b_norm)) {
    return false;
  }
  if (b_norm == 0.0) {
    const std::vector<double> zeros(static_cast<size_t>(size), 0.0);
    s.state_upload(s.dv, zeros.data(), size);
    cg.converged = true;
    solved = true;
  }
  if (!solved) {
    s.product_of(s.dv, s.product, 2);
    s.dot(dofs, s.dv, s.rhs, guess_slot, &s.dv, &s.product, guess_slot + 1);
    s.run(Kernel::scale_guess, dofs, {{a_binding, &s.dv}, {b_binding, &s.product}}, 0, guess_slot, guess_slot + 1);
    s.run(Kernel::residual_init, dofs,
          {{a_binding, &s.product}, {b_binding, &s.rhs}, {c_binding, &s.r}, {d_binding, &s.z}, {e_binding, &s.p},
           {f_binding, &s.inverse_diagonal}});
    // CG's checks run on the GPU (kernel cg_check); the host reads the status back every
    // cg_iterations_per_check iterations, and sees the deadline there.
    const double threshold = settings.cg.tolerance * b_norm * settings.cg.tolerance * b_norm;
    s.upload_reals(s.scalars, threshold_slot, &threshold, 1);
    const int cleared[2] = {0, 0};
    s.upload_ints(s.flags, 1, cleared, 2);
    const CgBudget& budget = settings.cg.budget;
    s.cg_limit = budget.stop_at > 0 ? std::min(budget.stop_at, settings.cg.max_iterations) : settings.cg.max_iterations;
    int rz_current = rz_slot, rz_next = rz_slot + 1;
    s.dot(dofs, s.r, s.r, residual_slot, &s.r, &s.z, rz_current);
    s.run(Kernel::cg_check, 1, {}, 1, curvature_slot, residual_slot);
    s.cg_gate = 1;
    int status = 0;
    for (int queued = 0;;) {
      int flags[2] = {0, 0};
      glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
      glGetNamedBufferSubData(s.flags.id, 4, 8, flags);
      status = flags[0];
      cg.iterations = flags[1];
      if (status != 0 || queued >= s.cg_limit) break;
      if (budget.stop_at == 0 && budget_spent(budget, cg.iterations)) {
        cg.stopped_by_budget = true;
        break;
      }
      // Iterations queued past the stop cost a dispatch of kernels that return at once.
      const int batch = std::min(settings_.cg_iterations_per_check, s.cg_limit - queued);
      for (int k = 0; k < batch; ++k, ++queued) {
        s.product_of(s.p, s.product, 2);
        s.dot(dofs, s.p, s.product, curvature_slot);
        s.run(Kernel::cg_update, dofs,
              {{a_binding, &s.dv}, {b_binding, &s.p}, {c_binding, &s.r}, {d_binding, &s.product}, {e_binding, &s.z},
               {f_binding, &s.inverse_diagonal}},
              0, curvature_slot, rz_current);
        s.dot(dofs, s.r, s.r, residual_slot, &s.r, &s.z, rz_next);
        s.run(Kernel::cg_check, 1, {}, 0, curvature_slot, residual_slot);
        s.run(Kernel::cg_direction, dofs, {{a_binding, &s.z}, {b_binding, &s.p}}, 0, rz_current, rz_next);
        std::swap(rz_current, rz_next);
      }
    }
    s.cg_gate = 0;
    const double residual_norm = std::sqrt(s.read_scalars(curvature_slot)[1]);
    cg.relative_residual = residual_norm / b_norm;
    cg.converged = status == 1;
    cg.nonfinite = status == 2 || (status == 1 && !std::isfinite(residual_norm));
    cg.non_positive_curvature = status == 3;
    if (status == 4 && budget.stop_at > 0 && cg.iterations >= budget.stop_at) cg.stopped_by_budget = true;
    if (cg.nonfinite) return false;
  }

  return true;
}

// v += dv, x += dt v on the GPU, read back; the fixed nodes keep their positions.
bool EfgStep::integrate(const CorotationalEfg& model, State& state, const std::vector<uint8_t>& fixed,
                        Vector* velocity_change_guess) {
  Impl& s = *impl_;
  const int nodes = s.nodes;
  const Index size = 3 * static_cast<Index>(nodes);
  const int dofs = static_cast<int>(size);
  s.run(Kernel::integrate, dofs,
        {{a_binding, &s.u}, {b_binding, &s.v}, {c_binding, &s.v_next}, {d_binding, &s.dv}, {e_binding, &s.u_next}});
  Vector velocities(size), next_displacement(size), velocity_change(size);
  s.download_reals(s.v_next, size, velocities.data());
  s.download_reals(s.u_next, size, next_displacement.data());
  s.download_reals(s.dv, size, velocity_change.data());
  check_gl("the step's kernels");
  Vector positions = model.rest_positions() + next_displacement;
  for (int n = 0; n < nodes; ++n) {
    if (!fixed[n]) continue;
    velocities.segment<3>(3 * n).setZero();
    positions.segment<3>(3 * n) = state.positions.segment<3>(3 * n);
  }
  if (!velocities.allFinite() || !positions.allFinite() || !velocity_change.allFinite()) return false;
  std::swap(s.u, s.u_next);
  std::swap(s.v, s.v_next);
  if (velocity_change_guess) *velocity_change_guess = velocity_change;
  state.positions.swap(positions);
  state.velocities.swap(velocities);
  return true;
}

void EfgStep::upload_surface(const SurfaceEmbedding& embedding) {
  CurrentScope current(*context_);
  impl_->sync_surface(embedding);
  check_gl("uploading the surface mapping");
}

void EfgStep::surface_positions(const SurfaceEmbedding& embedding, Vector& out) {
  Impl& s = *impl_;
  CurrentScope current(*context_);
  s.sync_surface(embedding);
  const int vertices = embedding.vertex_count();
  for (int v = 0; v < vertices; ++v)
    for (int k = 0; k < embedding.row_lengths[v]; ++k)
      if (embedding.particles[static_cast<size_t>(v) * embedding.stride + k] >= s.nodes)
        throw std::invalid_argument("EfgStep::surface_positions: vertex " + std::to_string(v) + " names particle " +
                                    std::to_string(embedding.particles[static_cast<size_t>(v) * embedding.stride + k]) +
                                    " of " + std::to_string(s.nodes));
  s.bind_fixed();
  s.bind(neighbours_binding, s.surface_particles);
  s.bind(values_binding, s.surface_weights);
  s.bind(lengths_binding, s.surface_lengths);
  s.run(Kernel::surface, vertices, {{a_binding, &s.u}, {c_binding, &s.surface_out}}, 0, 0, 0, s.surface_stride_capacity);
  out.resize(3 * static_cast<Index>(vertices));
  s.download_reals(s.surface_out, 3LL * vertices, out.data());
  s.bind_fixed();
  check_gl("surface positions");
}

void EfgStep::integration_points(const CorotationalEfg& model, Vector& out) {
  Impl& s = *impl_;
  CurrentScope current(*context_);
  s.sync_rows(model);
  s.bind_fixed();
  s.run(Kernel::integration_points, s.elements, {{a_binding, &s.u}, {c_binding, &s.points_out}});
  out.resize(3 * static_cast<Index>(s.elements));
  s.download_reals(s.points_out, 3LL * s.elements, out.data());
  check_gl("integration points");
}

}  // namespace incise::physics::gpu
