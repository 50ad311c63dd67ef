// The explicit surface cut (physics/cut/front_surface): after every blade sample of a stroke
// the surface is a closed, consistently oriented 2-manifold enclosing the body's volume
// (divergence theorem, against the uncut mesh's), split three and four ways where the
// sheet crosses it, its cut face meshed behind a front; a cut through leaves two closed pieces
// whose volumes are the analytic caps; small motions make no new triangles and what is
// behind the front stays put.
#include "physics/cut/front_surface.hpp"

#include "tests/unit/icosphere.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

using namespace incise::physics;

namespace {

using Mesh = incise::testing::SphereMesh;

// A unit icosphere (subdivided icosahedron, `levels` times), turned by a fixed rotation so
// that no vertex lies on the blade's planes below, then scaled by `radius`.
Mesh icosphere(int levels, double radius) {
  return incise::testing::icosphere(levels, radius, (Eigen::AngleAxisd(0.3, Vec3::UnitX()) * Eigen::AngleAxisd(0.2, Vec3::UnitY()) * Eigen::AngleAxisd(0.1, Vec3::UnitZ()))
          .toRotationMatrix());
}

double volume(const std::vector<Vec3>& v, const std::vector<std::array<int, 3>>& triangles) {
  double total = 0;
  for (const auto& t : triangles)
    total += v[static_cast<size_t>(t[0])].dot(v[static_cast<size_t>(t[1])].cross(v[static_cast<size_t>(t[2])])) / 6;
  return total;
}

// Closed and consistently oriented: every directed edge is used once and its reverse once;
// no triangle repeats a vertex. Returns what is wrong, empty when nothing is.
std::string closedness(const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles) {
  std::map<std::pair<int, int>, int> directed;
  for (size_t t = 0; t < triangles.size(); ++t) {
    const auto& tri = triangles[t];
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[2] == tri[0]) return "triangle " + std::to_string(t) + " repeats a vertex";
    for (const int v : tri)
      if (v < 0 || v >= static_cast<int>(vertices.size())) return "triangle " + std::to_string(t) + " names a missing vertex";
    for (int k = 0; k < 3; ++k) ++directed[{tri[static_cast<size_t>(k)], tri[static_cast<size_t>((k + 1) % 3)]}];
  }
  for (const auto& [edge, count] : directed) {
    if (count != 1) return "edge (" + std::to_string(edge.first) + ", " + std::to_string(edge.second) + ") used " + std::to_string(count) + " times";
    const auto reverse = directed.find({edge.second, edge.first});
    if (reverse == directed.end() || reverse->second != 1)
      return "edge (" + std::to_string(edge.first) + ", " + std::to_string(edge.second) + ") has no reverse";
  }
  return "";
}

// Pieces through shared vertices, and each piece's Euler characteristic V - E + F.
std::vector<std::array<double, 2>> pieces(const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles) {
  std::vector<int> parent(vertices.size());
  for (size_t v = 0; v < parent.size(); ++v) parent[v] = static_cast<int>(v);
  const auto root = [&](int v) {
    while (parent[static_cast<size_t>(v)] != v) v = parent[static_cast<size_t>(v)] = parent[static_cast<size_t>(parent[static_cast<size_t>(v)])];
    return v;
  };
  for (const auto& t : triangles) {
    parent[static_cast<size_t>(root(t[1]))] = root(t[0]);
    parent[static_cast<size_t>(root(t[2]))] = root(t[0]);
  }
  std::map<int, std::vector<std::array<int, 3>>> by_root;
  for (const auto& t : triangles) by_root[root(t[0])].push_back(t);
  std::vector<std::array<double, 2>> out;  // (volume, Euler characteristic)
  for (const auto& [r, list] : by_root) {
    std::set<int> used;
    std::set<std::pair<int, int>> edges;
    for (const auto& t : list)
      for (int k = 0; k < 3; ++k) {
        used.insert(t[static_cast<size_t>(k)]);
        edges.insert({std::min(t[static_cast<size_t>(k)], t[static_cast<size_t>((k + 1) % 3)]),
                      std::max(t[static_cast<size_t>(k)], t[static_cast<size_t>((k + 1) % 3)])});
      }
    out.push_back({volume(vertices, list),
                   static_cast<double>(used.size()) - static_cast<double>(edges.size()) + static_cast<double>(list.size())});
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a[0] < b[0]; });
  return out;
}

// Volume of the unit-radius cap beyond a plane at distance d from the centre.
double cap_volume(double radius, double d) {
  const double h = radius - d;
  return std::numbers::pi * h * h * (3 * radius - h) / 3;
}

void expect_closed_with_volume(const FrontSurface& surface, double expected_volume, const std::string& when) {
  const std::string problem = closedness(surface.vertices(), surface.triangles());
  EXPECT_EQ(problem, "") << when;
  EXPECT_NEAR(volume(surface.vertices(), surface.triangles()), expected_volume, 1e-9 * std::abs(expected_volume)) << when;
  for (const Vec3& v : surface.vertices()) ASSERT_TRUE(v.allFinite()) << when;
}

}  // namespace

