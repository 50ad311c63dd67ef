// Boundary snapping: the voxel body gets closer to the true shape and no element inverts.
#include "physics/fem/surface_snap.hpp"
#include "physics/cut/voxel_boundary.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <string>
#include <numbers>

using namespace incise::physics;

TEST(SurfaceSnap, SphereVolumeAndNodesApproachTheTrueSurface) {
  const double radius = 0.05, cell = 0.01;
  auto inside = [&](const Vec3& p) { return p.norm() <= radius; };
  TetMesh mesh = make_tets_inside(inside, Vec3::Constant(-radius), Vec3::Constant(radius), cell);
  const double exact = 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
  const double voxel_error = std::abs(total_volume(mesh.rest, mesh.tets) - exact) / exact;

  auto distance_error = [&](const TetMesh& m) {
    double worst = 0;
    for (const auto& f : boundary_triangles(m.tets))
      for (int v : f) worst = std::max(worst, std::abs(m.rest.segment<3>(3 * v).norm() - radius));
    return worst;
  };
  const double voxel_distance = distance_error(mesh);
  SnapReport report = snap_boundary_to_surface(mesh, inside, 1.5 * cell, 0.1);
  const double snapped_error = std::abs(total_volume(mesh.rest, mesh.tets) - exact) / exact;

  EXPECT_GT(report.boundary_nodes, 0);
  EXPECT_GT(report.moved, report.boundary_nodes / 2);
  EXPECT_GE(report.min_volume_ratio, 0.1);
  for (const auto& t : mesh.tets) {
    Vec3 a = mesh.rest.segment<3>(3 * t[0]);
    double volume = (mesh.rest.segment<3>(3 * t[1]) - a)
                        .dot((mesh.rest.segment<3>(3 * t[2]) - a).cross(mesh.rest.segment<3>(3 * t[3]) - a));
    ASSERT_GT(volume, 0.0);
  }
  // The voxel sphere misses a few percent of the volume; snapped it is within about 1 %.
  EXPECT_LT(snapped_error, voxel_error / 2) << "voxel " << voxel_error << " snapped " << snapped_error;
  EXPECT_LT(snapped_error, 0.02);
  // Fully moved nodes sit on the sphere to the bisection's precision.
  EXPECT_LT(distance_error(mesh), voxel_distance);
}

// Fairing an embedded surface (fair_surface_onto_shape), checked against the shapes' exact
// geometry: distance to the true surface, enclosed volume, the angles between neighbouring
// triangles, and the creases kept where the shape has them.
namespace {

using Triangles = std::vector<std::array<int, 3>>;

struct VoxelSurface {
  std::vector<Vec3> vertices;
  Triangles triangles;
};

VoxelSurface voxel_surface(const std::function<bool(const Vec3&)>& inside, const Vec3& lo, const Vec3& hi, double cell) {
  TriangleSurface surface = voxel_boundary(inside, lo, hi, cell);
  return {std::move(surface.vertices), std::move(surface.triangles)};
}

double enclosed_volume(const std::vector<Vec3>& x, const Triangles& triangles) {
  double six = 0;
  for (const auto& t : triangles) six += x[static_cast<std::size_t>(t[0])].dot(x[static_cast<std::size_t>(t[1])].cross(x[static_cast<std::size_t>(t[2])]));
  return six / 6;
}

// Angles (degrees) between the normals of the two triangles on each edge.
std::vector<double> dihedral_angles(const std::vector<Vec3>& x, const Triangles& triangles) {
  std::map<std::pair<int, int>, std::vector<Vec3>> normals;
  for (const auto& t : triangles) {
    const Vec3 normal = (x[static_cast<std::size_t>(t[1])] - x[static_cast<std::size_t>(t[0])])
                            .cross(x[static_cast<std::size_t>(t[2])] - x[static_cast<std::size_t>(t[0])])
                            .normalized();
    for (int c = 0; c < 3; ++c) {
      const int a = t[static_cast<std::size_t>(c)], b = t[static_cast<std::size_t>((c + 1) % 3)];
      normals[{std::min(a, b), std::max(a, b)}].push_back(normal);
    }
  }
  std::vector<double> angles;
  for (const auto& [edge, pair] : normals)
    if (pair.size() == 2) angles.push_back(std::acos(std::clamp(pair[0].dot(pair[1]), -1.0, 1.0)) * 180 / std::numbers::pi);
  return angles;
}

std::vector<int> used_vertices(const Triangles& triangles) {
  std::vector<int> used;
  for (const auto& t : triangles) used.insert(used.end(), t.begin(), t.end());
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  return used;
}

long count_over(const std::vector<double>& values, double bound) {
  return std::count_if(values.begin(), values.end(), [&](double v) { return v > bound; });
}

}  // namespace

