#include "bench/accuracy_shape_memory.hpp"

#include "physics/core/implicit_euler.hpp"
#include "physics/promayon/calibration.hpp"
#include "physics/promayon/lattice.hpp"
#include "physics/promayon/shape_memory.hpp"
#include "physics/promayon/truth_cube.hpp"

#include <Eigen/SparseLU>

#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <stdexcept>

namespace incise::bench::accuracy {

using physics::Neighbourhood;
using physics::PromayonKind;
using Index = Eigen::Index;
using Clock = std::chrono::steady_clock;

namespace {

struct CompressionModel {
  std::string model, variant;
  physics::TruthCubeModel spec;
};

// The full report adds the unmirrored triplet selection (shape_memory.hpp), an experiment.
std::vector<CompressionModel> compression_models(bool quick) {
  std::vector<CompressionModel> models{
      {"mass_spring_vn1", "vn1", {PromayonKind::spring_network, Neighbourhood::vn1, false}},
      {"mass_spring_moore", "moore", {PromayonKind::spring_network, Neighbourhood::moore, false}},
      {"mass_spring_moore", "moore_volume", {PromayonKind::spring_network, Neighbourhood::moore, true}},
      {"shape_memory", "vn1", {PromayonKind::shape_memory, Neighbourhood::vn1, false}},
      {"shape_memory_volume", "vn1", {PromayonKind::shape_memory, Neighbourhood::vn1, true}}};
  if (!quick) {
    const auto unmirrored = physics::TripletSelection::unmirrored;
    models.push_back({"shape_memory", "vn1_unmirrored", {PromayonKind::shape_memory, Neighbourhood::vn1, false, unmirrored}});
    models.push_back(
        {"shape_memory_volume", "vn1_unmirrored", {PromayonKind::shape_memory, Neighbourhood::vn1, true, unmirrored}});
  }
  return models;
}

// The FEM meshes besides the reference's 8 cells: their epsilon_REN against it.
std::vector<int> fem_levels(bool quick) { return quick ? std::vector<int>{4} : std::vector<int>{4, 12}; }

constexpr double kPoisson = 0.49;

std::string percent(double fraction) { return format(100 * fraction, 4) + " %"; }

}  // namespace

int compression_runs(bool quick) {
  return static_cast<int>(1 + fem_levels(quick).size() + compression_models(quick).size());
}

std::vector<Row> compression_rows(bool quick, common::ProgressBar& progress) {
  const physics::TruthCube cube;
  const int cells = physics::TruthCube::kCells;
  progress.draw("compression fem tet10 reference");
  const Vector reference = cube.fem_reference(cells, kPoisson);
  std::vector<Row> rows;
  const auto fem_row = [&](int c, double error, double volume_change) {
    Row row{"compression", "fem", "tet10", std::to_string(c) + "x" + std::to_string(c) + "x" + std::to_string(c) + "_cells",
            3LL * (2 * c + 1) * (2 * c + 1) * (2 * c + 1), 6LL * c * c * c, 0, 0, 100 * error, true};
    row.volume_change_pct = 100 * volume_change;
    rows.push_back(row);
  };
  const double reference_volume = physics::truth_cube_error(cube, reference, reference).volume_change;
  fem_row(cells, 0, reference_volume);
  progress.step("compression fem tet10 reference");
  progress.note("  compression reference: tet10 on 8^3 cells, nu " + format(kPoisson, 3) + ", volume change " +
                percent(reference_volume));
  for (int c : fem_levels(quick)) {
    progress.draw("compression fem tet10 " + std::to_string(c) + " cells");
    const physics::CompressionResult r = physics::truth_cube_error(cube, cube.fem_reference(c, kPoisson), reference);
    fem_row(c, r.error, r.volume_change);
    progress.note("  compression fem tet10 " + std::to_string(c) + "^3 cells against the reference: epsilon_REN " +
                  percent(r.error));
    progress.step("compression fem tet10 " + std::to_string(c) + " cells");
  }
  for (const CompressionModel& m : compression_models(quick)) {
    progress.draw("compression " + m.model + " " + m.variant);
    const auto start = Clock::now();
    const physics::CompressionResult r = physics::relax_truth_cube(cube, reference, m.spec);
    const std::chrono::duration<double, std::milli> elapsed = Clock::now() - start;
    if (!r.settled) throw std::runtime_error("compression: " + m.model + " " + m.variant + " did not settle");
    Row row{"compression", m.model, m.variant, "9x9x9_atoms", static_cast<long long>(cube.mesh().rest.size()), r.elements,
            elapsed.count() / r.steps, 0, 100 * r.error, true};
    row.volume_change_pct = 100 * r.volume_change;
    rows.push_back(row);
    progress.note("  compression " + m.model + " " + m.variant + ": epsilon_REN " + percent(r.error) + " +- " +
                  percent(r.spread) + ", volume change " + percent(r.volume_change) + " (" + std::to_string(r.steps) +
                  " steps, " + format(elapsed.count() / 1000, 3) + " s)");
    progress.step("compression " + m.model + " " + m.variant);
  }
  return rows;
}

// ---------------------------------------------------------------------------------------------
// B1.

namespace {

// The tangent at rest, -df/dx, by central differences over colours of atoms 5 lattice steps
// apart per axis: an atom's force depends on the atoms two steps away at most (its neighbours'
// attractors redistribute onto it), so each response has one perturbed atom within reach.
physics::SparseMatrix tangent_at_rest(const physics::DeformableModel& model, const physics::HexMesh& mesh,
                                      const Vec3& lo, double h) {
  const Vector& rest = mesh.rest;
  const Index n = rest.size() / 3;
  std::vector<std::array<int, 3>> cell(static_cast<std::size_t>(n));
  std::map<std::array<int, 3>, int> atom_at;
  for (Index i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) cell[static_cast<std::size_t>(i)][a] = static_cast<int>(std::lround((rest[3 * i + a] - lo[a]) / h));
    atom_at[cell[static_cast<std::size_t>(i)]] = static_cast<int>(i);
  }
  const double delta = 1e-6 * h;
  std::vector<Eigen::Triplet<double>> entries;
  for (int colour = 0; colour < 125; ++colour) {
    const std::array<int, 3> residue{colour % 5, colour / 5 % 5, colour / 25};
    for (int component = 0; component < 3; ++component) {
      Vector plus = rest, minus = rest;
      for (Index i = 0; i < n; ++i) {
        const auto& c = cell[static_cast<std::size_t>(i)];
        if (c[0] % 5 == residue[0] && c[1] % 5 == residue[1] && c[2] % 5 == residue[2]) {
          plus[3 * i + component] += delta;
          minus[3 * i + component] -= delta;
        }
      }
      Vector fp = Vector::Zero(rest.size()), fm = Vector::Zero(rest.size());
      model.add_elastic_forces(plus, fp);
      model.add_elastic_forces(minus, fm);
      const Vector column = -(fp - fm) / (2 * delta);
      for (Index i = 0; i < n; ++i) {
        // The perturbed atom within two steps of atom i, if any.
        std::array<int, 3> source{};
        for (int a = 0; a < 3; ++a) {
          int d = ((residue[a] - cell[static_cast<std::size_t>(i)][a]) % 5 + 5) % 5;
          if (d > 2) d -= 5;
          source[a] = cell[static_cast<std::size_t>(i)][a] + d;
        }
        const auto it = atom_at.find(source);
        if (it == atom_at.end()) continue;
        for (int r = 0; r < 3; ++r) {
          const double value = column[3 * i + r];
          if (value != 0) entries.emplace_back(3 * i + r, 3 * it->second + component, value);
        }
      }
    }
  }
  physics::SparseMatrix k(rest.size(), rest.size());
  k.setFromTriplets(entries.begin(), entries.end());
  return k;
}

// Solves K u = load on the free dofs (sparse LU: K is not symmetric).
Vector solve_linear(const physics::SparseMatrix& k, const Vector& load, const std::vector<uint8_t>& fixed) {
  std::vector<Index> free_of(static_cast<std::size_t>(k.rows()), -1);
  Index count = 0;
  for (Index i = 0; i < k.rows(); ++i)
    if (fixed[static_cast<std::size_t>(i / 3)] == 0) free_of[static_cast<std::size_t>(i)] = count++;
  std::vector<Eigen::Triplet<double>> entries;
  for (Index col = 0; col < k.outerSize(); ++col)
    for (physics::SparseMatrix::InnerIterator it(k, col); it; ++it) {
      const Index r = free_of[static_cast<std::size_t>(it.row())], c = free_of[static_cast<std::size_t>(it.col())];
      if (r >= 0 && c >= 0) entries.emplace_back(r, c, it.value());
    }
  physics::SparseMatrix reduced(count, count);
  reduced.setFromTriplets(entries.begin(), entries.end());
  Eigen::SparseLU<physics::SparseMatrix> lu;
  lu.compute(reduced);
  if (lu.info() != Eigen::Success) throw std::runtime_error("shape memory b1: the tangent's factorisation failed");
  Vector rhs(count);
  for (Index i = 0; i < k.rows(); ++i)
    if (free_of[static_cast<std::size_t>(i)] >= 0) rhs[free_of[static_cast<std::size_t>(i)]] = load[i];
  const Vector x = lu.solve(rhs);
  Vector u = Vector::Zero(k.rows());
  for (Index i = 0; i < k.rows(); ++i)
    if (free_of[static_cast<std::size_t>(i)] >= 0) u[i] = x[free_of[static_cast<std::size_t>(i)]];
  if (!u.allFinite()) throw std::runtime_error("shape memory b1: the static solution is not finite");
  return u;
}

}  // namespace

