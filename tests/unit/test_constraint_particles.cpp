// Dionne's constraint particles (physics/cp, seed 000): each constraint's forces sum to zero and
// have no moment (eq. 3.14), its gradient against central differences, the volume force's
// scaling with the 1/V0 the thesis lost (digest A.5.1), the 5-tet cube's counts (§4.2), the
// stretch limiter's projections keeping sum m dx = 0 (eq. 3.15) and their k' (eq. 1.40), a free
// body's momentum under each scheme and damping, an inverted tet counted and restored, the
// settings block's refusals, the model through the world, and the falling cube (digest D3).
#include "engine/scene.hpp"
#include "engine/world.hpp"
#include "physics/core/implicit_euler.hpp"
#include "physics/cp/constraint_particles.hpp"
#include "physics/cp/cp_step.hpp"
#include "physics/cp/cube_drop.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

namespace physics = incise::physics;
namespace engine = incise::engine;
using physics::Constraint;
using physics::ConstraintKind;
using physics::Vec3;
using physics::Vector;

namespace {

// A tet mesh of one cube (5 tets) scaled by `size`, positions jittered by `jitter` x size.
physics::TetMesh jittered_cube(double size, double jitter, unsigned seed, std::array<int, 3> cells = {1, 1, 1}) {
  physics::TetMesh mesh = physics::make_box_tets5(Vec3::Zero(), Vec3::Constant(size), cells);
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> u(-jitter * size, jitter * size);
  for (Eigen::Index i = 0; i < mesh.rest.size(); ++i) mesh.rest[i] += u(random);
  return mesh;
}

Vector deformed(const Vector& rest, double amount, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> u(-amount, amount);
  Vector x = rest;
  for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += u(random);
  return x;
}

std::vector<Constraint> one_of_each(const physics::TetMesh& mesh) {
  const auto& t = mesh.tets[0];
  std::vector<Constraint> out{{ConstraintKind::distance, {t[0], t[1], 0, 0}, 0, 500},
                              {ConstraintKind::area, {t[0], t[1], t[2], 0}, 0, 300},
                              {ConstraintKind::volume, t, 0, 700}};
  for (Constraint& c : out) c.rest = physics::constraint_measure(c, mesh.rest);
  return out;
}

}  // namespace

TEST(ConstraintParticles, EachConstraintsForcesSumToZeroWithoutMoment) {
  const physics::TetMesh mesh = jittered_cube(0.1, 0.05, 1);
  const Vector x = deformed(mesh.rest, 0.02, 2);
  for (const Constraint& c : one_of_each(mesh)) {
    std::array<Vec3, 4> g;
    const double value = physics::constraint_gradient(c, x, g);
    ASSERT_GT(std::abs(value), 1e-3);  // deformed: the forces are not trivially zero
    Vec3 force = Vec3::Zero(), moment = Vec3::Zero();
    double scale = 0;
    for (int a = 0; a < physics::constraint_arity(c.kind); ++a) {
      const Vec3 f = -c.stiffness * value * g[a];
      force += f;
      moment += x.segment<3>(3 * c.nodes[a]).cross(f);
      scale = std::max(scale, f.norm());
    }
    EXPECT_LT(force.norm(), 1e-12 * scale) << static_cast<int>(c.kind);
    EXPECT_LT(moment.norm(), 1e-12 * scale * 0.2) << static_cast<int>(c.kind);
  }
}

TEST(ConstraintParticles, GradientsMatchCentralDifferences) {
  const physics::TetMesh mesh = jittered_cube(0.1, 0.05, 3);
  const Vector x = deformed(mesh.rest, 0.02, 4);
  const double h = 1e-7;
  for (const Constraint& c : one_of_each(mesh)) {
    std::array<Vec3, 4> g, unused;
    physics::constraint_gradient(c, x, g);
    for (int a = 0; a < physics::constraint_arity(c.kind); ++a)
      for (int d = 0; d < 3; ++d) {
        Vector plus = x, minus = x;
        plus[3 * c.nodes[a] + d] += h;
        minus[3 * c.nodes[a] + d] -= h;
        const double numeric =
            (physics::constraint_gradient(c, plus, unused) - physics::constraint_gradient(c, minus, unused)) / (2 * h);
        EXPECT_NEAR(g[a][d], numeric, 1e-6 * std::max(1.0, std::abs(numeric))) << static_cast<int>(c.kind) << " " << a << " " << d;
      }
  }
  // The model's force is minus its energy's gradient.
  physics::ConstraintParticleSettings settings;
  settings.area_on_every_face = true;
  physics::ConstraintParticles model(mesh, settings);
  Vector f = Vector::Zero(x.size());
  model.add_elastic_forces(x, f);
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    Vector plus = x, minus = x;
    plus[i] += h;
    minus[i] -= h;
    const double numeric = -(model.elastic_energy(plus) - model.elastic_energy(minus)) / (2 * h);
    EXPECT_NEAR(f[i], numeric, 1e-5 * std::max(1.0, f.cwiseAbs().maxCoeff()));
  }
}

