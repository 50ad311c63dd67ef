#include "haptics/device.hpp"

namespace incise::haptics {

double quaternion_norm(const Quaternion& q) { return std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]); }

void require_finite_pose(const DevicePose& pose, const std::string& where) {
  for (int i = 0; i < 3; ++i) require_finite(pose.position[i], where + ".position[" + std::to_string(i) + "]");
  for (int i = 0; i < 4; ++i) require_finite(pose.orientation[i], where + ".orientation[" + std::to_string(i) + "]");
  const double n = quaternion_norm(pose.orientation);
  if (std::abs(n - 1) > kUnitQuaternionTolerance)
    throw std::invalid_argument(where + ".orientation is not a unit quaternion (|q| = " + std::to_string(n) + ")");
}

void validate_limits(const DeviceLimits& limits, const std::string& where) {
  for (int i = 0; i < 3; ++i) {
    require_finite(limits.workspace_min[i], where + ".workspace_min[" + std::to_string(i) + "]");
    require_finite(limits.workspace_max[i], where + ".workspace_max[" + std::to_string(i) + "]");
    if (!(limits.workspace_min[i] < limits.workspace_max[i]))
      throw std::invalid_argument(where + ": workspace_min[" + std::to_string(i) + "] is not < workspace_max[" +
                                  std::to_string(i) + "]");
  }
  require_finite(limits.max_force, where + ".max_force");
  if (!(limits.max_force >= 0)) throw std::invalid_argument(where + ".max_force is negative");
}

}  // namespace incise::haptics
