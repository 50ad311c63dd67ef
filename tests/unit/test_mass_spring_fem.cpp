// Baudet's hexahedral mass-spring against incise's converged FEM and the Van Gelder negative
// control (seed 003; digest seed-000-003.md D6, D8, D9). The reference: 10-node tets on the
// same box, each brick split into 2^3 cells of 6 tets (make_box_quadratic_tets), solved
// statically (small strain); the mass-spring's equilibrium is its nonlinear static solve
// (mss_static.hpp). Errors are the digest's %e_dm (RMS) and %e_max over the mass-spring's
// nodes, in % of the reference's largest displacement (B.3).
#include "physics/core/implicit_euler.hpp"
#include "physics/fem/static_solve.hpp"
#include "physics/fem/tet_mesh.hpp"
#include "physics/mss/hex_mass_spring.hpp"
#include "physics/mss/hex_mesh.hpp"
#include "physics/mss/mss_static.hpp"
#include "physics/mss/van_gelder.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <iostream>
#include <vector>

namespace physics = incise::physics;
using physics::Vec3;
using physics::Vector;

namespace {

constexpr double kDensity = 1500;  // Fléchon §5.3: 1.5 kg/L
// Reference cells per brick along each axis. 1 keeps the test fast; at 2 (8 x the tets) the
// figures move by under 0.25 points (D6 at 5 %: 0.565 instead of 0.550 % e_dm; D8 at g = 2:
// 4.01 instead of 3.77 %), well within the bars.
constexpr int kRefine = 1;

// The reference's displacement at the mass-spring's nodes: node (i, j, k) of the brick grid
// is node (2 r i, 2 r j, 2 r k) of the 10-node grid (make_box_quadratic_tets' numbering).
Vector at_brick_nodes(const Vector& u, const std::array<int, 3>& cells) {
  const int qx = 2 * kRefine * cells[0] + 1, qy = 2 * kRefine * cells[1] + 1;
  Vector out(3 * (cells[0] + 1) * (cells[1] + 1) * (cells[2] + 1));
  int at = 0;
  for (int k = 0; k <= cells[2]; ++k)
    for (int j = 0; j <= cells[1]; ++j)
      for (int i = 0; i <= cells[0]; ++i, ++at) {
        const int q = 2 * kRefine * i + qx * (2 * kRefine * j + qy * 2 * kRefine * k);
        out.segment<3>(3 * at) = u.segment<3>(3 * q);
      }
  return out;
}

struct Comparison {
  physics::PositionError error;
  double fem_max = 0;  // m
};

// A box of `cells` 0.1 m cubes, the nodes at x = 0 held and those at x = L moved by `end` (when
// non-zero), under the acceleration `g`, both models; the FEM at kRefine^3 x 6 10-node tets per brick.
Comparison compare(const std::array<int, 3>& cells, double youngs_modulus, double nu, const Vec3& end, const Vec3& g,
                   bool corrections) {
  const Vec3 size(0.1 * cells[0], 0.1 * cells[1], 0.1 * cells[2]);
  const bool pulled = end.norm() > 0;
  const auto held = [&](const Vector& rest) {
    std::vector<uint8_t> fixed(rest.size() / 3, 0);
    Vector prescribed = Vector::Zero(rest.size());
    for (Eigen::Index i = 0; i < rest.size() / 3; ++i) {
      if (rest[3 * i] < 1e-9) fixed[i] = 1;
      if (pulled && rest[3 * i] > size.x() - 1e-9) fixed[i] = 1, prescribed.segment<3>(3 * i) = end;
    }
    return std::make_pair(fixed, prescribed);
  };
  const physics::QuadraticTetMesh fine =
      physics::make_box_quadratic_tets(Vec3::Zero(), size, {kRefine * cells[0], kRefine * cells[1], kRefine * cells[2]});
  const auto [fine_fixed, fine_prescribed] = held(fine.rest);
  const Vector u_fem = physics::solve_static_quadratic(fine, {youngs_modulus, nu, kDensity}, fine_fixed, fine_prescribed,
                                                       kDensity * g, Vector());
  const physics::HexMesh mesh = physics::make_box_hexes(Vec3::Zero(), size, cells);
  physics::MassSpringMaterial material{youngs_modulus, nu, kDensity, 1, corrections};
  physics::HexMassSpring model(mesh, material);
  const auto [fixed, prescribed] = held(mesh.rest);
  const Vector load = physics::gravity_forces(model.lumped_masses(), g);
  const physics::MassSpringStatic solved = physics::solve_mass_spring_static(model, fixed, prescribed, load, 4);
  EXPECT_TRUE(solved.converged);
  const Vector reference = mesh.rest + at_brick_nodes(u_fem, cells);
  // The two grids' nodes coincide.
  const Vector fine_rest = at_brick_nodes(fine.rest, cells);
  EXPECT_LT((fine_rest - mesh.rest).norm(), 1e-12);
  return {physics::position_error(mesh.rest, reference, solved.positions), (reference - mesh.rest).cwiseAbs().maxCoeff()};
}

}  // namespace