TEST(FrontSurface, AStraightBladeThroughASphereLeavesTwoClosedCapsAfterEverySample) {
  const Mesh mesh = icosphere(3, 1.0);
  const double whole = volume(mesh.vertices, mesh.triangles);
  FrontSurface surface(mesh.vertices, mesh.triangles, 0.08);
  // The blade, longer than the sphere, goes down through it, tilted, in a plane x = 0.31 + 0.05 z.
  const int samples = 40;
  int split_seen = 0, lattice_seen = 0;
  for (int k = 0; k < samples; ++k) {
    const double z = 1.3 - 2.6 * k / (samples - 1);
    const std::vector<Vec3> blade{{0.31 + 0.05 * z, -1.4, z + 0.02}, {0.31 + 0.05 * z, 1.4, z - 0.02}};
    const FrontCutReport report = surface.advance(blade);
    ASSERT_TRUE(report.ok()) << "sample " << k << ": " << report.problems.front();
    expect_closed_with_volume(surface, whole, "sample " + std::to_string(k));
    split_seen = std::max(split_seen, report.split_triangles);
    lattice_seen = std::max(lattice_seen, report.lattice_vertices);
    const auto parts = pieces(surface.vertices(), surface.triangles());
    if (k < samples - 1 && report.tips > 0) {
      // Cut part way: one piece, a sphere with a pocket (Euler characteristic 2).
      ASSERT_EQ(parts.size(), 1u) << "sample " << k;
      EXPECT_EQ(parts[0][1], 2) << "sample " << k;
    }
  }
  EXPECT_GT(split_seen, 20);
  EXPECT_GT(lattice_seen, 50);
  // Through: two closed pieces, each a sphere topologically, with the caps' volumes.
  const auto parts = pieces(surface.vertices(), surface.triangles());
  ASSERT_EQ(parts.size(), 2u);
  EXPECT_EQ(parts[0][1], 2);
  EXPECT_EQ(parts[1][1], 2);
  // The plane's distance from the centre, in the sphere's frame: x - 0.05 z = 0.31.
  const double d = 0.31 / std::sqrt(1 + 0.05 * 0.05);
  const double discretisation = 1 - whole / (4 * std::numbers::pi / 3);  // the polyhedron's missing volume
  EXPECT_NEAR(parts[0][0] / cap_volume(1.0, d), 1.0, 2 * discretisation + 0.01);
  EXPECT_NEAR(parts[0][0] + parts[1][0], whole, 1e-9 * whole);
  // The cut faces: flagged, on the blade's plane, together twice the section's area.
  ASSERT_EQ(surface.on_cut_face().size(), surface.triangles().size());
  double face_area = 0;
  for (size_t t = 0; t < surface.triangles().size(); ++t) {
    if (!surface.on_cut_face()[t]) continue;
    const auto& tri = surface.triangles()[t];
    for (const int v : tri) {
      const Vec3& x = surface.vertices()[static_cast<size_t>(v)];
      // The blade translates, rolled: its sheet is the plane x = 0.31 + 0.05 (z + y / 70).
      EXPECT_NEAR(x.x() - 0.05 * (x.z() + x.y() / 70), 0.31, 1e-9) << "cut-face vertex " << v << " off the blade's plane";
    }
    face_area += 0.5 * (surface.vertices()[static_cast<size_t>(tri[1])] - surface.vertices()[static_cast<size_t>(tri[0])])
                           .cross(surface.vertices()[static_cast<size_t>(tri[2])] - surface.vertices()[static_cast<size_t>(tri[0])])
                           .norm();
  }
  EXPECT_NEAR(face_area / (2 * std::numbers::pi * (1 - d * d)), 1.0, 2 * discretisation + 0.01);
}

// Every constraint plane faces away from its vertex's side: once the flat cut is through, the
// vertex's neighbours on the surface (its side, by construction of the pairs) lie below it.
// (Near a crack tip they need not: a plane is infinite, the cut is not.)
// The blade mapped to rest wavers (its mapping moves a little where the topology changed):
// a sheet that zigzags across its mean plane crosses edges lying nearly in that plane back
// and forth. Those edges are left uncut; the stroke goes on and ends in two closed pieces.
TEST(FrontSurface, ASheetThatFoldsBackOverAnEdgeLeavesItUncutAndGoesOn) {
  const Mesh mesh = icosphere(3, 1.0);
  const double whole = volume(mesh.vertices, mesh.triangles);
  FrontSurface surface(mesh.vertices, mesh.triangles, 0.08);
  const int samples = 60;
  int folded = 0;
  for (int k = 0; k < samples; ++k) {
    const double z = 1.3 - 2.6 * k / (samples - 1);
    const double x = 0.31 + (k % 2 == 0 ? 1 : -1) * 0.02;
    const FrontCutReport report = surface.advance(std::vector<Vec3>{{x, -1.4, z}, {x, 1.4, z}});
    ASSERT_TRUE(report.ok()) << "sample " << k << ": " << report.problems.front();
    expect_closed_with_volume(surface, whole, "sample " + std::to_string(k));
    folded = std::max(folded, report.folded_edges);
  }
  EXPECT_GT(folded, 2);  // 10 here
  const auto parts = pieces(surface.vertices(), surface.triangles());
  ASSERT_EQ(parts.size(), 2u);
  EXPECT_EQ(parts[0][1], 2);
  EXPECT_EQ(parts[1][1], 2);
  const double discretisation = 1 - whole / (4 * std::numbers::pi / 3);
  EXPECT_NEAR(parts[0][0] / cap_volume(1.0, 0.31), 1.0, 2 * discretisation + 0.01);
}

