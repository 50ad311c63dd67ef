#include "physics/fem/tet_mesh.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <climits>
#include <cmath>
#include <stdexcept>
#include <string>

namespace incise::physics {

namespace {

using Offset = std::array<int, 3>;  // corner of the unit cell, components 0 or 1
using CellTet = std::array<Offset, 4>;

// The 6 Kuhn tets of the unit cube: for each permutation (a, b, c) of the axes, the path
// 0 -> e_a -> e_a + e_b -> (1, 1, 1). det[e_a, e_a + e_b, 1] equals the permutation's sign,
// so odd permutations get corners 1 and 2 swapped to be positively oriented.
std::array<CellTet, 6> kuhn_tets() {
  const std::array<std::array<int, 3>, 6> permutations{
      {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}}};
  std::array<CellTet, 6> result{};
  for (int t = 0; t < 6; ++t) {
    const auto& axes = permutations[t];
    Offset corner{0, 0, 0};
    result[t][0] = corner;
    for (int step = 0; step < 3; ++step) {
      corner[axes[step]] = 1;
      result[t][step + 1] = corner;
    }
    if (t >= 3) std::swap(result[t][1], result[t][2]);  // the odd permutations
  }
  return result;
}

void check_box(const Vec3& min, const Vec3& max, const char* function) {
  for (int axis = 0; axis < 3; ++axis) {
    if (!std::isfinite(min[axis]) || !std::isfinite(max[axis]) || !(max[axis] > min[axis])) {
      throw std::invalid_argument(std::string(function) +
                                  ": need finite min < max on every axis (axis " +
                                  std::to_string(axis) + ")");
    }
  }
}

void check_cells(const std::array<int, 3>& cells, int node_factor, const char* function) {
  long long nodes = 1;
  for (int axis = 0; axis < 3; ++axis) {
    if (cells[axis] < 1) {
      throw std::invalid_argument(std::string(function) + ": cells[" + std::to_string(axis) +
                                  "] = " + std::to_string(cells[axis]) + ", must be >= 1");
    }
    nodes *= static_cast<long long>(node_factor) * cells[axis] + 1;
    if (nodes > INT_MAX / 3) {
      throw std::invalid_argument(std::string(function) + ": too many nodes for int indices");
    }
  }
  if (6LL * cells[0] * cells[1] * cells[2] > INT_MAX) {
    throw std::invalid_argument(std::string(function) + ": too many tets");
  }
}

Vector grid_positions(const Vec3& min, const Vec3& max, const std::array<int, 3>& divisions) {
  const int nodes_x = divisions[0] + 1, nodes_y = divisions[1] + 1, nodes_z = divisions[2] + 1;
  Vector rest(3 * static_cast<Eigen::Index>(nodes_x) * nodes_y * nodes_z);
  Eigen::Index index = 0;
  for (int k = 0; k < nodes_z; ++k) {
    for (int j = 0; j < nodes_y; ++j) {
      for (int i = 0; i < nodes_x; ++i) {
        // Interpolate from both ends so the last node lands exactly on max.
        const Vec3 fraction(double(i) / divisions[0], double(j) / divisions[1],
                            double(k) / divisions[2]);
        rest.segment<3>(3 * index) =
            (Vec3::Ones() - fraction).cwiseProduct(min) + fraction.cwiseProduct(max);
        ++index;
      }
    }
  }
  return rest;
}

}  // namespace

TetMesh make_box_tets(Vec3 min, Vec3 max, std::array<int, 3> cells) {
  check_box(min, max, "make_box_tets");
  check_cells(cells, 1, "make_box_tets");
  TetMesh mesh;
  mesh.rest = grid_positions(min, max, cells);
  const int nodes_x = cells[0] + 1, nodes_y = cells[1] + 1;
  const auto node = [&](int i, int j, int k) { return i + nodes_x * (j + nodes_y * k); };
  const auto split = kuhn_tets();
  mesh.tets.reserve(6 * static_cast<size_t>(cells[0]) * cells[1] * cells[2]);
  for (int k = 0; k < cells[2]; ++k) {
    for (int j = 0; j < cells[1]; ++j) {
      for (int i = 0; i < cells[0]; ++i) {
        for (const CellTet& cell_tet : split) {
          std::array<int, 4> tet{};
          for (int c = 0; c < 4; ++c) {
            tet[c] = node(i + cell_tet[c][0], j + cell_tet[c][1], k + cell_tet[c][2]);
          }
          mesh.tets.push_back(tet);
        }
      }
    }
  }
  return mesh;
}

