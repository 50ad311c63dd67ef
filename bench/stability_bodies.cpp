// The stability sweep's cases: a body per model, case and material (bench/stability.cpp says
// what each case is).
#include "bench/stability_sweep.hpp"

#include "engine/model_registry.hpp"

#include "physics/cp/cp_step.hpp"
#include "physics/fem/corotational_fem.hpp"
#include "physics/fem/tet_mesh.hpp"
#include "physics/mss/hex_mass_spring.hpp"
#include "physics/mss/hex_mesh.hpp"
#include "physics/promayon/calibration.hpp"
#include "physics/promayon/lattice.hpp"
#include "physics/promayon/shape_memory.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <array>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace incise::bench::sweep {

using physics::CorotationalTetFem;
using physics::TetMesh;

// ---- Cases -------------------------------------------------------------------------------

bool is_beam(const std::string& case_name) { return case_name == "beam_gravity"; }
// The cases that cut, which only the models registered as cuttable run.
bool is_cut_case(const std::string& case_name) {
  return case_name == "fast_blade" || case_name == "thin_slice";
}
bool model_runs_case(const std::string& model_name, const std::string& case_name) {
  const engine::ModelEntry* model = engine::models().find(model_name);
  return !is_cut_case(case_name) || (model && model->cuttable);
}

Vec3 case_min(const std::string& case_name) {
  return is_beam(case_name) ? Vec3(0, -beam_half_side, -beam_half_side) : Vec3::Zero();
}
Vec3 case_max(const std::string& case_name) {
  return is_beam(case_name) ? Vec3(beam_length, beam_half_side, beam_half_side)
                            : Vec3::Constant(cube_side);
}

// Beam and thin_slice: clamped at x = 0; the other cubes: clamped at z = 0.
std::vector<uint8_t> clamped_nodes(const std::string& case_name, const Vector& rest) {
  if (is_beam(case_name) || case_name == "thin_slice") return physics::nodes_in_box(rest, Vec3::Constant(-1), Vec3(1e-9, 1, 1));
  return physics::nodes_in_box(rest, Vec3::Constant(-1), Vec3(1, 1, 1e-9));
}

// The nodes flipped by inverted_start: top-face nodes away from the cube's sides, three of
// them spread over the face (at a quarter, half and three quarters of their index order).
std::vector<int> nodes_to_flip(const Vector& rest) {
  std::vector<int> top;
  constexpr double tolerance = 1e-9;
  for (Index node = 0; node < rest.size() / 3; ++node) {
    const Vec3 x = rest.segment<3>(3 * node);
    const bool on_top = x.z() > cube_side - tolerance;
    const bool inside_face = x.x() > tolerance && x.x() < cube_side - tolerance &&
                             x.y() > tolerance && x.y() < cube_side - tolerance;
    if (on_top && inside_face) top.push_back(static_cast<int>(node));
  }
  std::vector<int> chosen;
  if (top.empty()) return chosen;
  for (int k = 1; k <= flipped_nodes; ++k) {
    const int node = top[static_cast<size_t>(k * top.size() / (flipped_nodes + 1))];
    if (std::find(chosen.begin(), chosen.end(), node) == chosen.end()) chosen.push_back(node);
  }
  return chosen;
}

double signed_volume(const Vector& x, const std::array<int, 4>& tet) {
  const Vec3 a = x.segment<3>(3 * tet[0]);
  Eigen::Matrix3d edges;
  edges << x.segment<3>(3 * tet[1]) - a, x.segment<3>(3 * tet[2]) - a, x.segment<3>(3 * tet[3]) - a;
  return edges.determinant() / 6.0;
}

void squeeze_heights(Vector& positions) {
  for (Index node = 0; node < positions.size() / 3; ++node) positions[3 * node + 2] *= squeeze;
}

// Common completion: state at rest, gravity, size.
// Particles a cut left with no element (EFG orphans) carry no stiffness: fixed, as the engine
// pins them (engine/world.cpp), else they would fall away under gravity as if the body had
// diverged.
void pin_orphans(Body& body, State* state) {
  if (!body.efg) return;
  for (int p : body.efg->orphaned_particles()) {
    body.fixed[static_cast<size_t>(p)] = 1;
    if (state) state->velocities.segment<3>(3 * static_cast<Index>(p)).setZero();
  }
}

