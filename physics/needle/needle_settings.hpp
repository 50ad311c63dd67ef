// The needle's parameters (seed 002 §2.3; docs/scenes.md, "Needle"): its nodes, the sizes of its
// zones of influence, the tissue's intensities and the virtual particles' stiffness.
#pragma once

namespace incise::physics {

struct NeedleSettings {
  double length = 0.05;           // m, tip to hub along the shaft
  int nodes = 11;                 // aligned nodes, the tip the first, `length / (nodes - 1)` apart
  double cutting_radius = 0.003;  // m, the hemisphere ahead of the tip (the cutting / puncture zone)
  double friction_radius = 0.003; // m, each node's cylinder (its half-length: half the node spacing)
  double cutting_force = 0.1;     // k_c, N: the cutting intensity of an interior node
  double puncture_force = 0.5;    // k_c of the boundary nodes, N (puncture: seed §2.3)
  double friction_force = 0.02;   // k_f, N: the friction intensity per needle node
  double stick_stiffness = 200;   // N/m: the virtual tissue particle's pull on its needle node
  // Below this axial speed (m/s) the needle neither advances nor retracts: no cutting force.
  double rest_speed = 1e-6;
};

}  // namespace incise::physics
