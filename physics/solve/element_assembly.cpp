#include "physics/solve/element_assembly.hpp"

#include <stdexcept>

namespace incise::physics {

bool ElementAssembly::matches(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours) const {
  return matrix_.nodes() == nodes && stride_ == stride && lengths_ == lengths && neighbours_ == neighbours;
}

namespace {

// The index of block (row, column) in `matrix`'s pattern, -1 if it is not there.
int find_block(const BlockMatrix& matrix, int row, int column) {
  const auto first = matrix.columns().begin() + matrix.row_start()[static_cast<size_t>(row)];
  const auto last = matrix.columns().begin() + matrix.row_start()[static_cast<size_t>(row) + 1];
  const auto found = std::lower_bound(first, last, column);
  return found != last && *found == column ? static_cast<int>(found - matrix.columns().begin()) : -1;
}

}  // namespace

void ElementAssembly::build(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours) {
  groups_ = group_elements(stride, lengths, neighbours);
  for (int node : groups_.nodes)
    if (node < 0 || node >= nodes) throw std::invalid_argument("ElementAssembly: a row names a node outside [0, nodes)");
  stride_ = stride;
  lengths_ = lengths;
  neighbours_ = neighbours;
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
  gradients_.resize(gradient_offset_.back());
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

bool ElementAssembly::index_pairs() {
  pair_index_.assign(static_cast<size_t>(pair_start_.back()), 0);
  for (int g = 0; g < groups_.count(); ++g) {
    const int* nodes = groups_.nodes.data() + groups_.node_start[static_cast<size_t>(g)];
    const int length = groups_.length(g);
    int next = pair_start_[static_cast<size_t>(g)];
    for (int a = 0; a < length; ++a)
      for (int b = a; b < length; ++b) {
        const int index = find_block(matrix_, nodes[a], nodes[b]);
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

void ElementAssembly::sum_pairs(const Incidence& incidence, std::span<const double> weights, double* sums) const {
  const int g = incidence.group, a = incidence.a;
  const int length = groups_.length(g);
  const int width = 3 * (length - a);
  std::fill(sums, sums + 3 * width, 0.0);
  const int first = groups_.member_start[static_cast<size_t>(g)];
  const int last = groups_.member_start[static_cast<size_t>(g) + 1];
  const double* rows = gradients_.data() + gradient_offset_[static_cast<size_t>(g)];
  for (int m = first; m < last; ++m) {
    const double weight = weights[static_cast<size_t>(groups_.members[static_cast<size_t>(m)])];
    if (weight == 0) continue;
    // h = this element's vectors from node a on: h[0..2] is h_a, h[3 (b - a) ..] is h_b.
    const double* h = rows + static_cast<size_t>(3 * length) * static_cast<size_t>(m - first) + 3 * a;
    for (int c = 0; c < 3; ++c) {
      const double factor = weight * h[c];
      double* out = sums + c * width;
      for (int j = 0; j < width; ++j) out[j] += factor * h[j];
    }
  }
}

}  // namespace incise::physics