void finish_body(Body& body, const std::string& case_name) {
  const Vector& rest = body.model->rest_positions();
  if (body.initial.positions.size() == 0) body.initial.positions = rest;
  body.initial.velocities = Vector::Zero(rest.size());
  body.fixed = clamped_nodes(case_name, rest);
  pin_orphans(body);
  body.external = physics::gravity_forces(body.model->lumped_masses(), gravity);
  body.size = (case_max(case_name) - case_min(case_name)).maxCoeff();
}

Body make_fem_body(const std::string& case_name, const Material& material) {
  const std::array<int, 3> cells = is_beam(case_name) ? std::array<int, 3>{10, 2, 2}
                                                      : std::array<int, 3>{4, 4, 4};
  const TetMesh mesh = physics::make_box_tets(case_min(case_name), case_max(case_name), cells);
  Body body;
  auto model = std::make_unique<CorotationalTetFem>(mesh, material);
  Vector positions = mesh.rest;
  if (case_name == "compression_release") squeeze_heights(positions);
  if (case_name == "inverted_start") {
    for (int node : nodes_to_flip(mesh.rest)) {
      // The first tetrahedron that holds the node; reflecting the node through the plane of
      // the opposite face negates that tetrahedron's signed volume.
      for (const auto& tet : mesh.tets) {
        const auto corner = std::find(tet.begin(), tet.end(), node);
        if (corner == tet.end()) continue;
        std::array<Vec3, 3> face;
        int k = 0;
        for (int other : tet) {
          if (other != node) face[static_cast<size_t>(k++)] = positions.segment<3>(3 * other);
        }
        const Vec3 normal = (face[1] - face[0]).cross(face[2] - face[0]).normalized();
        const Vec3 x = positions.segment<3>(3 * node);
        positions.segment<3>(3 * node) = x - 2.0 * (x - face[0]).dot(normal) * normal;
        break;
      }
    }
    body.count_inverted = [tets = mesh.tets](const Vector& x) {
      int inverted = 0;
      for (const auto& tet : tets) inverted += signed_volume(x, tet) < 0 ? 1 : 0;
      return inverted;
    };
    body.inverted = body.count_inverted(positions);
  }
  body.initial.positions = positions;
  body.model = std::move(model);
  finish_body(body, case_name);
  return body;
}

// The fast_blade edge at time t.
std::vector<Vec3> fast_blade_pose(double t) {
  const double x = blade_start_x + blade_speed * t;
  return {Vec3(x, fast_blade_y, fast_blade_top), Vec3(x, fast_blade_y, fast_blade_bottom)};
}

std::string count_pieces(const physics::VolumeCutter& cutter, const physics::VolumeCutReport& total) {
  std::vector<int> piece;
  const int pieces = cutter.pieces(piece);
  return std::to_string(cutter.total_links_severed()) + " links severed, " +
         std::to_string(total.elements_reselected) + " elements re-selected, " +
         std::to_string(total.elements_isolated) + " isolated, " +
         std::to_string(total.reselection_failures) + " re-selection failures, " +
         std::to_string(pieces) + " piece(s)";
}

