// physics::TriangleGrid (physics/core/triangle_grid.hpp): scanning only its candidates finds
// the same nearest triangle, at the same distance bit for bit, as scanning every triangle of
// the surface, for points on, near, inside and far outside a bumpy closed surface with
// degenerate, duplicated and left-out faces (ties between shared vertices and edges included).
#include "physics/core/contact.hpp"
#include "physics/core/triangle_grid.hpp"

#include <gtest/gtest.h>

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
// one that is strictly nearer, in the order given.
Nearest scan(const Surface& s, const physics::TriangleGrid& grid, const Vec3& p, const std::vector<int>& order) {
  Nearest out;
  for (int t : order) {
    if ((grid.lo(t) - p).cwiseMax(p - grid.hi(t)).cwiseMax(Vec3::Zero()).norm() >= out.distance) continue;
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
  int checked = 0;
  for (const Vec3& p : points) {
    grid.candidates(p, candidates);
    EXPECT_TRUE(std::is_sorted(candidates.begin(), candidates.end()));
    const Nearest all = scan(s, grid, p, every), near = scan(s, grid, p, candidates);
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
  physics::TriangleGrid grid(s.x, s.triangles, use);
  grid.candidates(Vec3(std::nan(""), 0, 0), candidates);
  EXPECT_EQ(candidates.size(), s.triangles.size() - 1);
  s.x[4] = std::numeric_limits<double>::infinity();
  physics::TriangleGrid broken(s.x, s.triangles, use);
  broken.candidates(Vec3::Zero(), candidates);
  EXPECT_EQ(candidates.size(), s.triangles.size() - 1);
  EXPECT_EQ(candidates.front(), 1);
}
