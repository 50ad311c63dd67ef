// The cut surface's rebuild after a cut is local (physics/cut/cut_surface.hpp): vertices
// away from the new cut keep their index, key and rest position, an index keeps its key as
// long as the key lives, the surface stays closed after every cut, and the outcome is the
// surface of the same cut made all at once (up to the numbering); the lists are patched in
// place and the rebuild reports exactly what it wrote.
#include "physics/cut/cut_surface.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <algorithm>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

using namespace incise::physics;

namespace {

const auto in_box = [](const Vec3& p) {
  return p.x() >= 0 && p.x() <= 0.1 && std::abs(p.y()) <= 0.01 && std::abs(p.z()) <= 0.01;
};
constexpr double cell = 0.0025;

CutSurface bar_surface() { return CutSurface(in_box, Vec3(0, -0.01, -0.01), Vec3(0.1, 0.01, 0.01), cell); }

// The quad [p0, p1, p2, p3] as two triangles.
std::vector<RestTriangle> quad(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3) {
  return {{p0, p1, p2}, {p0, p2, p3}};
}

// The blade plane x = x_cut from the top down to z_bottom, wider than the bar.
std::vector<RestTriangle> plane_cut(double x_cut, double z_bottom) {
  return quad(Vec3(x_cut, -0.03, 0.03), Vec3(x_cut, 0.03, 0.03), Vec3(x_cut, 0.03, z_bottom), Vec3(x_cut, -0.03, z_bottom));
}

// The same from the bottom up to z_top.
std::vector<RestTriangle> plane_cut_from_below(double x_cut, double z_top) {
  return quad(Vec3(x_cut, -0.03, -0.03), Vec3(x_cut, 0.03, -0.03), Vec3(x_cut, 0.03, z_top), Vec3(x_cut, -0.03, z_top));
}

// Expects a and b to be the same surface whatever their numbering: the same used keys with
// the same rest positions, anchors and cut flags, and the same triangles in the same order.
void expect_same_surface(const CutSurface& a, const CutSurface& b, const std::string& what) {
  const auto by_key = [](const CutSurface& s) {
    std::map<long long, int> index;
    for (int v = 0; v < static_cast<int>(s.vertex_keys().size()); ++v)
      if (s.vertex_used(v)) index[s.vertex_keys()[v]] = v;
    return index;
  };
  const auto in_a = by_key(a), in_b = by_key(b);
  ASSERT_EQ(in_a.size(), in_b.size()) << what;
  EXPECT_EQ(a.vertex_count(), b.vertex_count()) << what;
  for (const auto& [key, va] : in_a) {
    const auto it = in_b.find(key);
    ASSERT_NE(it, in_b.end()) << what << ": key " << key;
    const int vb = it->second;
    EXPECT_TRUE(a.rest_vertices().segment<3>(3 * va) == b.rest_vertices().segment<3>(3 * vb)) << what << ": key " << key;
    EXPECT_TRUE(a.anchors()[va] == b.anchors()[vb]) << what << ": key " << key;
    EXPECT_EQ(a.on_cut()[va], b.on_cut()[vb]) << what << ": key " << key;
  }
  ASSERT_EQ(a.triangles().size(), b.triangles().size()) << what;
  for (size_t t = 0; t < a.triangles().size(); ++t)
    for (int c = 0; c < 3; ++c)
      ASSERT_EQ(a.vertex_keys()[a.triangles()[t][c]], b.vertex_keys()[b.triangles()[t][c]]) << what << ": triangle " << t;
  EXPECT_EQ(a.pinches_closed(), b.pinches_closed()) << what;
}

// The rebuild patches its lists in place and reports what it wrote
// (CutSurface::changed_triangles, placed_vertices): a copy of the lists before it, patched
// with only that, must be the lists after it.
void expect_patch_complete(const std::vector<std::array<int, 3>>& triangles_before, const Vector& rest_before,
                           const CutSurface& surface, const std::string& what) {
  const auto& triangles = surface.triangles();
  const auto [first, last] = surface.changed_triangles();
  ASSERT_LE(0, first) << what;
  ASSERT_LE(first, last) << what;
  ASSERT_LE(last, static_cast<int>(triangles.size())) << what;
  if (triangles.size() != triangles_before.size()) {
    EXPECT_EQ(last, static_cast<int>(triangles.size())) << what << ": the count changed, the tail moved";
  }
  std::vector<std::array<int, 3>> patched = triangles_before;
  patched.resize(triangles.size());
  std::copy(triangles.begin() + first, triangles.begin() + last, patched.begin() + first);
  for (size_t t = 0; t < triangles.size(); ++t) ASSERT_EQ(patched[t], triangles[t]) << what << ": triangle " << t;
  const Eigen::Index rows = surface.rest_vertices().size();
  ASSERT_GE(rows, rest_before.size()) << what;
  Vector rest = rest_before;
  rest.conservativeResize(rows);
  std::set<int> placed;
  for (int v : surface.placed_vertices()) {
    ASSERT_TRUE(placed.insert(v).second) << what << ": vertex " << v << " placed twice";
    rest.segment<3>(3 * static_cast<Eigen::Index>(v)) = surface.rest_vertices().segment<3>(3 * static_cast<Eigen::Index>(v));
  }
  for (Eigen::Index v = rest_before.size() / 3; v < rows / 3; ++v) EXPECT_TRUE(placed.count(static_cast<int>(v))) << what << ": appended vertex " << v;
  for (Eigen::Index i = 0; i < rows; ++i) ASSERT_EQ(rest[i], surface.rest_vertices()[i]) << what << ": rest row " << i / 3;
}

}  // namespace