// The normalised constraints make k an energy: a body scaled by s under the same strain feels
// nodal forces scaled by 1/s. Eq. 3.7 as printed (without 1/V0) would scale the volume force by s^2.
TEST(ConstraintParticles, TheVolumeForceScalesAsOneOverSize) {
  const physics::TetMesh small = jittered_cube(0.01, 0.05, 5);
  physics::TetMesh large = small;
  large.rest *= 100;
  const Vector x_small = deformed(small.rest, 0.001, 6);
  const Vector x_large = 100 * x_small;
  for (ConstraintKind kind : {ConstraintKind::distance, ConstraintKind::area, ConstraintKind::volume}) {
    Constraint a = one_of_each(small)[static_cast<int>(kind)];
    Constraint b = one_of_each(large)[static_cast<int>(kind)];
    std::array<Vec3, 4> ga, gb;
    const double ca = physics::constraint_gradient(a, x_small, ga);
    const double cb = physics::constraint_gradient(b, x_large, gb);
    EXPECT_NEAR(ca, cb, 1e-9);
    EXPECT_NEAR((ga[0] / 100 - gb[0]).norm(), 0, 1e-9 * ga[0].norm()) << static_cast<int>(kind);
  }
}

// At rest every C is 0, so the stiffness K = sum k grad C grad C^T (Gauss-Newton) is the exact
// -df/dx there: checked against central differences of the forces.
TEST(ConstraintParticles, TheStiffnessAtRestIsTheForcesDerivative) {
  const physics::TetMesh mesh = jittered_cube(0.1, 0.05, 11, {2, 1, 1});
  physics::ConstraintParticleSettings settings;
  settings.area_on_every_face = true;
  physics::ConstraintParticles model(mesh, settings);
  model.update_rotations(mesh.rest);
  const Vector p = deformed(Vector::Zero(mesh.rest.size()), 1, 12);
  Vector kp = Vector::Zero(p.size());
  model.add_stiffness_product(p, kp);
  const double h = 1e-7;
  Vector plus = Vector::Zero(p.size()), minus = Vector::Zero(p.size());
  model.add_elastic_forces(mesh.rest + h * p, plus);
  model.add_elastic_forces(mesh.rest - h * p, minus);
  const Vector numeric = -(plus - minus) / (2 * h);
  EXPECT_LT((kp - numeric).norm(), 1e-5 * kp.norm());
  Vector diagonal = Vector::Zero(p.size());
  model.add_stiffness_diagonal(diagonal);
  for (Eigen::Index i = 0; i < p.size(); i += 7) {
    Vector unit = Vector::Zero(p.size()), column = Vector::Zero(p.size());
    unit[i] = 1;
    model.add_stiffness_product(unit, column);
    EXPECT_NEAR(diagonal[i], column[i], 1e-9 * diagonal[i]);
  }
}

