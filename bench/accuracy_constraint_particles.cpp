// The constraint-particle rows of `incise bench accuracy` (accuracy_constraint_particles.hpp
// says what they are and how the model is set up).
#include "bench/accuracy_constraint_particles.hpp"

#include "common/csv.hpp"
#include "physics/core/implicit_euler.hpp"
#include "physics/cp/constraint_particles.hpp"
#include "physics/cp/cp_step.hpp"
#include "physics/mss/hex_mesh.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace incise::bench::accuracy {

namespace {

using physics::ConstraintParticles;
using physics::ConstraintParticleSettings;
using physics::TetMesh;
using Index = Eigen::Index;
using Clock = std::chrono::steady_clock;

// The network's stiffness at rest, sum over the constraints of k grad C grad C^T: the exact
// Hessian of sum k C^2 / 2 there, as every C is 0.
physics::SparseMatrix rest_stiffness(const ConstraintParticles& model) {
  const Vector& rest = model.rest_positions();
  std::vector<Eigen::Triplet<double>> triplets;
  std::array<Vec3, 4> gradient;
  for (const physics::Constraint& c : model.constraints()) {
    physics::constraint_gradient(c, rest, gradient);
    const int arity = physics::constraint_arity(c.kind);
    for (int a = 0; a < arity; ++a)
      for (int b = 0; b < arity; ++b) {
        const Eigen::Matrix3d block = c.stiffness * gradient[a] * gradient[b].transpose();
        for (int r = 0; r < 3; ++r)
          for (int s = 0; s < 3; ++s) triplets.emplace_back(3 * c.nodes[a] + r, 3 * c.nodes[b] + s, block(r, s));
      }
  }
  physics::SparseMatrix k(rest.size(), rest.size());
  k.setFromTriplets(triplets.begin(), triplets.end());
  return k;
}

ConstraintParticleSettings particle_settings(double distance, double volume, double density) {
  ConstraintParticleSettings settings;
  settings.density = density;
  settings.distance_stiffness = distance;
  settings.area_stiffness = 0;  // no membrane on the skin (the header says why)
  settings.volume_stiffness = volume;
  settings.scaling = physics::StiffnessScaling::per_volume;  // k_D, k_V in Pa (the header says why)
  return settings;
}

// Each brick split into 5 tets as make_box_tets5 splits its cells, the split alternating with
// the parity of the brick's grid index (from its corner 0's position over `origin`).
TetMesh split_bricks(const physics::HexMesh& bricks, const Vec3& origin) {
  TetMesh mesh;
  mesh.rest = bricks.rest;
  if (bricks.hexes.empty()) throw std::runtime_error("constraint particles: the body has no voxels");
  const Vec3 cell = physics::hex_edge_lengths(bricks.rest, bricks.hexes.front());
  // make_box_tets5's tables: corners c = a + 2b + 4d at offsets (a, b, d); the brick's local
  // order has 0-1-2-3 round the bottom face and 4-7 above.
  const auto local = [](int c) { const int a = c & 1, b = (c >> 1) & 1, d = (c >> 2) & 1; return 4 * d + (b == 0 ? a : 3 - a); };
  static constexpr std::array<std::array<int, 4>, 5> even{{{0, 3, 5, 6}, {1, 0, 3, 5}, {2, 0, 6, 3}, {4, 0, 5, 6}, {7, 3, 6, 5}}};
  static constexpr std::array<std::array<int, 4>, 5> odd{{{1, 2, 4, 7}, {0, 1, 2, 4}, {3, 1, 7, 2}, {5, 1, 4, 7}, {6, 2, 7, 4}}};
  for (const auto& hex : bricks.hexes) {
    const Vec3 corner = bricks.rest.segment<3>(3 * static_cast<Index>(hex[0]));
    long parity = 0;
    for (int a = 0; a < 3; ++a) parity += std::lround((corner[a] - origin[a]) / cell[a]);
    for (const auto& tet : (parity % 2 == 0 ? even : odd)) {
      std::array<int, 4> t{};
      for (int v = 0; v < 4; ++v) t[v] = hex[local(tet[v])];
      const physics::Constraint volume{physics::ConstraintKind::volume, t, 0, 0};
      if (physics::constraint_measure(volume, mesh.rest) < 0) std::swap(t[2], t[3]);
      mesh.tets.push_back(t);
    }
  }
  return mesh;
}

struct BeamTets {
  TetMesh mesh;
  Vec3 cell;  // the bricks' edge lengths
};
// The beam's bricks `resolution` across, as the mass-spring rows have them (exact on a box,
// voxels of the shape otherwise), split into tets.
BeamTets beam_tets(Shape shape, double resolution) {
  const Vec3 lo = box_min(shape), hi = box_max(shape), extent = hi - lo;
  physics::HexMesh bricks;
  if (shape == Shape::square) {
    std::array<int, 3> cells{};
    for (int a = 0; a < 3; ++a) cells[a] = std::max(1, static_cast<int>(std::lround(extent[a] / resolution)));
    bricks = physics::make_box_hexes(lo, hi, cells);
  } else {
    bricks = physics::make_hexes_inside([shape](const Vec3& p) { return inside_shape(shape, p); }, lo, hi, resolution);
  }
  BeamTets body{split_bricks(bricks, lo), physics::hex_edge_lengths(bricks.rest, bricks.hexes.front())};
  // Neighbouring bricks' splits must share their face diagonals: then the tets' boundary is
  // the bricks' (two triangles a face), with no face left open inside.
  if (physics::boundary_triangles(body.mesh.tets).size() != physics::hex_boundary_triangles(bricks.hexes).size())
    throw std::runtime_error("constraint particles: the 5-tet split of the beam's bricks does not conform");
  return body;
}

// The lattice's moduli along x per unit k_D (Pa, per_volume), with k_V = ratio k_D: the homogenised stiffness of
// the periodic lattice (period 2 x 2 x 2 voxels: the split alternates), each constraint
// linearised at rest, C = grad C . u with u = eps X + w(X), w periodic (the 8 node classes of the
// period, the first held against the rigid translations); minimising the energy over w leaves
// the energy density eps^T C eps / 2, and E = 1 / S_xx, nu = -S_yx / S_xx with S = C^-1.
struct LatticeModuli {
  double youngs_modulus = 0, poisson_ratio = 0;
};
LatticeModuli lattice_moduli(const Vec3& cell, double ratio) {
  const TetMesh period = physics::make_box_tets5(Vec3::Zero(), 2 * cell, {2, 2, 2});
  const auto grid = [&](int node) {
    const Vec3 x = period.rest.segment<3>(3 * static_cast<Index>(node));
    return Eigen::Vector3i(static_cast<int>(std::lround(x.x() / cell.x())), static_cast<int>(std::lround(x.y() / cell.y())),
                           static_cast<int>(std::lround(x.z() / cell.z())));
  };
  const auto node_class = [&](int node) {
    const Eigen::Vector3i g = grid(node);
    return (g.x() % 2) + 2 * (g.y() % 2) + 4 * (g.z() % 2);
  };
  // Unknowns: eps in Voigt order (xx, yy, zz, 2yz, 2xz, 2xy), then w of the classes 1-7.
  constexpr int kStrains = 6, kUnknowns = kStrains + 21;
  Eigen::MatrixXd hessian = Eigen::MatrixXd::Zero(kUnknowns, kUnknowns);
  const auto add = [&](const physics::Constraint& c, double stiffness) {
    std::array<Vec3, 4> g;
    physics::constraint_gradient(c, period.rest, g);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(kUnknowns);
    for (int a = 0; a < physics::constraint_arity(c.kind); ++a) {
      const Vec3 x = period.rest.segment<3>(3 * static_cast<Index>(c.nodes[a]));
      b.head<3>() += g[a].cwiseProduct(x);
      b[3] += g[a].y() * x.z() / 2 + g[a].z() * x.y() / 2;
      b[4] += g[a].x() * x.z() / 2 + g[a].z() * x.x() / 2;
      b[5] += g[a].x() * x.y() / 2 + g[a].y() * x.x() / 2;
      const int k = node_class(c.nodes[a]);
      if (k > 0) b.segment<3>(kStrains + 3 * (k - 1)) += g[a];
    }
    hessian += stiffness * b * b.transpose();
  };
  // per_volume: each tet gives k_D V_t to its six edges and k_V V_t to its volume. Each tet of
  // the period is one of the lattice's, and an edge's linearised C depends only on its vector and
  // its ends' classes, so the tets' edge terms summed over the period (an edge on the period's
  // faces met again as its neighbour's image) are the lattice's shared edges' exactly.
  static constexpr std::array<std::array<int, 2>, 6> pairs{{{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}}};
  for (const auto& tet : period.tets) {
    physics::Constraint v{physics::ConstraintKind::volume, tet, 0, 1};
    v.rest = physics::constraint_measure(v, period.rest);
    for (const auto& p : pairs) {
      physics::Constraint c{physics::ConstraintKind::distance, {tet[p[0]], tet[p[1]], 0, 0}, 0, 1};
      c.rest = physics::constraint_measure(c, period.rest);
      add(c, v.rest);
    }
    add(v, ratio * v.rest);
  }
  const Eigen::MatrixXd ww = hessian.bottomRightCorner(21, 21);
  const Eigen::MatrixXd we = hessian.bottomLeftCorner(21, kStrains);
  const Eigen::MatrixXd stiffness =
      (hessian.topLeftCorner(kStrains, kStrains) - we.transpose() * ww.ldlt().solve(we)) / (8 * cell.prod());
  const Eigen::MatrixXd compliance = stiffness.inverse();
  return {1 / compliance(0, 0), -compliance(1, 0) / compliance(0, 0)};
}

// Alg. 3.2's relaxation of the body under `load` from rest; notes how far it lands from the
// static solution `u` and what an explicit step costs.
// The first mode of a beam under its own weight g is about critically damped by mass damping of
// 2.5 sqrt(g / tip): omega_1^2 = 1.875^4 EI / (rho A L^4) and tip = g rho A L^4 / (8 EI) give
// omega_1 = 1.24 sqrt(g / tip) in bending (1.11 sqrt(g / tip) along the axis).
void note_relaxation(ConstraintParticles& model, const std::vector<uint8_t>& fixed, const Vector& load, const Vector& u,
                     const Vec3& static_tip, double g, const TetMesh& mesh, const std::string& what,
                     common::ProgressBar& progress) {
  physics::CpStepSettings step;
  step.dt = 0.5 * model.explicit_step_limit();
  step.rayleigh_mass = 2.5 * std::sqrt(g / static_tip.norm());
  physics::RelaxSettings settings;
  settings.tolerance = 1e-10 * std::abs(load.dot(u));
  settings.max_steps = 400000;
  physics::State state{model.rest_positions(), Vector::Zero(model.rest_positions().size())};
  const auto start = Clock::now();
  const physics::RelaxReport report = physics::relax(model, state, fixed, load, step, settings);
  const std::chrono::duration<double, std::milli> elapsed = Clock::now() - start;
  const Vec3 tip = tip_mean(mesh, state.positions - model.rest_positions(), nullptr);
  // Along the static tip's direction, and across it: the nonlinear model's beam shortens as it
  // bends (about 0.6 tip^2 / L along x), which the linear solve has not.
  const Vec3 along = static_tip.normalized();
  progress.note("  " + what + ": Alg. 3.2's relaxation (velocity Verlet, dt " + format(1e6 * step.dt, 3) +
                " us, mass damping " + format(step.rayleigh_mass, 3) + "/s) " +
                (report.converged ? "settled" : report.nonfinite ? "went non-finite" : "did NOT settle") + " in " +
                std::to_string(report.steps) + " steps (" + format(elapsed.count() / report.steps, 3) +
                " ms per step): tip " + mm(tip) + " against the static solve's " + mm(static_tip) + ", " +
                format(100 * (tip.dot(along) / static_tip.norm() - 1), 3) + " % along it, " +
                format(100 * (tip - tip.dot(along) * along).norm() / static_tip.norm(), 3) + " % across");
}

}  // namespace

