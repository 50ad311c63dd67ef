// Promayon's discrete models (physics/promayon, seed 002): the shape memory's momentum and
// rigid-motion invariance, the exact volume projection against an independent evaluation of
// the volume, the 3-atom stability test (§5.2) by bisection against the analytic explicit-Euler
// limit, the seed step's volume ramp, and the stiffness calibration against the VN1 network's
// closed form.
#include "physics/promayon/calibration.hpp"
#include "physics/promayon/lattice.hpp"
#include "physics/promayon/seed_step.hpp"
#include "physics/promayon/shape_memory.hpp"
#include "physics/promayon/spring_network.hpp"
#include "physics/promayon/three_atom.hpp"
#include "physics/promayon/volume_projection.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <stdexcept>
#include <vector>

namespace physics = incise::physics;
using physics::Vec3;
using physics::Vector;

namespace {

struct Block {
  physics::HexMesh mesh;
  std::vector<std::vector<int>> neighbours;
  Vector masses;
};

Block block(int cells, physics::Neighbourhood n = physics::Neighbourhood::vn1) {
  Block b;
  b.mesh = physics::make_box_hexes(Vec3::Zero(), Vec3::Constant(0.01 * cells), {cells, cells, cells});
  b.neighbours = physics::lattice_neighbours(b.mesh, n);
  b.masses = physics::lattice_masses(b.mesh, 1000);
  return b;
}

Vector jiggled(const Vector& x, double amplitude, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amplitude, amplitude);
  Vector out = x;
  for (Eigen::Index i = 0; i < out.size(); ++i) out[i] += u(rng);
  return out;
}

Vec3 total(const Vector& f) {
  Vec3 s = Vec3::Zero();
  for (Eigen::Index i = 0; i < f.size(); i += 3) s += f.segment<3>(i);
  return s;
}

}  // namespace

TEST(ShapeMemory, TheForcesSumToZero) {
  const Block b = block(3);
  const physics::ShapeMemory model(b.mesh.rest, b.neighbours, b.masses, 500, 0.01);
  const Vector x = jiggled(b.mesh.rest, 2e-3, 1);
  Vector f = Vector::Zero(x.size());
  model.add_elastic_forces(x, f);
  double largest = 0;
  for (Eigen::Index i = 0; i < f.size(); i += 3) largest = std::max(largest, f.segment<3>(i).norm());
  ASSERT_GT(largest, 1e-3);  // the jiggle is felt
  EXPECT_LT(total(f).norm(), 1e-12 * largest * model.node_count());
}

TEST(ShapeMemory, ARigidMotionGivesNoForce) {
  const Block b = block(3, physics::Neighbourhood::moore);
  const physics::ShapeMemory model(b.mesh.rest, b.neighbours, b.masses, 500, 0.01);
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.9, Vec3(1, -2, 0.5).normalized()).toRotationMatrix();
  Vector x = b.mesh.rest;
  for (Eigen::Index i = 0; i < x.size(); i += 3) x.segment<3>(i) = r * x.segment<3>(i) + Vec3(0.3, -0.1, 0.7);
  Vector f = Vector::Zero(x.size());
  model.add_elastic_forces(x, f);
  EXPECT_LT(f.cwiseAbs().maxCoeff(), 1e-10);  // k_e 500 N/m x round-off on 1 m positions
  EXPECT_LT(model.elastic_energy(x), 1e-20);
  // Sanity: a shear is felt.
  Vector sheared = b.mesh.rest;
  for (Eigen::Index i = 0; i < x.size(); i += 3) sheared[i] += 0.2 * sheared[i + 2] * sheared[i + 2] / 0.03;
  EXPECT_GT(model.elastic_energy(sheared), 1e-6);
}

TEST(ShapeMemory, TripletsAreTheNonCollinearOnes) {
  const Block b = block(2);
  const physics::ShapeMemory model(b.mesh.rest, b.neighbours, b.masses, 1, 0.01);
  // A 3 x 3 x 3 lattice, VN1: 8 corners with 3 neighbours (1 triplet each), 12 edge atoms with 4
  // (4 each: no three collinear), 6 face centres with 5 (10 triplets less the 2 holding a
  // collinear opposite pair and... none: three atoms on a line need all three on one axis), the
  // centre with 6 (20).
  EXPECT_EQ(model.triplet_count(), 8u * 1 + 12u * 4 + 6u * 10 + 1u * 20);
}