// Both dashpots leave a translation alone; the constraint-projected one (eq. 1.16) leaves a
// rigid rotation alone too, the relative one (eq. 1.14) damps it (the "oil" the thesis notes).
TEST(ConstraintParticles, TheConstraintDashpotsLeaveRigidMotionUndamped) {
  const physics::TetMesh mesh = jittered_cube(0.1, 0.05, 13, {2, 2, 1});
  const Vector x = deformed(mesh.rest, 0.01, 14);
  const Vec3 omega(0.3, -1.2, 0.7), velocity(0.5, 0.1, -0.2);
  Vector translation(x.size()), rotation(x.size());
  for (Eigen::Index i = 0; i < x.size() / 3; ++i) {
    translation.segment<3>(3 * i) = velocity;
    rotation.segment<3>(3 * i) = omega.cross(Vec3(x.segment<3>(3 * i)));
  }
  for (physics::ParticleDamping damping : {physics::ParticleDamping::relative, physics::ParticleDamping::constraint}) {
    physics::ConstraintParticleSettings settings;
    settings.damping = damping;
    settings.damping_coefficient = 1;
    physics::ConstraintParticles model(mesh, settings);
    model.update_rotations(x);
    Vector d_translation = Vector::Zero(x.size()), d_rotation = Vector::Zero(x.size());
    model.add_damping_product(translation, d_translation);
    model.add_damping_product(rotation, d_rotation);
    EXPECT_LT(d_translation.norm(), 1e-12);
    if (damping == physics::ParticleDamping::constraint) EXPECT_LT(d_rotation.norm(), 1e-9);
    else EXPECT_GT(d_rotation.norm(), 0.1);
    EXPECT_GT(rotation.dot(d_rotation), -1e-12);  // dissipative: v . D v >= 0
  }
}

TEST(ConstraintParticles, TheThesisCubeHasItsCounts) {
  // §4.2: 729 particles, 2,560 tets, 3,672 distance, 5,504 area and 2,560 volume constraints.
  const physics::TetMesh mesh = physics::make_box_tets5(Vec3::Zero(), Vec3(8, 8, 8), {8, 8, 8});
  EXPECT_EQ(mesh.rest.size(), 3 * 729);
  EXPECT_EQ(mesh.tets.size(), 2560u);
  EXPECT_EQ(physics::unique_tet_edges(mesh.tets).size(), 3672u);
  EXPECT_EQ(physics::unique_tet_faces(mesh.tets).size(), 5504u);
  EXPECT_NEAR(physics::total_volume(mesh.rest, mesh.tets), 512, 1e-9);
  // Conforming: the boundary is the cube's 6 faces of 8 x 8 cells, 2 triangles each.
  EXPECT_EQ(physics::boundary_triangles(mesh.tets).size(), 6u * 64u * 2u);
  physics::ConstraintParticleSettings settings;
  settings.area_on_every_face = true;
  const physics::ConstraintParticles model(mesh, settings);
  EXPECT_EQ(model.constraints().size(), 3672u + 5504u + 2560u);
  EXPECT_NEAR(model.lumped_masses().sum(), 512 * settings.density, 1e-6);
  EXPECT_EQ(model.inverted_tets(mesh.rest), 0);
}

TEST(ConstraintParticles, EachStretchProjectionKeepsSumMDxZeroAndItsStiffness) {
  const physics::TetMesh mesh = jittered_cube(0.1, 0.05, 7, {2, 2, 2});
  physics::ConstraintParticleSettings settings;
  physics::ConstraintParticles model(mesh, settings);
  Vector masses = model.lumped_masses();
  std::mt19937 random(8);
  for (Eigen::Index i = 0; i < masses.size(); ++i) masses[i] *= std::uniform_real_distribution<double>(0.5, 2)(random);
  std::vector<std::uint8_t> fixed(masses.size(), 0);
  const Vector w = physics::inverse_masses(masses, fixed);
  const Vector x = 1.2 * mesh.rest;  // every edge 20 % long, beyond alpha = 1.05
  for (int iterations : {1, 4}) {
    physics::StretchLimiter limiter;
    limiter.iterations = iterations;
    for (const physics::StretchEdge& e : model.edges()) {
      Vector q = x;
      std::vector<std::uint8_t> moved;
      const physics::StretchReport report = physics::limit_stretch({e}, w, limiter, q, moved);
      ASSERT_EQ(report.projections, iterations);
      const Vec3 da = q.segment<3>(3 * e.a) - x.segment<3>(3 * e.a);
      const Vec3 db = q.segment<3>(3 * e.b) - x.segment<3>(3 * e.b);
      EXPECT_LT((masses[e.a] * da + masses[e.b] * db).norm(), 1e-14 * masses.maxCoeff());
      // eq. 1.40: n iterations of k' leave (1 - k_E) of the excess over alpha D0.
      const double before = 1.2 * e.rest - 1.05 * e.rest;
      const double after = (q.segment<3>(3 * e.a) - q.segment<3>(3 * e.b)).norm() - 1.05 * e.rest;
      EXPECT_NEAR(after / before, 0.9, 1e-12);
    }
  }
  // All edges at once: the sum stays zero; a fixed particle never moves.
  fixed[0] = 1;
  Vector q = x;
  std::vector<std::uint8_t> moved;
  physics::limit_stretch(model.edges(), physics::inverse_masses(masses, fixed), {}, q, moved);
  EXPECT_EQ(q.segment<3>(0), x.segment<3>(0));
  EXPECT_EQ(moved[0], 0);
  // Within alpha D0 nothing moves.
  Vector relaxed = 1.04 * mesh.rest;
  const Vector copy = relaxed;
  EXPECT_EQ(physics::limit_stretch(model.edges(), w, {}, relaxed, moved).projections, 0);
  EXPECT_EQ(relaxed, copy);
}

