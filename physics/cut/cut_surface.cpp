#include "physics/cut/cut_surface.hpp"

#include "physics/core/contact.hpp"
#include "physics/efg/mls.hpp"
#include "physics/fem/surface_snap.hpp"
#include "physics/fem/tet_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

namespace incise::physics {

namespace {

// The grid nodes of a cube's face (cube at `at`, the -axis face for side 0, +axis for 1), in
// the order the surface's quads take them (the -axis face's reversed, so that both wind the
// same way relative to the outward normal).
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

std::array<Vec3, 2> box_of(const RestTriangle& t) {
  return {t.a.cwiseMin(t.b).cwiseMin(t.c), t.a.cwiseMax(t.b).cwiseMax(t.c)};
}

bool boxes_overlap(const Vec3& lo_a, const Vec3& hi_a, const Vec3& lo_b, const Vec3& hi_b, double reach) {
  for (int axis = 0; axis < 3; ++axis) {
    if (lo_a[axis] > hi_b[axis] + reach || lo_b[axis] > hi_a[axis] + reach) return false;
  }
  return true;
}

// The six tetrahedra of a unit cube around its main diagonal (corner bits x = 1, y = 2, z = 4),
// all positively oriented: only used to let snap_boundary_to_surface judge element quality.
constexpr std::array<std::array<int, 4>, 6> cube_tets{{{0, 1, 3, 7}, {0, 3, 2, 7}, {0, 2, 6, 7},
                                                       {0, 6, 4, 7}, {0, 4, 5, 7}, {0, 5, 1, 7}}};

}  // namespace

std::optional<double> segment_crosses_triangle(const Vec3& p, const Vec3& q, const RestTriangle& t) {
  // Moller-Trumbore on the closed triangle and the closed segment.
  const Vec3 direction = q - p;
  const Vec3 edge_1 = t.b - t.a, edge_2 = t.c - t.a;
  const Vec3 h = direction.cross(edge_2);
  const double determinant = edge_1.dot(h);
  const double scale = edge_1.norm() * edge_2.norm() * direction.norm();
  if (!(scale > 0) || std::abs(determinant) <= 1e-12 * scale) return std::nullopt;  // parallel or degenerate
  const double inverse = 1.0 / determinant;
  const Vec3 s = p - t.a;
  const double u = inverse * s.dot(h);
  if (u < 0 || u > 1) return std::nullopt;
  const Vec3 k = s.cross(edge_1);
  const double v = inverse * direction.dot(k);
  if (v < 0 || u + v > 1) return std::nullopt;
  const double along = inverse * edge_2.dot(k);
  if (along < 0 || along > 1) return std::nullopt;
  return along;
}

const std::vector<int>* RestCut::bin(long long i, long long j, long long k) const {
  i -= bins_lo_[0], j -= bins_lo_[1], k -= bins_lo_[2];
  if (i < 0 || j < 0 || k < 0 || i >= bins_count_[0] || j >= bins_count_[1] || k >= bins_count_[2]) return nullptr;
  return &bins_[static_cast<size_t>(i + bins_count_[0] * (j + bins_count_[1] * k))];
}

std::vector<int>* RestCut::bin(long long i, long long j, long long k) {
  return const_cast<std::vector<int>*>(std::as_const(*this).bin(i, j, k));
}

void RestCut::cover(const std::array<long long, 3>& first, const std::array<long long, 3>& last) {
  bool inside = !bins_.empty();
  for (int axis = 0; axis < 3; ++axis)
    inside = inside && first[axis] >= bins_lo_[axis] && last[axis] < bins_lo_[axis] + bins_count_[axis];
  if (inside) return;
  // Grow to the union, with as much again as margin on each side that grew (amortised).
  std::array<long long, 3> lo{}, count{};
  for (int axis = 0; axis < 3; ++axis) {
    long long new_lo = first[axis], new_hi = last[axis];
    if (!bins_.empty()) {
      new_lo = std::min(new_lo, bins_lo_[axis]);
      new_hi = std::max(new_hi, bins_lo_[axis] + bins_count_[axis] - 1);
    }
    const long long margin = (new_hi - new_lo + 1) / 2 + 1;
    if (bins_.empty() || new_lo < bins_lo_[axis]) new_lo -= margin;
    if (bins_.empty() || new_hi >= bins_lo_[axis] + bins_count_[axis]) new_hi += margin;
    lo[axis] = new_lo;
    count[axis] = new_hi - new_lo + 1;
  }
  std::vector<std::vector<int>> grown(static_cast<size_t>(count[0] * count[1] * count[2]));
  for (long long k = 0; k < bins_count_[2]; ++k)
    for (long long j = 0; j < bins_count_[1]; ++j)
      for (long long i = 0; i < bins_count_[0]; ++i) {
        auto& from = bins_[static_cast<size_t>(i + bins_count_[0] * (j + bins_count_[1] * k))];
        if (from.empty()) continue;
        const long long gi = i + bins_lo_[0] - lo[0], gj = j + bins_lo_[1] - lo[1], gk = k + bins_lo_[2] - lo[2];
        grown[static_cast<size_t>(gi + count[0] * (gj + count[1] * gk))] = std::move(from);
      }
  bins_ = std::move(grown);
  bins_lo_ = lo;
  bins_count_ = count;
}

template <typename Visit>
void RestCut::for_each_near(const Vec3& lo, const Vec3& hi, double reach, const Visit& visit) const {
  if (triangles_.empty()) return;
  ++query_;
  std::array<long long, 3> first{}, last{};
  for (int axis = 0; axis < 3; ++axis) {
    // Only the bins that exist: clamped to the covered range (none outside it holds anything).
    first[axis] = std::max(bins_lo_[axis], static_cast<long long>(std::floor((lo[axis] - reach) / cell_)));
    last[axis] = std::min(bins_lo_[axis] + bins_count_[axis] - 1,
                          static_cast<long long>(std::floor((hi[axis] + reach) / cell_)));
    if (last[axis] < first[axis]) return;
  }
  // A query box much larger than the cut: scan the triangles instead of the cells.
  const double cells = static_cast<double>(last[0] - first[0] + 1) * (last[1] - first[1] + 1) * (last[2] - first[2] + 1);
  if (cells > 4.0 * static_cast<double>(triangles_.size())) {
    for (size_t t = 0; t < triangles_.size(); ++t)
      if (boxes_overlap(lo, hi, boxes_[t][0], boxes_[t][1], reach) && visit(static_cast<int>(t))) return;
    return;
  }
  for (long long k = first[2]; k <= last[2]; ++k)
    for (long long j = first[1]; j <= last[1]; ++j)
      for (long long i = first[0]; i <= last[0]; ++i) {
        for (int t : *bin(i, j, k)) {
          if (stamp_[t] == query_) continue;
          stamp_[t] = query_;
          if (boxes_overlap(lo, hi, boxes_[t][0], boxes_[t][1], reach) && visit(t)) return;
        }
      }
}

void RestCut::add(const RestTriangle& triangle) {
  const int index = static_cast<int>(triangles_.size());
  triangles_.push_back(triangle);
  const auto box = box_of(triangle);
  boxes_.push_back(box);
  stamp_.push_back(0);
  std::array<long long, 3> first{}, last{};
  for (int axis = 0; axis < 3; ++axis) {
    first[axis] = static_cast<long long>(std::floor(box[0][axis] / cell_));
    last[axis] = static_cast<long long>(std::floor(box[1][axis] / cell_));
    // A huge triangle (a blade far larger than the body) is clipped to a bounded bin range;
    // the triangle still gets its box test, so nothing is lost but speed.
    last[axis] = std::min(last[axis], first[axis] + 256);
  }
  cover(first, last);
  for (long long k = first[2]; k <= last[2]; ++k)
    for (long long j = first[1]; j <= last[1]; ++j)
      for (long long i = first[0]; i <= last[0]; ++i) bin(i, j, k)->push_back(index);
}

bool RestCut::crosses(const Vec3& p, const Vec3& q, int from) const {
  if (from >= size()) return false;
  bool crossed = false;
  for_each_near(p.cwiseMin(q), p.cwiseMax(q), 0, [&](int t) {
    crossed = t >= from && segment_crosses_triangle(p, q, triangles_[t]).has_value();
    return crossed;
  });
  return crossed;
}

std::optional<Vec3> RestCut::nearest_point(const Vec3& p, double reach) const {
  std::optional<Vec3> best;
  double best_distance = reach;
  int best_index = -1;
  for_each_near(p, p, reach, [&](int t) {
    const Vec3 closest = closest_point_on_triangle(p, triangles_[t].a, triangles_[t].b, triangles_[t].c);
    const double distance = (closest - p).norm();
    // Ties to the lower index, so the result does not depend on the bins' order.
    if (distance < best_distance || (distance == best_distance && best_index >= 0 && t < best_index)) {
      best_distance = distance;
      best = closest;
      best_index = t;
    }
    return false;
  });
  return best;
}

bool RestCut::near_box(const Vec3& lo, const Vec3& hi, double reach) const {
  bool near = false;
  for_each_near(lo, hi, reach, [&](int) { return near = true; });
  return near;
}

SurfaceTopology surface_topology(const std::vector<std::array<int, 3>>& triangles) {
  // Edges bucketed by their lower vertex (a counting sort, linear in the triangles), then
  // each bucket's few upper vertices counted.
  int vertices = 0;
  for (const auto& t : triangles)
    for (int v : t) vertices = std::max(vertices, v + 1);
  std::vector<int> start(static_cast<size_t>(vertices) + 1, 0);
  for (const auto& t : triangles)
    for (int e = 0; e < 3; ++e) ++start[static_cast<size_t>(std::min(t[e], t[(e + 1) % 3])) + 1];
  for (int v = 0; v < vertices; ++v) start[v + 1] += start[v];
  std::vector<int> upper(static_cast<size_t>(start[vertices]));
  std::vector<int> fill(start.begin(), start.end() - 1);
  for (const auto& t : triangles)
    for (int e = 0; e < 3; ++e) {
      const int a = t[e], b = t[(e + 1) % 3];
      upper[static_cast<size_t>(fill[std::min(a, b)]++)] = std::max(a, b);
    }
  SurfaceTopology topology;
  for (int v = 0; v < vertices; ++v) {
    const auto first = upper.begin() + start[v], last = upper.begin() + start[v + 1];
    std::sort(first, last);
    for (auto it = first; it != last;) {
      auto next = it;
      while (next != last && *next == *it) ++next;
      const auto count = next - it;
      topology.boundary_edges += count == 1 ? 1 : 0;
      topology.nonmanifold_edges += count > 2 ? 1 : 0;
      it = next;
    }
  }
  return topology;
}

SurfaceTopology surface_topology(const std::vector<std::array<int, 3>>& triangles, std::span<const std::uint8_t> among) {
  const auto in = [&](int v) { return v >= 0 && static_cast<size_t>(v) < among.size() && among[static_cast<size_t>(v)] != 0; };
  std::vector<std::pair<int, int>> edges;
  for (const auto& t : triangles)
    for (int e = 0; e < 3; ++e) {
      const int a = t[static_cast<size_t>(e)], b = t[static_cast<size_t>((e + 1) % 3)];
      if (in(a) && in(b)) edges.emplace_back(std::min(a, b), std::max(a, b));
    }
  std::sort(edges.begin(), edges.end());
  SurfaceTopology topology;
  for (size_t k = 0; k < edges.size();) {
    size_t next = k;
    while (next < edges.size() && edges[next] == edges[k]) ++next;
    topology.boundary_edges += next - k == 1 ? 1 : 0;
    topology.nonmanifold_edges += next - k > 2 ? 1 : 0;
    k = next;
  }
  return topology;
}

CutSurface::CutSurface(const std::function<bool(const Vec3&)>& inside, Vec3 lo, Vec3 hi, double cell)
    : cell_(cell), rest_cut_(2 * cell) {
  if (!(cell > 0) || !std::isfinite(cell)) {
    throw std::invalid_argument("CutSurface: cell must be positive and finite, got " + std::to_string(cell));
  }
  // One empty layer of cubes around the box, so that every inside cube has all its faces.
  origin_ = lo - Vec3::Constant(cell);
  for (int axis = 0; axis < 3; ++axis) {
    const double extent = (hi[axis] - lo[axis]) / cell;
    if (!(extent >= 0) || extent > 4096) {
      throw std::invalid_argument("CutSurface: the box is empty or holds more than 4096 cells along an axis");
    }
    counts_[axis] = static_cast<int>(std::ceil(extent * (1 - 1e-12))) + 2;
  }
  const int cubes = counts_[0] * counts_[1] * counts_[2];
  inside_.assign(static_cast<size_t>(cubes), 0);
  face_cut_.assign(3 * static_cast<size_t>(cubes), 0);
  face_shown_ = face_cut_;
  TetMesh mesh;
  const int nodes = (counts_[0] + 1) * (counts_[1] + 1) * (counts_[2] + 1);
  mesh.rest.resize(3 * static_cast<Eigen::Index>(nodes));
  for (int k = 0; k <= counts_[2]; ++k)
    for (int j = 0; j <= counts_[1]; ++j)
      for (int i = 0; i <= counts_[0]; ++i)
        mesh.rest.segment<3>(3 * static_cast<Eigen::Index>(node_index(i, j, k))) = origin_ + cell * Vec3(i, j, k);
  for (int k = 1; k + 1 < counts_[2]; ++k) {
    for (int j = 1; j + 1 < counts_[1]; ++j) {
      for (int i = 1; i + 1 < counts_[0]; ++i) {
        if (!inside(cube_centre(i, j, k))) continue;
        inside_[cube_index(i, j, k)] = 1;
        ++cube_count_;
      }
    }
  }
  if (cube_count_ == 0) throw std::invalid_argument("CutSurface: no cube centre is inside the body");
  node_rest_.resize(static_cast<size_t>(nodes));
  for (int n = 0; n < nodes; ++n) node_rest_[n] = mesh.rest.segment<3>(3 * static_cast<Eigen::Index>(n));
  // Fill the voxel set's pinches first, so that the snapped shape is the final one.
  node_groups_.assign(static_cast<size_t>(nodes), {});
  node_groups_done_.assign(static_cast<size_t>(nodes), 0);
  vertex_of_.assign(8 * static_cast<size_t>(nodes), -1);
  for (int pass = 0; pass < 16 && fill_pinches() > 0; ++pass) {
  }
  std::fill(node_groups_done_.begin(), node_groups_done_.end(), 0);
  std::fill(vertex_of_.begin(), vertex_of_.end(), -1);
  // The snap moves only the nodes on the voxel boundary, judging each move by the elements
  // around the node, so its mesh needs only the cubes near the boundary: those within two
  // cubes of a boundary node. The cut-off mesh's inner boundary lies two cubes deeper than
  // any boundary node, so its moves (if any) touch no element the real ones do, and they
  // are undone below: the outcome is that of the whole voxel mesh, at a fraction of the cost
  // (2.3M cubes at 20k elements and s = 0.6 mm, 5 s of the load).
  cube_count_ = 0;
  std::vector<std::uint8_t> boundary_node(static_cast<size_t>(nodes), 0), near_node(static_cast<size_t>(nodes), 0);
  const auto for_cubes = [&](const auto& visit) {
    for (int k = 1; k + 1 < counts_[2]; ++k)
      for (int j = 1; j + 1 < counts_[1]; ++j)
        for (int i = 1; i + 1 < counts_[0]; ++i)
          if (inside_[cube_index(i, j, k)]) visit(i, j, k);
  };
  const auto any_corner = [&](const std::vector<std::uint8_t>& mark, int i, int j, int k) {
    for (int c = 0; c < 8; ++c)
      if (mark[corner_node(i, j, k, c)]) return true;
    return false;
  };
  const auto mark_corners = [&](std::vector<std::uint8_t>& mark, int i, int j, int k) {
    for (int c = 0; c < 8; ++c) mark[corner_node(i, j, k, c)] = 1;
  };
  for_cubes([&](int i, int j, int k) {
    ++cube_count_;
    for (int axis = 0; axis < 3; ++axis)
      for (int side = 0; side < 2; ++side) {
        std::array<int, 3> next{i, j, k};
        next[axis] += side == 0 ? -1 : 1;
        if (inside_[cube_index(next[0], next[1], next[2])]) continue;
        for (const auto& corner : face_corners({i, j, k}, axis, side)) boundary_node[node_index(corner[0], corner[1], corner[2])] = 1;
      }
  });
  for_cubes([&](int i, int j, int k) {
    if (any_corner(boundary_node, i, j, k)) mark_corners(near_node, i, j, k);
  });
  mesh.tets.clear();
  for_cubes([&](int i, int j, int k) {
    if (!any_corner(near_node, i, j, k)) return;
    for (const auto& tet : cube_tets) {
      std::array<int, 4> nodes_of{};
      for (int c = 0; c < 4; ++c) nodes_of[c] = corner_node(i, j, k, tet[c]);
      mesh.tets.push_back(nodes_of);
    }
  });
  // The cubes with an outside neighbour: the surface's, until cuts add theirs.
  surface_cubes_.clear();
  for (int k = 1; k + 1 < counts_[2]; ++k)
    for (int j = 1; j + 1 < counts_[1]; ++j)
      for (int i = 1; i + 1 < counts_[0]; ++i) {
        if (!inside_[cube_index(i, j, k)]) continue;
        const bool outer = !inside_[cube_index(i - 1, j, k)] || !inside_[cube_index(i + 1, j, k)] ||
                           !inside_[cube_index(i, j - 1, k)] || !inside_[cube_index(i, j + 1, k)] ||
                           !inside_[cube_index(i, j, k - 1)] || !inside_[cube_index(i, j, k + 1)];
        if (outer) surface_cubes_.push_back(cube_index(i, j, k));
      }
  // The outer nodes onto the true surface, as for the tetrahedral bodies.
  snap_boundary_to_surface(mesh, inside, 1.5 * cell, 0.1);
  for (int n = 0; n < nodes; ++n)
    if (boundary_node[n]) node_rest_[n] = mesh.rest.segment<3>(3 * static_cast<Eigen::Index>(n));
  // The whole surface, numbered as its faces meet the vertices.
  std::vector<int> surface_nodes;
  for (int cube : surface_cubes_)
    for (int s = 0; s < 8; ++s) {
      const int i = cube % counts_[0], j = (cube / counts_[0]) % counts_[1], k = cube / (counts_[0] * counts_[1]);
      surface_nodes.push_back(corner_node(i, j, k, s));
    }
  refresh(std::move(surface_nodes));
  // Room for what the cuts add, so that the first cuts grow the per-vertex and per-triangle
  // lists in place rather than move them (past the room they double as usual).
  const auto room = [](auto& list) { list.reserve(list.size() + list.size() / 4); };
  room(triangles_), room(positions_), room(anchors_), room(on_cut_), room(vertex_keys_), room(vertex_node_);
  room(vertex_revision_), room(vertex_stamp_);
}

Vec3 CutSurface::cube_centre(int i, int j, int k) const {
  return origin_ + cell_ * Vec3(i + 0.5, j + 0.5, k + 0.5);
}

int CutSurface::cut(std::span<const RestTriangle> triangles) {
  int newly = 0;
  for (const RestTriangle& triangle : triangles) {
    rest_cut_.add(triangle);
    const auto [lo, hi] = box_of(triangle);
    std::array<int, 3> first{}, last{};
    for (int axis = 0; axis < 3; ++axis) {
      first[axis] = std::clamp(static_cast<int>(std::floor((lo[axis] - origin_[axis]) / cell_ - 0.5)), 0, counts_[axis] - 1);
      last[axis] = std::clamp(static_cast<int>(std::floor((hi[axis] - origin_[axis]) / cell_ + 0.5)), 0, counts_[axis] - 1);
    }
    for (int k = first[2]; k <= last[2]; ++k) {
      for (int j = first[1]; j <= last[1]; ++j) {
        for (int i = first[0]; i <= last[0]; ++i) {
          const int cube = cube_index(i, j, k);
          if (!inside_[cube]) continue;
          const std::array<int, 3> at{i, j, k};
          for (int axis = 0; axis < 3; ++axis) {
            std::array<int, 3> next = at;
            ++next[axis];
            if (next[axis] >= counts_[axis]) continue;
            const int other = cube_index(next[0], next[1], next[2]);
            if (!inside_[other] || face_cut_[3 * static_cast<size_t>(cube) + axis]) continue;
            if (segment_crosses_triangle(cube_centre(i, j, k), cube_centre(next[0], next[1], next[2]), triangle)) {
              face_cut_[3 * static_cast<size_t>(cube) + axis] = 1;
              pending_faces_.push_back(3 * cube + axis);
              new_surface_cubes_.push_back(cube);
              new_surface_cubes_.push_back(other);
              ++newly;
            }
          }
        }
      }
    }
  }
  cut_faces_ += newly;
  return newly;
}

void CutSurface::rebuild() {
  if (!new_surface_cubes_.empty()) {
    // Merged in, sorted: the few new cubes are sorted and merged rather than the whole list.
    // A cube new to the list has no triangles yet; its first is where its predecessor's end.
    std::sort(new_surface_cubes_.begin(), new_surface_cubes_.end());
    new_surface_cubes_.erase(std::unique(new_surface_cubes_.begin(), new_surface_cubes_.end()), new_surface_cubes_.end());
    size_t added = 0;
    for (int cube : new_surface_cubes_) {
      const auto at = std::lower_bound(surface_cubes_.begin(), surface_cubes_.end(), cube);
      if (at != surface_cubes_.end() && *at == cube) continue;
      const int before = at == surface_cubes_.begin() ? -1 : *(at - 1);
      cube_first_[cube] = before < 0 ? 0 : cube_first_[before] + cube_triangles_[before];
      cube_triangles_[cube] = 0;
      new_surface_cubes_[added++] = cube;
    }
    new_surface_cubes_.resize(added);
    if (added > 0) {
      merged_cubes_.resize(surface_cubes_.size() + added);
      std::merge(surface_cubes_.begin(), surface_cubes_.end(), new_surface_cubes_.begin(), new_surface_cubes_.end(),
                 merged_cubes_.begin());
      surface_cubes_.swap(merged_cubes_);
    }
    new_surface_cubes_.clear();
  }
  // The faces whose state changes: the newly cut ones, and those the last rebuild hid (shown
  // again, then hidden anew if they still pinch), so that the faces shown are as if every
  // cut face had been shown and the pinches closed from scratch.
  std::vector<int> nodes;
  for (int face : pending_faces_) face_shown_[face] = 1, add_face_corners(face, nodes);
  for (int face : hidden_faces_) face_shown_[face] = 1, add_face_corners(face, nodes);
  pending_faces_.clear();
  hidden_faces_.clear();
  refresh(std::move(nodes));
}

SurfaceTopology CutSurface::topology() const {
  SurfaceTopology topology;
  for (const auto& [edge, count] : bad_edges_) (count == 1 ? topology.boundary_edges : topology.nonmanifold_edges) += 1;
  return topology;
}

void CutSurface::add_face_corners(int face, std::vector<int>& nodes) {
  const int cube = face / 3, axis = face % 3;
  const int nx = counts_[0], ny = counts_[1];
  std::array<int, 3> at{cube % nx, (cube / nx) % ny, cube / (nx * ny)};
  at[axis] += 1;  // the +axis face of the cube
  const int u = (axis + 1) % 3, v = (axis + 2) % 3;
  for (int c = 0; c < 4; ++c) {
    std::array<int, 3> node = at;
    node[u] += c & 1;
    node[v] += (c >> 1) & 1;
    nodes.push_back(node_index(node[0], node[1], node[2]));
  }
}

const std::array<std::int8_t, 8>& CutSurface::node_groups(int node) {
  std::array<std::int8_t, 8>& label = node_groups_[node];
  if (node_groups_done_[node]) return label;
  node_groups_done_[node] = 1;
  const int nx = counts_[0] + 1, ny = counts_[1] + 1;
  const int i = node % nx, j = (node / nx) % ny, k = node / (nx * ny);
  std::array<int, 8> cube{};
  for (int s = 0; s < 8; ++s) {
    const int ci = i - 1 + (s & 1), cj = j - 1 + ((s >> 1) & 1), ck = k - 1 + ((s >> 2) & 1);
    const bool valid = ci >= 0 && cj >= 0 && ck >= 0 && ci < counts_[0] && cj < counts_[1] && ck < counts_[2];
    cube[s] = valid ? cube_index(ci, cj, ck) : -1;
    label[s] = static_cast<std::int8_t>(cube[s] >= 0 && inside_[cube[s]] ? s : -1);
  }
  // Union by smallest slot over the 12 face adjacencies of the 2 x 2 x 2 block.
  bool changed = true;
  while (changed) {
    changed = false;
    for (int s = 0; s < 8; ++s) {
      if (label[s] < 0) continue;
      for (int axis = 0; axis < 3; ++axis) {
        const int bit = 1 << axis;
        if (s & bit) continue;
        const int t = s | bit;
        if (label[t] < 0) continue;
        if (face_shown_[3 * static_cast<size_t>(cube[s]) + axis]) continue;  // s's +axis face is t's -axis face
        const std::int8_t joined = std::min(label[s], label[t]);
        if (label[s] != joined || label[t] != joined) {
          // Relabel both groups to the smaller label.
          const std::int8_t from_s = label[s], from_t = label[t];
          for (auto& l : label)
            if (l == from_s || l == from_t) l = joined;
          changed = true;
        }
      }
    }
  }
  return label;
}

namespace {

// A face of the surface: its corners' keys, counter-clockwise seen from outside its cube.
struct Quad {
  std::array<long long, 4> key{};
  int cube = 0;
  bool cut = false;   // a cut face (else one towards an empty cube)
  bool flip = false;  // split along the other diagonal (the -axis side of a cut face)
  std::array<std::array<int, 3>, 2> triangles() const {
    if (flip) return {{{1, 2, 3}, {1, 3, 0}}};
    return {{{0, 1, 2}, {0, 2, 3}}};
  }
};

}  // namespace

void CutSurface::refresh(std::vector<int> nodes) {
  ++revision_;
  written_.clear();
  const auto touch = [&](int id) {  // its key, rest position or anchor written now
    if (vertex_revision_[id] == revision_) return;
    vertex_revision_[id] = revision_;
    written_.push_back(id);
  };
  const int nx = counts_[0], ny = counts_[1];
  const int node_nx = counts_[0] + 1, node_ny = counts_[1] + 1;
  if (node_mark_.size() != node_rest_.size()) node_mark_.assign(node_rest_.size(), 0);
  if (cube_mark_.size() != inside_.size()) cube_mark_.assign(inside_.size(), 0);
  // The dirty nodes (each once), and the cubes around them.
  std::vector<int> dirty, region;
  const auto add_nodes = [&](const std::vector<int>& more) {
    for (int node : more) {
      if (node_mark_[node]) continue;
      node_mark_[node] = 1;
      dirty.push_back(node);
      const int i = node % node_nx, j = (node / node_nx) % node_ny, k = node / (node_nx * node_ny);
      for (int s = 0; s < 8; ++s) {
        const int ci = i - 1 + (s & 1), cj = j - 1 + ((s >> 1) & 1), ck = k - 1 + ((s >> 2) & 1);
        if (ci < 0 || cj < 0 || ck < 0 || ci >= counts_[0] || cj >= counts_[1] || ck >= counts_[2]) continue;
        const int cube = cube_index(ci, cj, ck);
        if (cube_mark_[cube] || !inside_[cube]) continue;
        cube_mark_[cube] = 1;
        region.push_back(cube);
      }
    }
    std::sort(region.begin(), region.end());
  };
  add_nodes(nodes);
  std::vector<Quad> quads;
  std::vector<std::pair<long long, long long>> edges;
  std::vector<int> more;
  bool edges_final = false;
  // The region's triangle edges by key (min, max), sorted, from the current quads.
  const auto region_edges = [&]() {
    edges.clear();
    for (const Quad& quad : quads)
      for (const auto& t : quad.triangles())
        for (int e = 0; e < 3; ++e) {
          const long long a = quad.key[t[e]], b = quad.key[t[(e + 1) % 3]];
          edges.emplace_back(std::min(a, b), std::max(a, b));
        }
    std::sort(edges.begin(), edges.end());
  };
  pinches_closed_ = 0;
  for (int pass = 0;; ++pass) {
    // The region's faces, cube by cube in increasing order, as a full rebuild walks them.
    for (int node : dirty) node_groups_done_[node] = 0;
    quads.clear();
    for (int cube : region) {
      const std::array<int, 3> at{cube % nx, (cube / nx) % ny, cube / (nx * ny)};
      for (int axis = 0; axis < 3; ++axis) {
        for (int side = 0; side < 2; ++side) {  // 0: the -axis face, 1: the +axis face
          std::array<int, 3> next = at;
          next[axis] += side ? 1 : -1;
          const int other = cube_index(next[0], next[1], next[2]);
          const bool cut_face = inside_[other] && face_shown_[3 * static_cast<size_t>(side ? cube : other) + axis] != 0;
          if (inside_[other] && !cut_face) continue;
          const std::array<std::array<int, 3>, 4> corners = face_corners(at, axis, side);
          Quad quad;
          quad.cube = cube;
          quad.cut = cut_face;
          // The two sides of a cut face share the corners the cut has not separated yet
          // (a crack of a few faces inside the body has all four shared: a closed pillow
          // of zero volume). Splitting the two sides' quads along different diagonals keeps
          // every edge used by exactly two triangles whatever is shared.
          quad.flip = cut_face && side == 0;
          for (int c = 0; c < 4; ++c) {
            const auto& n = corners[c];
            const int node = node_index(n[0], n[1], n[2]);
            // The corner's cube slot at that node.
            const int slot = (at[0] - (n[0] - 1)) + 2 * (at[1] - (n[1] - 1)) + 4 * (at[2] - (n[2] - 1));
            quad.key[c] = 8LL * node + node_groups(node)[slot];
          }
          quads.push_back(quad);
        }
      }
    }
    edges_final = false;
    if (pass == 64) break;  // never seen: the faces are kept as they are, the checks will tell
    // Pinches: edges used by four triangles. Every edge with a dirty end has all its
    // triangles in the region (they belong to the cubes around that end) and the others are
    // as after the last rebuild, closed, so the region's edges are the only suspects. The
    // four cubes around such an edge alternate full, gap, full, gap; the first gap (in slot
    // order) that is a cut face between two full cubes is hidden.
    region_edges();
    int closed = 0;
    more.clear();
    for (size_t first = 0; first < edges.size();) {
      size_t last = first;
      while (last < edges.size() && edges[last] == edges[first]) ++last;
      const auto edge = edges[first];
      const size_t count = last - first;
      first = last;
      if (count <= 2) continue;
      const int n1 = static_cast<int>(std::min(edge.first / 8, edge.second / 8));
      const int n2 = static_cast<int>(std::max(edge.first / 8, edge.second / 8));
      const int i = n1 % node_nx, j = (n1 / node_nx) % node_ny, k = n1 / (node_nx * node_ny);
      const int step = n2 - n1;
      const int axis = step == 1 ? 0 : step == node_nx ? 1 : 2;
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      // The cubes around the edge: offsets (0 or -1) along u and v, in cyclic order.
      const std::array<std::array<int, 2>, 4> around{{{0, 0}, {-1, 0}, {-1, -1}, {0, -1}}};
      std::array<std::array<int, 3>, 4> cube{};
      std::array<bool, 4> full{};
      for (int c = 0; c < 4; ++c) {
        cube[c] = {i, j, k};
        cube[c][u] += around[c][0];
        cube[c][v] += around[c][1];
        full[c] = inside_[cube_index(cube[c][0], cube[c][1], cube[c][2])] != 0;
      }
      for (int c = 0; c < 4; ++c) {
        const int gap = c, previous = (c + 3) % 4;
        if (!full[gap]) continue;  // empty cubes are filled at build only
        // A full cube cut from its neighbour: restore the face between them.
        const auto& a = cube[previous];
        const auto& b = cube[gap];
        int differ = 0;
        while (differ < 3 && a[differ] == b[differ]) ++differ;
        const bool a_lower = a[differ] < b[differ];
        const auto& lower = a_lower ? a : b;
        const int face = 3 * cube_index(lower[0], lower[1], lower[2]) + differ;
        std::uint8_t& flag = face_shown_[static_cast<size_t>(face)];
        if (full[previous] && flag) {
          flag = 0;  // hidden from the surface for now; the cut itself stays
          hidden_faces_.push_back(face);
          add_face_corners(face, more);
          ++closed;
          break;
        }
      }
    }
    pinches_closed_ += closed;
    edges_final = closed == 0;  // `edges` are then those of the final faces
    if (closed == 0) break;
    add_nodes(more);
  }

  // Vertices. The keys the region's faces use at the dirty nodes are the live ones there;
  // the other vertices of those nodes are freed first, then new keys take the lowest free
  // index (or the next one), in the order the faces meet them.
  // The edges with a dirty end are redone below (their triangles are all in the region);
  // the others keep their triangles, so their counts stand.
  for (auto it = bad_edges_.begin(); it != bad_edges_.end();) {
    const bool redone = node_mark_[static_cast<size_t>(vertex_node_[it->first.first])] ||
                        node_mark_[static_cast<size_t>(vertex_node_[it->first.second])];
    it = redone ? bad_edges_.erase(it) : std::next(it);
  }
  std::vector<long long> live;
  for (const Quad& quad : quads)
    for (long long key : quad.key)
      if (node_mark_[static_cast<size_t>(key / 8)]) live.push_back(key);
  std::sort(live.begin(), live.end());
  live.erase(std::unique(live.begin(), live.end()), live.end());
  for (int node : dirty)
    for (int g = 0; g < 8; ++g) {
      const long long key = 8LL * node + g;
      int& id = vertex_of_[static_cast<size_t>(key)];
      if (id < 0 || std::binary_search(live.begin(), live.end(), key)) continue;
      vertex_keys_[id] = -1;
      touch(id);
      on_cut_[id] = 0;
      free_vertices_.push_back(id);
      std::push_heap(free_vertices_.begin(), free_vertices_.end(), std::greater<>());
      --used_vertices_;
      id = -1;
    }
  if (++stamp_ == 0) stamp_ = 1, std::fill(vertex_stamp_.begin(), vertex_stamp_.end(), 0);
  std::vector<int> redone;  // the dirty nodes' vertices, each once
  const auto id_of = [&](long long key, int cube, bool cut_face) {
    int& id = vertex_of_[static_cast<size_t>(key)];
    if (!node_mark_[static_cast<size_t>(key / 8)]) {
      // A node left as it was: its vertices are the ones it had.
      if (id < 0) throw std::logic_error("CutSurface: a kept node lost its vertex");
      return id;
    }
    if (id < 0) {
      if (!free_vertices_.empty()) {
        std::pop_heap(free_vertices_.begin(), free_vertices_.end(), std::greater<>());
        id = free_vertices_.back();
        free_vertices_.pop_back();
      } else {
        id = static_cast<int>(vertex_keys_.size());
        vertex_keys_.push_back(-1);
        vertex_node_.push_back(0);
        anchors_.push_back(Vec3::Zero());
        on_cut_.push_back(0);
        positions_.push_back(Vec3::Zero());
        vertex_revision_.push_back(0);
        vertex_stamp_.push_back(0);
      }
      vertex_keys_[id] = key;
      touch(id);
      vertex_node_[id] = static_cast<int>(key / 8);
      ++used_vertices_;
    }
    if (vertex_stamp_[id] != stamp_) {
      // The first cube that meets it (the lowest): its anchor, as a full rebuild finds it.
      vertex_stamp_[id] = stamp_;
      const int nxy = nx * ny;
      anchors_[id] = cube_centre(cube % nx, (cube / nx) % ny, cube / nxy);
      touch(id);
      on_cut_[id] = 0;
      redone.push_back(id);
    }
    if (cut_face) on_cut_[id] = 1;
    return id;
  };
  std::vector<std::array<int, 3>> region_triangles;
  region_triangles.reserve(2 * quads.size());
  for (const Quad& quad : quads) {
    std::array<int, 4> ids{};
    for (int c = 0; c < 4; ++c) ids[c] = id_of(quad.key[c], quad.cube, quad.cut);
    for (const auto& t : quad.triangles()) region_triangles.push_back({ids[t[0]], ids[t[1]], ids[t[2]]});
  }
  {
    // The region's edges by key, sorted, as the pinch pass left them (else taken again): a
    // key is one vertex, so counts by key are counts by vertex.
    if (!edges_final) region_edges();
    for (size_t first = 0; first < edges.size();) {
      size_t last = first;
      while (last < edges.size() && edges[last] == edges[first]) ++last;
      const auto [a, b] = edges[first];
      const size_t count = last - first;
      first = last;
      if (count == 2 || !(node_mark_[static_cast<size_t>(a / 8)] || node_mark_[static_cast<size_t>(b / 8)])) continue;
      const int u = vertex_of_[static_cast<size_t>(a)], v = vertex_of_[static_cast<size_t>(b)];
      bad_edges_[{std::min(u, v), std::max(u, v)}] = static_cast<int>(count);
    }
  }
  // Positions: the redone vertices from their nodes, cut-face ones onto the cut; the other
  // cut-face vertices again where the cut gained triangles within reach.
  const double reach = std::sqrt(3.0) * cell_;
  placed_.clear();
  const auto place = [&](int id) {
    placed_.push_back(id);
    touch(id);
    positions_[id] = node_rest_[vertex_node_[id]];
    if (!on_cut_[id]) return;
    if (const auto nearest = rest_cut_.nearest_point(positions_[id], reach)) positions_[id] = *nearest;
  };
  for (int id : redone) place(id);
  if (rest_cut_.size() > projected_triangles_) {
    // A kept vertex's position is its node's nearest point on the triangles before these
    // (the nearer, lower index on ties; none within reach: the node itself): only the new
    // triangles are searched, and their nearest replaces it when strictly nearer, which is
    // what a search of the whole cut finds. A vertex at its node (nothing was within reach,
    // or it lies on the cut) is searched against the whole cut.
    RestCut added;
    Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
    for (int t = projected_triangles_; t < rest_cut_.size(); ++t) {
      const auto box = box_of(rest_cut_.triangles()[t]);
      lo = lo.cwiseMin(box[0]), hi = hi.cwiseMax(box[1]);
      added.add(rest_cut_.triangles()[t]);
    }
    lo -= Vec3::Constant(reach), hi += Vec3::Constant(reach);
    for (size_t id = 0; id < positions_.size(); ++id) {
      if (!on_cut_[id] || vertex_stamp_[id] == stamp_) continue;
      const Vec3& p = node_rest_[vertex_node_[id]];
      if (!((p.array() >= lo.array()).all() && (p.array() <= hi.array()).all())) continue;
      if (positions_[id] == p) {
        place(static_cast<int>(id));
        continue;
      }
      placed_.push_back(static_cast<int>(id));
      touch(static_cast<int>(id));
      if (const auto nearest = added.nearest_point(p, reach))
        if ((*nearest - p).norm() < (positions_[id] - p).norm()) positions_[id] = *nearest;
    }
    projected_triangles_ = rest_cut_.size();
  }
  // Only the placed vertices' rest positions are written (an index keeps its row otherwise).
  if (rest_vertices_.size() != 3 * static_cast<Eigen::Index>(positions_.size()))
    rest_vertices_.conservativeResize(3 * static_cast<Eigen::Index>(positions_.size()));
  for (int id : placed_) rest_vertices_.segment<3>(3 * static_cast<Eigen::Index>(id)) = positions_[id];

  // Triangles: the surface cubes' in increasing order, each cube's contiguous. Only the
  // region's cubes have new triangles: they are written over their old ones in place while
  // every cube keeps its count; from the first cube whose count changes on, the rest of the
  // list moves by the counts' difference (moved as runs, the kept cubes' firsts shifted).
  if (cube_first_.size() != inside_.size()) cube_first_.assign(inside_.size(), 0), cube_triangles_.assign(inside_.size(), 0);
  struct Segment {
    int cube, old_first, old_count;
    size_t quad;  // its first quad; it has (new count) / 2
    int count;
  };
  std::vector<Segment> segments;
  {
    size_t q = 0;
    for (int cube : region) {
      const size_t from = q;
      while (q < quads.size() && quads[q].cube == cube) ++q;
      const int count = static_cast<int>(2 * (q - from));
      if (count == 0 && cube_triangles_[cube] == 0) continue;  // nothing there, before or now
      if (count > 0 && !std::binary_search(surface_cubes_.begin(), surface_cubes_.end(), cube))
        throw std::logic_error("CutSurface: a face outside the surface cubes");
      segments.push_back({cube, cube_first_[cube], cube_triangles_[cube], from, count});
    }
    if (q != quads.size()) throw std::logic_error("CutSurface: a face outside the surface cubes");
  }
  const auto write = [&](const Segment& s, std::array<int, 3>* to) {
    for (int t = 0; t < s.count; ++t) to[t] = region_triangles[2 * s.quad + t];
  };
  const int old_size = static_cast<int>(triangles_.size());
  int changed_from = old_size, changed_to = 0;
  size_t m = 0;
  for (; m < segments.size() && segments[m].count == segments[m].old_count; ++m) {
    const Segment& s = segments[m];
    write(s, triangles_.data() + s.old_first);
    changed_from = std::min(changed_from, s.old_first);
    changed_to = std::max(changed_to, s.old_first + s.count);
  }
  if (m < segments.size()) {
    const int from = segments[m].old_first;
    int delta = 0;
    for (size_t s = m; s < segments.size(); ++s) delta += segments[s].count - segments[s].old_count;
    moved_.assign(triangles_.begin() + from, triangles_.end());  // the old tail
    triangles_.resize(static_cast<size_t>(old_size + delta));
    // The kept cubes after `from` move by the difference so far.
    auto cube_at = std::lower_bound(surface_cubes_.begin(), surface_cubes_.end(), segments[m].cube);
    int read = from, at = from, shift = 0;
    const auto copy_run = [&](int to_old) {  // old [read, to_old) to `at`
      std::copy(moved_.begin() + (read - from), moved_.begin() + (to_old - from), triangles_.begin() + at);
      at += to_old - read;
      read = to_old;
    };
    const auto shift_until = [&](int cube) {  // the kept cubes' firsts below `cube`
      for (; cube_at != surface_cubes_.end() && *cube_at < cube; ++cube_at) cube_first_[*cube_at] += shift;
    };
    for (size_t s = m; s < segments.size(); ++s) {
      const Segment& segment = segments[s];
      shift_until(segment.cube);
      if (cube_at != surface_cubes_.end() && *cube_at == segment.cube) ++cube_at;
      copy_run(segment.old_first);
      write(segment, triangles_.data() + at);
      cube_first_[segment.cube] = at;
      cube_triangles_[segment.cube] = static_cast<std::uint8_t>(segment.count);
      at += segment.count;
      read = segment.old_first + segment.old_count;
      shift += segment.count - segment.old_count;
    }
    shift_until(std::numeric_limits<int>::max());
    const int last_end = at;  // the last redone cube's end: the rest is as before when delta is 0
    copy_run(old_size);
    changed_from = std::min(changed_from, from);
    changed_to = delta == 0 ? std::max(changed_to, last_end) : static_cast<int>(triangles_.size());
  }
  changed_triangles_ = changed_from < changed_to ? std::pair{changed_from, changed_to} : std::pair{0, 0};
  for (int node : dirty) node_mark_[node] = 0;
  for (int cube : region) cube_mark_[cube] = 0;
}

int CutSurface::fill_pinches() {
  // The voxel set's surface numbered as the faces meet its vertices, cube by cube, and its
  // edges used more than twice (sorted by vertex, so the order of the fills is that order).
  std::fill(node_groups_done_.begin(), node_groups_done_.end(), 0);
  std::fill(vertex_of_.begin(), vertex_of_.end(), -1);
  std::vector<int> vertex_node;
  std::vector<std::array<int, 3>> triangles;
  for (int k = 1; k + 1 < counts_[2]; ++k)
    for (int j = 1; j + 1 < counts_[1]; ++j)
      for (int i = 1; i + 1 < counts_[0]; ++i) {
        const int cube = cube_index(i, j, k);
        if (!inside_[cube]) continue;
        const std::array<int, 3> at{i, j, k};
        for (int axis = 0; axis < 3; ++axis)
          for (int side = 0; side < 2; ++side) {
            std::array<int, 3> next = at;
            next[axis] += side ? 1 : -1;
            if (inside_[cube_index(next[0], next[1], next[2])]) continue;
            const std::array<std::array<int, 3>, 4> corners = face_corners(at, axis, side);
            std::array<int, 4> ids{};
            for (int c = 0; c < 4; ++c) {
              const auto& n = corners[c];
              const int node = node_index(n[0], n[1], n[2]);
              const int slot = (i - (n[0] - 1)) + 2 * (j - (n[1] - 1)) + 4 * (k - (n[2] - 1));
              int& id = vertex_of_[8 * static_cast<size_t>(node) + static_cast<size_t>(node_groups(node)[slot])];
              if (id < 0) id = static_cast<int>(vertex_node.size()), vertex_node.push_back(node);
              ids[c] = id;
            }
            triangles.push_back({ids[0], ids[1], ids[2]});
            triangles.push_back({ids[0], ids[2], ids[3]});
          }
      }
  std::vector<std::pair<int, int>> edges;
  for (const auto& t : triangles)
    for (int e = 0; e < 3; ++e) edges.emplace_back(std::min(t[e], t[(e + 1) % 3]), std::max(t[e], t[(e + 1) % 3]));
  std::sort(edges.begin(), edges.end());
  // The four cubes around an edge used four times alternate full, empty, full, empty: the
  // first empty one (in slot order) off the margin is filled.
  int filled = 0;
  const int nx = counts_[0] + 1, ny = counts_[1] + 1;
  for (size_t first = 0; first < edges.size();) {
    size_t last = first;
    while (last < edges.size() && edges[last] == edges[first]) ++last;
    const auto edge = edges[first];
    const size_t count = last - first;
    first = last;
    if (count <= 2) continue;
    const int n1 = std::min(vertex_node[edge.first], vertex_node[edge.second]);
    const int n2 = std::max(vertex_node[edge.first], vertex_node[edge.second]);
    const int i = n1 % nx, j = (n1 / nx) % ny, k = n1 / (nx * ny);
    const int step = n2 - n1;
    const int axis = step == 1 ? 0 : step == nx ? 1 : 2;
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    const std::array<std::array<int, 2>, 4> around{{{0, 0}, {-1, 0}, {-1, -1}, {0, -1}}};
    for (int c = 0; c < 4; ++c) {
      std::array<int, 3> gap{i, j, k};
      gap[u] += around[c][0];
      gap[v] += around[c][1];
      const int gap_cube = cube_index(gap[0], gap[1], gap[2]);
      if (inside_[gap_cube]) continue;
      bool margin = false;
      for (int d = 0; d < 3; ++d) margin = margin || gap[d] <= 0 || gap[d] >= counts_[d] - 1;
      if (margin) continue;
      inside_[gap_cube] = 1;
      ++filled;
      break;
    }
  }
  return filled;
}

// The elements by integration cube, in a dense table over the cubes' range.
struct ElementCubes {
  explicit ElementCubes(const CorotationalEfg& model) : elements(model.element_count()) {
    const auto& cubes = model.element_grid_coordinates();
    if (!cubes.empty()) {
      std::array<long long, 3> cube_hi{};
      for (int axis = 0; axis < 3; ++axis) lo[axis] = cube_hi[axis] = cubes[0][axis];
      for (const auto& c : cubes)
        for (int axis = 0; axis < 3; ++axis)
          lo[axis] = std::min<long long>(lo[axis], c[axis]), cube_hi[axis] = std::max<long long>(cube_hi[axis], c[axis]);
      for (int axis = 0; axis < 3; ++axis) count[axis] = cube_hi[axis] - lo[axis] + 1;
    }
    element_at.assign(static_cast<size_t>(count[0] * count[1] * count[2]), -1);
    for (int e = 0; e < model.element_count(); ++e) element_at[slot(cubes[e][0], cubes[e][1], cubes[e][2])] = e;
  }
  long long slot(long long i, long long j, long long k) const {
    i -= lo[0], j -= lo[1], k -= lo[2];
    if (i < 0 || j < 0 || k < 0 || i >= count[0] || j >= count[1] || k >= count[2]) return -1;
    return i + count[0] * (j + count[1] * k);
  }
  int at(long long i, long long j, long long k) const {
    const long long s = slot(i, j, k);
    return s < 0 ? -1 : element_at[static_cast<size_t>(s)];
  }
  int elements = 0;
  std::array<long long, 3> lo{0, 0, 0}, count{0, 0, 0};
  std::vector<int> element_at;
};

namespace {

// What mapping one vertex needs: the elements by integration cube, and scratch.
class VertexMapper {
 public:
  VertexMapper(const CorotationalEfg& model, const CutSurface& surface, const ElementCubes& cubes)
      : model_(model), surface_(surface), cubes_(cubes) {}