int shape_memory_beam_runs(const std::vector<int>& cells_across) { return static_cast<int>(cells_across.size()); }

std::vector<Row> shape_memory_beam_rows(const std::vector<Case>& cases, const std::map<std::string, Reference>& references,
                                        const std::vector<int>& cells_across, int timed_steps,
                                        common::ProgressBar& progress) {
  std::vector<Row> rows;
  const Vec3 lo = box_min(Shape::square), hi = box_max(Shape::square), extent = hi - lo;
  for (int across : cells_across) {
    const double h = extent.y() / across;
    std::array<int, 3> cells{};
    for (int a = 0; a < 3; ++a) cells[a] = std::max(1, static_cast<int>(std::lround(extent[a] / h)));
    const physics::HexMesh mesh = physics::make_box_hexes(lo, hi, cells);
    const std::string name = "h" + format(1e3 * h, 3) + "mm";
    progress.draw("shape_memory vn1 " + name);
    const auto start = Clock::now();
    const double ke = physics::stiffness_from_youngs_modulus(PromayonKind::shape_memory, Neighbourhood::vn1,
                                                             beam_material.youngs_modulus, h);
    physics::ShapeMemory model(mesh.rest, physics::lattice_neighbours(mesh, Neighbourhood::vn1),
                               physics::lattice_masses(mesh, beam_material.density), ke, h);
    const std::vector<uint8_t> fixed = clamped_nodes(mesh.rest);
    const physics::SparseMatrix k = tangent_at_rest(model, mesh, lo, h);
    for (const Case& c : cases) {
      const Vector load = physics::gravity_forces(model.lumped_masses(), c.acceleration);
      const Vector u = solve_linear(k, load, fixed);
      const Vec3 tip = hex_tip_mean(mesh, u, hi.x());
      const Timing timing = time_steps(model, fixed, load, timed_steps);
      const Vec3 reference = references.at(c.name).tip;
      rows.push_back({c.name, "shape_memory", "vn1", name, 3 * static_cast<long long>(model.node_count()),
                      static_cast<long long>(model.triplet_count()), timing.ms_per_step, timing.cg_iterations,
                      100 * (tip - reference).norm() / reference.norm(), timing.converged, tip});
      progress.note("  " + c.name + " shape_memory vn1 " + name + " (k_e " + format(ke, 4) + " N/m): tip " + mm(tip) +
                    ", error " + format(rows.back().error_pct, 4) + " %");
    }
    const std::chrono::duration<double> elapsed = Clock::now() - start;
    progress.note("  shape_memory vn1 " + name + ": " + std::to_string(model.node_count()) + " atoms, " +
                  std::to_string(model.triplet_count()) + " triplets, " + format(elapsed.count(), 3) + " s");
    progress.step("shape_memory vn1 " + name);
  }
  return rows;
}

}  // namespace incise::bench::accuracy