TEST(ShapeMemory, ABadSetUpIsRefusedNamingTheAtom) {
  Vector rest(9);
  rest << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  const Vector m = Vector::Ones(3);
  try {
    physics::ShapeMemory model(rest, {{1, 2}, {0, 2}, {0, 1}}, m, 1, 1);
    FAIL() << "two neighbours accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("atom 0 has 2 neighbours"), std::string::npos) << e.what();
  }
  Vector line(12);
  line << 0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0;
  EXPECT_THROW(physics::ShapeMemory(line, {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}}, Vector::Ones(4), 1, 1),
               std::invalid_argument);  // every triplet collinear
  const Block b = block(1);
  EXPECT_THROW(physics::ShapeMemory(b.mesh.rest, b.neighbours, b.masses, 0, 0.01), std::invalid_argument);
}

TEST(SpringNetwork, TheForcesSumToZeroAndMatchTheEnergy) {
  const Block b = block(2, physics::Neighbourhood::moore);
  const physics::SpringNetwork model(b.mesh.rest, b.neighbours, b.masses, 300, 0, 0.01);
  // 3 x 3 x 3 atoms: per axis 7 ordered pairs within one step, 7^3 - 27 self pairs, halved.
  EXPECT_EQ(model.springs().size(), 158u);
  const Vector x = jiggled(b.mesh.rest, 1e-3, 2);
  Vector f = Vector::Zero(x.size());
  model.add_elastic_forces(x, f);
  EXPECT_LT(total(f).norm(), 1e-12 * f.norm());
  // f = -dE/dx, by central differences.
  const double h = 1e-7;
  for (Eigen::Index i : {0, 13, 40}) {
    Vector xp = x, xm = x;
    xp[i] += h, xm[i] -= h;
    EXPECT_NEAR(f[i], -(model.elastic_energy(xp) - model.elastic_energy(xm)) / (2 * h), 1e-6 * f.norm());
  }
}

TEST(VolumeProjection, TheCubicIsTheVolumeAlongTheGradient) {
  const Block b = block(3);
  const auto triangles = physics::hex_boundary_triangles(b.mesh.hexes);
  const Vector x = jiggled(b.mesh.rest, 1e-3, 3);
  const Vector g = physics::volume_gradient(x, triangles, {});
  const physics::VolumeCubic k = physics::volume_cubic(x, g, triangles);
  EXPECT_NEAR(k.d, std::pow(0.03, 3), 2e-6);
  // c = |g|^2 (the derivative of V along g is g.g).
  EXPECT_NEAR(k.c, g.squaredNorm(), 1e-12 * g.squaredNorm());
  for (double l : {-0.5, 0.3, 2.0}) {
    const Vector moved = x + l * g;
    EXPECT_NEAR(((k.a * l + k.b) * l + k.c) * l + k.d, physics::closed_volume(moved, triangles), 1e-15);
  }
  // The gradient against central differences of the volume.
  for (Eigen::Index i : {0, 7, 50}) {
    Vector xp = x, xm = x;
    xp[i] += 1e-6, xm[i] -= 1e-6;
    EXPECT_NEAR(g[i], (physics::closed_volume(xp, triangles) - physics::closed_volume(xm, triangles)) / 2e-6, 1e-12);
  }
}

TEST(VolumeProjection, HitsTheTargetToRoundOff) {
  const Block b = block(3);
  const auto triangles = physics::hex_boundary_triangles(b.mesh.hexes);
  std::vector<std::uint8_t> fixed(b.masses.size(), 0);
  for (int i = 0; i < 8; ++i) fixed[static_cast<std::size_t>(i)] = 1;  // some atoms held
  for (double factor : {0.6, 0.97, 1.0, 1.05, 2.5}) {
    Vector x = jiggled(b.mesh.rest, 2e-3, 4);
    const Vector before = x;
    const double target = factor * std::pow(0.03, 3);
    const physics::VolumeProjection p = physics::project_volume(x, triangles, fixed, target);
    EXPECT_LE(std::abs(physics::closed_volume(x, triangles) - target) / target, 1e-12) << factor;
    EXPECT_EQ(p.volume_after, physics::closed_volume(x, triangles));
    for (int i = 0; i < 8; ++i) EXPECT_EQ(x.segment<3>(3 * i), before.segment<3>(3 * i));
    // The smallest root: a larger change needs a larger multiplier of the same sign.
    EXPECT_EQ(p.lambda > 0, target > p.volume_before);
  }
}

