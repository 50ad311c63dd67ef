#include "engine/models/mass_spring_settings.hpp"

namespace incise::engine {

void read_mass_spring_settings(Reader& block, BodySpec& body) {
  MassSpringSettings settings;
  settings.damping_ratio = block.number("damping_ratio", false, 1, 0, 100, false);
  settings.corrections = block.boolean("corrections", false);
  body.settings = settings;
}

}  // namespace incise::engine
