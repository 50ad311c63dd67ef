// The cut's supporting pieces (physics/cut/): the voxel boundary a cuttable body's surface
// starts from (closed, enclosing the body, snapped as the whole voxel mesh would be), the
// surface topology counts, and the linked-across check kept up to date as the rest cut grows.
#include "physics/cut/linked_across.hpp"
#include "physics/cut/rest_cut.hpp"
#include "physics/cut/surface_topology.hpp"
#include "physics/cut/voxel_boundary.hpp"
#include "physics/fem/surface_snap.hpp"
#include "physics/fem/tet_mesh.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

using namespace incise::physics;

namespace {

// Signed volume enclosed by a closed triangle mesh (divergence theorem).
double enclosed_volume(const std::vector<Vec3>& x, const std::vector<std::array<int, 3>>& triangles) {
  double volume = 0;
  for (const auto& t : triangles) volume += x[t[0]].dot(x[t[1]].cross(x[t[2]])) / 6.0;
  return volume;
}

const auto in_box = [](const Vec3& p) {
  return p.x() >= 0 && p.x() <= 0.1 && std::abs(p.y()) <= 0.01 && std::abs(p.z()) <= 0.01;
};

// The EFG model of the bar in_box describes (a = 2.5 mm, single-threaded).
CorotationalEfg bar_model() {
  EfgSettings settings;
  settings.spacing = 0.0025;
  settings.threaded_elements = 0;
  return CorotationalEfg(Vec3(0, -0.01, -0.01), Vec3(0.1, 0.01, 0.01), Material{1e5, 0.3, 1000}, settings);
}

}  // namespace

TEST(VoxelBoundary, IsClosedAndEnclosesTheBody) {
  const TriangleSurface surface = voxel_boundary(in_box, Vec3(0, -0.01, -0.01), Vec3(0.1, 0.01, 0.01), 0.0025);
  const SurfaceTopology topology = surface_topology(surface.triangles);
  EXPECT_TRUE(topology.watertight()) << topology.boundary_edges << " boundary, " << topology.nonmanifold_edges << " non-manifold";
  // 40 x 8 x 8 cubes: 2 (40 x 8 + 40 x 8 + 8 x 8) faces, 2 triangles each.
  EXPECT_EQ(surface.triangles.size(), 2u * 2u * (320u + 320u + 64u));
  EXPECT_NEAR(enclosed_volume(surface.vertices, surface.triangles), 0.1 * 0.02 * 0.02, 1e-9);
}

// The count over the edges between flagged vertices: every use of such an edge is counted
// (the triangles around it may have unflagged corners), edges with an unflagged end are not.
TEST(SurfaceTopology, TheCountAmongFlaggedVerticesTakesTheirEdgesOnly) {
  const TriangleSurface surface = voxel_boundary(in_box, Vec3(0, -0.01, -0.01), Vec3(0.1, 0.01, 0.01), 0.0025);
  std::vector<std::array<int, 3>> triangles = surface.triangles;
  const int vertices = static_cast<int>(surface.vertices.size());
  const std::array<int, 3> hole = triangles[17];
  triangles.erase(triangles.begin() + 17);
  ASSERT_EQ(surface_topology(triangles).boundary_edges, 3);
  std::vector<std::uint8_t> among(static_cast<size_t>(vertices), 1);
  EXPECT_EQ(surface_topology(triangles, among).boundary_edges, 3);
  among.assign(static_cast<size_t>(vertices), 0);
  EXPECT_EQ(surface_topology(triangles, among).boundary_edges, 0);
  among[static_cast<size_t>(hole[0])] = among[static_cast<size_t>(hole[1])] = 1;
  EXPECT_EQ(surface_topology(triangles, among).boundary_edges, 1);  // the hole's edge (hole[0], hole[1])
  among[static_cast<size_t>(hole[2])] = 1;
  EXPECT_EQ(surface_topology(triangles, among).boundary_edges, 3);
  // The triangle put back twice: its three edges used three times.
  triangles.push_back(hole);
  triangles.push_back(hole);
  const SurfaceTopology doubled = surface_topology(triangles, among);
  EXPECT_EQ(doubled.boundary_edges, 0);
  EXPECT_EQ(doubled.nonmanifold_edges, 3);
  EXPECT_EQ(surface_topology(triangles).nonmanifold_edges, 3);
  // A short flag vector: the vertices past its end are not flagged.
  EXPECT_EQ(surface_topology(triangles, std::span<const std::uint8_t>(among.data(), 0)).nonmanifold_edges, 0);
}