// A stroke that ends with its front just short of the far side (the blade's image at rest
// extrapolates outside the body) is carried through when it ends with a reach; one that
// ends deep in the body is not.
TEST(FrontSurface, AStrokeEndingJustShortOfTheFarSideIsCarriedThroughOneEndingDeepIsNot) {
  const Mesh mesh = icosphere(3, 1.0);
  const double whole = volume(mesh.vertices, mesh.triangles);
  // The sphere's polyhedron reaches z = -0.95 or a little less on the plane x = 0.31.
  for (const double stop : {-0.93, -0.5}) {
    FrontSurface surface(mesh.vertices, mesh.triangles, 0.08);
    FrontCutReport last;
    for (double z = 1.3; z >= stop - 1e-12; z -= 0.05) last = surface.advance(std::vector<Vec3>{{0.31, -1.4, z}, {0.31, 1.4, z}});
    ASSERT_TRUE(last.ok()) << last.problems.front();
    ASSERT_TRUE(last.front_in_body) << "stop " << stop;
    const bool carried = surface.end_stroke(0.08);
    EXPECT_EQ(carried, stop < -0.9) << "stop " << stop;
    expect_closed_with_volume(surface, whole, "stop " + std::to_string(stop));
    EXPECT_EQ(pieces(surface.vertices(), surface.triangles()).size(), stop < -0.9 ? 2u : 1u) << "stop " << stop;
    // Cut through, no crack is left; else the crack stays inside, its vertices still where
    // the two sides meet in the next stroke's base.
    const long crack = std::count(surface.crack_front().begin(), surface.crack_front().end(), 1);
    if (stop < -0.9)
      EXPECT_EQ(crack, 0);
    else
      EXPECT_GT(crack, 10);
  }
}

TEST(FrontSurface, ConstraintPlanesFaceAwayFromTheirVertexsSide) {
  const Mesh mesh = icosphere(3, 1.0);
  FrontSurface surface(mesh.vertices, mesh.triangles, 0.08);
  for (int k = 0; k <= 30; ++k) {
    const double z = 1.3 - 2.6 * k / 30;
    ASSERT_TRUE(surface.advance(std::vector<Vec3>{{0.27, -1.4, z}, {0.33, 1.4, z}}).ok());
  }
  const auto& planes = surface.vertex_planes();
  ASSERT_EQ(planes.size(), surface.vertices().size());
  std::vector<std::set<int>> ring(surface.vertices().size());
  for (const auto& t : surface.triangles())
    for (int k = 0; k < 3; ++k) ring[static_cast<size_t>(t[static_cast<size_t>(k)])].insert(t[static_cast<size_t>((k + 1) % 3)]);
  int with_planes = 0, base_with_planes = 0, checked = 0;
  for (size_t v = 0; v < planes.size(); ++v) {
    if (planes[v].empty()) continue;
    ++with_planes;
    base_with_planes += static_cast<int>(v) < surface.base_vertex_count();
    for (const ConstraintPlane& plane : planes[v]) {
      EXPECT_NEAR(plane.normal.norm(), 1.0, 1e-12);
      for (const int n : ring[v]) {
        EXPECT_LE((surface.vertices()[static_cast<size_t>(n)] - plane.point).dot(plane.normal), 1e-12) << "vertex " << v << " neighbour " << n;
        ++checked;
      }
    }
  }
  // A vertex inside a cut face (every triangle of it on the face) has the face's outward
  // normal, which is its plane's: the side it must stay on is behind both.
  std::vector<Vec3> normal_sum(surface.vertices().size(), Vec3::Zero());
  std::vector<int> off_face(surface.vertices().size(), 0);
  for (size_t t = 0; t < surface.triangles().size(); ++t) {
    const auto& tri = surface.triangles()[t];
    const Vec3 n = (surface.vertices()[static_cast<size_t>(tri[1])] - surface.vertices()[static_cast<size_t>(tri[0])])
                       .cross(surface.vertices()[static_cast<size_t>(tri[2])] - surface.vertices()[static_cast<size_t>(tri[0])]);
    for (const int v : tri) {
      normal_sum[static_cast<size_t>(v)] += n;
      off_face[static_cast<size_t>(v)] += surface.on_cut_face()[t] ? 0 : 1;
    }
  }
  int inner = 0;
  for (size_t v = 0; v < planes.size(); ++v) {
    if (planes[v].size() != 1 || off_face[v] > 0) continue;
    ++inner;
    EXPECT_GT(normal_sum[v].normalized().dot(planes[v][0].normal), 0.99) << "vertex " << v;
  }
  EXPECT_GT(inner, 50);
  EXPECT_GT(base_with_planes, 20);
  EXPECT_GT(with_planes, 200);
  EXPECT_GT(checked, 1000);
  // The base vertices keep theirs into the next stroke.
  surface.end_stroke();
  int kept = 0;
  for (size_t v = 0; v < static_cast<size_t>(mesh.vertices.size()); ++v) kept += !surface.vertex_planes()[v].empty();
  EXPECT_EQ(kept, base_with_planes);
}

