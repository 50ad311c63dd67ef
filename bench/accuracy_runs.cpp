// The runs of `incise bench accuracy` (accuracy_runs.hpp): per body, the tet10 references on a
// refinement sequence, then the rows of every model against them.
#include "bench/accuracy_runs.hpp"
#include "bench/accuracy_constraint_particles.hpp"
#include "bench/accuracy_shape_memory.hpp"

#include "physics/core/implicit_euler.hpp"
#include "physics/efg/efg_static.hpp"
#include "physics/fem/corotational_fem.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace incise::bench::accuracy {

using physics::CorotationalEfg;
using physics::CorotationalTetFem;
using physics::DeformableModel;
using physics::EfgSettings;
using physics::QuadraticTetMesh;
using physics::TetMesh;
using Clock = std::chrono::steady_clock;

Sweep make_sweep(bool quick) {
  Sweep s;
  s.quick = quick;
  s.timed_steps = quick ? 1 : 4;
  // Reference levels (10-node tets): hexagon (lattice m, layers), square (cells per side,
  // layers); the finest is the reference, the refinement check compares the last two.
  s.hexagon_levels = quick ? Levels{{1, 10}, {2, 20}, {3, 30}} : Levels{{1, 10}, {2, 20}, {3, 30}, {4, 40}};
  s.square_levels = quick ? Levels{{2, 10}, {3, 15}, {4, 20}} : Levels{{2, 10}, {4, 20}, {6, 30}, {8, 40}};
  // The cut cases (rows either side of the crack front, layers from crack_layers): their
  // tip converges at about h^1.5 even with quarter points, so they need finer meshes (sizes
  // and solve times: docs/physics-choices.md, "Accuracy references").
  s.crack_levels = quick ? Levels{{2, 0}, {3, 0}, {6, 0}, {9, 0}, {12, 0}}
                         : Levels{{2, 0}, {3, 0}, {4, 0}, {6, 0}, {8, 0}, {12, 0}, {16, 0}};
  // Linear tets (the real-time baseline), uniform, about 1k, 3k and 10k dofs (more in full).
  s.hexagon_linear = quick ? Levels{{2, 20}, {3, 30}, {4, 50}} : Levels{{2, 20}, {3, 30}, {4, 50}, {6, 80}};
  s.square_linear = quick ? Levels{{2, 20}, {4, 40}, {6, 60}} : Levels{{2, 20}, {4, 40}, {6, 60}, {10, 100}};
  // EFG: particle cells along the beam (spacing a = L / (2 cells)).
  s.efg_cells = quick ? std::vector<int>{20, 30, 50} : std::vector<int>{20, 30, 50, 70};
  // The cut cases: an odd count, so that the crack plane x = 0.1 (= cells x a) falls on
  // integration-cube faces, midway between two particle layers, instead of on a particle
  // layer that one side would own (see accuracy.cpp's file comment).
  for (int cells : s.efg_cells) s.efg_cells_cut.push_back(cells + 1);
  const EfgSettings defaults;
  s.efg_variants = {{"nb8", 8, true, defaults.support_factor, true, defaults.samples_per_axis},
                    {"nb4", 4, true, defaults.support_factor, true, defaults.samples_per_axis},
                    {"novolume", 8, false, defaults.support_factor, true, defaults.samples_per_axis},
                    {"nb8_support3", 8, true, 3.0, true, defaults.samples_per_axis},
                    {"nb8_thesis", 8, true, 3.0, false, 4}};
  // The mass-spring (uncut bodies only: it cannot be cut): bricks across the beam's y extent.
  s.mass_spring_across = quick ? std::vector<int>{2, 4, 6} : std::vector<int>{2, 4, 6, 8};
  // The constraint particles (uncut bodies only: no cutter here), voxels across as above.
  s.constraint_particles_across = s.mass_spring_across;
  s.cutter_variants = {"nb8", "nb4", "novolume"};
  return s;
}

std::vector<Body> group_bodies(const std::vector<Case>& cases) {
  std::vector<Body> bodies;
  for (const Case& c : cases) {
    auto it = std::find_if(bodies.begin(), bodies.end(),
                           [&](const Body& b) { return b.shape == c.shape && b.cut == c.cut; });
    if (it == bodies.end()) {
      bodies.push_back({c.shape, c.cut, {}});
      it = bodies.end() - 1;
    }
    it->cases.push_back(c);
  }
  return bodies;
}

