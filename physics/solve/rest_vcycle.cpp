#include "physics/solve/rest_vcycle.hpp"

#include <stdexcept>

namespace incise::physics {

RestVcycle::RestVcycle(const RestFactor& factor, const std::vector<Eigen::Quaterniond>& rotations,
                       ChebyshevSmoother smoother, Executor& executor)
    : factor_(factor), rotations_(rotations), smoother_(smoother), executor_(executor), steps_(smoother) {
  if (factor_.smoothing_degree() <= 0) throw std::invalid_argument("RestVcycle: the factor is not a V-cycle's");
  if (smoother_.degree < 1 || !(smoother_.upper > 0) || !(smoother_.ratio > 1))
    throw std::invalid_argument("RestVcycle: the smoother needs a degree >= 1, upper > 0 and ratio > 1");
  if (smoother_.node_blocks) throw std::invalid_argument("RestVcycle: its smoother scales by A0's diagonal, not its node blocks");
  if (!rotations_.empty() && static_cast<int>(rotations_.size()) != factor_.size() / 3)
    throw std::invalid_argument("RestVcycle: one rotation per node");
}

void RestVcycle::smooth(Vector* output) {
  const BlockSystem& system = factor_.rest_system();
  const double* inverse_diagonal = factor_.rest_inverse_diagonal().data();
  const double* residual = residual_.data();
  double* step = step_.data();
  double* x = x_.data();
  const Eigen::Index size = residual_.size();
  const double theta = steps_.theta;
  // One pass per step, its branches outside the loops (they vectorise).
  auto pass = [&](auto next_step, bool add_to_x) {
    if (add_to_x) {
      for (Eigen::Index i = 0; i < size; ++i) {
        step[i] = next_step(i);
        x[i] += step[i];
      }
    } else {
      for (Eigen::Index i = 0; i < size; ++i) step[i] = next_step(i);
    }
  };
  const int degree = smoother_.degree;
  for (int k = 0; k < degree; ++k) {
    const bool add_to_x = !(k + 1 == degree && output);  // the last step of the post-smoothing goes to *output
    if (k == 0) {
      pass([&](Eigen::Index i) { return inverse_diagonal[i] * residual[i] / theta; }, add_to_x);
      continue;
    }
    system.subtract_product(step_, residual_, executor_);
    const double a = steps_.a[static_cast<size_t>(k)], b = steps_.b[static_cast<size_t>(k)];
    pass([&](Eigen::Index i) { return a * step[i] + b * (inverse_diagonal[i] * residual[i]); }, add_to_x);
  }
  if (!output) {
    system.subtract_product(step_, residual_, executor_);
    return;
  }
  const Eigen::Index nodes = size / 3;
  for (Eigen::Index node = 0; node < nodes; ++node) {
    const Vec3 rest = x_.segment<3>(3 * node) + step_.segment<3>(3 * node);
    output->segment<3>(3 * node) = rotations_.empty() ? rest : Vec3(rotations_[static_cast<size_t>(node)] * rest);
  }
}

void RestVcycle::operator()(const Vector& r, Vector& z) {
  const Eigen::Index size = r.size(), nodes = size / 3;
  if (size != factor_.size()) throw std::invalid_argument("RestVcycle: the vector's size is not the factor's");
  residual_.resize(size);
  step_.resize(size);
  x_.resize(size);
  z.resize(size);
  // R^T r with the fixed nodes zeroed; x starts at zero (the first step adds to it).
  const std::vector<std::uint8_t>& fixed = factor_.rest_fixed();
  for (Eigen::Index node = 0; node < nodes; ++node) {
    const bool is_fixed = !fixed.empty() && fixed[static_cast<size_t>(node)] != 0;
    const Vec3 turned = rotations_.empty() ? Vec3(r.segment<3>(3 * node))
                                           : Vec3(rotations_[static_cast<size_t>(node)].conjugate() * Vec3(r.segment<3>(3 * node)));
    residual_.segment<3>(3 * node) = is_fixed ? Vec3::Zero() : turned;
  }
  x_.setZero();
  smooth(nullptr);
  // The coarse correction, unwarped (the cycle is the rest system's).
  correction_ = residual_;
  factor_.solve(correction_);
  for (Eigen::Index node = 0; node < nodes; ++node)
    if (!fixed.empty() && fixed[static_cast<size_t>(node)] != 0) correction_.segment<3>(3 * node).setZero();
  x_ += correction_;
  factor_.rest_system().subtract_product(correction_, residual_, executor_);
  smooth(&z);
}

}  // namespace incise::physics
