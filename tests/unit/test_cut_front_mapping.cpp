// Mapping a FrontSurface onto the EFG model's integration points (physics/cut/front_mapping,
// seed 004 §2.6): every row reproduces its vertex's rest position (linear MLS reproduces
// affine fields, an independent check of the weights); the chosen point is the nearest that
// meets the criteria, checked here against a scan of every element; after a straight cut
// through a ball no vertex is mapped across the cut (with the test's planes, and with the
// FrontSurface's own), where the nearest-point mapping maps some; criterion 1 moves a vertex to a farther point; fallbacks are counted.
#include "physics/cut/front_mapping.hpp"
#include "physics/cut/volume_cut.hpp"

#include "tests/unit/icosphere.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

using namespace incise::physics;

namespace {

using Mesh = incise::testing::SphereMesh;

// An icosahedron subdivided `levels` times onto the sphere of radius `radius` about the
// origin, turned so that no vertex lies on a grid plane or on the blade's plane.
Mesh ball_surface(int levels, double radius) {
  return incise::testing::icosphere(levels, radius, (Eigen::AngleAxisd(0.7, Vec3::UnitZ()) * Eigen::AngleAxisd(0.4, Vec3::UnitY())).toRotationMatrix());
}

EfgSettings settings_with(double spacing) {
  EfgSettings settings;
  settings.spacing = spacing;
  return settings;
}

CorotationalEfg ball_model(double radius, double spacing) {
  return CorotationalEfg([radius](const Vec3& x) { return x.norm() < radius; }, Vec3::Constant(-radius),
                         Vec3::Constant(radius), Material{1e5, 0.3, 1000}, settings_with(spacing));
}

std::vector<int> all_of(int n) {
  std::vector<int> list(static_cast<size_t>(n));
  for (int v = 0; v < n; ++v) list[static_cast<size_t>(v)] = v;
  return list;
}

// The test's own area-weighted normals.
std::vector<Vec3> normals_of(const Mesh& mesh) {
  std::vector<Vec3> normals(mesh.vertices.size(), Vec3::Zero());
  for (const auto& t : mesh.triangles) {
    const Vec3 a = mesh.vertices[static_cast<size_t>(t[0])], b = mesh.vertices[static_cast<size_t>(t[1])],
               c = mesh.vertices[static_cast<size_t>(t[2])];
    for (const int v : t) normals[static_cast<size_t>(v)] += (b - a).cross(c - a);
  }
  return normals;
}

// sum_k w_k X_k for vertex v's row.
Vec3 reproduced(const CorotationalEfg& model, const SurfaceEmbedding& embedding, int v) {
  Vec3 x = Vec3::Zero();
  const size_t row = static_cast<size_t>(v) * embedding.stride;
  for (int k = 0; k < embedding.row_lengths[static_cast<size_t>(v)]; ++k) {
    const double w = embedding.weights[row + k];
    EXPECT_TRUE(std::isfinite(w)) << "vertex " << v;
    x += w * model.rest_positions().segment<3>(3 * static_cast<Eigen::Index>(embedding.particles[row + k]));
  }
  return x;
}

bool share_a_particle(const CorotationalEfg& model, int e, int f) {
  const size_t s = static_cast<size_t>(model.row_stride());
  for (int i = 0; i < model.row_lengths()[static_cast<size_t>(e)]; ++i)
    for (int j = 0; j < model.row_lengths()[static_cast<size_t>(f)]; ++j)
      if (model.neighbours()[static_cast<size_t>(e) * s + i] == model.neighbours()[static_cast<size_t>(f) * s + j]) return true;
  return false;
}

bool below(const std::vector<ConstraintPlane>& planes, const Vec3& x) {
  return std::all_of(planes.begin(), planes.end(), [&](const ConstraintPlane& p) { return (x - p.point).dot(p.normal) <= 0; });
}

int element_at(const CorotationalEfg& model, const Vec3& centre) {
  for (int e = 0; e < model.element_count(); ++e)
    if ((model.element_centres()[static_cast<size_t>(e)] - centre).norm() < 1e-9) return e;
  return -1;
}

std::string message_of(const std::function<void()>& call) {
  try {
    call();
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  return "(no std::invalid_argument)";
}

// The straight blade of the cut test, at height z: it sweeps the plane through p0 with
// normal blade_normal().
std::vector<Vec3> blade_at(double z) { return {{0.31 + 0.05 * z, -1.4, z + 0.02}, {0.31 + 0.05 * z, 1.4, z - 0.02}}; }
Vec3 blade_normal() { return (blade_at(0)[1] - blade_at(0)[0]).cross(blade_at(1)[0] - blade_at(0)[0]).normalized(); }
Vec3 blade_point() { return blade_at(0)[0]; }

}  // namespace

TEST(FrontMapping, MapsEveryVertexOfAnUncutBallToTheNearestPointBelowItsPlanes) {
  const Mesh mesh = ball_surface(3, 1.0);
  const CorotationalEfg model = ball_model(1.0, 0.2);
  const int n = static_cast<int>(mesh.vertices.size());
  // The vertices beyond x = 0.3 get a plane through them across the surface (as a cut at the
  // vertex would give), which takes away half of their candidates.
  std::vector<std::vector<ConstraintPlane>> planes(static_cast<size_t>(n));
  int with_planes = 0;
  for (int v = 0; v < n; ++v) {
    const Vec3& x = mesh.vertices[static_cast<size_t>(v)];
    if (x.x() > 0.3) {
      planes[static_cast<size_t>(v)].push_back({x, x.cross(Vec3::UnitZ()).normalized()});
      ++with_planes;
    }
  }
  ASSERT_GT(with_planes, 20);
  SurfaceEmbedding embedding;
  FrontMappingReport report;
  map_front_surface(model, mesh.vertices, mesh.triangles, planes, all_of(n), embedding, report);
  EXPECT_EQ(report.mapped, n);
  EXPECT_EQ(report.relaxed_fallbacks, 0);
  ASSERT_EQ(embedding.vertex_count(), n);

  const std::vector<Vec3> normals = normals_of(mesh);
  std::vector<std::set<int>> ring(static_cast<size_t>(n));
  for (const auto& t : mesh.triangles)
    for (const int v : t)
      for (const int u : t)
        if (u != v) ring[static_cast<size_t>(v)].insert(u);
  int plane_moved = 0;  // vertices whose plane excludes the nearest point below the tangent plane
  for (int v = 0; v < n; ++v) {
    const Vec3& x = mesh.vertices[static_cast<size_t>(v)];
    EXPECT_LT((reproduced(model, embedding, v) - x).norm(), 1e-9) << "vertex " << v;
    const int chosen = embedding.elements[static_cast<size_t>(v)];
    const Vec3& point = model.element_centres()[static_cast<size_t>(chosen)];
    EXPECT_LE((point - x).dot(normals[static_cast<size_t>(v)]), 0) << "vertex " << v;
    EXPECT_TRUE(below(planes[static_cast<size_t>(v)], point)) << "vertex " << v;
    for (const int u : ring[static_cast<size_t>(v)])
      EXPECT_TRUE(share_a_particle(model, chosen, embedding.elements[static_cast<size_t>(u)])) << "vertices " << v << ", " << u;
    // Brute force: the nearest of all elements below the tangent plane and the planes.
    double best = std::numeric_limits<double>::infinity(), best_tangent_only = best;
    for (int e = 0; e < model.element_count(); ++e) {
      const Vec3& c = model.element_centres()[static_cast<size_t>(e)];
      if ((c - x).dot(normals[static_cast<size_t>(v)]) > 0) continue;
      best_tangent_only = std::min(best_tangent_only, (c - x).norm());
      if (below(planes[static_cast<size_t>(v)], c)) best = std::min(best, (c - x).norm());
    }
    EXPECT_EQ((point - x).norm(), best) << "vertex " << v;
    plane_moved += best > best_tangent_only ? 1 : 0;
  }
  EXPECT_GT(plane_moved, 0);  // the planes mattered somewhere
  std::printf("uncut ball: %d vertices, %d elements, %d vertices moved by their plane\n", n, model.element_count(), plane_moved);
}

TEST(FrontMapping, MapsNoVertexAcrossAStraightCutThroughABallWhereTheNearestPointMappingDoes) {
  const Mesh mesh = ball_surface(3, 1.0);
  CorotationalEfg model = ball_model(1.0, 0.2);
  const double a = model.spacing();
  const int base_count = static_cast<int>(mesh.vertices.size());
  SurfaceEmbedding embedding;
  FrontMappingReport initial;
  map_front_surface(model, mesh.vertices, mesh.triangles, {}, all_of(base_count), embedding, initial);
  ASSERT_EQ(initial.relaxed_fallbacks, 0);

  // The same straight blade, top to bottom, through the volume (one step at rest) and the surface.
  VolumeCutter cutter(model, 1e-6, 0.05);
  const Vector rest = model.rest_positions();
  const VolumeCutReport volume = cutter.cut(blade_at(1.3), blade_at(-1.3), rest, rest);
  ASSERT_GT(volume.element_links_severed, 0);
  std::vector<int> piece;
  ASSERT_EQ(cutter.pieces(piece), 2);
  FrontSurface surface(mesh.vertices, mesh.triangles, 0.08);
  for (int k = 0; k < 40; ++k) {
    const FrontCutReport cut = surface.advance(blade_at(1.3 - 2.6 * k / 39));
    ASSERT_TRUE(cut.ok()) << cut.problems.front();
  }
  surface.end_stroke();
  const std::vector<Vec3>& vertices = surface.vertices();
  const auto& triangles = surface.triangles();
  const int n = static_cast<int>(vertices.size());
  ASSERT_GT(n, base_count);

  // The remap triggers of §2.6: vertices the cut created or touched (in a triangle the cut
  // made), vertices mapped to an element whose neighbourhood changed, and vertices whose
  // link to their point the blade crossed.
  std::set<std::array<int, 3>> old_triangles(mesh.triangles.begin(), mesh.triangles.end());
  std::set<int> remap;
  for (int v = base_count; v < n; ++v) remap.insert(v);
  for (const auto& t : triangles)
    if (!old_triangles.contains(t))
      for (const int v : t) remap.insert(v);
  const std::set<int> changed(volume.changed_elements.begin(), volume.changed_elements.end());
  const Vec3 normal = blade_normal(), p0 = blade_point();
  for (int v = 0; v < base_count; ++v) {
    const double side = (vertices[static_cast<size_t>(v)] - p0).dot(normal);
    const double point_side = (model.element_centres()[static_cast<size_t>(embedding.elements[static_cast<size_t>(v)])] - p0).dot(normal);
    if (changed.contains(embedding.elements[static_cast<size_t>(v)]) || side * point_side < 0) remap.insert(v);
  }
  // Each remapped vertex near the cut gets the cut's plane, facing away from its side (a
  // vertex on the sheet is on the side its cut face's normal points away from), merged with
  // the planes the FrontSurface gives.
  // (the normal of the vertex's cut-face triangles, those on the sheet: a vertex pair's two
  // copies each belong to their own side's face only).
  const auto on_sheet = [&](int v) { return std::abs((vertices[static_cast<size_t>(v)] - p0).dot(normal)) < 1e-9; };
  std::vector<Vec3> face_normals(static_cast<size_t>(n), Vec3::Zero());
  for (const auto& t : triangles)
    if (on_sheet(t[0]) && on_sheet(t[1]) && on_sheet(t[2]))
      for (const int v : t)
        face_normals[static_cast<size_t>(v)] += (vertices[static_cast<size_t>(t[1])] - vertices[static_cast<size_t>(t[0])])
                                                     .cross(vertices[static_cast<size_t>(t[2])] - vertices[static_cast<size_t>(t[0])]);
  std::vector<std::vector<ConstraintPlane>> planes(static_cast<size_t>(n));
  for (const int v : remap) {
    const double d = (vertices[static_cast<size_t>(v)] - p0).dot(normal);
    if (std::abs(d) > 2 * a) continue;
    const double across = face_normals[static_cast<size_t>(v)].dot(normal);
    if (on_sheet(v)) {
      ASSERT_NE(across, 0) << "vertex " << v << " on the sheet in no cut face";
    }
    const double side = !on_sheet(v) ? (d > 0 ? 1.0 : -1.0) : (across > 0 ? -1.0 : 1.0);
    planes[static_cast<size_t>(v)].push_back({p0, -side * normal});
  }
  const std::vector<Vec3> normals = normals_of(Mesh{vertices, triangles});
  const auto& given = surface.vertex_planes();
  for (size_t v = 0; v < given.size() && v < planes.size(); ++v) planes[v].insert(planes[v].end(), given[v].begin(), given[v].end());

  const std::vector<int> list(remap.begin(), remap.end());
  const SurfaceEmbedding before = embedding;
  FrontMappingReport report;
  map_front_surface(model, vertices, triangles, planes, list, embedding, report);
  EXPECT_EQ(report.mapped, static_cast<int>(list.size()));
  EXPECT_EQ(report.relaxed_fallbacks, 0);
  ASSERT_EQ(embedding.vertex_count(), n);
  for (int v = 0; v < n; ++v) {
    EXPECT_LT((reproduced(model, embedding, v) - vertices[static_cast<size_t>(v)]).norm(), 1e-9) << "vertex " << v;
    EXPECT_TRUE(model.element_active(embedding.elements[static_cast<size_t>(v)])) << "vertex " << v;
  }

  // The cut faces: the surface's triangles lying on the sheet, each once (both sides' copies
  // have the same corners; count_wrong_side counts crossings, odd meaning across).
  std::vector<std::array<Vec3, 3>> cut_faces;
  std::set<std::array<double, 9>> faces_seen;
  for (const auto& t : triangles) {
    std::array<Vec3, 3> corners{vertices[static_cast<size_t>(t[0])], vertices[static_cast<size_t>(t[1])], vertices[static_cast<size_t>(t[2])]};
    if (!std::all_of(corners.begin(), corners.end(), [&](const Vec3& x) { return std::abs((x - p0).dot(normal)) < 1e-9; })) continue;
    std::sort(corners.begin(), corners.end(), [](const Vec3& l, const Vec3& r) {
      return std::lexicographical_compare(l.data(), l.data() + 3, r.data(), r.data() + 3);
    });
    std::array<double, 9> key{};
    for (int c = 0; c < 3; ++c)
      for (int d = 0; d < 3; ++d) key[static_cast<size_t>(3 * c + d)] = corners[static_cast<size_t>(c)][d];
    if (faces_seen.insert(key).second) cut_faces.push_back(corners);
  }
  ASSERT_GT(cut_faces.size(), 100u);
  const int wrong = count_wrong_side(model, vertices, triangles, embedding, cut_faces, 0.01 * a);
  Vector flat(3 * static_cast<Eigen::Index>(n));
  for (int v = 0; v < n; ++v) flat.segment<3>(3 * v) = vertices[static_cast<size_t>(v)];
  const int naive = count_wrong_side(model, vertices, triangles, model.embed_surface(flat), cut_faces, 0.01 * a);
  EXPECT_EQ(wrong, 0);
  EXPECT_GT(naive, 0);
  // The metric against a scan of every cut face, with the test's own angle-weighted normals and
  // segment test (a 3x3 solve for the crossing's parameters).
  {
    const SurfaceEmbedding nearest = model.embed_surface(flat);
    std::vector<Vec3> pseudo(static_cast<size_t>(n), Vec3::Zero());
    for (const auto& t : triangles) {
      const Vec3 unit = (vertices[static_cast<size_t>(t[1])] - vertices[static_cast<size_t>(t[0])])
                            .cross(vertices[static_cast<size_t>(t[2])] - vertices[static_cast<size_t>(t[0])]).normalized();
      for (int i = 0; i < 3; ++i) {
        const Vec3 u = vertices[static_cast<size_t>(t[(i + 1) % 3])] - vertices[static_cast<size_t>(t[i])];
        const Vec3 w = vertices[static_cast<size_t>(t[(i + 2) % 3])] - vertices[static_cast<size_t>(t[i])];
        pseudo[static_cast<size_t>(t[i])] += std::acos(std::clamp(u.normalized().dot(w.normalized()), -1.0, 1.0)) * unit;
      }
    }
    int scanned = 0;
    for (int v = 0; v < n; ++v) {
      const Vec3 from = vertices[static_cast<size_t>(v)] - 0.01 * a * pseudo[static_cast<size_t>(v)].normalized();
      const Vec3 to = model.element_centres()[static_cast<size_t>(nearest.elements[static_cast<size_t>(v)])];
      int crossings = 0;
      for (const auto& f : cut_faces) {
        Eigen::Matrix3d system;
        system << to - from, f[0] - f[1], f[0] - f[2];
        const Vec3 tuw = system.fullPivLu().solve(f[0] - from);
        crossings += (tuw[0] > 0 && tuw[0] < 1 && tuw[1] >= 0 && tuw[2] >= 0 && tuw[1] + tuw[2] <= 1) ? 1 : 0;
      }
      scanned += crossings % 2;
    }
    EXPECT_EQ(naive, scanned);
  }
  // Criterion 2 alone (no planes at all): a vertex inside a cut face (all its triangles on
  // the sheet) has the face's normal, so its tangent plane is the cut and keeps its point on
  // its side, where the nearest point is often across.
  SurfaceEmbedding tangent_only = before;
  FrontMappingReport without_planes;
  map_front_surface(model, vertices, triangles, {}, list, tangent_only, without_planes);
  std::vector<int> incident(static_cast<size_t>(n), 0), incident_on_sheet(static_cast<size_t>(n), 0);
  for (const auto& t : triangles)
    for (const int v : t) {
      ++incident[static_cast<size_t>(v)];
      incident_on_sheet[static_cast<size_t>(v)] += on_sheet(t[0]) && on_sheet(t[1]) && on_sheet(t[2]) ? 1 : 0;
    }
  int inside_face = 0, across_tangent_only = 0;
  for (const int v : list) {
    if (incident[static_cast<size_t>(v)] == 0 || incident_on_sheet[static_cast<size_t>(v)] != incident[static_cast<size_t>(v)]) continue;
    ++inside_face;
    const double side = face_normals[static_cast<size_t>(v)].dot(normal) > 0 ? -1.0 : 1.0;
    const Vec3& point = model.element_centres()[static_cast<size_t>(tangent_only.elements[static_cast<size_t>(v)])];
    across_tangent_only += side * (point - p0).dot(normal) < 0 ? 1 : 0;
  }
  EXPECT_GT(inside_face, 100);
  EXPECT_EQ(across_tangent_only, 0);
  // With the FrontSurface's planes alone (none of the test's).
  SurfaceEmbedding surface_planes = before;
  FrontMappingReport with_surface_planes;
  map_front_surface(model, vertices, triangles, surface.vertex_planes(), list, surface_planes, with_surface_planes);
  const int wrong_surface_planes = count_wrong_side(model, vertices, triangles, surface_planes, cut_faces, 0.01 * a);
  EXPECT_EQ(wrong_surface_planes, 0);
  EXPECT_EQ(with_surface_planes.relaxed_fallbacks, 0);
  // No planes, the visibility criterion instead: what wrong_side measures holds by
  // construction (76 across with criterion 2 alone).
  SurfaceEmbedding visible_only = before;
  FrontMappingReport with_visibility;
  const CutFaceIndex face_index(model, cut_faces);
  const FrontVisibility visibility{&face_index, 0.01 * a, surface.crack_front(), {}};
  map_front_surface(model, vertices, triangles, {}, list, visible_only, with_visibility, &visibility);
  const int wrong_visible = count_wrong_side(model, vertices, triangles, visible_only, cut_faces, 0.01 * a);
  EXPECT_EQ(wrong_visible, 0);
  EXPECT_GT(count_wrong_side(model, vertices, triangles, tangent_only, cut_faces, 0.01 * a), 10);
  // The index counts what a scan of every face counts (from the vertices off the sheet).
  int compared = 0;
  for (int v = 0; v < n; v += 3) {
    const Vec3& x = vertices[static_cast<size_t>(v)];
    if (std::abs((x - p0).dot(normal)) < 1e-6) continue;
    ++compared;
    const Vec3& q = model.element_centres()[static_cast<size_t>(tangent_only.elements[static_cast<size_t>(v)])];
    int crossings = 0;
    for (const auto& f : cut_faces) {
      Eigen::Matrix3d system;
      system << q - x, f[0] - f[1], f[0] - f[2];
      const Vec3 tuw = system.fullPivLu().solve(f[0] - x);
      crossings += (tuw[0] > 1e-12 && tuw[0] < 1 - 1e-12 && tuw[1] >= 0 && tuw[2] >= 0 && tuw[1] + tuw[2] <= 1) ? 1 : 0;
    }
    EXPECT_EQ(face_index.crossings(x, q), crossings) << "vertex " << v;
  }
  EXPECT_GT(compared, 100);
  std::printf("cut ball with the visibility criterion and no planes: mapping.wrong_side %d, %d fallbacks\n", wrong_visible,
              with_visibility.relaxed_fallbacks);
  std::printf("cut ball with FrontSurface::vertex_planes only (%zu entries): mapping.wrong_side %d, %d fallbacks\n",
              surface.vertex_planes().size(), wrong_surface_planes, with_surface_planes.relaxed_fallbacks);
  std::printf("cut ball without planes: %d cut-face vertices, %d mapped across; mapping.wrong_side %d\n", inside_face,
              across_tangent_only, count_wrong_side(model, vertices, triangles, tangent_only, cut_faces, 0.01 * a));
  std::printf("cut ball: %d vertices (%d remapped), %zu cut-face triangles, mapping.wrong_side %d (nearest point: %d), %d fallbacks\n",
              n, static_cast<int>(list.size()), cut_faces.size(), wrong, naive, report.relaxed_fallbacks);
}

TEST(FrontMapping, TakesAFartherPointWhenTheNearestSharesNoParticleWithANeighboursPoint) {
  // A box, particles 0.2 apart from -0.4 to 0.4 (one on each face), integration cubes 0.1.
  const CorotationalEfg model(Vec3::Constant(-0.4), Vec3::Constant(0.4), Material{1e5, 0.3, 1000}, settings_with(0.1));
  // A patch of the top face: vertex 0 and its two neighbours, outward normal +z.
  const std::vector<Vec3> vertices{{0.05, 0.05, 0.4}, {0.15, 0.05, 0.4}, {0.05, 0.15, 0.4}};
  const std::vector<std::array<int, 3>> triangles{{0, 1, 2}};
  SurfaceEmbedding embedding;
  FrontMappingReport report;
  map_front_surface(model, vertices, triangles, {}, all_of(3), embedding, report);
  const int nearest = element_at(model, Vec3(0.05, 0.05, 0.35));
  ASSERT_GE(nearest, 0);
  EXPECT_EQ(embedding.elements[0], nearest);
  // The neighbours mapped (as by an earlier cut) to a point two particle cells away, whose
  // neighbourhood shares no particle with the nearest point's.
  const int far = element_at(model, Vec3(-0.25, 0.05, 0.35));
  ASSERT_GE(far, 0);
  ASSERT_FALSE(share_a_particle(model, nearest, far));
  embedding.elements[1] = embedding.elements[2] = far;
  const int remap[] = {0};
  report = {};
  map_front_surface(model, vertices, triangles, {}, remap, embedding, report);
  EXPECT_EQ(report.relaxed_fallbacks, 0);
  const int chosen = embedding.elements[0];
  EXPECT_NE(chosen, nearest);
  EXPECT_TRUE(share_a_particle(model, chosen, far));
  EXPECT_EQ(chosen, element_at(model, Vec3(-0.05, 0.05, 0.35)));
  // The nearest point passed criteria 2 and 3 (no planes); the chosen one is the nearest
  // below the tangent plane that shares a particle with the neighbours' point.
  const Vec3& x = vertices[0];
  EXPECT_LE(model.element_centres()[static_cast<size_t>(nearest)].z(), x.z());
  double best = std::numeric_limits<double>::infinity();
  for (int e = 0; e < model.element_count(); ++e)
    if (model.element_centres()[static_cast<size_t>(e)].z() <= x.z() && share_a_particle(model, e, far))
      best = std::min(best, (model.element_centres()[static_cast<size_t>(e)] - x).norm());
  EXPECT_EQ((model.element_centres()[static_cast<size_t>(chosen)] - x).norm(), best);
  EXPECT_LT((reproduced(model, embedding, 0) - x).norm(), 1e-12);
}

// A cut passing nearer a vertex than the inset: pulled in by the full inset the vertex would
// start across the cut, where every point on its own side looks hidden and those across look
// visible. The start is pulled in by less, so it is judged from its own side.
TEST(FrontMapping, JudgesAVertexACutPassesNearerThanTheInsetFromItsOwnSide) {
  const CorotationalEfg model(Vec3::Constant(-0.4), Vec3::Constant(0.4), Material{1e5, 0.3, 1000}, settings_with(0.1));
  const std::vector<Vec3> vertices{{0.05, 0.05, 0.4}, {-0.1, 0.05, 0.4}, {0.05, -0.05, 0.4}};
  const std::vector<std::array<int, 3>> triangles{{0, 1, 2}};
  SurfaceEmbedding embedding;
  FrontMappingReport report;
  map_front_surface(model, vertices, triangles, {}, all_of(3), embedding, report);
  // A wide cut face 2 mm under the top face: every integration point is below it, across.
  const std::vector<std::array<Vec3, 3>> faces{{Vec3(-1, -1, 0.398), Vec3(1, -1, 0.398), Vec3(0, 1, 0.398)}};
  EXPECT_EQ(count_wrong_side(model, vertices, triangles, embedding, faces, 0.01), 3);
  EXPECT_EQ(count_wrong_side(model, vertices, triangles, embedding, faces, 0.001), 3);
  // Mapped with the visibility criterion: no point is visible, so each vertex is relaxed and
  // counted (before, the full inset made the nearest points look visible: no fallback).
  const CutFaceIndex index(model, faces);
  const FrontVisibility visibility{&index, 0.01, {}, {}};
  FrontMappingReport relaxed;
  map_front_surface(model, vertices, triangles, {}, all_of(3), embedding, relaxed, &visibility);
  EXPECT_EQ(relaxed.relaxed_fallbacks, 3);
}

TEST(FrontMapping, ChecksCriterionOneAgainstNeighboursRemappedInTheSameCall) {
  const CorotationalEfg model(Vec3::Constant(-0.4), Vec3::Constant(0.4), Material{1e5, 0.3, 1000}, settings_with(0.1));
  // Three new vertices of the top face, all remapped together. Vertex 1 has a plane keeping
  // its point at x <= -0.2, two particle cells from vertex 0's nearest point.
  const std::vector<Vec3> vertices{{0.05, 0.05, 0.4}, {-0.1, 0.05, 0.4}, {0.05, -0.05, 0.4}};
  const std::vector<std::array<int, 3>> triangles{{0, 1, 2}};
  std::vector<std::vector<ConstraintPlane>> planes(2);
  planes[1].push_back({Vec3(-0.2, 0, 0), Vec3(1, 0, 0)});
  SurfaceEmbedding embedding;
  FrontMappingReport report;
  map_front_surface(model, vertices, triangles, planes, all_of(3), embedding, report);
  const int nearest = element_at(model, Vec3(0.05, 0.05, 0.35));
  const int of_1 = embedding.elements[1];
  EXPECT_LE(model.element_centres()[static_cast<size_t>(of_1)].x(), -0.2);
  ASSERT_FALSE(share_a_particle(model, nearest, of_1));
  // Vertex 0 gives up its nearest point for one that shares a particle with vertex 1's.
  EXPECT_EQ(embedding.elements[0], element_at(model, Vec3(-0.05, 0.05, 0.35)));
  for (int v = 0; v < 3; ++v)
    for (int u = 0; u < 3; ++u)
      EXPECT_TRUE(share_a_particle(model, embedding.elements[static_cast<size_t>(v)], embedding.elements[static_cast<size_t>(u)]))
          << "vertices " << v << ", " << u;
  // Vertex 1's plane and vertex 0's first-pass point (its nearest) exclude each other: the
  // second pass checks against first-pass points, so vertex 1 is relaxed, and counted.
  EXPECT_EQ(report.relaxed_fallbacks, 1);
}

TEST(FrontMapping, CountsAFallbackWhenThePlanesExcludeEveryPointAndStillGivesAValidRow) {
  const Mesh mesh = ball_surface(2, 1.0);
  const CorotationalEfg model = ball_model(1.0, 0.2);
  const int n = static_cast<int>(mesh.vertices.size());
  // Every point would have to lie at z >= 10; only the vertices below z = 0 get the plane.
  std::vector<std::vector<ConstraintPlane>> planes(static_cast<size_t>(n));
  int excluded = 0;
  for (int v = 0; v < n; ++v)
    if (mesh.vertices[static_cast<size_t>(v)].z() < 0) {
      planes[static_cast<size_t>(v)].push_back({Vec3(0, 0, 10), Vec3(0, 0, -1)});
      ++excluded;
    }
  SurfaceEmbedding embedding;
  FrontMappingReport report;
  map_front_surface(model, mesh.vertices, mesh.triangles, planes, all_of(n), embedding, report);
  EXPECT_EQ(report.mapped, n);
  EXPECT_EQ(report.relaxed_fallbacks, excluded);
  const std::vector<Vec3> normals = normals_of(mesh);
  for (int v = 0; v < n; ++v) {
    const Vec3& x = mesh.vertices[static_cast<size_t>(v)];
    EXPECT_LT((reproduced(model, embedding, v) - x).norm(), 1e-9) << "vertex " << v;
    // Relaxed, criterion 2 is the last kept: still below the tangent plane.
    EXPECT_LE((model.element_centres()[static_cast<size_t>(embedding.elements[static_cast<size_t>(v)])] - x).dot(normals[static_cast<size_t>(v)]), 0)
        << "vertex " << v;
  }
}

TEST(FrontMapping, RejectsBadInputNamingTheVertexOrTriangle) {
  const CorotationalEfg model(Vec3::Constant(-0.4), Vec3::Constant(0.4), Material{1e5, 0.3, 1000}, settings_with(0.1));
  const std::vector<Vec3> vertices{{0.05, 0.05, 0.4}, {0.15, 0.05, 0.4}, {0.05, 0.15, 0.4}};
  const std::vector<std::array<int, 3>> triangles{{0, 1, 2}};
  const auto map = [&](const std::vector<Vec3>& v, const std::vector<std::array<int, 3>>& t, std::vector<int> remap) {
    return message_of([&] {
      SurfaceEmbedding embedding;
      FrontMappingReport report;
      map_front_surface(model, v, t, {}, remap, embedding, report);
    });
  };
  EXPECT_NE(map(vertices, {{0, 1, 2}, {0, 3, 1}}, {0, 1, 2}).find("triangle 1 has vertex 3"), std::string::npos);
  EXPECT_NE(map(vertices, {{0, -1, 2}}, {0, 1, 2}).find("triangle 0 has vertex -1"), std::string::npos);
  std::vector<Vec3> bad = vertices;
  bad[2].y() = std::nan("");
  EXPECT_NE(map(bad, triangles, {0, 1, 2}).find("vertex 2 is not finite"), std::string::npos);
  EXPECT_NE(map(vertices, triangles, {0, 2, 1}).find("vertex 1 does not follow vertex 2"), std::string::npos);
  EXPECT_NE(map(vertices, triangles, {0, 1, 1, 2}).find("vertex 1 does not follow vertex 1"), std::string::npos);
  EXPECT_NE(map(vertices, triangles, {0, 1, 2, 3}).find("vertex 3 out of range"), std::string::npos);
  EXPECT_NE(map(vertices, triangles, {-1, 0, 1, 2}).find("vertex -1 out of range"), std::string::npos);
  EXPECT_NE(map(vertices, triangles, {0, 2}).find("vertex 1 has no row"), std::string::npos);
  // A bad input changes nothing.
  SurfaceEmbedding embedding;
  FrontMappingReport report;
  map_front_surface(model, vertices, triangles, {}, all_of(3), embedding, report);
  const SurfaceEmbedding before = embedding;
  const std::vector<int> wrong_order{2, 1};
  EXPECT_THROW(map_front_surface(model, vertices, triangles, {}, wrong_order, embedding, report), std::invalid_argument);
  EXPECT_EQ(embedding.elements, before.elements);
  EXPECT_EQ(embedding.weights, before.weights);
  EXPECT_EQ(report.mapped, 3);
  EXPECT_NE(message_of([&] { count_wrong_side(model, bad, triangles, embedding, {}, 0.0); }).find("count_wrong_side: vertex 2 is not finite"),
            std::string::npos);
}

TEST(FrontMapping, MapsAHundredThousandVertexSurfaceInBinsNotAScan) {
  const Mesh mesh = ball_surface(7, 1.0);
  const CorotationalEfg model = ball_model(1.0, 0.1);
  const int n = static_cast<int>(mesh.vertices.size());
  ASSERT_GT(n, 100000);
  SurfaceEmbedding embedding;
  FrontMappingReport report;
  const auto start = std::chrono::steady_clock::now();
  map_front_surface(model, mesh.vertices, mesh.triangles, {}, all_of(n), embedding, report);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(report.mapped, n);
  EXPECT_EQ(report.relaxed_fallbacks, 0);
  for (int v = 0; v < n; v += 997)
    EXPECT_LT((reproduced(model, embedding, v) - mesh.vertices[static_cast<size_t>(v)]).norm(), 1e-9) << "vertex " << v;
  std::printf("mapped %d vertices onto %d elements in %.3f s\n", n, model.element_count(), seconds);
}

// The stroke's vertices are numbered anew at every sample (front_surface.hpp); those behind
// the front come out the same and are told apart from what the front made anew, so that the
// world keeps their rows.
TEST(FrontMapping, TellsTheStrokesVerticesBehindTheFrontFromThoseItMadeAnew) {
  const Mesh mesh = ball_surface(3, 1.0);
  const int base_count = static_cast<int>(mesh.vertices.size());
  const double w = 0.08;
  FrontSurface surface(mesh.vertices, mesh.triangles, w);
  const auto height = [](int k) { return 1.3 - 2.6 * k / 39; };
  for (int k = 0; k < 20; ++k) ASSERT_TRUE(surface.advance(blade_at(height(k))).ok());
  const std::vector<Vec3> vertices_before = surface.vertices();
  const auto planes_before = surface.vertex_planes();
  const auto crack_before = surface.crack_front();
  const FrontVertexIdentity before =
      front_vertex_identity(surface.vertices(), surface.triangles(), surface.vertex_planes(), surface.crack_front(), base_count);
  ASSERT_TRUE(surface.advance(blade_at(height(20))).ok());
  const std::vector<Vec3>& vertices = surface.vertices();
  const int n = static_cast<int>(vertices.size());
  const FrontVertexIdentity now = front_vertex_identity(vertices, surface.triangles(), surface.vertex_planes(), surface.crack_front(), base_count);
  const std::vector<int> same = match_front_vertices(before, now);
  ASSERT_EQ(static_cast<int>(same.size()), n);

  // A match is the same vertex; each old vertex is matched once at most.
  std::set<int> taken;
  int matched = 0, behind = 0, behind_matched = 0, fresh = 0;
  const double front = height(20) + 0.02;  // the blade's highest point at the last sample
  for (int v = base_count; v < n; ++v) {
    const int u = same[static_cast<size_t>(v)];
    const bool far_behind = vertices[static_cast<size_t>(v)].z() > front + 4 * w;
    behind += far_behind;
    if (u < 0) {
      ++fresh;
      continue;
    }
    ++matched;
    behind_matched += far_behind;
    ASSERT_GE(u, base_count);
    ASSERT_LT(u, static_cast<int>(vertices_before.size()));
    EXPECT_TRUE(taken.insert(u).second) << "old vertex " << u << " matched twice";
    EXPECT_EQ(vertices[static_cast<size_t>(v)], vertices_before[static_cast<size_t>(u)]) << "vertex " << v;
    ASSERT_EQ(surface.vertex_planes()[static_cast<size_t>(v)].size(), planes_before[static_cast<size_t>(u)].size()) << "vertex " << v;
    for (size_t p = 0; p < planes_before[static_cast<size_t>(u)].size(); ++p)
      EXPECT_EQ(surface.vertex_planes()[static_cast<size_t>(v)][p].normal, planes_before[static_cast<size_t>(u)][p].normal);
    EXPECT_EQ(surface.crack_front()[static_cast<size_t>(v)], crack_before[static_cast<size_t>(u)]);
  }
  for (int v = 0; v < base_count; ++v) EXPECT_EQ(same[static_cast<size_t>(v)], -1);
  std::printf("front identity: %d stroke vertices, %d kept (%d of the %d more than 4 w behind the front), %d new\n", n - base_count,
              matched, behind_matched, behind, fresh);
  // Behind the front the cut is what it was: every vertex there is kept; along the front
  // the vertices move with the blade and are new.
  ASSERT_GT(behind, 50);
  EXPECT_EQ(behind_matched, behind);
  EXPECT_GT(fresh, 0);

  // A vertex whose triangles changed is not the same: one triangle turned over changes its
  // three corners.
  std::vector<std::array<int, 3>> turned = surface.triangles();
  size_t t = 0;
  while (t < turned.size() && !(turned[t][0] >= base_count && turned[t][1] >= base_count && turned[t][2] >= base_count &&
                                same[static_cast<size_t>(turned[t][0])] >= 0 && same[static_cast<size_t>(turned[t][1])] >= 0 &&
                                same[static_cast<size_t>(turned[t][2])] >= 0))
    ++t;
  ASSERT_LT(t, turned.size());
  std::swap(turned[t][1], turned[t][2]);
  std::vector<int> point_after_turn;
  const std::vector<int> after_turn = match_front_vertices(
      before, front_vertex_identity(vertices, turned, surface.vertex_planes(), surface.crack_front(), base_count), &point_after_turn);
  for (const int v : turned[t]) EXPECT_EQ(after_turn[static_cast<size_t>(v)], -1) << "corner " << v;
  // By key alone (the same point, planes and flag) they are still the same points, and every
  // other match is the same as before.
  ASSERT_EQ(point_after_turn.size(), after_turn.size());
  for (const int v : turned[t]) EXPECT_EQ(point_after_turn[static_cast<size_t>(v)], same[static_cast<size_t>(v)]) << "corner " << v;
  for (int v = 0; v < n; ++v) {
    if (after_turn[static_cast<size_t>(v)] >= 0) {
      EXPECT_EQ(point_after_turn[static_cast<size_t>(v)], after_turn[static_cast<size_t>(v)]) << "vertex " << v;
    }
  }
  int still = 0;
  for (int v = base_count; v < n; ++v) still += after_turn[static_cast<size_t>(v)] >= 0;
  EXPECT_EQ(still, matched - 3);
  // Against a different first base vertex nothing is matched.
  const std::vector<int> other =
      match_front_vertices(before, front_vertex_identity(vertices, surface.triangles(), surface.vertex_planes(), surface.crack_front(), base_count - 1));
  EXPECT_TRUE(std::all_of(other.begin(), other.end(), [](int u) { return u < 0; }));
  EXPECT_THROW(front_vertex_identity(vertices, surface.triangles(), surface.vertex_planes(), surface.crack_front(), n + 1), std::invalid_argument);
}

// The elements binned by cube, kept by the caller between calls (ElementCubes), follow the
// model: an element deactivated since the last call is no longer a candidate.
TEST(FrontMapping, KeptElementCubesFollowTheModelsDeactivatedElements) {
  CorotationalEfg model(Vec3::Constant(-0.4), Vec3::Constant(0.4), Material{1e5, 0.3, 1000}, settings_with(0.1));
  const std::vector<Vec3> vertices{{0.05, 0.05, 0.4}, {0.15, 0.05, 0.4}, {0.05, 0.15, 0.4}};
  const std::vector<std::array<int, 3>> triangles{{0, 1, 2}};
  ElementCubes cubes;
  SurfaceEmbedding embedding;
  FrontMappingReport report;
  map_front_surface(model, vertices, triangles, {}, all_of(3), embedding, report, nullptr, nullptr, &cubes);
  const int nearest = element_at(model, Vec3(0.05, 0.05, 0.35));
  ASSERT_GE(nearest, 0);
  ASSERT_EQ(embedding.elements[0], nearest);
  model.deactivate_element(nearest);
  const int remap[] = {0};
  map_front_surface(model, vertices, triangles, {}, remap, embedding, report, nullptr, nullptr, &cubes);
  EXPECT_NE(embedding.elements[0], nearest);
  EXPECT_TRUE(model.element_active(embedding.elements[0]));
  // The same as without a kept copy.
  SurfaceEmbedding fresh = embedding;
  map_front_surface(model, vertices, triangles, {}, remap, fresh, report);
  EXPECT_EQ(fresh.elements[0], embedding.elements[0]);
}
