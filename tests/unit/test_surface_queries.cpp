// The fast inside and nearest-point queries of imported surfaces (engine/surface_queries.hpp,
// engine/mesh_shape.hpp) against the brute-force sums they replace, on a closed, non-convex,
// organ-like mesh.
#include "engine/mesh_import.hpp"
#include "engine/mesh_shape.hpp"
#include "engine/surface_queries.hpp"
#include "icosphere.hpp"
#include "physics/cut/voxel_boundary.hpp"
#include "physics/fem/surface_snap.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

namespace {

using incise::engine::MeshShape;
using incise::engine::SurfaceQueries;
using incise::engine::TriangleSoup;
using Eigen::Vector3d;

// An icosphere pushed in and out along its rays (so it stays closed and manifold) and
// stretched: lobes and dents, about 16 cm by 10 by 8, like an organ.
TriangleSoup organ_like(int levels) {
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(0.3, Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const auto sphere = incise::testing::icosphere(levels, 1.0, turn);
  TriangleSoup soup;
  for (const auto& v : sphere.vertices) {
    const double r = 1 + 0.3 * std::sin(3 * v.x()) * std::cos(2 * v.y()) + 0.15 * v.z() * v.z();
    soup.vertices.push_back({0.08 * r * v.x(), 0.05 * r * v.y(), 0.04 * r * v.z()});
  }
  soup.triangles = sphere.triangles;
  soup.min = soup.max = soup.vertices.front();
  for (const auto& v : soup.vertices)
    for (int i = 0; i < 3; ++i) {
      soup.min[i] = std::min(soup.min[i], v[i]);
      soup.max[i] = std::max(soup.max[i], v[i]);
    }
  return soup;
}

double exact_winding(const TriangleSoup& soup, const Vector3d& p) {
  return incise::engine::winding_number(soup, {p.x(), p.y(), p.z()});
}

// The distance to every triangle, each the smaller of the distance to its plane (where the
// foot lies inside it) and to its three edges: another route than the hierarchy's (Ericson's
// regions), over every triangle.
double brute_distance(const TriangleSoup& soup, const Vector3d& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& t : soup.triangles) {
    const Vector3d a(soup.vertices[t[0]][0], soup.vertices[t[0]][1], soup.vertices[t[0]][2]);
    const Vector3d b(soup.vertices[t[1]][0], soup.vertices[t[1]][1], soup.vertices[t[1]][2]);
    const Vector3d c(soup.vertices[t[2]][0], soup.vertices[t[2]][1], soup.vertices[t[2]][2]);
    const Vector3d n = (b - a).cross(c - a).normalized();
    const Vector3d foot = p - n.dot(p - a) * n;
    const bool in = (b - a).cross(foot - a).dot(n) >= 0 && (c - b).cross(foot - b).dot(n) >= 0 &&
                    (a - c).cross(foot - c).dot(n) >= 0;
    if (in) best = std::min(best, (p - foot).norm());
    for (const auto& [u, v] : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}}) {
      const double s = std::clamp((p - u).dot(v - u) / (v - u).squaredNorm(), 0.0, 1.0);
      best = std::min(best, (p - (u + s * (v - u))).norm());
    }
  }
  return best;
}

Vector3d random_point(std::mt19937& rng, const TriangleSoup& soup, double margin) {
  std::uniform_real_distribution<double> unit(0, 1);
  Vector3d p;
  for (int i = 0; i < 3; ++i) p[i] = soup.min[i] - margin + unit(rng) * (soup.max[i] - soup.min[i] + 2 * margin);
  return p;
}

TEST(SurfaceQueries, WindingNumberAgreesWithTheExactSum) {
  const TriangleSoup soup = organ_like(3);
  const SurfaceQueries queries(soup);
  std::mt19937 rng(7);
  int inside = 0, near = 0;
  double worst = 0;
  for (int k = 0; k < 3000; ++k) {
    const Vector3d p = random_point(rng, soup, 0.03);
    const double exact = exact_winding(soup, p), fast = queries.winding_number(p);
    worst = std::max(worst, std::abs(fast - exact));
    // Identical classification wherever the point is not within rounding of the surface.
    if (queries.nearest(p).distance > 1e-9) {
      EXPECT_EQ(fast > 0.5, exact > 0.5) << p.transpose();
    }
    inside += exact > 0.5;
    near += queries.nearest(p).distance < 0.003;
  }
  EXPECT_LT(worst, 0.1);  // the expansion's error (order 2, accuracy 2), away from and near the surface alike
  EXPECT_GT(inside, 300);  // the test saw both sides, and points near the surface
  EXPECT_GT(near, 100);
  // Far away, every cluster is expanded: the number is 0 within the expansion's error.
  EXPECT_NEAR(queries.winding_number(Vector3d(1, 2, 3)), 0.0, 1e-6);
}

