#include "physics/cut/voxel_boundary.hpp"

#include "physics/fem/surface_snap.hpp"
#include "physics/fem/tet_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>

namespace incise::physics {

namespace {

// The six tetrahedra of a unit cube around its main diagonal (corner bits x = 1, y = 2, z = 4),
// all positively oriented: only used to let snap_boundary_to_surface judge element quality.
constexpr std::array<std::array<int, 4>, 6> cube_tets{{{0, 1, 3, 7}, {0, 3, 2, 7}, {0, 2, 6, 7},
                                                       {0, 6, 4, 7}, {0, 4, 5, 7}, {0, 5, 1, 7}}};

// The cubes of a box with one empty layer around it, so that every inside cube has all its faces.
class VoxelGrid {
 public:
  VoxelGrid(const std::function<bool(const Vec3&)>& inside, Vec3 lo, double cell, const std::array<int, 3>& counts)
      : cell_(cell), origin_(lo - Vec3::Constant(cell)), counts_(counts) {
    inside_.assign(static_cast<std::size_t>(counts_[0]) * counts_[1] * counts_[2], 0);
    for_interior([&](int i, int j, int k) {
      if (inside(centre(i, j, k))) inside_[cube(i, j, k)] = 1;
    });
  }

  int cube(int i, int j, int k) const { return i + counts_[0] * (j + counts_[1] * k); }
  int node(int i, int j, int k) const { return i + (counts_[0] + 1) * (j + (counts_[1] + 1) * k); }
  int node_count() const { return (counts_[0] + 1) * (counts_[1] + 1) * (counts_[2] + 1); }
  // The grid node at corner `corner` (bits x = 1, y = 2, z = 4) of cube (i, j, k).
  int corner_node(int i, int j, int k, int corner) const {
    return node(i + (corner & 1), j + ((corner >> 1) & 1), k + ((corner >> 2) & 1));
  }
  Vec3 centre(int i, int j, int k) const { return origin_ + cell_ * Vec3(i + 0.5, j + 0.5, k + 0.5); }
  Vec3 node_position(int n) const {
    const int nx = counts_[0] + 1, ny = counts_[1] + 1;
    return origin_ + cell_ * Vec3(n % nx, (n / nx) % ny, n / (nx * ny));
  }
  bool is_inside(int i, int j, int k) const { return inside_[cube(i, j, k)] != 0; }
  void fill(int i, int j, int k) { inside_[cube(i, j, k)] = 1; }
  bool on_margin(const std::array<int, 3>& at) const {
    for (int d = 0; d < 3; ++d)
      if (at[d] <= 0 || at[d] >= counts_[d] - 1) return true;
    return false;
  }
  const std::array<int, 3>& counts() const { return counts_; }

  // visit(i, j, k) over the cubes off the empty layer, in increasing index.
  template <typename Visit>
  void for_interior(const Visit& visit) const {
    for (int k = 1; k + 1 < counts_[2]; ++k)
      for (int j = 1; j + 1 < counts_[1]; ++j)
        for (int i = 1; i + 1 < counts_[0]; ++i) visit(i, j, k);
  }

  // The groups of node n's 8 cubes (slot s = dx + 2 dy + 4 dz): the connected sets of its
  // inside cubes through shared faces, each labelled by its smallest slot (-1: outside).
  std::array<std::int8_t, 8> node_groups(int n) const {
    const int nx = counts_[0] + 1, ny = counts_[1] + 1;
    const int i = n % nx, j = (n / nx) % ny, k = n / (nx * ny);
    std::array<std::int8_t, 8> label{};
    for (int s = 0; s < 8; ++s) {
      const int ci = i - 1 + (s & 1), cj = j - 1 + ((s >> 1) & 1), ck = k - 1 + ((s >> 2) & 1);
      const bool valid = ci >= 0 && cj >= 0 && ck >= 0 && ci < counts_[0] && cj < counts_[1] && ck < counts_[2];
      label[s] = static_cast<std::int8_t>(valid && is_inside(ci, cj, ck) ? s : -1);
    }
    for (bool changed = true; changed;) {
      changed = false;
      for (int s = 0; s < 8; ++s)
        for (int axis = 0; axis < 3; ++axis) {
          const int t = s | (1 << axis);
          if (t == s || label[s] < 0 || label[t] < 0 || label[s] == label[t]) continue;
          const std::int8_t joined = std::min(label[s], label[t]), from_s = label[s], from_t = label[t];
          for (auto& l : label)
            if (l == from_s || l == from_t) l = joined;
          changed = true;
        }
    }
    return label;
  }

