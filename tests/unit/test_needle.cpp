// The needle's physics (physics/needle/, seed 002 §2.3) on a lattice of tissue nodes held still,
// so each figure is checked against a hand computation: the inverse-distance shares and the
// cutting force C, none on retraction, the puncture's larger k_c on the boundary, forces on the
// tissue and the needle equal and opposite, the zones kept through neighbours equal to a full
// scan, and stick / slip of a node's virtual particle with its transitions counted.
#include "physics/needle/needle.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace physics = incise::physics;
using physics::Vec3;

namespace {

constexpr double h = 0.005;

// 5 x 5 x 5 nodes h apart over [-2h, 2h]^2 x [0, 4h]; the outer ones are the boundary.
physics::Vector lattice() {
  physics::Vector x(3 * 125);
  int n = 0;
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 5; ++j)
      for (int i = 0; i < 5; ++i, ++n) x.segment<3>(3 * n) = Vec3((i - 2) * h, (j - 2) * h, k * h);
  return x;
}

int node(int i, int j, int k) { return i + 5 * j + 25 * k; }

std::vector<std::array<int, 3>> boundary_triangles() {
  // One degenerate "triangle" per boundary node is enough for make_needle_tissue's flags.
  std::vector<std::array<int, 3>> t;
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 5; ++j)
      for (int i = 0; i < 5; ++i)
        if (i == 0 || i == 4 || j == 0 || j == 4 || k == 0 || k == 4) t.push_back({node(i, j, k), node(i, j, k), node(i, j, k)});
  return t;
}

physics::NeedleSettings settings() {
  physics::NeedleSettings s;
  s.length = 0.03;
  s.nodes = 7;
  s.cutting_radius = 0.003;
  s.friction_radius = 0.0045;
  s.cutting_force = 0.05;
  s.puncture_force = 0.3;
  s.friction_force = 0.03;
  s.stick_stiffness = 200;
  return s;
}

physics::NeedlePose pose_at(double tip_z, double off = 0.001) {
  physics::NeedlePose p;
  p.tip = Vec3(off, off, tip_z);
  p.axis = Vec3(0, 0, -1);
  p.nodes = 7;
  p.spacing = 0.005;
  return p;
}

physics::Needle make_needle(const physics::Vector& x) {
  return physics::Needle(settings(), physics::make_needle_tissue(x, h, boundary_triangles(), settings()));
}

}  // namespace

TEST(Needle, InverseDistanceSharesSumToOneAndFavourTheNearest) {
  const auto w = physics::inverse_distance_shares({{0, 1.0}, {1, 2.0}, {2, 4.0}});
  ASSERT_EQ(w.size(), 3u);
  EXPECT_NEAR(w[0] + w[1] + w[2], 1, 1e-15);
  EXPECT_NEAR(w[0], 1.0 / 1.75, 1e-15);  // (1/1) / (1 + 1/2 + 1/4)
  EXPECT_NEAR(w[1], 0.5 / 1.75, 1e-15);
  const auto at_zero = physics::inverse_distance_shares({{0, 1.0}, {1, 0.0}, {2, 4.0}});
  EXPECT_EQ(at_zero[1], 1);  // seed: a particle at d = 0 is the only one used
  EXPECT_EQ(at_zero[0] + at_zero[2], 0);
}

TEST(Needle, CuttingIsTheInverseDistanceMeanOfKcAndPunctureTheBoundarys) {
  const physics::Vector x = lattice();
  physics::Needle needle = make_needle(x);
  // Tip 2 mm above the top face's centre column node (0, 0, 4h), 1.4 mm off its axis: the only
  // node in the 3 mm hemisphere, a boundary one: C = k_c(boundary), all of it on that node.
  const physics::NeedleForces top = needle.step(pose_at(4 * h + 0.002), 0.01, x);
  ASSERT_EQ(needle.zones().cutting.size(), 1u);
  EXPECT_EQ(needle.zones().cutting[0].atom, node(2, 2, 4));
  EXPECT_NEAR(top.cutting, 0.3, 1e-15);
  EXPECT_TRUE(top.puncturing);
  EXPECT_NEAR(top.axial, -0.3, 1e-15);  // resisting the insertion
  // Inside, between the layers 3h and 2h: only the interior node (2, 2, 2) ahead within 3 mm.
  physics::Needle inside = make_needle(x);
  const physics::NeedleForces in = inside.step(pose_at(2 * h + 0.002), 0.01, x);
  ASSERT_EQ(inside.zones().cutting.size(), 1u);
  EXPECT_NEAR(in.cutting, 0.05, 1e-15);
  EXPECT_FALSE(in.puncturing);
}

TEST(Needle, NoCuttingOnRetractionOrAtRest) {
  const physics::Vector x = lattice();
  physics::Needle needle = make_needle(x);
  EXPECT_GT(needle.step(pose_at(2 * h + 0.002), 0.01, x).cutting, 0);
  EXPECT_EQ(needle.step(pose_at(2 * h + 0.002), -0.01, x).cutting, 0);
  EXPECT_EQ(needle.step(pose_at(2 * h + 0.002), 0.0, x).cutting, 0);
}