std::vector<Unit> make_units(const std::vector<Body>& bodies, bool traction, bool compression) {
  std::vector<Unit> units;
  for (const Body& body : bodies) units.push_back({&body});
  if (traction) units.push_back({nullptr});
  if (compression) units.push_back({nullptr, true});
  return units;
}

int unit_runs(const Sweep& s, const Unit& unit) {
  if (unit.body == nullptr) return unit.compression ? compression_runs(s.quick) : traction_runs();
  const Body& body = *unit.body;
  const bool hexagon = body.shape == Shape::hexagon;
  return static_cast<int>((body.cut ? s.crack_levels : hexagon ? s.hexagon_levels : s.square_levels).size() +
                          (hexagon ? s.hexagon_linear : s.square_linear).size() +
                          s.efg_cells.size() * (s.efg_variants.size() + (body.cut ? s.cutter_variants.size() : 0)) +
                          (body.cut ? 0 : mass_spring_beam_runs(s.mass_spring_across)) +
                          (body.cut ? 0 : constraint_particles_runs(s.constraint_particles_across)) +
                          (body.cut || hexagon ? 0 : shape_memory_beam_runs(s.mass_spring_across)));
}

namespace {

double relative_error_pct(const Vec3& tip, const Vec3& reference) {
  return 100 * (tip - reference).norm() / reference.norm();
}

// One reference level with its name and size.
struct Level : ReferenceLevel {
  std::string name;
  int section = 0;  // the mesh size is proportional to 1 / section
};

// The runs of one body: what they share.
class BodyRuns {
 public:
  BodyRuns(const Sweep& sweep, const Body& body, Results& results, common::ProgressBar& progress)
      : s_(sweep), body_(body), results_(results), progress_(progress), hexagon_(body.shape == Shape::hexagon),
        name_(std::string(hexagon_ ? "hexagon" : "square") + (body.cut ? " cut" : "")),
        cut_suffix_(body.cut ? "_geomcut" : "") {}

  void run() {
    const auto start = Clock::now();
    references();
    tet10_rows();
    tet4_rows();
    efg_rows();
    if (!body_.cut) mass_spring_rows();
    if (!body_.cut) constraint_particles_rows();
    if (!body_.cut && !hexagon_) shape_memory_rows();
    const std::chrono::duration<double> elapsed = Clock::now() - start;
    progress_.note("  " + name_ + " body done in " + format(elapsed.count(), 3) + " s");
  }

 private:
  std::string describe(int section, int layers, bool graded) const {
    if (body_.cut && graded) {
      return "hexagon_rows" + std::to_string(section) + "_y" + std::to_string(crack_section_ny) + "_x" +
             std::to_string(layers) + "_graded";
    }
    return hexagon_ ? "hexagon_lattice" + std::to_string(section) + "_x" + std::to_string(layers) +
                          (graded ? "_graded" : "")
                    : "square_" + std::to_string(section) + "x" + std::to_string(section) + "_x" +
                          std::to_string(layers) + (graded ? "_graded" : "");
  }

  Timing time(DeformableModel& model, const std::vector<uint8_t>& fixed, const Vector& load) const {
    return time_steps(model, fixed, load, s_.timed_steps);
  }

  // 10-node tets on a refinement sequence graded towards the singular lines (clamp, crack
  // front); the finest is the reference of each case.
  void references();
  void note_richardson(const Case& c, size_t i) const;
  void tet10_rows();
  void tet4_rows();
  void efg_rows();
  void efg_row(const EfgVariant& variant, bool cutter, int cells);
  void mass_spring_rows();
  void constraint_particles_rows();
  void shape_memory_rows();

