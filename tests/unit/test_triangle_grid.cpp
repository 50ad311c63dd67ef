// physics::TriangleGrid (physics/core/triangle_grid.hpp): scanning only its candidates finds
// the same nearest triangle, at the same distance bit for bit, as scanning every triangle of
// the surface, for points on, near, inside and far outside a bumpy closed surface with
// degenerate, duplicated and left-out faces (ties between shared vertices and edges included).
// physics::nearest_triangles (physics/core/nearest_triangles.hpp) likewise, with every kind of
// hint (none, stale after the surface and the points moved, far, out of range, unusable).
#include "physics/core/contact.hpp"
#include "physics/core/nearest_triangles.hpp"
#include "physics/core/triangle_grid.hpp"
#include "tests/unit/test_executors.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

namespace physics = incise::physics;
using physics::Vec3;

namespace {

struct Surface {
  physics::Vector x;
  std::vector<std::array<int, 3>> triangles;
};

// A latitude-longitude sphere of radius about 0.05 m with bumps, its poles' triangles
// degenerate (the pole repeated per longitude), every 17th triangle repeated.
Surface bumpy_sphere(int rings, int sectors, std::mt19937& random) {
  std::uniform_real_distribution<double> bump(0.95, 1.05);
  Surface s;
  std::vector<Vec3> points;
  for (int i = 0; i <= rings; ++i)
    for (int j = 0; j < sectors; ++j) {
      const double theta = M_PI * i / rings, phi = 2 * M_PI * j / sectors;
      const double r = (i == 0 || i == rings) ? 0.05 : 0.05 * bump(random);
      points.push_back(r * Vec3(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)));
    }
  s.x.resize(3 * static_cast<Eigen::Index>(points.size()));
  for (std::size_t n = 0; n < points.size(); ++n) s.x.segment<3>(3 * static_cast<Eigen::Index>(n)) = points[n];
  const auto at = [&](int i, int j) { return i * sectors + (j % sectors); };
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < sectors; ++j) {
      s.triangles.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      s.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
      if (s.triangles.size() % 17 == 0) s.triangles.push_back(s.triangles.back());
    }
  return s;
}

struct Nearest {
  int triangle = -1;
  double distance = std::numeric_limits<double>::infinity();
};

// The scans' rule (mark_engaged, held_contact): skip a triangle whose box is no nearer, take
// one that is strictly nearer, in the order given (the grid's slots).
Nearest scan(const Surface& s, const physics::TriangleGrid& grid, const Vec3& p, const std::vector<int>& order) {
  Nearest out;
  for (int slot : order) {
    if ((grid.lo(slot) - p).cwiseMax(p - grid.hi(slot)).cwiseMax(Vec3::Zero()).norm() >= out.distance) continue;
    const int t = grid.triangle(slot);
    const auto& tri = s.triangles[static_cast<std::size_t>(t)];
    const Vec3 q = physics::closest_point_on_triangle(p, s.x.segment<3>(3 * tri[0]), s.x.segment<3>(3 * tri[1]),
                                                      s.x.segment<3>(3 * tri[2]));
    const double d = (p - q).norm();
    if (d < out.distance) out = {t, d};
  }
  return out;
}

}  // namespace

