// The cuttable render surface (physics/cut/cut_surface): closed before and after cuts, open
// exactly where the blade passed, and mapped onto the right side of the cut.
#include "physics/cut/cut_surface.hpp"
#include "physics/cut/volume_cut.hpp"
#include "physics/fem/surface_snap.hpp"
#include "physics/fem/tet_mesh.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <map>
#include <set>
#include <span>
#include <string>
#include <vector>

using namespace incise::physics;

namespace {

// Connected components of a triangle mesh through shared vertices.
int components(const std::vector<std::array<int, 3>>& triangles, int vertices) {
  std::vector<int> parent(static_cast<size_t>(vertices));
  for (int v = 0; v < vertices; ++v) parent[v] = v;
  const auto root = [&](int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (const auto& t : triangles) {
    parent[root(t[1])] = root(t[0]);
    parent[root(t[2])] = root(t[0]);
  }
  std::set<int> roots;
  for (const auto& t : triangles) roots.insert(root(t[0]));
  return static_cast<int>(roots.size());
}

// Signed volume enclosed by a closed triangle mesh (divergence theorem).
double enclosed_volume(const Vector& x, const std::vector<std::array<int, 3>>& triangles) {
  double volume = 0;
  for (const auto& t : triangles) {
    const Vec3 a = x.segment<3>(3 * t[0]), b = x.segment<3>(3 * t[1]), c = x.segment<3>(3 * t[2]);
    volume += a.dot(b.cross(c)) / 6.0;
  }
  return volume;
}

const auto in_box = [](const Vec3& p) {
  return p.x() >= 0 && p.x() <= 0.1 && std::abs(p.y()) <= 0.01 && std::abs(p.z()) <= 0.01;
};

// The blade plane x = x_cut from the top down to z_bottom, wider than the body, as two triangles.
std::vector<RestTriangle> plane_cut(double x_cut, double z_bottom) {
  const Vec3 p0(x_cut, -0.03, 0.03), p1(x_cut, 0.03, 0.03), p2(x_cut, 0.03, z_bottom), p3(x_cut, -0.03, z_bottom);
  return {{p0, p1, p2}, {p0, p2, p3}};
}

// The EFG model of the bar in_box describes (a = 2.5 mm, single-threaded).
CorotationalEfg bar_model() {
  EfgSettings settings;
  settings.spacing = 0.0025;
  settings.threaded_elements = 0;
  return CorotationalEfg(Vec3(0, -0.01, -0.01), Vec3(0.1, 0.01, 0.01), Material{1e5, 0.3, 1000}, settings);
}

}  // namespace

TEST(CutSurface, TheUncutSurfaceIsClosedAndEnclosesTheBody) {
  CutSurface surface(in_box, Vec3(0, -0.01, -0.01), Vec3(0.1, 0.01, 0.01), 0.0025);
  const SurfaceTopology topology = surface_topology(surface.triangles());
  EXPECT_TRUE(topology.watertight()) << topology.boundary_edges << " boundary, " << topology.nonmanifold_edges << " non-manifold";
  // 40 x 8 x 8 cubes: 2 (40 x 8 + 40 x 8 + 8 x 8) faces, 2 triangles each.
  EXPECT_EQ(surface.triangles().size(), 2u * 2u * (320u + 320u + 64u));
  EXPECT_NEAR(enclosed_volume(surface.rest_vertices(), surface.triangles()), 0.1 * 0.02 * 0.02, 1e-9);
}

// The count over the edges between flagged vertices: every use of such an edge is counted
// (the triangles around it may have unflagged corners), edges with an unflagged end are not.
TEST(CutSurface, TheTopologyAmongFlaggedVerticesCountsTheirEdgesOnly) {
  CutSurface surface(in_box, Vec3(0, -0.01, -0.01), Vec3(0.1, 0.01, 0.01), 0.0025);
  std::vector<std::array<int, 3>> triangles = surface.triangles();
  const int vertices = static_cast<int>(surface.rest_vertices().size() / 3);
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

TEST(CutSurface, AFullCutMakesTwoClosedPiecesMeetingOnTheCutPlane) {
  CutSurface surface(in_box, Vec3(0, -0.01, -0.01), Vec3(0.1, 0.01, 0.01), 0.0025);
  const auto triangles = plane_cut(0.0512, -0.03);
  EXPECT_EQ(surface.cut(triangles), 64);  // the 8 x 8 faces between two cube layers
  surface.rebuild();
  const SurfaceTopology topology = surface_topology(surface.triangles());
  EXPECT_TRUE(topology.watertight()) << topology.boundary_edges << " boundary, " << topology.nonmanifold_edges << " non-manifold";
  const int vertices = static_cast<int>(surface.rest_vertices().size() / 3);
  EXPECT_EQ(components(surface.triangles(), vertices), 2);
  // Each side's cut-face vertices lie on the plane; the volume is unchanged (zero thickness).
  int on_plane = 0;
  for (int v = 0; v < vertices; ++v) {
    if (!surface.on_cut()[v]) continue;
    EXPECT_NEAR(surface.rest_vertices()[3 * v], 0.0512, 1e-12);
    ++on_plane;
  }
  EXPECT_EQ(on_plane, 2 * 9 * 9);
  EXPECT_NEAR(enclosed_volume(surface.rest_vertices(), surface.triangles()), 0.1 * 0.02 * 0.02, 1e-9);
}

TEST(CutSurface, APartialCutOpensAClosedPocket) {
  CutSurface surface(in_box, Vec3(0, -0.01, -0.01), Vec3(0.1, 0.01, 0.01), 0.0025);
  const size_t before = surface.triangles().size();
  EXPECT_EQ(surface.cut(plane_cut(0.0512, 0.0)), 32);  // the top half of the section
  surface.rebuild();
  const SurfaceTopology topology = surface_topology(surface.triangles());
  EXPECT_TRUE(topology.watertight()) << topology.boundary_edges << " boundary, " << topology.nonmanifold_edges << " non-manifold";
  EXPECT_EQ(components(surface.triangles(), static_cast<int>(surface.rest_vertices().size() / 3)), 1);
  EXPECT_EQ(surface.triangles().size(), before + 2 * 2 * 32);  // both sides of each cut face
}

TEST(CutSurface, AnObliqueCutThroughACurvedBodyStaysClosed) {
  const auto ellipsoid = [](const Vec3& p) {
    return std::pow(p.x() / 0.05, 2) + std::pow(p.y() / 0.03, 2) + std::pow(p.z() / 0.025, 2) <= 1;
  };
  CutSurface surface(ellipsoid, Vec3(-0.05, -0.03, -0.025), Vec3(0.05, 0.03, 0.025), 0.002);
  ASSERT_TRUE(surface_topology(surface.triangles()).watertight());
  // A tilted plane through the middle, then a second one crossing it.
  const Vec3 n = Vec3(1, 0.3, 0.4).normalized();
  const Vec3 u = n.cross(Vec3(0, 0, 1)).normalized(), w = n.cross(u);
  const Vec3 c(0.003, 0.001, 0.0);
  std::vector<RestTriangle> tilted = {{c - 0.1 * u - 0.1 * w, c + 0.1 * u - 0.1 * w, c + 0.1 * u + 0.1 * w},
                                      {c - 0.1 * u - 0.1 * w, c + 0.1 * u + 0.1 * w, c - 0.1 * u + 0.1 * w}};
  EXPECT_GT(surface.cut(tilted), 0);
  surface.rebuild();
  SurfaceTopology topology = surface_topology(surface.triangles());
  std::printf("oblique cut: %zu triangles, %d boundary, %d non-manifold edges\n", surface.triangles().size(),
              topology.boundary_edges, topology.nonmanifold_edges);
  EXPECT_TRUE(topology.watertight());
  // Two pieces, and perhaps chips: cubes on the far side whose only neighbours were across
  // the cut (a curved boundary at voxel resolution). Each is closed on its own.
  const int pieces = components(surface.triangles(), static_cast<int>(surface.rest_vertices().size() / 3));
  std::printf("oblique cut: %d pieces, %d pinches closed\n", pieces, surface.pinches_closed());
  EXPECT_GE(pieces, 2);
  EXPECT_LE(pieces, 6);
  // A half-depth cut across the first: still closed.
  surface.cut(plane_cut(-0.0201, 0.0));
  surface.rebuild();
  topology = surface_topology(surface.triangles());
  EXPECT_TRUE(topology.watertight()) << topology.boundary_edges << " boundary, " << topology.nonmanifold_edges << " non-manifold";
}

TEST(CutSurface, VerticesMapToTheirOwnSideAndAgreeWithTheVolumeCut) {
  CorotationalEfg model = bar_model();
  const Vector rest = model.rest_positions();
  VolumeCutter cutter(model, 1e-6, 0.002);
  const double x_cut = 0.0512;
  cutter.cut(std::vector<Vec3>{Vec3(x_cut, -0.03, 0.03), Vec3(x_cut, 0.03, 0.03)},
             std::vector<Vec3>{Vec3(x_cut, -0.03, -0.03), Vec3(x_cut, 0.03, -0.03)}, rest, rest);
  CutSurface surface(in_box, Vec3(0, -0.01, -0.01), Vec3(0.1, 0.01, 0.01), 0.00125);
  surface.cut(plane_cut(x_cut, -0.03));
  surface.rebuild();
  EXPECT_EQ(elements_linked_across(model, surface.rest_cut()), 0);
  SurfaceMappingReport report;
  const SurfaceEmbedding embedding = map_surface(model, surface, report);
  EXPECT_EQ(report.relaxed_fallbacks, 0);
  EXPECT_EQ(report.wrong_side, 0);
  // Every vertex follows particles on its own side, and a rigid shift of one piece moves
  // exactly that piece's vertices.
  Vector moved = rest;
  for (int i = 0; i < model.node_count(); ++i)
    if (rest[3 * i] > x_cut) moved[3 * i + 2] -= 0.01;
  Vector vertices;
  CorotationalEfg::surface_positions(embedding, moved, vertices);
  for (int v = 0; v < embedding.vertex_count(); ++v) {
    const bool right = surface.anchors()[v].x() > x_cut;
    const double dz = vertices[3 * v + 2] - surface.rest_vertices()[3 * v + 2];
    EXPECT_NEAR(dz, right ? -0.01 : 0.0, 1e-9) << "vertex " << v;
  }
}

TEST(CutSurface, EachVertexMapsToTheNearestVisibleIntegrationPoint) {
  // map_surface searches ring by ring of cubes; the answer must be the brute-force one: the
  // nearest active integration point whose segment to the vertex's anchor crosses no cut.
  CorotationalEfg model = bar_model();
  const Vector rest = model.rest_positions();
  VolumeCutter cutter(model, 1e-6, 0.002);
  const double x_cut = 0.0512;
  cutter.cut(std::vector<Vec3>{Vec3(x_cut, -0.03, 0.03), Vec3(x_cut, 0.03, 0.03)},
             std::vector<Vec3>{Vec3(x_cut, -0.03, 0.0), Vec3(x_cut, 0.03, 0.0)}, rest, rest);
  CutSurface surface(in_box, Vec3(0, -0.01, -0.01), Vec3(0.1, 0.01, 0.01), 0.00125);
  surface.cut(plane_cut(x_cut, 0.0));
  surface.rebuild();
  SurfaceMappingReport report;
  const SurfaceEmbedding embedding = map_surface(model, surface, report);
  ASSERT_EQ(report.relaxed_fallbacks, 0);
  int near_the_cut = 0;
  for (int v = 0; v < embedding.vertex_count(); ++v) {
    const Vec3 vertex = surface.rest_vertices().segment<3>(3 * v);
    const Vec3 anchor = surface.anchors()[v];
    int best = -1;
    double best_distance = 0;
    for (int e = 0; e < model.element_count(); ++e) {
      if (!model.element_active(e)) continue;
      const double d = (model.element_centres()[e] - vertex).squaredNorm();
      if (best >= 0 && d >= best_distance) continue;
      if (surface.rest_cut().crosses(anchor, model.element_centres()[e])) continue;
      best = e, best_distance = d;
    }
    ASSERT_EQ(embedding.elements[v], best) << "vertex " << v;
    near_the_cut += std::abs(vertex.x() - x_cut) < 0.005 ? 1 : 0;
  }
  EXPECT_GT(near_the_cut, 50) << "the case exercises the visibility test";
}

TEST(CutSurface, LinkedAcrossKeptUpToDateEqualsTheFullCount) {
  // The surface's cut grows strip by strip while the volume is not cut, so elements linked
  // across appear at every strip; the incremental count (elements near the new strip and the
  // ones marked changed) must equal a full recount each time.
  CorotationalEfg model = bar_model();
  CutSurface surface(in_box, Vec3(0, -0.01, -0.01), Vec3(0.1, 0.01, 0.01), 0.00125);
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
    surface.cut(triangles);
    Vec3 lo = p0, hi = p0;
    for (const Vec3& p : {p1, p2, p3}) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    const int incremental = update_elements_linked_across(model, surface.rest_cut(), linked, lo, hi, nullptr);
    // The same with the elements' link boxes cached between calls (no neighbourhood changes).
    const int cached = update_elements_linked_across(model, surface.rest_cut(), linked_cached, lo, hi, &unchanged, &boxes);
    ASSERT_EQ(static_cast<int>(boxes.size()), model.element_count());
    // The same testing only the triangles added since each element's flag was taken.
    const int since = update_elements_linked_across(model, surface.rest_cut(), linked_seen, lo, hi, &unchanged,
                                                    &boxes_seen, &seen);
    const int full = elements_linked_across(model, surface.rest_cut());
    EXPECT_EQ(incremental, full) << "strip " << strip;
    EXPECT_EQ(cached, full) << "strip " << strip;
    EXPECT_EQ(since, full) << "strip " << strip;
    EXPECT_EQ(linked_cached, linked) << "strip " << strip;
    EXPECT_EQ(linked_seen, linked) << "strip " << strip;
    const int indexed = update_elements_linked_across(model, surface.rest_cut(), linked_indexed, lo, hi, &some_changed,
                                                      &boxes_indexed, &seen_indexed, &index);
    EXPECT_EQ(indexed, full) << "strip " << strip;
    EXPECT_EQ(linked_indexed, linked) << "strip " << strip;
    EXPECT_EQ(index.centres.items.size(), strip == 0 ? 0u : static_cast<size_t>(model.element_count())) << "strip " << strip << ": built after the first";
    // Called only every other strip with that strip's box (the triangles of the strip between
    // are outside it: the count can miss them), the per-element `seen` must still give
    // exactly what testing the whole cut gives.
    if (strip % 2 == 1) {
      const int skipping = update_elements_linked_across(model, surface.rest_cut(), linked_skipping, lo, hi, &unchanged,
                                                         &boxes_skipping);
      const int skipping_since = update_elements_linked_across(model, surface.rest_cut(), linked_skipping_seen, lo, hi,
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

namespace {

// One blade pass of a remapping test: the segment [top0, top1] swept down to [bottom0, bottom1].
struct Pass {
  Vec3 top0, top1, bottom0, bottom1;
};

// Cuts the bar pass by pass (volume and surface), remapping in place after each: every used
// vertex's row must be the one a fresh map_surface gives, and most rows must have been kept.
// With `cut_volume` false only the surface is cut (no element is marked changed): the rows to
// redo are then found by the new triangles crossing their anchors' segments alone.
void expect_remapping_equals_fresh(const std::vector<Pass>& passes, bool cut_volume = true) {
  CorotationalEfg model = bar_model();
  const Vector rest = model.rest_positions();
  VolumeCutter cutter(model, 1e-6, 0.002);
  CutSurface surface(in_box, Vec3(0, -0.01, -0.01), Vec3(0.1, 0.01, 0.01), 0.00125);
  SurfaceMappingReport first;
  SurfaceEmbedding embedding = map_surface(model, surface, first);
  MappingReuse reuse;
  reuse.keys = surface.vertex_keys();
  reuse.rest_vertices = surface.rest_vertices();
  reuse.anchors = surface.anchors();
  int reused_somewhere = 0;
  for (size_t step = 0; step < passes.size(); ++step) {
    const Pass& pass = passes[step];
    const VolumeCutReport cut = cut_volume ? cutter.cut(std::vector<Vec3>{pass.top0, pass.top1},
                                                        std::vector<Vec3>{pass.bottom0, pass.bottom1}, rest, rest)
                                           : VolumeCutReport{};
    surface.cut(std::vector<RestTriangle>{{pass.top0, pass.top1, pass.bottom1}, {pass.top0, pass.bottom1, pass.bottom0}});
    surface.rebuild();
    std::vector<std::uint8_t> changed(static_cast<size_t>(model.element_count()), 0);
    for (int e : cut.changed_elements) changed[e] = 1;
    reuse.element_changed = &changed;
    SurfaceMappingReport report;
    remap_surface(model, surface, embedding, report, reuse);
    EXPECT_EQ(reuse.revision, surface.revision());
    SurfaceMappingReport fresh_report;
    const SurfaceEmbedding fresh = map_surface(model, surface, fresh_report);
    ASSERT_EQ(embedding.vertex_count(), fresh.vertex_count());
    ASSERT_EQ(embedding.stride, fresh.stride);
    EXPECT_EQ(reuse.keys, surface.vertex_keys());
    EXPECT_TRUE(reuse.rest_vertices == surface.rest_vertices()) << "step " << step;
    EXPECT_TRUE(reuse.anchors == surface.anchors()) << "step " << step;
    int used = 0;
    for (int v = 0; v < fresh.vertex_count(); ++v) {
      if (!surface.vertex_used(v)) continue;
      ++used;
      ASSERT_EQ(embedding.elements[v], fresh.elements[v]) << "step " << step << " vertex " << v;
      ASSERT_EQ(embedding.row_lengths[v], fresh.row_lengths[v]) << "step " << step << " vertex " << v;
      for (int k = 0; k < fresh.row_lengths[v]; ++k) {
        const size_t at = static_cast<size_t>(v) * fresh.stride + k;
        ASSERT_EQ(embedding.particles[at], fresh.particles[at]) << "step " << step << " vertex " << v;
        ASSERT_EQ(embedding.weights[at], fresh.weights[at]) << "step " << step << " vertex " << v;
      }
    }
    // What the next remapping's search by element relies on: each row is listed under its
    // element, whose box holds the segment from the vertex's anchor to the element's point,
    // and the tree of boxes finds the element from either end of that segment.
    ASSERT_TRUE(reuse.element_tree);
    std::vector<int> found;
    for (int v = 0; v < embedding.vertex_count(); ++v) {
      const int e = embedding.elements[v];
      const auto& listed = reuse.by_element[e];
      ASSERT_NE(std::find(listed.begin(), listed.end(), v), listed.end()) << "step " << step << " vertex " << v;
      const auto& box = reuse.element_boxes[e];
      for (const Vec3& end : {surface.anchors()[v], model.element_centres()[e]}) {
        ASSERT_TRUE((box[0].array() <= end.array()).all() && (box[1].array() >= end.array()).all()) << "step " << step << " vertex " << v;
        reuse.element_tree->query(MovingSegment{{end, end}, {end, end}}, found);
        ASSERT_TRUE(std::binary_search(found.begin(), found.end(), e)) << "step " << step << " vertex " << v;
      }
    }
    EXPECT_EQ(report.wrong_side, 0);
    EXPECT_LE(report.mapped, used);
    EXPECT_EQ(report.mapped, static_cast<int>(std::count_if(reuse.remapped.begin(), reuse.remapped.end(),
                                                            [&](int v) { return surface.vertex_used(v); })));
    reused_somewhere += report.mapped < used ? 1 : 0;
    EXPECT_LT(report.mapped, used / 4) << "step " << step << ": most vertices are far from the cut";
  }
  EXPECT_EQ(reused_somewhere, static_cast<int>(passes.size()));
}

}  // namespace

TEST(CutSurface, RemappingInPlaceEqualsAFreshMappingAtEveryStepOfAProgressiveCut) {
  // remap_surface reuses rows by index where nothing near changed (the first remapping
  // compares every index, the next ones only those the surface wrote since the last).
  std::vector<Pass> passes;
  const double x_cut = 0.0512;
  for (int step = 0; step < 6; ++step) {
    const double z0 = 0.012 - 0.004 * step, z1 = z0 - 0.004;
    passes.push_back({Vec3(x_cut, -0.03, z0), Vec3(x_cut, 0.03, z0), Vec3(x_cut, -0.03, z1), Vec3(x_cut, 0.03, z1)});
  }
  expect_remapping_equals_fresh(passes);
}

TEST(CutSurface, RemappingInPlaceFollowsCutFaceVerticesProjectedAgain) {
  // A shallow cut, then a deeper one a little nearer the grid nodes: the shallow cut's face
  // vertices are projected onto the second plane, where it is nearer, though their faces are
  // not cut again (their rest positions change, nothing else about them does).
  const auto plane = [](double x, double z_bottom) {
    return Pass{Vec3(x, -0.03, 0.03), Vec3(x, 0.03, 0.03), Vec3(x, -0.03, z_bottom), Vec3(x, 0.03, z_bottom)};
  };
  expect_remapping_equals_fresh({plane(0.0758, 0.004), plane(0.0762, -0.004)});
}

TEST(CutSurface, RemappingInPlaceFindsTheRowsANewSurfaceCutHides) {
  // The surface cut strip by strip, the volume left whole: no element is marked changed, so
  // every row to redo is one whose segment from its anchor to its point a new triangle crosses.
  for (const double x_cut : {0.0488, 0.0491}) {  // planes whose neighbours map across them
    SCOPED_TRACE("x_cut " + std::to_string(x_cut));
    std::vector<Pass> passes;
    for (int step = 0; step < 4; ++step) {
      const double z0 = 0.012 - 0.006 * step, z1 = z0 - 0.006;
      passes.push_back({Vec3(x_cut, -0.03, z0), Vec3(x_cut, 0.03, z0), Vec3(x_cut, -0.03, z1), Vec3(x_cut, 0.03, z1)});
    }
    expect_remapping_equals_fresh(passes, false);
  }
}

TEST(CutSurface, SnapsItsNodesAsTheWholeVoxelMeshWould) {
  // CutSurface snaps its outer nodes with a tet mesh of the cubes near the voxel boundary
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
    const CutSurface surface(shape.inside, shape.lo, shape.hi, shape.cell);
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
    int checked = 0;
    double worst = 0;
    for (int v = 0; v < static_cast<int>(surface.vertex_keys().size()); ++v) {
      const long long node = surface.vertex_keys()[v] / 8;
      const Vec3 expected = mesh.rest.segment<3>(3 * static_cast<Eigen::Index>(node));
      worst = std::max(worst, (Vec3(surface.rest_vertices().segment<3>(3 * v)) - expected).norm());
      ++checked;
    }
    EXPECT_EQ(checked, surface.vertex_count());
    EXPECT_LT(worst, 1e-12 * shape.cell) << "a vertex is not where the whole mesh's snap puts its node";
  }
}