TEST(LinkedAcross, KeptUpToDateEqualsTheFullCount) {
  // The rest cut grows strip by strip while the volume is not cut, so elements linked
  // across appear at every strip; the incremental count (elements near the new strip and the
  // ones marked changed) must equal a full recount each time.
  CorotationalEfg model = bar_model();
  RestCut cut(0.0025);
  std::vector<std::uint8_t> linked, linked_cached, linked_seen, linked_skipping, linked_skipping_seen;
  const std::vector<std::uint8_t> unchanged(static_cast<size_t>(model.element_count()), 0);
  std::vector<std::array<Vec3, 2>> boxes, boxes_seen, boxes_skipping, boxes_skipping_seen;
  std::vector<int> seen, skipping_seen;
  // Found by their centres (LinkedAcrossIndex), with every seventh element marked changed.
  std::vector<std::uint8_t> linked_indexed, some_changed(static_cast<size_t>(model.element_count()), 0);
  for (size_t e = 0; e < some_changed.size(); e += 7) some_changed[e] = 1;
  std::vector<std::array<Vec3, 2>> boxes_indexed;
  std::vector<int> seen_indexed;
  LinkedAcrossIndex index;
  int previous = 0;
  for (int strip = 0; strip < 8; ++strip) {
    // A slanted strip: x from 0.02 + 0.008 strip, top to bottom.
    const double x0 = 0.02 + 0.008 * strip, x1 = x0 + 0.008;
    const Vec3 p0(x0, -0.03, 0.03), p1(x1, -0.03, 0.03), p2(x1, 0.03, -0.03), p3(x0, 0.03, -0.03);
    const std::vector<RestTriangle> triangles{{p0, p1, p2}, {p0, p2, p3}};
    for (const RestTriangle& t : triangles) cut.add(t);
    Vec3 lo = p0, hi = p0;
    for (const Vec3& p : {p1, p2, p3}) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    const int incremental = update_elements_linked_across(model, cut, linked, lo, hi, nullptr);
    // The same with the elements' link boxes cached between calls (no neighbourhood changes).
    const int cached = update_elements_linked_across(model, cut, linked_cached, lo, hi, &unchanged, &boxes);
    ASSERT_EQ(static_cast<int>(boxes.size()), model.element_count());
    // The same testing only the triangles added since each element's flag was taken.
    const int since = update_elements_linked_across(model, cut, linked_seen, lo, hi, &unchanged,
                                                    &boxes_seen, &seen);
    const int full = elements_linked_across(model, cut);
    EXPECT_EQ(incremental, full) << "strip " << strip;
    EXPECT_EQ(cached, full) << "strip " << strip;
    EXPECT_EQ(since, full) << "strip " << strip;
    EXPECT_EQ(linked_cached, linked) << "strip " << strip;
    EXPECT_EQ(linked_seen, linked) << "strip " << strip;
    const int indexed = update_elements_linked_across(model, cut, linked_indexed, lo, hi, &some_changed,
                                                      &boxes_indexed, &seen_indexed, &index);
    EXPECT_EQ(indexed, full) << "strip " << strip;
    EXPECT_EQ(linked_indexed, linked) << "strip " << strip;
    EXPECT_EQ(index.centres.slots(), strip == 0 ? 0u : static_cast<size_t>(model.element_count())) << "strip " << strip << ": built after the first";
    // Called only every other strip with that strip's box (the triangles of the strip between
    // are outside it: the count can miss them), the per-element `seen` must still give
    // exactly what testing the whole cut gives.
    if (strip % 2 == 1) {
      const int skipping = update_elements_linked_across(model, cut, linked_skipping, lo, hi, &unchanged,
                                                         &boxes_skipping);
      const int skipping_since = update_elements_linked_across(model, cut, linked_skipping_seen, lo, hi,
                                                               &unchanged, &boxes_skipping_seen, &skipping_seen);
      EXPECT_EQ(skipping_since, skipping) << "strip " << strip;
      EXPECT_EQ(linked_skipping_seen, linked_skipping) << "strip " << strip;
    }
    EXPECT_GT(full, previous) << "strip " << strip << " links more elements across";
    previous = full;
  }
}