TEST(CutSurfaceIncremental, VerticesAwayFromANewCutKeepTheirIndexAndTheSurfaceStaysClosed) {
  CutSurface surface = bar_surface();
  ASSERT_TRUE(surface_topology(surface.triangles()).watertight());
  const Vec3 n = Vec3(1, 0.4, 0.3).normalized();
  const Vec3 u = n.cross(Vec3(0, 0, 1)).normalized(), w = n.cross(u);
  const Vec3 c(0.0205, 0.001, 0.004);
  const std::vector<std::vector<RestTriangle>> cuts = {
      // The blade's entry: one face at the top, a pinch (hidden until the cut grows).
      quad(Vec3(0.0512, 0.0004, 0.03), Vec3(0.0512, 0.0021, 0.03), Vec3(0.0512, 0.0021, 0.008), Vec3(0.0512, 0.0004, 0.008)),
      plane_cut(0.0512, 0.0),    // the top half of that section
      plane_cut(0.0512, -0.03),  // through: two pieces
      plane_cut(0.0765, 0.004),  // a shallow cut in the right piece
      // Deeper, a little nearer the grid nodes: the shallow cut's faces get their vertices
      // projected onto this plane, where it is nearer, though they are not cut again.
      plane_cut(0.0770, -0.004),
      // From below, then further up: the second's new faces are in higher cubes (the grid
      // is numbered x fastest, z slowest) than those whose vertices it splits at the old
      // crack front, which keep their faces' count (rewritten in place, not moved).
      plane_cut_from_below(0.0890, -0.004),
      plane_cut_from_below(0.0890, 0.004),
      // An oblique cut in the left piece, ending inside the bar.
      quad(c - 0.05 * u + 0.05 * w, c + 0.05 * u + 0.05 * w, c + 0.05 * u - 0.005 * w, c - 0.05 * u - 0.005 * w),
  };
  std::vector<RestTriangle> all;
  for (size_t step = 0; step < cuts.size(); ++step) {
    const std::string what = "cut " + std::to_string(step);
    const std::vector<long long> keys = surface.vertex_keys();
    const Vector rest = surface.rest_vertices();
    const std::vector<Vec3> anchors = surface.anchors();
    const std::vector<std::array<int, 3>> triangles = surface.triangles();
    EXPECT_GT(surface.cut(cuts[step]), 0) << what;
    surface.rebuild();
    expect_patch_complete(triangles, rest, surface, what);
    // The cut left the list's head in place; after the first (a pinch: the face is hidden,
    // the count kept) cubes gained faces, so the tail moved.
    EXPECT_GT(surface.changed_triangles().first, 0) << what;
    if (step > 0) {
      EXPECT_NE(surface.triangles().size(), triangles.size()) << what;
    }
    if (step == 0) {
      EXPECT_EQ(surface.pinches_closed(), 1) << what;
    }
    const SurfaceTopology topology = surface_topology(surface.triangles());
    EXPECT_TRUE(topology.watertight()) << what << ": " << topology.boundary_edges << " boundary, "
                                       << topology.nonmanifold_edges << " non-manifold";
    // The count the rebuild keeps is the full one.
    EXPECT_EQ(surface.topology().boundary_edges, topology.boundary_edges) << what;
    EXPECT_EQ(surface.topology().nonmanifold_edges, topology.nonmanifold_edges) << what;
    // The used indices are exactly those the triangles use.
    std::set<int> in_triangles;
    for (const auto& t : surface.triangles())
      for (int v : t) in_triangles.insert(v);
    EXPECT_EQ(static_cast<int>(in_triangles.size()), surface.vertex_count()) << what;
    for (int v : in_triangles) EXPECT_TRUE(surface.vertex_used(v)) << what << ": vertex " << v;
    // A key still used is at the index it had.
    std::set<long long> used_keys;
    for (int v : in_triangles) used_keys.insert(surface.vertex_keys()[v]);
    for (size_t v = 0; v < keys.size(); ++v) {
      if (keys[v] >= 0 && used_keys.count(keys[v])) {
        EXPECT_EQ(surface.vertex_keys()[v], keys[v]) << what << ": vertex " << v;
      }
    }
    // Vertices more than two cells from the new triangles keep index, key, position, anchor.
    Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
    for (const RestTriangle& t : cuts[step]) lo = lo.cwiseMin(t.a).cwiseMin(t.b).cwiseMin(t.c), hi = hi.cwiseMax(t.a).cwiseMax(t.b).cwiseMax(t.c);
    int far = 0;
    for (size_t v = 0; v < keys.size(); ++v) {
      if (keys[v] < 0) continue;
      const Vec3 p = rest.segment<3>(3 * static_cast<Eigen::Index>(v));
      if ((p.array() > lo.array() - 2 * cell).all() && (p.array() < hi.array() + 2 * cell).all()) continue;
      ++far;
      ASSERT_EQ(surface.vertex_keys()[v], keys[v]) << what << ": vertex " << v;
      EXPECT_TRUE(surface.rest_vertices().segment<3>(3 * static_cast<Eigen::Index>(v)) == p) << what << ": vertex " << v;
      EXPECT_TRUE(surface.anchors()[v] == anchors[v]) << what << ": vertex " << v;
    }
    EXPECT_GT(far, 500) << what << ": the case exercises vertices away from the cut";
    // The same cut made at once, rebuilt once from the uncut surface.
    all.insert(all.end(), cuts[step].begin(), cuts[step].end());
    CutSurface at_once = bar_surface();
    at_once.cut(all);
    at_once.rebuild();
    expect_same_surface(surface, at_once, what);
  }
  // New vertices were appended: the cut split groups at many nodes.
  EXPECT_GT(static_cast<int>(surface.vertex_keys().size()), 1500);
}

