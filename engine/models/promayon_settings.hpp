// The settings blocks of Promayon's models (seed 002; physics/promayon/), `shape_memory` and
// `spring_network` (docs/scenes.md): one reader for both, in a file free of physics/ so that the
// scene fuzz target (fuzz/fuzz_models.cpp) reads the blocks as the product does.
#pragma once

#include "engine/scene.hpp"
#include "engine/scene_reader.hpp"

#include <string>
#include <utility>
#include <vector>

namespace incise::engine {

struct PromayonSettings {
  std::string neighbourhood = "vn1";  // vn1 | moore
  double stiffness = 0;               // k_e or k_r, N/m; 0: from E by the calibration
  double damping = 0;                 // k_a, N s/m per atom (the seed's -k_a v)
  double mass_damping = 0;            // alpha, 1/s: -alpha m v per atom
  double dashpot = 0;                 // spring_network only: N s/m on each spring
  std::string integrator = "explicit";       // explicit (the seed's step) | implicit (implicit Euler + steps 4-6)
  std::string scheme = "symplectic_euler";   // explicit_euler | symplectic_euler
  int substeps = 1;                          // explicit steps per solver.dt
  std::string volume = "none";               // none | exact | penalty
  double volume_stiffness = 0;               // k_V, N m (penalty)
  std::vector<std::pair<double, double>> volume_target;  // [time s, V0 m^3]; empty: the rest volume
};

// Reads a `shape_memory` block (dashpot refused) or a `spring_network` block into body.settings.
void read_shape_memory_settings(Reader& block, BodySpec& body);
void read_spring_network_settings(Reader& block, BodySpec& body);

}  // namespace incise::engine
