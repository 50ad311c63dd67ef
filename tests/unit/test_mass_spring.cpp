// Baudet's hexahedral mass-spring model (physics/mss, seed 003): the stiffness formulas
// against the digest's tabulated values (seed-000-003.md B.1.3), the mesh-quality guard,
// linear traction of a cube and a bar with roller supports against the digest's measured E and
// nu (D5, springs only: no correction forces), Newton's third law, the tangent against finite
// differences, the lumped mass, the explicit bound and the dashpots' dissipation.
#include "physics/core/explicit_integrators.hpp"
#include "physics/core/implicit_euler.hpp"
#include "physics/mss/baudet_stiffness.hpp"
#include "physics/mss/hex_mass_spring.hpp"
#include "physics/mss/hex_mesh.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <random>
#include <string>
#include <vector>

namespace physics = incise::physics;
using physics::Vec3;
using physics::Vector;

namespace {

physics::MassSpringMaterial material(double nu, double damping_ratio = 1) {
  return {1e4, nu, 1500, damping_ratio};  // the report's test material (Fléchon §5.3)
}

// K assembled column by column from the model's product (small meshes only).
Eigen::MatrixXd dense_stiffness(const physics::DeformableModel& model) {
  const Eigen::Index size = 3 * model.node_count();
  Eigen::MatrixXd k(size, size);
  for (Eigen::Index c = 0; c < size; ++c) {
    Vector unit = Vector::Zero(size), column = Vector::Zero(size);
    unit[c] = 1;
    model.add_stiffness_product(unit, column);
    k.col(c) = column;
  }
  return k;
}

struct Measured {
  double youngs_modulus = 0, poisson_ratio = 0, lateral_y = 0;
};

// Linear traction along x of a box of `cells` bricks (digest B.1.3's check): the face x = min
// held only along x (rollers), the face x = max pulled by a total force F shared by the
// consistent weights (corner 1/4, edge 1/2, interior 1 per face brick, Fléchon Fig. 9), three
// lateral DOFs at x = min holding the rigid motions without restraining the contraction.
// With `corrections`, Baudet's correction forces enter the linear solve through their
// derivative at rest (central differences: they vanish at rest and are linear in small strain).
Measured traction(const Vec3& size, std::array<int, 3> cells, double nu, bool corrections = false) {
  const physics::HexMesh mesh = physics::make_box_hexes(Vec3::Zero(), size, cells);
  physics::MassSpringMaterial properties = material(nu);
  properties.corrections = corrections;
  physics::HexMassSpring model(mesh, properties);
  model.update_rotations(mesh.rest);
  Eigen::MatrixXd k = dense_stiffness(model);
  if (corrections) {
    const double h = 1e-6 * size.minCoeff();
    for (Eigen::Index d = 0; d < mesh.rest.size(); ++d) {
      Vector plus = mesh.rest, minus = mesh.rest, fp = Vector::Zero(mesh.rest.size()), fm = fp;
      plus[d] += h, minus[d] -= h;
      model.add_correction_forces(plus, fp);
      model.add_correction_forces(minus, fm);
      k.col(d) -= (fp - fm) / (2 * h);
    }
  }
  const int n = model.node_count();
  const double force = 1e-3;
  Vector load = Vector::Zero(3 * n);
  std::vector<bool> held(3 * n, false);
  const double eps = 1e-9;
  for (int i = 0; i < n; ++i) {
    const Vec3 p = mesh.rest.segment<3>(3 * i);
    if (p.x() < eps) {
      held[3 * i] = true;
      if (p.y() < eps && p.z() < eps) held[3 * i + 1] = held[3 * i + 2] = true;
      if (p.y() > size.y() - eps && p.z() < eps) held[3 * i + 2] = true;
      if (p.y() < eps && p.z() > size.z() - eps) held[3 * i + 1] = true;
    }
    if (p.x() > size.x() - eps) {
      const bool y_edge = p.y() < eps || p.y() > size.y() - eps, z_edge = p.z() < eps || p.z() > size.z() - eps;
      const double weight = (y_edge ? 0.5 : 1.0) * (z_edge ? 0.5 : 1.0);
      load[3 * i] = force * weight / (cells[1] * cells[2]);
    }
  }
  std::vector<Eigen::Index> free;
  for (Eigen::Index d = 0; d < 3 * n; ++d)
    if (!held[d]) free.push_back(d);
  Eigen::MatrixXd reduced(free.size(), free.size());
  Vector rhs(free.size());
  for (std::size_t a = 0; a < free.size(); ++a) {
    rhs[a] = load[free[a]];
    for (std::size_t b = 0; b < free.size(); ++b) reduced(a, b) = k(free[a], free[b]);
  }
  const Vector solution = reduced.fullPivLu().solve(rhs);
  Vector u = Vector::Zero(3 * n);
  for (std::size_t a = 0; a < free.size(); ++a) u[free[a]] = solution[a];
  double stretch = 0, y_top = 0, y_bottom = 0;
  int loaded = 0, top = 0, bottom = 0;
  for (int i = 0; i < n; ++i) {
    const Vec3 p = mesh.rest.segment<3>(3 * i);
    if (p.x() > size.x() - eps) stretch += u[3 * i], ++loaded;
    if (p.y() > size.y() - eps) y_top += u[3 * i + 1], ++top;
    if (p.y() < eps) y_bottom += u[3 * i + 1], ++bottom;
  }
  const double strain = stretch / loaded / size.x();
  const double lateral = (y_top / top - y_bottom / bottom) / size.y();
  return {force / (size.y() * size.z()) / strain, -lateral / strain, lateral};
}

}  // namespace

