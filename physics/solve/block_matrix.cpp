#include "physics/solve/block_matrix.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <utility>

namespace incise::physics {

BlockMatrix::BlockMatrix(int nodes,
                         const std::function<void(const std::function<void(std::span<const int>)>&)>& for_each_element)
    : nodes_(nodes), row_start_(static_cast<size_t>(nodes) + 1, 0) {
  std::vector<std::vector<int>> adjacency(static_cast<size_t>(nodes));
  for_each_element([&](std::span<const int> element) {
    for (int row : element) {
      auto& list = adjacency[static_cast<size_t>(row)];
      list.insert(list.end(), element.begin(), element.end());
    }
  });
  for (int row = 0; row < nodes; ++row) {
    auto& list = adjacency[static_cast<size_t>(row)];
    list.push_back(row);  // every diagonal block exists, so a node no element uses stays solvable
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
    row_start_[static_cast<size_t>(row) + 1] = row_start_[static_cast<size_t>(row)] + static_cast<int>(list.size());
  }
  columns_.reserve(static_cast<size_t>(row_start_.back()));
  for (auto& list : adjacency) {
    columns_.insert(columns_.end(), list.begin(), list.end());
    std::vector<int>().swap(list);
  }
  blocks_.assign(columns_.size(), Mat3::Zero());
}

BlockMatrix::BlockMatrix(int nodes, std::vector<int> row_start, std::vector<int> columns, std::vector<Mat3> blocks)
    : nodes_(nodes), row_start_(std::move(row_start)), columns_(std::move(columns)), blocks_(std::move(blocks)) {
  const bool sized = nodes >= 0 && row_start_.size() == static_cast<size_t>(nodes) + 1 && row_start_.front() == 0 &&
                     static_cast<size_t>(row_start_.back()) == columns_.size() && blocks_.size() == columns_.size();
  if (!sized) throw std::invalid_argument("BlockMatrix: row_start, columns and blocks do not match the node count");
  for (int row = 0; row < nodes; ++row) {
    const int first = row_start_[static_cast<size_t>(row)], last = row_start_[static_cast<size_t>(row) + 1];
    if (first > last) throw std::invalid_argument("BlockMatrix: row_start decreases at row " + std::to_string(row));
    for (int k = first; k < last; ++k) {
      const int column = columns_[static_cast<size_t>(k)];
      if (column < 0 || column >= nodes || (k > first && column <= columns_[static_cast<size_t>(k) - 1]))
        throw std::invalid_argument("BlockMatrix: the columns of row " + std::to_string(row) +
                                    " are not increasing node indices");
    }
  }
}

int BlockMatrix::find(int row, int column) const {
  const auto first = columns_.begin() + row_start_[static_cast<size_t>(row)];
  const auto last = columns_.begin() + row_start_[static_cast<size_t>(row) + 1];
  const auto found = std::lower_bound(first, last, column);
  return found != last && *found == column ? static_cast<int>(found - columns_.begin()) : -1;
}

Mat3& BlockMatrix::at(int row, int column) {
  const int index = find(row, column);
  if (index < 0)
    throw std::out_of_range("BlockMatrix: block (" + std::to_string(row) + ", " + std::to_string(column) +
                            ") is not in the pattern");
  return blocks_[static_cast<size_t>(index)];
}

Eigen::SparseMatrix<double> BlockMatrix::system(const Eigen::VectorXd& masses, const std::vector<std::uint8_t>& fixed,
                                                double mass_coefficient, double stiffness_coefficient) const {
  auto is_fixed = [&](int node) { return !fixed.empty() && fixed[static_cast<size_t>(node)] != 0; };
  // Column-major with both triangles: block column j is block row j (symmetry), each scalar
  // column 3j + c lists rows 3i + r in increasing order.
  Eigen::SparseMatrix<double> matrix(3 * nodes_, 3 * nodes_);
  std::vector<int> per_column(static_cast<size_t>(3 * nodes_));
  for (int j = 0; j < nodes_; ++j) {
    const int count = is_fixed(j) ? 1 : 3 * (row_start_[static_cast<size_t>(j) + 1] - row_start_[static_cast<size_t>(j)]);
    for (int c = 0; c < 3; ++c) per_column[static_cast<size_t>(3 * j + c)] = count;
  }
  matrix.reserve(per_column);
  for (int j = 0; j < nodes_; ++j) {
    for (int c = 0; c < 3; ++c) {
      const int column = 3 * j + c;
      if (is_fixed(j)) {
        matrix.insert(column, column) = 1.0;
        continue;
      }
      for (int k = row_start_[static_cast<size_t>(j)]; k < row_start_[static_cast<size_t>(j) + 1]; ++k) {
        const int i = columns_[static_cast<size_t>(k)];
        if (is_fixed(i)) continue;
        // Block (i, j) = block (j, i)^T: its column c is block (j, i)'s row c.
        const Mat3& block = blocks_[static_cast<size_t>(k)];
        for (int r = 0; r < 3; ++r) {
          double value = stiffness_coefficient * block(c, r);
          if (i == j && r == c) value += mass_coefficient * masses[j];
          matrix.insert(3 * i + r, column) = value;
        }
      }
    }
  }
  matrix.makeCompressed();
  return matrix;
}

}  // namespace incise::physics
