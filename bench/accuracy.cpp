// The error-against-run-time report (issue 3; Magnoux 2020 Table 4.1 with our dimensions).
//
// Cases: a beam of regular hexagonal section (circumradius 15 mm, vertices on +-y), 0.2 m
// along +x, clamped at x = 0, E = 10 MPa, nu = 0.3, rho = 1000, under a body force of 9.81
// m/s^2 along -z (`bend`) or +x (`stretch`); the `_cut` cases add a zero-thickness planar cut
// at x = 0.1 m from the top (z max) down to z = 0 across the whole width; `b1` is the square
// beam 0.2 x 0.02 x 0.02 under its own weight.
//
// The cut, made before any solve:
// - EFG with the cutter (variant suffix `_cutter`; physics/cut/volume_cut.hpp, issue 4): the
//   uncut model is cut by one step of a straight blade along y, wider than the beam, moving
//   from above the grid down to the crack front with the particles at rest; the cutter severs
//   the links the blade touches (continuous collision) and re-selects the broken
//   neighbourhoods (each severed corner replaced by its mirror through the nearest kept one,
//   then by graph distance), which gives the geometry cut's neighbourhoods exactly: the two
//   variants' errors agree to 0.01 %. (By graph distance alone the tie between the particle behind
//   the kept face and those beside or below it makes irregular neighbourhoods and a cut beam much
//   farther off: docs/physics-choices.md, "Cutting".) Where the cut lies, relative to the grids:
//   the cut cases use an odd number of particle cells along the beam, so x = 0.1 is a plane of
//   integration-cube faces, midway between the particle layers at 0.1 +- a and the integration
//   points at 0.1 +- a/2; the blade runs on it, no grid point within a/2. (With an even count a
//   particle layer lies on the plane and belongs to one side, the other side's crack face being a
//   spacing away from its particles: the cut beams' errors grow severalfold;
//   docs/physics-choices.md, "Accuracy references".) The blade's edge stops at z = 1e-3 a, just
//   above the particle row on the crack front z = 0 (see the grid alignment below): the links from
//   the integration points above the front to the front particles across the plane cross it a/3
//   above z = 0 and are cut, those from the points below it are not, and the row's own links along
//   x, which a blade ending exactly on z = 0 would touch at t = 1, stay (the front is shared by
//   both sides, as the reference's front nodes are).
// - EFG with the geometry cut (suffix `_geomcut`), for comparison: integration-point-to-particle
//   links that cross the cut rectangle are removed at build time and the neighbourhood
//   re-selected on the element's own side (EfgSettings::cuts);
// - FEM (suffix `_geomcut`): a conforming mesh whose nodes on the cut (x = 0.1, z > 0) are
//   duplicated for the tets on the x < 0.1 side.
//
// Error: |mean tip displacement - reference| / |reference| x 100, the mean taken over the tip
// face x = L (area-weighted: exact face integrals for the tets; for EFG, the MLS displacement
// at the centroids of a fine triangulation of the face, through the surface embedding).
// Reference: 10-node tets solved statically (CHOLMOD) on the finest mesh of a refinement
// sequence graded towards the clamp and the crack front, printed in the progress and written
// to references.json; for the cut cases with quarter-point elements at the crack front (the
// midside nodes of the edges leaving it at a quarter of the edge, isoparametric tets), which
// carry its 1 / sqrt r strain, on sections of graded rows (hexagon_row_section) with x layers
// matched to them near the crack (crack_layers): the tip still converges at about h^1.5, so
// the quick run goes to 12 rows, the full run to 16 (docs/physics-choices.md, "Accuracy
// references", has the mesh study and the solve sizes and times).
//
// Rows: efg nb8 (8 cell corners with the model's defaults: h = 1.1 x the farthest corner, 8^3 volume samples,
// partial-cube points at the inside centroid; corotational_efg.hpp says why), nb4, novolume
// (nb8 with every touched cube counted whole), nb8_support3 (h = 3 x the farthest corner, the
// literal reading of the thesis's constant) and nb8_thesis (that support, cube-centre points
// and 4^3 samples: the thesis's literal model), each `_geomcut` for the cut cases, plus
// nb8_cutter, nb4_cutter and novolume_cutter; for the cut cases the EFG grid's z extent is
// widened so that a particle row lies on the crack front (the cutter needs it as much as the
// geometry cut: with the front mid-cell, between particle rows at z = +-a, nb8_cutter's
// stretch_cut tip moves by +69 % at a = 5 mm and +21 % at 2 mm); fem tet4 (the
// corotational real-time baseline) and tet10 (the coarser reference meshes; timed with their
// assembled linear stiffness and HRZ-lumped masses, as no dynamic tet10 model exists);
// mass_spring and mass_spring_uncorrected (Baudet's bricks with and without their correction
// forces) on the uncut cases, and the `traction` case of the spring networks' measured E and nu
// with Van Gelder's springs beside (bench/accuracy_mass_spring.hpp); constraint_particles
// (Dionne's particles on the same voxels split 5 tets each, k_D and k_V per tet volume calibrated
// on the lattice's homogenised E and nu; bench/accuracy_constraint_particles.hpp) on the uncut cases;
// shape_memory (Promayon's VN1 lattice, k_e from E by the calibration) on b1, and the
// `compression` case of Promayon's models against the FEM (bench/accuracy_shape_memory.hpp).
//
// Equilibrium: each model's linear static solution (sparse direct solve of its stiffness at
// rest), i.e. the small-strain problem the reference solves. ms_per_step: the mean wall time
// of implicit Euler steps at dt = 1/60 from rest under the load (Rayleigh mass damping 2/s),
// with the scenes' CG (tolerance 1e-6, at most 2000 iterations) and their default
// preconditioner where the model has a rest stiffness (EFG: multigrid_current; tet4: the same
// factor's rest-system cycle, `multigrid`; its factor built once before the timed steps, the
// build in preconditioner_build_ms), else Jacobi; cg_iterations is their mean iteration count.
// The rows with a factor are timed again with today's Jacobi CG (ms_per_step_jacobi,
// cg_iterations_jacobi, speedup_vs_jacobi): the solver's gain at the same error, since the
// error is the static solution's and the tolerance is the same.
//
// The code: the beams' meshes (accuracy_meshes.cpp) and models (accuracy_models.cpp), the runs
// per body (accuracy_runs.cpp), the report (accuracy_report.cpp); here the whole report, a
// batch's part of it and the join of the parts, and the tests' entry points.
#include "bench/accuracy.hpp"
#include "bench/accuracy_runs.hpp"

