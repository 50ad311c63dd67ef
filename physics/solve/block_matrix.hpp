// A symmetric sparse matrix of 3x3 blocks, one block row per node (block CSR, both triangles
// stored): the rest stiffness K0 a rest-shape preconditioner factors (physics/solve/).
//
// Built in two passes so that no triplet list of every element's 3x3 blocks is ever held (at
// 20k EFG elements that list would be 1.3M blocks): the pattern from the elements' node lists
// first, then each element's blocks added in place.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <functional>
#include <span>
#include <utility>
#include <vector>

namespace incise::physics {

using Mat3 = Eigen::Matrix3d;

class BlockMatrix {
 public:
  BlockMatrix() = default;
  // The pattern where every pair of nodes of an element couples. `for_each_element(visit)`
  // calls visit(nodes) once per element with its node list (any order; repeated nodes allowed).
  BlockMatrix(int nodes, const std::function<void(const std::function<void(std::span<const int>)>&)>& for_each_element);

  // Given block rows: row_start (nodes + 1, from 0), columns increasing within a row,
  // blocks as many as columns (throws std::invalid_argument otherwise).
  BlockMatrix(int nodes, std::vector<int> row_start, std::vector<int> columns, std::vector<Mat3> blocks);

  int nodes() const { return nodes_; }
  int block_count() const { return static_cast<int>(columns_.size()); }
  // The block (row, column); it must be in the pattern (throws std::out_of_range otherwise).
  Mat3& at(int row, int column);
  // The index of block (row, column) in blocks(), -1 if it is not in the pattern.
  int find(int row, int column) const;
  // Block row r holds the blocks k in [row_start()[r], row_start()[r + 1]), block k in
  // column columns()[k].
  const std::vector<int>& row_start() const { return row_start_; }
  const std::vector<int>& columns() const { return columns_; }
  const std::vector<Mat3>& blocks() const { return blocks_; }
  Mat3* mutable_blocks() { return blocks_.data(); }
  // Hands the blocks' storage to a caller that lays a new pattern in it (ElementAssembly: a
  // refill rewrites every block); the matrix is left without blocks until it is replaced.
  std::vector<Mat3> release_blocks() { return std::move(blocks_); }

  // The scalar matrix mass_coefficient M + stiffness_coefficient K (3n x 3n, column-major),
  // M = diag(masses) per node, with the rows and columns of nodes marked fixed (1) replaced by
  // the identity's, so that the fixed degrees of freedom decouple (the filtered CG never
  // reads them).
  Eigen::SparseMatrix<double> system(const Eigen::VectorXd& masses, const std::vector<std::uint8_t>& fixed,
                                     double mass_coefficient, double stiffness_coefficient) const;

 private:
  int nodes_ = 0;
  std::vector<int> row_start_;  // nodes + 1
  std::vector<int> columns_;    // increasing within a row
  std::vector<Mat3> blocks_;
};

}  // namespace incise::physics
