// The mass-spring model's settings block, `mass_spring` (docs/scenes.md): its own file, free of
// physics/, so that the scene fuzz target (fuzz/fuzz_models.cpp) reads the block as the
// product does.
#pragma once

#include "engine/scene.hpp"
#include "engine/scene_reader.hpp"

namespace incise::engine {

struct MassSpringSettings {
  double damping_ratio = 1;  // each spring's dashpot over its critical 2 sqrt(m k)
  bool corrections = false;  // Baudet's correction forces (HexMassSpring::add_correction_forces)
};

// Reads the block into body.settings (a MassSpringSettings).
void read_mass_spring_settings(Reader& block, BodySpec& body);

}  // namespace incise::engine