#include "common/progress_bar.hpp"

#include "physics/core/implicit_euler.hpp"
#include "physics/efg/efg_static.hpp"
#include "physics/fem/corotational_fem.hpp"
#include "physics/solve/rest_factor.hpp"

#include <algorithm>
#include <chrono>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace incise::bench {

using namespace accuracy;
using physics::CorotationalEfg;
using physics::EfgSettings;

namespace {

// The command line the report stands for, as its page's title.
std::string title(const AccuracyOptions& options) {
  return std::string("incise bench accuracy") + (options.quick ? " --quick" : "") +
         (options.cases.empty() ? "" : " --cases " + options.cases);
}

// The parts' results into one report: every case must have its reference (all parts joined).
void join_parts(const AccuracyOptions& options, const std::vector<Case>& cases, bool traction, bool compression,
                const std::filesystem::path& out_dir,
                std::chrono::steady_clock::time_point start, std::ostream& progress) {
  Results results;
  for (const std::filesystem::path& dir : options.join) results.add(read_part_results(dir / "accuracy_part.json"));
  std::string missing;
  for (const Case& c : cases) {
    if (results.references.count(c.name) == 0) missing += " " + c.name;
  }
  if (traction && std::none_of(results.rows.begin(), results.rows.end(), [](const Row& r) { return r.case_name == "traction"; }))
    missing += " traction";
  if (compression &&
      std::none_of(results.rows.begin(), results.rows.end(), [](const Row& r) { return r.case_name == "compression"; }))
    missing += " compression";
  if (!missing.empty()) throw std::runtime_error("the joined parts have no rows for the cases" + missing);
  progress << title(options) << ": " << options.join.size()
           << " parts joined, " << results.rows.size() << " rows\n";
  write_report(title(options), cases, results, out_dir, start, progress);
}

// The cases --cases names (all without it), in the report's order; whether traction and
// compression are among them.
std::vector<Case> select_cases(const std::string& names, bool& traction, bool& compression) {
  const std::vector<Case> all = all_cases();
  traction = compression = names.empty();
  if (names.empty()) return all;
  std::vector<std::string> wanted;
  std::stringstream list(names);
  for (std::string name; std::getline(list, name, ',');) {
    const std::vector<std::string> known = accuracy_case_names();
    if (std::find(known.begin(), known.end(), name) == known.end())
      throw std::runtime_error("--cases: '" + name + "' is not a case (" + accuracy_case_list() + ")");
    wanted.push_back(name);
  }
  std::vector<Case> cases;
  for (const Case& c : all) {
    if (std::find(wanted.begin(), wanted.end(), c.name) != wanted.end()) cases.push_back(c);
  }
  traction = std::find(wanted.begin(), wanted.end(), "traction") != wanted.end();
  compression = std::find(wanted.begin(), wanted.end(), "compression") != wanted.end();
  return cases;
}

}  // namespace

