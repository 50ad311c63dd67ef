#include "physics/mss/hex_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>

namespace incise::physics {

const std::array<std::array<int, 2>, 12> kHexEdges = {{
    {0, 1}, {3, 2}, {4, 5}, {7, 6},  // along x
    {0, 3}, {1, 2}, {4, 7}, {5, 6},  // along y
    {0, 4}, {1, 5}, {2, 6}, {3, 7},  // along z
}};
const std::array<std::array<int, 2>, 4> kHexDiagonals = {{{0, 6}, {1, 7}, {2, 4}, {3, 5}}};

namespace {

Vec3 node_at(const Vector& x, int node) { return x.segment<3>(3 * static_cast<Eigen::Index>(node)); }

void check_box(const Vec3& min, const Vec3& max, const char* who) {
  if (!min.allFinite() || !max.allFinite() || !(max.array() > min.array()).all())
    throw std::invalid_argument(std::string(who) + ": the box's max must exceed its min on every axis");
}

// Grid nodes over [min, max], x fastest.
Vector grid_nodes(const Vec3& min, const Vec3& max, const std::array<int, 3>& cells) {
  const int nx = cells[0] + 1, ny = cells[1] + 1, nz = cells[2] + 1;
  Vector rest(3 * static_cast<Eigen::Index>(nx) * ny * nz);
  Eigen::Index at = 0;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const Vec3 t(double(i) / cells[0], double(j) / cells[1], double(k) / cells[2]);
        rest.segment<3>(at) = min + (max - min).cwiseProduct(t);
        at += 3;
      }
  return rest;
}

std::array<int, 8> cell_hex(int i, int j, int k, const std::array<int, 3>& cells) {
  const int nx = cells[0] + 1, ny = cells[1] + 1;
  const auto node = [&](int a, int b, int c) { return a + nx * (b + ny * c); };
  return {node(i, j, k),         node(i + 1, j, k),         node(i + 1, j + 1, k),     node(i, j + 1, k),
          node(i, j, k + 1),     node(i + 1, j, k + 1),     node(i + 1, j + 1, k + 1), node(i, j + 1, k + 1)};
}

}  // namespace

HexMesh make_box_hexes(Vec3 min, Vec3 max, std::array<int, 3> cells) {
  check_box(min, max, "make_box_hexes");
  for (int c : cells)
    if (c < 1) throw std::invalid_argument("make_box_hexes: every axis needs at least one cell");
  HexMesh mesh;
  mesh.rest = grid_nodes(min, max, cells);
  for (int k = 0; k < cells[2]; ++k)
    for (int j = 0; j < cells[1]; ++j)
      for (int i = 0; i < cells[0]; ++i) mesh.hexes.push_back(cell_hex(i, j, k, cells));
  return mesh;
}

HexMesh make_hexes_inside(const std::function<bool(const Vec3&)>& inside, Vec3 min, Vec3 max, double resolution) {
  check_box(min, max, "make_hexes_inside");
  if (!(resolution > 0)) throw std::invalid_argument("make_hexes_inside: resolution must be positive");
  std::array<int, 3> cells{};
  for (int a = 0; a < 3; ++a) cells[a] = std::max(1, static_cast<int>(std::ceil((max[a] - min[a]) / resolution)));
  const Vector grid = grid_nodes(min, max, cells);
  std::vector<int> renumbered(grid.size() / 3, -1);
  HexMesh mesh;
  for (int k = 0; k < cells[2]; ++k)
    for (int j = 0; j < cells[1]; ++j)
      for (int i = 0; i < cells[0]; ++i) {
        const Vec3 centre((i + 0.5) / cells[0], (j + 0.5) / cells[1], (k + 0.5) / cells[2]);
        if (!inside(min + (max - min).cwiseProduct(centre))) continue;
        mesh.hexes.push_back(cell_hex(i, j, k, cells));
      }
  int used = 0;
  for (auto& hex : mesh.hexes)
    for (int& node : hex) {
      if (renumbered[node] < 0) renumbered[node] = used++;
      node = renumbered[node];
    }
  mesh.rest.resize(3 * static_cast<Eigen::Index>(used));
  for (std::size_t node = 0; node < renumbered.size(); ++node)
    if (renumbered[node] >= 0)
      mesh.rest.segment<3>(3 * static_cast<Eigen::Index>(renumbered[node])) = grid.segment<3>(3 * static_cast<Eigen::Index>(node));
  return mesh;
}

double hex_volume(const Vector& x, const std::array<int, 8>& hex) {
  // The 5-tetrahedron split of a hexahedron: four corner tetrahedra and the central one.
  static constexpr int kTets[5][4] = {{0, 1, 3, 4}, {1, 2, 3, 6}, {1, 4, 5, 6}, {3, 6, 7, 4}, {1, 3, 4, 6}};
  double volume = 0;
  for (const auto& t : kTets) {
    const Vec3 a = node_at(x, hex[t[0]]);
    volume += std::abs((node_at(x, hex[t[1]]) - a).dot((node_at(x, hex[t[2]]) - a).cross(node_at(x, hex[t[3]]) - a))) / 6;
  }
  return volume;
}

Vec3 hex_edge_lengths(const Vector& x, const std::array<int, 8>& hex) {
  Vec3 lengths = Vec3::Zero();
  for (int e = 0; e < 12; ++e)
    lengths[e / 4] += 0.25 * (node_at(x, hex[kHexEdges[e][1]]) - node_at(x, hex[kHexEdges[e][0]])).norm();
  return lengths;
}

std::vector<std::array<int, 3>> hex_boundary_triangles(const std::vector<std::array<int, 8>>& hexes) {
  // Outward faces in the local order: -z, +z, -y, +x, +y, -x.
  static constexpr int kFaces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
  std::map<std::array<int, 4>, std::pair<int, std::array<int, 4>>> faces;  // sorted nodes -> (count, face)
  for (const auto& hex : hexes)
    for (const auto& f : kFaces) {
      std::array<int, 4> face{hex[f[0]], hex[f[1]], hex[f[2]], hex[f[3]]};
      std::array<int, 4> key = face;
      std::sort(key.begin(), key.end());
      auto [it, added] = faces.try_emplace(key, 0, face);
      ++it->second.first;
    }
  std::vector<std::array<int, 3>> triangles;
  for (const auto& [key, entry] : faces) {
    if (entry.first != 1) continue;
    const auto& q = entry.second;
    triangles.push_back({q[0], q[1], q[2]});
    triangles.push_back({q[0], q[2], q[3]});
  }
  return triangles;
}

}  // namespace incise::physics