  // Maps vertex v into row v of `embedding` (stride the model's).
  void map(int v, SurfaceEmbedding& embedding, SurfaceMappingReport& report) {
    const CorotationalEfg& model = model_;
    const double a = model.spacing();
    const Vec3 origin = model.grid_origin();
    const RestCut& cut = surface_.rest_cut();
    const int stride = model.row_stride();
    constexpr int shells = 3;  // search radius, in integration cubes
    const Vec3 vertex = surface_.rest_vertices().segment<3>(3 * static_cast<Eigen::Index>(v));
    const Vec3 anchor = surface_.anchors()[v];
    const bool used = surface_.vertex_used(v);  // unused indices are mapped, not counted
    report.mapped += used ? 1 : 0;
    nearby_.clear();
    std::array<long long, 3> cube{};
    for (int axis = 0; axis < 3; ++axis) cube[axis] = static_cast<long long>(std::floor((vertex[axis] - origin[axis]) / a));
    int chosen = -1;
    const bool near_cut = cut.size() > 0 && cut.near_box(vertex.cwiseMin(anchor), vertex.cwiseMax(anchor), (shells + 1) * a);
    // The nearest valid point (nearest, and visible from the anchor near the cut), searched
    // ring by ring of cubes: every element of a ring beyond s lies farther than s a from the
    // vertex (its point is inside its cube), so a valid one nearer than that is the nearest of
    // all `shells` rings, as if they had all been sorted.
    for (long long ring = 0; ring <= shells && chosen < 0; ++ring) {
      for (long long dz = -ring; dz <= ring; ++dz)
        for (long long dy = -ring; dy <= ring; ++dy)
          for (long long dx = -ring; dx <= ring; ++dx) {
            if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != ring) continue;
            const int e = cubes_.at(cube[0] + dx, cube[1] + dy, cube[2] + dz);
            if (e < 0 || !model.element_active(e)) continue;
            nearby_.emplace_back((model.element_centres()[e] - vertex).squaredNorm(), e);
          }
      std::sort(nearby_.begin(), nearby_.end());
      const double bound = static_cast<double>(ring) * a;
      for (const auto& [distance, e] : nearby_) {
        if (ring < shells && !(distance < bound * bound)) break;  // a farther ring may hold a nearer one
        if (!near_cut || !cut.crosses(anchor, model.element_centres()[e])) {
          chosen = e;
          break;
        }
      }
    }
    if (chosen < 0) {
      // Relaxed: the nearest integration point whatever the cut (or, with none nearby, the
      // nearest of all), counted.
      report.relaxed_fallbacks += used ? 1 : 0;
      if (!nearby_.empty()) {
        chosen = nearby_.front().second;
      } else {
        double best = 0;
        for (int e = 0; e < model.element_count(); ++e) {
          if (!model.element_active(e)) continue;
          const double d = (model.element_centres()[e] - vertex).squaredNorm();
          if (chosen < 0 || d < best) chosen = e, best = d;
        }
      }
      if (used && near_cut && cut.crosses(anchor, model.element_centres()[chosen])) ++report.wrong_side;
    }
    // MLS weights of the chosen element's neighbourhood at the vertex, with its support
    // widened as needed so that every neighbour keeps a positive weight.
    const size_t base = static_cast<size_t>(chosen) * stride;
    const int length = model.row_lengths()[chosen];
    positions_.clear();
    double farthest = 0;
    for (int k = 0; k < length; ++k) {
      positions_.push_back(model.rest_positions().segment<3>(3 * static_cast<Eigen::Index>(model.neighbours()[base + k])));
      farthest = std::max(farthest, (positions_.back() - vertex).norm());
    }
    const double support = std::max(model.element_supports()[chosen], 1.05 * farthest);
    const size_t row = static_cast<size_t>(v) * stride;
    if (!mls_shape_functions(vertex, positions_, support, a, std::span<double>(&embedding.weights[row], length), {})) {
      throw std::runtime_error("map_surface: no MLS weights for vertex " + std::to_string(v) +
                               " on element " + std::to_string(chosen));
    }
    embedding.elements[v] = chosen;
    embedding.row_lengths[v] = length;
    for (int k = 0; k < length; ++k) embedding.particles[row + k] = model.neighbours()[base + k];
  }

