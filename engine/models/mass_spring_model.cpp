// Baudet's hexahedral mass-spring model (physics/mss/hex_mass_spring.hpp, seed 003): bricks of
// about `resolution` over the body's shape (a box generator meshed exactly, any other shape or
// mesh voxelised, the staircase kept: the formulas hold on bricks only), stepped by the shared
// implicit Euler + CG. Its settings block is `mass_spring`; it cannot be cut and runs on the CPU.
#include "engine/body_builder.hpp"
#include "engine/model_registry.hpp"
#include "engine/models/mass_spring_settings.hpp"
#include "physics/core/cg.hpp"
#include "physics/core/stopwatch.hpp"
#include "physics/mss/hex_mass_spring.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace incise::engine {

namespace {

// Static equilibrium under gravity with the rest-shape stiffness (small strain), by CG.
physics::Vector settle(physics::DeformableModel& model, const physics::BodyData& body) {
  if (std::none_of(body.fixed.begin(), body.fixed.end(), [](std::uint8_t f) { return f != 0; }))
    throw std::runtime_error("no node is fixed");
  model.update_rotations(model.rest_positions());
  physics::Vector diagonal = physics::Vector::Zero(body.gravity.size());
  model.add_stiffness_diagonal(diagonal);
  physics::Vector displacement = physics::Vector::Zero(body.gravity.size());
  physics::CgSettings settings;
  settings.tolerance = 1e-10;
  settings.max_iterations = static_cast<int>(std::min<Eigen::Index>(100000, body.gravity.size() * 4));
  const physics::LinearOperator apply = [&](const physics::Vector& p, physics::Vector& out) {
    out.setZero();
    model.add_stiffness_product(p, out);
  };
  const physics::CgResult result =
      physics::conjugate_gradient(apply, body.gravity, diagonal, body.fixed, displacement, settings);
  if (result.nonfinite || !displacement.allFinite()) throw std::runtime_error("the static solve gave non-finite values");
  return displacement;
}

Body build_mass_spring_body(const BodySpec& spec, const SolverSpec& solver, const BodyShape& shape) {
  Body result;
  auto model = body_model(spec, solver);
  model->rest_lo = shape.lo;
  model->rest_hi = shape.hi;
  physics::BodyData& body = result.data;
  const std::string where = "body '" + spec.name + "'";
  const auto settings = std::any_cast<MassSpringSettings>(spec.settings);
  physics::HexMesh mesh;
  try {
    physics::Stopwatch watch;
    mesh = hex_cells(spec, shape, "brick");
    physics::MassSpringMaterial material{spec.material.youngs_modulus, spec.material.poisson_ratio,
                                         spec.material.density, settings.damping_ratio, settings.corrections};
    body.mechanics = std::make_unique<physics::HexMassSpring>(mesh, material);
    result.build_ms.volume = watch.ms();
  } catch (const std::exception& e) {
    throw std::runtime_error(where + ": " + e.what());
  }
  model->elements = mesh.hexes.size();
  body.surface = physics::hex_boundary_triangles(mesh.hexes);
  index_surface(*model, body, static_cast<int>(mesh.rest.size() / 3));
  start_at_rest(body);
  fix_nodes(body, spec, body.mechanics->rest_positions());
  body.gravity = physics::gravity_forces(body.mechanics->lumped_masses(), model->gravity);
  settle_if_asked(result, solver, where, [&] { return settle(*body.mechanics, body); });
  result.model = std::move(model);
  return result;
}

}  // namespace

void register_mass_spring_model(ModelRegistry& registry) {
  registry.add({.name = "mass_spring",
                .summary = "Baudet's hexahedral mass-spring, springs from E and nu",
                .cuttable = false,
                .gpu = false,
                .node_name = "node",
                .read_settings = read_mass_spring_settings,
                .build = build_mass_spring_body});
}

}  // namespace incise::engine
