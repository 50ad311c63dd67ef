// The report's models (bench/accuracy_beams.hpp): the static solves (CHOLMOD), the timing of
// implicit Euler steps, the tet10 reference levels and the EFG models of the beams, cut by the
// geometry or by the cutter.
#include "bench/accuracy_beams.hpp"

#include "engine/scene.hpp"
#include "physics/core/implicit_euler.hpp"
#include "physics/solve/rest_preconditioner.hpp"
#include "physics/efg/efg_static.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/LU>
#include <Eigen/SparseCholesky>

#include <chrono>
#include <cmath>
#include <stdexcept>

namespace incise::bench::accuracy {

using physics::CorotationalEfg;
using physics::DeformableModel;
using physics::EfgSettings;
using physics::QuadraticTetMesh;
using physics::SparseMatrix;
using physics::TetMesh;
using Index = Eigen::Index;
using Clock = std::chrono::steady_clock;

namespace {

// A linear model from an assembled stiffness (the 10-node tets have no corotational model):
// drives the same implicit Euler integrator for the timing of the tet10 rows.
class AssembledLinearModel final : public DeformableModel {
 public:
  AssembledLinearModel(SparseMatrix stiffness, Vector rest, Vector masses)
      : stiffness_(std::move(stiffness)), rest_(std::move(rest)), masses_(std::move(masses)) {}
  int node_count() const override { return static_cast<int>(masses_.size()); }
  const Vector& rest_positions() const override { return rest_; }
  const Vector& lumped_masses() const override { return masses_; }
  void update_rotations(const Vector&) override {}
  void add_elastic_forces(const Vector& x, Vector& f) const override { f -= stiffness_ * (x - rest_); }
  void add_stiffness_product(const Vector& p, Vector& out) const override { out += stiffness_ * p; }
  void add_stiffness_diagonal(Vector& diagonal) const override { diagonal += stiffness_.diagonal(); }
  double elastic_energy(const Vector& x) const override {
    const Vector u = x - rest_;
    return 0.5 * u.dot(stiffness_ * u);
  }