TEST(TriangleGrid, ItsCandidatesGiveTheSameNearestTriangleAsAScanOfEveryTriangle) {
  std::mt19937 random(29);
  const Surface s = bumpy_sphere(40, 64, random);
  std::vector<std::uint8_t> use(s.triangles.size(), 1);
  std::vector<int> every;
  for (std::size_t t = 0; t < s.triangles.size(); ++t) {
    const auto& tri = s.triangles[t];
    const Vec3 a = s.x.segment<3>(3 * tri[0]), b = s.x.segment<3>(3 * tri[1]), c = s.x.segment<3>(3 * tri[2]);
    use[t] = (b - a).cross(c - a).squaredNorm() > 0 && t % 23 != 5;  // degenerate or "cut": left out
    if (use[t]) every.push_back(static_cast<int>(t));
  }
  physics::TriangleGrid grid(s.x, s.triangles, use);
  ASSERT_EQ(grid.size(), static_cast<int>(every.size()));
  for (int slot = 0; slot < grid.size(); ++slot) ASSERT_EQ(grid.triangle(slot), every[static_cast<std::size_t>(slot)]);
  std::vector<int> slots(every.size());
  for (std::size_t slot = 0; slot < slots.size(); ++slot) slots[slot] = static_cast<int>(slot);
  std::vector<Vec3> points;
  std::uniform_real_distribution<double> box(-0.12, 0.12), unit(0, 1);
  for (int k = 0; k < 400; ++k) points.push_back(Vec3(box(random), box(random), box(random)));  // in, near and out
  for (int k = 0; k < 100; ++k) points.push_back(0.01 * Vec3(box(random), box(random), box(random)));  // deep inside
  for (int k = 0; k < 100; ++k) points.push_back(3.0 * Vec3(box(random), box(random), box(random)));   // far away
  for (int n = 0; n < s.x.size() / 3; n += 7) points.push_back(s.x.segment<3>(3 * n));  // on vertices: ties
  for (std::size_t t = 0; t < s.triangles.size(); t += 5) {
    const auto& tri = s.triangles[t];
    const double w = unit(random);
    points.push_back(w * s.x.segment<3>(3 * tri[0]) + (1 - w) * s.x.segment<3>(3 * tri[1]));  // on edges
  }
  std::vector<int> candidates;
  physics::TriangleGrid::Scratch scratch;
  int checked = 0;
  for (const Vec3& p : points) {
    grid.candidates(p, candidates, scratch);
    EXPECT_TRUE(std::is_sorted(candidates.begin(), candidates.end()));
    const Nearest all = scan(s, grid, p, slots), near = scan(s, grid, p, candidates);
    // Near the surface the grid leaves most of it out (deep inside, a point is nearly as far
    // from much of it).
    if (all.distance < 0.005) {
      EXPECT_LT(candidates.size(), every.size() / 20);
    }
    ASSERT_EQ(near.triangle, all.triangle) << "at " << p.transpose();
    ASSERT_EQ(near.distance, all.distance) << "at " << p.transpose();
    ++checked;
  }
  EXPECT_EQ(checked, static_cast<int>(points.size()));
}

TEST(TriangleGrid, NonFinitePositionsOrPointsScanEveryUsedTriangle) {
  std::mt19937 random(3);
  Surface s = bumpy_sphere(6, 8, random);
  std::vector<std::uint8_t> use(s.triangles.size(), 1);
  use[0] = 0;
  std::vector<int> candidates;
  physics::TriangleGrid::Scratch scratch;
  physics::TriangleGrid grid(s.x, s.triangles, use);
  grid.candidates(Vec3(std::nan(""), 0, 0), candidates, scratch);
  EXPECT_EQ(candidates.size(), s.triangles.size() - 1);
  s.x[4] = std::numeric_limits<double>::infinity();
  physics::TriangleGrid broken(s.x, s.triangles, use);
  broken.candidates(Vec3::Zero(), candidates, scratch);
  EXPECT_EQ(candidates.size(), s.triangles.size() - 1);
  EXPECT_EQ(broken.triangle(candidates.front()), 1);
}

namespace {

// The scan of every usable triangle (not skipped, nonzero normal), in order, each with its own
// box: the reference nearest_triangles must match.
physics::NearestTriangle scan_every(const Surface& s, const std::vector<std::uint8_t>& skip, const Vec3& p) {
  physics::NearestTriangle out;
  for (std::size_t t = 0; t < s.triangles.size(); ++t) {
    if (t < skip.size() && skip[t]) continue;
    const auto& tri = s.triangles[t];
    const Vec3 a = s.x.segment<3>(3 * tri[0]), b = s.x.segment<3>(3 * tri[1]), c = s.x.segment<3>(3 * tri[2]);
    if (!((b - a).cross(c - a).squaredNorm() > 0)) continue;
    const Vec3 lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
    if ((lo - p).cwiseMax(p - hi).cwiseMax(Vec3::Zero()).norm() >= out.distance) continue;
    const Vec3 q = physics::closest_point_on_triangle(p, a, b, c);
    const double d = (p - q).norm();
    if (d < out.distance) out = {static_cast<int>(t), d, q};
  }
  return out;
}

}  // namespace