Body make_efg_body(const std::string& case_name, const Material& material, physics::EfgRotation rotation) {
  physics::EfgSettings settings;
  settings.spacing = efg_spacing;
  settings.rotation = rotation;
  auto model = std::make_unique<CorotationalEfg>(case_min(case_name), case_max(case_name),
                                                 material, settings);
  Body body;
  if (is_cut_case(case_name)) {
    // The engine's cutter settings (engine/world.cpp): CCD margin 1 um, slack a / 2.
    body.cutter = std::make_unique<physics::VolumeCutter>(*model, 1e-6, 0.5 * efg_spacing);
  }
  if (case_name == "fast_blade") {
    body.blade = fast_blade_pose;
    body.single_use = true;
  }
  if (case_name == "thin_slice") {
    // Each cut: the edge across the whole width (y from -a to 0.04 + a) swept at rest from
    // beyond the free face back to the front, in one call, as a blade would in one step.
    const Vector& rest = model->rest_positions();
    physics::VolumeCutReport total;
    for (double z : thin_slice_cuts) {
      const std::vector<Vec3> start{Vec3(cube_side + 0.01, -efg_spacing, z),
                                    Vec3(cube_side + 0.01, cube_side + efg_spacing, z)};
      const std::vector<Vec3> end{Vec3(thin_slice_front, -efg_spacing, z),
                                  Vec3(thin_slice_front, cube_side + efg_spacing, z)};
      const physics::VolumeCutReport report = body.cutter->cut(start, end, rest, rest);
      total.elements_reselected += report.elements_reselected;
      total.elements_isolated += report.elements_isolated;
      total.reselection_failures += report.reselection_failures;
    }
    body.note = count_pieces(*body.cutter, total);
    body.slices.assign(thin_slice_cuts.size(), {});
    for (Index node = 0; node < rest.size() / 3; ++node) {
      const Vec3 x = rest.segment<3>(3 * node);
      if (x.x() <= thin_slice_front) continue;
      if (x.z() > thin_slice_cuts[0]) body.slices[0].push_back(static_cast<int>(node));
      if (x.z() < thin_slice_cuts[1]) body.slices[1].push_back(static_cast<int>(node));
    }
  }
  Vector positions = model->rest_positions();
  if (case_name == "compression_release") squeeze_heights(positions);
  if (case_name == "inverted_start") {
    // Particles are 2a apart in z: the layer below a top particle is 2a lower.
    for (int node : nodes_to_flip(model->rest_positions())) positions[3 * node + 2] -= 4.0 * efg_spacing;
    // Inverted integration points: det of the shape-matching fit F_e = sum_n x_n (x) c_n.
    const CorotationalEfg* efg = model.get();
    body.count_inverted = [efg](const Vector& x) {
      int inverted = 0;
      for (int element = 0; element < efg->element_count(); ++element) {
        Eigen::Matrix3d fit = Eigen::Matrix3d::Zero();
        for (int k = 0; k < efg->row_lengths()[static_cast<size_t>(element)]; ++k) {
          const size_t slot = static_cast<size_t>(element) * static_cast<size_t>(efg->row_stride()) +
                              static_cast<size_t>(k);
          fit += x.segment<3>(3 * static_cast<Index>(efg->neighbours()[slot])) *
                 efg->matching_coefficients()[slot].transpose();
        }
        inverted += fit.determinant() < 0 ? 1 : 0;
      }
      return inverted;
    };
    body.inverted = body.count_inverted(positions);
  }
  body.initial.positions = positions;
  body.efg = model.get();
  body.model = std::move(model);
  finish_body(body, case_name);
  return body;
}

// Hexahedra inverted at x: a corner whose three edges (oriented along +x, +y, +z of the local
// order, hex_mesh.hpp) have a non-positive triple product.
int count_inverted_hexes(const std::vector<std::array<int, 8>>& hexes, const Vector& x) {
  int inverted = 0;
  for (const auto& hex : hexes) {
    bool bad = false;
    for (int a = 0; a < 8 && !bad; ++a) {
      const bool plus_x = a == 1 || a == 2 || a == 5 || a == 6, plus_y = (a & 3) >= 2, plus_z = a >= 4;
      const Vec3 p = x.segment<3>(3 * hex[a]);
      const Vec3 ex = (plus_x ? -1.0 : 1.0) * (Vec3(x.segment<3>(3 * hex[a ^ 1])) - p);
      const Vec3 ey = (plus_y ? -1.0 : 1.0) * (Vec3(x.segment<3>(3 * hex[a ^ 3])) - p);
      const Vec3 ez = (plus_z ? -1.0 : 1.0) * (Vec3(x.segment<3>(3 * hex[a ^ 4])) - p);
      bad = ex.cross(ey).dot(ez) <= 0;
    }
    inverted += bad ? 1 : 0;
  }
  return inverted;
}