TEST(MassSpringFormulas, CubeStiffnessesAreTheDigestsTable) {
  // Digest B.1.3, E = 1e4 Pa, edge 0.1 m: (nu, k_edge, k_d, F_perp / F).
  const double table[4][4] = {{0.1, 159.09, 340.91, 0.0375}, {0.2, 187.50, 312.50, 0.0125},
                              {0.3, 211.54, 288.46, -0.0125}, {0.4, 232.14, 267.86, -0.0375}};
  for (const auto& row : table) {
    const physics::BrickSprings k = physics::baudet_brick_springs(Vec3::Constant(0.1), 1e4, row[0]);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(k.edge[i], row[1], 0.006) << "nu " << row[0];
    EXPECT_NEAR(k.diagonal, row[2], 0.006) << "nu " << row[0];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) EXPECT_NEAR(k.correction(i, j), i == j ? 0.0 : row[3], 1e-12);
  }
}

TEST(MassSpringFormulas, BrickFormulasFollowTheAxes) {
  // The same brick turned: its stiffnesses turn with it.
  const physics::BrickSprings a = physics::baudet_brick_springs({0.12, 0.1, 0.08}, 1e4, 0.3);
  const physics::BrickSprings b = physics::baudet_brick_springs({0.1, 0.08, 0.12}, 1e4, 0.3);
  EXPECT_NEAR(a.edge[0], b.edge[2], 1e-9);
  EXPECT_NEAR(a.edge[1], b.edge[0], 1e-9);
  EXPECT_NEAR(a.edge[2], b.edge[1], 1e-9);
  EXPECT_NEAR(a.diagonal, b.diagonal, 1e-9);
  EXPECT_NEAR(a.correction(0, 1), b.correction(2, 0), 1e-12);
}

TEST(MassSpringGuard, TheEdgeStiffnessChangesSignAtTheDigestsAspectRatio) {
  // Digest B.1.3: at nu = 0.3 a brick i x j x j keeps k_i > 0 only while i / j <= 1.543.
  EXPECT_GT(physics::baudet_brick_springs({1.54, 1, 1}, 1e4, 0.3).edge[0], 0);
  EXPECT_LT(physics::baudet_brick_springs({1.55, 1, 1}, 1e4, 0.3).edge[0], 0);
  EXPECT_GT(physics::baudet_brick_springs({1.65, 1, 1}, 1e4, 0.45).edge[0], 0);
  EXPECT_LT(physics::baudet_brick_springs({1.66, 1, 1}, 1e4, 0.45).edge[0], 0);
}

