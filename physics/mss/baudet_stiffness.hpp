// Baudet's spring stiffnesses for one brick x0 x y0 x z0 in the configuration "12 edges + 4
// body diagonals" (seed 003, Fléchon §4.2-4.4 and Annexe A.2; digest seed-000-003.md B.1.3,
// whose reconstructions of the garbled printed formulas are used and cited below).
#pragma once

#include "physics/core/model.hpp"

#include <array>

namespace incise::physics {

struct BrickSprings {
  Vec3 edge = Vec3::Zero();  // k of each of the 4 edge springs along x, y, z, N/m
  double diagonal = 0;       // k of each of the 4 body diagonals, N/m
  // correction[i][j]: F_ij / F_i, the correction force along j per unit axial load along i
  // (0 on the diagonal). Fléchon applies 2 F_ij on each of the 8 nodes (digest B.1.3).
  Mat3 correction = Mat3::Zero();
};

// The stiffnesses from Young's modulus E and Poisson's ratio nu. No check of their sign: see
// brick_problem.
BrickSprings baudet_brick_springs(const Vec3& size, double youngs_modulus, double poisson_ratio);

// Longest over shortest edge of the brick.
double brick_aspect_ratio(const Vec3& size);

// Empty when every stiffness is positive; otherwise which one is not, and its value. Baudet's
// edge stiffness turns negative for elongated bricks (digest B.1.3's table: at nu = 0.3 a
// brick j = k stays positive only while i / j <= 1.543).
std::string brick_problem(const BrickSprings& springs);

}  // namespace incise::physics