// A free body (no gravity, no floor) keeps its momentum under every explicit scheme and either
// damping: the constraint forces and both dashpots are internal.
TEST(ConstraintParticles, AFreeBodyKeepsItsMomentum) {
  const physics::TetMesh mesh = physics::make_box_tets5(Vec3::Zero(), Vec3::Constant(0.04), {2, 2, 2});
  for (physics::ParticleDamping damping : {physics::ParticleDamping::relative, physics::ParticleDamping::constraint})
    for (physics::ExplicitScheme scheme : {physics::ExplicitScheme::explicit_euler, physics::ExplicitScheme::midpoint,
                                           physics::ExplicitScheme::runge_kutta4, physics::ExplicitScheme::verlet,
                                           physics::ExplicitScheme::velocity_verlet}) {
      physics::ConstraintParticleSettings settings;
      settings.distance_stiffness = settings.area_stiffness = settings.volume_stiffness = 1;  // omega dt ~ 0.05
      settings.damping = damping;
      settings.damping_coefficient = damping == physics::ParticleDamping::relative ? 0.05 : 1e-4;
      physics::ConstraintParticles model(mesh, settings);
      physics::State state{deformed(mesh.rest, 0.002, 9), deformed(Vector::Zero(mesh.rest.size()), 0.1, 10)};
      const Vector& m = model.lumped_masses();
      auto momentum = [&] {
        Vec3 p = Vec3::Zero();
        for (Eigen::Index i = 0; i < m.size(); ++i) p += m[i] * state.velocities.segment<3>(3 * i);
        return p;
      };
      const Vec3 start = momentum();
      physics::CpStepSettings step;
      step.scheme = scheme;
      step.dt = 5e-6;
      step.limiter.enabled = false;  // its velocity update (Alg. 3.2) mixes two velocities: below
      physics::VerletHistory history;
      const double kinetic_start = physics::kinetic_energy(m, state.velocities);
      for (int k = 0; k < 200; ++k)
        ASSERT_FALSE(physics::constraint_particles_step(model, state, {}, Vector::Zero(mesh.rest.size()), step, history).nonfinite);
      EXPECT_LT((momentum() - start).norm(), 1e-12 * m.sum()) << physics::explicit_scheme_name(scheme);
      // The dashpots dissipate (explicit Euler and RK2 add energy of their own: not checked).
      if (scheme == physics::ExplicitScheme::runge_kutta4 || scheme == physics::ExplicitScheme::velocity_verlet) {
        EXPECT_LT(physics::kinetic_energy(m, state.velocities) + model.elastic_energy(state.positions),
                  0.99 * (kinetic_start + model.elastic_energy(deformed(mesh.rest, 0.002, 9))))
            << physics::explicit_scheme_name(scheme);
      }
    }
}

TEST(ConstraintParticles, AnInvertedTetIsCountedAndTheVolumeConstraintTurnsItBack) {
  physics::TetMesh mesh;
  mesh.rest.resize(12);
  mesh.rest << 0, 0, 0, 0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.01;
  mesh.tets = {{0, 1, 2, 3}};
  physics::ConstraintParticleSettings settings;
  settings.distance_stiffness = 0;
  settings.area_stiffness = 0;
  settings.damping = physics::ParticleDamping::constraint;
  settings.damping_coefficient = 1e-7;
  physics::ConstraintParticles model(mesh, settings);
  physics::State state{mesh.rest, Vector::Zero(12)};
  state.positions[11] = -0.005;  // the apex pushed through the base
  EXPECT_EQ(model.inverted_tets(state.positions), 1);
  EXPECT_LT(model.volume(state.positions), 0);
  physics::CpStepSettings step;
  step.dt = 1e-6;
  step.limiter.enabled = false;
  physics::VerletHistory history;
  std::vector<std::uint8_t> fixed{1, 1, 1, 0};
  int inverted = 1;
  for (int k = 0; k < 2000 && inverted; ++k)
    inverted = physics::constraint_particles_step(model, state, fixed, Vector::Zero(12), step, history).inverted_tets;
  EXPECT_EQ(inverted, 0);
  EXPECT_GT(state.positions[11], 0);
}