TEST(MassSpringGuard, AnElongatedBrickIsRefusedByIndexAndAspectRatio) {
  const physics::HexMesh mesh = physics::make_box_hexes(Vec3::Zero(), {0.3, 0.1, 0.1}, {1, 1, 1});
  try {
    physics::HexMassSpring model(mesh, material(0.3));
    FAIL() << "a 3:1 brick was accepted";
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("hexahedron 0 "), std::string::npos) << message;
    EXPECT_NE(message.find("aspect ratio 3"), std::string::npos) << message;
    EXPECT_NE(message.find("edge stiffness along x"), std::string::npos) << message;
  }
  EXPECT_NO_THROW(physics::HexMassSpring(physics::make_box_hexes(Vec3::Zero(), {0.15, 0.1, 0.1}, {1, 1, 1}), material(0.3)));
}

TEST(MassSpringTraction, ACubeWithoutCorrectionsMeasuresTheDigestsEAndNu) {
  // Digest B.1.3 / D5, springs only: (8 235, 0.294), (10 476, 0.238), (11 667, 0.208).
  const double expected[3][3] = {{0.1, 8235, 0.294}, {0.3, 10476, 0.238}, {0.45, 11667, 0.208}};
  for (const auto& row : expected) {
    const Measured m = traction(Vec3::Constant(0.1), {1, 1, 1}, row[0]);
    EXPECT_NEAR(m.youngs_modulus, row[1], 1.0) << "nu " << row[0];
    EXPECT_NEAR(m.poisson_ratio, row[2], 6e-4) << "nu " << row[0];
  }
}

TEST(MassSpringTraction, ABarStretchesAndContractsAsOneCube) {
  // Summed parallel springs make a uniform lattice carry the cube's homogeneous strain: a
  // 4 x 2 x 2 bar measures the single cube's E and nu (stretch within the digest's 4.8 % of E
  // at nu = 0.3 without corrections), and its sides move inwards (a positive nu).
  const Measured cube = traction(Vec3::Constant(0.1), {1, 1, 1}, 0.3);
  const Measured bar = traction({0.4, 0.2, 0.2}, {4, 2, 2}, 0.3);
  EXPECT_NEAR(bar.youngs_modulus, cube.youngs_modulus, 1e-6 * cube.youngs_modulus);
  EXPECT_NEAR(bar.poisson_ratio, cube.poisson_ratio, 1e-6);
  EXPECT_LT(bar.lateral_y, 0);
  EXPECT_NEAR(bar.youngs_modulus, 1e4, 0.05 * 1e4);
}