QuadraticTetMesh make_box_quadratic_tets(Vec3 min, Vec3 max, std::array<int, 3> cells) {
  check_box(min, max, "make_box_quadratic_tets");
  check_cells(cells, 2, "make_box_quadratic_tets");
  const std::array<int, 3> fine{2 * cells[0], 2 * cells[1], 2 * cells[2]};
  QuadraticTetMesh mesh;
  mesh.rest = grid_positions(min, max, fine);
  const int nodes_x = fine[0] + 1, nodes_y = fine[1] + 1;
  const auto node = [&](const Offset& point) {
    return point[0] + nodes_x * (point[1] + nodes_y * point[2]);
  };
  const auto split = kuhn_tets();
  mesh.tets.reserve(6 * static_cast<size_t>(cells[0]) * cells[1] * cells[2]);
  for (int k = 0; k < cells[2]; ++k) {
    for (int j = 0; j < cells[1]; ++j) {
      for (int i = 0; i < cells[0]; ++i) {
        for (const CellTet& cell_tet : split) {
          std::array<Offset, 4> corner{};  // on the fine grid
          for (int c = 0; c < 4; ++c) {
            corner[c] = {2 * (i + cell_tet[c][0]), 2 * (j + cell_tet[c][1]),
                         2 * (k + cell_tet[c][2])};
          }
          std::array<int, 10> tet{};
          for (int c = 0; c < 4; ++c) tet[c] = node(corner[c]);
          for (int e = 0; e < 6; ++e) {
            const Offset& a = corner[quadratic_tet_edges[e][0]];
            const Offset& b = corner[quadratic_tet_edges[e][1]];
            tet[4 + e] = node({(a[0] + b[0]) / 2, (a[1] + b[1]) / 2, (a[2] + b[2]) / 2});
          }
          mesh.tets.push_back(tet);
        }
      }
    }
  }
  return mesh;
}

TetMesh make_tets_inside(const std::function<bool(const Vec3&)>& inside, Vec3 min, Vec3 max,
                         double cell_size) {
  if (!(cell_size > 0.0) || !std::isfinite(cell_size)) {
    throw std::invalid_argument("make_tets_inside: cell_size must be positive and finite, got " +
                                std::to_string(cell_size));
  }
  check_box(min, max, "make_tets_inside");
  std::array<int, 3> cells{};
  for (int axis = 0; axis < 3; ++axis) {
    // The small shrink keeps an extent that is an exact multiple of cell_size from gaining a
    // cell through rounding.
    const double count = std::ceil((max[axis] - min[axis]) / cell_size * (1.0 - 1e-12));
    if (count > INT_MAX / 8) {
      throw std::invalid_argument("make_tets_inside: cell_size too small for the box");
    }
    cells[axis] = std::max(1, static_cast<int>(count));
  }
  check_cells(cells, 1, "make_tets_inside");

  const Vec3 spacing((max[0] - min[0]) / cells[0], (max[1] - min[1]) / cells[1],
                     (max[2] - min[2]) / cells[2]);
  const int nodes_x = cells[0] + 1, nodes_y = cells[1] + 1, nodes_z = cells[2] + 1;
  const auto grid_node = [&](int i, int j, int k) { return i + nodes_x * (j + nodes_y * k); };
  const auto split = kuhn_tets();

  std::vector<std::array<int, 4>> grid_tets;
  for (int k = 0; k < cells[2]; ++k) {
    for (int j = 0; j < cells[1]; ++j) {
      for (int i = 0; i < cells[0]; ++i) {
        const Vec3 centre = min + Vec3(i + 0.5, j + 0.5, k + 0.5).cwiseProduct(spacing);
        if (!inside(centre)) continue;
        for (const CellTet& cell_tet : split) {
          std::array<int, 4> tet{};
          for (int c = 0; c < 4; ++c) {
            tet[c] = grid_node(i + cell_tet[c][0], j + cell_tet[c][1], k + cell_tet[c][2]);
          }
          grid_tets.push_back(tet);
        }
      }
    }
  }
  if (grid_tets.empty()) {
    throw std::invalid_argument(
        "make_tets_inside: no cell centre is inside the shape (check the box and cell_size)");
  }

  // Compact: referenced grid nodes, in grid order, get consecutive indices.
  const Vector grid = grid_positions(min, max, cells);
  std::vector<int> new_index(static_cast<size_t>(nodes_x) * nodes_y * nodes_z, -1);
  for (const auto& tet : grid_tets) {
    for (int node : tet) new_index[node] = 0;
  }
  int count = 0;
  for (int& index : new_index) {
    if (index == 0) index = count++;
  }
  TetMesh mesh;
  mesh.rest.resize(3 * static_cast<Eigen::Index>(count));
  for (size_t node = 0; node < new_index.size(); ++node) {
    if (new_index[node] >= 0) {
      mesh.rest.segment<3>(3 * new_index[node]) =
          grid.segment<3>(3 * static_cast<Eigen::Index>(node));
    }
  }
  mesh.tets = std::move(grid_tets);
  for (auto& tet : mesh.tets) {
    for (int& node : tet) node = new_index[node];
  }
  return mesh;
}

