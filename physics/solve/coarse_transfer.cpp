#include "physics/solve/coarse_transfer.hpp"

#include <stdexcept>

namespace incise::physics {

namespace {

[[noreturn]] void not_blocks() {
  throw std::invalid_argument("CoarseTransfer: the prolongation is not 3x3 blocks w I");
}

}  // namespace

CoarseTransfer::CoarseTransfer(const Eigen::SparseMatrix<double>& prolongation) {
  using Iterator = Eigen::SparseMatrix<double>::InnerIterator;
  if (prolongation.rows() % 3 != 0 || prolongation.cols() % 3 != 0) not_blocks();
  const int nodes = static_cast<int>(prolongation.rows() / 3), coarse = static_cast<int>(prolongation.cols() / 3);
  std::vector<int> count(static_cast<size_t>(nodes), 0);
  coarse_start_.reserve(static_cast<size_t>(coarse) + 1);
  for (int c = 0; c < coarse; ++c) {
    // Column 3c holds the weights; columns 3c + 1 and 3c + 2 the same ones a row lower.
    Iterator y(prolongation, 3 * c + 1), z(prolongation, 3 * c + 2);
    for (Iterator x(prolongation, 3 * c); x; ++x, ++y, ++z) {
      if (x.row() % 3 != 0 || !y || !z || y.row() != x.row() + 1 || z.row() != x.row() + 2 || y.value() != x.value() ||
          z.value() != x.value())
        not_blocks();
      const int node = static_cast<int>(x.row() / 3);
      coarse_node_.push_back(node);
      coarse_weight_.push_back(x.value());
      ++count[static_cast<size_t>(node)];
    }
    if (y || z) not_blocks();
    coarse_start_.push_back(static_cast<int>(coarse_node_.size()));
  }
  // The transpose: scanning the coarse nodes in order leaves each node's list ascending.
  node_start_.resize(static_cast<size_t>(nodes) + 1);
  for (int i = 0; i < nodes; ++i) node_start_[static_cast<size_t>(i) + 1] = node_start_[static_cast<size_t>(i)] + count[static_cast<size_t>(i)];
  node_coarse_.resize(coarse_node_.size());
  node_weight_.resize(coarse_node_.size());
  std::vector<int> next(node_start_.begin(), node_start_.end() - 1);
  for (int c = 0; c < coarse; ++c)
    for (int k = coarse_start_[static_cast<size_t>(c)]; k < coarse_start_[static_cast<size_t>(c) + 1]; ++k) {
      const int slot = next[static_cast<size_t>(coarse_node_[static_cast<size_t>(k)])]++;
      node_coarse_[static_cast<size_t>(slot)] = c;
      node_weight_[static_cast<size_t>(slot)] = coarse_weight_[static_cast<size_t>(k)];
    }
}

void CoarseTransfer::restrict_nodes(const double* t, double* u, int begin, int end) const {
  for (int c = begin; c < end; ++c) {
    // Eigen's row-major sparse product: tmp = 0, tmp += w t in the row's order, res = 0 + 1 tmp.
    double sum[3] = {0, 0, 0};
    for (int k = coarse_start_[static_cast<size_t>(c)]; k < coarse_start_[static_cast<size_t>(c) + 1]; ++k) {
      const double w = coarse_weight_[static_cast<size_t>(k)];
      const double* node = t + 3 * static_cast<size_t>(coarse_node_[static_cast<size_t>(k)]);
      for (int a = 0; a < 3; ++a) sum[a] += w * node[a];
    }
    for (int a = 0; a < 3; ++a) u[3 * static_cast<size_t>(c) + static_cast<size_t>(a)] = 0.0 + sum[a];
  }
}

Eigen::Vector3d CoarseTransfer::prolong_node(const double* u, int node) const {
  // Eigen's column-major sparse product: res = 0, res_i += w (1 u_c) over the columns in order.
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int k = node_start_[static_cast<size_t>(node)]; k < node_start_[static_cast<size_t>(node) + 1]; ++k) {
    const double w = node_weight_[static_cast<size_t>(k)];
    const double* coarse = u + 3 * static_cast<size_t>(node_coarse_[static_cast<size_t>(k)]);
    for (int a = 0; a < 3; ++a) sum[a] += w * coarse[a];
  }
  return sum;
}

}  // namespace incise::physics