// A hex lattice's start for the case (the mass-spring's nodes, the shape memory's atoms):
// squeezed, or with each flipped node two node layers down through the layer below (as the
// EFG's particles), the inverted hexes then counted.
Vector hex_lattice_start(const std::string& case_name, const physics::HexMesh& mesh, int layers, Body& body) {
  Vector positions = mesh.rest;
  if (case_name == "compression_release") squeeze_heights(positions);
  if (case_name == "inverted_start") {
    for (int node : nodes_to_flip(mesh.rest)) positions[3 * node + 2] -= 2 * cube_side / layers;
    body.count_inverted = [hexes = mesh.hexes](const Vector& x) { return count_inverted_hexes(hexes, x); };
    body.inverted = body.count_inverted(positions);
  }
  return positions;
}

// Baudet's mass-spring (physics/mss): cubic bricks, the beam 20 x 2 x 2 (the fem's 10 x 2 x 2
// cells are 2:1 bricks, whose edge stiffness is negative at every nu: refused), the cube
// 4 x 4 x 4; its default dashpots (critical) and no corrections. Throws std::invalid_argument
// when the formulas give a brick a non-positive stiffness (counted as refused by the sweep).
Body make_mass_spring_body(const std::string& case_name, const Material& material) {
  const std::array<int, 3> cells = is_beam(case_name) ? std::array<int, 3>{20, 2, 2} : std::array<int, 3>{4, 4, 4};
  const physics::HexMesh mesh = physics::make_box_hexes(case_min(case_name), case_max(case_name), cells);
  auto model = std::make_unique<physics::HexMassSpring>(
      mesh, physics::MassSpringMaterial{material.youngs_modulus, material.poisson_ratio, material.density});
  Body body;
  const Vector positions = hex_lattice_start(case_name, mesh, cells[2], body);
  body.initial.positions = positions;
  body.model = std::move(model);
  finish_body(body, case_name);
  return body;
}

// Dionne's constraint particles (physics/cp): the fem's box split 5 tets per cubic cell (beam
// 20 x 2 x 2, cube 4 x 4 x 4, h = 10 mm), the default stretch limiter (k_E 0.1 beyond 1.05 D0)
// after each explicit step, no dashpots of its own (the sweep's mass damping only). The thesis
// tunes k by hand; the sweep's E and nu are mapped (ours) so that an edge is a spring of about
// E h (k_D = E h^3, as the lattice's springs; k_A the same on the surface triangles) and a tet's
// volume energy is the continuum's K (dV / V)^2 V / 2 with K = E / (3 (1 - 2 nu)) over the
// average tet volume h^3 / 5 (k_V = K h^3 / 5).
Body make_constraint_particles_body(const std::string& case_name, const Material& material) {
  constexpr double h = 0.01;
  const std::array<int, 3> cells = is_beam(case_name) ? std::array<int, 3>{20, 2, 2} : std::array<int, 3>{4, 4, 4};
  const TetMesh mesh = physics::make_box_tets5(case_min(case_name), case_max(case_name), cells);
  physics::ConstraintParticleSettings settings;
  settings.density = material.density;
  settings.distance_stiffness = settings.area_stiffness = material.youngs_modulus * h * h * h;
  const double bulk = material.youngs_modulus / (3 * (1 - 2 * material.poisson_ratio));
  settings.volume_stiffness = bulk * h * h * h / 5;
  auto model = std::make_unique<physics::ConstraintParticles>(mesh, settings);
  Body body;
  Vector positions = mesh.rest;
  if (case_name == "compression_release") squeeze_heights(positions);
  if (case_name == "inverted_start") {
    // As the mass-spring's nodes: each flipped particle two layers down, through the layer below.
    for (int node : nodes_to_flip(mesh.rest)) positions[3 * node + 2] -= 2 * cube_side / cells[2];
    const physics::ConstraintParticles* particles = model.get();
    body.count_inverted = [particles](const Vector& x) { return particles->inverted_tets(x); };
    body.inverted = body.count_inverted(positions);
  }
  body.own_explicit_step = [particles = model.get()](const Integrator& integrator, State& state,
                                                     const std::vector<uint8_t>& fixed, const Vector& external,
                                                     const physics::ExplicitSettings& given,
                                                     physics::VerletHistory& history) {
    physics::CpStepSettings step;  // the default limiter
    step.scheme = integrator.scheme;
    step.dt = given.dt;
    step.rayleigh_mass = given.rayleigh_mass;
    const physics::CpStepReport report = physics::constraint_particles_step(*particles, state, fixed, external, step, history);
    physics::ExplicitStepReport out = report.integrator;
    out.nonfinite = report.nonfinite;
    out.elastic_energy = particles->elastic_energy(state.positions);  // after the limiter
    out.kinetic_energy = physics::kinetic_energy(particles->lumped_masses(), state.velocities);
    return out;
  };
  body.initial.positions = positions;
  body.model = std::move(model);
  finish_body(body, case_name);
  return body;
}

