// The rest-shape factor warped by the current rotations (SOFA's WarpPreconditioner;
// Courtecuisse et al. 2010): with R the block diagonal of per-node rotations,
//   P^-1 r = R A0^-1 R^T r,
// exact for a body that has turned rigidly, and close while the rotations vary slowly across
// it. Any SPD approximation is a valid CG preconditioner, so a factor of the body before a cut
// still preconditions it after (less well) until the new one is in.
#pragma once

#include "physics/core/model.hpp"
#include "physics/solve/rest_factor.hpp"

#include <Eigen/Geometry>

#include <vector>

namespace incise::physics {

// Per node, the weighted mean of the rotations of the elements around it: quaternions, each
// turned into the hemisphere of the node's running sum (q and -q are one rotation), added with
// its weight and normalised. Deterministic: the elements are added in the caller's order.
class NodeRotations {
 public:
  void reset(int nodes);
  void add(int node, const Eigen::Quaterniond& rotation, double weight);
  // Normalises the sums (a node nothing reached gets the identity) into `out`.
  void finish(std::vector<Eigen::Quaterniond>& out) const;
  // One node's sum and its normalisation, as add and finish do them: a caller that sums each
  // node's rotations apart (in the same order) gets the same bits.
  static void accumulate(Eigen::Vector4d& sum, const Eigen::Quaterniond& rotation, double weight) {
    const Eigen::Vector4d q = rotation.coeffs();
    sum += (sum.dot(q) < 0 ? -weight : weight) * q;
  }
  static Eigen::Quaterniond normalised(const Eigen::Vector4d& sum) {
    const double norm = sum.norm();
    return norm > 0 ? Eigen::Quaterniond(Eigen::Vector4d(sum / norm)) : Eigen::Quaterniond::Identity();
  }

 private:
  std::vector<Eigen::Vector4d> sums_;
};

// z = R A0^-1 R^T r. `rotations` has one unit quaternion per node (empty: the identity).
void warped_solve(const RestFactor& factor, const std::vector<Eigen::Quaterniond>& rotations, const Vector& r,
                  Vector& z);

}  // namespace incise::physics