TEST(SurfaceQueries, PointsJustOffTheSurfaceAreClassifiedAsTheExactSumClassifiesThem) {
  const TriangleSoup soup = organ_like(3);
  const SurfaceQueries queries(soup);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(0, 1);
  for (std::size_t t = 0; t < soup.triangles.size(); t += 7) {
    const auto& c = soup.triangles[t];
    const Vector3d a(soup.vertices[c[0]][0], soup.vertices[c[0]][1], soup.vertices[c[0]][2]);
    const Vector3d b(soup.vertices[c[1]][0], soup.vertices[c[1]][1], soup.vertices[c[1]][2]);
    const Vector3d d(soup.vertices[c[2]][0], soup.vertices[c[2]][1], soup.vertices[c[2]][2]);
    const Vector3d n = (b - a).cross(d - a).normalized();
    double u = unit(rng), v = unit(rng);
    if (u + v > 1) u = 1 - u, v = 1 - v;
    const Vector3d on = a + u * (b - a) + v * (d - a);
    for (const double offset : {-1e-4, -1e-6, 1e-6, 1e-4}) {
      const Vector3d p = on + offset * n;
      EXPECT_EQ(queries.inside(p), exact_winding(soup, p) > 0.5) << "triangle " << t << " offset " << offset;
      EXPECT_EQ(queries.inside(p), offset < 0);
    }
  }
}

TEST(SurfaceQueries, NearestPointIsTheBruteForceNearest) {
  const TriangleSoup soup = organ_like(2);
  const SurfaceQueries queries(soup);
  std::mt19937 rng(3);
  for (int k = 0; k < 400; ++k) {
    const Vector3d p = random_point(rng, soup, 0.05);
    const auto nearest = queries.nearest(p);
    EXPECT_NEAR(nearest.distance, brute_distance(soup, p), 1e-12);
    EXPECT_NEAR((nearest.point - p).norm(), nearest.distance, 1e-12);
    ASSERT_GE(nearest.triangle, 0);
  }
}

TEST(MeshShape, InsideAndLineSectionsAgreeWithTheExactSum) {
  const TriangleSoup soup = organ_like(3);
  const MeshShape shape(soup);
  EXPECT_GT(shape.classified_cells(), shape.cells() / 2);  // most points never reach the hierarchy
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> unit(-1, 1);
  int sections = 0;
  for (int k = 0; k < 300; ++k) {
    const Vector3d p = random_point(rng, soup, 0.02);
    EXPECT_EQ(shape.inside(p), exact_winding(soup, p) > 0.5) << p.transpose();
    const Vector3d n = Vector3d(unit(rng), unit(rng), unit(rng)).normalized();
    const auto section = shape.along(p, n, 0.05);
    if (!section) continue;
    ++sections;
    for (int j = 0; j < 20; ++j) {
      const double s = 0.05 * unit(rng);
      const Vector3d q = p + s * n;
      if (shape.queries().nearest(q).distance < 1e-9) continue;  // within rounding of the surface
      EXPECT_EQ(section->inside_at(s), exact_winding(soup, q) > 0.5) << "point " << k << " s " << s;
    }
  }
  EXPECT_GT(sections, 290);  // grazing an edge is rare
}

// The fairing with the mesh's line sections puts every vertex where the point-by-point fairing
// puts it (within the bisection's last step), at a fraction of the queries.
TEST(MeshShape, FairingAlongLinesMatchesFairingPointByPoint) {
  const TriangleSoup soup = organ_like(3);
  const MeshShape shape(soup);
  const auto inside = [&](const incise::physics::Vec3& p) { return shape.inside(p); };
  const auto along = [&](const incise::physics::Vec3& p, const incise::physics::Vec3& n, double reach) {
    return shape.along(p, n, reach);
  };
  const double cell = 0.008;
  const Vector3d lo(soup.min[0], soup.min[1], soup.min[2]), hi(soup.max[0], soup.max[1], soup.max[2]);
  auto by_points = incise::physics::voxel_boundary(inside, lo, hi, cell);
  auto by_lines = by_points;
  const auto report_points = incise::physics::fair_surface_onto_shape(by_points.vertices, by_points.triangles, inside, cell);
  const auto report_lines =
      incise::physics::fair_surface_onto_shape(by_lines.vertices, by_lines.triangles, inside, cell, 3, along);
  EXPECT_EQ(report_points.projected, report_lines.projected);
  EXPECT_EQ(report_points.creases, report_lines.creases);
  EXPECT_GT(report_lines.projected, 100);
  double worst = 0;
  for (std::size_t v = 0; v < by_points.vertices.size(); ++v)
    worst = std::max(worst, (by_points.vertices[v] - by_lines.vertices[v]).norm());
  EXPECT_LT(worst, 1e-12);
}

}  // namespace
