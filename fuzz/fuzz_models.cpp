// The built-in models as the scene fuzz target registers them: the names, capabilities and
// settings readers of engine/models/NAME_model.cpp, without the builders (which need physics/,
// not in the fuzz build). A model added to INCISE_MODELS (engine/CMakeLists.txt) is added here
// too, its settings reader in a file of its own like engine/models/efg_settings.cpp.
#include "engine/body.hpp"
#include "engine/body_builder.hpp"
#include "engine/model_registry.hpp"
#include "engine/models/constraint_particles_settings.hpp"
#include "engine/models/efg_settings.hpp"
#include "engine/models/mass_spring_settings.hpp"
#include "engine/models/promayon_settings.hpp"

#include <stdexcept>

namespace incise::engine {

namespace {

Body no_build(const BodySpec&, const SolverSpec&, const BodyShape&) {
  throw std::logic_error("the fuzz build reads scenes, it builds no body");
}

}  // namespace

void register_fuzz_models(ModelRegistry& registry) {
  registry.add({.name = "fem", .summary = "corotational linear tetrahedra", .read_settings = nullptr, .build = no_build});
  registry.add({.name = "efg",
                .summary = "meshless corotational element-free Galerkin",
                .cuttable = true,
                .gpu = true,
                .node_name = "particle",
                .read_settings = read_efg_settings,
                .build = no_build});
  registry.add({.name = "mass_spring",
                .summary = "Baudet's hexahedral mass-spring, springs from E and nu",
                .read_settings = read_mass_spring_settings,
                .build = no_build});
  registry.add({.name = "constraint_particles",
                .summary = "Dionne's particles held by distance, area and volume constraints, explicit + stretch limiter",
                .node_name = "particle",
                .read_settings = read_constraint_particles_settings,
                .build = no_build});
  registry.add({.name = "shape_memory",
                .summary = "Promayon's volumetric shape memory on a lattice, exact volume control",
                .node_name = "atom",
                .read_settings = read_shape_memory_settings,
                .build = no_build});
  registry.add({.name = "spring_network",
                .summary = "the seed-002 mass-spring baseline, VN1 or Moore neighbourhood",
                .node_name = "atom",
                .read_settings = read_spring_network_settings,
                .build = no_build});
}

}  // namespace incise::engine
