// The numerical stability sweep (issue 7): where each model and integrator breaks on stiff
// and extreme settings, as a map anyone can rerun.
//
// Cases (all under gravity, 9.81 m/s^2 along -z, rho = 1000 kg/m^3):
// - beam_gravity: B1, the beam 0.2 x 0.02 x 0.02 m along +x clamped at x = 0, from rest;
// - compression_release: a 0.04 m cube on a clamped base (z = 0), its nodes starting at 10 %
//   of their height (z -> 0.1 z, a prescribed squeezed state) and at rest, then released;
// - inverted_start: the same cube at rest with three top nodes flipped, so that some elements
//   start inverted (FEM: each node reflected through the face opposite it in its first
//   tetrahedron; EFG: each particle reflected through the plane of the particle layer below).
// - fast_blade (efg only): the cube clamped at z = 0, at rest; a straight vertical blade edge
//   (y = 21.5 mm, z from 60 mm down to 15.5 mm) crosses it along +x at 5 m/s from x = -10 mm
//   at t = 0, cutting the upper part in two (both halves stay attached below z = 15.5 mm),
//   and the run goes on. The blade goes through physics::VolumeCutter every step, before the
//   solve, with the particles' motion over the previous step (positions before the last
//   solve to after it), as the engine does (continuous collision: at dt = 33 ms the whole
//   crossing is one step); gravity is recomputed from the masses the re-selection moves;
// - thin_slice (efg only): the cube clamped on its face x = 0, cut at rest by VolumeCutter
//   with two horizontal blade sweeps across its width, from beyond the free face x = 40 mm
//   back to x = 11.5 mm: at z = 34 mm (a slice one integration element thick on top: one
//   integration layer, one particle layer) and at z = 11 mm (a slice two elements thick at the
//   bottom: two integration and two particle layers); the slices hang from the block under
//   gravity. One element is too thin for the discretisation (thesis §4.3.3, ch. 5: about 2
//   elements is the thinnest separable part): the top slice's elements find no neighbourhood
//   spanning 3 dimensions on their side, the cutter counts them as re-selection failures
//   (32 of them) and they keep their old rows, so the top slice stays partly tied across its
//   cut (stability_summary.txt, Set-up).
// After the sweep, the thin-slice study runs thin_slice under gravity for 3 s (6 s in the full
// sweep) at dt = 16.7 ms with each rotation of the corotation (EfgSettings::rotation), E 10 kPa,
// 100 kPa and 1 MPa, nu 0.45, and prints for each slice the rms particle speed and the
// centroid drift over the last second and the sag, and the energy the run gained (sum of the
// per-step rises of elastic + kinetic + gravitational energy) over its net change: a damped
// conservative model never gains any. What it shows and why the corotation takes its rotation
// from the deformation gradient: docs/physics-choices.md, "`rotation` = deformation_gradient"
// (corotational_efg.hpp, "Rotation").
//
// Models: `fem`, CorotationalTetFem (beam 10 x 2 x 2 cells, cube 4 x 4 x 4 cells, 6 tets per
// cell) with implicit Euler and the five explicit integrators; `efg`, CorotationalEfg (grid
// spacing a = 5 mm, particles 10 mm apart) with implicit Euler; `mass_spring`, Baudet's
// HexMassSpring (cubic bricks: beam 20 x 2 x 2, cube 4 x 4 x 4; critical dashpots, no
// corrections) with implicit Euler and the five explicit integrators, an explicit run whose dt
// is beyond its bound 2 sqrt(m_min / k_node_max) counted as `refused` (as is a body whose bricks
// the formulas give a non-positive stiffness; the cubic bricks never do); `constraint_particles`,
// Dionne's ConstraintParticles (beam 20 x 2 x 2, cube 4 x 4 x 4 cubic cells of 5 tets; k_D = k_A =
// E h^3 and k_V = E h^3 / (15 (1 - 2 nu)), make_constraint_particles_body says why) with implicit
// Euler and the five explicit integrators, each explicit step followed by the stretch limiter
// (Alg. 3.2), an explicit dt beyond its bound min 2 sqrt(m_i / k_i) refused. Damping: Rayleigh mass
// damping alpha = 1/s for every integrator; implicit Euler's CG: tolerance 1e-6, at most 1000
// iterations, warm started from the previous step's velocity change, as in the engine.
//
// Each run, at the nominal dt, applies the engine's non-finite guard: a step that produces a
// non-finite value is rolled back and retried as 2, 4, 8 sub-steps; guard_events counts the
// steps that needed it. Outcomes, the first that applies:
// - nonfinite: a step stayed non-finite after 3 halvings (the run stops there);
// - diverged: the elastic + kinetic energy exceeded 100 x E_ref, E_ref the larger of the
//   initial elastic + kinetic energy and the work gravity would do on the whole body falling
//   freely for the run's duration T (M g^2 T^2 / 2), or a node moved more than 10 x the body
//   size (the largest side of its rest bounding box); the run stops at the first such step;
// - cg_not_converged: implicit Euler's CG hit its 1000-iteration cap in more than 10 % of the
//   run's steps; the run stops as soon as that count is reached (its steps are then not
//   implicit Euler's solution, and the stiff runs that never converge would otherwise take
//   most of the sweep's time);
// - stable otherwise.
// Runs are T = 1 s (beam) or 0.5 s (cubes) of simulated time; 0.25 s in quick mode.
// Quick sweep: 3 E x 3 nu x 2 dt, 1062 runs. The sweeps' outcomes: docs/status.md, "Benchmarks".
#include "bench/stability.hpp"
#include "bench/bench_page.hpp"
#include "bench/plot.hpp"

#include "common/csv.hpp"
#include "common/progress_bar.hpp"
#include "engine/model_registry.hpp"

#include "physics/core/explicit_integrators.hpp"
#include "physics/core/implicit_euler.hpp"
#include "physics/cp/cp_step.hpp"
#include "physics/cut/volume_cut.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/fem/corotational_fem.hpp"
#include "physics/fem/tet_mesh.hpp"
#include "physics/mss/hex_mass_spring.hpp"
#include "physics/mss/hex_mesh.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace incise::bench {