  std::unique_ptr<DeformableModel> clone() const override { return std::make_unique<AssembledLinearModel>(*this); }
 private:
  SparseMatrix stiffness_;
  Vector rest_;
  Vector masses_;
};

}  // namespace

std::unique_ptr<DeformableModel> make_assembled_linear_model(SparseMatrix stiffness, Vector rest, Vector masses) {
  return std::make_unique<AssembledLinearModel>(std::move(stiffness), std::move(rest), std::move(masses));
}

// HRZ lumping of the 10-node tet (the row sums give negative corner masses): the consistent
// diagonal, integral N_a^2 = V/70 (corner) and 8V/105 (midpoint), scaled to the element mass,
// gives rho V/36 per corner and 4 rho V/27 per midpoint.
Vector quadratic_lumped_masses(const QuadraticTetMesh& mesh, double density) {
  Vector masses = Vector::Zero(mesh.rest.size() / 3);
  for (const auto& tet : mesh.tets) {
    physics::Mat3 shape;
    for (int c = 0; c < 3; ++c) {
      shape.col(c) = mesh.rest.segment<3>(3 * tet[c + 1]) - mesh.rest.segment<3>(3 * tet[0]);
    }
    const double mass = density * shape.determinant() / 6;
    for (int c = 0; c < 4; ++c) masses[tet[c]] += mass / 36;
    for (int e = 4; e < 10; ++e) masses[tet[e]] += 4 * mass / 27;
  }
  return masses;
}

// Solves K u = load for several loads with one factorisation, u = 0 on the fixed nodes.
std::vector<Vector> solve_static_loads(const SparseMatrix& stiffness, const std::vector<Vector>& loads,
                                       const std::vector<uint8_t>& fixed) {
  std::vector<Index> free_of(stiffness.rows(), -1);
  Index free_count = 0;
  for (Index i = 0; i < stiffness.rows(); ++i) {
    if (fixed[i / 3] == 0) free_of[i] = free_count++;
  }
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(stiffness.nonZeros());
  for (Index column = 0; column < stiffness.outerSize(); ++column) {
    for (SparseMatrix::InnerIterator it(stiffness, column); it; ++it) {
      if (free_of[it.row()] >= 0 && free_of[it.col()] >= 0) {
        triplets.emplace_back(free_of[it.row()], free_of[it.col()], it.value());
      }
    }
  }
  SparseMatrix reduced(free_count, free_count);
  reduced.setFromTriplets(triplets.begin(), triplets.end());
  // CHOLMOD's supernodal Cholesky (dense BLAS on supernodes): on the references many times
  // faster than SimplicialLDLT (docs/physics-choices.md, "Accuracy references"), which stays
  // as the fallback for a matrix that is not positive definite, and is used under
  // ThreadSanitizer: CHOLMOD's OpenMP threads and OpenBLAS's synchronise in code TSan does not
  // see (libgomp, spin waits), which it reports as races (test_cut_beam_accuracy's solves are
  // small enough for either).
#if defined(__SANITIZE_THREAD__)
  constexpr bool use_cholmod = false;
#else
  constexpr bool use_cholmod = true;
#endif
  Eigen::CholmodSupernodalLLT<SparseMatrix> cholmod;
  if (use_cholmod) cholmod.compute(reduced);
  std::unique_ptr<Eigen::SimplicialLDLT<SparseMatrix>> ldlt;
  if (!use_cholmod || cholmod.info() != Eigen::Success) {
    ldlt = std::make_unique<Eigen::SimplicialLDLT<SparseMatrix>>(reduced);
    if (ldlt->info() != Eigen::Success) throw std::runtime_error("static solve: factorisation failed");
  }
  std::vector<Vector> solutions;
  for (const Vector& load : loads) {
    Vector reduced_load(free_count);
    for (Index i = 0; i < stiffness.rows(); ++i) {
      if (free_of[i] >= 0) reduced_load[free_of[i]] = load[i];
    }
    const Vector reduced_solution = ldlt ? Vector(ldlt->solve(reduced_load)) : Vector(cholmod.solve(reduced_load));
    Vector u = Vector::Zero(stiffness.rows());
    for (Index i = 0; i < stiffness.rows(); ++i) {
      if (free_of[i] >= 0) u[i] = reduced_solution[free_of[i]];
    }
    if (!u.allFinite()) throw std::runtime_error("static solve: the solution is not finite");
    solutions.push_back(std::move(u));
  }
  return solutions;
}

namespace {

// `steps` implicit Euler steps from rest under the load at dt = 1/60 (Rayleigh mass damping
// 2/s, CG to 1e-6, at most 2000 iterations), preconditioned with `factor` (nullptr: Jacobi).
Timing run_steps(DeformableModel& model, const std::vector<uint8_t>& fixed, const Vector& load, int steps,
                 const physics::RestFactor* factor, bool assembled_system) {
  physics::State state{model.rest_positions(), Vector::Zero(model.rest_positions().size())};
  physics::ImplicitEulerSettings settings;
  settings.dt = 1.0 / 60;
  settings.rayleigh_mass = 2;  // the scenes' default damping
  settings.cg.tolerance = 1e-6;
  settings.cg.max_iterations = 2000;
  settings.assembled_system = assembled_system;
  Timing timing;
  const auto start = Clock::now();
  for (int step = 0; step < steps; ++step) {
    const physics::StepReport report =
        physics::implicit_euler_step(model, state, fixed, load, {}, settings, nullptr, factor);
    timing.cg_iterations += report.cg.iterations;
    timing.converged = timing.converged && report.cg.converged && !report.nonfinite;
  }
  const std::chrono::duration<double, std::milli> elapsed = Clock::now() - start;
  timing.ms_per_step = elapsed.count() / steps;
  timing.cg_iterations /= steps;
  return timing;
}

}  // namespace

// The scenes' preconditioner (engine::SolverSpec's default, its smoothing degree the engine's),
// its factor built once before the timed steps, and today's Jacobi CG beside it.
Timing time_steps(DeformableModel& model, const std::vector<uint8_t>& fixed, const Vector& load, int steps) {
  const engine::SolverSpec solver;
  physics::PreconditionerSettings preconditioner;
  preconditioner.kind = physics::PreconditionerKind::multigrid_current;
  preconditioner.smoothing = engine::multigrid_smoothing_degree(solver);
  const double dt = 1.0 / 60, rayleigh_mass = 2;
  physics::RestPreconditioner rest;
  physics::PreconditionerReport report;
  const auto build_start = Clock::now();
  const physics::RestFactor* factor =
      rest.prepare(preconditioner, model, fixed, 1 + dt * rayleigh_mass, dt * dt, 0, 0, model.executor(), report);
  const std::chrono::duration<double, std::milli> build = Clock::now() - build_start;
  if (!factor) return run_steps(model, fixed, load, steps, nullptr, false);  // no rest stiffness: Jacobi
  // The step smooths with the current system where the model assembles one (EFG); the others
  // (tet FEM) run the same factor's rest-system cycle, as the engine's bodies do.
  const bool current = dynamic_cast<const CorotationalEfg*>(&model) != nullptr;
  Timing timing = run_steps(model, fixed, load, steps, factor, current);
  timing.preconditioner = current ? "multigrid_current" : "multigrid";
  timing.build_ms = build.count();
  const Timing jacobi = run_steps(model, fixed, load, steps, nullptr, false);
  timing.jacobi_ms_per_step = jacobi.ms_per_step;
  timing.jacobi_cg_iterations = jacobi.cg_iterations;
  return timing;
}

// ---------------------------------------------------------------------------------------------
// The models of a case, shared by the report and by the tests' entry points (accuracy.hpp).

ReferenceLevel solve_reference_level(const std::vector<Case>& cases, int section, int layers) {
  const Case& first = cases.front();
  ReferenceLevel level;
  level.linear = case_mesh(first, section, layers, true);
  level.quadratic = make_quadratic(level.linear);
  if (first.cut) {
    quarter_points_at_crack_front(level.quadratic);
    open_cut(level.quadratic.mesh.rest, level.quadratic.mesh.tets);
  }
  level.fixed = clamped_nodes(level.quadratic.mesh.rest);
  std::vector<Vector> loads;
  for (const Case& c : cases) {
    loads.push_back(physics::assemble_body_load(level.quadratic.mesh, beam_material.density * c.acceleration));
  }
  const std::vector<Vector> solutions =
      solve_static_loads(physics::assemble_stiffness(level.quadratic.mesh, beam_material), loads, level.fixed);
  for (const Vector& u : solutions) level.tips.push_back(tip_mean(level.linear, u, &level.quadratic));
  return level;
}

// The EFG models' tip face: the centroids of a fine triangulation, with their areas.
TipFace make_tip_face(Shape shape) {
  const Section face = shape == Shape::hexagon ? hexagon_section(8) : square_section(10);
  TipFace result;
  result.points.resize(3 * static_cast<Index>(face.triangles.size()));
  for (size_t t = 0; t < face.triangles.size(); ++t) {
    const auto& corners = face.triangles[t];
    const Eigen::Vector2d centroid = (face.points[corners[0]] + face.points[corners[1]] + face.points[corners[2]]) / 3;
    result.points.segment<3>(3 * static_cast<Index>(t)) = Vec3(beam_length, centroid.x(), centroid.y());
    result.weights.push_back(triangle_area(face.points[corners[0]], face.points[corners[1]], face.points[corners[2]]));
    result.area += result.weights.back();
  }
  return result;
}

// The area-weighted mean displacement over the tip face, through the surface embedding.
Vec3 efg_tip_mean(const CorotationalEfg& model, const physics::SurfaceEmbedding& embedding, const TipFace& face,
                  const Vector& u) {
  Vector moved;
  CorotationalEfg::surface_positions(embedding, model.rest_positions() + u, moved);
  Vec3 tip = Vec3::Zero();
  for (size_t t = 0; t < face.weights.size(); ++t) {
    const Index at = 3 * static_cast<Index>(t);
    tip += face.weights[t] / face.area * (moved.segment<3>(at) - face.points.segment<3>(at));
  }
  return tip;
}

// An EFG model of a case's body (settings.spacing set), the cut cases cut by the geometry
// (`cutter` false: settings.cuts) or by the cutter (the report in `cut_report`).
std::unique_ptr<CorotationalEfg> make_case_efg(Shape shape, bool cut, bool cutter, EfgSettings settings,
                                               physics::VolumeCutReport* cut_report) {
  const double spacing = settings.spacing;
  if (cut && !cutter) {
    // From the top down to z = 0 across the whole width. Particles on the plane count on
    // the +x side; links through the rim z = 0 stay (the crack front is shared).
    settings.cuts.push_back({Vec3(cut_x, -1, 0), Vec3(0, 2, 0), Vec3(0, 0, 1)});
  }
  Vec3 grid_min = box_min(shape), grid_max = box_max(shape);
  if (cut) {
    // The grid's z extent widened to a multiple of 4a, so that a row of particles lies on
    // the crack front z = 0 (shared by both sides, like the conforming FEM's front nodes).
    // Otherwise the front falls mid-cell at every other resolution and the effective
    // crack depth jumps by about a between sizes (stretch_cut: +220 %, -28 %, +46 % at
    // a = 5, 3.3, 2 mm against -37 %, -28 % aligned).
    const int cubes = static_cast<int>(std::ceil((grid_max.z() - grid_min.z()) / spacing * (1 - 1e-12)));
    const int aligned = (cubes + 3) / 4 * 4;
    grid_min.z() = -0.5 * aligned * spacing;
    grid_max.z() = 0.5 * aligned * spacing;
  }
  auto model = std::make_unique<CorotationalEfg>([shape](const Vec3& p) { return inside_shape(shape, p); },
                                                 grid_min, grid_max, beam_material, settings);
  if (cut && cutter) {
    // One step of a straight blade along y (twice the beam's width), on the plane x =
    // cut_x, from 2a above the grid down to 1e-3 a above the front row z = 0; the
    // particles at rest (start = end). The file comment says why there.
    const double width = 2 * hexagon_radius;
    const std::vector<Vec3> blade_start{Vec3(cut_x, -width, grid_max.z() + 2 * spacing),
                                        Vec3(cut_x, width, grid_max.z() + 2 * spacing)};
    const std::vector<Vec3> blade_end{Vec3(cut_x, -width, 1e-3 * spacing), Vec3(cut_x, width, 1e-3 * spacing)};
    // Broad-phase margin 1 um (well above the CCD's touching distance, 1e-8 of the
    // problem's size), no slack: one refit only.
    physics::VolumeCutter volume_cutter(*model, 1e-6, 0);
    const Vector rest = model->rest_positions();
    const physics::VolumeCutReport report = volume_cutter.cut(blade_start, blade_end, rest, rest);
    if (cut_report != nullptr) *cut_report = report;
  }
  model->update_rotations(model->rest_positions());
  return model;
}

}  // namespace incise::bench::accuracy