 private:
  const CorotationalEfg& model_;
  const CutSurface& surface_;
  const ElementCubes& cubes_;
  std::vector<std::pair<double, int>> nearby_;
  std::vector<Vec3> positions_;
};


}  // namespace

void fit_rows(SurfaceEmbedding& embedding, int vertices, int stride) {
  // A list that must grow gets room for a quarter more: a cut adds vertices at every event,
  // and moving these lists (about 40 MB at 20k elements and 232k triangles) takes about 10 ms.
  const auto fit = [](auto& list, size_t size) {
    if (size > list.capacity()) list.reserve(size + size / 4);
    list.resize(size, {});
  };
  if (embedding.stride != stride && !embedding.elements.empty()) {
    const size_t rows = embedding.elements.size(), wanted = std::max(rows, static_cast<size_t>(std::max(vertices, 0)));
    std::vector<int> particles;
    std::vector<double> weights;
    particles.reserve((wanted + wanted / 4) * static_cast<size_t>(stride));
    weights.reserve(particles.capacity());
    particles.resize(rows * static_cast<size_t>(stride), 0);
    weights.resize(particles.size(), 0.0);
    for (size_t v = 0; v < rows; ++v) {
      const int length = std::min(embedding.row_lengths[v], stride);
      std::copy_n(embedding.particles.begin() + static_cast<std::ptrdiff_t>(v * embedding.stride), length,
                  particles.begin() + static_cast<std::ptrdiff_t>(v * stride));
      std::copy_n(embedding.weights.begin() + static_cast<std::ptrdiff_t>(v * embedding.stride), length,
                  weights.begin() + static_cast<std::ptrdiff_t>(v * stride));
    }
    embedding.particles.swap(particles);
    embedding.weights.swap(weights);
  }
  embedding.stride = stride;
  fit(embedding.elements, static_cast<size_t>(vertices));
  fit(embedding.row_lengths, static_cast<size_t>(vertices));
  fit(embedding.particles, static_cast<size_t>(vertices) * stride);
  fit(embedding.weights, static_cast<size_t>(vertices) * stride);
}