std::vector<std::array<int, 3>> boundary_triangles(const std::vector<std::array<int, 4>>& tets) {
  // Outward faces of a positive tet, listed opposite corner 0, 1, 2, 3.
  static constexpr std::array<std::array<int, 3>, 4> faces{
      {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}}};
  struct Entry {
    std::array<int, 3> key;  // sorted corners: equal for the two sides of a shared face
    size_t face;             // 4 * tet + local face
  };
  std::vector<Entry> entries;
  entries.reserve(4 * tets.size());
  for (size_t t = 0; t < tets.size(); ++t) {
    for (int f = 0; f < 4; ++f) {
      std::array<int, 3> key{tets[t][faces[f][0]], tets[t][faces[f][1]], tets[t][faces[f][2]]};
      std::sort(key.begin(), key.end());
      entries.push_back({key, 4 * t + f});
    }
  }
  // Compared component by component (std::array's == and < go through memcmp and a
  // three-way compare: several times slower on the millions of faces of a fine snap mesh).
  std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
    for (int i = 0; i < 3; ++i)
      if (a.key[i] != b.key[i]) return a.key[i] < b.key[i];
    return a.face < b.face;
  });
  std::vector<size_t> single;
  for (size_t begin = 0; begin < entries.size();) {
    size_t end = begin + 1;
    const auto& key = entries[begin].key;
    while (end < entries.size() && entries[end].key[0] == key[0] && entries[end].key[1] == key[1] &&
           entries[end].key[2] == key[2])
      ++end;
    if (end - begin == 1) single.push_back(entries[begin].face);
    begin = end;
  }
  std::sort(single.begin(), single.end());
  std::vector<std::array<int, 3>> triangles;
  triangles.reserve(single.size());
  for (size_t id : single) {
    const auto& tet = tets[id / 4];
    const auto& face = faces[id % 4];
    triangles.push_back({tet[face[0]], tet[face[1]], tet[face[2]]});
  }
  return triangles;
}

std::vector<uint8_t> nodes_in_box(const Vector& rest, Vec3 min, Vec3 max) {
  const Eigen::Index nodes = rest.size() / 3;
  std::vector<uint8_t> mask(static_cast<size_t>(nodes), 0);
  for (Eigen::Index node = 0; node < nodes; ++node) {
    const Vec3 x = rest.segment<3>(3 * node);
    mask[static_cast<size_t>(node)] =
        (x.array() >= min.array()).all() && (x.array() <= max.array()).all() ? 1 : 0;
  }
  return mask;
}

double total_volume(const Vector& rest, const std::vector<std::array<int, 4>>& tets) {
  double volume = 0;
  for (const auto& tet : tets) {
    const Vec3 x0 = rest.segment<3>(3 * tet[0]);
    Mat3 edges;
    for (int c = 0; c < 3; ++c) edges.col(c) = rest.segment<3>(3 * tet[c + 1]) - x0;
    volume += edges.determinant() / 6.0;
  }
  return volume;
}

}  // namespace incise::physics