TEST(MassSpringModel, ForcesSumToZeroAndTheTangentIsTheirDerivative) {
  const physics::HexMesh mesh = physics::make_box_hexes(Vec3::Zero(), {0.3, 0.2, 0.1}, {3, 2, 1});
  physics::HexMassSpring model(mesh, material(0.3));
  std::mt19937 random(7);
  std::uniform_real_distribution<double> jitter(-0.01, 0.01);
  // Stretched by 20 % and jittered: every spring longer than at rest, where the tangent is exact.
  Vector x = 1.2 * mesh.rest;
  for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += jitter(random);
  Vector f = Vector::Zero(x.size());
  model.add_elastic_forces(x, f);
  Vec3 total = Vec3::Zero(), torque = Vec3::Zero();
  for (int i = 0; i < model.node_count(); ++i) {
    total += f.segment<3>(3 * i);
    torque += Vec3(x.segment<3>(3 * i)).cross(Vec3(f.segment<3>(3 * i)));
  }
  EXPECT_LT(total.norm(), 1e-12 * f.norm());
  EXPECT_LT(torque.norm(), 1e-12 * f.norm());
  model.update_rotations(x);
  const Eigen::MatrixXd k = dense_stiffness(model);
  EXPECT_LT((k - k.transpose()).norm(), 1e-12 * k.norm());
  const double h = 1e-7;
  for (Eigen::Index d = 0; d < x.size(); d += 5) {
    Vector plus = x, minus = x;
    plus[d] += h, minus[d] -= h;
    Vector fp = Vector::Zero(x.size()), fm = Vector::Zero(x.size());
    model.add_elastic_forces(plus, fp);
    model.add_elastic_forces(minus, fm);
    const Vector numeric = -(fp - fm) / (2 * h);
    EXPECT_LT((numeric - k.col(d)).norm(), 1e-5 * k.col(d).norm()) << "dof " << d;
  }
  // The dashpots act on relative velocities only: a rigid translation is not damped.
  Vector translation(x.size()), damped = Vector::Zero(x.size());
  for (int i = 0; i < model.node_count(); ++i) translation.segment<3>(3 * i) = Vec3(1, -2, 0.5);
  model.add_damping_product(translation, damped);
  EXPECT_LT(damped.norm(), 1e-12);
}

TEST(MassSpringModel, SharedSpringsAreMergedAndMassIsRhoV) {
  const physics::HexMesh mesh = physics::make_box_hexes(Vec3::Zero(), {0.2, 0.2, 0.2}, {2, 2, 2});
  physics::HexMassSpring model(mesh, material(0.3));
  // 27 nodes: 3 x 3 x 2 x 3 = 54 edges along the axes, 8 x 4 = 32 diagonals, each created once.
  EXPECT_EQ(model.springs().size(), 54u + 32u);
  const physics::BrickSprings k = physics::baudet_brick_springs(Vec3::Constant(0.1), 1e4, 0.3);
  int interior = 0;
  for (const physics::Spring& s : model.springs()) {
    const Vec3 middle = 0.5 * (mesh.rest.segment<3>(3 * s.a) + mesh.rest.segment<3>(3 * s.b));
    // An edge through the block's centre, shared by 4 bricks: 4 k_edge (digest: 846.15 N/m).
    if ((middle - Vec3(0.1, 0.1, 0.1)).norm() < 0.051 && std::abs(s.rest_length - 0.1) < 1e-12) {
      EXPECT_NEAR(s.stiffness, 4 * k.edge[0], 1e-9);
      ++interior;
    }
  }
  EXPECT_EQ(interior, 6);
  EXPECT_NEAR(model.lumped_masses().sum(), 1500 * 0.008, 1e-12);
  EXPECT_NEAR(model.lumped_masses()[13], 1.5, 1e-12);  // the centre node: 8 x 0.1875 kg (digest)
  // A voxelised ball: the mass is rho x the bricks' volume.
  const physics::HexMesh ball = physics::make_hexes_inside(
      [](const Vec3& p) { return p.norm() <= 0.05; }, Vec3::Constant(-0.05), Vec3::Constant(0.05), 0.01);
  physics::HexMassSpring voxels(ball, material(0.3));
  EXPECT_NEAR(voxels.lumped_masses().sum(), 1500 * 1e-6 * static_cast<double>(ball.hexes.size()), 1e-12);
  EXPECT_GT(ball.hexes.size(), 400u);
  EXPECT_LT(ball.hexes.size(), 600u);  // 4/3 pi 5^3 = 524 cells of the 1000
}

