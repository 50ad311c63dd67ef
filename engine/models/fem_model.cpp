// The corotational linear tetrahedral model (physics/fem/corotational_fem.hpp): tetrahedra
// fill the body's shape (or are the body's tetrahedral mesh), its surface is their boundary. It takes no settings block, cannot be
// cut and runs on the CPU only.
#include "engine/body_builder.hpp"
#include "engine/model_registry.hpp"
#include "physics/core/stopwatch.hpp"
#include "physics/fem/corotational_fem.hpp"
#include "physics/fem/static_solve.hpp"

#include <stdexcept>
#include <string>
#include <vector>

namespace incise::engine {

namespace {

Body build_fem_body(const BodySpec& spec, const SolverSpec& solver, const BodyShape& shape) {
  Body result;
  auto model = body_model(spec, solver);
  physics::BodyData& body = result.data;
  const std::string where = "body '" + spec.name + "'";
  physics::TetMesh mesh;
  physics::Stopwatch watch;
  try {
    mesh = fill_with_tets(spec, shape, spec.resolution, &model->snap);
    result.build_ms.volume = watch.ms();
  } catch (const std::exception& e) {
    throw std::runtime_error(where + ": " + e.what());
  }
  model->elements = mesh.tets.size();
  physics::Material material{spec.material.youngs_modulus, spec.material.poisson_ratio,
                             spec.material.density};
  body.surface = physics::boundary_triangles(mesh.tets);
  body.mechanics = std::make_unique<physics::CorotationalTetFem>(mesh, material);
  const int n = body.mechanics->node_count();
  start_at_rest(body);
  fix_nodes(body, spec, body.mechanics->rest_positions());
  body.gravity = physics::gravity_forces(body.mechanics->lumped_masses(), model->gravity);
  // Static equilibrium under gravity by a small-strain solve: exact enough for the sag of a
  // supported organ.
  settle_if_asked(result, solver, where, [&] {
    return physics::solve_static_linear(mesh, material, body.fixed, spec.material.density * model->gravity);
  });
  std::vector<int> surface_index(n, -1);
  for (const auto& t : body.surface)
    for (int v : t) surface_index[v] = 0;
  for (int i = 0; i < n; ++i)
    if (surface_index[i] == 0) {
      surface_index[i] = static_cast<int>(model->surface_nodes.size());
      model->surface_nodes.push_back(i);
    }
  body.render_triangles.reserve(body.surface.size() * 3);
  for (const auto& t : body.surface)
    for (int v : t) body.render_triangles.push_back(static_cast<std::uint32_t>(surface_index[v]));
  result.model = std::move(model);
  return result;
}

}  // namespace

void register_fem_model(ModelRegistry& registry) {
  registry.add({.name = "fem",
                .summary = "corotational linear tetrahedra",
                .cuttable = false,
                .gpu = false,
                .node_name = "node",
                .read_settings = nullptr,
                .build = build_fem_body});
}

}  // namespace incise::engine