TEST(CutSurfaceIncremental, RandomBladeWalksStayClosedAndEqualTheCutMadeAtOnce) {
  // Blades wandering through an ellipsoid, a few random triangles per step: many pinches,
  // and (seed 17) groups joined again, which frees indices that later steps reuse.
  const auto ellipsoid = [](const Vec3& p) {
    return std::pow(p.x() / 0.03, 2) + std::pow(p.y() / 0.02, 2) + std::pow(p.z() / 0.015, 2) <= 1;
  };
  const Vec3 lo(-0.03, -0.02, -0.015), hi(0.03, 0.02, 0.015);
  int pinches = 0, most_unused = 0, reused = 0, in_place = 0;
  for (unsigned seed = 15; seed < 21; ++seed) {
    std::mt19937 random(seed);
    const auto uniform = [&random] { return random() / 2147483648.0 - 1.0; };  // in [-1, 1)
    const auto jitter = [&uniform] { return Vec3(uniform(), uniform(), uniform()); };
    const double size = seed % 3 == 0 ? 0.002 : seed % 3 == 1 ? 0.004 : 0.008;
    CutSurface surface(ellipsoid, lo, hi, 0.002);
    std::vector<RestTriangle> all;
    Vec3 p(0.02 * uniform(), 0.015 * uniform(), 0.02);
    Vec3 direction(uniform(), uniform(), -0.5);
    direction.normalize();
    int unused_before = 0;
    for (int step = 0; step < 25; ++step) {
      const std::string what = "seed " + std::to_string(seed) + " step " + std::to_string(step);
      std::vector<RestTriangle> triangles;
      const int count = 1 + static_cast<int>(random() % 3);
      for (int t = 0; t < count; ++t) {
        const Vec3 q = p + size * jitter(), r = p + size * jitter();
        triangles.push_back({p, q, r});
        p += 0.003 * direction + 0.0015 * jitter();
      }
      const std::vector<long long> keys = surface.vertex_keys();
      const std::vector<std::array<int, 3>> triangles_before = surface.triangles();
      const Vector rest_before = surface.rest_vertices();
      surface.cut(triangles);
      surface.rebuild();
      expect_patch_complete(triangles_before, rest_before, surface, what);
      in_place += triangles_before.size() == surface.triangles().size() && surface.changed_triangles().second > 0 ? 1 : 0;
      all.insert(all.end(), triangles.begin(), triangles.end());
      pinches += surface.pinches_closed();
      ASSERT_TRUE(surface_topology(surface.triangles()).watertight()) << what;
      ASSERT_TRUE(surface.topology().watertight()) << what;
      std::set<int> in_triangles;
      for (const auto& t : surface.triangles())
        for (int v : t) in_triangles.insert(v);
      ASSERT_EQ(static_cast<int>(in_triangles.size()), surface.vertex_count()) << what;
      const int indices = static_cast<int>(surface.vertex_keys().size());
      std::set<long long> used_keys;
      for (int v : in_triangles) used_keys.insert(surface.vertex_keys()[v]);
      for (int v = 0; v < indices; ++v) {
        ASSERT_EQ(surface.vertex_used(v), in_triangles.count(v) == 1) << what << ": vertex " << v;
        if (!surface.vertex_used(v)) {
          ASSERT_EQ(surface.on_cut()[v], 0) << what << ": vertex " << v;
        }
        // A key still in use is at the index it had (a freed index may hold a new key).
        if (v < static_cast<int>(keys.size()) && keys[v] >= 0 && used_keys.count(keys[v])) {
          ASSERT_EQ(surface.vertex_keys()[v], keys[v]) << what << ": vertex " << v;
        }
      }
      const int unused = indices - surface.vertex_count();
      most_unused = std::max(most_unused, unused);
      // Freed indices taken again: fewer unused than before without growing, or a used index
      // whose key changed.
      for (int v = 0; v < static_cast<int>(keys.size()); ++v)
        reused += keys[v] >= 0 && surface.vertex_used(v) && surface.vertex_keys()[v] != keys[v] ? 1 : 0;
      reused += unused < unused_before && indices == static_cast<int>(keys.size()) ? 1 : 0;
      unused_before = unused;
      if (step % 5 == 4) {
        CutSurface at_once(ellipsoid, lo, hi, 0.002);
        at_once.cut(all);
        at_once.rebuild();
        expect_same_surface(surface, at_once, what);
      }
    }
  }
  EXPECT_GT(pinches, 100) << "the walks exercise pinch closing";
  EXPECT_GT(most_unused, 0) << "the walks exercise freed indices";
  EXPECT_GT(reused, 0) << "the walks exercise reusing freed indices";
  EXPECT_GT(in_place, 0) << "the walks exercise rebuilds that keep the triangle count";
}