std::vector<std::string> accuracy_case_names() {
  std::vector<std::string> names;
  for (const Case& c : all_cases()) names.push_back(c.name);
  names.push_back("traction");
  names.push_back("compression");
  return names;
}

std::string accuracy_case_list() {
  std::string list;
  for (const std::string& name : accuracy_case_names()) list += (list.empty() ? "" : ", ") + name;
  return list;
}

int run_accuracy_bench(const AccuracyOptions& options, const std::filesystem::path& out_dir, std::ostream& progress_stream) {
  try {
    // The reference solves' bits must not depend on whether a timed row has built a rest factor
    // before them (which sets one BLAS thread): a part of a batch runs other rows first than
    // the whole report does.
    physics::use_single_threaded_blas();
    std::filesystem::create_directories(out_dir);
    const auto start = std::chrono::steady_clock::now();
    bool traction = true, compression = true;
    const std::vector<Case> cases = select_cases(options.cases, traction, compression);
    if (!options.join.empty()) {
      join_parts(options, cases, traction, compression, out_dir, start, progress_stream);
      return 0;
    }
    const Sweep sweep = make_sweep(options.quick);
    const std::vector<Body> bodies = group_bodies(cases);
    // A part runs the units whose index modulo parts is its own (a body with all its runs:
    // its references serve only its cases).
    std::vector<Unit> units;
    const std::vector<Unit> all_units = make_units(bodies, traction, compression);
    for (size_t u = 0; u < all_units.size(); ++u) {
      if (!options.as_part || static_cast<int>(u % options.parts) == options.part) units.push_back(all_units[u]);
    }
    int total = 0;
    for (const Unit& unit : units) total += unit_runs(sweep, unit);
    common::ProgressBar progress(progress_stream, total);
    progress.note(title(options) + (options.as_part ? " part " + std::to_string(options.part) + "/" + std::to_string(options.parts) : "") +
                  ": " + std::to_string(cases.size() + (traction ? 1 : 0) + (compression ? 1 : 0)) + " cases, output in " + out_dir.string());
    Results results;
    for (const Unit& unit : units) run_unit(sweep, unit, results, progress);
    progress.finish();
    if (!options.as_part) {
      write_report(title(options), cases, results, out_dir, start, progress_stream);
      return 0;
    }
    write_part_results(out_dir / "accuracy_part.json", results);
    write_rows_csv(out_dir / "accuracy.csv", cases, results.rows);
    progress_stream << "wrote " << (out_dir / "accuracy_part.json").string() << " and accuracy.csv ("
                    << results.rows.size() << " rows of " << units.size() << " of the " << all_units.size()
                    << " units)\n";
    return 0;
  } catch (const std::exception& error) {
    progress_stream << "\nbench accuracy failed: " << error.what() << "\n";
    return 1;
  }
}

CutBeamTips cut_beam_reference(int rows) {
  const std::vector<Case> all = all_cases();
  std::vector<Case> cut;
  for (const Case& c : all) {
    if (c.cut) cut.push_back(c);
  }
  const ReferenceLevel level = solve_reference_level(cut, rows, 0);
  return {level.tips[0], level.tips[1], 3 * static_cast<long long>(level.quadratic.mesh.rest.size() / 3)};
}

CutBeamTips cut_beam_efg(int cells, bool cutter) {
  const std::vector<Case> all = all_cases();
  EfgSettings settings;
  settings.spacing = beam_length / (2 * cells);
  const std::unique_ptr<CorotationalEfg> model = make_case_efg(Shape::hexagon, true, cutter, settings);
  const std::vector<uint8_t> fixed = clamped_nodes(model->rest_positions());
  std::vector<Vector> loads;
  for (const Case& c : all) {
    if (c.cut) loads.push_back(physics::gravity_forces(model->lumped_masses(), c.acceleration));
  }
  const std::vector<Vector> solutions = solve_static_loads(physics::assemble_stiffness(*model), loads, fixed);
  const TipFace face = make_tip_face(Shape::hexagon);
  const physics::SurfaceEmbedding embedding = model->embed_surface(face.points);
  return {efg_tip_mean(*model, embedding, face, solutions[0]), efg_tip_mean(*model, embedding, face, solutions[1]),
          3 * static_cast<long long>(model->node_count())};
}

}  // namespace incise::bench