TEST(Needle, ForcesOnTissueAndNeedleAreEqualAndOpposite) {
  const physics::Vector x = lattice();
  physics::Needle needle = make_needle(x);
  // Insert with a lateral drift too, so every kind of force acts.
  double worst = 0;
  for (int s = 0; s <= 200; ++s) {
    physics::NeedlePose p = pose_at(4 * h + 0.003 - 0.0001 * s);
    p.tip.x() += 2e-6 * s;
    const physics::NeedleForces f = needle.step(p, 0.1, x);
    Vec3 sum = f.on_needle;
    for (const auto& [atom, force] : f.tissue) sum += force;
    worst = std::max(worst, sum.norm());
  }
  EXPECT_LT(worst, 1e-15);
}

TEST(Needle, ZonesKeptThroughNeighboursEqualAFullScan) {
  const physics::Vector x = lattice();
  physics::Needle tracked = make_needle(x);
  long scans_at_contact = -1;
  for (int s = 0; s <= 150; ++s) {
    const physics::NeedlePose p = pose_at(4 * h + 0.004 - 0.0001 * s);
    tracked.step(p, 0.1, x);
    if (scans_at_contact < 0 && !tracked.zones().empty()) scans_at_contact = tracked.full_scans();
    physics::NeedleZones scanned;  // empty: a full scan
    physics::update_zones(scanned, p, x, tracked.tissue(), tracked.settings());
    ASSERT_EQ(scanned.cutting.size(), tracked.zones().cutting.size()) << "step " << s;
    for (std::size_t j = 0; j < scanned.friction.size(); ++j) {
      ASSERT_EQ(scanned.friction[j].size(), tracked.zones().friction[j].size()) << "step " << s << " node " << j;
      for (std::size_t m = 0; m < scanned.friction[j].size(); ++m)
        EXPECT_EQ(scanned.friction[j][m].atom, tracked.zones().friction[j][m].atom);
    }
  }
  // A full scan every step until the first contact, none after it: the top node, 1.4 mm off the
  // axis, is within 3 mm of the tip once the tip is 2.65 mm above it (step 14 of 0.1 mm).
  EXPECT_EQ(scans_at_contact, 15);
  EXPECT_EQ(tracked.full_scans(), scans_at_contact);
}

TEST(Needle, ANodeSticksAtRestAndSlipsPastTheFrictionWithTransitionsCounted) {
  const physics::Vector x = lattice();
  physics::Needle needle = make_needle(x);
  // In the tissue, still: every engaged node sticks, holding no force.
  const double z = 2 * h + 0.002;
  physics::NeedleForces f = needle.step(pose_at(z), 0, x);
  EXPECT_GT(f.sticking, 0);
  EXPECT_EQ(f.slipping, 0);
  EXPECT_NEAR(f.friction, 0, 1e-15);
  // Moved in by 0.1 mm (k_v 0.1 mm = 0.02 N < k_f 0.03 N): still stuck, the pull 0.02 N back
  // (friction is along the axis: negative resists the insertion).
  f = needle.step(pose_at(z - 0.0001), 0, x);
  EXPECT_EQ(f.slipping, 0);
  EXPECT_NEAR(f.friction / f.sticking, -0.02, 1e-12);
  EXPECT_EQ(needle.stick_to_slip(), 0);
  // 0.1 mm more (0.04 N > 0.03 N): every node slips, kinetic friction 0.03 N each.
  f = needle.step(pose_at(z - 0.0002), 0, x);
  const int engaged = f.slipping;
  EXPECT_GT(engaged, 0);
  EXPECT_EQ(f.sticking, 0);
  EXPECT_NEAR(f.friction, -0.03 * engaged, 1e-12);
  EXPECT_EQ(needle.stick_to_slip(), engaged);
  // Still again: the particles were left 0.15 mm behind (|pull| = k_f): they stick at k_f.
  f = needle.step(pose_at(z - 0.0002), 0, x);
  EXPECT_EQ(f.sticking, engaged);
  EXPECT_EQ(needle.slip_to_stick(), engaged);
  EXPECT_NEAR(f.friction, -0.03 * engaged, 1e-12);
  // Pulled back 0.1 mm: the pull falls to 0.01 N, still static friction.
  f = needle.step(pose_at(z - 0.0001), 0, x);
  EXPECT_EQ(f.sticking, engaged);
  EXPECT_NEAR(f.friction, -0.01 * engaged, 1e-12);
}

TEST(Needle, BadSettingsAreRefusedByName) {
  const physics::Vector x = lattice();
  auto s = settings();
  s.nodes = 1;
  EXPECT_THROW(physics::Needle(s, physics::make_needle_tissue(x, h, {}, s)), std::invalid_argument);
  EXPECT_THROW(physics::make_needle_tissue(x, 0, {}, settings()), std::invalid_argument);
}
