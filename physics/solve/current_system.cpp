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
}

void CurrentSystem::multiply(const Vector& x, Vector& y, Executor& executor) const {
  y.resize(x.size());
  const std::vector<int>& start = stiffness_.row_start();
  const std::vector<int>& columns = stiffness_.columns();
  const std::vector<Mat3>& blocks = stiffness_.blocks();
  constexpr int rows_per_thread = 256;  // as BlockSystem::multiply
  executor.parallel_for(stiffness_.nodes(), [&](int begin, int end) {
    for (int row = begin; row < end; ++row) {
      const Eigen::Index offset = 3 * static_cast<Eigen::Index>(row);
      if (is_fixed(row)) {
        y.segment<3>(offset) = x.segment<3>(offset);
        continue;
      }
      Vec3 sum = Vec3::Zero();
      for (int k = start[static_cast<size_t>(row)]; k < start[static_cast<size_t>(row) + 1]; ++k) {
        const int column = columns[static_cast<size_t>(k)];
        if (is_fixed(column)) continue;
        sum.noalias() += blocks[static_cast<size_t>(k)] * x.segment<3>(3 * static_cast<Eigen::Index>(column));
      }
      if (!spring_blocks_.empty()) sum.noalias() += spring_blocks_[static_cast<size_t>(row)] * x.segment<3>(offset);
      y.segment<3>(offset) = mass_coefficient_ * masses_[row] * x.segment<3>(offset) + stiffness_coefficient_ * sum;
    }
  }, rows_per_thread);
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
    // Every diagonal block is in the pattern (BlockMatrix).
    Mat3 block = stiffness_.blocks()[static_cast<size_t>(
        std::lower_bound(stiffness_.columns().begin() + stiffness_.row_start()[static_cast<size_t>(row)],
                         stiffness_.columns().begin() + stiffness_.row_start()[static_cast<size_t>(row) + 1], row) -
        stiffness_.columns().begin())];
    if (!spring_blocks_.empty()) block += spring_blocks_[static_cast<size_t>(row)];
    out.segment<3>(offset) = Vec3::Constant(mass_coefficient_ * masses_[row]) + stiffness_coefficient_ * block.diagonal();
  }
  return out;
}

}  // namespace incise::physics