namespace {

using physics::CorotationalEfg;
using physics::CorotationalTetFem;
using physics::DeformableModel;
using physics::ExplicitScheme;
using physics::Material;
using physics::State;
using physics::TetMesh;
using physics::Vec3;
using physics::Vector;
using Index = Eigen::Index;

constexpr double density = 1000;
const Vec3 gravity(0, 0, -9.81);
constexpr double rayleigh_mass = 1.0;  // 1/s
constexpr double cg_tolerance = 1e-6;
// The CG budget per step. Jacobi-preconditioned CG on these bodies (about 300 free dofs)
// needs 200 iterations at nu = 0.3 and 450-620 at nu = 0.49 (the system's condition number
// reaches 1e6 when dt^2 K dominates M: measured on the assembled matrix, block-Jacobi saves
// only 10-15 %), more than the dof count, as finite-precision CG loses orthogonality. A cap
// of 1000 separates that slow but steady convergence from the stagnation of locked elements
// at nu = 0.499, which is what cg_not_converged should report.
constexpr int cg_max_iterations = 1000;
constexpr int max_halvings = 3;
constexpr double energy_bound = 100;          // x E_ref
constexpr double displacement_bound = 10;     // x body size
constexpr double cg_capped_fraction = 0.1;    // of the steps
constexpr double beam_length = 0.2;
constexpr double beam_half_side = 0.01;
constexpr double cube_side = 0.04;
constexpr double squeeze = 0.1;               // compression_release starts at 10 % height
constexpr double efg_spacing = 0.005;
constexpr int flipped_nodes = 3;
// fast_blade: a straight vertical edge (x, 0.0215, z), z from fast_blade_top down to
// fast_blade_bottom, moving along +x at blade_speed from x = blade_start_x at t = 0.
constexpr double blade_speed = 5;             // m/s
constexpr double blade_start_x = -0.01;
constexpr double fast_blade_y = 0.0215;
constexpr double fast_blade_bottom = 0.0155;
constexpr double fast_blade_top = 0.06;
// thin_slice: horizontal cuts at these heights, from beyond the free face x = 0.04 back to
// x = thin_slice_front, the cube clamped on its face x = 0.
constexpr double thin_slice_front = 0.0115;
constexpr std::array<double, 2> thin_slice_cuts{0.034, 0.011};  // one element on top, two below

enum class Outcome { stable, diverged, nonfinite, cg_not_converged, refused };
constexpr std::array<Outcome, 5> all_outcomes{Outcome::stable, Outcome::diverged, Outcome::nonfinite,
                                              Outcome::cg_not_converged, Outcome::refused};

const char* outcome_name(Outcome outcome) {
  switch (outcome) {
    case Outcome::stable: return "stable";
    case Outcome::diverged: return "diverged";
    case Outcome::nonfinite: return "nonfinite";
    case Outcome::cg_not_converged: return "cg_not_converged";
    case Outcome::refused: return "refused";
  }
  return "unknown";
}

// Colours of the outcome map (RGB).
int outcome_colour(Outcome outcome) {
  switch (outcome) {
    case Outcome::stable: return 0x2ca02c;
    case Outcome::diverged: return 0xd62728;
    case Outcome::nonfinite: return 0x222222;
    case Outcome::cg_not_converged: return 0xf0b400;
    case Outcome::refused: return 0x9e9e9e;
  }
  return 0xffffff;
}

struct Integrator {
  std::string name;
  bool implicit = false;
  ExplicitScheme scheme = ExplicitScheme::explicit_euler;
};

struct ModelKind {
  std::string name;
  std::vector<Integrator> integrators;
};

// One case at one material for one model: the static set-up of a run.
struct Body {
  std::unique_ptr<DeformableModel> model;
  State initial;
  std::vector<uint8_t> fixed;
  Vector external;
  double size = 0;      // largest side of the rest bounding box, m
  // Elements inverted at positions x (inverted_start only, else empty).
  std::function<int(const Vector&)> count_inverted;
  int inverted = 0;     // in the initial state
  // Cutting (fast_blade, thin_slice): the cutter of the EFG model, and for fast_blade the
  // blade polyline at time t, applied every step. single_use: the run edits the model, so each
  // run needs a fresh body.
  std::unique_ptr<physics::VolumeCutter> cutter;
  const CorotationalEfg* efg = nullptr;  // the model, when it is an EFG one
  std::function<std::vector<Vec3>(double)> blade;
  bool single_use = false;
  std::string note;  // set-up figures for the summary
  // thin_slice: the particles of each slice beyond the cut front (top, then bottom).
  std::vector<std::vector<int>> slices;
  // The model's own explicit step, when it has one (the constraint particles' Alg. 3.2: the
  // integrator, then the stretch limiter); empty: physics::explicit_step.
  std::function<physics::ExplicitStepReport(ExplicitScheme, State&, const std::vector<uint8_t>&, const Vector&,
                                            const physics::ExplicitSettings&, physics::VerletHistory&)>
      own_explicit_step;
};

struct Run {
  std::string model;
  std::string integrator;
  std::string case_name;
  double youngs_modulus = 0;
  double poisson_ratio = 0;
  double dt = 0;
  Outcome outcome = Outcome::stable;
  double max_energy_ratio = 0;
  double max_displacement = 0;
  int steps = 0;
  int guard_events = 0;
  int inverted_at_end = -1;  // elements still inverted when the run ended (-1: not counted)
};

struct Sweep {
  std::vector<double> youngs_moduli;
  std::vector<double> poisson_ratios;
  std::vector<double> time_steps;
  std::vector<std::string> cases;
  double beam_duration = 0;
  double cube_duration = 0;
};

Sweep make_sweep(bool quick) {
  if (quick) {
    // Soft, stiff and beyond; compressible, nearly and almost incompressible; a haptic-rate
    // and a frame-rate step; every case.
    return {{10e3, 10e6, 1e9}, {0.3, 0.49, 0.499}, {1e-3, 33e-3},
            {"beam_gravity", "compression_release", "inverted_start", "fast_blade", "thin_slice"},
            0.25, 0.25};
  }
  return {{1e3, 10e3, 100e3, 1e6, 10e6, 100e6, 1e9},
          {0.3, 0.45, 0.49, 0.499},
          {0.5e-3, 1e-3, 4e-3, 16.7e-3, 33e-3},
          {"beam_gravity", "compression_release", "inverted_start", "fast_blade", "thin_slice"},
          1.0,
          0.5};
}

// The models this bench sets up bodies for (make_body, below the engine's builder: the cases
// need the bare DeformableModel), with the integrators each offers.
const std::set<std::string>& bench_models() {
  static const std::set<std::string> names{"fem", "efg", "mass_spring", "constraint_particles"};
  return names;
}

// The sweep's models: the registry's (engine/model_registry.hpp), in its order, those this bench
// can set up; `left_out` receives the others.
std::vector<ModelKind> model_kinds(std::vector<std::string>* left_out = nullptr) {
  std::vector<Integrator> fem{{"implicit_euler", true}};
  for (ExplicitScheme scheme : {ExplicitScheme::explicit_euler, ExplicitScheme::midpoint,
                                ExplicitScheme::runge_kutta4, ExplicitScheme::verlet,
                                ExplicitScheme::velocity_verlet}) {
    fem.push_back({std::string(physics::explicit_scheme_name(scheme)), false, scheme});
  }
  std::vector<ModelKind> kinds;
  for (const std::string& name : engine::models().names()) {
    if (!bench_models().count(name)) {
      if (left_out) left_out->push_back(name);
      continue;
    }
    // The EFG model offers implicit Euler only (issue 7: explicit integrators "where a model
    // offers them"); any DeformableModel would take the explicit steps as well. The mass-spring
    // and the constraint particles take them all, up to their explicit bound (beyond it the run
    // is refused).
    kinds.push_back({name, name != "efg" ? fem : std::vector<Integrator>{{"implicit_euler", true}}});
  }
  return kinds;
}

// This report's figures: 6 significant digits unless a caller asks for others.
std::string format(double value, int digits = 6) { return common::significant(value, digits); }

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
void pin_orphans(Body& body, State* state = nullptr) {
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

Body make_efg_body(const std::string& case_name, const Material& material,
                   physics::EfgRotation rotation = physics::EfgSettings{}.rotation) {
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
  Vector positions = mesh.rest;
  if (case_name == "compression_release") squeeze_heights(positions);
  if (case_name == "inverted_start") {
    // As the EFG's particles: each flipped node two node layers down, through the layer below.
    for (int node : nodes_to_flip(mesh.rest)) positions[3 * node + 2] -= 2 * cube_side / cells[2];
    body.count_inverted = [hexes = mesh.hexes](const Vector& x) { return count_inverted_hexes(hexes, x); };
    body.inverted = body.count_inverted(positions);
  }
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
  body.own_explicit_step = [particles = model.get()](ExplicitScheme scheme, State& state,
                                                     const std::vector<uint8_t>& fixed, const Vector& external,
                                                     const physics::ExplicitSettings& given,
                                                     physics::VerletHistory& history) {
    physics::CpStepSettings step;  // the default limiter
    step.scheme = scheme;
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

Body make_body(const std::string& model_name, const std::string& case_name,
               const Material& material) {
  if (model_name == "fem") return make_fem_body(case_name, material);
  if (model_name == "efg") return make_efg_body(case_name, material);
  if (model_name == "mass_spring") return make_mass_spring_body(case_name, material);
  if (model_name == "constraint_particles") return make_constraint_particles_body(case_name, material);
  throw std::invalid_argument("stability bench: unknown model " + model_name);
}

// ---- Runs --------------------------------------------------------------------------------

double max_node_displacement(const Vector& positions, const Vector& rest) {
  double largest = 0;
  for (Index node = 0; node < rest.size() / 3; ++node) {
    largest = std::max(largest, (positions.segment<3>(3 * node) - rest.segment<3>(3 * node)).norm());
  }
  return largest;
}

// The sweep's implicit Euler step (its damping and CG budget) at step `dt`: the runs and the
// thin-slice study step alike.
physics::ImplicitEulerSettings implicit_settings(double dt) {
  physics::ImplicitEulerSettings settings;
  settings.dt = dt;
  settings.rayleigh_mass = rayleigh_mass;
  settings.cg.tolerance = cg_tolerance;
  settings.cg.max_iterations = cg_max_iterations;
  return settings;
}

Run simulate(Body& body, const Integrator& integrator, double dt, double duration) {
  DeformableModel& model = *body.model;
  Run run;
  run.dt = dt;
  State state = body.initial;
  physics::VerletHistory history;
  Vector velocity_change = Vector::Zero(state.positions.size());
  const Vector& rest = model.rest_positions();

  const double total_mass = model.lumped_masses().sum();
  const double initial_energy = model.elastic_energy(state.positions) +
                                physics::kinetic_energy(model.lumped_masses(), state.velocities);
  const double free_fall_work = 0.5 * total_mass * gravity.squaredNorm() * duration * duration;
  const double reference_energy = std::max(initial_energy, free_fall_work);
  run.max_displacement = max_node_displacement(state.positions, rest);
  run.max_energy_ratio = initial_energy / reference_energy;

  const int steps = std::max(1, static_cast<int>(std::lround(duration / dt)));
  // A model that knows its explicit bound (the mass-spring's, the constraint particles') refuses a step beyond it
  // (explicit_step throws): the run is counted as refused, not taken.
  if (!integrator.implicit && dt > model.explicit_step_limit()) {
    run.outcome = Outcome::refused;
    return run;
  }
  int capped_steps = 0;
  Vector before_last_solve = state.positions;
  physics::VolumeCutReport cuts;
  for (int step = 0; step < steps; ++step) {
    if (body.cutter && body.blade) {
      // As the engine does: the blade's sweep over this step against the particles' motion
      // over the previous one (positions before the last solve to after it), before the solve.
      const std::vector<Vec3> from = body.blade(step * dt), to = body.blade((step + 1) * dt);
      const physics::VolumeCutReport report =
          body.cutter->cut(from, to, before_last_solve, state.positions);
      if (report.any()) {
        pin_orphans(body, &state);
        body.external = physics::gravity_forces(model.lumped_masses(), gravity);
        cuts.elements_reselected += report.elements_reselected;
        cuts.elements_isolated += report.elements_isolated;
        cuts.reselection_failures += report.reselection_failures;
      }
    }
    before_last_solve = state.positions;
    bool accepted = false;
    bool capped = false;
    double energy = 0;
    for (int attempt = 0; attempt <= max_halvings && !accepted; ++attempt) {
      const int substeps = 1 << attempt;
      const double sub_dt = dt / substeps;
      const State saved_state = state;
      const physics::VerletHistory saved_history = history;
      const Vector saved_change = velocity_change;
      bool failed = false;
      capped = false;
      for (int sub = 0; sub < substeps && !failed; ++sub) {
        if (integrator.implicit) {
          const physics::StepReport report = physics::implicit_euler_step(
              model, state, body.fixed, body.external, {}, implicit_settings(sub_dt), &velocity_change);
          failed = report.nonfinite;
          capped = capped || (!report.nonfinite && !report.cg.converged);
          energy = report.elastic_energy + report.kinetic_energy;
        } else {
          const physics::ExplicitSettings settings{sub_dt, rayleigh_mass};
          const physics::ExplicitStepReport report =
              body.own_explicit_step
                  ? body.own_explicit_step(integrator.scheme, state, body.fixed, body.external, settings, history)
                  : physics::explicit_step(integrator.scheme, model, state, body.fixed, body.external, settings,
                                           &history);
          failed = report.nonfinite;
          energy = report.elastic_energy + report.kinetic_energy;
        }
      }
      if (failed) {
        state = saved_state;
        history = saved_history;
        velocity_change = saved_change;
        if (attempt == 0) ++run.guard_events;
        continue;
      }
      accepted = true;
    }
    if (!accepted) {
      run.outcome = Outcome::nonfinite;
      break;
    }
    run.steps = step + 1;
    capped_steps += capped ? 1 : 0;
    run.max_energy_ratio = std::max(run.max_energy_ratio, energy / reference_energy);
    run.max_displacement = std::max(run.max_displacement, max_node_displacement(state.positions, rest));
    if (run.max_energy_ratio > energy_bound || run.max_displacement > displacement_bound * body.size) {
      run.outcome = Outcome::diverged;
      break;
    }
    if (capped_steps > cg_capped_fraction * steps) break;  // cg_not_converged, below
  }
  if (run.outcome == Outcome::stable && capped_steps > cg_capped_fraction * steps) {
    run.outcome = Outcome::cg_not_converged;
  }
  if (body.count_inverted) run.inverted_at_end = body.count_inverted(state.positions);
  if (body.cutter && body.blade) body.note = count_pieces(*body.cutter, cuts);
  return run;
}

// ---- The thin-slice study ------------------------------------------------------------------

std::string short_modulus(double pascals);

// thin_slice under gravity with each rotation of the corotation: the slices hang from their
// attachment and should come to rest. Spontaneous motion shows as kinetic energy and drift
// that do not die out, and as a rise of the total energy (elastic + kinetic + gravitational),
// which a damped conservative model never has (implicit Euler and mass damping only dissipate).
struct SliceStudy {
  physics::EfgRotation rotation;
  double youngs_modulus = 0;
  double dt = 0;
  int steps = 0;
  bool finite = true;
  std::array<double, 2> late_speed{};  // rms particle speed over the last second, m/s, per slice
  std::array<double, 2> late_drift{};  // centroid motion over the last second, m, per slice
  std::array<double, 2> sag{};         // centroid displacement from rest at the end, m
  double energy_rise = 0;              // sum of the per-step rises of the total energy, J
  double energy_scale = 0;             // |total energy at the end - at the start|, J
};

const char* rotation_name(physics::EfgRotation rotation) {
  return rotation == physics::EfgRotation::shape_matching ? "shape_matching" : "deformation_gradient";
}

SliceStudy study_thin_slice(physics::EfgRotation rotation, double youngs_modulus, double dt,
                            double duration) {
  const Material material{youngs_modulus, 0.45, density};
  Body body = make_efg_body("thin_slice", material, rotation);
  DeformableModel& model = *body.model;
  const Vector& masses = model.lumped_masses();
  State state = body.initial;
  Vector velocity_change = Vector::Zero(state.positions.size());
  SliceStudy study;
  study.rotation = rotation;
  study.youngs_modulus = youngs_modulus;
  study.dt = dt;
  const auto centroid = [&](const std::vector<int>& slice, const Vector& x) {
    Vec3 sum = Vec3::Zero();
    double mass = 0;
    for (int node : slice) sum += masses[node] * x.segment<3>(3 * node), mass += masses[node];
    return Vec3(sum / mass);
  };
  const auto total_energy = [&](const State& s) {
    return model.elastic_energy(s.positions) + physics::kinetic_energy(masses, s.velocities) -
           body.external.dot(s.positions);
  };
  const int steps = static_cast<int>(std::lround(duration / dt));
  const int late = static_cast<int>(std::lround(1.0 / dt));
  std::array<Vec3, 2> late_start{};
  std::array<double, 2> squared_speed{};
  std::array<int, 2> samples{};
  const double initial_energy = total_energy(state);
  double energy = initial_energy;
  for (int step = 0; step < steps; ++step) {
    const physics::StepReport report = physics::implicit_euler_step(
        model, state, body.fixed, body.external, {}, implicit_settings(dt), &velocity_change);
    if (report.nonfinite) {
      study.finite = false;
      break;
    }
    study.steps = step + 1;
    const double next = total_energy(state);
    study.energy_rise += std::max(0.0, next - energy);
    energy = next;
    if (step == steps - late - 1) {
      for (size_t k = 0; k < 2; ++k) late_start[k] = centroid(body.slices[k], state.positions);
    }
    if (step >= steps - late) {
      for (size_t k = 0; k < 2; ++k) {
        for (int node : body.slices[k]) squared_speed[k] += state.velocities.segment<3>(3 * node).squaredNorm();
        samples[k] += static_cast<int>(body.slices[k].size());
      }
    }
  }
  study.energy_scale = std::abs(energy - initial_energy);
  for (size_t k = 0; k < 2; ++k) {
    const std::vector<int>& slice = body.slices[k];
    study.late_speed[k] = samples[k] ? std::sqrt(squared_speed[k] / samples[k]) : 0;
    study.late_drift[k] = (centroid(slice, state.positions) - late_start[k]).norm();
    study.sag[k] = (centroid(slice, state.positions) - centroid(slice, model.rest_positions())).norm();
  }
  return study;
}

std::string thin_slice_report(bool quick, std::ostream& progress) {
  const double duration = quick ? 3.0 : 6.0;
  const double dt = 1.0 / 60;
  std::ostringstream text;
  text << "Thin-slice study (thin_slice under gravity, nu 0.45, dt " << format(1e3 * dt, 3)
       << " ms, mass damping " << format(rayleigh_mass) << "/s, T = " << format(duration)
       << " s; slices: top one element thick, bottom two; late = the last second):\n";
  char line[320];
  std::snprintf(line, sizeof line, "  %-21s %8s %6s | %12s %12s %9s | %12s %12s %9s | %11s\n",
                "rotation", "E", "steps", "top v mm/s", "top drift mm", "top sag", "bot v mm/s",
                "bot drift mm", "bot sag", "E rise / dE");
  text << line;
  for (double youngs_modulus : {10e3, 100e3, 1e6}) {
    for (physics::EfgRotation rotation :
         {physics::EfgRotation::shape_matching, physics::EfgRotation::deformation_gradient}) {
      progress << "\rthin-slice study: " << rotation_name(rotation) << " E " << short_modulus(youngs_modulus)
               << "          " << std::flush;
      const SliceStudy s = study_thin_slice(rotation, youngs_modulus, dt, duration);
      std::snprintf(line, sizeof line,
                    "  %-21s %8s %6d | %12.4g %12.4g %9.4g | %12.4g %12.4g %9.4g | %11.3g%s\n",
                    rotation_name(rotation), short_modulus(youngs_modulus).c_str(), s.steps,
                    1e3 * s.late_speed[0], 1e3 * s.late_drift[0], 1e3 * s.sag[0],
                    1e3 * s.late_speed[1], 1e3 * s.late_drift[1], 1e3 * s.sag[1],
                    s.energy_scale > 0 ? s.energy_rise / s.energy_scale : 0.0,
                    s.finite ? "" : "  (non-finite: stopped)");
      text << line;
    }
  }
  progress << "\n";
  return text.str();
}

// ---- Output ------------------------------------------------------------------------------

// One row of stability.csv, flushed: an interrupted sweep leaves whole rows to resume from.
void write_row(common::CsvWriter& csv, const Run& run) {
  csv.row(run.model, run.integrator, run.case_name, format(run.youngs_modulus), format(run.poisson_ratio),
          format(run.dt), outcome_name(run.outcome), format(run.max_energy_ratio, 4), format(run.max_displacement, 4),
          run.steps, run.guard_events);
  csv.flush();
}

// The key of a run in the sweep: what identifies it, as the CSV writes it.
std::string run_key(const std::string& model, const std::string& integrator, const std::string& case_name,
                    double youngs_modulus, double poisson_ratio, double dt) {
  return model + "," + integrator + "," + case_name + "," + format(youngs_modulus) + "," + format(poisson_ratio) +
         "," + format(dt);
}

// The runs of an earlier (interrupted) sweep in `path`, by key. A row that does not parse
// (a line cut short when the sweep was killed) ends the list: it and what follows are run
// again. The CSV does not keep the inverted-element counts, so kept runs are left out of the
// summary's inverted_start table.
std::map<std::string, Run> read_previous_runs(const std::filesystem::path& path, std::ostream& progress) {
  std::map<std::string, Run> runs;
  std::ifstream in(path);
  if (!in) return runs;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (number == 1) {
      if (line.rfind("model,integrator,case,E,nu,dt,outcome", 0) != 0) {
        throw std::runtime_error(path.string() + ": line 1 is not a stability.csv header; not resuming from it");
      }
      continue;
    }
    std::vector<std::string> fields;
    std::stringstream stream(line);
    for (std::string field; std::getline(stream, field, ',');) fields.push_back(field);
    if (!line.empty() && line.back() == ',') fields.emplace_back();  // an empty last field
    Run run;
    bool ok = fields.size() == 11;
    try {
      if (ok) {
        run.model = fields[0], run.integrator = fields[1], run.case_name = fields[2];
        run.youngs_modulus = std::stod(fields[3]);
        run.poisson_ratio = std::stod(fields[4]);
        run.dt = std::stod(fields[5]);
        ok = false;
        for (Outcome outcome : all_outcomes)
          if (fields[6] == outcome_name(outcome)) run.outcome = outcome, ok = true;
        run.max_energy_ratio = std::stod(fields[7]);
        run.max_displacement = std::stod(fields[8]);
        run.steps = std::stoi(fields[9]);
        run.guard_events = std::stoi(fields[10]);
      }
    } catch (const std::exception&) {
      ok = false;
    }
    if (!ok) {
      progress << path.string() << ": line " << number << " is incomplete or malformed; it and any later lines are run again\n";
      break;
    }
    runs[run_key(run.model, run.integrator, run.case_name, run.youngs_modulus, run.poisson_ratio, run.dt)] = run;
  }
  return runs;
}

std::string short_modulus(double pascals) {
  if (pascals >= 1e9) return format(pascals / 1e9) + " GPa";
  if (pascals >= 1e6) return format(pascals / 1e6) + " MPa";
  if (pascals >= 1e3) return format(pascals / 1e3) + " kPa";
  return format(pascals) + " Pa";
}

size_t index_of(const std::vector<double>& values, double value) {
  return static_cast<size_t>(std::find(values.begin(), values.end(), value) - values.begin());
}

// gnuplot wants underscores escaped in enhanced-text strings (inside double quotes: "\\_").
std::string gnuplot_text(const std::string& text) {
  std::string escaped;
  for (char c : text) {
    if (c == '_') escaped += "\\\\";
    escaped += c;
  }
  return escaped;
}

// One panel per model + integrator (rows) and case (columns); inside a panel, E upwards and
// dt to the right, one block of dt columns per nu; each cell coloured by its outcome. The
// panels are placed in pixels (multiplot margins and spacing), so that the three-line title,
// the panel titles and the rotated dt labels never overlap whatever the sweep's size.
std::string plot_script(const std::string& png, bool quick, const Sweep& sweep, const std::vector<ModelKind>& kinds,
                        const std::vector<Run>& runs) {
  std::ostringstream script;
  const size_t block = sweep.time_steps.size() + 1;  // dt columns and a gap per nu
  const size_t columns = block * sweep.poisson_ratios.size() - 1;
  int rows = 0;
  for (const ModelKind& kind : kinds) rows += static_cast<int>(kind.integrators.size());
  const int cases = static_cast<int>(sweep.cases.size());
  // Pixels: the plot area of a panel, and the room around it.
  const int area_width = std::max(260, 24 * static_cast<int>(columns));
  const int area_height = std::max(90, 24 * static_cast<int>(sweep.youngs_moduli.size()));
  constexpr int left = 70, right = 20, header = 80, above = 40, below = 75, between = 80;
  const int width = left + cases * area_width + (cases - 1) * between + right;
  const int height = header + above + rows * area_height + (rows - 1) * (above + below) + below;
  auto fraction_x = [&](int pixels) { return format(static_cast<double>(pixels) / width, 5); };
  auto fraction_y = [&](int pixels) { return format(static_cast<double>(pixels) / height, 5); };

  script << "# Written by incise bench stability: the outcome map of stability.csv.\n"
         << "set terminal pngcairo size " << width << "," << height << " font ',9'\n"
         << "set output '" << png << "'\n"
         << "unset key\nset tics scale 0\nset border 0\n"
         << "set xrange [-0.6:" << columns - 0.4 << "]\n"
         << "set yrange [-0.6:" << sweep.youngs_moduli.size() - 0.4 << "]\n";
  script << "set ytics (";
  for (size_t e = 0; e < sweep.youngs_moduli.size(); ++e) {
    script << (e ? ", " : "") << "'" << short_modulus(sweep.youngs_moduli[e]) << "' " << e;
  }
  script << ")\nset xtics rotate by 90 right font ',8' (";
  bool first = true;
  for (size_t p = 0; p < sweep.poisson_ratios.size(); ++p) {
    for (size_t d = 0; d < sweep.time_steps.size(); ++d) {
      script << (first ? "" : ", ") << "'" << format(1e3 * sweep.time_steps[d], 3) << "' "
             << p * block + d;
      first = false;
    }
  }
  script << ")\n";
  for (size_t p = 0; p < sweep.poisson_ratios.size(); ++p) {
    const double centre = static_cast<double>(p * block) + 0.5 * (sweep.time_steps.size() - 1);
    script << "set label " << p + 1 << " 'nu " << format(sweep.poisson_ratios[p]) << "' at "
           << centre << ", graph 1.06 center font ',8'\n";
  }
  script << "set xlabel 'dt (ms), a block per Poisson ratio' font ',8' offset 0,0.2\n";
  int panel = 0;
  for (const ModelKind& kind : kinds) {
    for (const Integrator& integrator : kind.integrators) {
      for (const std::string& case_name : sweep.cases) {
        script << "$panel" << panel << " << EOD\n";
        for (const Run& run : runs) {
          if (run.model != kind.name || run.integrator != integrator.name || run.case_name != case_name)
            continue;
          const size_t column = index_of(sweep.poisson_ratios, run.poisson_ratio) * block +
                                index_of(sweep.time_steps, run.dt);
          script << column << " " << index_of(sweep.youngs_moduli, run.youngs_modulus) << " "
                 << outcome_colour(run.outcome) << "\n";
        }
        // A model that does not run the case (fem on the cutting cases): one point outside the
        // ranges, so the panel stays white and gnuplot has something to plot.
        if (!model_runs_case(kind.name, case_name)) script << "-10 -10 16777215\n";
        script << "EOD\n";
        ++panel;
      }
    }
  }
  const std::string title =
      std::string("incise stability sweep") + (quick ? " (quick)" : "") +
      "\\ngreen stable, red diverged, black nonfinite, gold cg_not_converged, white not run" +
      "\\ndiverged: energy > " + format(energy_bound) + " x E_ref or displacement > " +
      format(displacement_bound) + " x body size (stability_summary.txt)";
  script << "set multiplot layout " << rows << "," << cases << " margins " << fraction_x(left)
         << "," << fraction_x(width - right) << "," << fraction_y(below) << ","
         << fraction_y(height - header - above) << " spacing " << fraction_x(between) << ","
         << fraction_y(above + below) << " title \"" << gnuplot_text(title) << "\" font ',11'\n";
  panel = 0;
  for (const ModelKind& kind : kinds) {
    for (const Integrator& integrator : kind.integrators) {
      for (const std::string& case_name : sweep.cases) {
        script << "set title \"" << gnuplot_text(kind.name + " " + integrator.name + ", " + case_name)
               << "\" font ',10' offset 0,0.9\n"
               << "plot $panel" << panel
               << " using 1:2:(0.46):(0.46):3 with boxxyerror fill solid 1.0 noborder lc rgb variable\n";
        ++panel;
      }
    }
  }
  script << "unset multiplot\n";
  return script.str();
}

std::string counts_table(const std::vector<ModelKind>& kinds, const std::vector<Run>& runs) {
  std::ostringstream table;
  char line[160];
  std::snprintf(line, sizeof line, "%-36s %8s %9s %10s %17s %8s\n", "model/integrator", "stable",
                "diverged", "nonfinite", "cg_not_converged", "refused");
  table << line;
  for (const ModelKind& kind : kinds) {
    for (const Integrator& integrator : kind.integrators) {
      std::map<Outcome, int> counts;
      for (const Run& run : runs) {
        if (run.model == kind.name && run.integrator == integrator.name) ++counts[run.outcome];
      }
      const std::string name = kind.name + "/" + integrator.name;
      std::snprintf(line, sizeof line, "%-36s %8d %9d %10d %17d %8d\n", name.c_str(),
                    counts[Outcome::stable], counts[Outcome::diverged], counts[Outcome::nonfinite],
                    counts[Outcome::cg_not_converged], counts[Outcome::refused]);
      table << line;
    }
  }
  return table.str();
}

// inverted_start: of the runs that ended stable, how many still had inverted elements (a
// corotational model can settle into an inverted equilibrium instead of recovering).
std::string inverted_table(const std::vector<ModelKind>& kinds, const std::vector<Run>& runs) {
  std::ostringstream table;
  char line[160];
  for (const ModelKind& kind : kinds) {
    for (const Integrator& integrator : kind.integrators) {
      int stable = 0;
      int still_inverted = 0;
      for (const Run& run : runs) {
        if (run.model != kind.name || run.integrator != integrator.name || run.inverted_at_end < 0 ||
            run.outcome != Outcome::stable)
          continue;
        ++stable;
        still_inverted += run.inverted_at_end > 0 ? 1 : 0;
      }
      if (stable == 0) continue;
      const std::string name = kind.name + "/" + integrator.name;
      std::snprintf(line, sizeof line, "%-36s %d of %d stable inverted_start runs ended with inverted elements\n",
                    name.c_str(), still_inverted, stable);
      table << line;
    }
  }
  return table.str();
}

std::string bounds_text(const Sweep& sweep) {
  std::ostringstream text;
  text << "Outcomes (the first that applies): nonfinite = a step stayed non-finite after "
       << max_halvings << " halvings of dt; diverged = elastic + kinetic energy > " << energy_bound
       << " x E_ref (E_ref = max(initial elastic + kinetic energy, M g^2 T^2 / 2, the work of "
          "gravity on the body falling freely for the run's duration T)) or a node displacement > "
       << displacement_bound << " x the body size (largest side of its rest bounding box); "
       << "cg_not_converged = implicit Euler's CG hit its " << cg_max_iterations
       << "-iteration cap (tolerance " << format(cg_tolerance) << ") in more than "
       << 100 * cg_capped_fraction << " % of the run's steps (the run stops when it has); stable otherwise.\n"
       << "guard_events = steps that produced a non-finite value and were retried with dt "
          "halved (2, 4, 8 sub-steps).\n"
       << "Runs: T = " << format(sweep.beam_duration) << " s (beam_gravity), "
       << format(sweep.cube_duration)
       << " s (cubes) of simulated time, stopped at the first divergence; Rayleigh mass damping "
       << format(rayleigh_mass) << "/s; gravity 9.81 m/s^2 along -z; rho " << format(density)
       << " kg/m^3.\n"
       << "refused = the model refused the run: an explicit dt beyond its stability bound (the "
          "mass-spring's 2 sqrt(m_min / k_node_max), the constraint particles' min 2 sqrt(m_i / k_i)), or a brick "
          "its formulas give a non-positive stiffness.\n"
       << "fast_blade and thin_slice cut, which only the efg model does: the others are not run on them.\n";
  return text.str();
}

}  // namespace

// The summary's line on a body as built: its nodes, the elements inverted at the start of
// inverted_start, and the body's own note.
std::string set_up_note(const std::string& model, const std::string& case_name, const Body& body) {
  return model + " " + case_name + ": " + std::to_string(body.model->node_count()) + " nodes" +
         (case_name == "inverted_start" ? ", " + std::to_string(body.inverted) + " elements inverted at the start" : "") +
         (body.note.empty() ? "" : ", " + body.note);
}

// Resuming: every run of a body (a model, case and material) from the earlier sweep, or none
// when one is missing (the body is then built and the missing runs made).
std::vector<Run> all_kept(const std::map<std::string, Run>& previous, const ModelKind& kind, const std::string& case_name,
                          double youngs_modulus, double poisson_ratio, const std::vector<double>& time_steps) {
  std::vector<Run> kept;
  for (const Integrator& integrator : kind.integrators)
    for (double dt : time_steps) {
      const auto run = previous.find(run_key(kind.name, integrator.name, case_name, youngs_modulus, poisson_ratio, dt));
      if (run == previous.end()) return {};
      kept.push_back(run->second);
    }
  return kept;
}

// The runs of a set-up the model refused (a mass-spring brick of non-positive stiffness): one
// per integrator and dt, each counted as refused.
std::vector<Run> refused_runs(const ModelKind& kind, const std::string& case_name, double youngs_modulus,
                              double poisson_ratio, const std::vector<double>& time_steps) {
  std::vector<Run> runs;
  for (const Integrator& integrator : kind.integrators)
    for (double dt : time_steps) {
      Run run;
      run.model = kind.name, run.integrator = integrator.name, run.case_name = case_name;
      run.youngs_modulus = youngs_modulus, run.poisson_ratio = poisson_ratio, run.dt = dt;
      run.outcome = Outcome::refused;
      runs.push_back(std::move(run));
    }
  return runs;
}

// The runs of the part: every run of the bodies (a model, a case and a material, in the sweep's
// order) whose index `in_part` takes.
template <class InPart>
int runs_in_part(const Sweep& sweep, const std::vector<ModelKind>& kinds, const InPart& in_part) {
  int total = 0, body_index = 0;
  for (const std::string& case_name : sweep.cases)
    for (const ModelKind& kind : kinds) {
      if (!model_runs_case(kind.name, case_name)) continue;
      for (std::size_t m = 0; m < sweep.youngs_moduli.size() * sweep.poisson_ratios.size(); ++m)
        if (in_part(body_index++)) total += static_cast<int>(kind.integrators.size() * sweep.time_steps.size());
    }
  return total;
}

int run_stability_bench(const StabilityOptions& options, const std::filesystem::path& out_dir,
                        std::ostream& progress_stream) {
  const bool quick = options.quick, resume = options.resume;
  if (options.parts < 1 || options.part < 0 || options.part >= options.parts) {
    progress_stream << "stability bench: part " << options.part << " of " << options.parts << " does not exist\n";
    return 1;
  }
  // A part runs every parts-th body of the sweep (a model, case and material, in the order
  // below) with all its runs: a body serves its runs in turn and keeps its rotations' warm
  // starts from one to the next, so its runs are only reproduced bit for bit in that order.
  const auto in_part = [&](int body_index) { return body_index % options.parts == options.part; };
  try {
    std::filesystem::create_directories(out_dir);
    const Sweep sweep = make_sweep(quick);
    std::vector<std::string> left_out;
    const std::vector<ModelKind> kinds = model_kinds(&left_out);
    for (const std::string& name : left_out)
      progress_stream << "model '" << name << "' is registered but left out: this bench sets up "
                      << engine::alternatives({bench_models().begin(), bench_models().end()}) << " bodies only\n";
    const std::map<std::string, Run> previous =
        resume ? read_previous_runs(out_dir / "stability.csv", progress_stream) : std::map<std::string, Run>{};
    common::CsvWriter csv(out_dir / "stability.csv",
                          {"model", "integrator", "case", "E", "nu", "dt", "outcome", "max_energy_ratio",
                           "max_displacement", "steps", "guard_events"});
    if (resume) progress_stream << "resuming: " << previous.size() << " runs kept from the earlier sweep\n";

    const int total = runs_in_part(sweep, kinds, in_part);
    progress_stream << "stability sweep" << (quick ? " (quick)" : "") << ": " << total << " runs";
    if (options.parts > 1) progress_stream << " (part " << options.part << " of " << options.parts << ")";
    progress_stream << "\n" << bounds_text(sweep);
    const auto start = std::chrono::steady_clock::now();
    common::ProgressBar progress(progress_stream, total);
    std::vector<Run> runs;
    std::vector<std::string> set_up_notes;
    int body_index = 0;
    for (const std::string& case_name : sweep.cases) {
      const double duration = is_beam(case_name) ? sweep.beam_duration : sweep.cube_duration;
      for (const ModelKind& kind : kinds) {
        if (!model_runs_case(kind.name, case_name)) continue;
        for (double youngs_modulus : sweep.youngs_moduli) {
          for (double poisson_ratio : sweep.poisson_ratios) {
            if (!in_part(body_index++)) continue;
            const Material material{youngs_modulus, poisson_ratio, density};
            const bool first_material = youngs_modulus == sweep.youngs_moduli.front() &&
                                        poisson_ratio == sweep.poisson_ratios.front();
            // Resuming: the runs of this material already done are kept as they were; the
            // body is only built when a run is missing (or for the set-up note).
            if (!first_material) {
              const std::vector<Run> kept = all_kept(previous, kind, case_name, youngs_modulus, poisson_ratio,
                                                     sweep.time_steps);
              for (const Run& run : kept) {
                write_row(csv, run);
                runs.push_back(run);
                progress.advance();
              }
              if (!kept.empty()) continue;
            }
            Body body;
            try {
              body = make_body(kind.name, case_name, material);
            } catch (const std::invalid_argument& refusal) {
              // The model refused the set-up (a mass-spring brick with a non-positive stiffness):
              // each of its runs is counted as refused, and the sweep goes on.
              if (first_material) set_up_notes.push_back(kind.name + " " + case_name + ": refused: " + refusal.what());
              for (Run& run : refused_runs(kind, case_name, youngs_modulus, poisson_ratio, sweep.time_steps)) {
                write_row(csv, run);
                runs.push_back(std::move(run));
                progress.advance();
              }
              continue;
            }
            if (first_material) set_up_notes.push_back(set_up_note(kind.name, case_name, body));
            bool used = false;
            for (const Integrator& integrator : kind.integrators) {
              for (double dt : sweep.time_steps) {
                if (used && body.single_use) {
                  body.cutter.reset();  // before the model it refers to
                  body = make_body(kind.name, case_name, material);
                }
                const auto kept = previous.find(run_key(kind.name, integrator.name, case_name, youngs_modulus,
                                                        poisson_ratio, dt));
                if (kept != previous.end()) {
                  write_row(csv, kept->second);
                  runs.push_back(kept->second);
                  progress.advance();
                  continue;
                }
                used = true;
                progress.draw(kind.name + " " + integrator.name + " " + case_name + " E " +
                              short_modulus(youngs_modulus) + " nu " + format(poisson_ratio) +
                              " dt " + format(1e3 * dt, 3) + " ms");
                Run run = simulate(body, integrator, dt, duration);
                if (first_material && body.single_use && dt == sweep.time_steps.front()) {
                  set_up_notes.push_back(kind.name + " " + case_name + " after the run at dt " +
                                         format(1e3 * dt, 3) + " ms: " + body.note);
                }
                run.model = kind.name;
                run.integrator = integrator.name;
                run.case_name = case_name;
                run.youngs_modulus = youngs_modulus;
                run.poisson_ratio = poisson_ratio;
                write_row(csv, run);
                runs.push_back(std::move(run));
                progress.advance();
              }
            }
          }
        }
      }
    }
    progress.draw("done");
    progress.finish();
    const std::string slices = options.parts > 1 ? "Thin-slice study: run by the merge of the parts.\n"
                                                 : thin_slice_report(quick, progress_stream);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

    const std::string counts = counts_table(kinds, runs);
    progress_stream << "outcome counts (" << runs.size() << " runs, " << format(seconds, 3)
                    << " s):\n"
                    << counts << inverted_table(kinds, runs) << slices;
    std::ofstream summary(out_dir / "stability_summary.txt");
    summary << "incise bench stability" << (quick ? " --quick" : "") << "\n\n"
            << bounds_text(sweep) << "\nSet-up:\n";
    for (const std::string& note : set_up_notes) summary << "  " << note << "\n";
    summary << "\nOutcome counts (" << runs.size() << " runs, " << format(seconds, 3) << " s):\n"
            << counts << "\nInverted elements at the end of the stable inverted_start runs:\n"
            << inverted_table(kinds, runs) << "\n" << slices;

    draw_with_gnuplot(out_dir, "stability.gnuplot", plot_script("stability.png", quick, sweep, kinds, runs),
                      "stability.png", progress_stream);
    progress_stream << "wrote " << (out_dir / "stability.csv").string() << "\n";
    progress_stream << "report: "
                    << write_bench_page(out_dir, {"incise bench stability" + std::string(quick ? " --quick" : ""),
                                                  "Stiff and extreme cases: the outcome of each model, integrator, "
                                                  "case, E, nu and dt (bench/stability.cpp says what each case is).",
                                                  {{"stability.png", "Outcome map"}}, "stability_summary.txt",
                                                  "stability.csv"})
                           .string()
                    << "\n";
    return 0;
  } catch (const std::exception& error) {
    progress_stream << "\nstability bench failed: " << error.what() << "\n";
    return 1;
  }
}

}  // namespace incise::bench
