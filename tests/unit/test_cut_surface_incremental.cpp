// The cut surface's rebuild after a cut is local (physics/cut/cut_surface.hpp): vertices
// away from the new cut keep their index, key and rest position, an index keeps its key as
// long as the key lives, the surface stays closed after every cut, and the outcome is the
// surface of the same cut made all at once (up to the numbering).
#include "physics/cut/cut_surface.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
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
      // An oblique cut in the left piece, ending inside the bar.
      quad(c - 0.05 * u + 0.05 * w, c + 0.05 * u + 0.05 * w, c + 0.05 * u - 0.005 * w, c - 0.05 * u - 0.005 * w),
  };
  std::vector<RestTriangle> all;
  for (size_t step = 0; step < cuts.size(); ++step) {
    const std::string what = "cut " + std::to_string(step);
    const std::vector<long long> keys = surface.vertex_keys();
    const Vector rest = surface.rest_vertices();
    const std::vector<Vec3> anchors = surface.anchors();
    EXPECT_GT(surface.cut(cuts[step]), 0) << what;
    surface.rebuild();
    if (step == 0) {
      EXPECT_EQ(surface.pinches_closed(), 1) << what;
    }
    const SurfaceTopology topology = surface_topology(surface.triangles());
    EXPECT_TRUE(topology.watertight()) << what << ": " << topology.boundary_edges << " boundary, "
                                       << topology.nonmanifold_edges << " non-manifold";
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