TEST(FairSurface, PutsAVoxelSphereOnTheSphereAndEvensOutItsNotches) {
  const double radius = 0.04, cell = 0.0025;
  const Vec3 centre(0.0011, -0.0007, 0.0003);  // off the grid's symmetry
  auto inside = [&](const Vec3& p) { return (p - centre).norm() <= radius; };
  VoxelSurface surface = voxel_surface(inside, centre.array() - 1.1 * radius, centre.array() + 1.1 * radius, cell);
  const auto used = used_vertices(surface.triangles);
  const auto off_sphere = [&] {
    double worst = 0;
    for (const int v : used) worst = std::max(worst, std::abs((surface.vertices[static_cast<std::size_t>(v)] - centre).norm() - radius));
    return worst;
  };
  const double exact = 4.0 / 3.0 * std::numbers::pi * std::pow(radius, 3);
  const auto shifted = [&] {
    std::vector<Vec3> x = surface.vertices;
    for (auto& p : x) p -= centre;
    return x;
  };
  const double off_before = off_sphere();
  const double volume_before = enclosed_volume(shifted(), surface.triangles);
  const auto angles_before = dihedral_angles(surface.vertices, surface.triangles);

  const FairReport report = fair_surface_onto_shape(surface.vertices, surface.triangles, inside, cell);

  const double off_after = off_sphere();
  const double volume_after = enclosed_volume(shifted(), surface.triangles);
  const auto angles_after = dihedral_angles(surface.vertices, surface.triangles);
  std::printf("sphere R %.3f cell %.4f: %d vertices, %d projected, %d creases, %d slid, %d refused, %d not found\n"
              "  off the sphere %.3g -> %.3g m; volume error %.3f %% -> %.3f %%; edges over 30 deg %ld -> %ld, "
              "over 15 deg %ld -> %ld, largest %.1f -> %.1f deg\n",
              radius, cell, report.vertices, report.projected, report.creases, report.slid, report.refused,
              report.not_found, off_before, off_after, 100 * (volume_before - exact) / exact, 100 * (volume_after - exact) / exact,
              count_over(angles_before, 30), count_over(angles_after, 30), count_over(angles_before, 15), count_over(angles_after, 15),
              *std::max_element(angles_before.begin(), angles_before.end()), *std::max_element(angles_after.begin(), angles_after.end()));
  EXPECT_EQ(report.vertices, static_cast<int>(used.size()));
  EXPECT_EQ(report.not_found, 0);
  EXPECT_EQ(report.off_shape, 0);
  EXPECT_EQ(report.creases, 0);  // a sphere 16 cells across has none
  // On the sphere to the bisection's precision; the snap left vertices a good part of a cell off.
  EXPECT_GT(off_before, 0.1 * cell);
  EXPECT_LT(off_after, 1e-9);
  // Inscribed in the sphere, the polyhedron misses a little volume, less than a chord's sag
  // (cell^2 / 8R deep over the whole area) would.
  const double sag = std::pow(cell, 2) / (8 * radius) * 4 * std::numbers::pi * radius * radius;
  EXPECT_LT(volume_after, exact);
  EXPECT_GT(volume_after, exact - sag);
  // Neighbouring triangles of a sphere 32 cells round meet at a few degrees: no notch left.
  EXPECT_GT(count_over(angles_before, 30), 0);
  EXPECT_EQ(count_over(angles_after, 20), 0);
  // Nothing turned over: every triangle faces away from the centre.
  for (const auto& t : surface.triangles) {
    const Vec3 a = surface.vertices[static_cast<std::size_t>(t[0])] - centre;
    const Vec3 normal = (surface.vertices[static_cast<std::size_t>(t[1])] - surface.vertices[static_cast<std::size_t>(t[0])])
                            .cross(surface.vertices[static_cast<std::size_t>(t[2])] - surface.vertices[static_cast<std::size_t>(t[0])]);
    ASSERT_GT(normal.dot(a), 0.0);
  }
}