TEST(NearestTriangles, AnyHintGivesTheScanOfEveryTriangleBitForBit) {
  std::mt19937 random(31);
  Surface s = bumpy_sphere(40, 64, random);
  std::vector<std::uint8_t> skip(s.triangles.size(), 0);
  for (std::size_t t = 5; t < skip.size(); t += 23) skip[t] = 1;  // "cut faces"
  std::uniform_real_distribution<double> unit(-1, 1);
  // A blade's pieces: a line of points from far above the surface down to deep inside it.
  const auto blade = [&](const Vec3& top, const Vec3& bottom, int count) {
    std::vector<Vec3> points;
    for (int k = 0; k < count; ++k) points.push_back(top + (bottom - top) * (k + 0.5) / count);
    return points;
  };
  std::vector<int> carried;  // the hint carried from call to call, as resist_cutting does
  int checked = 0;
  for (int step = 0; step < 40; ++step) {
    // The surface moves a little every step, as the tissue does.
    for (Eigen::Index i = 0; i < s.x.size(); ++i) s.x[i] += 2e-4 * unit(random);
    const double along = -0.04 + 0.002 * step;
    const std::vector<Vec3> points = blade(Vec3(along, 0.01 * unit(random), 0.08), Vec3(along, 0, -0.01), 30);
    const std::vector<int> far{0, 1, static_cast<int>(s.triangles.size()) - 1};
    const std::vector<int> garbage{-7, static_cast<int>(s.triangles.size()), 5, 28};  // out of range, skipped, ...
    std::vector<std::vector<int>> hints{{}, far, garbage, carried};
    for (std::size_t h = 0; h <= hints.size(); ++h) {
      std::vector<int>* hint = h < hints.size() ? &hints[h] : nullptr;
      const auto found = physics::nearest_triangles(s.x, s.triangles, skip, points, hint);
      ASSERT_EQ(found.size(), points.size());
      for (std::size_t i = 0; i < points.size(); ++i) {
        const physics::NearestTriangle reference = scan_every(s, skip, points[i]);
        ASSERT_EQ(found[i].triangle, reference.triangle) << "hint " << h << " at " << points[i].transpose();
        ASSERT_EQ(found[i].distance, reference.distance) << "hint " << h;
        ASSERT_EQ(found[i].closest, reference.closest) << "hint " << h;
        ++checked;
      }
      if (hint) {
        // The hint comes back as the points' nearest triangles, each once.
        for (const auto& n : found) EXPECT_NE(std::find(hint->begin(), hint->end(), n.triangle), hint->end());
        EXPECT_LE(hint->size(), points.size());
      }
      if (h == 3) carried = *hint;
    }
    EXPECT_FALSE(carried.empty());
  }
  EXPECT_EQ(checked, 40 * 5 * 30);
}

// resist_cutting runs it on the body's threads: the box pass in chunks of 8192 triangles and the
// points' scans in ranges. A surface of three chunks, split in pieces or on two threads, gives
// the serial result, hint and all.
TEST(NearestTriangles, OnThreadsGiveTheSerialResultBitForBit) {
  std::mt19937 random(47);
  Surface s = bumpy_sphere(100, 96, random);
  ASSERT_GT(s.triangles.size(), 2u * 8192u);
  std::vector<std::uint8_t> skip(s.triangles.size(), 0);
  for (std::size_t t = 3; t < skip.size(); t += 19) skip[t] = 1;
  std::vector<Vec3> points;
  for (int k = 0; k < 41; ++k) points.push_back(Vec3(0.002 * (k - 20), 0.001 * k, 0.07 - 0.003 * k));
  incise::test::ShufflingExecutor pieces(3);
  incise::test::TwoThreadExecutor two;
  std::vector<int> serial_hint{0, 7}, pieces_hint = serial_hint, two_hint = serial_hint;
  for (int step = 0; step < 3; ++step) {
    const auto serial = physics::nearest_triangles(s.x, s.triangles, skip, points, &serial_hint);
    const auto split = physics::nearest_triangles(s.x, s.triangles, skip, points, &pieces_hint, pieces);
    const auto threads = physics::nearest_triangles(s.x, s.triangles, skip, points, &two_hint, two);
    for (std::size_t i = 0; i < points.size(); ++i) {
      ASSERT_GE(serial[i].triangle, 0);
      EXPECT_EQ(serial[i].triangle, scan_every(s, skip, points[i]).triangle);
      for (const auto* other : {&split, &threads}) {
        EXPECT_EQ((*other)[i].triangle, serial[i].triangle);
        EXPECT_EQ((*other)[i].distance, serial[i].distance);
        EXPECT_EQ((*other)[i].closest, serial[i].closest);
      }
    }
    EXPECT_EQ(pieces_hint, serial_hint);
    EXPECT_EQ(two_hint, serial_hint);
    for (Eigen::Index i = 0; i < s.x.size(); ++i) s.x[i] *= 1.01;
  }
}

TEST(NearestTriangles, NoUsableTriangleOrNonFinitePointFindsNone) {
  std::mt19937 random(5);
  const Surface s = bumpy_sphere(6, 8, random);
  const std::vector<std::uint8_t> skip(s.triangles.size(), 1);
  std::vector<int> hint{0, 1};
  const auto none = physics::nearest_triangles(s.x, s.triangles, skip, {Vec3::Zero()}, &hint);
  EXPECT_EQ(none[0].triangle, -1);
  EXPECT_TRUE(hint.empty());
  const auto nan = physics::nearest_triangles(s.x, s.triangles, {}, {Vec3(std::nan(""), 0, 0), Vec3::Zero()}, &hint);
  EXPECT_EQ(nan[0].triangle, -1);
  EXPECT_EQ(nan[1].triangle, scan_every(s, {}, Vec3::Zero()).triangle);
}