SurfaceEmbedding map_surface(const CorotationalEfg& model, const CutSurface& surface, SurfaceMappingReport& report) {
  SurfaceEmbedding embedding;
  const int vertices = static_cast<int>(surface.rest_vertices().size() / 3);
  fit_rows(embedding, vertices, model.row_stride());
  const ElementCubes cubes(model);
  VertexMapper mapper(model, surface, cubes);
  for (int v = 0; v < vertices; ++v) mapper.map(v, embedding, report);
  return embedding;
}

void remap_surface(const CorotationalEfg& model, const CutSurface& surface, SurfaceEmbedding& embedding,
                   SurfaceMappingReport& report, MappingReuse& reuse) {
  const Vector& rest_vertices = surface.rest_vertices();
  const int vertices = static_cast<int>(rest_vertices.size() / 3);
  const int stride = model.row_stride();
  const int previous = embedding.vertex_count();
  if (static_cast<int>(reuse.keys.size()) != previous || reuse.rest_vertices.size() != 3 * static_cast<Eigen::Index>(previous) ||
      static_cast<int>(reuse.anchors.size()) != previous)
    throw std::invalid_argument("remap_surface: the keys, rest positions and anchors are not those of the embedding's vertices");
  if (vertices < previous) throw std::invalid_argument("remap_surface: the surface has fewer vertex indices than the embedding");
  const RestCut& cut = surface.rest_cut();
  if (reuse.triangles_mapped > cut.size()) throw std::invalid_argument("remap_surface: the cut lost triangles");
  // The box of the triangles the cut gained since the last mapping.
  Vec3 cut_lo = Vec3::Constant(std::numeric_limits<double>::infinity()), cut_hi = -cut_lo;
  for (int t = reuse.triangles_mapped; t < cut.size(); ++t) {
    const auto box = box_of(cut.triangles()[t]);
    cut_lo = cut_lo.cwiseMin(box[0]), cut_hi = cut_hi.cwiseMax(box[1]);
  }
  const bool cut_grew = reuse.triangles_mapped < cut.size();
  fit_rows(embedding, vertices, stride);
  reuse.keys.resize(static_cast<size_t>(vertices), -1);
  reuse.rest_vertices.conservativeResize(3 * static_cast<Eigen::Index>(vertices));
  reuse.anchors.resize(static_cast<size_t>(vertices), Vec3::Zero());
  reuse.remapped.clear();
  std::optional<VertexMapper> mapper;
  const auto& keys = surface.vertex_keys();
  const auto& anchors = surface.anchors();
  // With the copies taken at a known revision of the surface, an index it has not written
  // since holds them still: neither compared nor copied again.
  const bool by_revision = reuse.revision >= 0 && reuse.revision <= surface.revision();
  const auto& revisions = surface.vertex_revisions();
  const auto& centres = model.element_centres();
  const int elements = model.element_count();
  // The indices to look at: all, or (with the rows indexed by element, see MappingReuse) only
  // those that can be dirty: appended, written since (one rebuild at most: its list), on an
  // element marked changed, or on an element whose segments' box meets the new triangles'.
  const bool indexed = by_revision && surface.revision() - reuse.revision <= 1 && reuse.stride == stride &&
                       static_cast<int>(reuse.by_element.size()) == elements &&
                       static_cast<int>(reuse.element_boxes.size()) == elements && reuse.element_tree;
  std::vector<int> candidates;
  if (indexed) {
    for (int v = previous; v < vertices; ++v) candidates.push_back(v);
    if (surface.revision() > reuse.revision)
      for (int v : surface.written_vertices())
        if (v < previous) candidates.push_back(v);
    const auto take = [&](int e) { candidates.insert(candidates.end(), reuse.by_element[e].begin(), reuse.by_element[e].end()); };
    if (cut_grew) {
      // The tree's boxes hold the exact ones (rounded outwards): the exact test decides.
      std::vector<int> near;
      reuse.element_tree->query(MovingSegment{{cut_lo, cut_hi}, {cut_lo, cut_hi}}, near);
      for (int e : near) {
        const auto& box = reuse.element_boxes[e];
        if ((box[0].array() <= cut_hi.array()).all() && (box[1].array() >= cut_lo.array()).all()) take(e);
      }
    }
    if (reuse.element_changed)
      for (int e = 0; e < elements; ++e)
        if ((*reuse.element_changed)[e]) take(e);
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
  }
  const auto grow_box = [&](int v) {
    auto& box = reuse.element_boxes[embedding.elements[v]];
    const Vec3& centre = centres[embedding.elements[v]];
    box[0] = box[0].cwiseMin(anchors[v].cwiseMin(centre)), box[1] = box[1].cwiseMax(anchors[v].cwiseMax(centre));
  };
  const auto visit = [&](int v) {
    const Eigen::Index at = 3 * static_cast<Eigen::Index>(v);
    bool dirty = v >= previous || embedding.row_lengths[v] > stride;
    const bool written = v >= previous || !by_revision || revisions[v] > reuse.revision;
    if (!dirty && keys[v] >= 0) {
      // A used index: the same vertex (key, rest position, anchor) on an element whose
      // neighbourhood did not change. Its point is then still the nearest visible one unless
      // a new triangle hides it from the anchor: the cut only grows, so points hidden before
      // stay hidden and the chosen one is the only one that can be lost.
      const Vec3& anchor = anchors[v];
      const int e = embedding.elements[v];
      dirty = (written && (reuse.keys[v] != keys[v] || Vec3(reuse.rest_vertices.segment<3>(at)) != Vec3(rest_vertices.segment<3>(at)) ||
                           reuse.anchors[v] != anchor)) ||
              (reuse.element_changed && (*reuse.element_changed)[e]);
      if (!dirty && cut_grew) {
        const Vec3& centre = centres[e];
        const Vec3 lo = anchor.cwiseMin(centre), hi = anchor.cwiseMax(centre);
        if ((lo.array() <= cut_hi.array()).all() && (hi.array() >= cut_lo.array()).all()) dirty = cut.crosses(anchor, centre);
      }
    }
    if (written) {
      reuse.keys[v] = keys[v];
      reuse.rest_vertices.segment<3>(at) = rest_vertices.segment<3>(at);
      reuse.anchors[v] = anchors[v];
    }
    if (!dirty) return;  // an unused index keeps the row it had: it stays where it was
    if (!mapper) {
      if (!reuse.element_cubes || reuse.element_cubes->elements != elements)
        reuse.element_cubes = std::make_shared<const ElementCubes>(model);
      mapper.emplace(model, surface, *reuse.element_cubes);
    }
    if (indexed && v < previous) {
      auto& from = reuse.by_element[embedding.elements[v]];
      const auto it = std::find(from.begin(), from.end(), v);
      if (it != from.end()) *it = from.back(), from.pop_back();
    }
    mapper->map(v, embedding, report);
    reuse.remapped.push_back(v);
    if (indexed) {
      const int e = embedding.elements[v];
      reuse.by_element[e].push_back(v);
      grow_box(v);
      const auto& box = reuse.element_boxes[e];
      reuse.element_tree->set_edge(e, MovingSegment{{box[0], box[1]}, {box[0], box[1]}});
    }
  };
  if (indexed) {
    for (int v : candidates) visit(v);
  } else {
    for (int v = 0; v < vertices; ++v) visit(v);
    // The index, taken from every row.
    reuse.by_element.assign(static_cast<size_t>(elements), {});
    reuse.element_boxes.assign(static_cast<size_t>(elements), {Vec3::Constant(std::numeric_limits<double>::infinity()),
                                                               Vec3::Constant(-std::numeric_limits<double>::infinity())});
    for (int v = 0; v < vertices; ++v) {
      reuse.by_element[embedding.elements[v]].push_back(v);
      grow_box(v);
    }
    reuse.element_tree = std::make_unique<EdgeBroadPhase>(0.0);
    for (int e = 0; e < elements; ++e) {
      const auto& box = reuse.element_boxes[e];
      if (!reuse.by_element[e].empty()) reuse.element_tree->set_edge(e, MovingSegment{{box[0], box[1]}, {box[0], box[1]}});
    }
  }
  reuse.stride = stride;
  reuse.triangles_mapped = cut.size();
  reuse.revision = surface.revision();
}

