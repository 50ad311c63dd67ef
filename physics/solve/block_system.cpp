#include "physics/solve/block_system.hpp"

#include <stdexcept>

namespace incise::physics {

BlockSystem::BlockSystem(const BlockMatrix& stiffness, const Eigen::VectorXd& masses, const std::vector<std::uint8_t>& fixed,
                         double mass_coefficient, double stiffness_coefficient) {
  const int nodes = stiffness.nodes();
  if (masses.size() != nodes || (!fixed.empty() && static_cast<int>(fixed.size()) != nodes))
    throw std::invalid_argument("BlockSystem: masses and fixed need one entry per node");
  auto is_fixed = [&](int node) { return !fixed.empty() && fixed[static_cast<size_t>(node)] != 0; };
  const std::vector<int>& start = stiffness.row_start();
  const std::vector<int>& columns = stiffness.columns();
  const std::vector<Mat3>& blocks = stiffness.blocks();
  row_start_.assign(1, 0);
  row_start_.reserve(static_cast<size_t>(nodes) + 1);
  columns_.reserve(columns.size());
  blocks_.reserve(blocks.size());
  for (int row = 0; row < nodes; ++row) {
    if (is_fixed(row)) {
      columns_.push_back(row);
      blocks_.push_back(Mat3::Identity());
    } else {
      for (int k = start[static_cast<size_t>(row)]; k < start[static_cast<size_t>(row) + 1]; ++k) {
        const int column = columns[static_cast<size_t>(k)];
        if (is_fixed(column)) continue;
        Mat3 block = stiffness_coefficient * blocks[static_cast<size_t>(k)];
        if (column == row) block.diagonal().array() += mass_coefficient * masses[row];
        columns_.push_back(column);
        blocks_.push_back(block);
      }
    }
    row_start_.push_back(static_cast<int>(columns_.size()));
  }
}

void BlockSystem::multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y, Executor& executor) const {
  y.resize(x.size());
  // Rows per range: a few hundred rows are a few microseconds, below which a thread hand-off
  // costs more than it saves.
  constexpr int rows_per_thread = 256;
  executor.parallel_for(nodes(), [&](int begin, int end) {
    for (int row = begin; row < end; ++row) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int k = row_start_[static_cast<size_t>(row)]; k < row_start_[static_cast<size_t>(row) + 1]; ++k)
        sum.noalias() += blocks_[static_cast<size_t>(k)] * x.segment<3>(3 * static_cast<Eigen::Index>(columns_[static_cast<size_t>(k)]));
      y.segment<3>(3 * static_cast<Eigen::Index>(row)) = sum;
    }
  }, rows_per_thread);
}

Eigen::VectorXd BlockSystem::diagonal() const {
  Eigen::VectorXd out = Eigen::VectorXd::Zero(3 * static_cast<Eigen::Index>(nodes()));
  for (int row = 0; row < nodes(); ++row)
    for (int k = row_start_[static_cast<size_t>(row)]; k < row_start_[static_cast<size_t>(row) + 1]; ++k)
      if (columns_[static_cast<size_t>(k)] == row) out.segment<3>(3 * static_cast<Eigen::Index>(row)) = blocks_[static_cast<size_t>(k)].diagonal();
  return out;
}

}  // namespace incise::physics
