// Promayon's volumetric shape memory (physics/promayon/shape_memory.hpp, seed 002 §1.4): atoms
// on a lattice filling the body's shape, the seed's explicit step (or implicit Euler) and, as an
// option of the body, the exact volume projection or its penalty. Settings block `shape_memory`;
// it cannot be cut and runs on the CPU.
#include "engine/model_registry.hpp"
#include "engine/models/promayon_builder.hpp"
#include "engine/models/promayon_settings.hpp"

namespace incise::engine {

void register_shape_memory_model(ModelRegistry& registry) {
  registry.add({.name = "shape_memory",
                .summary = "Promayon's volumetric shape memory on a lattice, exact volume control",
                .cuttable = false,
                .gpu = false,
                .node_name = "atom",
                .read_settings = read_shape_memory_settings,
                .build = [](const BodySpec& spec, const SolverSpec& solver, const BodyShape& shape) {
                  return build_promayon_body(physics::PromayonKind::shape_memory, spec, solver, shape);
                }});
}

}  // namespace incise::engine
