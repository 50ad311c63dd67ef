#include "bench/accuracy_mass_spring.hpp"

#include "common/csv.hpp"
#include "physics/core/implicit_euler.hpp"
#include "physics/fem/tet_mesh.hpp"
#include "physics/mss/hex_mass_spring.hpp"
#include "physics/mss/hex_mesh.hpp"
#include "physics/mss/mss_static.hpp"
#include "physics/mss/van_gelder.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

namespace incise::bench {

namespace {

using physics::Vec3;
using physics::Vector;
using Index = Eigen::Index;

std::vector<uint8_t> clamped_at_zero(const Vector& rest) {
  return physics::nodes_in_box(rest, Vec3::Constant(-1e9), Vec3(1e-9, 1e9, 1e9));
}

}  // namespace

Vec3 hex_tip_mean(const physics::HexMesh& mesh, const Vector& u, double tip_x) {
  Vec3 sum = Vec3::Zero();
  double area = 0;
  for (const auto& t : physics::hex_boundary_triangles(mesh.hexes)) {
    bool on_tip = true;
    for (int v : t) on_tip = on_tip && std::abs(mesh.rest[3 * v] - tip_x) < 1e-12;
    if (!on_tip) continue;
    const Vec3 a = mesh.rest.segment<3>(3 * t[0]), b = mesh.rest.segment<3>(3 * t[1]), c = mesh.rest.segment<3>(3 * t[2]);
    const double triangle = 0.5 * (b - a).cross(c - a).norm();
    sum += triangle * (u.segment<3>(3 * t[0]) + u.segment<3>(3 * t[1]) + u.segment<3>(3 * t[2])) / 3;
    area += triangle;
  }
  return sum / area;
}

namespace {

const std::array<bool, 2> kCorrections{true, false};
std::string model_name(bool corrections) { return corrections ? "mass_spring" : "mass_spring_uncorrected"; }

}  // namespace

int mass_spring_beam_runs(const std::vector<int>& cells_across) {
  return static_cast<int>(cells_across.size() * kCorrections.size());
}

std::vector<MassSpringRow> mass_spring_beam_rows(const MassSpringBeam& beam, const std::vector<MassSpringCase>& cases,
                                                 const std::vector<int>& cells_across, const TimeSteps& time_steps,
                                                 common::ProgressBar& progress) {
  std::vector<MassSpringRow> rows;
  const Vec3 extent = beam.hi - beam.lo;
  for (int across : cells_across) {
    const double resolution = extent.y() / across;
    physics::HexMesh mesh;
    if (beam.box) {
      std::array<int, 3> cells{};
      for (int a = 0; a < 3; ++a) cells[a] = std::max(1, static_cast<int>(std::lround(extent[a] / resolution)));
      mesh = physics::make_box_hexes(beam.lo, beam.hi, cells);
    } else {
      mesh = physics::make_hexes_inside(beam.inside, beam.lo, beam.hi, resolution);
    }
    const std::string name = "h" + common::significant(1e3 * resolution, 3) + "mm";
    const std::vector<uint8_t> fixed = clamped_at_zero(mesh.rest);
    for (bool corrections : kCorrections) {
      progress.draw(model_name(corrections) + " " + name);
      physics::HexMassSpring model(mesh, {beam.youngs_modulus, beam.poisson_ratio, beam.density, 1, corrections});
      for (const MassSpringCase& c : cases) {
        const Vector load = physics::gravity_forces(model.lumped_masses(), c.acceleration);
        const physics::MassSpringStatic solved =
            physics::solve_mass_spring_static(model, fixed, Vector(), load, 1, 1e-9);
        const Vec3 tip = hex_tip_mean(mesh, solved.positions - mesh.rest, beam.hi.x());
        const StepTiming timing = time_steps(model, fixed, load);
        MassSpringRow row;
        row.case_name = c.name, row.model = model_name(corrections), row.variant = "hex", row.resolution = name;
        row.dofs = 3 * static_cast<long long>(model.node_count());
        row.elements = static_cast<long long>(mesh.hexes.size());
        row.ms_per_step = timing.ms_per_step, row.cg_iterations = timing.cg_iterations, row.converged = timing.converged;
        row.error_pct = 100 * (tip - c.reference_tip).norm() / c.reference_tip.norm();
        row.tip = tip;
        rows.push_back(row);
      }
      progress.step(model_name(corrections) + " " + name);
    }
  }
  return rows;
}

namespace {

struct Block {
  std::string name;
  Vec3 size;
  std::array<int, 3> cells;
};
const std::array<Block, 3> kBlocks{{{"cube", Vec3::Constant(0.1), {1, 1, 1}},
                                     {"cubes3x3x3", Vec3::Constant(0.3), {3, 3, 3}},
                                     {"bricks4x2x2", Vec3(0.48, 0.2, 0.16), {4, 2, 2}}}};
const std::array<double, 3> kPoisson{0.1, 0.3, 0.45};
constexpr double kYoungs = 1e4, kDensity = 1500;

double deviation_pct(const physics::TractionMeasure& m, double nu) {
  return 100 * std::max(std::abs(m.youngs_modulus / kYoungs - 1), std::abs(m.poisson_ratio / nu - 1));
}

}  // namespace

int traction_runs() { return static_cast<int>(kPoisson.size() * (kBlocks.size() * kCorrections.size() + 1)); }

std::vector<MassSpringRow> traction_rows(const TimeSteps& time_steps, common::ProgressBar& progress) {
  std::vector<MassSpringRow> rows;
  for (double nu : kPoisson) {
    const std::string variant = "nu" + common::significant(nu, 3);
    for (const Block& block : kBlocks) {
      const physics::HexMesh mesh = physics::make_box_hexes(Vec3::Zero(), block.size, block.cells);
      for (bool corrections : kCorrections) {
        progress.draw("traction " + model_name(corrections) + " " + block.name + " " + variant);
        physics::HexMassSpring model(mesh, {kYoungs, nu, kDensity, 1, corrections});
        const physics::TractionMeasure m =
            physics::measure_traction(physics::mass_spring_rest_stiffness(model), mesh.rest, block.size, block.cells);
        const std::vector<uint8_t> fixed = clamped_at_zero(mesh.rest);
        const StepTiming timing =
            time_steps(model, fixed, physics::gravity_forces(model.lumped_masses(), Vec3(0, 0, -9.81)));
        MassSpringRow row;
        row.case_name = "traction", row.model = model_name(corrections), row.variant = variant;
        row.resolution = block.name;
        row.dofs = 3 * static_cast<long long>(model.node_count());
        row.elements = static_cast<long long>(mesh.hexes.size());
        row.ms_per_step = timing.ms_per_step, row.cg_iterations = timing.cg_iterations, row.converged = timing.converged;
        row.error_pct = deviation_pct(m, nu);
        row.measured_E = m.youngs_modulus, row.measured_nu = m.poisson_ratio;
        rows.push_back(row);
        progress.step("traction " + model_name(corrections) + " " + block.name + " " + variant);
      }
    }
    // Van Gelder's springs on the tets of the 3 x 3 x 3 block (the negative control, D9).
    const Block& block = kBlocks[1];
    const physics::TetMesh tets = physics::make_box_tets(Vec3::Zero(), block.size, block.cells);
    const physics::TractionMeasure m = physics::measure_traction(
        physics::spring_network_stiffness(tets.rest, physics::van_gelder_springs(tets, kYoungs, nu)), tets.rest,
        block.size, block.cells);
    MassSpringRow row;
    row.case_name = "traction", row.model = "van_gelder", row.variant = variant, row.resolution = "tets_" + block.name;
    row.dofs = tets.rest.size();
    row.elements = static_cast<long long>(tets.tets.size());
    row.error_pct = deviation_pct(m, nu);
    row.measured_E = m.youngs_modulus, row.measured_nu = m.poisson_ratio;
    rows.push_back(row);
    progress.step("traction van_gelder " + variant);
  }
  return rows;
}

}  // namespace incise::bench
