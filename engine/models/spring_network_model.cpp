// The classical mass-spring of Promayon's comparisons (physics/promayon/spring_network.hpp,
// seed 002 §1.2): one spring per pair of lattice neighbours, VN1 or Moore, stepped like the
// shape memory (the seed's explicit step, its volume control included). Settings block
// `spring_network`; it cannot be cut and runs on the CPU.
#include "engine/model_registry.hpp"
#include "engine/models/promayon_builder.hpp"
#include "engine/models/promayon_settings.hpp"

namespace incise::engine {

void register_spring_network_model(ModelRegistry& registry) {
  registry.add({.name = "spring_network",
                .summary = "the seed-002 mass-spring baseline, VN1 or Moore neighbourhood",
                .cuttable = false,
                .gpu = false,
                .node_name = "atom",
                .read_settings = read_spring_network_settings,
                .build = [](const BodySpec& spec, const SolverSpec& solver, const BodyShape& shape) {
                  return build_promayon_body(physics::PromayonKind::spring_network, spec, solver, shape);
                }});
}

}  // namespace incise::engine