TEST(FrontSurface, ABladeShorterThanTheBodyLeavesAPocketClosedAlongItsEnds) {
  const Mesh mesh = icosphere(3, 1.0);
  const double whole = volume(mesh.vertices, mesh.triangles);
  FrontSurface surface(mesh.vertices, mesh.triangles, 0.07);
  for (int k = 0; k < 30; ++k) {
    const double z = 1.25 - 1.6 * k / 29;
    const std::vector<Vec3> blade{{-0.1, -0.42, z}, {0.05, 0.0, z - 0.03}, {-0.08, 0.45, z + 0.01}};
    const FrontCutReport report = surface.advance(blade);
    ASSERT_TRUE(report.ok()) << "sample " << k << ": " << report.problems.front();
    expect_closed_with_volume(surface, whole, "sample " + std::to_string(k));
    const auto parts = pieces(surface.vertices(), surface.triangles());
    ASSERT_EQ(parts.size(), 1u);
    EXPECT_EQ(parts[0][1], 2) << "sample " << k;
  }
  surface.end_stroke();
  expect_closed_with_volume(surface, whole, "after the stroke");
}

TEST(FrontSurface, ATwistingCurvedBladeKeepsTheSurfaceClosed) {
  const Mesh mesh = icosphere(3, 1.0);
  const double whole = volume(mesh.vertices, mesh.triangles);
  FrontSurface surface(mesh.vertices, mesh.triangles, 0.06);
  const int samples = 45;
  for (int k = 0; k < samples; ++k) {
    const double f = static_cast<double>(k) / (samples - 1);
    const double z = 1.3 - 2.6 * f, twist = 0.5 * f;
    std::vector<Vec3> blade;
    for (int i = 0; i < 6; ++i) {
      const double y = -1.5 + 3.0 * i / 5;
      const Vec3 p(0.15 * std::cos(1.2 * y), y, z + 0.1 * y * y);
      blade.push_back(Eigen::AngleAxisd(twist, Vec3::UnitZ()) * p);
    }
    const FrontCutReport report = surface.advance(blade);
    ASSERT_TRUE(report.ok()) << "sample " << k << ": " << report.problems.front();
    expect_closed_with_volume(surface, whole, "sample " + std::to_string(k));
  }
  const auto parts = pieces(surface.vertices(), surface.triangles());
  ASSERT_EQ(parts.size(), 2u);
  EXPECT_NEAR(parts[0][0] + parts[1][0], whole, 1e-9 * whole);
}

TEST(FrontSurface, AStabInsideOneTriangleOpensASlitClosedAtBothEnds) {
  const Mesh mesh = icosphere(2, 1.0);  // triangles about 0.3 across
  const double whole = volume(mesh.vertices, mesh.triangles);
  // A short blade at the centre of a triangle, pushed in along its normal.
  const auto& t = mesh.triangles[7];
  const Vec3 a = mesh.vertices[static_cast<size_t>(t[0])], b = mesh.vertices[static_cast<size_t>(t[1])],
             c = mesh.vertices[static_cast<size_t>(t[2])];
  const Vec3 centre = (a + b + c) / 3, normal = (b - a).cross(c - a).normalized();
  const Vec3 along = (b - a).normalized() * 0.04;
  FrontSurface surface(mesh.vertices, mesh.triangles, 0.02);
  int slit = 0;
  for (int k = 0; k < 12; ++k) {
    const Vec3 at = centre + normal * (0.03 - 0.01 * k);
    const std::vector<Vec3> blade{at - along, at + along};
    const FrontCutReport report = surface.advance(blade);
    ASSERT_TRUE(report.ok()) << "sample " << k << ": " << report.problems.front();
    expect_closed_with_volume(surface, whole, "sample " + std::to_string(k));
    if (report.tips == 2 && report.crossings == 0) ++slit;
  }
  EXPECT_GT(slit, 5);  // the slit case did happen
  // Every vertex the stroke made, but for the crack front's, has a plane facing away from its
  // side (the slit's middle pair too), with its neighbours behind it.
  std::vector<std::set<int>> ring(surface.vertices().size());
  for (const auto& tri : surface.triangles())
    for (int k = 0; k < 3; ++k) ring[static_cast<size_t>(tri[static_cast<size_t>(k)])].insert(tri[static_cast<size_t>((k + 1) % 3)]);
  int made = 0;
  for (size_t v = static_cast<size_t>(surface.base_vertex_count()); v < surface.vertices().size(); ++v) {
    if (surface.crack_front()[v] || ring[v].empty()) continue;
    ++made;
    ASSERT_FALSE(surface.vertex_planes()[v].empty()) << "vertex " << v;
    for (const ConstraintPlane& plane : surface.vertex_planes()[v])
      for (const int n : ring[v])
        EXPECT_LE((surface.vertices()[static_cast<size_t>(n)] - plane.point).dot(plane.normal), 1e-9) << "vertex " << v << " neighbour " << n;
  }
  EXPECT_GT(made, 2);
}