TEST(ConstraintParticles, ADegenerateTetIsRefusedNamingIt) {
  physics::TetMesh mesh;
  mesh.rest.resize(15);
  mesh.rest << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 0;
  mesh.tets = {{0, 1, 2, 3}, {0, 1, 2, 4}};  // the second is flat
  try {
    physics::ConstraintParticles model(mesh, {});
    ADD_FAILURE() << "a flat tet was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("tet 1 has signed volume 0"), std::string::npos) << e.what();
  }
}

// Alg. 3.2's relaxation: a damped block held at its base under gravity settles where the
// constraint forces balance the weight (the residual on its free particles a small fraction of
// their weight) and stops once its energy no longer changes.
TEST(ConstraintParticles, RelaxationSettlesAHeldBlockUnderGravity) {
  const physics::TetMesh mesh = physics::make_box_tets5(Vec3::Zero(), Vec3(0.04, 0.02, 0.02), {4, 2, 2});
  physics::ConstraintParticleSettings settings;
  settings.distance_stiffness = settings.area_stiffness = settings.volume_stiffness = 0.05;
  settings.damping_coefficient = 0.02;  // N s/m on every edge
  physics::ConstraintParticles model(mesh, settings);
  std::vector<std::uint8_t> fixed = physics::nodes_in_box(mesh.rest, Vec3(-1, -1, -1), Vec3(1e-9, 1, 1));
  const Vector weight = physics::gravity_forces(model.lumped_masses(), Vec3(0, 0, -9.81));
  physics::State state{mesh.rest, Vector::Zero(mesh.rest.size())};
  physics::CpStepSettings step;
  step.dt = 1e-4;
  const physics::RelaxReport report = physics::relax(model, state, fixed, weight, step, {1e-12, 200000, 100});
  ASSERT_TRUE(report.converged) << report.steps << " steps";
  Vector residual = weight;
  model.add_elastic_forces(state.positions, residual);
  double worst = 0, sag = 0;
  for (Eigen::Index i = 0; i < model.node_count(); ++i)
    if (!fixed[i]) {
      worst = std::max(worst, residual.segment<3>(3 * i).norm() / weight.segment<3>(3 * i).norm());
      sag = std::min(sag, state.positions[3 * i + 2] - mesh.rest[3 * i + 2]);
    }
  EXPECT_LT(worst, 1e-3) << report.steps << " steps";  // 2.4e-6 measured, after 13,569 steps
  EXPECT_LT(sag, -1e-5);  // it did bend
}

namespace {

std::string scene_text(const std::string& block, const std::string& extra_body = "") {
  return R"({"name": "cp", "bodies": [{"name": "cube", "model": "constraint_particles",
    "generator": {"type": "box", "min": [0, 0, 0.01], "max": [0.04, 0.04, 0.05]}, "resolution": 0.01,
    "material": {"E": 1e4, "nu": 0.3, "rho": 1000}, "constraint_particles": )" +
         block + extra_body + R"(}], "solver": {"dt": 2e-5, "duration": 0.001}})";
}

std::string refusal(const std::string& block) {
  try {
    engine::parse_scene(scene_text(block), "cp.json");
  } catch (const engine::SceneError& e) {
    std::string all;
    for (const auto& line : e.errors()) all += line + "\n";
    return all;
  }
  return "accepted";
}

}  // namespace