namespace {

// Whether a link of element e crosses the cut (its triangles from index `from` on).
bool element_linked_across(const CorotationalEfg& model, const RestCut& cut, int e, int from = 0) {
  if (!model.element_active(e)) return false;
  const Vec3 centre = model.element_centres()[e];
  const size_t base = static_cast<size_t>(e) * model.row_stride();
  for (int k = 0; k < model.row_lengths()[e]; ++k) {
    const Vec3 particle = model.rest_positions().segment<3>(3 * static_cast<Eigen::Index>(model.neighbours()[base + k]));
    if (cut.crosses(centre, particle, from)) return true;
  }
  return false;
}

}  // namespace

int elements_linked_across(const CorotationalEfg& model, const RestCut& cut) {
  if (cut.size() == 0) return 0;
  int across = 0;
  for (int e = 0; e < model.element_count(); ++e) across += element_linked_across(model, cut, e) ? 1 : 0;
  return across;
}

int update_elements_linked_across(const CorotationalEfg& model, const RestCut& cut, std::vector<std::uint8_t>& linked,
                                  const Vec3& lo, const Vec3& hi, const std::vector<std::uint8_t>* changed,
                                  std::vector<std::array<Vec3, 2>>* boxes, std::vector<int>* seen, LinkedAcrossIndex* index) {
  const int elements = model.element_count();
  const bool all = static_cast<int>(linked.size()) != elements;
  if (all) linked.assign(static_cast<size_t>(elements), 0);
  if (seen && (all || static_cast<int>(seen->size()) != elements)) seen->assign(static_cast<size_t>(elements), -1);
  const int stride = model.row_stride();
  // The box of an element's links: its centre and its neighbours, at rest.
  const auto link_box = [&](int e) {
    Vec3 box_lo = model.element_centres()[e], box_hi = box_lo;
    const size_t base = static_cast<size_t>(e) * stride;
    for (int k = 0; k < model.row_lengths()[e]; ++k) {
      const Vec3 particle = model.rest_positions().segment<3>(3 * static_cast<Eigen::Index>(model.neighbours()[base + k]));
      box_lo = box_lo.cwiseMin(particle), box_hi = box_hi.cwiseMax(particle);
    }
    return std::array<Vec3, 2>{box_lo, box_hi};
  };
  // Cached boxes stand for the elements whose neighbourhood did not change.
  const bool cached = boxes && changed && static_cast<int>(boxes->size()) == elements;
  if (boxes && !cached) {
    boxes->resize(static_cast<size_t>(elements));
    for (int e = 0; e < elements; ++e) (*boxes)[e] = link_box(e);
  }
  // The index stands for the cached boxes: built again after they were all taken again.
  if (index && (!cached || cut.size() == 0)) index->centres.items.clear();
  if (cut.size() == 0) {  // nothing to be linked across (the boxes are kept up to date all the same)
    if (cached)
      for (int e = 0; e < elements; ++e)
        if ((*changed)[e]) (*boxes)[e] = link_box(e);
    if (seen) std::fill(seen->begin(), seen->end(), 0);
    return 0;
  }
  const auto in_box = [&](const std::array<Vec3, 2>& box) {
    return (box[0].array() <= hi.array()).all() && (box[1].array() >= lo.array()).all();
  };
  // The cut only grows and an unchanged element keeps its links: one linked across stays so,
  // and one that was not becomes so only through a triangle added since its flag was taken
  // (`seen`, per element): those unchanged elements are tested against the cut's triangles
  // from their `seen` on only (RestCut::crosses(p, q, from): the cut's own index, nothing
  // built per call), the same answer as the full cut's.
  // Elements are never re-activated (CorotationalEfg::deactivate_element is final).
  // One pass over the elements: those to test (changed, or whose links reach into the box).
  std::vector<int> to_test;
  // How far an element's cached link box reaches from its centre (per axis).
  const auto extent = [&](int e) {
    const Vec3 centre = model.element_centres()[e];
    const auto& box = (*boxes)[e];
    return std::max((centre - box[0]).maxCoeff(), (box[1] - centre).maxCoeff());
  };
  bool indexed = index && cached && !all;
  if (indexed && index->centres.items.empty()) {
    index->reach = 0;
    for (int e = 0; e < elements; ++e) index->reach = std::max(index->reach, extent(e));
    index->deactivated = -1;
    indexed = index->centres.build(model.element_centres(), model.spacing());  // else the plain pass below
  }
  if (indexed) {
    // The same elements from the index: those changed (their boxes taken again, the reach
    // grown to hold them), and those whose centre lies within the reach of the box, tested.
    // Elements are never re-activated: their flags are cleared once, when the count moves.
    if (index->deactivated != model.deactivated_elements()) {
      for (int e = 0; e < elements; ++e)
        if (!model.element_active(e)) linked[e] = 0;
      index->deactivated = model.deactivated_elements();
    }
    for (int e = 0; e < elements; ++e)
      if ((*changed)[e] && model.element_active(e)) {
        (*boxes)[e] = link_box(e);
        index->reach = std::max(index->reach, extent(e));
        to_test.push_back(e);
      }
    const size_t changed_count = to_test.size();
    // The bins holding every centre within the reach of [lo, hi] (with room for rounding).
    const double margin = index->reach * (1 + 1e-9) + 1e-12 * index->centres.cell;
    const PointBins& bins = index->centres;
    bins.visit_box(lo - Vec3::Constant(margin), hi + Vec3::Constant(margin), [&](int s) {
      const int e = bins.items[static_cast<size_t>(s)];
      if (!(*changed)[e] && model.element_active(e) && in_box((*boxes)[e])) to_test.push_back(e);
    });
    std::sort(to_test.begin() + static_cast<std::ptrdiff_t>(changed_count), to_test.end());
    std::inplace_merge(to_test.begin(), to_test.begin() + static_cast<std::ptrdiff_t>(changed_count), to_test.end());
  } else {
    if (index) index->centres.items.clear();  // the boxes may change without it
    for (int e = 0; e < elements; ++e) {
      if (!model.element_active(e)) {
        linked[e] = 0;
        continue;
      }
      const bool element_changed = changed && (*changed)[e];
      if (cached && element_changed) (*boxes)[e] = link_box(e);
      if (all || element_changed || in_box(boxes ? (*boxes)[e] : link_box(e))) to_test.push_back(e);
    }
  }
  const bool since_flag = seen && cached && !all;  // unchanged elements: the triangles since their flag
  // The box of the triangles any of them is tested against: one whose links' box misses it
  // is not linked across them.
  int added_from = cut.size();
  if (since_flag)
    for (const int e : to_test)
      if (!(*changed)[e] && !linked[e]) added_from = std::min(added_from, std::max(0, (*seen)[e]));
  Vec3 added_lo = Vec3::Constant(std::numeric_limits<double>::infinity()), added_hi = -added_lo;
  for (int t = added_from; t < cut.size(); ++t) {
    const RestTriangle& triangle = cut.triangles()[static_cast<size_t>(t)];
    for (const Vec3* p : {&triangle.a, &triangle.b, &triangle.c}) added_lo = added_lo.cwiseMin(*p), added_hi = added_hi.cwiseMax(*p);
  }
  const auto meets_added = [&](int e) {
    const auto& box = (*boxes)[e];
    return (box[0].array() <= added_hi.array()).all() && (box[1].array() >= added_lo.array()).all();
  };
  for (const int e : to_test) {
    if (since_flag && !(*changed)[e]) {
      // Linked before, linked still; else only the triangles since its flag can link it.
      if (!linked[e] && meets_added(e)) linked[e] = element_linked_across(model, cut, e, std::max(0, (*seen)[e])) ? 1 : 0;
    } else {
      linked[e] = element_linked_across(model, cut, e) ? 1 : 0;
    }
    if (seen) (*seen)[e] = cut.size();
  }
  int across = 0;
  for (const std::uint8_t flag : linked) across += flag;
  return across;
}

}  // namespace incise::physics
