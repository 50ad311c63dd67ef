#include "engine/models/promayon_builder.hpp"

#include "engine/models/promayon_settings.hpp"
#include "physics/core/stopwatch.hpp"
#include "physics/promayon/lattice.hpp"
#include "physics/promayon/promayon_body.hpp"
#include "physics/promayon/shape_memory.hpp"
#include "physics/promayon/spring_network.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace incise::engine {

namespace {

std::unique_ptr<physics::DeformableModel> force_model(physics::PromayonKind kind, const BodySpec& spec,
                                                      const PromayonSettings& s, const physics::HexMesh& mesh) {
  const physics::Neighbourhood n = *physics::neighbourhood_from_name(s.neighbourhood);
  const double spacing = physics::hex_edge_lengths(mesh.rest, mesh.hexes.front()).mean();
  const double k = s.stiffness > 0 ? s.stiffness
                                   : physics::stiffness_from_youngs_modulus(kind, n, spec.material.youngs_modulus, spacing);
  const auto neighbours = physics::lattice_neighbours(mesh, n);
  const physics::Vector masses = physics::lattice_masses(mesh, spec.material.density);
  if (kind == physics::PromayonKind::shape_memory)
    return std::make_unique<physics::ShapeMemory>(mesh.rest, neighbours, masses, k, spacing);
  return std::make_unique<physics::SpringNetwork>(mesh.rest, neighbours, masses, k, s.dashpot, spacing);
}

std::optional<physics::VolumeControl> volume_control(const PromayonSettings& s, const physics::BodyData& body,
                                                     const physics::Vector& rest) {
  if (s.volume == "none") return std::nullopt;
  physics::VolumeControl v;
  v.triangles = body.surface;
  v.mode = s.volume == "exact" ? physics::VolumeMode::exact : physics::VolumeMode::penalty;
  v.penalty_stiffness = s.volume_stiffness;
  v.rest_volume = physics::closed_volume(rest, v.triangles);
  v.target = s.volume_target;
  if (!(v.rest_volume > 0)) throw std::runtime_error("the lattice's surface encloses no volume");
  return v;
}

}  // namespace

Body build_promayon_body(physics::PromayonKind kind, const BodySpec& spec, const SolverSpec& solver, const BodyShape& shape) {
  Body result;
  auto model = body_model(spec, solver);
  model->rest_lo = shape.lo;
  model->rest_hi = shape.hi;
  physics::BodyData& body = result.data;
  const std::string where = "body '" + spec.name + "'";
  const auto settings = std::any_cast<PromayonSettings>(spec.settings);
  try {
    physics::Stopwatch watch;
    const physics::HexMesh mesh = hex_cells(spec, shape, "lattice cell");
    auto forces = force_model(kind, spec, settings, mesh);
    model->elements = mesh.hexes.size();
    body.surface = physics::hex_boundary_triangles(mesh.hexes);
    index_surface(*model, body, static_cast<int>(mesh.rest.size() / 3));
    physics::PromayonStepping stepping;
    stepping.implicit = settings.integrator == "implicit";
    stepping.substeps = settings.substeps;
    stepping.damping = settings.damping;
    stepping.mass_damping = settings.mass_damping;
    stepping.scheme = *physics::seed_scheme_from_name(settings.scheme);
    body.mechanics = std::make_unique<physics::PromayonBody>(std::move(forces), stepping,
                                                             volume_control(settings, body, mesh.rest));
    // The seed's step, not implicit Euler (physics/promayon/seed_step.hpp).
    model->own_step = [](physics::DeformableModel& mechanics, physics::State& state, const std::vector<std::uint8_t>& fixed,
                         const physics::Vector& external, const std::vector<physics::NodalSpring>& springs,
                         const physics::ImplicitEulerSettings& given, double start_time) {
      return dynamic_cast<physics::PromayonBody&>(mechanics).step(state, fixed, external, springs, given, start_time);
    };
    result.build_ms.volume = watch.ms();
  } catch (const std::exception& e) {
    throw std::runtime_error(where + ": " + e.what());
  }
  start_at_rest(body);
  fix_nodes(body, spec, body.mechanics->rest_positions());
  body.gravity = physics::gravity_forces(body.mechanics->lumped_masses(), model->gravity);
  if (settings.integrator == "explicit" && settings.scheme == "symplectic_euler") {
    // The explicit step's bound, estimated at rest (seed_step_limit): a dt beyond it blows up.
    const double limit = physics::seed_step_limit(*body.mechanics, body.fixed);
    const double dt = solver.dt / settings.substeps;
    if (dt > limit) {
      std::ostringstream out;
      out << where << ": " << model->kind << ".substeps: solver.dt / substeps = " << dt
          << " s is beyond the explicit step's limit " << limit << " s (2 / omega_max at rest); substeps "
          << static_cast<int>(std::ceil(solver.dt / limit)) << " or more would do";
      throw std::runtime_error(out.str());
    }
  }
  settle_if_asked(result, solver, where, []() -> physics::Vector {
    throw std::runtime_error("Promayon's models have no static settle (their step is explicit): use solver.start \"rest\"");
  });
  result.model = std::move(model);
  return result;
}

}  // namespace incise::engine