// The slit's pieces around the tips: which of the base triangle's two far corners faces which
// tip follows from the side of the slit the lone corner is on. On an obtuse triangle the far
// corners' own order along the slit says the opposite, and pairing them by it made two pieces
// overlap, an edge used twice the same way: the stroke's surface then could not become the base
// (`incise bench haptics` stopped with "edge (..) is not used exactly once in each direction").
TEST(FrontSurface, AStabInAnObtuseTriangleKeepsTheSurfaceClosedWhicheverWayTheSlitRuns) {
  // A tetrahedron whose top face (z = 0, facing up) is long and obtuse: the line y = 0 crosses
  // it from x = 0.57 (edge P-R) to x = 5 (edge P-Q), while R lies further along x than Q.
  const Vec3 p{0, 1, 0}, q{10, -1, 0}, r{12, -20, 0}, d{7, -6, -5};
  const std::vector<Vec3> vertices{p, q, r, d};
  const std::vector<std::array<int, 3>> triangles{{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {2, 0, 3}};
  const double whole = volume(vertices, triangles);
  ASSERT_GT(whole, 0);
  for (const bool reversed : {false, true}) {
    const std::string way = reversed ? "blade -x: " : "blade +x: ";
    FrontSurface surface(vertices, triangles, 0.5);
    int slit = 0;
    // A blade along y = 0, from x = 1.5 to 4, pushed down through the top face, not deep
    // enough to reach another face: both its ends pierce the top triangle, no edge is cut.
    for (int k = 0; k < 8; ++k) {
      const double z = 0.3 - 0.05 * k;
      std::vector<Vec3> blade{{1.5, 0, z}, {4, 0, z}};
      if (reversed) std::swap(blade[0], blade[1]);
      const FrontCutReport report = surface.advance(blade);
      ASSERT_TRUE(report.ok()) << way << "sample " << k << ": " << report.problems.front();
      expect_closed_with_volume(surface, whole, way + "sample " + std::to_string(k));
      if (report.tips == 2 && report.crossings == 0) ++slit;
    }
    EXPECT_GT(slit, 0) << way << "the slit case did happen";
    ASSERT_NO_THROW(surface.end_stroke()) << way;
    EXPECT_EQ(surface.end_problem(), "") << way << "the stroke's surface became the base";
    expect_closed_with_volume(surface, whole, way + "after the stroke");
    EXPECT_GT(surface.base_vertex_count(), 4) << way << "the slit's vertices are base ones now";
  }
}

TEST(FrontSurface, SmallMotionsMakeNoNewTrianglesAndWhatIsBehindTheFrontStaysPut) {
  const Mesh mesh = icosphere(3, 1.0);
  FrontSurface surface(mesh.vertices, mesh.triangles, 0.08);
  const auto blade_at = [](double z) { return std::vector<Vec3>{{0.2, -1.4, z}, {0.25, 1.4, z}}; };
  for (int k = 0; k < 12; ++k) surface.advance(blade_at(1.3 - 0.1 * k));
  const auto before = surface.triangles();
  const auto vertices_before = surface.vertices();
  // A motion far below the front's width.
  const FrontCutReport report = surface.advance(blade_at(1.3 - 0.1 * 11 - 1e-4));
  ASSERT_TRUE(report.ok());
  EXPECT_EQ(surface.triangles().size(), before.size());
  // Going on by several widths: every lattice vertex of before (away from the front) is
  // still there, at the same place.
  for (int k = 0; k < 5; ++k) surface.advance(blade_at(1.3 - 1.1 - 0.1 * (k + 1)));
  std::set<std::array<double, 3>> now;
  for (const Vec3& v : surface.vertices()) now.insert({v.x(), v.y(), v.z()});
  int kept = 0, checked = 0;
  const double front_z = 1.3 - 1.1;
  for (size_t v = static_cast<size_t>(surface.base_vertex_count()); v < vertices_before.size(); ++v) {
    if (vertices_before[v].z() < front_z + 0.25) continue;  // near the front then
    ++checked;
    kept += now.count({vertices_before[v].x(), vertices_before[v].y(), vertices_before[v].z()}) > 0;
  }
  EXPECT_GT(checked, 20);
  EXPECT_EQ(kept, checked);
}

// A blade paused in the body still moves at rest by the solver's roundoff. A sample of that
// jitter would set the direction the next samples must follow (a sample against the last
// motion is held): sideways, against a blade coming down on a slant, it held every later one
// and the front froze (the default scene on the GPU in single precision). Motions below a
// hundredth of w are not samples.
TEST(FrontSurface, ABladePausedInTheBodyThatJittersByRoundoffDoesNotStopTheFront) {
  const Mesh mesh = icosphere(3, 1.0);
  const double w = 0.08;
  FrontSurface surface(mesh.vertices, mesh.triangles, w);
  const auto blade_at = [](double x, double z) { return std::vector<Vec3>{{x, -1.4, z + 0.02}, {x + 0.04, 1.4, z - 0.02}}; };
  const auto z_of = [](int k) { return 1.3 - 2.6 * k / 39; };
  // Straight down, a pause, then on down at a slant (x growing half as fast as z falls).
  for (int k = 0; k < 16; ++k) ASSERT_TRUE(surface.advance(blade_at(0.2, z_of(k))).ok());
  // The pause's jitter: a hair further down (so it is taken as going on) and back in x,
  // against the slant to come.
  const double jitter = 1e-4 * w;
  ASSERT_TRUE(surface.advance(blade_at(0.2 - jitter, z_of(15) - 0.1 * jitter)).ok());
  for (int k = 16; k < 40; ++k) {
    const FrontCutReport report = surface.advance(blade_at(0.2 + 0.5 * (z_of(15) - z_of(k)), z_of(k)));
    ASSERT_TRUE(report.ok()) << "sample " << k << ": " << report.problems.front();
    EXPECT_EQ(report.samples_held, 0) << "sample " << k;
  }
  surface.end_stroke();
  EXPECT_EQ(pieces(surface.vertices(), surface.triangles()).size(), 2u);
}

TEST(FrontSurface, ASecondStrokeCutsBesideTheFirst) {
  const Mesh mesh = icosphere(3, 1.0);
  const double whole = volume(mesh.vertices, mesh.triangles);
  FrontSurface surface(mesh.vertices, mesh.triangles, 0.08);
  for (const double x : {-0.35, 0.3}) {
    for (int k = 0; k < 20; ++k) {
      const double z = 1.3 - 1.5 * k / 19;
      const FrontCutReport report = surface.advance(std::vector<Vec3>{{x, -1.4, z}, {x + 0.02, 1.4, z}});
      ASSERT_TRUE(report.ok()) << "x " << x << " sample " << k << ": " << report.problems.front();
      expect_closed_with_volume(surface, whole, "x " + std::to_string(x) + " sample " + std::to_string(k));
    }
    surface.end_stroke();
    expect_closed_with_volume(surface, whole, "after the stroke at x " + std::to_string(x));
  }
}

TEST(FrontSurface, AStrokeBeginsAtTheLastSampleBeforeTheBladeMeetsTheBody) {
  const Mesh mesh = icosphere(3, 1.0);
  const double whole = volume(mesh.vertices, mesh.triangles);
  FrontSurface surface(mesh.vertices, mesh.triangles, 0.08);
  const auto blade_at = [](double z) { return std::vector<Vec3>{{0.1, -1.4, z}, {0.12, 1.4, z}}; };
  for (int k = 0; k < 10; ++k) {
    const FrontCutReport report = surface.advance(blade_at(3.0 - 0.15 * k));  // down to z = 1.65, outside
    EXPECT_FALSE(report.front_in_body);
    EXPECT_EQ(surface.stroke_samples(), 1);
  }
  bool was_in = false;
  for (int k = 0; k < 40; ++k) {
    const FrontCutReport report = surface.advance(blade_at(1.5 - 0.08 * k));  // through, out at z = -1.6
    ASSERT_TRUE(report.ok()) << report.problems.front();
    expect_closed_with_volume(surface, whole, "sample " + std::to_string(k));
    const double z = 1.5 - 0.08 * k;
    // In the body while the blade's line crosses the sphere (the polyhedron is inside it).
    if (std::abs(z) < 0.9) {
      EXPECT_TRUE(report.front_in_body) << z;
    }
    if (std::abs(z) > 1.0) {
      EXPECT_FALSE(report.front_in_body) << z;
    }
    was_in = was_in || report.front_in_body;
  }
  EXPECT_TRUE(was_in);
  EXPECT_EQ(pieces(surface.vertices(), surface.triangles()).size(), 2u);
  EXPECT_LT(surface.stroke_samples(), 40);  // it began near the body, not at z = 3
}

TEST(FrontSurface, ABladeThatGoesBackOverItsCutLeavesTheSurfaceAsIfItHadNot) {
  const Mesh mesh = icosphere(3, 1.0);
  const auto blade_at = [](double z) { return std::vector<Vec3>{{0.2, -1.4, z}, {0.24, 1.4, z}}; };
  FrontSurface straight(mesh.vertices, mesh.triangles, 0.08), sawing(mesh.vertices, mesh.triangles, 0.08);
  int held = 0;
  for (int k = 0; k < 25; ++k) {
    const double z = 1.3 - 0.1 * k;
    ASSERT_TRUE(straight.advance(blade_at(z)).ok());
    ASSERT_TRUE(sawing.advance(blade_at(z)).ok());
    if (k > 2 && k % 3 == 0) {
      // Back up by half a step and a little more, then down again to the same place.
      held += sawing.advance(blade_at(z + 0.05)).samples_held;
      held += sawing.advance(blade_at(z + 0.08)).samples_held;
      ASSERT_TRUE(sawing.advance(blade_at(z)).ok());
    }
    ASSERT_EQ(sawing.triangles(), straight.triangles()) << "sample " << k;
    ASSERT_EQ(sawing.vertices(), straight.vertices()) << "sample " << k;
  }
  EXPECT_GT(held, 10);
}

TEST(FrontSurface, ASampleItCannotCutIsLeftOutAndTheCutSoFarStays) {
  const Mesh mesh = icosphere(3, 1.0);
  const double whole = volume(mesh.vertices, mesh.triangles);
  FrontSurface surface(mesh.vertices, mesh.triangles, 0.08);
  const auto blade_at = [](double z, double turn) {
    const Eigen::AngleAxisd r(turn, Vec3::UnitZ());
    return std::vector<Vec3>{r * Vec3(0.1, -1.4, z), r * Vec3(0.12, 1.4, z)};
  };
  for (int k = 0; k < 14; ++k) ASSERT_TRUE(surface.advance(blade_at(1.3 - 0.1 * k, 0)).ok());
  const auto triangles = surface.triangles();
  const auto vertices = surface.vertices();
  // Turned a quarter round: the new strip crosses the stroke's own sheet.
  const FrontCutReport report = surface.advance(blade_at(1.3 - 0.1 * 14, 1.5));
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.samples_held, 1);
  EXPECT_EQ(surface.triangles(), triangles);
  EXPECT_EQ(surface.vertices(), vertices);
  expect_closed_with_volume(surface, whole, "after the sample left out");
  // The blade comes back in line and goes on: the stroke carries on from its last good sample.
  const FrontCutReport on = surface.advance(blade_at(1.3 - 0.1 * 14, 0));
  ASSERT_TRUE(on.ok()) << on.problems.front();
  EXPECT_GT(surface.triangles().size(), triangles.size());
  expect_closed_with_volume(surface, whole, "going on");
}