TEST(MassSpringModel, AnExplicitStepBeyondTheBoundIsRefused) {
  // One 0.1 m cube, nu = 0.3, rho = 1500: every node has 0.1875 kg and 3 k_edge + k_d =
  // 923.08 N/m, so dt <= 2 sqrt(0.1875 / 923.08) = 28.5 ms.
  const physics::HexMesh mesh = physics::make_box_hexes(Vec3::Zero(), Vec3::Constant(0.1), {1, 1, 1});
  physics::HexMassSpring model(mesh, material(0.3));
  const double bound = 2 * std::sqrt(0.1875 / (3 * 211.538461538 + 288.461538462));
  EXPECT_NEAR(model.explicit_step_limit(), bound, 1e-9);
  physics::State state{mesh.rest, Vector::Zero(mesh.rest.size())};
  physics::ExplicitSettings settings;
  settings.dt = 1.01 * bound;
  try {
    physics::explicit_step(physics::ExplicitScheme::velocity_verlet, model, state, {}, Vector::Zero(24), settings);
    FAIL() << "a step beyond the bound was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("explicit stability bound 0.0285 s"), std::string::npos) << e.what();
  }
  settings.dt = 0.99 * bound;
  EXPECT_FALSE(physics::explicit_step(physics::ExplicitScheme::velocity_verlet, model, state, {}, Vector::Zero(24), settings)
                   .nonfinite);
}

TEST(MassSpringModel, TheDashpotsOnlyDissipateAndTheCubeComesToRest) {
  const physics::HexMesh mesh = physics::make_box_hexes(Vec3::Zero(), Vec3::Constant(0.1), {1, 1, 1});
  physics::HexMassSpring model(mesh, material(0.3));
  physics::State state{mesh.rest, Vector::Zero(mesh.rest.size())};
  state.positions *= 1.1;  // stretched 10 % and let go, no external force
  physics::ImplicitEulerSettings settings;
  settings.dt = 0.01;
  settings.cg.tolerance = 1e-12;
  double energy = model.elastic_energy(state.positions);
  Vec3 momentum = Vec3::Zero();
  for (int step = 0; step < 200; ++step) {
    const physics::StepReport report =
        physics::implicit_euler_step(model, state, {}, Vector::Zero(24), {}, settings);
    ASSERT_FALSE(report.nonfinite);
    const double total = report.elastic_energy + report.kinetic_energy;
    EXPECT_LE(total, energy * (1 + 1e-9)) << "step " << step;
    energy = total;
  }
  for (int i = 0; i < 8; ++i) momentum += 0.1875 * Vec3(state.velocities.segment<3>(3 * i));
  EXPECT_LT(momentum.norm(), 1e-9);
  EXPECT_LT(energy, 1e-6 * model.elastic_energy(1.1 * mesh.rest));
  // Back to its rest size: every edge 0.1 m again.
  for (const physics::Spring& s : model.springs())
    EXPECT_NEAR((state.positions.segment<3>(3 * s.b) - state.positions.segment<3>(3 * s.a)).norm(), s.rest_length, 1e-4);
}

TEST(MassSpringTraction, CorrectionForcesGiveTheTargetEAndNuExactly) {
  // Digest B.1.3 / D5: with 2 F_ij on each node, F_i the brick's axial load from its springs,
  // a cube, a 1.2 x 1.0 x 0.8 brick, a 3 x 3 x 3 block of cubes and a 4 x 2 x 2 block of
  // 0.12 x 0.1 x 0.08 bricks measure E = 1e4 and the target nu.
  for (double nu : {0.1, 0.3, 0.45}) {
    for (const auto& [size, cells] : std::vector<std::pair<Vec3, std::array<int, 3>>>{
             {Vec3::Constant(0.1), {1, 1, 1}}, {Vec3(1.2, 1.0, 0.8), {1, 1, 1}},
             {Vec3::Constant(0.3), {3, 3, 3}}, {Vec3(0.48, 0.2, 0.16), {4, 2, 2}}}) {
      const Measured m = traction(size, cells, nu, true);
      EXPECT_NEAR(m.youngs_modulus, 1e4, 1e-6 * 1e4) << "nu " << nu << ", " << cells[0] << " bricks along x";
      EXPECT_NEAR(m.poisson_ratio, nu, 1e-6) << "nu " << nu << ", " << cells[0] << " bricks along x";
    }
  }
}

