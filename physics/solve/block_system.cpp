#include "physics/solve/block_system.hpp"

#include "physics/solve/block_product.hpp"

#include <stdexcept>

namespace incise::physics {

BlockSystem::BlockSystem(const BlockMatrix& stiffness, const Eigen::VectorXd& masses, const std::vector<std::uint8_t>& fixed,
                         double mass_coefficient, double stiffness_coefficient, bool single) {
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
  std::vector<Mat3> kept;
  kept.reserve(blocks.size());
  for (int row = 0; row < nodes; ++row) {
    if (is_fixed(row)) {
      columns_.push_back(row);
      kept.push_back(Mat3::Identity());
    } else {
      for (int k = start[static_cast<size_t>(row)]; k < start[static_cast<size_t>(row) + 1]; ++k) {
        const int column = columns[static_cast<size_t>(k)];
        if (is_fixed(column)) continue;
        Mat3 block = stiffness_coefficient * blocks[static_cast<size_t>(k)];
        if (column == row) block.diagonal().array() += mass_coefficient * masses[row];
        columns_.push_back(column);
        kept.push_back(block);
      }
    }
    row_start_.push_back(static_cast<int>(columns_.size()));
  }
  auto store = [&](auto& out) {
    out.assign(9 * kept.size() + 1, 0);
    for (size_t k = 0; k < kept.size(); ++k) store_lane_order(kept[k], out.data() + 9 * k);
  };
  if (single)
    store(single_blocks_);
  else
    store(blocks_);
}

void BlockSystem::rows(const Eigen::VectorXd& x, Eigen::VectorXd& y, Executor& executor, bool subtract) const {
  const BlockRows block_rows{row_start_.data(), columns_.data()};
  // Rows per range: a few hundred rows are a few microseconds, below which a thread hand-off
  // costs more than it saves.
  constexpr int rows_per_thread = 256;
  executor.parallel_for(nodes(), [&](int begin, int end) {
    if (single())
      block_rows_product(block_rows, single_blocks_.data(), x.data(), y.data(), begin, end, subtract);
    else
      block_rows_product(block_rows, blocks_.data(), x.data(), y.data(), begin, end, subtract);
  }, rows_per_thread);
}

void BlockSystem::multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y, Executor& executor) const {
  y.resize(x.size());
  rows(x, y, executor, false);
}

void BlockSystem::subtract_product(const Eigen::VectorXd& x, Eigen::VectorXd& residual, Executor& executor) const {
  if (residual.size() != x.size()) throw std::invalid_argument("BlockSystem::subtract_product: sizes differ");
  rows(x, residual, executor, true);
}

Mat3 BlockSystem::block(int k) const {
  return single() ? load_lane_order(single_blocks_.data() + 9 * static_cast<size_t>(k))
                  : load_lane_order(blocks_.data() + 9 * static_cast<size_t>(k));
}

Eigen::VectorXd BlockSystem::diagonal() const {
  Eigen::VectorXd out = Eigen::VectorXd::Zero(3 * static_cast<Eigen::Index>(nodes()));
  for (int row = 0; row < nodes(); ++row)
    for (int k = row_start_[static_cast<size_t>(row)]; k < row_start_[static_cast<size_t>(row) + 1]; ++k)
      if (columns_[static_cast<size_t>(k)] == row) out.segment<3>(3 * static_cast<Eigen::Index>(row)) = block(k).diagonal();
  return out;
}

std::vector<Mat3> BlockSystem::diagonal_blocks() const {
  std::vector<Mat3> out(static_cast<size_t>(nodes()), Mat3::Zero());
  for (int row = 0; row < nodes(); ++row)
    for (int k = row_start_[static_cast<size_t>(row)]; k < row_start_[static_cast<size_t>(row) + 1]; ++k)
      if (columns_[static_cast<size_t>(k)] == row) out[static_cast<size_t>(row)] = block(k);
  return out;
}

void BlockSystem::round_to_single() {
  if (single()) return;
  // Lane order is a permutation of each block's entries, so rounding entry by entry rounds as
  // store_lane_order does from the blocks; the padding scalar stays zero.
  single_blocks_.assign(blocks_.begin(), blocks_.end());
  std::vector<double>().swap(blocks_);
}

}  // namespace incise::physics
