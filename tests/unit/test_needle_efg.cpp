// The needle's glue to the EFG body (physics/needle/needle_efg.hpp), checked against independent
// figures on a small box: the integration points at rest are their element centres (linear MLS
// reproduces them), a rigid translation of the particles moves every point by it, the boundary
// points are exactly the box's outer layer of cubes, a force on a point reaches the particles
// with its sum and its moment kept (virtual work: the same shape functions), and a needle pushed
// through the top face of the body takes the puncture's k_c from a boundary point.
#include "physics/needle/needle.hpp"
#include "physics/needle/needle_efg.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace physics = incise::physics;
using physics::Vec3;

namespace {

// A 20 x 20 x 20 mm box at a = 5 mm: 4 x 4 x 4 full cubes, particles 10 mm apart (27).
physics::CorotationalEfg box() {
  physics::Material material;
  material.youngs_modulus = 2e4;
  material.poisson_ratio = 0.3;
  material.density = 1000;
  physics::EfgSettings settings;
  settings.spacing = 0.005;
  return physics::CorotationalEfg(Vec3(-0.01, -0.01, 0), Vec3(0.01, 0.01, 0.02), material, settings);
}

}  // namespace

TEST(NeedleEfg, PointsFollowTheParticlesByTheirShapeFunctions) {
  const physics::CorotationalEfg efg = box();
  ASSERT_EQ(efg.element_count(), 64);
  physics::Vector points;
  physics::efg_point_positions(efg, efg.rest_positions(), points);
  for (int e = 0; e < efg.element_count(); ++e)
    EXPECT_LT((points.segment<3>(3 * e) - efg.element_centres()[e]).norm(), 1e-12) << "element " << e;
  physics::Vector moved = efg.rest_positions();
  const Vec3 shift(0.003, -0.002, 0.001);
  for (int n = 0; n < efg.node_count(); ++n) moved.segment<3>(3 * n) += shift;
  physics::efg_point_positions(efg, moved, points);
  for (int e = 0; e < efg.element_count(); ++e)
    EXPECT_LT((points.segment<3>(3 * e) - efg.element_centres()[e] - shift).norm(), 1e-12) << "element " << e;
}

TEST(NeedleEfg, TheBoundaryPointsAreTheOuterLayerOfCubes) {
  const physics::CorotationalEfg efg = box();
  const auto boundary = physics::efg_boundary_points(efg);
  int count = 0;
  for (int e = 0; e < efg.element_count(); ++e) {
    const Vec3 c = efg.element_centres()[e];
    const bool outer = std::abs(c.x()) > 0.005 || std::abs(c.y()) > 0.005 || c.z() < 0.005 || c.z() > 0.015;
    EXPECT_EQ(boundary[e] != 0, outer) << "element " << e << " at " << c.transpose();
    count += boundary[e];
  }
  EXPECT_EQ(count, 64 - 8);  // all but the 2 x 2 x 2 inner cubes
}

TEST(NeedleEfg, APointForceReachesTheParticlesWithItsSumAndMoment) {
  const physics::CorotationalEfg efg = box();
  std::vector<std::uint8_t> fixed(efg.node_count(), 0);
  const Vec3 f(0.1, -0.2, 0.3), g(0, 0, -0.05);
  const int e = 21, k = 42;
  const auto springs = physics::efg_point_forces_on_particles(efg, {{e, f}, {k, g}}, fixed);
  Vec3 sum = Vec3::Zero(), moment = Vec3::Zero();
  int previous = -1;
  for (const auto& s : springs) {
    EXPECT_GT(s.node, previous);  // one spring per particle, increasing
    previous = s.node;
    EXPECT_EQ(s.stiffness, physics::Mat3::Zero());
    sum += s.force;
    moment += Vec3(efg.rest_positions().segment<3>(3 * s.node)).cross(s.force);
  }
  EXPECT_LT((sum - f - g).norm(), 1e-14);
  const Vec3 expected = efg.element_centres()[e].cross(f) + efg.element_centres()[k].cross(g);
  EXPECT_LT((moment - expected).norm(), 1e-15);
  // Fixed particles take none: the rest is what reaches the free ones.
  fixed.assign(efg.node_count(), 1);
  EXPECT_TRUE(physics::efg_point_forces_on_particles(efg, {{e, f}}, fixed).empty());
}

TEST(NeedleEfg, TheNeedlePuncturesAtABoundaryPoint) {
  const physics::CorotationalEfg efg = box();
  physics::NeedleSettings settings;
  settings.nodes = 5;
  settings.length = 0.02;
  settings.cutting_radius = 0.004;
  settings.friction_radius = 0.004;
  physics::Needle needle(settings, physics::make_efg_needle_tissue(efg, settings));
  physics::Vector points;
  physics::efg_point_positions(efg, efg.rest_positions(), points);
  physics::NeedlePose pose;
  pose.tip = Vec3(0.0026, 0.0024, 0.021);  // 1 mm above the top face, above the top cubes' centres
  pose.nodes = settings.nodes;
  pose.spacing = 0.005;
  const physics::NeedleForces f = needle.step(pose, 0.01, points);
  ASSERT_FALSE(needle.zones().cutting.empty());
  EXPECT_TRUE(f.puncturing);
  EXPECT_NEAR(f.cutting, settings.puncture_force, 1e-12);  // only boundary points ahead
  EXPECT_LT((f.on_needle + Vec3(0, 0, -settings.puncture_force)).norm(), 1e-12);  // pushed back up
}
