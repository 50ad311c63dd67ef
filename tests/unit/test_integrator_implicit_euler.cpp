#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "physics/core/implicit_euler.hpp"
#include "physics/fem/corotational_fem.hpp"
#include "physics/fem/tet_mesh.hpp"

namespace incise::physics {
namespace {

// Point masses with no elasticity: the springs alone drive them.
class PointMasses final : public DeformableModel {
 public:
  explicit PointMasses(Vector masses)
      : masses_(std::move(masses)), rest_(Vector::Zero(3 * masses_.size())) {}
  int node_count() const override { return static_cast<int>(masses_.size()); }
  const Vector& rest_positions() const override { return rest_; }
  const Vector& lumped_masses() const override { return masses_; }
  void update_rotations(const Vector&) override {}
  void add_elastic_forces(const Vector&, Vector&) const override {}
  void add_stiffness_product(const Vector&, Vector&) const override {}
  void add_stiffness_diagonal(Vector&) const override {}
  double elastic_energy(const Vector&) const override { return 0; }

  std::unique_ptr<DeformableModel> clone() const override { return std::make_unique<PointMasses>(*this); }
 private:
  Vector masses_;
  Vector rest_;
};

const Material soft{50e3, 0.3, 1000};

// A 2x2x2-cell cube of side 0.1 m with a deterministic non-affine deformation.
TetMesh small_cube() { return make_box_tets(Vec3::Zero(), Vec3::Constant(0.1), {2, 2, 2}); }

State deformed_state(const Vector& rest, const Vec3& uniform_velocity) {
  State state;
  state.positions = rest;
  state.velocities = Vector::Zero(rest.size());
  for (Eigen::Index node = 0; node < rest.size() / 3; ++node) {
    const Vec3 x = rest.segment<3>(3 * node);
    state.positions.segment<3>(3 * node) +=
        0.01 * Vec3(std::sin(40 * x.y()), std::cos(30 * x.z()) * x.x() * 10,
                    0.5 * std::sin(20 * x.x() + 10 * x.y()));
    state.velocities.segment<3>(3 * node) =
        uniform_velocity +
        0.2 * Vec3(std::cos(25 * x.z()), std::sin(35 * x.x()), std::cos(15 * x.y()));
  }
  return state;
}

Vec3 momentum(const Vector& masses, const Vector& velocities) {
  Vec3 total = Vec3::Zero();
  for (Eigen::Index node = 0; node < masses.size(); ++node)
    total += masses[node] * velocities.segment<3>(3 * node);
  return total;
}

ImplicitEulerSettings tight_settings(double dt) {
  ImplicitEulerSettings settings;
  settings.dt = dt;
  settings.cg.tolerance = 1e-12;
  settings.cg.max_iterations = 2000;
  return settings;
}

TEST(ImplicitEuler, SpringMassMatchesBackwardEulerAmplitudeDecay) {
  // Backward Euler on x'' = -w^2 x maps (w x, v) by a rotation scaled by 1 / sqrt(1 + (w dt)^2):
  // [1, -h; h, 1] (w x, v)_{n+1} = (w x, v)_n with h = w dt.
  const double mass = 0.2, stiffness = 80.0, dt = 0.01;
  const double omega = std::sqrt(stiffness / mass);
  PointMasses model(Vector::Constant(1, mass));
  State state{Vector::Zero(3), Vector::Zero(3)};
  const Vec3 anchor(0.3, -0.1, 0.2);
  state.positions = anchor + Vec3(0.05, 0.02, -0.03);
  state.velocities = Vec3(0.0, 0.4, 0.1);
  const auto amplitude = [&](const State& s) {
    return std::sqrt(omega * omega * (s.positions - anchor).squaredNorm() +
                     s.velocities.squaredNorm());
  };
  const double initial = amplitude(state);
  const int steps = 50;
  for (int step = 0; step < steps; ++step) {
    const NodalSpring spring{0, -stiffness * (Vec3(state.positions) - anchor),
                             stiffness * Mat3::Identity()};
    const StepReport report =
        implicit_euler_step(model, state, {}, Vector::Zero(3), {&spring, 1}, tight_settings(dt));
    ASSERT_FALSE(report.nonfinite);
    ASSERT_TRUE(report.cg.converged);
  }
  const double expected = initial * std::pow(1.0 + omega * omega * dt * dt, -0.5 * steps);
  EXPECT_NEAR(amplitude(state) / expected, 1.0, 1e-9);
  EXPECT_LT(amplitude(state), 0.5 * initial);  // the decay is substantial, so the check bites
}

TEST(ImplicitEuler, FreeBodyKeepsMomentum) {
  CorotationalTetFem model(small_cube(), soft);
  State state = deformed_state(model.rest_positions(), Vec3(0.3, -0.2, 0.1));
  const Vec3 initial = momentum(model.lumped_masses(), state.velocities);
  const Vector no_forces = Vector::Zero(state.positions.size());
  for (int step = 0; step < 30; ++step) {
    const StepReport report =
        implicit_euler_step(model, state, {}, no_forces, {}, tight_settings(1e-3));
    ASSERT_FALSE(report.nonfinite);
  }
  const Vec3 final_momentum = momentum(model.lumped_masses(), state.velocities);
  const double total_mass = model.lumped_masses().sum();
  // The elastic forces of each element sum to zero and K has the translations in its kernel,
  // so momentum changes only by the CG residual.
  EXPECT_LE((final_momentum - initial).norm() / total_mass, 1e-9);
  // The body did deform: the velocities are no longer the initial ones.
  EXPECT_GT(
      (state.velocities - deformed_state(model.rest_positions(), Vec3(0.3, -0.2, 0.1)).velocities)
          .norm(),
      1e-3);
}

TEST(ImplicitEuler, FreeFallFollowsGravityExactly) {
  CorotationalTetFem model(small_cube(), soft);
  State state{model.rest_positions(), Vector::Zero(model.rest_positions().size())};
  const Vec3 g(0, 0, -9.81);
  const Vector gravity = gravity_forces(model.lumped_masses(), g);
  const double dt = 1e-3;
  const int steps = 10;
  for (int step = 0; step < steps; ++step) {
    ASSERT_FALSE(implicit_euler_step(model, state, {}, gravity, {}, tight_settings(dt)).nonfinite);
  }
  // Backward Euler: v_n = n dt g, x_n = X + dt^2 g n (n + 1) / 2, uniformly (no strain arises).
  for (Eigen::Index node = 0; node < model.node_count(); ++node) {
    EXPECT_LE((state.velocities.segment<3>(3 * node) - steps * dt * g).norm(), 1e-12);
    const Vec3 expected =
        model.rest_positions().segment<3>(3 * node) + dt * dt * g * steps * (steps + 1) / 2.0;
    EXPECT_LE((state.positions.segment<3>(3 * node) - expected).norm(), 1e-12);
  }
}

TEST(ImplicitEuler, DampingDissipatesEnergy) {
  const auto run = [](double mass_damping, double stiffness_damping) {
    CorotationalTetFem model(small_cube(), soft);
    State state = deformed_state(model.rest_positions(), Vec3::Zero());
    ImplicitEulerSettings settings = tight_settings(2e-3);
    settings.rayleigh_mass = mass_damping;
    settings.rayleigh_stiffness = stiffness_damping;
    const Vector no_forces = Vector::Zero(state.positions.size());
    std::vector<double> energies{model.elastic_energy(state.positions) +
                                 kinetic_energy(model.lumped_masses(), state.velocities)};
    for (int step = 0; step < 100; ++step) {
      const StepReport report = implicit_euler_step(model, state, {}, no_forces, {}, settings);
      EXPECT_FALSE(report.nonfinite);
      energies.push_back(report.elastic_energy + report.kinetic_energy);
    }
    return energies;
  };
  const std::vector<double> undamped = run(0, 0);
  const std::vector<double> damped = run(20, 0.005);
  EXPECT_LE(undamped.back(), undamped.front());  // backward Euler's own dissipation
  EXPECT_LT(damped.back(), 0.1 * undamped.back());
  EXPECT_LT(damped.back(), 0.01 * damped.front());
  for (size_t step = 1; step < damped.size(); ++step) {
    EXPECT_LE(damped[step], damped[step - 1] * (1 + 1e-9)) << "step " << step;
  }
}

TEST(ImplicitEuler, FixedNodesStayPutWithZeroVelocity) {
  CorotationalTetFem model(small_cube(), soft);
  State state = deformed_state(model.rest_positions(), Vec3(0.1, 0, 0));
  const std::vector<uint8_t> fixed =
      nodes_in_box(model.rest_positions(), Vec3::Constant(-1), Vec3(1e-9, 1, 1));
  const Vector start = state.positions;
  const Vector gravity = gravity_forces(model.lumped_masses(), Vec3(0, 0, -9.81));
  for (int step = 0; step < 5; ++step) {
    ASSERT_FALSE(
        implicit_euler_step(model, state, fixed, gravity, {}, tight_settings(1e-3)).nonfinite);
  }
  int fixed_count = 0;
  for (int node = 0; node < model.node_count(); ++node) {
    if (!fixed[node]) continue;
    ++fixed_count;
    EXPECT_EQ(Vec3(state.positions.segment<3>(3 * node)), Vec3(start.segment<3>(3 * node)));
    EXPECT_EQ(Vec3(state.velocities.segment<3>(3 * node)), Vec3::Zero());
  }
  EXPECT_EQ(fixed_count, 9);
}

TEST(ImplicitEuler, NonFiniteInputLeavesStateUnchanged) {
  CorotationalTetFem model(small_cube(), soft);
  State state = deformed_state(model.rest_positions(), Vec3::Zero());
  const State before = state;
  Vector forces = Vector::Zero(state.positions.size());
  forces[7] = std::numeric_limits<double>::quiet_NaN();
  const StepReport report = implicit_euler_step(model, state, {}, forces, {}, tight_settings(1e-3));
  EXPECT_TRUE(report.nonfinite);
  EXPECT_EQ(state.positions, before.positions);
  EXPECT_EQ(state.velocities, before.velocities);

  NodalSpring spring{3, Vec3::Zero(), Mat3::Identity() * std::numeric_limits<double>::infinity()};
  const StepReport spring_report = implicit_euler_step(
      model, state, {}, Vector::Zero(forces.size()), {&spring, 1}, tight_settings(1e-3));
  EXPECT_TRUE(spring_report.nonfinite);
  EXPECT_EQ(state.positions, before.positions);
  EXPECT_EQ(state.velocities, before.velocities);
}

TEST(ImplicitEuler, SpringIsImplicitAndStableForStiffPenalty) {
  // A penalty far stiffer than dt allows explicitly (w dt = 100) must not blow up.
  const double mass = 1e-3, stiffness = 1e4, dt = 0.03;
  PointMasses model(Vector::Constant(1, mass));
  State state{Vec3(0, 0, -0.01), Vector::Zero(3)};
  for (int step = 0; step < 20; ++step) {
    const NodalSpring spring{0, -stiffness * Vec3(state.positions), stiffness * Mat3::Identity()};
    ASSERT_FALSE(
        implicit_euler_step(model, state, {}, Vector::Zero(3), {&spring, 1}, tight_settings(dt))
            .nonfinite);
  }
  EXPECT_LT(state.positions.norm(), 1e-6);
}

TEST(ImplicitEuler, IsBitwiseDeterministic) {
  const auto run = [] {
    CorotationalTetFem model(small_cube(), soft);
    State state = deformed_state(model.rest_positions(), Vec3(0.1, 0.2, 0.3));
    ImplicitEulerSettings settings;
    settings.dt = 1e-3;
    settings.rayleigh_mass = 1;
    settings.rayleigh_stiffness = 1e-3;
    const Vector gravity = gravity_forces(model.lumped_masses(), Vec3(0, 0, -9.81));
    for (int step = 0; step < 10; ++step)
      implicit_euler_step(model, state, {}, gravity, {}, settings);
    return state;
  };
  const State first = run(), second = run();
  EXPECT_EQ(first.positions, second.positions);
  EXPECT_EQ(first.velocities, second.velocities);
}

TEST(ImplicitEuler, RejectsMismatchedSizes) {
  CorotationalTetFem model(small_cube(), soft);
  State state{model.rest_positions(), Vector::Zero(model.rest_positions().size())};
  EXPECT_THROW(implicit_euler_step(model, state, {}, Vector::Zero(3), {}, {}),
               std::invalid_argument);
  NodalSpring spring{model.node_count(), Vec3::Zero(), Mat3::Zero()};
  EXPECT_THROW(
      implicit_euler_step(model, state, {}, Vector::Zero(state.positions.size()), {&spring, 1}, {}),
      std::invalid_argument);
}

}  // namespace
}  // namespace incise::physics
