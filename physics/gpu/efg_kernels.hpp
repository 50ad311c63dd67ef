// GLSL sources of the EFG step's compute kernels (efg_step.hpp describes the algorithm).
#pragma once

#include <string>

namespace incise::physics::gpu {

// The work-group size of the kernels, and the groups of the reductions' first pass (each of
// its invocations sums a fixed stride, so sums do not depend on scheduling).
inline constexpr int kGroupSize = 64;
inline constexpr int kReduceGroups = 16;

enum class Kernel {
  element_stress,
  node_gather,
  diagonal,
  right_hand_side,
  scale_guess,
  residual_init,
  dot_partial,
  dot_final,
  cg_update,
  cg_direction,
  cg_check,
  integrate,
  surface,
  integration_points,
  element_rotation,
  count
};

// The full source of one kernel with `real` float or double.
std::string kernel_source(Kernel kernel, bool double_precision);
const char* kernel_name(Kernel kernel);

}  // namespace incise::physics::gpu