TEST(ConstraintParticles, BadSettingsAreRefusedNamingTheField) {
  EXPECT_NE(refusal(R"({"stretch_stiffness": 2})").find("bodies[0].constraint_particles.stretch_stiffness: 2 must be in [0, 1]"),
            std::string::npos) << refusal(R"({"stretch_stiffness": 2})");
  EXPECT_NE(refusal(R"({"integrator": "leapfrog"})").find("bodies[0].constraint_particles.integrator: 'leapfrog' is not one of"),
            std::string::npos);
  EXPECT_NE(refusal(R"({"distance_stiffness": -1})").find("bodies[0].constraint_particles.distance_stiffness: -1 must be in"),
            std::string::npos);
  EXPECT_NE(refusal(R"({"distance_stiffness": 0, "area_stiffness": 0, "volume_stiffness": 0})")
                .find("bodies[0].constraint_particles.distance_stiffness: at least one of"),
            std::string::npos);
  EXPECT_NE(refusal(R"({"damping": "oil"})").find("bodies[0].constraint_particles.damping: 'oil' is not one of"), std::string::npos);
  EXPECT_NE(refusal(R"({"stiffness": 3})").find("bodies[0].constraint_particles.stiffness"), std::string::npos);
  EXPECT_NE(refusal(R"({"integrator": "implicit_euler", "floor_z": 0})").find("bodies[0].constraint_particles.floor_z"),
            std::string::npos);
  EXPECT_EQ(refusal(R"({"damping": "constraint", "damping_coefficient": 0.001, "floor_z": 0})"), "accepted");
  EXPECT_NE(refusal(R"({"stiffness_per": "edge"})").find("bodies[0].constraint_particles.stiffness_per: 'edge' is not one of"),
            std::string::npos);
  EXPECT_EQ(refusal(R"({"stiffness_per": "volume", "distance_stiffness": 1e4})"), "accepted");
}

// per_volume on one cube of side h split into 5 tets (the central one h^3 / 3, four corner ones
// h^3 / 6): an axis edge is in one corner tet (k_D h^3 / 6), a face diagonal in the central tet
// and two corner tets (k_D 2 h^3 / 3); each volume constraint has k_V times its tet's volume, each
// skin triangle (half a face) k_A h^2 / 2.
TEST(ConstraintParticles, StiffnessPerVolumeSumsTheTetsRoundEachEdge) {
  const double h = 0.02, h3 = h * h * h;
  const physics::TetMesh cube = physics::make_box_tets5(Vec3::Zero(), Vec3::Constant(h), {1, 1, 1});
  physics::ConstraintParticleSettings settings;
  settings.distance_stiffness = 3e4;
  settings.volume_stiffness = 5e4;
  settings.area_stiffness = 7;
  settings.scaling = physics::StiffnessScaling::per_volume;
  const physics::ConstraintParticles model(cube, settings);
  int axis = 0, diagonal = 0, central = 0, corner = 0, triangles = 0;
  for (const Constraint& c : model.constraints()) {
    if (c.kind == ConstraintKind::distance) {
      const bool is_axis = std::abs(c.rest - h) < 1e-12;
      EXPECT_NEAR(c.stiffness, settings.distance_stiffness * h3 * (is_axis ? 1.0 / 6 : 2.0 / 3), 1e-12);
      ++(is_axis ? axis : diagonal);
    } else if (c.kind == ConstraintKind::volume) {
      const bool is_central = std::abs(c.rest - h3 / 3) < 1e-15;
      EXPECT_NEAR(c.stiffness, settings.volume_stiffness * h3 * (is_central ? 1.0 / 3 : 1.0 / 6), 1e-12);
      ++(is_central ? central : corner);
    } else {
      EXPECT_NEAR(c.stiffness, settings.area_stiffness * h * h / 2, 1e-15);
      ++triangles;
    }
  }
  EXPECT_EQ(axis, 12);
  EXPECT_EQ(diagonal, 6);
  EXPECT_EQ(central, 1);
  EXPECT_EQ(corner, 4);
  EXPECT_EQ(triangles, 12);
}