TEST(VolumeProjection, ThePenaltyPullsTowardsTheTargetWithoutNetForce) {
  const Block b = block(2);
  const auto triangles = physics::hex_boundary_triangles(b.mesh.hexes);
  Vector f = Vector::Zero(b.mesh.rest.size());
  const double v = physics::closed_volume(b.mesh.rest, triangles);
  physics::add_volume_penalty_forces(b.mesh.rest, triangles, {}, 1.2 * v, 1e3, f);
  EXPECT_LT(total(f).norm(), 1e-12 * f.norm());
  // Outward: moving along f raises the volume.
  EXPECT_GT(physics::closed_volume(b.mesh.rest + 1e-6 * f / f.norm(), triangles), v);
}

namespace {

// The linear analysis of the seed (§1.3: the Jacobian of the system under explicit Euler): A's
// step x+ = x + dt v, v+ = v - dt (K x + D v) (unit mass) is stable while the 6 x 6 amplification
// matrix has spectral radius <= 1. K is -df/dx on A by central differences, normals included.
Eigen::Matrix3d stiffness_on_a(const physics::DeformableModel& model, const Vector& rest) {
  Eigen::Matrix3d k;
  for (int c = 0; c < 3; ++c) {
    Vector xp = rest, xm = rest, fp = Vector::Zero(rest.size()), fm = Vector::Zero(rest.size());
    xp[c] += 1e-6, xm[c] -= 1e-6;
    model.add_elastic_forces(xp, fp);
    model.add_elastic_forces(xm, fm);
    k.col(c) = -(fp - fm).segment<3>(0) / 2e-6;
  }
  return k;
}

double linear_limit(const Eigen::Matrix3d& k, const Eigen::Matrix3d& d) {
  return physics::largest_stable_dt([&](double dt) {
    Eigen::Matrix<double, 6, 6> g;
    g << Eigen::Matrix3d::Identity(), dt * Eigen::Matrix3d::Identity(), -dt * k, Eigen::Matrix3d::Identity() - dt * d;
    return Eigen::EigenSolver<Eigen::Matrix<double, 6, 6>>(g).eigenvalues().cwiseAbs().maxCoeff() <= 1 + 1e-12;
  });
}

}  // namespace

// The 3-atom test (physics/promayon/three_atom.hpp) by bisection on the step itself.
TEST(ThreeAtomStability, ShapeMemoryTakesTwiceTheExplicitStepOfMassSpring) {
  const physics::ThreeAtom t;
  const double ka = 1, k = 0.05;
  physics::ShapeMemory sm = t.shape_memory(k);
  physics::SpringNetwork ms = t.mass_spring(k, ka);
  const physics::ThreeAtomLimits limits = physics::three_atom_limits(k, ka);
  const double dt_sm = limits.shape_memory, dt_ms = limits.mass_spring;
  std::printf("3-atom test: largest stable explicit Euler dt, shape memory %.4f, mass-spring %.4f, ratio %.3f\n",
              dt_sm, dt_ms, dt_sm / dt_ms);
  // Each against the linear analysis. The network's A sees k_r sum u u^T and k_a sum u u^T
  // (largest eigenvalue 2, along the apex axis). The shape memory's A sees k_a I and a
  // stiffness k_e I plus what B, C and D's own attractors (which hold A in their triplets)
  // redistribute onto it.
  const Eigen::Matrix3d k_sm = stiffness_on_a(sm, t.rest), k_ms = stiffness_on_a(ms, t.rest);
  Eigen::Matrix3d d_ms = Eigen::Matrix3d::Zero();
  for (int j = 1; j <= 3; ++j) {
    const Vec3 u = (t.rest.segment<3>(3 * j) - t.rest.segment<3>(0)).normalized();
    d_ms += ka * u * u.transpose();
  }
  const double linear_sm = linear_limit(k_sm, ka * Eigen::Matrix3d::Identity()), linear_ms = linear_limit(k_ms, d_ms);
  std::printf("linear analysis: shape memory %.4f, mass-spring %.4f\n", linear_sm, linear_ms);
  EXPECT_NEAR(dt_sm, linear_sm, 0.01 * dt_sm);
  EXPECT_NEAR(dt_ms, linear_ms, 0.01 * dt_ms);
  EXPECT_GT(dt_sm / dt_ms, 1.9);
  EXPECT_LT(dt_sm / dt_ms, 2.3);
}

