// The EFG balls and the helpers the solver's tests share: the small ball at rest (the rest
// preconditioner's, coarse space's and multigrid's tests), the bent, turned one of the assembled
// current system (test_current_system.cpp: K(x) and its products; test_current_vcycle.cpp: the
// V-cycle on it).
#pragma once

#include "physics/core/implicit_euler.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/solve/coarse_space.hpp"
#include "physics/solve/rest_factor.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <random>
#include <string>
#include <vector>

namespace incise::physics::fixtures {

inline const Material tissue{5e3, 0.45, 1060};

// An EFG ball of the given node spacing, nothing fixed, at rest: partial cubes, re-selected
// neighbourhoods and varied rows, not only full cells (the rest preconditioner's, coarse
// space's and multigrid's tests, and BentBall's before it bends it).
inline std::unique_ptr<CorotationalEfg> small_efg(double spacing = 0.005) {
  EfgSettings settings;
  settings.spacing = spacing;
  return std::make_unique<CorotationalEfg>([](const Vec3& p) { return p.norm() < 0.021; }, Vec3::Constant(-0.025),
                                           Vec3::Constant(0.025), tissue, settings);
}

inline Vector random_vector(Eigen::Index size, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> uniform(-1, 1);
  Vector v(size);
  for (Eigen::Index i = 0; i < size; ++i) v[i] = uniform(random);
  return v;
}

// A random vector zero on the fixed nodes, as CG's vectors are.
inline Vector free_random(const std::vector<std::uint8_t>& fixed, unsigned seed) {
  Vector v = random_vector(3 * static_cast<Eigen::Index>(fixed.size()), seed);
  for (std::size_t i = 0; i < fixed.size(); ++i)
    if (fixed[i]) v.segment<3>(3 * static_cast<Eigen::Index>(i)).setZero();
  return v;
}

// What CG asks of a preconditioner M, on five pairs of such vectors: x . M y = y . M x within
// `tolerance` of |x| |M y|, and x . M x > 0.
template <class Preconditioner>
void expect_symmetric_positive(Preconditioner& m, const std::vector<std::uint8_t>& fixed, double tolerance,
                               const std::string& what = "") {
  for (unsigned seed = 1; seed <= 5; ++seed) {
    const Vector x = free_random(fixed, seed), y = free_random(fixed, 100 + seed);
    Vector mx(x.size()), my(y.size());
    m(x, mx);
    m(y, my);
    EXPECT_LE(std::abs(x.dot(my) - y.dot(mx)), tolerance * x.norm() * my.norm()) << what << " seed " << seed;
    EXPECT_GT(x.dot(mx), 0.0) << what << " seed " << seed;
  }
}

inline bool same_bits(const Vector& a, const Vector& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())) == 0;
}

// An EFG ball, its bottom fixed, bent about y (the rotation varies across it, up to 0.6 rad),
// stretched and turned as a whole: every element has its own rotation.
struct BentBall {
  std::unique_ptr<CorotationalEfg> model;
  Vector x;
  std::vector<std::uint8_t> fixed;
  explicit BentBall(double spacing = 0.0025) {
    model = small_efg(spacing);
    const Vector& rest = model->rest_positions();
    const Eigen::Quaterniond turn(Eigen::AngleAxisd(0.5, Vec3(1, 2, 3).normalized()));
    x.resize(rest.size());
    for (Eigen::Index i = 0; i < rest.size() / 3; ++i) {
      const Vec3 p = rest.segment<3>(3 * i).cwiseProduct(Vec3(1.08, 1.0, 0.96));
      const Eigen::AngleAxisd bend(15.0 * p.x(), Vec3::UnitY());
      x.segment<3>(3 * i) = turn * (bend * p);
    }
    fixed.assign(static_cast<size_t>(model->node_count()), 0);
    for (int i = 0; i < model->node_count(); ++i) fixed[static_cast<size_t>(i)] = rest[3 * i + 2] < -0.015;
  }
};

// The step's settings on the engine's path: the assembled system, the current V-cycle.
inline ImplicitEulerSettings current_cycle_settings(double tolerance) {
  ImplicitEulerSettings settings;
  settings.dt = 0.01;
  settings.cg.tolerance = tolerance;
  settings.cg.max_iterations = 300;
  settings.assembled_system = true;
  return settings;
}

// The ball's coarse factor for a degree-4 cycle, built at rest (`node_blocks`: with the top of
// B0^-1 A0 for the node blocks' scaling).
inline std::unique_ptr<RestFactor> ball_factor(BentBall& ball, double dt, bool node_blocks = false) {
  CorotationalEfg& model = *ball.model;
  const CoarseSpace space = make_coarse_space(model.rest_positions(), 2 * model.node_spacing(), ball.fixed);
  model.update_rotations(model.rest_positions());
  return std::make_unique<RestFactor>(model.rest_stiffness_job()(), model.lumped_masses(), ball.fixed, 1.0, dt * dt,
                                      default_factor_backend(), &space, 4, false, node_blocks);
}

// A few steps' summed CG iterations and the positions they reach.
struct BallRun {
  int iterations = 0;
  Vector positions;
};

}  // namespace incise::physics::fixtures
