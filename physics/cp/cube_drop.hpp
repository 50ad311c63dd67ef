// Dionne's falling cube (seed 000 §4.2, digest D3): a cube of 9 x 9 x 9 particles split into
// 2,560 tets (5 per cell), all constraints at k = 500, dropped under gravity onto the plane
// z = 0; the volume (the tets' signed sum) over its rest value is recorded once per frame. The
// thesis plots this per rendered frame for distance only, + area, + volume, + the stretch
// limiter, and gives no numbers (its units are unstated; density 1.0, Table 4.8). The
// parameters below are ours: a cube of side 8 (cells of 1), density 1, g = 9.81, its base 1
// above the floor, a frame every 1/60 of simulated time.
#pragma once

#include "physics/cp/cp_step.hpp"

#include <string>
#include <vector>

namespace incise::physics {

struct CubeDrop {
  double side = 8;
  int cells = 8;
  double density = 1;
  double stiffness = 500;  // k_D = k_A = k_V
  bool area = true, volume = true, limiter = true;
  double drop = 1;       // base above the floor at rest
  double gravity = 9.81;
  double damping = 0;    // relative-velocity dashpots, N s/m
  double dt = 1e-3;
  int steps_per_frame = 17;  // about 1/60 s
  int frames = 400;
};

struct CubeDropResult {
  std::vector<double> volume_ratio;  // per frame, frame 0 at rest
  std::vector<int> inverted;         // inverted tets per frame
  bool finite = true;
};

CubeDropResult run_cube_drop(const CubeDrop& drop);

}  // namespace incise::physics