  const Sweep& s_;
  const Body& body_;
  Results& results_;
  common::ProgressBar& progress_;
  const bool hexagon_;
  const std::string name_, cut_suffix_;
  std::vector<Level> levels_;
};

void BodyRuns::references() {
  const Levels& reference_levels = body_.cut ? s_.crack_levels : hexagon_ ? s_.hexagon_levels : s_.square_levels;
  for (const auto& [section, layers] : reference_levels) {
    const std::string name = describe(
        section, body_.cut ? static_cast<int>(crack_layers(section, crack_grading_power).size()) - 1 : layers, true);
    progress_.draw(name_ + " reference tet10 " + name);
    Level level;
    static_cast<ReferenceLevel&>(level) = solve_reference_level(body_.cases, section, layers);
    level.name = name;
    level.section = section;
    levels_.push_back(std::move(level));
    progress_.step(name_ + " reference tet10 " + levels_.back().name);
  }
  for (size_t i = 0; i < body_.cases.size(); ++i) {
    const Case& c = body_.cases[i];
    Reference reference;
    reference.element = body_.cut ? "tet10 static, conforming cut (nodes on x = 0.1, z > 0 duplicated)" : "tet10 static";
    for (size_t l = 0; l < levels_.size(); ++l) {
      Reference::Level entry{levels_[l].name, 3 * static_cast<long long>(levels_[l].quadratic.mesh.rest.size() / 3),
                             levels_[l].tips[i], 0};
      if (l > 0) entry.change_pct = relative_error_pct(levels_[l - 1].tips[i], levels_[l].tips[i]);
      reference.levels.push_back(entry);
      progress_.note("  " + c.name + " reference tet10 " + entry.mesh + " (" + std::to_string(entry.dofs) +
                     " dofs): tip " + mm(entry.tip) +
                     (l > 0 ? ", change from the coarser mesh " + format(entry.change_pct, 3) + " %" : ""));
    }
    reference.tip = levels_.back().tips[i];
    const double last_change = reference.levels.back().change_pct;
    if (levels_.size() >= 3) note_richardson(c, i);
    progress_.note("  " + c.name + " reference: " + (last_change < 0.2 ? "converged" : "NOT converged") +
                   " to 0.2 % (the two finest differ by " + format(last_change, 3) + " %)" +
                   (c.name == "b1" ? "; beam theory tip z " + format(-1e3 * b1_beam_theory_tip, 4) + " mm" : ""));
    results_.references[c.name] = reference;
  }
}

// Richardson: the three finest levels along the finest tip's direction, s(h) = s0 + C h^p with
// h = 1 / section; the observed rate p by bisection.
void BodyRuns::note_richardson(const Case& c, size_t i) const {
  const size_t n = levels_.size();
  const Vec3 direction = levels_[n - 1].tips[i].normalized();
  const double s1 = levels_[n - 3].tips[i].dot(direction), s2 = levels_[n - 2].tips[i].dot(direction),
               s3 = levels_[n - 1].tips[i].dot(direction);
  const double h1 = 1.0 / levels_[n - 3].section, h2 = 1.0 / levels_[n - 2].section, h3 = 1.0 / levels_[n - 1].section;
  const double ratio = (s2 - s1) / (s3 - s2);
  const auto model_ratio = [&](double p) {
    return (std::pow(h1, p) - std::pow(h2, p)) / (std::pow(h2, p) - std::pow(h3, p));
  };
  if (ratio > model_ratio(0.25) && ratio < model_ratio(8.0)) {
    double low = 0.25, high = 8.0;
    for (int it = 0; it < 100; ++it) {
      const double mid = 0.5 * (low + high);
      (model_ratio(mid) < ratio ? low : high) = mid;
    }
    const double p = 0.5 * (low + high);
    const double extrapolated = s3 + (s3 - s2) * std::pow(h3, p) / (std::pow(h2, p) - std::pow(h3, p));
    progress_.note("  " + c.name + " reference Richardson (three finest, observed rate " + format(p, 3) +
                   "): extrapolated tip " + format(1e3 * extrapolated, 6) +
                   " mm along the finest tip; the finest differs from it by " +
                   format(100 * std::abs(s3 / extrapolated - 1), 3) + " %");
  } else {
    progress_.note("  " + c.name +
                   " reference Richardson: the three finest levels do not converge monotonically at a rate in "
                   "[0.25, 8] (ratio " + format(ratio, 3) + ")");
  }
}

// tet10 rows: the coarser reference levels up to 40k dofs (beyond, one implicit step with
// Jacobi-CG takes minutes), timed with the assembled linear model.
void BodyRuns::tet10_rows() {
  for (size_t l = 0; l + 1 < levels_.size(); ++l) {
    const Level& level = levels_[l];
    const QuadraticTetMesh& mesh = level.quadratic.mesh;
    if (mesh.rest.size() > 40000) continue;
    const std::unique_ptr<DeformableModel> model = make_assembled_linear_model(
        physics::assemble_stiffness(mesh, beam_material), mesh.rest, quadratic_lumped_masses(mesh, beam_material.density));
    for (size_t i = 0; i < body_.cases.size(); ++i) {
      const Case& c = body_.cases[i];
      const Timing timing =
          time(*model, level.fixed, physics::assemble_body_load(mesh, beam_material.density * c.acceleration));
      results_.rows.push_back({c.name, "fem", "tet10" + cut_suffix_, level.name,
                               3 * static_cast<long long>(mesh.rest.size() / 3), static_cast<long long>(mesh.tets.size()),
                               timing.ms_per_step, timing.cg_iterations,
                               relative_error_pct(level.tips[i], results_.references[c.name].tip), timing.converged});
      take_solver(results_.rows.back(), timing);
    }
  }
}

// tet4 rows: the corotational linear tets on uniform meshes.
void BodyRuns::tet4_rows() {
  for (const auto& [section, layers] : hexagon_ ? s_.hexagon_linear : s_.square_linear) {
    const std::string name = describe(section, layers, false);
    progress_.draw(name_ + " fem tet4 " + name);
    TetMesh mesh = case_mesh(body_.cases.front(), section, layers, false);
    if (body_.cut) open_cut(mesh.rest, mesh.tets);
    const std::vector<uint8_t> fixed = clamped_nodes(mesh.rest);
    CorotationalTetFem model(mesh, beam_material);
    std::vector<Vector> loads;
    for (const Case& c : body_.cases) loads.push_back(physics::gravity_forces(model.lumped_masses(), c.acceleration));
    const std::vector<Vector> solutions = solve_static_loads(physics::assemble_stiffness(mesh, beam_material), loads, fixed);
    for (size_t i = 0; i < body_.cases.size(); ++i) {
      const Case& c = body_.cases[i];
      const Timing timing = time(model, fixed, loads[i]);
      results_.rows.push_back({c.name, "fem", "tet4" + cut_suffix_, name, 3 * static_cast<long long>(mesh.rest.size() / 3),
                               static_cast<long long>(mesh.tets.size()), timing.ms_per_step, timing.cg_iterations,
                               relative_error_pct(tip_mean(mesh, solutions[i], nullptr), results_.references[c.name].tip),
                               timing.converged});
      take_solver(results_.rows.back(), timing);
    }
    progress_.step(name_ + " fem tet4 " + name);
  }
}

// EFG rows: per resolution, every variant (with the geometry cut for the cut cases), then for
// the cut cases the cutter variants on the uncut model.
void BodyRuns::efg_rows() {
  for (int cells : body_.cut ? s_.efg_cells_cut : s_.efg_cells) {
    for (const EfgVariant& variant : s_.efg_variants) efg_row(variant, false, cells);
    if (!body_.cut) continue;
    for (const std::string& name : s_.cutter_variants) {
      const auto it = std::find_if(s_.efg_variants.begin(), s_.efg_variants.end(),
                                   [&](const EfgVariant& v) { return v.name == name; });
      efg_row(*it, true, cells);
    }
  }
}

// One EFG model's rows, its tip sampled at the centroids of a fine triangulation of the face.
void BodyRuns::efg_row(const EfgVariant& variant, bool cutter, int cells) {
  const std::string variant_name = variant.name + (cutter ? "_cutter" : cut_suffix_);
  const double spacing = beam_length / (2 * cells);
  const std::string resolution = "a" + format(1e3 * spacing, 3) + "mm";
  progress_.draw(name_ + " efg " + variant_name + " " + resolution);
  EfgSettings settings;
  settings.spacing = spacing;
  settings.neighbours = variant.neighbours;
  settings.estimate_volumes = variant.estimate_volumes;
  settings.support_factor = variant.support_factor;
  settings.centroid_points = variant.centroid_points;
  settings.samples_per_axis = variant.samples_per_axis;
  physics::VolumeCutReport report;
  const std::unique_ptr<CorotationalEfg> built = make_case_efg(body_.shape, body_.cut, cutter, settings, &report);
  CorotationalEfg& model = *built;
  if (cutter) {
    progress_.note("  " + name_ + " efg " + variant_name + " " + resolution + ": the cutter severed " +
                   std::to_string(report.particle_links_severed) + " particle links and " +
                   std::to_string(report.element_links_severed) + " element links (" +
                   std::to_string(report.candidates) + " candidates), re-selected " +
                   std::to_string(report.elements_reselected) + " elements, " +
                   std::to_string(report.elements_isolated) + " isolated, " +
                   std::to_string(report.reselection_failures) + " failures (CCD " + format(report.ms_ccd, 3) +
                   " ms, topology " + format(report.ms_topology, 3) + " ms)");
    results_.cut_reports[variant_name + " " + resolution] = report;
  }
  const std::vector<uint8_t> fixed = clamped_nodes(model.rest_positions());
  std::vector<Vector> loads;
  for (const Case& c : body_.cases) loads.push_back(physics::gravity_forces(model.lumped_masses(), c.acceleration));
  const std::vector<Vector> solutions = solve_static_loads(physics::assemble_stiffness(model), loads, fixed);
  const TipFace face = make_tip_face(body_.shape);
  const physics::SurfaceEmbedding embedding = model.embed_surface(face.points);
  for (size_t i = 0; i < body_.cases.size(); ++i) {
    const Case& c = body_.cases[i];
    const Vec3 tip = efg_tip_mean(model, embedding, face, solutions[i]);
    const Timing timing = time(model, fixed, loads[i]);
    results_.rows.push_back({c.name, "efg", variant_name, resolution, 3 * static_cast<long long>(model.node_count()),
                             model.element_count(), timing.ms_per_step, timing.cg_iterations,
                             relative_error_pct(tip, results_.references[c.name].tip), timing.converged, tip});
    take_solver(results_.rows.back(), timing);
  }
  progress_.step(name_ + " efg " + variant_name + " " + resolution);
}

TimeSteps step_timer(int steps) {
  return [steps](DeformableModel& model, const std::vector<uint8_t>& fixed, const Vector& load) {
    const Timing timing = time_steps(model, fixed, load, steps);
    return StepTiming{timing.ms_per_step, timing.cg_iterations, timing.converged};
  };
}

void BodyRuns::mass_spring_rows() {
  const Shape shape = body_.shape;
  MassSpringBeam beam{[shape](const Vec3& p) { return inside_shape(shape, p); }, box_min(shape), box_max(shape),
                      !hexagon_, beam_material.youngs_modulus, beam_material.poisson_ratio, beam_material.density};
  std::vector<MassSpringCase> spring_cases;
  for (const Case& c : body_.cases) spring_cases.push_back({c.name, c.acceleration, results_.references[c.name].tip});
  for (const MassSpringRow& r :
       mass_spring_beam_rows(beam, spring_cases, s_.mass_spring_across, step_timer(s_.timed_steps), progress_)) {
    results_.rows.push_back(from_mass_spring(r));
  }
}

void BodyRuns::constraint_particles_rows() {
  for (Row& row : accuracy::constraint_particles_rows(body_.shape, body_.cases, results_.references,
                                                      s_.constraint_particles_across, s_.timed_steps, progress_)) {
    results_.rows.push_back(std::move(row));
  }
}

// The shape memory on the square beam (b1) at the mass-spring's sizes; not on the voxelised hexagon.
void BodyRuns::shape_memory_rows() {
  for (Row& row : shape_memory_beam_rows(body_.cases, results_.references, s_.mass_spring_across, s_.timed_steps,
                                         progress_))
    results_.rows.push_back(std::move(row));
}

}  // namespace

void run_unit(const Sweep& sweep, const Unit& unit, Results& results, common::ProgressBar& progress) {
  if (unit.body != nullptr) {
    BodyRuns(sweep, *unit.body, results, progress).run();
    return;
  }
  if (unit.compression) {
    for (Row& row : compression_rows(sweep.quick, progress)) results.rows.push_back(std::move(row));
    return;
  }
  for (const MassSpringRow& r : traction_rows(step_timer(sweep.timed_steps), progress))
    results.rows.push_back(from_mass_spring(r));
}

}  // namespace incise::bench::accuracy