TEST(SeedStep, AVolumeRampIsFollowedExactlyAtEveryStep) {
  const Block b = block(3);
  physics::ShapeMemory model(b.mesh.rest, b.neighbours, b.masses, 50, 0.01);
  physics::VolumeControl volume;
  volume.triangles = physics::hex_boundary_triangles(b.mesh.hexes);
  volume.rest_volume = physics::closed_volume(b.mesh.rest, volume.triangles);
  volume.target = {{0, volume.rest_volume}, {0.2, 2.5 / 0.9 * volume.rest_volume}};
  physics::State state{b.mesh.rest, Vector::Zero(b.mesh.rest.size())};
  std::vector<std::uint8_t> fixed(b.masses.size(), 0);
  fixed[0] = 1;
  const physics::SeedStepSettings settings{1e-3, 0.05, 0, physics::SeedScheme::symplectic_euler};
  double worst = 0;
  for (int k = 1; k <= 300; ++k) {
    const auto r = physics::seed_explicit_step(model, state, fixed, Vector::Zero(state.positions.size()), {}, settings,
                                               &volume, k * 1e-3);
    ASSERT_FALSE(r.nonfinite) << k;
    const double target = volume.at(k * 1e-3);
    worst = std::max(worst, std::abs(physics::closed_volume(state.positions, volume.triangles) - target) / target);
  }
  std::printf("volume ramp x2.78 over 200 steps: worst relative volume error %.2e\n", worst);
  EXPECT_LE(worst, 1e-9);
  EXPECT_EQ(state.positions.segment<3>(0), b.mesh.rest.segment<3>(0));
}

TEST(Calibration, TheVn1NetworkMatchesItsClosedForm) {
  // Clamped compression of c^3 cells: (c + 1)^2 columns of c springs in series, each
  // compressed by strain x h: E = k (c + 1)^2 / (c^2 h).
  for (int c : {2, 4}) {
    const double e = physics::apparent_modulus(physics::PromayonKind::spring_network, physics::Neighbourhood::vn1, c);
    EXPECT_NEAR(e, (c + 1.0) * (c + 1) / (c * c), 1e-6) << c;
  }
}

TEST(Calibration, ShapeMemoryStiffnessFromE) {
  const double c4 = physics::calibration_constant(physics::PromayonKind::shape_memory, physics::Neighbourhood::vn1);
  const double c6 = physics::apparent_modulus(physics::PromayonKind::shape_memory, physics::Neighbourhood::vn1, 6);
  const double moore = physics::calibration_constant(physics::PromayonKind::shape_memory, physics::Neighbourhood::moore);
  std::printf("shape memory apparent modulus per k_e/h: VN1 4 cells %.4f, 6 cells %.4f; Moore 4 cells %.4f\n", c4, c6,
              moore);
  EXPECT_GT(c4, 0);
  EXPECT_GT(moore, 0);
  // Linear in k_e and 1/h: k_e from E reproduces E on the calibration block at another spacing.
  const double h = 0.004, target = 3e4;
  const double ke = physics::stiffness_from_youngs_modulus(physics::PromayonKind::shape_memory, physics::Neighbourhood::vn1,
                                                           target, h);
  EXPECT_NEAR(ke, target * h / c4, 1e-12 * ke);
}

// The symplectic step's bound (seed_step_limit) against bisection on the step itself: a 3 x 3 x 3
// Moore network and shape memory block with its bottom fixed, no damping; stable: the
// perturbation stays within 10 x its size over 3000 steps.
TEST(SeedStep, TheEstimatedLimitIsTheMeasuredOne) {
  const Block b = block(2, physics::Neighbourhood::moore);
  std::vector<std::uint8_t> fixed(b.masses.size(), 0);
  for (std::size_t i = 0; i < fixed.size(); ++i) fixed[i] = b.mesh.rest[static_cast<Eigen::Index>(3 * i + 2)] < 1e-9;
  physics::SpringNetwork network(b.mesh.rest, b.neighbours, b.masses, 300, 0, 0.01);
  const Vector zero = Vector::Zero(b.mesh.rest.size());
  const auto stable = [&](physics::DeformableModel& model, double dt) {
    physics::State state{jiggled(b.mesh.rest, 1e-7, 5), zero};
    for (std::size_t i = 0; i < fixed.size(); ++i)
      if (fixed[i]) state.positions.segment<3>(3 * static_cast<Eigen::Index>(i)) = b.mesh.rest.segment<3>(3 * static_cast<Eigen::Index>(i));
    const physics::SeedStepSettings settings{dt, 0, 0, physics::SeedScheme::symplectic_euler};
    for (int k = 0; k < 3000; ++k) {
      if (physics::seed_explicit_step(model, state, fixed, zero, {}, settings, nullptr, 0).nonfinite) return false;
      if ((state.positions - b.mesh.rest).cwiseAbs().maxCoeff() > 1e-6) return false;
    }
    return true;
  };
  const double estimate = physics::seed_step_limit(network, fixed);
  double lo = estimate / 10, hi = estimate * 10;
  while (hi - lo > 1e-3 * lo) {
    const double mid = 0.5 * (lo + hi);
    (stable(network, mid) ? lo : hi) = mid;
  }
  std::printf("spring network: estimated limit %.4e s, measured %.4e s\n", estimate, lo);
  EXPECT_NEAR(lo, estimate, 0.03 * estimate);
}