 private:
  double cell_;
  Vec3 origin_;
  std::array<int, 3> counts_;
  std::vector<std::uint8_t> inside_;
};

// The grid nodes of a cube's face (cube at `at`, the -axis face for side 0, +axis for 1),
// counter-clockwise seen from outside (the -axis face's reversed, so both wind alike).
std::array<std::array<int, 3>, 4> face_corners(const std::array<int, 3>& at, int axis, int side) {
  const int u = (axis + 1) % 3, v = (axis + 2) % 3;
  const std::array<std::array<int, 2>, 4> square{{{0, 0}, {1, 0}, {1, 1}, {0, 1}}};
  std::array<std::array<int, 3>, 4> corners{};
  for (int c = 0; c < 4; ++c) {
    std::array<int, 3> node = at;
    node[axis] += side;
    node[u] += square[c][0];
    node[v] += square[c][1];
    corners[c] = node;
  }
  if (!side) std::swap(corners[1], corners[3]);
  return corners;
}

// The boundary of the inside cubes: triangles over vertices, each vertex a (node, group) as
// the faces meet them; `vertex_node` gets each vertex's grid node.
std::vector<std::array<int, 3>> boundary_faces(const VoxelGrid& grid, std::vector<int>& vertex_node) {
  vertex_node.clear();
  std::vector<int> vertex_of(8 * static_cast<std::size_t>(grid.node_count()), -1);
  std::vector<std::array<std::int8_t, 8>> groups(static_cast<std::size_t>(grid.node_count()));
  std::vector<std::uint8_t> grouped(static_cast<std::size_t>(grid.node_count()), 0);
  std::vector<std::array<int, 3>> triangles;
  grid.for_interior([&](int i, int j, int k) {
    if (!grid.is_inside(i, j, k)) return;
    const std::array<int, 3> at{i, j, k};
    for (int axis = 0; axis < 3; ++axis)
      for (int side = 0; side < 2; ++side) {
        std::array<int, 3> next = at;
        next[axis] += side ? 1 : -1;
        if (grid.is_inside(next[0], next[1], next[2])) continue;
        std::array<int, 4> ids{};
        const auto corners = face_corners(at, axis, side);
        for (int c = 0; c < 4; ++c) {
          const auto& n = corners[c];
          const int node = grid.node(n[0], n[1], n[2]);
          if (!grouped[node]) groups[node] = grid.node_groups(node), grouped[node] = 1;
          const int slot = (i - (n[0] - 1)) + 2 * (j - (n[1] - 1)) + 4 * (k - (n[2] - 1));
          int& id = vertex_of[8 * static_cast<std::size_t>(node) + static_cast<std::size_t>(groups[node][slot])];
          if (id < 0) id = static_cast<int>(vertex_node.size()), vertex_node.push_back(node);
          ids[c] = id;
        }
        triangles.push_back({ids[0], ids[1], ids[2]});
        triangles.push_back({ids[0], ids[2], ids[3]});
      }
  });
  return triangles;
}

// One pass filling the empty cubes at pinches; returns how many it filled. The four cubes
// around an edge used four times alternate full, empty, full, empty: the first empty one (in
// slot order) off the margin is filled.
int fill_pinches(VoxelGrid& grid) {
  std::vector<int> vertex_node;
  const auto triangles = boundary_faces(grid, vertex_node);
  std::vector<std::pair<int, int>> edges;
  for (const auto& t : triangles)
    for (int e = 0; e < 3; ++e) edges.emplace_back(std::min(t[e], t[(e + 1) % 3]), std::max(t[e], t[(e + 1) % 3]));
  std::sort(edges.begin(), edges.end());
  int filled = 0;
  const int nx = grid.counts()[0] + 1, ny = grid.counts()[1] + 1;
  for (std::size_t first = 0; first < edges.size();) {
    std::size_t last = first;
    while (last < edges.size() && edges[last] == edges[first]) ++last;
    const auto edge = edges[first];
    const std::size_t count = last - first;
    first = last;
    if (count <= 2) continue;
    const int n1 = std::min(vertex_node[edge.first], vertex_node[edge.second]);
    const int n2 = std::max(vertex_node[edge.first], vertex_node[edge.second]);
    const int step = n2 - n1;
    const int axis = step == 1 ? 0 : step == nx ? 1 : 2;
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    const std::array<std::array<int, 2>, 4> around{{{0, 0}, {-1, 0}, {-1, -1}, {0, -1}}};
    for (int c = 0; c < 4; ++c) {
      std::array<int, 3> gap{n1 % nx, (n1 / nx) % ny, n1 / (nx * ny)};
      gap[u] += around[c][0];
      gap[v] += around[c][1];
      if (grid.is_inside(gap[0], gap[1], gap[2]) || grid.on_margin(gap)) continue;
      grid.fill(gap[0], gap[1], gap[2]);
      ++filled;
      break;
    }
  }
  return filled;
}

// The boundary nodes' positions snapped onto the true surface, as for the tetrahedral bodies.
// The snap moves only nodes on the voxel boundary, judging each move by the elements around
// it, so its mesh needs only the cubes within two cubes of a boundary node: the cut-off mesh's
// inner boundary lies deeper than any boundary node, and its moves are discarded (the outcome
// is that of the whole voxel mesh, at a fraction of the cost).
std::vector<Vec3> snapped_nodes(const VoxelGrid& grid, const std::function<bool(const Vec3&)>& inside, double cell) {
  const int nodes = grid.node_count();
  std::vector<std::uint8_t> boundary(static_cast<std::size_t>(nodes), 0), near(static_cast<std::size_t>(nodes), 0);
  const auto for_cubes = [&](const auto& visit) {
    grid.for_interior([&](int i, int j, int k) {
      if (grid.is_inside(i, j, k)) visit(i, j, k);
    });
  };
  const auto any_corner = [&](const std::vector<std::uint8_t>& mark, int i, int j, int k) {
    for (int c = 0; c < 8; ++c)
      if (mark[grid.corner_node(i, j, k, c)]) return true;
    return false;
  };
  for_cubes([&](int i, int j, int k) {
    for (int axis = 0; axis < 3; ++axis)
      for (int side = 0; side < 2; ++side) {
        std::array<int, 3> next{i, j, k};
        next[axis] += side == 0 ? -1 : 1;
        if (grid.is_inside(next[0], next[1], next[2])) continue;
        for (const auto& corner : face_corners({i, j, k}, axis, side)) boundary[grid.node(corner[0], corner[1], corner[2])] = 1;
      }
  });
  for_cubes([&](int i, int j, int k) {
    if (any_corner(boundary, i, j, k))
      for (int c = 0; c < 8; ++c) near[grid.corner_node(i, j, k, c)] = 1;
  });
  TetMesh mesh;
  mesh.rest.resize(3 * static_cast<Eigen::Index>(nodes));
  for (int n = 0; n < nodes; ++n) mesh.rest.segment<3>(3 * static_cast<Eigen::Index>(n)) = grid.node_position(n);
  for_cubes([&](int i, int j, int k) {
    if (!any_corner(near, i, j, k)) return;
    for (const auto& tet : cube_tets) {
      std::array<int, 4> nodes_of{};
      for (int c = 0; c < 4; ++c) nodes_of[c] = grid.corner_node(i, j, k, tet[c]);
      mesh.tets.push_back(nodes_of);
    }
  });
  snap_boundary_to_surface(mesh, inside, 1.5 * cell, 0.1);
  std::vector<Vec3> positions(static_cast<std::size_t>(nodes));
  for (int n = 0; n < nodes; ++n)
    positions[n] = boundary[n] ? Vec3(mesh.rest.segment<3>(3 * static_cast<Eigen::Index>(n))) : grid.node_position(n);
  return positions;
}

}  // namespace

TriangleSurface voxel_boundary(const std::function<bool(const Vec3&)>& inside, Vec3 lo, Vec3 hi, double cell) {
  if (!(cell > 0) || !std::isfinite(cell))
    throw std::invalid_argument("voxel boundary: cell must be positive and finite, got " + std::to_string(cell));
  std::array<int, 3> counts{};
  for (int axis = 0; axis < 3; ++axis) {
    const double extent = (hi[axis] - lo[axis]) / cell;
    if (!(extent >= 0) || extent > 4096)
      throw std::invalid_argument("voxel boundary: the box is empty or holds more than 4096 cells along an axis");
    counts[axis] = static_cast<int>(std::ceil(extent * (1 - 1e-12))) + 2;
  }
  VoxelGrid grid(inside, lo, cell, counts);
  bool any = false;
  grid.for_interior([&](int i, int j, int k) { any = any || grid.is_inside(i, j, k); });
  if (!any) throw std::invalid_argument("voxel boundary: no cube centre is inside the body");
  // Pinches first, so that the snapped shape is the final one.
  for (int pass = 0; pass < 16 && fill_pinches(grid) > 0; ++pass) {
  }
  const std::vector<Vec3> nodes = snapped_nodes(grid, inside, cell);
  TriangleSurface surface;
  std::vector<int> vertex_node;
  surface.triangles = boundary_faces(grid, vertex_node);
  surface.vertices.reserve(vertex_node.size());
  for (int node : vertex_node) surface.vertices.push_back(nodes[static_cast<std::size_t>(node)]);
  return surface;
}

}  // namespace incise::physics