TEST(MassSpringAgainstFem, ElongationBeyondTenPercentStaysWithinFivePercentWithCorrections) {
  // D6 (Fléchon Fig. 14): a 0.6 x 0.3 x 0.3 m bar of 0.1 m cubes, E = 1e4 Pa, nu = 0.3, clamped
  // at x = 0 and its face x = L pulled along x (held laterally) by 5 to 20 % strain. With the
  // corrections the RMS position error stays <= 5 % of the largest displacement; without them
  // it is reported beside (the springs alone measure nu = 0.238, E 4.8 % stiff: digest B.1.3).
  const std::array<int, 3> cells{6, 3, 3};
  for (double strain : {0.05, 0.1, 0.15, 0.2}) {
    const Vec3 end(strain * 0.6, 0, 0);
    const Comparison with = compare(cells, 1e4, 0.3, end, Vec3::Zero(), true);
    const Comparison without = compare(cells, 1e4, 0.3, end, Vec3::Zero(), false);
    std::cout << "D6 strain " << 100 * strain << " %: corrected %e_dm " << with.error.rms_pct << " %e_max "
              << with.error.max_pct << "; uncorrected %e_dm " << without.error.rms_pct << " %e_max "
              << without.error.max_pct << "\n";
    EXPECT_LE(with.error.rms_pct, 5.0) << "strain " << strain;
    EXPECT_GT(without.error.rms_pct, with.error.rms_pct) << "strain " << strain;
  }
}

TEST(MassSpringAgainstFem, BendingUnderGravity) {
  // D8 (Fléchon Fig. 16-17): the 1.0 x 0.5 x 0.4 m beam of 10 x 5 x 4 cubes of 0.1 m, rho = 1500,
  // nu = 0.3, clamped at x = 0, under gravity (0, -2, 0) and (0, -4, 0); E = 1 MPa, so that the
  // tip sags about 2 and 4 % of the length (the digest's small-deflection regime).
  const std::array<int, 3> cells{10, 5, 4};
  for (double g : {2.0, 4.0}) {
    const Comparison with = compare(cells, 1e6, 0.3, Vec3::Zero(), Vec3(0, -g, 0), true);
    const Comparison without = compare(cells, 1e6, 0.3, Vec3::Zero(), Vec3(0, -g, 0), false);
    std::cout << "D8 g " << g << ": tip " << with.error.reference_max << " m; corrected %e_dm " << with.error.rms_pct
              << " %e_max " << with.error.max_pct << "; uncorrected %e_dm " << without.error.rms_pct << " %e_max "
              << without.error.max_pct << "\n";
    EXPECT_LE(with.error.rms_pct, 5.0) << "g " << g;
    EXPECT_GT(without.error.rms_pct, with.error.rms_pct) << "g " << g;
  }
}

TEST(MassSpringVanGelder, TractionMeasuresEFarOffTarget) {
  // D9: Van Gelder's springs on the tets of a 3 x 3 x 3 block of 0.1 m cubes (6 tets each), the
  // same traction as Baudet's springs: at nu = 0.3 E is off by about Baudet's 25 % (measured
  // -21 %) and nu is nearly 0 (springs on tets have no Poisson effect of their own to speak
  // of), where the corrected hexahedral springs measure both targets exactly.
  const std::array<int, 3> cells{3, 3, 3};
  const Vec3 size = Vec3::Constant(0.3);
  const physics::TetMesh tets = physics::make_box_tets(Vec3::Zero(), size, cells);
  const physics::TractionMeasure van_gelder = physics::measure_traction(
      physics::spring_network_stiffness(tets.rest, physics::van_gelder_springs(tets, 1e4, 0.3)), tets.rest, size, cells);
  physics::HexMassSpring baudet(physics::make_box_hexes(Vec3::Zero(), size, cells), {1e4, 0.3, kDensity, 1, true});
  const physics::TractionMeasure corrected =
      physics::measure_traction(physics::mass_spring_rest_stiffness(baudet), baudet.rest_positions(), size, cells);
  std::cout << "D9 Van Gelder E " << van_gelder.youngs_modulus << " nu " << van_gelder.poisson_ratio
            << "; Baudet corrected E " << corrected.youngs_modulus << " nu " << corrected.poisson_ratio << "\n";
  const double e_off = std::abs(van_gelder.youngs_modulus / 1e4 - 1);
  EXPECT_GT(e_off, 0.15);
  EXPECT_LT(e_off, 0.30);
  EXPECT_LT(van_gelder.poisson_ratio, 0.1);
  // nu = 0, where the report says the formula holds: E within a few %.
  const physics::TractionMeasure at_zero = physics::measure_traction(
      physics::spring_network_stiffness(tets.rest, physics::van_gelder_springs(tets, 1e4, 0)), tets.rest, size, cells);
  std::cout << "D9 Van Gelder at nu = 0: E " << at_zero.youngs_modulus << " nu " << at_zero.poisson_ratio << "\n";
  EXPECT_NEAR(at_zero.youngs_modulus, 1e4, 0.05 * 1e4);
  EXPECT_NEAR(corrected.youngs_modulus, 1e4, 1e-6 * 1e4);
  EXPECT_NEAR(corrected.poisson_ratio, 0.3, 1e-6);
}