// Promayon's volumetric shape memory (physics/promayon): the mass-spring's lattice (cubic cells,
// beam 20 x 2 x 2, cube 4 x 4 x 4, h = 10 mm) with VN1 neighbours and every non-collinear
// triplet, k_e from E by the calibration (nu has no counterpart), lumped masses. Implicit Euler
// takes its frozen-normal K; the explicit runs take the seed's step (§1.9) in the integrator's
// scheme, the sweep's damping as its -alpha m v. No explicit dt is refused: beyond the bound the
// run diverges, and the set-up note gives the symplectic step's bound 2 / omega_max.
Body make_shape_memory_body(const std::string& case_name, const Material& material) {
  constexpr double h = 0.01;
  const std::array<int, 3> cells = is_beam(case_name) ? std::array<int, 3>{20, 2, 2} : std::array<int, 3>{4, 4, 4};
  const physics::HexMesh mesh = physics::make_box_hexes(case_min(case_name), case_max(case_name), cells);
  const double ke = physics::stiffness_from_youngs_modulus(physics::PromayonKind::shape_memory,
                                                           physics::Neighbourhood::vn1, material.youngs_modulus, h);
  auto model = std::make_unique<physics::ShapeMemory>(mesh.rest, physics::lattice_neighbours(mesh, physics::Neighbourhood::vn1),
                                                      physics::lattice_masses(mesh, material.density), ke, h);
  Body body;
  const Vector positions = hex_lattice_start(case_name, mesh, cells[2], body);
  body.own_explicit_step = [sm = model.get()](const Integrator& integrator, State& state,
                                              const std::vector<uint8_t>& fixed, const Vector& external,
                                              const physics::ExplicitSettings& given, physics::VerletHistory&) {
    const physics::SeedStepSettings step{given.dt, 0, given.rayleigh_mass,
                                         integrator.seed.value_or(physics::SeedScheme::symplectic_euler)};
    const physics::SeedStepReport report = physics::seed_explicit_step(*sm, state, fixed, external, {}, step, nullptr, 0);
    physics::ExplicitStepReport out;
    out.nonfinite = report.nonfinite;
    out.force_evaluations = 1;
    out.elastic_energy = report.elastic_energy;
    out.kinetic_energy = report.kinetic_energy;
    return out;
  };
  body.initial.positions = positions;
  body.model = std::move(model);
  finish_body(body, case_name);
  body.note = "k_e " + format(ke, 4) + " N/m, symplectic bound " +
              format(1e3 * physics::seed_step_limit(*body.model, body.fixed), 4) + " ms";
  return body;
}

Body make_body(const std::string& model_name, const std::string& case_name,
               const Material& material) {
  if (model_name == "fem") return make_fem_body(case_name, material);
  if (model_name == "efg") return make_efg_body(case_name, material);
  if (model_name == "mass_spring") return make_mass_spring_body(case_name, material);
  if (model_name == "constraint_particles") return make_constraint_particles_body(case_name, material);
  if (model_name == "shape_memory") return make_shape_memory_body(case_name, material);
  throw std::invalid_argument("stability bench: unknown model " + model_name);
}


}  // namespace incise::bench::sweep
