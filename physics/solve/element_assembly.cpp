#include "physics/solve/element_assembly.hpp"

#include <stdexcept>

namespace incise::physics {

bool ElementAssembly::matches(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours) const {
  return matrix_.nodes() == nodes && stride_ == stride && lengths_ == lengths && neighbours_ == neighbours;
}

void ElementAssembly::build(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours) {
  if (stride < 1 || neighbours.size() != lengths.size() * static_cast<size_t>(stride))
    throw std::invalid_argument("ElementAssembly: the rows need lengths.size() x stride neighbours");
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
  incidence_start_.assign(static_cast<size_t>(nodes) + 1, 0);
  for (int e = 0; e < elements; ++e)
    for (int node : row(e)) ++incidence_start_[static_cast<size_t>(node) + 1];
  for (int n = 0; n < nodes; ++n) incidence_start_[static_cast<size_t>(n) + 1] += incidence_start_[static_cast<size_t>(n)];
  incidence_.assign(static_cast<size_t>(incidence_start_.back()), 0);
  std::vector<int> next(incidence_start_.begin(), incidence_start_.end() - 1);
  block_index_.assign(static_cast<size_t>(elements) * stride * stride, 0);
  const Mat3* first = matrix_.blocks().data();
  for (int e = 0; e < elements; ++e) {
    const auto nodes_of_e = row(e);
    for (int a = 0; a < static_cast<int>(nodes_of_e.size()); ++a) {
      incidence_[static_cast<size_t>(next[static_cast<size_t>(nodes_of_e[a])]++)] = e * stride + a;
      for (int b = 0; b < static_cast<int>(nodes_of_e.size()); ++b)
        block_index_[(static_cast<size_t>(e) * stride + a) * stride + b] =
            static_cast<int>(&matrix_.at(nodes_of_e[a], nodes_of_e[b]) - first);
    }
  }
}

}  // namespace incise::physics