// Why the shape memory's bulk is soft (docs/status.md): an atom whose neighbourhood is
// centrally symmetric (interior VN1 or Moore) feels no pull under ANY affine map of its
// neighbourhood, not only a small one: the barycentric part follows the map exactly, and a
// triplet's mirror image through the atom (which an affine map keeps the mirror image) has the
// same normal and the opposite beta, so their normal terms cancel. A homogeneous strain of the
// lattice is resisted by the boundary atoms only, at first order (halving it halves the pull).
TEST(ShapeMemory, AnInteriorAtomIgnoresAnyAffineMap) {
  const Block b = block(4);
  const physics::ShapeMemory model(b.mesh.rest, b.neighbours, b.masses, 1, 0.01);
  Eigen::Matrix3d strain;
  strain << 0.3, 0.1, -0.05, 0.1, -0.2, 0.07, -0.05, 0.07, 0.15;
  const auto pull_at = [&](double scale, int atom) {
    Vector x = b.mesh.rest;
    for (Eigen::Index i = 0; i < x.size(); i += 3) x.segment<3>(i) += scale * strain * b.mesh.rest.segment<3>(i);
    return (model.attractor(x, atom) - x.segment<3>(3 * atom)).norm();
  };
  const int centre = 2 + 5 * (2 + 5 * 2), face = 2 + 5 * (2 + 5 * 0);  // atoms (2,2,2) and (2,2,0)
  ASSERT_NEAR(b.mesh.rest[3 * centre], 0.02, 1e-12);
  std::printf("pull at strain scale 1: interior atom %.2e m, boundary atom %.2e m\n", pull_at(1, centre), pull_at(1, face));
  EXPECT_LT(pull_at(1, centre), 1e-15);  // round-off on 4 cm positions, at 30 % strain
  EXPECT_GT(pull_at(1, face), 1e-4);
  EXPECT_NEAR(pull_at(1e-3, face) / pull_at(5e-4, face), 2, 0.01);
}

// The unmirrored triplet selection (shape_memory.hpp): half the interior atom's triplets, and
// the one left of each mirror pair no longer cancels, so the interior atom is pulled under a
// homogeneous strain (linearly for small strains); forces still sum to zero.
TEST(ShapeMemory, TheUnmirroredSelectionPullsAnInteriorAtomUnderAnAffineMap) {
  const Block b = block(4);
  const physics::ShapeMemory all(b.mesh.rest, b.neighbours, b.masses, 1, 0.01);
  const physics::ShapeMemory half(b.mesh.rest, b.neighbours, b.masses, 1, 0.01, physics::TripletSelection::unmirrored);
  // 5^3 atoms: 27 interior (20 triplets each, 10 kept), 54 face (10, 8 kept), 36 edge (4), 8 corners (1).
  EXPECT_EQ(all.triplet_count(), 27u * 20 + 54 * 10 + 36 * 4 + 8);
  EXPECT_EQ(half.triplet_count(), 27u * 10 + 54 * 8 + 36 * 4 + 8);
  Eigen::Matrix3d strain;
  strain << 0.3, 0.1, -0.05, 0.1, -0.2, 0.07, -0.05, 0.07, 0.15;
  const int centre = 2 + 5 * (2 + 5 * 2);
  const auto pull_at = [&](const physics::ShapeMemory& model, double scale) {
    Vector x = b.mesh.rest;
    for (Eigen::Index i = 0; i < x.size(); i += 3) x.segment<3>(i) += scale * strain * b.mesh.rest.segment<3>(i);
    return (model.attractor(x, centre) - x.segment<3>(3 * centre)).norm();
  };
  std::printf("interior atom's pull at strain scale 1: all triplets %.2e m, unmirrored %.2e m\n", pull_at(all, 1),
              pull_at(half, 1));
  EXPECT_LT(pull_at(all, 1), 1e-15);
  EXPECT_GT(pull_at(half, 1), 1e-4);
  EXPECT_NEAR(pull_at(half, 1e-3) / pull_at(half, 5e-4), 2, 0.01);
  Vector f = Vector::Zero(b.mesh.rest.size());
  half.add_elastic_forces(jiggled(b.mesh.rest, 1e-3, 3), f);
  EXPECT_LT(total(f).norm(), 1e-12 * f.norm());
}