ParticleCalibration calibrate_constraint_particles(const Vec3& cell, const Material& material) {
  // nu grows with k_V / k_D (the volume constraints stiffen the bulk only): bisection on its log.
  const auto nu_at = [&](double ratio) { return lattice_moduli(cell, ratio).poisson_ratio; };
  double low = std::log(1e-4), high = std::log(1e4);
  if (!(nu_at(std::exp(low)) < material.poisson_ratio && nu_at(std::exp(high)) > material.poisson_ratio)) {
    throw std::runtime_error("constraint particles: no k_V / k_D in [1e-4, 1e4] gives nu " +
                             format(material.poisson_ratio, 3));
  }
  for (int it = 0; it < 60; ++it) {
    const double mid = 0.5 * (low + high);
    (nu_at(std::exp(mid)) < material.poisson_ratio ? low : high) = mid;
  }
  const double ratio = std::exp(0.5 * (low + high));
  ParticleCalibration calibration;
  calibration.distance_stiffness = material.youngs_modulus / lattice_moduli(cell, ratio).youngs_modulus;
  calibration.volume_stiffness = ratio * calibration.distance_stiffness;
  const LatticeModuli check = lattice_moduli(cell, ratio);
  calibration.measured_E = calibration.distance_stiffness * check.youngs_modulus;
  calibration.measured_nu = check.poisson_ratio;
  return calibration;
}

