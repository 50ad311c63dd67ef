#include "physics/solve/jacobi_scaling.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include <cmath>
#include <stdexcept>

namespace incise::physics {

namespace {

// The block's two triangles made one (the upper's), as the paired copy makes them: K's
// diagonal blocks differ across by an ulp.
Mat3 symmetric(const Mat3& block) {
  Mat3 out = block;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < i; ++j) out(i, j) = out(j, i);
  return out;
}

// A block that is not finite and positive definite (Sylvester's minors) falls back to its
// diagonal's inverse, as jacobi_inverse does (1 where an entry is not a positive number): the
// scaling stays positive and CG's own product reports what is wrong with the system.
Mat3 inverse_block(const Mat3& given) {
  const Mat3 block = symmetric(given);
  const double minor = block(0, 0) * block(1, 1) - block(0, 1) * block(1, 0);
  const double determinant = block.determinant();
  if (std::isfinite(determinant) && block(0, 0) > 0 && minor > 0 && determinant > 0) return symmetric(block.inverse());
  Mat3 fallback = Mat3::Zero();
  for (int a = 0; a < 3; ++a) {
    const double d = block(a, a);
    fallback(a, a) = d > 0.0 && std::isfinite(d) ? 1.0 / d : 1.0;
  }
  return fallback;
}

}  // namespace

JacobiScaling JacobiScaling::node_blocks(const std::vector<Mat3>& blocks, Executor& executor) {
  JacobiScaling out;
  out.inverse_blocks_.resize(blocks.size());
  executor.parallel_for(static_cast<int>(blocks.size()), [&](int begin, int end) {
    for (auto node = static_cast<std::size_t>(begin); node < static_cast<std::size_t>(end); ++node)
      out.inverse_blocks_[node] = inverse_block(blocks[node]);
  }, 512);
  return out;
}

Mat3 inverse_square_root(const Mat3& block) {
  const Eigen::SelfAdjointEigenSolver<Mat3> eigen(symmetric(block));
  const Vec3 values = eigen.eigenvalues();
  if (eigen.info() != Eigen::Success || !(values.minCoeff() > 0))
    throw std::runtime_error("inverse_square_root: the block is not positive definite");
  return eigen.eigenvectors() * values.cwiseSqrt().cwiseInverse().asDiagonal() * eigen.eigenvectors().transpose();
}

}  // namespace incise::physics
