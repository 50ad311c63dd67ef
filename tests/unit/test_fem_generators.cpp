#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <set>
#include <stdexcept>
#include <utility>

#include "physics/fem/tet_mesh.hpp"

namespace incise::physics {
namespace {

double signed_volume(const Vector& rest, const std::array<int, 4>& tet) {
  Mat3 edges;
  for (int c = 0; c < 3; ++c)
    edges.col(c) = rest.segment<3>(3 * tet[c + 1]) - rest.segment<3>(3 * tet[0]);
  return edges.determinant() / 6.0;
}

// Divergence theorem with F = x / 3: volume = sum over triangles of a . (b x c) / 6.
double enclosed_volume(const Vector& rest, const std::vector<std::array<int, 3>>& triangles) {
  double volume = 0;
  for (const auto& t : triangles) {
    volume += Vec3(rest.segment<3>(3 * t[0]))
                  .dot(Vec3(rest.segment<3>(3 * t[1])).cross(Vec3(rest.segment<3>(3 * t[2])))) /
              6.0;
  }
  return volume;
}

TEST(BoxTets, CountsVolumeAndOrientation) {
  const Vec3 min(-0.1, 0.0, 0.2), max(0.3, 0.1, 0.25);
  const TetMesh mesh = make_box_tets(min, max, {4, 3, 2});
  EXPECT_EQ(mesh.rest.size(), 3 * 5 * 4 * 3);
  ASSERT_EQ(mesh.tets.size(), 6u * 4 * 3 * 2);
  const double cell_volume = 0.1 * (0.1 / 3) * 0.025;
  for (const auto& tet : mesh.tets)
    EXPECT_NEAR(signed_volume(mesh.rest, tet), cell_volume / 6, 1e-12 * cell_volume);
  EXPECT_NEAR(total_volume(mesh.rest, mesh.tets), 0.4 * 0.1 * 0.05, 1e-15);
  EXPECT_EQ(Vec3(mesh.rest.tail<3>()), max);
}

TEST(BoxTets, BoundaryIsClosedOutwardAndConforming) {
  const std::array<int, 3> cells{3, 2, 4};
  const TetMesh mesh = make_box_tets(Vec3(0.5, -1, 0), Vec3(1.5, 1, 3), cells);
  const auto triangles = boundary_triangles(mesh.tets);
  // Conforming: only the box faces remain, 2 triangles per cell face.
  EXPECT_EQ(triangles.size(),
            4u * (cells[0] * cells[1] + cells[1] * cells[2] + cells[0] * cells[2]));
  // Closed and consistently oriented: every directed edge once, its reverse once.
  std::map<std::pair<int, int>, int> directed;
  for (const auto& t : triangles) {
    for (int e = 0; e < 3; ++e) ++directed[{t[e], t[(e + 1) % 3]}];
  }
  for (const auto& [edge, count] : directed) {
    EXPECT_EQ(count, 1) << edge.first << "-" << edge.second;
    const auto reverse = directed.find({edge.second, edge.first});
    ASSERT_NE(reverse, directed.end()) << "open edge " << edge.first << "-" << edge.second;
    EXPECT_EQ(reverse->second, 1);
  }
  // Outward: the divergence theorem gives +volume (inward would give -volume).
  EXPECT_NEAR(enclosed_volume(mesh.rest, triangles), 1.0 * 2.0 * 3.0, 1e-12);
  EXPECT_EQ(boundary_triangles(mesh.tets), triangles);  // deterministic
}

TEST(QuadraticBoxTets, NodesAreTheDoubledGridAndMidpointsAreMidpoints) {
  const std::array<int, 3> cells{2, 3, 1};
  const QuadraticTetMesh mesh = make_box_quadratic_tets(Vec3(0, 0, 0), Vec3(2, 3, 1), cells);
  EXPECT_EQ(mesh.rest.size(), 3 * 5 * 7 * 3);
  ASSERT_EQ(mesh.tets.size(), 6u * 2 * 3 * 1);
  std::set<int> used;
  std::vector<std::array<int, 4>> corners;
  for (const auto& tet : mesh.tets) {
    for (int node : tet) used.insert(node);
    corners.push_back({tet[0], tet[1], tet[2], tet[3]});
    for (int e = 0; e < 6; ++e) {
      const Vec3 a = mesh.rest.segment<3>(3 * tet[quadratic_tet_edges[e][0]]);
      const Vec3 b = mesh.rest.segment<3>(3 * tet[quadratic_tet_edges[e][1]]);
      EXPECT_LE((Vec3(mesh.rest.segment<3>(3 * tet[4 + e])) - 0.5 * (a + b)).norm(), 1e-15);
    }
  }
  EXPECT_EQ(used.size(), static_cast<size_t>(mesh.rest.size() / 3));
  for (const auto& tet : corners) EXPECT_GT(signed_volume(mesh.rest, tet), 0);
  EXPECT_NEAR(total_volume(mesh.rest, corners), 6.0, 1e-12);
}

TEST(TetsInside, SphereVolume) {
  const double radius = 0.05;
  const Vec3 centre(0.01, -0.02, 0.03);
  const auto inside = [&](const Vec3& x) { return (x - centre).squaredNorm() <= radius * radius; };
  const Vec3 min = centre - Vec3::Constant(1.1 * radius),
             max = centre + Vec3::Constant(1.1 * radius);
  const double cell = radius / 20;
  const TetMesh mesh = make_tets_inside(inside, min, max, cell);

  // Independent count of the cells whose centre is inside.
  const int per_axis = static_cast<int>(std::ceil(2.2 * radius / cell - 1e-9));
  ASSERT_EQ(per_axis, 44);
  const Vec3 spacing = (max - min) / per_axis;
  long long cells_inside = 0;
  for (int k = 0; k < per_axis; ++k)
    for (int j = 0; j < per_axis; ++j)
      for (int i = 0; i < per_axis; ++i)
        cells_inside += inside(min + spacing.cwiseProduct(Vec3(i + 0.5, j + 0.5, k + 0.5))) ? 1 : 0;
  ASSERT_EQ(mesh.tets.size(), static_cast<size_t>(6 * cells_inside));
  const double volume = total_volume(mesh.rest, mesh.tets);
  EXPECT_NEAR(volume, cells_inside * spacing.prod(), 1e-12 * volume);
  const double sphere = 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
  EXPECT_NEAR(volume / sphere, 1.0, 0.02);

  // Compact: every node is used, all tets positive, boundary encloses the same volume.
  std::vector<uint8_t> used(mesh.rest.size() / 3, 0);
  for (const auto& tet : mesh.tets) {
    EXPECT_GT(signed_volume(mesh.rest, tet), 0);
    for (int node : tet) used[node] = 1;
  }
  EXPECT_TRUE(std::all_of(used.begin(), used.end(), [](uint8_t u) { return u == 1; }));
  EXPECT_NEAR(enclosed_volume(mesh.rest, boundary_triangles(mesh.tets)), volume, 1e-12 * volume);
}

TEST(TetsInside, RejectsBadInput) {
  const auto everywhere = [](const Vec3&) { return true; };
  const auto nowhere = [](const Vec3&) { return false; };
  EXPECT_THROW(make_tets_inside(everywhere, Vec3::Zero(), Vec3::Ones(), 0.0),
               std::invalid_argument);
  EXPECT_THROW(make_tets_inside(everywhere, Vec3::Zero(), Vec3::Ones(), -0.1),
               std::invalid_argument);
  EXPECT_THROW(make_tets_inside(nowhere, Vec3::Zero(), Vec3::Ones(), 0.1), std::invalid_argument);
  EXPECT_THROW(make_tets_inside(everywhere, Vec3::Ones(), Vec3::Zero(), 0.1),
               std::invalid_argument);
  try {
    make_tets_inside(nowhere, Vec3::Zero(), Vec3::Ones(), 0.1);
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("no cell"), std::string::npos) << error.what();
  }
}

TEST(TetsInside, FullBoxEqualsBoxTets) {
  const auto everywhere = [](const Vec3&) { return true; };
  const TetMesh inside = make_tets_inside(everywhere, Vec3::Zero(), Vec3(1, 0.5, 0.25), 0.25);
  const TetMesh box = make_box_tets(Vec3::Zero(), Vec3(1, 0.5, 0.25), {4, 2, 1});
  EXPECT_EQ(inside.tets, box.tets);
  EXPECT_EQ(inside.rest, box.rest);
}

TEST(NodesInBox, SelectsClosedBox) {
  const TetMesh mesh = make_box_tets(Vec3::Zero(), Vec3(2, 1, 1), {2, 1, 1});
  const auto mask = nodes_in_box(mesh.rest, Vec3(-1, -1, -1), Vec3(0, 2, 2));
  EXPECT_EQ(std::count(mask.begin(), mask.end(), 1), 4);
  for (size_t node = 0; node < mask.size(); ++node) {
    EXPECT_EQ(mask[node] == 1, mesh.rest[3 * node] == 0.0);
  }
}

}  // namespace
}  // namespace incise::physics