int constraint_particles_runs(const std::vector<int>& cells_across) { return static_cast<int>(cells_across.size()); }

std::vector<Row> constraint_particles_rows(Shape shape, const std::vector<Case>& cases,
                                           const std::map<std::string, Reference>& references,
                                           const std::vector<int>& cells_across, int timed_steps,
                                           common::ProgressBar& progress) {
  const auto start = Clock::now();
  std::vector<Row> rows;
  const double across_extent = (box_max(shape) - box_min(shape)).y();
  for (size_t level = 0; level < cells_across.size(); ++level) {
    const double resolution = across_extent / cells_across[level];
    const std::string name = "h" + common::significant(1e3 * resolution, 3) + "mm";
    progress.draw("constraint_particles " + name);
    const BeamTets body = beam_tets(shape, resolution);
    const ParticleCalibration calibration = calibrate_constraint_particles(body.cell, beam_material);
    ConstraintParticles model(body.mesh, particle_settings(calibration.distance_stiffness, calibration.volume_stiffness,
                                                           beam_material.density));
    progress.note("  constraint_particles " + name + ": k_D " + format(calibration.distance_stiffness, 4) + " Pa, k_V " +
                  format(calibration.volume_stiffness, 4) + " Pa per tet volume (the lattice of its voxels: E " +
                  format(calibration.measured_E, 6) + " Pa, nu " + format(calibration.measured_nu, 6) + ")");
    const std::vector<uint8_t> fixed = clamped_nodes(model.rest_positions());
    std::vector<Vector> loads;
    for (const Case& c : cases) loads.push_back(physics::gravity_forces(model.lumped_masses(), c.acceleration));
    const std::vector<Vector> solutions = solve_static_loads(rest_stiffness(model), loads, fixed);
    for (size_t i = 0; i < cases.size(); ++i) {
      const Case& c = cases[i];
      const Vec3 tip = tip_mean(body.mesh, solutions[i], nullptr);
      const Vec3 reference = references.at(c.name).tip;
      const Timing timing = time_steps(model, fixed, loads[i], timed_steps);
      rows.push_back({c.name, "constraint_particles", "tets5", name, 3 * static_cast<long long>(model.node_count()),
                      static_cast<long long>(body.mesh.tets.size()), timing.ms_per_step, timing.cg_iterations,
                      100 * (tip - reference).norm() / reference.norm(), timing.converged, tip});
      if (level == 0) {
        note_relaxation(model, fixed, loads[i], solutions[i], tip, c.acceleration.norm(), body.mesh,
                        c.name + " constraint_particles " + name, progress);
      }
    }
    progress.step("constraint_particles " + name);
  }
  const std::chrono::duration<double> elapsed = Clock::now() - start;
  progress.note("  constraint_particles rows (calibration, static solves, timing, relaxation) in " +
                format(elapsed.count(), 3) + " s");
  return rows;
}

}  // namespace incise::bench::accuracy