TEST(SurfaceTopology, CountsBoundaryAndNonManifoldEdges) {
  // A closed tetrahedron: watertight.
  const std::vector<std::array<int, 3>> tetrahedron{{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}};
  EXPECT_TRUE(surface_topology(tetrahedron).watertight());
  // One face removed: its three edges are boundary edges.
  const std::vector<std::array<int, 3>> open(tetrahedron.begin(), tetrahedron.end() - 1);
  EXPECT_EQ(surface_topology(open).boundary_edges, 3);
  EXPECT_EQ(surface_topology(open).nonmanifold_edges, 0);
  // A third triangle on edge (0, 1) of the closed one: one non-manifold edge, two boundary ones.
  auto fin = tetrahedron;
  fin.push_back({0, 1, 4});
  EXPECT_EQ(surface_topology(fin).nonmanifold_edges, 1);
  EXPECT_EQ(surface_topology(fin).boundary_edges, 2);
}

TEST(VoxelBoundary, SnapsItsNodesAsTheWholeVoxelMeshWould) {
  // voxel_boundary snaps its outer nodes with a tet mesh of the cubes near the voxel boundary
  // only. Reference: the whole voxel mesh of the same grid (make_box_tets over the grid,
  // kept where the cube's centre is inside, the outer layer of cubes left empty as there),
  // snapped the same way; every vertex of the uncut surface sits on its node's position.
  struct Shape {
    const char* name;
    std::function<bool(const Vec3&)> inside;
    Vec3 lo, hi;
    double cell;
  };
  const std::vector<Shape> shapes{
      {"ellipsoid", [](const Vec3& p) { return std::pow(p.x() / 0.03, 2) + std::pow(p.y() / 0.02, 2) + std::pow(p.z() / 0.015, 2) <= 1; },
       Vec3(-0.03, -0.02, -0.015), Vec3(0.03, 0.02, 0.015), 0.0011},
      {"peanut", [](const Vec3& p) { return (p - Vec3(-0.012, 0, 0)).norm() <= 0.016 || (p - Vec3(0.012, 0.003, 0)).norm() <= 0.014; },
       Vec3(-0.028, -0.016, -0.016), Vec3(0.026, 0.017, 0.016), 0.0013}};
  for (const Shape& shape : shapes) {
    SCOPED_TRACE(shape.name);
    const TriangleSurface surface = voxel_boundary(shape.inside, shape.lo, shape.hi, shape.cell);
    const Vec3 origin = shape.lo - Vec3::Constant(shape.cell);
    std::array<int, 3> counts{};
    for (int axis = 0; axis < 3; ++axis)
      counts[axis] = static_cast<int>(std::ceil((shape.hi[axis] - shape.lo[axis]) / shape.cell * (1 - 1e-12))) + 2;
    TetMesh mesh = make_box_tets(origin, origin + shape.cell * Vec3(counts[0], counts[1], counts[2]), counts);
    std::vector<std::array<int, 4>> kept;
    const int per_cube = static_cast<int>(mesh.tets.size()) / (counts[0] * counts[1] * counts[2]);
    ASSERT_EQ(per_cube, 6);
    for (int k = 1; k + 1 < counts[2]; ++k)
      for (int j = 1; j + 1 < counts[1]; ++j)
        for (int i = 1; i + 1 < counts[0]; ++i) {
          if (!shape.inside(origin + shape.cell * Vec3(i + 0.5, j + 0.5, k + 0.5))) continue;
          const size_t cube = static_cast<size_t>(i + counts[0] * (j + counts[1] * k));
          for (int t = 0; t < per_cube; ++t) kept.push_back(mesh.tets[per_cube * cube + t]);
        }
    mesh.tets = kept;
    const SnapReport snap = snap_boundary_to_surface(mesh, shape.inside, 1.5 * shape.cell, 0.1);
    ASSERT_GT(snap.moved, 100);
    // Every vertex sits where the whole mesh's snap puts some grid node, and (pinches filled)
    // the vertices are as many as the nodes of the voxel boundary.
    const auto boundary = boundary_triangles(mesh.tets);
    std::vector<std::uint8_t> on_boundary(mesh.rest.size() / 3, 0);
    for (const auto& t : boundary)
      for (int node : t) on_boundary[static_cast<size_t>(node)] = 1;
    std::vector<Vec3> snapped;
    for (size_t node = 0; node < on_boundary.size(); ++node)
      if (on_boundary[node]) snapped.push_back(mesh.rest.segment<3>(3 * static_cast<Eigen::Index>(node)));
    EXPECT_EQ(surface.vertices.size(), snapped.size());
    double worst = 0;
    for (const Vec3& vertex : surface.vertices) {
      double nearest = 1e300;
      for (const Vec3& node : snapped) nearest = std::min(nearest, (vertex - node).norm());
      worst = std::max(worst, nearest);
    }
    EXPECT_LT(worst, 1e-12 * shape.cell) << "a vertex is not where the whole mesh's snap puts its node";
  }
}
