// The transfers between a body's nodes and a coarse space's (coarse_space.hpp), read from the
// prolongation P (3n x 3m, 3x3 blocks w_ic I) into two row-wise tables, so that both run as
// gathers over independent rows, on any split of them into threads:
//   restriction   u_c = sum_i w_ic t_i   over the nodes i of coarse node c (P^T's row),
//   prolongation  v_i = sum_c w_ic u_c   over the coarse nodes c of node i (P's row, <= 8).
// Each sum runs in the order of Eigen's sparse products on P (the restriction: P's column
// top to bottom; the prolongation: the coarse nodes in increasing order) from +0, so the
// results have the bits of P.transpose() * t and P * u (current_vcycle.hpp relies on it).
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <vector>

namespace incise::physics {

class CoarseTransfer {
 public:
  CoarseTransfer() = default;
  // Throws std::invalid_argument unless P is 3n x 3m in blocks w I.
  explicit CoarseTransfer(const Eigen::SparseMatrix<double>& prolongation);

  int nodes() const { return static_cast<int>(node_start_.size()) - 1; }
  int coarse_nodes() const { return static_cast<int>(coarse_start_.size()) - 1; }

  // u's coarse nodes [begin, end) = P^T t (3 entries a node each).
  void restrict_nodes(const double* t, double* u, int begin, int end) const;
  // P u at `node` (+0 for a node no coarse node reaches).
  Eigen::Vector3d prolong_node(const double* u, int node) const;

 private:
  // Per coarse node, its nodes ascending and their weights (P's column 3c).
  std::vector<int> coarse_start_{0}, coarse_node_;
  std::vector<double> coarse_weight_;
  // Per node, its coarse nodes ascending and their weights (P's row 3i).
  std::vector<int> node_start_{0}, node_coarse_;
  std::vector<double> node_weight_;
};

}  // namespace incise::physics