TEST(FrontSurface, ReportsWhatItCannotCutInsteadOfOpeningTheSurface) {
  const Mesh mesh = icosphere(3, 1.0);
  const double whole = volume(mesh.vertices, mesh.triangles);
  FrontSurface surface(mesh.vertices, mesh.triangles, 0.08);
  // A stroke that begins inside the body.
  surface.advance(std::vector<Vec3>{{0.1, -1.4, 0.2}, {0.1, 1.4, 0.2}});
  const FrontCutReport report = surface.advance(std::vector<Vec3>{{0.1, -1.4, 0.1}, {0.1, 1.4, 0.1}});
  ASSERT_FALSE(report.ok());
  EXPECT_NE(report.problems.front().find("inside the body"), std::string::npos) << report.problems.front();
  expect_closed_with_volume(surface, whole, "after the refused stroke");
  EXPECT_EQ(surface.triangles().size(), mesh.triangles.size());
}

TEST(FrontSurface, RejectsBadInputNamingIt) {
  const Mesh mesh = icosphere(1, 1.0);
  const auto message = [](auto&& make) {
    try {
      make();
    } catch (const std::invalid_argument& error) {
      return std::string(error.what());
    }
    return std::string("no exception");
  };
  auto open = mesh.triangles;
  open.pop_back();
  EXPECT_NE(message([&] { FrontSurface(mesh.vertices, open, 0.1); }).find("edge ("), std::string::npos);
  auto nan = mesh.vertices;
  nan[5].y() = std::nan("");
  EXPECT_NE(message([&] { FrontSurface(nan, mesh.triangles, 0.1); }).find("vertex 5"), std::string::npos);
  EXPECT_NE(message([&] { FrontSurface(mesh.vertices, mesh.triangles, 0.0); }).find("front_width"), std::string::npos);
  auto out_of_range = mesh.triangles;
  out_of_range[3][1] = 999;
  EXPECT_NE(message([&] { FrontSurface(mesh.vertices, out_of_range, 0.1); }).find("triangle 3"), std::string::npos);
  FrontSurface surface(mesh.vertices, mesh.triangles, 0.1);
  surface.advance(std::vector<Vec3>{{0, -2, 2}, {0, 2, 2}});
  EXPECT_NE(message([&] { surface.advance(std::vector<Vec3>{{0, -2, 1}, {0, 0, 1}, {0, 2, 1}}); }).find("3 points"), std::string::npos);
  EXPECT_NE(message([&] { surface.advance(std::vector<Vec3>{{0, -2, 1}, {0, std::nan(""), 1}}); }).find("blade point 1"),
            std::string::npos);
  EXPECT_EQ(surface.stroke_samples(), 1);
}

