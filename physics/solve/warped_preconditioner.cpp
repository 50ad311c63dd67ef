#include "physics/solve/warped_preconditioner.hpp"

namespace incise::physics {

void NodeRotations::reset(int nodes) { sums_.assign(static_cast<size_t>(nodes), Eigen::Vector4d::Zero()); }

void NodeRotations::add(int node, const Eigen::Quaterniond& rotation, double weight) {
  accumulate(sums_[static_cast<size_t>(node)], rotation, weight);
}

void NodeRotations::finish(std::vector<Eigen::Quaterniond>& out) const {
  out.resize(sums_.size());
  for (size_t node = 0; node < sums_.size(); ++node) out[node] = normalised(sums_[node]);
}

void warped_solve(const RestFactor& factor, const std::vector<Eigen::Quaterniond>& rotations, const Vector& r,
                  Vector& z) {
  z = r;
  const Eigen::Index nodes = r.size() / 3;
  if (!rotations.empty()) {
    for (Eigen::Index node = 0; node < nodes; ++node)
      z.segment<3>(3 * node) = rotations[static_cast<size_t>(node)].conjugate() * Vec3(r.segment<3>(3 * node));
  }
  factor.solve(z);
  if (!rotations.empty()) {
    for (Eigen::Index node = 0; node < nodes; ++node)
      z.segment<3>(3 * node) = rotations[static_cast<size_t>(node)] * Vec3(z.segment<3>(3 * node));
  }
}

}  // namespace incise::physics
