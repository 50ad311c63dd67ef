#include "physics/solve/current_system.hpp"

#include <algorithm>
#include <stdexcept>

namespace incise::physics {

CurrentSystem::CurrentSystem(const BlockMatrix& stiffness, const Vector& masses, const std::vector<std::uint8_t>& fixed,
                             std::span<const NodalSpring> springs, double mass_coefficient, double stiffness_coefficient)
    : stiffness_(stiffness),
      masses_(masses),
      fixed_(fixed),
      mass_coefficient_(mass_coefficient),
      stiffness_coefficient_(stiffness_coefficient) {
  const int nodes = stiffness.nodes();
  if (masses.size() != nodes || (!fixed.empty() && static_cast<int>(fixed.size()) != nodes))
    throw std::invalid_argument("CurrentSystem: masses and fixed need one entry per node");
  if (!springs.empty()) {
    spring_blocks_.assign(static_cast<size_t>(nodes), Mat3::Zero());
    for (const NodalSpring& spring : springs) spring_blocks_[static_cast<size_t>(spring.node)] += spring.stiffness;
  }
  for (int node = 0; node < static_cast<int>(fixed.size()); ++node)
    if (fixed[static_cast<size_t>(node)] != 0) fixed_nodes_.push_back(node);
}

namespace {

constexpr int rows_per_thread = 256;  // as BlockSystem::multiply
// multiply_several's rows at a time: about 25 KB of the lobe's blocks (~21 a row), read from memory by the
// first vector's product and from the caches by the others'.
constexpr int rows_together = 16;

}  // namespace

const double* CurrentSystem::free_entries(const Vector& x, Vector& zeroed) const {
  if (x.size() != 3 * static_cast<Eigen::Index>(stiffness_.nodes()))
    throw std::invalid_argument("CurrentSystem::multiply: x needs 3 entries per node");
  // The kernel sums over fixed columns too, so it reads x zeroed on the fixed nodes
  // (current_product.hpp); CG's vectors already are.
  for (const int node : fixed_nodes_) {
    if ((x.segment<3>(3 * static_cast<Eigen::Index>(node)).array() != 0.0).any()) {  // (NaN included)
      zeroed = x;
      for (const int fixed : fixed_nodes_) zeroed.segment<3>(3 * static_cast<Eigen::Index>(fixed)).setZero();
      return zeroed.data();
    }
  }
  return x.data();
}

void CurrentSystem::multiply(const Vector& x, Vector& y, Executor& executor) const {
  Vector zeroed;
  const double* free_x = free_entries(x, zeroed);
  y.resize(x.size());
  const CurrentRows rows = this->rows();
  executor.parallel_for(stiffness_.nodes(), [&](int begin, int end) {
    current_rows_product(rows, x.data(), free_x, y.data(), begin, end);
  }, rows_per_thread);
}

void CurrentSystem::multiply_several(std::span<const Vector> x, std::span<Vector> y, Executor& executor) const {
  if (x.size() != y.size()) throw std::invalid_argument("CurrentSystem::multiply_several: as many products as vectors");
  std::vector<Vector> zeroed(x.size());
  std::vector<const double*> free_x(x.size());
  for (size_t k = 0; k < x.size(); ++k) {
    free_x[k] = free_entries(x[k], zeroed[k]);
    y[k].resize(x[k].size());
  }
  const CurrentRows rows = this->rows();
  executor.parallel_for(stiffness_.nodes(), [&](int begin, int end) {
    for (int first = begin; first < end; first += rows_together) {
      const int last = std::min(end, first + rows_together);
      for (size_t k = 0; k < x.size(); ++k) current_rows_product(rows, x[k].data(), free_x[k], y[k].data(), first, last);
    }
  }, rows_per_thread);
}

CurrentRows CurrentSystem::rows() const {
  CurrentRows rows;
  rows.blocks = stiffness_.block_count();
  rows.row_start = stiffness_.row_start().data();
  rows.columns = stiffness_.columns().data();
  rows.stiffness = stiffness_.blocks().empty() ? nullptr : stiffness_.blocks().front().data();
  rows.masses = masses_.data();
  rows.fixed = fixed_.empty() ? nullptr : fixed_.data();
  rows.springs = spring_blocks_.empty() ? nullptr : spring_blocks_.front().data();
  rows.mass_coefficient = mass_coefficient_;
  rows.stiffness_coefficient = stiffness_coefficient_;
  return rows;
}

void CurrentSystem::multiply_rows(const double* x, double* y, int begin, int end) const {
  current_rows_product(rows(), x, x, y, begin, end);
}

Mat3 CurrentSystem::free_diagonal_block(int row) const {
  // Every diagonal block is in the pattern (BlockMatrix).
  Mat3 block = stiffness_.blocks()[static_cast<size_t>(
      std::lower_bound(stiffness_.columns().begin() + stiffness_.row_start()[static_cast<size_t>(row)],
                       stiffness_.columns().begin() + stiffness_.row_start()[static_cast<size_t>(row) + 1], row) -
      stiffness_.columns().begin())];
  if (!spring_blocks_.empty()) block += spring_blocks_[static_cast<size_t>(row)];
  return block;
}

Vector CurrentSystem::diagonal() const {
  const int nodes = stiffness_.nodes();
  Vector out(3 * static_cast<Eigen::Index>(nodes));
  for (int row = 0; row < nodes; ++row) {
    const Eigen::Index offset = 3 * static_cast<Eigen::Index>(row);
    if (is_fixed(row)) {
      out.segment<3>(offset).setOnes();
      continue;
    }
    out.segment<3>(offset) = Vec3::Constant(mass_coefficient_ * masses_[row]) + stiffness_coefficient_ * free_diagonal_block(row).diagonal();
  }
  return out;
}

std::vector<Mat3> CurrentSystem::diagonal_blocks(Executor& executor) const {
  const int nodes = stiffness_.nodes();
  std::vector<Mat3> out(static_cast<size_t>(nodes));
  executor.parallel_for(nodes, [&](int begin, int end) {
    for (int row = begin; row < end; ++row) {
      Mat3& block = out[static_cast<size_t>(row)];
      if (is_fixed(row)) {
        block.setIdentity();
        continue;
      }
      // Entry by entry as diagonal() computes the diagonal's: the same bits there.
      const Mat3 stiffness = free_diagonal_block(row);
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
          block(a, b) = (a == b ? mass_coefficient_ * masses_[row] : 0.0) + stiffness_coefficient_ * stiffness(a, b);
    }
  }, 512);
  return out;
}

}  // namespace incise::physics