// Through the world: the 5-tet split of the box, the explicit step (own_step), a free fall at g.
TEST(ConstraintParticles, TheWorldBuildsAndStepsAFallingBody) {
  const engine::Scene scene = engine::parse_scene(scene_text(R"({"distance_stiffness": 1, "area_stiffness": 1, "volume_stiffness": 1, "damping_coefficient": 0.001})"), "cp.json");
  engine::World world(scene, std::nullopt);
  const auto& body = world.bodies()[0];
  EXPECT_EQ(body.model->elements, 5u * 4u * 4u * 4u);
  EXPECT_TRUE(static_cast<bool>(body.model->own_step));
  for (int k = 0; k < 50; ++k) world.step();
  const Vector& m = body.data.mechanics->lumped_masses();
  double momentum = 0;
  for (Eigen::Index i = 0; i < m.size(); ++i) momentum += m[i] * body.data.state.velocities[3 * i + 2];
  EXPECT_NEAR(momentum / m.sum(), -9.81 * 50 * 2e-5, 1e-9);

  // "implicit_euler": the shared step with the Gauss-Newton stiffness; held at its base it sags.
  std::string text = scene_text(R"({"integrator": "implicit_euler", "stretch_stiffness": 0})",
                                R"(, "fixed": [{"min": [-1, -1, -1], "max": [1, 1, 0.0101]}])");
  engine::World held(engine::parse_scene(text, "cp.json"), std::nullopt);
  EXPECT_FALSE(static_cast<bool>(held.bodies()[0].model->own_step));
  for (int k = 0; k < 20; ++k) EXPECT_TRUE(held.step().cg_converged);
  const auto& sagging = held.bodies()[0].data;
  const Vector shift = sagging.state.positions - sagging.mechanics->rest_positions();
  EXPECT_TRUE(shift.allFinite());
  EXPECT_LT(shift.segment<3>(shift.size() - 3)[2], 0);  // the top corner moved down
  EXPECT_EQ(shift.head<3>().norm(), 0);                 // a base particle is held
}

// Digest D3 (§4.2, Fig. 4.5-4.9): the thesis's cube (9^3 particles, 2,560 tets, k = 500) dropped
// on a plane. With every constraint and the stretch limiter the volume is back within 1 % of
// its rest value by frame 400 and stays there; with distances only the cube caves in at impact
// (the volume dips below 0.9 and tets invert). Parameters: physics/cp/cube_drop.hpp.
TEST(ConstraintParticles, TheFallingCubeGetsItsVolumeBackWithEveryConstraint) {
  physics::CubeDrop drop;
  const physics::CubeDropResult all = physics::run_cube_drop(drop);
  ASSERT_TRUE(all.finite);
  ASSERT_EQ(all.volume_ratio.size(), 401u);
  double worst_late = 0, lowest = 1;
  for (std::size_t f = 0; f < all.volume_ratio.size(); ++f) {
    lowest = std::min(lowest, all.volume_ratio[f]);
    if (f >= 380) worst_late = std::max(worst_late, std::abs(all.volume_ratio[f] - 1));
    EXPECT_EQ(all.inverted[f], 0) << "frame " << f;
  }
  EXPECT_LT(lowest, 0.995);  // it did hit the floor
  EXPECT_LT(worst_late, 0.01);
  drop.area = drop.volume = drop.limiter = false;
  drop.frames = 80;
  const physics::CubeDropResult distance = physics::run_cube_drop(drop);
  ASSERT_TRUE(distance.finite);
  EXPECT_LT(*std::min_element(distance.volume_ratio.begin(), distance.volume_ratio.end()), 0.9);
  EXPECT_GT(*std::max_element(distance.inverted.begin(), distance.inverted.end()), 0);
}

// solver.start "settled": the body is relaxed (Alg. 3.2, physics::relax) before the run, so it
// starts at rest: at its start positions gravity and the constraints' forces balance on every
// free particle, and the first steps barely move it.
TEST(ConstraintParticles, ASettledStartIsRelaxedToRest) {
  const std::string held = R"(, "fixed": [{"min": [-1, -1, -1], "max": [1, 1, 0.0101]}])";
  std::string text = scene_text(R"({"distance_stiffness": 1, "area_stiffness": 1, "volume_stiffness": 1,
    "relax": {"tolerance": 1e-15, "mass_damping": 300}})", held);
  text.replace(text.find(R"("duration")"), 0, R"("start": "settled", )");
  engine::World world(engine::parse_scene(text, "cp.json"), std::nullopt);
  const auto& body = world.bodies()[0].data;
  const Vector& rest = body.mechanics->rest_positions();
  const Vector start = body.state.positions;
  Vector residual = body.gravity;
  body.mechanics->add_elastic_forces(start, residual);
  double worst = 0, sag = 0;
  for (Eigen::Index i = 0; i < body.mechanics->node_count(); ++i)
    if (!body.fixed[static_cast<std::size_t>(i)]) {
      worst = std::max(worst, residual.segment<3>(3 * i).norm() / body.gravity.segment<3>(3 * i).norm());
      sag = std::min(sag, start[3 * i + 2] - rest[3 * i + 2]);
    }
  EXPECT_LT(worst, 1e-3);  // of each particle's weight (3.7e-8 measured)
  EXPECT_LT(sag, -1e-6);   // it did sag (3.2 um at its free top corner) before the run
  EXPECT_EQ(body.state.velocities.norm(), 0);
  for (int k = 0; k < 50; ++k) world.step();
  EXPECT_LT((world.bodies()[0].data.state.positions - start).cwiseAbs().maxCoeff(), 1e-2 * -sag);
}

