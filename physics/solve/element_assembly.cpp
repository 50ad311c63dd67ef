#include "physics/solve/element_assembly.hpp"

#include <algorithm>
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

// The incidence lists of the rows: per node, e * stride + a for each element e holding it as
// local node a, in increasing order.
void build_incidence(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours,
                     std::vector<int>& start, std::vector<int>& incidence) {
  const int elements = static_cast<int>(lengths.size());
  start.assign(static_cast<size_t>(nodes) + 1, 0);
  for (int e = 0; e < elements; ++e)
    for (int k = 0; k < lengths[static_cast<size_t>(e)]; ++k)
      ++start[static_cast<size_t>(neighbours[static_cast<size_t>(e) * stride + k]) + 1];
  for (int n = 0; n < nodes; ++n) start[static_cast<size_t>(n) + 1] += start[static_cast<size_t>(n)];
  incidence.assign(static_cast<size_t>(start.back()), 0);
  std::vector<int> next(start.begin(), start.end() - 1);
  for (int e = 0; e < elements; ++e)
    for (int a = 0; a < lengths[static_cast<size_t>(e)]; ++a)
      incidence[static_cast<size_t>(next[static_cast<size_t>(neighbours[static_cast<size_t>(e) * stride + a])]++)] = e * stride + a;
}

// A cut changes a few rows per step, whose pairs are mostly in the pattern already: only their
// block indices are redone (blocks of pairs no row holds any more stay in the pattern, zero).
// False, with nothing changed, when a pair is outside the pattern.
bool update_block_indices(const BlockMatrix& matrix, int stride, const std::vector<int>& old_lengths,
                          const std::vector<int>& old_neighbours, const std::vector<int>& lengths,
                          const std::vector<int>& neighbours, std::vector<int>& block_index) {
  const int elements = static_cast<int>(lengths.size());
  std::vector<int> changed, indices;
  for (int e = 0; e < elements; ++e) {
    const size_t base = static_cast<size_t>(e) * stride;
    const int length = lengths[static_cast<size_t>(e)];
    if (length != old_lengths[static_cast<size_t>(e)] ||
        !std::equal(neighbours.begin() + base, neighbours.begin() + base + length, old_neighbours.begin() + base))
      changed.push_back(e);
  }
  for (int e : changed) {
    const size_t base = static_cast<size_t>(e) * stride;
    const int length = lengths[static_cast<size_t>(e)];
    for (int a = 0; a < length; ++a)
      for (int b = 0; b < length; ++b) {
        const int index = find_block(matrix, neighbours[base + a], neighbours[base + b]);
        if (index < 0) return false;
        indices.push_back(index);
      }
  }
  size_t next = 0;
  for (int e : changed) {
    const int length = lengths[static_cast<size_t>(e)];
    for (int a = 0; a < length; ++a)
      for (int b = 0; b < length; ++b) block_index[(static_cast<size_t>(e) * stride + a) * stride + b] = indices[next++];
  }
  return true;
}

}  // namespace

void ElementAssembly::build(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours) {
  if (stride < 1 || neighbours.size() != lengths.size() * static_cast<size_t>(stride))
    throw std::invalid_argument("ElementAssembly: the rows need lengths.size() x stride neighbours");
  if (matrix_.nodes() == nodes && stride_ == stride && lengths_.size() == lengths.size() &&
      update_block_indices(matrix_, stride, lengths_, neighbours_, lengths, neighbours, block_index_)) {
    lengths_ = lengths;
    neighbours_ = neighbours;
    build_incidence(nodes, stride, lengths_, neighbours_, incidence_start_, incidence_);
    return;
  }
  stride_ = stride;
  lengths_ = lengths;
  neighbours_ = neighbours;
  const int elements = static_cast<int>(lengths.size());
  auto row = [&](int e) {
    return std::span<const int>(neighbours.data() + static_cast<size_t>(e) * stride, static_cast<size_t>(lengths[static_cast<size_t>(e)]));
  };
  matrix_ = BlockMatrix(nodes, [&](const std::function<void(std::span<const int>)>& visit) {
    for (int e = 0; e < elements; ++e) visit(row(e));
  });
  build_incidence(nodes, stride, lengths, neighbours, incidence_start_, incidence_);
  block_index_.assign(static_cast<size_t>(elements) * stride * stride, 0);
  const Mat3* first = matrix_.blocks().data();
  for (int e = 0; e < elements; ++e) {
    const auto nodes_of_e = row(e);
    for (int a = 0; a < static_cast<int>(nodes_of_e.size()); ++a) {
      for (int b = 0; b < static_cast<int>(nodes_of_e.size()); ++b)
        block_index_[(static_cast<size_t>(e) * stride + a) * stride + b] =
            static_cast<int>(&matrix_.at(nodes_of_e[a], nodes_of_e[b]) - first);
    }
  }
}

}  // namespace incise::physics
