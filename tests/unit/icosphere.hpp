// A closed sphere mesh for the cutting tests: an icosahedron subdivided `levels` times onto the
// sphere of radius `radius` about the origin, counter-clockwise seen from outside, turned by
// `turn` (so that no vertex lies on a grid plane or on a test blade's plane).
#pragma once

#include "physics/core/model.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

namespace incise::testing {

struct SphereMesh {
  std::vector<physics::Vec3> vertices;
  std::vector<std::array<int, 3>> triangles;
};

inline SphereMesh icosphere(int levels, double radius, const Eigen::Matrix3d& turn) {
  const double g = (1 + std::sqrt(5.0)) / 2;
  SphereMesh mesh;
  mesh.vertices = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                   {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  mesh.triangles = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                    {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                    {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  for (physics::Vec3& v : mesh.vertices) v.normalize();
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<int, int>, int> halves;
    const auto half = [&](int a, int b) {
      const auto [it, added] = halves.try_emplace(std::minmax(a, b), static_cast<int>(mesh.vertices.size()));
      if (added) mesh.vertices.push_back((mesh.vertices[static_cast<size_t>(a)] + mesh.vertices[static_cast<size_t>(b)]).normalized());
      return it->second;
    };
    std::vector<std::array<int, 3>> finer;
    finer.reserve(4 * mesh.triangles.size());
    for (const auto& t : mesh.triangles) {
      const int ab = half(t[0], t[1]), bc = half(t[1], t[2]), ca = half(t[2], t[0]);
      finer.push_back({t[0], ab, ca});
      finer.push_back({t[1], bc, ab});
      finer.push_back({t[2], ca, bc});
      finer.push_back({ab, bc, ca});
    }
    mesh.triangles.swap(finer);
  }
  for (physics::Vec3& v : mesh.vertices) v = radius * (turn * v);
  return mesh;
}

}  // namespace incise::testing