TEST(FairSurface, KeepsABoxsEdgesAndCornersAndItsVolume) {
  const double cell = 0.0025;
  const Vec3 lo(0.0, 0.0, 0.0), hi(0.03, 0.0125, 0.01);  // on the grid: the voxel box is the box
  auto inside = [&](const Vec3& p) { return (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all(); };
  VoxelSurface surface = voxel_surface(inside, lo.array() - cell, hi.array() + cell, cell);
  const auto used = used_vertices(surface.triangles);
  // How many of the box's planes p lies on (2: an edge, 3: a corner), and its distance to the
  // box's boundary. The snap's bisection leaves its nodes within 1e-7 m of where they were.
  const double near = 1e-6;
  const auto planes_at = [&](const Vec3& p) {
    int count = 0;
    for (int axis = 0; axis < 3; ++axis) count += std::abs(p[axis] - lo[axis]) < near || std::abs(p[axis] - hi[axis]) < near;
    return count;
  };
  const auto off_boundary = [&](const Vec3& p) {
    const Eigen::Array3d below = lo.array() - p.array(), above = p.array() - hi.array();
    const Eigen::Array3d outside = below.max(above);
    if ((outside <= 0).all()) return -outside.maxCoeff();
    return outside.max(0.0).matrix().norm();
  };
  const std::vector<Vec3> before = surface.vertices;
  const FairReport report = fair_surface_onto_shape(surface.vertices, surface.triangles, inside, cell);
  std::printf("box: %d vertices, %d creases, %d slid, %d refused\n", report.vertices, report.creases, report.slid, report.refused);
  int on_edges = 0;
  for (const int v : used) {
    const Vec3& p0 = before[static_cast<std::size_t>(v)];
    const Vec3& p = surface.vertices[static_cast<std::size_t>(v)];
    ASSERT_GE(planes_at(p0), 1) << "the voxel box is the box";
    // On an edge or a corner: it stays there.
    if (planes_at(p0) >= 2) {
      ++on_edges;
      EXPECT_EQ(planes_at(p), planes_at(p0)) << "vertex " << v;
      EXPECT_LT((p - p0).norm(), near) << "vertex " << v;
    }
    EXPECT_LT(off_boundary(p), 1e-9) << "vertex " << v;
  }
  EXPECT_GT(on_edges, 0);
  EXPECT_EQ(report.creases, on_edges);
  EXPECT_EQ(report.off_shape + report.not_found, 0);
  EXPECT_NEAR(enclosed_volume(surface.vertices, surface.triangles), (hi - lo).prod(), 1e-6 * (hi - lo).prod());
}

TEST(FairSurface, PutsACappedCylinderOnItsBoundaryCloserToItsVolume) {
  const double radius = 0.012, length = 0.05, cell = 0.002;
  const Vec3 centre(0.0007, 0.0013, 0.0004);
  // Axis along x, off the grid: the rims are creases the snap only approximates.
  auto inside = [&](const Vec3& p) {
    const Vec3 d = p - centre;
    return std::abs(d.x()) <= 0.5 * length && d.y() * d.y() + d.z() * d.z() <= radius * radius;
  };
  // The distance to the cylinder's boundary (zero on it).
  auto distance = [&](const Vec3& p) {
    const Vec3 d = p - centre;
    const double side = std::hypot(d.y(), d.z()) - radius, cap = std::abs(d.x()) - 0.5 * length;
    if (side <= 0 && cap <= 0) return -std::max(side, cap);
    return std::hypot(std::max(side, 0.0), std::max(cap, 0.0));
  };
  const Vec3 half(0.5 * length + 2 * cell, radius + 2 * cell, radius + 2 * cell);
  VoxelSurface surface = voxel_surface(inside, centre - half, centre + half, cell);
  const auto used = used_vertices(surface.triangles);
  const double exact = std::numbers::pi * radius * radius * length;
  const auto shifted_volume = [&] {
    std::vector<Vec3> x = surface.vertices;
    for (auto& p : x) p -= centre;
    return enclosed_volume(x, surface.triangles);
  };
  double off_before = 0;
  for (const int v : used) off_before = std::max(off_before, distance(surface.vertices[static_cast<std::size_t>(v)]));
  const double volume_before = shifted_volume();
  const FairReport report = fair_surface_onto_shape(surface.vertices, surface.triangles, inside, cell);
  double off_after = 0;
  int on_rim = 0;
  for (const int v : used) {
    const Vec3 d = surface.vertices[static_cast<std::size_t>(v)] - centre;
    off_after = std::max(off_after, distance(surface.vertices[static_cast<std::size_t>(v)]));
    on_rim += std::abs(std::hypot(d.y(), d.z()) - radius) < 0.05 * cell && std::abs(std::abs(d.x()) - 0.5 * length) < 0.05 * cell;
  }
  const double volume_after = shifted_volume();
  std::printf("cylinder: %d vertices, %d creases, %d slid, %d refused, %d not found; off %.3g -> %.3g m; "
              "volume error %.3f %% -> %.3f %%; %d vertices on the rims\n",
              report.vertices, report.creases, report.slid, report.refused, report.not_found, off_before, off_after,
              100 * (volume_before - exact) / exact, 100 * (volume_after - exact) / exact, on_rim);
  EXPECT_EQ(report.not_found, 0);
  EXPECT_LT(off_after, 1e-9);
  EXPECT_GT(report.creases, 0);
  // The rims stay sharp: the faired volume is that of the cylinder less the sides' chord sag.
  const double sag = std::pow(cell, 2) / (8 * radius) * 2 * std::numbers::pi * radius * length;
  EXPECT_LT(std::abs(volume_after - exact), sag);
  EXPECT_LT(std::abs(volume_after - exact), std::abs(volume_before - exact));
}

TEST(FairSurface, RefusesBadInputBeforeMovingAnything) {
  auto inside = [](const Vec3& p) { return p.norm() <= 1.0; };
  std::vector<Vec3> vertices{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const std::vector<Vec3> before = vertices;
  const auto message = [&](const Triangles& triangles, double cell, int passes) {
    try {
      fair_surface_onto_shape(vertices, triangles, inside, cell, passes);
    } catch (const std::invalid_argument& error) {
      return std::string(error.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message({{0, 1, 3}}, 0.1, 3).find("triangle 0 has vertex 3"), std::string::npos);
  EXPECT_NE(message({{0, 1, 2}}, 0.0, 3).find("cell"), std::string::npos);
  EXPECT_NE(message({{0, 1, 2}}, std::nan(""), 3).find("cell"), std::string::npos);
  EXPECT_NE(message({{0, 1, 2}}, 0.1, -1).find("passes"), std::string::npos);
  vertices[2].x() = std::nan("");
  EXPECT_NE(message({{0, 1, 2}}, 0.1, 3).find("vertex 2 is not finite"), std::string::npos);
  vertices[2] = before[2];
  EXPECT_EQ(vertices, before);
}