TEST(FrontSurface, WhatAStrokeLeavesAloneKeepsItsSlotAndIndexAndTheChangeIsListed) {
  // A user follows the stroke's change instead of the whole surface (front_surface.hpp): the
  // base's triangles keep their slots but for replaced_slots(), its vertices their index, flags
  // and planes but for planed_base_vertices(); base_triangles_around and base_cut_face_slots
  // are the base's. Checked after every sample of two strokes (the second's base holds the
  // first's cut), one of whose samples is left out.
  const Mesh mesh = icosphere(3, 1.0);
  FrontSurface surface(mesh.vertices, mesh.triangles, 0.08);
  const auto blade_at = [](double x, double z, double turn) {
    const Eigen::AngleAxisd r(turn, Vec3::UnitZ());
    return std::vector<Vec3>{r * Vec3(x, -1.4, z), r * Vec3(x + 0.02, 1.4, z)};
  };
  int samples = 0, replaced = 0;
  for (const double x : {-0.3, 0.25}) {
    const std::vector<Vec3> base_vertices = surface.vertices();
    const std::vector<std::array<int, 3>> base_triangles = surface.triangles();
    const std::vector<std::vector<ConstraintPlane>> base_planes = surface.vertex_planes().lists();
    const std::vector<std::uint8_t> base_crack = surface.crack_front(), base_face = surface.on_cut_face();
    ASSERT_EQ(surface.base_triangle_count(), static_cast<int>(base_triangles.size()));
    ASSERT_EQ(surface.base_vertex_count(), static_cast<int>(base_vertices.size()));
    std::vector<std::vector<int>> around(base_vertices.size());
    std::vector<int> faces;
    for (size_t t = 0; t < base_triangles.size(); ++t) {
      for (const int v : base_triangles[t]) around[static_cast<size_t>(v)].push_back(static_cast<int>(t));
      if (base_face[t]) faces.push_back(static_cast<int>(t));
    }
    for (size_t v = 0; v < around.size(); ++v) {
      const auto listed = surface.base_triangles_around(static_cast<int>(v));
      ASSERT_EQ(std::vector<int>(listed.begin(), listed.end()), around[v]) << "vertex " << v;
    }
    ASSERT_EQ(surface.base_cut_face_slots(), faces);
    if (x > 0) {
      EXPECT_FALSE(faces.empty());  // the first stroke's faces
    }
    for (int k = 0; k < 24; ++k) {
      const double z = 1.3 - 0.1 * k;
      surface.advance(blade_at(x, z, 0));
      if (k == 12) {
        EXPECT_FALSE(surface.advance(blade_at(x, z - 0.1, 1.5)).ok());  // left out
      }
      ++samples;
      const auto& slots = surface.replaced_slots();
      ASSERT_TRUE(std::is_sorted(slots.begin(), slots.end()));
      replaced += static_cast<int>(slots.size());
      std::vector<std::uint8_t> is_replaced(base_triangles.size(), 0);
      for (const int s : slots) is_replaced[static_cast<size_t>(s)] = 1;
      ASSERT_GE(surface.triangles().size(), base_triangles.size());
      for (size_t t = 0; t < base_triangles.size(); ++t) {
        if (is_replaced[t]) continue;
        ASSERT_EQ(surface.triangles()[t], base_triangles[t]) << "x " << x << " sample " << k << " slot " << t;
        ASSERT_EQ(surface.on_cut_face()[t], base_face[t]) << "x " << x << " sample " << k << " slot " << t;
      }
      const auto& planed = surface.planed_base_vertices();
      for (size_t v = 0; v < base_vertices.size(); ++v) {
        ASSERT_EQ(surface.vertices()[v], base_vertices[v]);
        ASSERT_EQ(surface.crack_front()[v], base_crack[v]);
        if (std::binary_search(planed.begin(), planed.end(), static_cast<int>(v))) {
          // One plane per cut edge at the vertex, at most one per edge (as many as triangles).
          ASSERT_GT(surface.vertex_planes()[v].size(), base_planes[v].size()) << "vertex " << v;
          ASSERT_LE(surface.vertex_planes()[v].size(), base_planes[v].size() + around[v].size())
              << "x " << x << " sample " << k << " vertex " << v;
          continue;
        }
        ASSERT_EQ(surface.vertex_planes()[v].size(), base_planes[v].size()) << "x " << x << " sample " << k << " vertex " << v;
      }
    }
    surface.end_stroke();
  }
  EXPECT_GT(replaced, samples);  // the strokes did replace triangles
}