TEST(MassSpringModel, CorrectionForcesConserveMomentumAndFollowTheBrick) {
  // A stretched cube turned by 90 degrees about z gets the same corrections, turned.
  const physics::HexMesh mesh = physics::make_box_hexes(Vec3::Zero(), Vec3::Constant(0.1), {1, 1, 1});
  physics::MassSpringMaterial properties = material(0.3);
  properties.corrections = true;
  physics::HexMassSpring model(mesh, properties);
  Vector x = mesh.rest;
  for (int i = 0; i < 8; ++i) x[3 * i] *= 1.05;  // 5 % along x
  Vector f = Vector::Zero(24);
  model.add_correction_forces(x, f);
  Vec3 total = Vec3::Zero();
  for (int i = 0; i < 8; ++i) total += f.segment<3>(3 * i);
  EXPECT_LT(total.norm(), 1e-15);
  const Vec3 loads = model.axial_loads(x, 0);
  EXPECT_GT(loads.x(), 0);
  // Node 0 (at y = 0: outward is -y) gets 2 (F_xy + F_zy) along -y, F_ij = F_i (1 - 4 nu) / 16
  // on a cube (digest B.1.3).
  EXPECT_NEAR(f[1], -2 * (loads.x() + loads.z()) * (1 - 4 * 0.3) / 16, 1e-12);
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(M_PI / 2, Vec3::UnitZ()).toRotationMatrix();
  Vector turned = x, g = Vector::Zero(24);
  for (int i = 0; i < 8; ++i) turned.segment<3>(3 * i) = turn * Vec3(x.segment<3>(3 * i));
  model.add_correction_forces(turned, g);
  for (int i = 0; i < 8; ++i) EXPECT_LT((Vec3(g.segment<3>(3 * i)) - turn * Vec3(f.segment<3>(3 * i))).norm(), 1e-12);
}

TEST(MassSpringTraction, TheStepsSettleACorrectedCubeAtTheTargetEAndNu) {
  // With the corrections' derivative in the implicit steps (BiCGSTAB): pulled apart by F on its
  // two x faces (free, the loads balanced), a corrected cube comes to rest at the strain E and
  // nu give, within the geometric nonlinearity of a 1e-4 strain.
  const physics::HexMesh mesh = physics::make_box_hexes(Vec3::Zero(), Vec3::Constant(0.1), {1, 1, 1});
  physics::MassSpringMaterial properties = material(0.3);
  properties.corrections = true;
  physics::HexMassSpring model(mesh, properties);
  const double force = 1e-4 * 1e4 * 0.01;  // stress E x 1e-4 on the 0.01 m^2 face
  Vector load = Vector::Zero(24);
  for (int i = 0; i < 8; ++i) load[3 * i] = (mesh.rest[3 * i] > 0.05 ? 0.25 : -0.25) * force;
  physics::State state{mesh.rest, Vector::Zero(24)};
  physics::ImplicitEulerSettings settings;
  settings.dt = 0.01;
  settings.cg.tolerance = 1e-12;
  settings.cg.max_iterations = 1000;
  for (int step = 0; step < 2000; ++step)
    ASSERT_FALSE(physics::implicit_euler_step(model, state, {}, load, {}, settings).nonfinite);
  const Vector u = state.positions - mesh.rest;
  double stretch = 0, lateral = 0;
  for (int i = 0; i < 8; ++i) {
    stretch += (mesh.rest[3 * i] > 0.05 ? 0.25 : -0.25) * u[3 * i];
    lateral += (mesh.rest[3 * i + 1] > 0.05 ? 0.25 : -0.25) * u[3 * i + 1];
  }
  const double strain = stretch / 0.1;
  EXPECT_NEAR((force / 0.01) / strain, 1e4, 1e-3 * 1e4);
  EXPECT_NEAR(-lateral / stretch, 0.3, 1e-3);
  EXPECT_LT(state.velocities.norm(), 1e-9);
}
