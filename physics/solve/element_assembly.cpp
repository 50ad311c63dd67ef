#include "physics/solve/element_assembly.hpp"

#include "physics/core/cpu_features.hpp"

#include <atomic>
#include <stdexcept>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define INCISE_ELEMENT_ASSEMBLY_AVX2 1
#include <immintrin.h>
#endif

namespace incise::physics {

bool ElementAssembly::matches(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours) const {
  return matrix_.nodes() == nodes && stride_ == stride && lengths_ == lengths && neighbours_ == neighbours;
}

void ElementAssembly::build(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours,
                            const std::vector<int>* changed) {
  if (edit(nodes, stride, lengths, neighbours, changed)) return;  // element_assembly_edit.cpp
  groups_ = group_elements(stride, lengths, neighbours);
  for (int node : groups_.nodes)
    if (node < 0 || node >= nodes) throw std::invalid_argument("ElementAssembly: a row names a node outside [0, nodes)");
  stride_ = stride;
  lengths_ = lengths;
  neighbours_ = neighbours;
  const int count = groups_.count();
  size_groups();
  pattern_rebuilt_ = matrix_.nodes() != nodes || !index_pairs();
  if (pattern_rebuilt_) {
    matrix_ = BlockMatrix(nodes, [&](const std::function<void(std::span<const int>)>& visit) {
      for (int g = 0; g < count; ++g)
        visit(std::span<const int>(groups_.nodes.data() + groups_.node_start[static_cast<size_t>(g)], static_cast<size_t>(groups_.length(g))));
    });
    if (!index_pairs()) throw std::logic_error("ElementAssembly: a pair is missing from the pattern just built");
    index_mirrors();
  }
  list_incidences();
}

void ElementAssembly::size_groups() {
  const int count = groups_.count();
  longest_ = 0;
  pair_start_.assign(static_cast<size_t>(count) + 1, 0);
  gradient_offset_.assign(static_cast<size_t>(count) + 1, 0);
  for (int g = 0; g < count; ++g) {
    const int length = groups_.length(g);
    const int members = groups_.member_start[static_cast<size_t>(g) + 1] - groups_.member_start[static_cast<size_t>(g)];
    longest_ = std::max(longest_, length);
    pair_start_[static_cast<size_t>(g) + 1] = pair_start_[static_cast<size_t>(g)] + length * (length + 1) / 2;
    gradient_offset_[static_cast<size_t>(g) + 1] = gradient_offset_[static_cast<size_t>(g)] + static_cast<size_t>(3 * length * members);
  }
  // Every refill writes every element's vectors and weight: only the padding needs a value.
  gradients_.resize(gradient_offset_.back() + padding);
  std::fill(gradients_.end() - padding, gradients_.end(), 0.0);
  weights_.resize(groups_.members.size());
}

bool ElementAssembly::index_pairs() {
  pair_index_.assign(static_cast<size_t>(pair_start_.back()), 0);
  for (int g = 0; g < groups_.count(); ++g) {
    const int* nodes = groups_.nodes.data() + groups_.node_start[static_cast<size_t>(g)];
    const int length = groups_.length(g);
    int next = pair_start_[static_cast<size_t>(g)];
    for (int a = 0; a < length; ++a)
      for (int b = a; b < length; ++b) {
        const int index = matrix_.find(nodes[a], nodes[b]);
        if (index < 0) return false;
        pair_index_[static_cast<size_t>(next++)] = index;
      }
  }
  return true;
}

void ElementAssembly::index_mirrors() {
  const std::vector<int>& start = matrix_.row_start();
  const std::vector<int>& columns = matrix_.columns();
  // The pattern is symmetric: visiting the rows in order meets the blocks (j, i) of each row j
  // in its column order.
  mirror_.assign(columns.size(), -1);
  std::vector<int> next(start.begin(), start.end() - 1);
  for (int row = 0; row < matrix_.nodes(); ++row)
    for (int k = start[static_cast<size_t>(row)]; k < start[static_cast<size_t>(row) + 1]; ++k)
      mirror_[static_cast<size_t>(k)] = next[static_cast<size_t>(columns[static_cast<size_t>(k)])]++;
}

void ElementAssembly::list_incidences() {
  const int nodes = matrix_.nodes();
  upper_start_.assign(static_cast<size_t>(nodes), 0);
  range_begin_.assign(static_cast<size_t>(nodes), 0);
  widest_ = 0;
  for (int row = 0; row < nodes; ++row) {
    const auto first = matrix_.columns().begin() + matrix_.row_start()[static_cast<size_t>(row)];
    const auto last = matrix_.columns().begin() + matrix_.row_start()[static_cast<size_t>(row) + 1];
    upper_start_[static_cast<size_t>(row)] = static_cast<int>(std::lower_bound(first, last, row) - matrix_.columns().begin());
    widest_ = std::max(widest_, static_cast<int>(last - matrix_.columns().begin()) - upper_start_[static_cast<size_t>(row)]);
  }
  incidence_start_.assign(static_cast<size_t>(nodes) + 1, 0);
  for (int node : groups_.nodes) ++incidence_start_[static_cast<size_t>(node) + 1];
  for (int n = 0; n < nodes; ++n) incidence_start_[static_cast<size_t>(n) + 1] += incidence_start_[static_cast<size_t>(n)];
  incidence_.assign(static_cast<size_t>(incidence_start_.back()), Incidence{});
  std::vector<int> next(incidence_start_.begin(), incidence_start_.end() - 1);
  for (int g = 0; g < groups_.count(); ++g) {
    const int* group_nodes = groups_.nodes.data() + groups_.node_start[static_cast<size_t>(g)];
    const int length = groups_.length(g);
    for (int a = 0; a < length; ++a)
      incidence_[static_cast<size_t>(next[static_cast<size_t>(group_nodes[a])]++)] =
          Incidence{g, a, pair_start_[static_cast<size_t>(g)] + a * length - a * (a - 1) / 2};
  }
}

namespace {

#if defined(INCISE_ELEMENT_ASSEMBLY_AVX2)
// sum_pairs for a group of 8 nodes, node a: the same products and sums in the same order, four
// columns to a lane set. Row c's 3 (8 - a) sums sit in registers across the elements; columns
// past the row's end are summed too (from the next element's vectors or the padding) and stored
// into the next row, which overwrites them, or into the scratch's padding.
template <int A>
__attribute__((target("avx2"))) void avx2_sums8(const double* rows, const double* element_weights, int elements,
                                                double* sums) {
  constexpr int sets = (3 * (8 - A) + 3) / 4;
  for (int c = 0; c < 3; ++c) {
    __m256d sum[sets];
    for (int v = 0; v < sets; ++v) sum[v] = _mm256_setzero_pd();
    for (int m = 0; m < elements; ++m) {
      const double weight = element_weights[m];
      if (weight == 0) continue;
      const double* h = rows + 24 * m + 3 * A;
      const __m256d factor = _mm256_set1_pd(weight * h[c]);
      for (int v = 0; v < sets; ++v) sum[v] = _mm256_add_pd(sum[v], _mm256_mul_pd(factor, _mm256_loadu_pd(h + 4 * v)));
    }
    for (int v = 0; v < sets; ++v) _mm256_storeu_pd(sums + 24 * c + 4 * v, sum[v]);
  }
}

using Sums8 = void (*)(const double*, const double*, int, double*);
constexpr Sums8 avx2_sums8_of[8] = {avx2_sums8<0>, avx2_sums8<1>, avx2_sums8<2>, avx2_sums8<3>,
                                    avx2_sums8<4>, avx2_sums8<5>, avx2_sums8<6>, avx2_sums8<7>};

#endif

std::atomic<bool> vectorised_allowed{true};

}  // namespace

bool element_assembly_vectorised() {
#if defined(INCISE_ELEMENT_ASSEMBLY_AVX2)
  return vectorised_allowed.load(std::memory_order_relaxed) && cpu_has_avx2();
#else
  return false;
#endif
}

void set_element_assembly_vectorised(bool allowed) { vectorised_allowed.store(allowed, std::memory_order_relaxed); }

void ElementAssembly::sum_row(int row, double* scratch, Mat3* sums) const {
  const int first = upper_start_[static_cast<size_t>(row)];
  std::fill(sums, sums + (matrix_.row_start()[static_cast<size_t>(row) + 1] - first), Mat3::Zero());
  for (int i = incidence_start_[static_cast<size_t>(row)]; i < incidence_start_[static_cast<size_t>(row) + 1]; ++i) {
    const Incidence& incidence = incidence_[static_cast<size_t>(i)];
    const int pitch = sum_pairs(incidence, scratch);
    const int* nodes = groups_.nodes.data() + groups_.node_start[static_cast<size_t>(incidence.group)];
    const int length = groups_.length(incidence.group);
    for (int b = incidence.a; b < length; ++b) {
      const double* sum = scratch + 3 * (b - incidence.a);
      Mat3& out = sums[pair_index_[static_cast<size_t>(incidence.pairs + b - incidence.a)] - first];
      for (int c = 0; c < 3; ++c)
        for (int d = 0; d < 3; ++d) out(c, d) += sum[c * pitch + d];
      // A node repeated in the group: its pair (b, a) falls on the same diagonal block.
      if (b != incidence.a && nodes[b] == nodes[incidence.a])
        for (int c = 0; c < 3; ++c)
          for (int d = 0; d < 3; ++d) out(d, c) += sum[c * pitch + d];
    }
  }
}

int ElementAssembly::sum_pairs(const Incidence& incidence, double* sums) const {
  const int g = incidence.group, a = incidence.a;
  const int length = groups_.length(g);
  const int first = groups_.member_start[static_cast<size_t>(g)];
  const int last = groups_.member_start[static_cast<size_t>(g) + 1];
  const double* rows = gradients_.data() + gradient_offset_[static_cast<size_t>(g)];
#if defined(INCISE_ELEMENT_ASSEMBLY_AVX2)
  if (length == 8 && element_assembly_vectorised()) {
    avx2_sums8_of[a](rows, weights_.data() + first, last - first, sums);
    return 24;
  }
#endif
  const int width = 3 * (length - a);
  std::fill(sums, sums + 3 * width, 0.0);
  for (int m = first; m < last; ++m) {
    const double weight = weights_[static_cast<size_t>(m)];
    if (weight == 0) continue;
    // h = this element's vectors from node a on: h[0..2] is h_a, h[3 (b - a) ..] is h_b.
    const double* h = rows + static_cast<size_t>(3 * length) * static_cast<size_t>(m - first) + 3 * a;
    for (int c = 0; c < 3; ++c) {
      const double factor = weight * h[c];
      double* out = sums + c * width;
      for (int j = 0; j < width; ++j) out[j] += factor * h[j];
    }
  }
  return width;
}

}  // namespace incise::physics