// What lies well behind the front is kept from the last sample's cut face instead of being
// triangulated again (FrontSurface::reuse_face): the surface is the same, to the bit, as when
// the whole face is triangulated at every sample, and the reuse is not idle.
TEST(FrontSurface, KeepingTheFaceBehindTheFrontGivesTheSurfaceOfTriangulatingItWhole) {
  const Mesh mesh = icosphere(3, 1.0);
  const auto same_surface = [](const FrontSurface& kept, const FrontSurface& whole, const std::string& when) {
    ASSERT_EQ(kept.vertices(), whole.vertices()) << when;
    ASSERT_EQ(kept.triangles(), whole.triangles()) << when;
    ASSERT_EQ(kept.crack_front(), whole.crack_front()) << when;
    ASSERT_EQ(kept.vertex_planes().size(), whole.vertex_planes().size()) << when;
    for (size_t v = 0; v < kept.vertex_planes().size(); ++v) {
      ASSERT_EQ(kept.vertex_planes()[v].size(), whole.vertex_planes()[v].size()) << when;
      for (size_t p = 0; p < kept.vertex_planes()[v].size(); ++p) {
        ASSERT_EQ(kept.vertex_planes()[v][p].point, whole.vertex_planes()[v][p].point) << when;
        ASSERT_EQ(kept.vertex_planes()[v][p].normal, whole.vertex_planes()[v][p].normal) << when;
      }
    }
  };
  // A curved blade, twisting and going on after a pause, then a second stroke beside it.
  FrontSurface kept(mesh.vertices, mesh.triangles, 0.05), whole(mesh.vertices, mesh.triangles, 0.05);
  whole.reuse_face(false);
  long kept_triangles = 0, face_triangles = 0;
  const auto blade = [](double z, double twist, double x) {
    std::vector<Vec3> points;
    for (int i = 0; i < 6; ++i) {
      const double y = -1.5 + 3.0 * i / 5;
      points.push_back(Eigen::AngleAxisd(twist, Vec3::UnitZ()) * Vec3(x + 0.15 * std::cos(1.2 * y), y, z + 0.1 * y * y));
    }
    return points;
  };
  for (int stroke = 0; stroke < 2; ++stroke) {
    const int samples = 70;
    for (int k = 0; k < samples; ++k) {
      const double f = static_cast<double>(k) / (samples - 1);
      // Held for three samples a third of the way down (the same sample: left as it is).
      const double g = k < 23 ? f : k < 26 ? 22.0 / (samples - 1) : f;
      const auto points = blade(1.3 - 2.6 * g, 0.4 * g, stroke == 0 ? 0.0 : 0.4);
      const FrontCutReport a = kept.advance(points), b = whole.advance(points);
      const std::string when = "stroke " + std::to_string(stroke) + ", sample " + std::to_string(k);
      ASSERT_EQ(a.ok(), b.ok()) << when;
      ASSERT_EQ(b.face_triangles_kept, 0) << when;
      kept_triangles += a.face_triangles_kept;
      face_triangles += a.cut_face_triangles;
      same_surface(kept, whole, when);
      if (testing::Test::HasFatalFailure()) return;
    }
    kept.end_stroke();
    whole.end_stroke();
    same_surface(kept, whole, "after stroke " + std::to_string(stroke));
  }
  std::printf("cut-face triangles kept from the last sample: %ld of %ld\n", kept_triangles, face_triangles);
  EXPECT_GT(kept_triangles, face_triangles / 2);
}