TEST(ConstraintParticles, BadRelaxationSettingsAreRefusedNamingTheKey) {
  EXPECT_NE(refusal(R"({"relax": {"tolerance": 0}})").find("bodies[0].constraint_particles.relax.tolerance: 0 must be in (0"),
            std::string::npos) << refusal(R"({"relax": {"tolerance": 0}})");
  EXPECT_NE(refusal(R"({"relax": {"max_steps": 0}})").find("bodies[0].constraint_particles.relax.max_steps: 0 must be in [1"),
            std::string::npos);
  EXPECT_NE(refusal(R"({"relax": {"calm_steps": 1.5}})").find("bodies[0].constraint_particles.relax.calm_steps: must be an integer"),
            std::string::npos);
  EXPECT_NE(refusal(R"({"relax": {"mass_damping": -1}})").find("bodies[0].constraint_particles.relax.mass_damping: -1 must be in"),
            std::string::npos);
  EXPECT_NE(refusal(R"({"relax": {"steps": 3}})").find("bodies[0].constraint_particles.relax.steps: unknown key"), std::string::npos);
  EXPECT_NE(refusal(R"({"relax": 3})").find("bodies[0].constraint_particles.relax: must be an object"), std::string::npos);
  // A relaxation that cannot settle in its steps (no damping at all) is refused, naming the key.
  std::string text = scene_text(R"({"distance_stiffness": 1, "area_stiffness": 1, "volume_stiffness": 1, "relax": {"max_steps": 50}})",
                                R"(, "fixed": [{"min": [-1, -1, -1], "max": [1, 1, 0.0101]}])");
  text.replace(text.find(R"("duration")"), 0, R"("start": "settled", )");
  try {
    engine::World world(engine::parse_scene(text, "cp.json"), std::nullopt);
    ADD_FAILURE() << "an unsettled relaxation was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("constraint_particles.relax: not settled after max_steps = 50"), std::string::npos) << e.what();
  }
}

// The explicit bound min_i 2 sqrt(m_i / k_i) on one right-angled tet with distance constraints
// only: the corner at the origin has its three unit edges, k_0 = 3 k, the others 2 k (one unit
// edge, two of length sqrt 2 at k / 2 each); every particle has rho V / 4 = rho / 24. A step
// beyond it is refused by explicit_step.
TEST(ConstraintParticles, TheExplicitBoundIsTheStiffestParticles) {
  physics::TetMesh mesh;
  mesh.rest.resize(12);
  mesh.rest << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  mesh.tets = {{0, 1, 2, 3}};
  physics::ConstraintParticleSettings settings;
  settings.density = 24;  // m = 1 per particle
  settings.distance_stiffness = 3;
  settings.area_stiffness = settings.volume_stiffness = 0;
  physics::ConstraintParticles model(mesh, settings);
  EXPECT_NEAR(model.explicit_step_limit(), 2 * std::sqrt(1.0 / 9.0), 1e-12);
  physics::State state{mesh.rest, Vector::Zero(12)};
  physics::ExplicitSettings step;
  step.dt = 1.01 * model.explicit_step_limit();
  EXPECT_THROW(physics::explicit_step(physics::ExplicitScheme::velocity_verlet, model, state, {}, Vector::Zero(12), step),
               std::invalid_argument);
  step.dt = 0.99 * model.explicit_step_limit();
  EXPECT_NO_THROW(physics::explicit_step(physics::ExplicitScheme::velocity_verlet, model, state, {}, Vector::Zero(12), step));
}
