#include "physics/cut/front_surface.hpp"

#include "physics/core/mix.hpp"
#include "physics/cut/triangulate_2d.hpp"
#include "physics/cut/uniform_grid.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <numbers>
#include <set>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <tuple>
#include <utility>

namespace incise::physics {

namespace {

bool finite(const Vec3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }

// The sign of an orientation, evaluated on the points in increasing id order and fixed up by
// the permutation's parity, zero counted as positive: every test that shares the four points
// sees the same sign (see the header). `value` is the determinant in the caller's order.
struct Orientation {
  double value = 0;
  int sign = 1;
};

// The stroke's points: the base mesh's vertices, then the sheet's (blade point i of sample j
// at base + j * points + i).
struct PointTable {
  const std::vector<Vec3>* base = nullptr;
  const std::vector<std::vector<Vec3>>* samples = nullptr;
  int points_per_sample = 0;
  int base_count() const { return static_cast<int>(base->size()); }
  int sheet_id(int point, int sample) const { return base_count() + sample * points_per_sample + point; }
  const Vec3& operator[](int id) const {
    if (id < base_count()) return (*base)[static_cast<size_t>(id)];
    const int local = id - base_count();
    return (*samples)[static_cast<size_t>(local / points_per_sample)][static_cast<size_t>(local % points_per_sample)];
  }
};

Orientation orient(const PointTable& points, int a, int b, int c, int d) {
  std::array<int, 4> ids{a, b, c, d};
  int parity = 1;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j + 1 < 4 - i; ++j)
      if (ids[static_cast<size_t>(j)] > ids[static_cast<size_t>(j + 1)]) {
        std::swap(ids[static_cast<size_t>(j)], ids[static_cast<size_t>(j + 1)]);
        parity = -parity;
      }
  const Vec3& p = points[ids[0]];
  const double det = (points[ids[1]] - p).dot((points[ids[2]] - p).cross(points[ids[3]] - p));
  return {parity * det, parity * (det >= 0 ? 1 : -1)};
}

// Segment [p, q] against triangle (x, y, z), all ids. `along`: the crossing's fraction from p;
// `weights`: its barycentric coordinates on x, y, z; `p_sign`: orient(p, x, y, z)'s sign
// (positive: p is on the side opposite the triangle's normal).
struct Crossing {
  double along = 0;
  std::array<double, 3> weights{};
  int p_sign = 0;
};

std::optional<Crossing> segment_crosses(const PointTable& points, int p, int q, int x, int y, int z) {
  const Orientation sp = orient(points, p, x, y, z), sq = orient(points, q, x, y, z);
  if (sp.sign == sq.sign) return std::nullopt;
  const Orientation e_xy = orient(points, p, q, x, y), e_yz = orient(points, p, q, y, z),
                    e_zx = orient(points, p, q, z, x);
  if (e_xy.sign != e_yz.sign || e_yz.sign != e_zx.sign) return std::nullopt;
  Crossing hit;
  const double denominator = sp.value - sq.value;
  hit.along = denominator != 0 ? std::clamp(sp.value / denominator, 0.0, 1.0) : 0.5;
  const double total = e_xy.value + e_yz.value + e_zx.value;
  if (total != 0)
    hit.weights = {e_yz.value / total, e_zx.value / total, e_xy.value / total};
  else
    hit.weights = {1.0 / 3, 1.0 / 3, 1.0 / 3};
  hit.p_sign = sp.sign;
  return hit;
}

// Whether the segment [p, q] crosses triangle (a, b, c) (Moller-Trumbore), for the parity of
// a ray: only the "began inside" report rests on it.
int ray_crosses(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 direction = q - p, e1 = b - a, e2 = c - a;
  const Vec3 h = direction.cross(e2);
  const double determinant = e1.dot(h);
  if (determinant == 0) return 0;
  const double inverse = 1 / determinant;
  const Vec3 s = p - a;
  const double u = inverse * s.dot(h);
  if (u < 0 || u > 1) return 0;
  const Vec3 k = s.cross(e1);
  const double v = inverse * direction.dot(k);
  if (v < 0 || u + v > 1) return 0;
  const double along = inverse * e2.dot(k);
  return along >= 0 && along <= 1 ? 1 : 0;
}

// Triangulates a small polygon lying in a plane of normal n by clipping ears. The polygon
// comes in the order its triangles must keep (the base triangle's, so that they share each
// edge with their neighbours the other way round), and every triangle keeps it, whatever the
// geometry says: an ear is taken where the polygon turns counter-clockwise about n, and where
// none does (a sliver, rounding) one is clipped anyway, still in that order. A vertex on the
// line of its neighbours (the slit's middle) is never an ear: it is clipped last, with a
// vertex off that line.
void ear_clip(std::vector<int> polygon, const Vec3& n, const std::vector<Vec3>& positions, std::vector<std::array<int, 3>>& out) {
  const auto at = [&](int id) -> const Vec3& { return positions[static_cast<size_t>(id)]; };
  const auto turn = [&](int a, int b, int c) { return (at(b) - at(a)).cross(at(c) - at(a)).dot(n); };
  while (polygon.size() > 3) {
    const size_t m = polygon.size();
    size_t best = m;
    double best_turn = 0;
    for (size_t k = 0; k < m; ++k) {
      const int a = polygon[(k + m - 1) % m], b = polygon[k], c = polygon[(k + 1) % m];
      const double area = turn(a, b, c);
      if (!(area > 0)) continue;
      bool empty = true;
      for (size_t j = 0; j < m && empty; ++j) {
        const int p = polygon[j];
        if (p == a || p == b || p == c) continue;
        empty = !(turn(a, b, p) >= 0 && turn(b, c, p) >= 0 && turn(c, a, p) >= 0);
      }
      // The fattest ear, so that slivers are left for last.
      if (empty && (best == m || area > best_turn)) {
        best = k;
        best_turn = area;
      }
    }
    if (best == m) best = 0;  // no ear (a degenerate polygon): clip anyway
    out.push_back({polygon[(best + m - 1) % m], polygon[best], polygon[(best + 1) % m]});
    polygon.erase(polygon.begin() + static_cast<long>(best));
  }
  out.push_back({polygon[0], polygon[1], polygon[2]});
}

// Each undirected edge of a closed mesh, with the triangle on each side.
struct EdgeTable {
  std::vector<std::array<int, 2>> ends;          // lower id first
  std::vector<std::array<int, 2>> triangles;     // the two triangles using the edge
  std::vector<std::array<int, 3>> of_triangle;   // edge k of triangle (t[k], t[k+1])
};

EdgeTable edge_table(const std::vector<std::array<int, 3>>& triangles) {
  struct Use {
    int lower, higher, triangle, corner;
    bool forward;  // lower -> higher
  };
  std::vector<Use> uses;
  uses.reserve(3 * triangles.size());
  for (size_t t = 0; t < triangles.size(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = triangles[t][static_cast<size_t>(k)], b = triangles[t][static_cast<size_t>((k + 1) % 3)];
      uses.push_back({std::min(a, b), std::max(a, b), static_cast<int>(t), k, a < b});
    }
  std::sort(uses.begin(), uses.end(), [](const Use& l, const Use& r) {
    return l.lower != r.lower ? l.lower < r.lower : l.higher != r.higher ? l.higher < r.higher : l.forward > r.forward;
  });
  EdgeTable table;
  table.of_triangle.assign(triangles.size(), {-1, -1, -1});
  for (size_t u = 0; u < uses.size();) {
    size_t v = u;
    while (v < uses.size() && uses[v].lower == uses[u].lower && uses[v].higher == uses[u].higher) ++v;
    if (v - u != 2 || !uses[u].forward || uses[u + 1].forward) {
      std::ostringstream message;
      message << "FrontSurface: edge (" << uses[u].lower << ", " << uses[u].higher
              << ") is not used exactly once in each direction: the mesh must be closed and consistently oriented";
      throw std::invalid_argument(message.str());
    }
    const int e = static_cast<int>(table.ends.size());
    table.ends.push_back({uses[u].lower, uses[u].higher});
    table.triangles.push_back({uses[u].triangle, uses[u + 1].triangle});
    table.of_triangle[static_cast<size_t>(uses[u].triangle)][static_cast<size_t>(uses[u].corner)] = e;
    table.of_triangle[static_cast<size_t>(uses[u + 1].triangle)][static_cast<size_t>(uses[u + 1].corner)] = e;
    u = v;
  }
  return table;
}

// Items with boxes binned in a uniform grid, for box queries; each item is visited once per
// query, at the first of its cells the grid's order meets (the crossings are numbered in that
// order: the frame below is part of the result).
class BoxBins {
 public:
  void build(const std::vector<std::array<Vec3, 2>>& boxes, double cell) {
    boxes_ = boxes;
    lo_ = boxes.front()[0];
    hi_ = boxes.front()[1];
    for (const auto& box : boxes) lo_ = lo_.cwiseMin(box[0]), hi_ = hi_.cwiseMax(box[1]);
    // At most about 2^22 cells: the cell grows for large extents.
    GridCells frame;
    frame.origin = lo_;
    frame.cell = cell;
    for (;;) {
      for (int d = 0; d < 3; ++d) frame.count[static_cast<size_t>(d)] = std::max(1LL, static_cast<long long>(std::ceil((hi_[d] - lo_[d]) / frame.cell)) + 1);
      if (static_cast<double>(frame.total()) <= 4.2e6) break;
      frame.cell *= 1.5;
    }
    grid_.build_boxes(frame, boxes);
  }
  // The diagonal of the box around every item.
  double extent() const { return (hi_ - lo_).norm(); }
  template <typename Visit>
  void near(const Vec3& lo, const Vec3& hi, const Visit& visit) const {
    if (boxes_.empty()) return;
    grid_.visit_box_once(lo, hi, [&](int b) {
      const auto& box = boxes_[static_cast<size_t>(b)];
      if ((lo.array() > box[1].array()).any() || (hi.array() < box[0].array()).any()) return;
      visit(b);
    });
  }

 private:
  std::vector<std::array<Vec3, 2>> boxes_;
  Vec3 lo_ = Vec3::Zero(), hi_ = Vec3::Zero();
  UniformGrid grid_;
};

// A base edge the stroke's sheet crosses: a pair of coincident vertices, one per side.
struct EdgeCut {
  Vec3 point;
  Vec2 st;
  int lower = -1, higher = -1;             // the edge's ends
  bool lower_on_plus = false;              // the lower end is on the sheet's normal side
  Vec3 normal = Vec3::Zero();              // the sheet's there (unit)
  int copy_lower = -1, copy_higher = -1;   // the output vertices on each end's side
};

// A base triangle an outline segment crosses, `along` it from its first point.
struct OutlineHit {
  int triangle;
  double along;
  Vec3 point;
  bool entering;  // the outline goes into the body here
};

// The last sample's cut face as triangulated, in (s, t): the region's points and boundary and
// the constrained Delaunay triangles (before the shared inner edges are split). The region's
// points are the boundary's (the ends of its edges: chords, outline, slits), then the
// lattice's, row by row, each row by increasing column.
using StKey = std::pair<double, double>;
StKey st_key(const Vec2& p) { return {p.x(), p.y()}; }

struct FaceCache {
  bool valid = false;
  PlanarRegion region;
  std::vector<std::array<int, 3>> triangles;
  std::vector<std::pair<StKey, int>> sorted;  // the boundary's points by (s, t), with their index
  int lattice_begin = 0;                      // the lattice's first point in region.points
  std::vector<int> row_start;                 // per lattice row r: its points from lattice_begin + row_start[r]
  std::vector<int> column;                    // per lattice point: its column
  // Per lattice point: its point on the sheet, once the cell of the sheet that holds it is
  // fixed (between two samples before the last: it no longer changes), else lifted_final 0.
  std::vector<Vec3> lifted;
  std::vector<std::uint8_t> lifted_final;
};

std::vector<std::pair<StKey, int>> sorted_points(const std::vector<Vec2>& points, size_t count) {
  std::vector<std::pair<StKey, int>> sorted(count);
  for (size_t k = 0; k < count; ++k) sorted[k] = {st_key(points[k]), static_cast<int>(k)};
  std::sort(sorted.begin(), sorted.end());
  return sorted;
}

// What changed in the region since the last sample's (FaceCache): per old point its new
// index (-1: gone), points told apart by their exact (s, t), which the stroke computes the
// same way at every sample; and the lowest t of a point added or gone, or of an end of a
// boundary edge added or gone.
struct FaceChange {
  std::vector<int> to_new;
  double t_change = std::numeric_limits<double>::infinity();
  std::vector<std::array<int, 2>> sorted_boundary;  // the region's boundary, sorted
};

// What changed in the region's boundary since the last sample's (`cache`): its points matched
// by their exact (s, t) (`new_sorted`: the region's boundary points sorted), its edges
// compared; t_change is the lowest t of a point or edge end added or gone. Lattice points are
// matched afterwards, by row and column (FrontSurface::recompute).
FaceChange boundary_change(const FaceCache& cache, const PlanarRegion& region, const std::vector<std::pair<StKey, int>>& new_sorted) {
  FaceChange change;
  double t_boundary = std::numeric_limits<double>::infinity();
  const auto& old_points = cache.region.points;
  change.to_new.assign(old_points.size(), -1);
  const auto& old_sorted = cache.sorted;
  size_t o = 0, n = 0;
  while (o < old_sorted.size() || n < new_sorted.size()) {
    if (n == new_sorted.size() || (o < old_sorted.size() && old_sorted[o].first < new_sorted[n].first)) {
      t_boundary = std::min(t_boundary, old_sorted[o++].first.second);  // gone
    } else if (o == old_sorted.size() || new_sorted[n].first < old_sorted[o].first) {
      t_boundary = std::min(t_boundary, new_sorted[n++].first.second);  // added
    } else {
      change.to_new[static_cast<size_t>(old_sorted[o++].second)] = new_sorted[n++].second;
    }
  }
  // Boundary edges added or gone, in the new numbering (an old edge with a gone end is gone).
  std::vector<std::array<int, 2>> old_boundary;
  old_boundary.reserve(cache.region.boundary.size());
  for (const auto& e : cache.region.boundary) {
    const int from = change.to_new[static_cast<size_t>(e[0])], to = change.to_new[static_cast<size_t>(e[1])];
    if (from < 0 || to < 0) {
      t_boundary = std::min({t_boundary, old_points[static_cast<size_t>(e[0])].y(), old_points[static_cast<size_t>(e[1])].y()});
      continue;
    }
    old_boundary.push_back({from, to});
  }
  change.sorted_boundary = region.boundary;
  std::sort(old_boundary.begin(), old_boundary.end());
  std::sort(change.sorted_boundary.begin(), change.sorted_boundary.end());
  std::vector<std::array<int, 2>> differ;
  std::set_symmetric_difference(old_boundary.begin(), old_boundary.end(), change.sorted_boundary.begin(), change.sorted_boundary.end(),
                                std::back_inserter(differ));
  for (const auto& e : differ)
    t_boundary = std::min({t_boundary, region.points[static_cast<size_t>(e[0])].y(), region.points[static_cast<size_t>(e[1])].y()});
  change.t_change = t_boundary;
  return change;
}

// triangulate_face's steps on a valid cache (see there): which of the last triangles to keep,
// the rest's region bounded by them, and (in triangulate_face) the two put together.
struct FaceReuse {
  FaceReuse(const PlanarRegion& region, const FaceCache& cache, const FaceChange& change)
      : region(region), cache(cache), change(change) {}

  bool choose_kept(double slack);
  int triangle_with(int a, int b) const;
  bool kept_edge(int a, int b) const;
  std::vector<std::array<int, 2>> rest_boundary();
  void gather_rest(const std::vector<std::array<int, 2>>& boundary);

  const PlanarRegion& region;
  const FaceCache& cache;
  const FaceChange& change;
  // The last triangles listed around each of their corners (compressed rows), and per last
  // triangle whether it is kept; the kept ones (new numbering) and the others.
  std::vector<int> around_start, around;
  std::vector<std::uint8_t> is_kept;
  std::vector<std::array<int, 3>> kept;
  std::vector<int> not_kept;
  std::vector<int> old_of_new;  // per new point: its last index, or -1
  PlanarRegion rest;            // what is triangulated again
  std::vector<int> from_rest;   // per point of rest: its index in region
};

// The kept triangles: all corners still there, the circumcircle below t_change. The last
// triangles are also listed around each of their corners (compressed rows), to find the
// rest's boundary from the triangles not kept, which lie near the front. False when none is
// kept.
bool FaceReuse::choose_kept(double slack) {
  const auto& old_points = cache.region.points;
  const std::vector<int>& to_new = change.to_new;
  const double t_change = change.t_change;
  const auto& old_triangles = cache.triangles;
  const size_t old_count = old_points.size();
  around_start.assign(old_count + 1, 0);
  around.assign(3 * old_triangles.size(), 0);
  is_kept.assign(old_triangles.size(), 0);
  for (size_t t = 0; t < old_triangles.size(); ++t) {
    const auto& tri = old_triangles[t];
    for (const int p : tri) ++around_start[static_cast<size_t>(p) + 1];
    const std::array<int, 3> now{to_new[static_cast<size_t>(tri[0])], to_new[static_cast<size_t>(tri[1])], to_new[static_cast<size_t>(tri[2])]};
    const bool keep_it = [&] {
      if (now[0] < 0 || now[1] < 0 || now[2] < 0) return false;
      const Vec2& a = old_points[static_cast<size_t>(tri[0])];
      const Vec2 b = old_points[static_cast<size_t>(tri[1])] - a, c = old_points[static_cast<size_t>(tri[2])] - a;
      const double d = 2 * (b.x() * c.y() - b.y() * c.x());
      if (!(std::abs(d) > 0)) return false;
      const Vec2 centre((c.y() * b.squaredNorm() - b.y() * c.squaredNorm()) / d, (b.x() * c.squaredNorm() - c.x() * b.squaredNorm()) / d);
      return a.y() + centre.y() + centre.norm() < t_change - slack;
    }();
    if (keep_it) {
      is_kept[t] = 1;
      kept.push_back(now);
    } else {
      not_kept.push_back(static_cast<int>(t));
    }
  }
  if (kept.empty()) return false;
  for (size_t p = 0; p < old_count; ++p) around_start[p + 1] += around_start[p];
  std::vector<int> fill(around_start.begin(), around_start.end() - 1);
  for (size_t t = 0; t < old_triangles.size(); ++t)
    for (const int p : old_triangles[t]) around[static_cast<size_t>(fill[static_cast<size_t>(p)]++)] = static_cast<int>(t);
  return true;
}

// The last triangle with the directed edge a -> b (last numbering), or -1.
int FaceReuse::triangle_with(int a, int b) const {
  for (int k = around_start[static_cast<size_t>(a)]; k < around_start[static_cast<size_t>(a) + 1]; ++k) {
    const int t = around[static_cast<size_t>(k)];
    const auto& tri = cache.triangles[static_cast<size_t>(t)];
    for (size_t c = 0; c < 3; ++c)
      if (tri[c] == a && tri[(c + 1) % 3] == b) return t;
  }
  return -1;
}

bool FaceReuse::kept_edge(int a, int b) const {
  const int t = a >= 0 && b >= 0 ? triangle_with(a, b) : -1;
  return t >= 0 && is_kept[static_cast<size_t>(t)] != 0;
}

// The rest's boundary: the region's edges no kept triangle has, and the kept triangles'
// edges that neither another kept triangle nor the region's boundary has, turned round.
// Such a kept edge is the twin of an edge of a triangle not kept or, with no twin, an edge
// of the last region's boundary (the triangulation covers the region exactly: every other
// edge has two triangles).
std::vector<std::array<int, 2>> FaceReuse::rest_boundary() {
  const std::vector<int>& to_new = change.to_new;
  const std::vector<std::array<int, 2>>& new_boundary = change.sorted_boundary;
  const auto& old_triangles = cache.triangles;
  old_of_new.assign(region.points.size(), -1);
  for (size_t o = 0; o < cache.region.points.size(); ++o)
    if (to_new[o] >= 0) old_of_new[static_cast<size_t>(to_new[o])] = static_cast<int>(o);
  std::vector<std::array<int, 2>> boundary;
  for (const auto& e : region.boundary)
    if (!kept_edge(old_of_new[static_cast<size_t>(e[0])], old_of_new[static_cast<size_t>(e[1])])) boundary.push_back(e);
  const size_t from_region = boundary.size();
  const auto turn_round = [&](int a, int b) {  // the kept edge a -> b (last numbering)
    const int from = to_new[static_cast<size_t>(a)], to = to_new[static_cast<size_t>(b)];
    if (!std::binary_search(new_boundary.begin(), new_boundary.end(), std::array<int, 2>{from, to})) boundary.push_back({to, from});
  };
  for (const int t : not_kept) {
    const auto& tri = old_triangles[static_cast<size_t>(t)];
    for (size_t c = 0; c < 3; ++c)
      if (kept_edge(tri[(c + 1) % 3], tri[c])) turn_round(tri[(c + 1) % 3], tri[c]);
  }
  for (const auto& e : cache.region.boundary)
    if (kept_edge(e[0], e[1]) && triangle_with(e[1], e[0]) < 0) turn_round(e[0], e[1]);
  // Those in the order of the kept edges they turn round (the points' numbering in
  // gather_rest, and with it the triangulation's ties, follow it).
  std::sort(boundary.begin() + static_cast<std::ptrdiff_t>(from_region), boundary.end(),
            [](const std::array<int, 2>& l, const std::array<int, 2>& r) { return std::tie(l[1], l[0]) < std::tie(r[1], r[0]); });
  return boundary;
}

// The rest's points: the ends of its boundary, and those no kept triangle uses within its
// boundary's box (a point outside the box is outside the rest, and the triangulation ignores
// it), by increasing index: the new points, and the last ones with no kept triangle around
// them (the corners of triangles not kept, and those with none).
void FaceReuse::gather_rest(const std::vector<std::array<int, 2>>& boundary) {
  const auto& points = region.points;
  const std::vector<int>& to_new = change.to_new;
  const size_t point_count = points.size(), old_count = cache.region.points.size();
  std::vector<int> rest_index(point_count, -1);
  const auto take = [&](int p) {
    if (rest_index[static_cast<size_t>(p)] < 0) {
      rest_index[static_cast<size_t>(p)] = static_cast<int>(rest.points.size());
      rest.points.push_back(points[static_cast<size_t>(p)]);
      from_rest.push_back(p);
    }
    return rest_index[static_cast<size_t>(p)];
  };
  for (const auto& e : boundary) rest.boundary.push_back({take(e[0]), take(e[1])});
  std::vector<int> free_points;
  for (size_t p = 0; p < point_count; ++p)
    if (old_of_new[p] < 0) free_points.push_back(static_cast<int>(p));
  const auto unused = [&](int o) {
    for (int k = around_start[static_cast<size_t>(o)]; k < around_start[static_cast<size_t>(o) + 1]; ++k)
      if (is_kept[static_cast<size_t>(around[static_cast<size_t>(k)])]) return false;
    return true;
  };
  for (const int t : not_kept)
    for (const int o : cache.triangles[static_cast<size_t>(t)])
      if (to_new[static_cast<size_t>(o)] >= 0 && unused(o)) free_points.push_back(to_new[static_cast<size_t>(o)]);
  for (size_t o = 0; o < old_count; ++o)
    if (around_start[o] == around_start[o + 1] && to_new[o] >= 0) free_points.push_back(to_new[o]);
  std::sort(free_points.begin(), free_points.end());
  free_points.erase(std::unique(free_points.begin(), free_points.end()), free_points.end());
  Eigen::AlignedBox2d box;
  for (const Vec2& p : rest.points) box.extend(p);
  for (const int p : free_points)
    if (box.contains(points[static_cast<size_t>(p)])) take(p);
}

// triangulate_region(region), keeping what the last sample's triangulation (`cache`) has well
// behind the front. Between two samples the region changes only at and above some t (the
// lowest t of a point added or gone, or of an end of a boundary edge added or gone: the
// front, its new crossings, a crossing a fold cancelled): a last triangle whose circumcircle
// lies below that t keeps its corners, has no new point in its circle and no new boundary
// edge through it, and stays inside (the boundary's change is a closed chain above it), so it
// is a triangle of the new constrained Delaunay triangulation too (which is unique for points
// in general position: the cut face's lattice is moved off its cocircular spots). Only the
// rest is triangulated again, bounded by the kept triangles' edges. The result is the same
// as triangulate_region's, element for element (both sorted, each triangle from its smallest
// index). Falls back to the whole region when nothing is kept, the rest cannot be
// triangulated on its own, or `change` is null (no valid cache). `next` is what the cache
// keeps of this region (its sorted boundary points and its lattice's rows), for the next.
std::vector<std::array<int, 3>> triangulate_face(const PlanarRegion& region, FaceCache& cache, const FaceChange* change,
                                                 FaceCache&& next, double slack, int& kept_count) {
  kept_count = 0;
  const auto keep = [&](std::vector<std::array<int, 3>> face) {
    next.valid = true;
    next.region = region;
    next.triangles = face;
    cache = std::move(next);
    return face;
  };
  const auto whole = [&] { return keep(triangulate_region(region)); };
  if (!cache.valid || !change) return whole();
  FaceReuse reuse(region, cache, *change);
  if (!reuse.choose_kept(slack)) return whole();
  const std::vector<std::array<int, 3>>& kept = reuse.kept;
  kept_count = static_cast<int>(kept.size());
  reuse.gather_rest(reuse.rest_boundary());
  std::vector<std::array<int, 3>> face = kept;
  if (!reuse.rest.boundary.empty()) {
    std::vector<std::array<int, 3>> rest_face;
    try {
      rest_face = triangulate_region(reuse.rest);
    } catch (const std::invalid_argument&) {
      kept_count = 0;
      return whole();
    }
    const std::vector<int>& from_rest = reuse.from_rest;
    for (const auto& tri : rest_face)
      face.push_back({from_rest[static_cast<size_t>(tri[0])], from_rest[static_cast<size_t>(tri[1])], from_rest[static_cast<size_t>(tri[2])]});
  }
  // In triangulate_region's order: each triangle from its smallest index, sorted. The kept
  // ones, renumbered, are mostly still in order (the numbering follows the region's, which
  // changes near the front): when they are, only the rest is sorted and merged in.
  for (auto& tri : face) std::rotate(tri.begin(), std::min_element(tri.begin(), tri.end()), tri.end());
  const auto rest_begin = face.begin() + static_cast<std::ptrdiff_t>(kept.size());
  if (std::is_sorted(face.begin(), rest_begin)) {
    std::sort(rest_begin, face.end());
    std::inplace_merge(face.begin(), rest_begin, face.end());
  } else {
    std::sort(face.begin(), face.end());
  }
  return keep(std::move(face));
}

}  // namespace

struct FrontSurface::Base {
  EdgeTable edges;
  BoxBins edge_bins, triangle_bins;
  std::vector<int> around_start, around;  // per base vertex, its triangles (compressed rows)
  std::vector<int> cut_face_slots;        // the base's cut-face triangles
};

struct FrontSurface::Stroke {
  int intervals_searched = 0;  // sample intervals whose sheet was searched for crossings
  std::vector<int> edge_cut;   // per base edge: index into cuts, or -1
  std::vector<EdgeCut> cuts;
  std::vector<int> cut_edges;  // the base edge of each cut
  std::vector<std::string> problems;  // found in the fixed part, kept for the stroke
  int folded_edges = 0;               // crossings cancelled by a second one (see recompute)
  // Hits of the outline's fixed segments: the first sample's, and each interval's segment of
  // the far end's path (first to last) and the near end's (last to first).
  std::vector<std::vector<OutlineHit>> first_sample, far_end, near_end;
  // The last sample's cut face (triangulate_face), not kept by a snapshot: a stroke undone
  // to one triangulates its next face whole.
  FaceCache face;

  // What a sample may have to be undone to: all but edge_cut (as long as the base's edges),
  // which follows from cut_edges, and the face's cache.
  Stroke snapshot() const {
    Stroke copy;
    copy.intervals_searched = intervals_searched;
    copy.cuts = cuts;
    copy.cut_edges = cut_edges;
    copy.problems = problems;
    copy.folded_edges = folded_edges;
    copy.first_sample = first_sample;
    copy.far_end = far_end;
    copy.near_end = near_end;
    return copy;
  }
  void restore(Stroke&& from) {
    for (const int e : cut_edges) edge_cut[static_cast<size_t>(e)] = -1;
    std::vector<int> keep = std::move(edge_cut);
    *this = std::move(from);
    edge_cut = std::move(keep);
    for (size_t c = 0; c < cut_edges.size(); ++c) edge_cut[static_cast<size_t>(cut_edges[c])] = static_cast<int>(c);
  }
};

std::vector<std::vector<ConstraintPlane>> VertexPlanes::lists() const {
  std::vector<std::vector<ConstraintPlane>> all = lists_;
  all.reserve(size());
  for (std::size_t v = lists_.size(); v < size(); ++v) {
    const auto planes = (*this)[v];
    all.emplace_back(planes.begin(), planes.end());
  }
  return all;
}

void VertexPlanes::set_singles(std::size_t count) {
  singles_ = count;
  if (single_.size() < count) single_.resize(count);
  has_single_.assign(count, 0);
}

void VertexPlanes::add(std::size_t v, const ConstraintPlane& plane) {
  if (v < lists_.size()) {
    lists_[v].push_back(plane);
    return;
  }
  const std::size_t k = v - lists_.size();
  if (k >= singles_) throw std::logic_error("VertexPlanes::add: vertex " + std::to_string(v) + " is past the last one");
  if (has_single_[k]) throw std::logic_error("VertexPlanes::add: vertex " + std::to_string(v) + " takes one plane and has it");
  single_[k] = plane;
  has_single_[k] = 1;
}

FrontSurface::~FrontSurface() = default;
FrontSurface::FrontSurface(FrontSurface&&) noexcept = default;
FrontSurface& FrontSurface::operator=(FrontSurface&&) noexcept = default;

// Every member is copied here: a member added to FrontSurface must be added to this list.
FrontSurface::FrontSurface(const FrontSurface& other)
    : front_width_(other.front_width_),
      base_vertices_(other.base_vertices_),
      base_triangles_(other.base_triangles_),
      base_(other.base_ ? std::make_unique<Base>(*other.base_) : nullptr),
      stroke_(other.stroke_ ? std::make_unique<Stroke>(*other.stroke_) : nullptr),
      spare_edge_cut_(other.spare_edge_cut_),
      samples_(other.samples_),
      sample_t_(other.sample_t_),
      blade_s_(other.blade_s_),
      base_planes_(other.base_planes_),
      vertices_(other.vertices_),
      triangles_(other.triangles_),
      vertex_planes_(other.vertex_planes_),
      crack_front_(other.crack_front_),
      base_crack_front_(other.base_crack_front_),
      base_cut_face_(other.base_cut_face_),
      cut_face_(other.cut_face_),
      replaced_slots_(other.replaced_slots_),
      planed_base_(other.planed_base_),
      last_report_(other.last_report_),
      end_problem_(other.end_problem_),
      reuse_face_(other.reuse_face_) {}

FrontSurface& FrontSurface::operator=(const FrontSurface& other) {
  if (this != &other) *this = FrontSurface(other);
  return *this;
}

void FrontSurface::index_base(std::unique_ptr<Base> with_edges) {
  if (with_edges) {
    base_ = std::move(with_edges);
  } else {
    base_ = std::make_unique<Base>();
    base_->edges = edge_table(base_triangles_);
  }
  double length = 0;
  std::vector<std::array<Vec3, 2>> boxes;
  boxes.reserve(base_->edges.ends.size());
  for (const auto& e : base_->edges.ends) {
    const Vec3& a = base_vertices_[static_cast<size_t>(e[0])];
    const Vec3& b = base_vertices_[static_cast<size_t>(e[1])];
    boxes.push_back({a.cwiseMin(b), a.cwiseMax(b)});
    length += (b - a).norm();
  }
  const double cell = 2 * length / static_cast<double>(std::max<size_t>(1, boxes.size()));
  base_->edge_bins.build(boxes, cell);
  boxes.clear();
  for (const auto& t : base_triangles_) {
    Vec3 lo = base_vertices_[static_cast<size_t>(t[0])], hi = lo;
    for (const int v : t) {
      lo = lo.cwiseMin(base_vertices_[static_cast<size_t>(v)]);
      hi = hi.cwiseMax(base_vertices_[static_cast<size_t>(v)]);
    }
    boxes.push_back({lo, hi});
  }
  base_->triangle_bins.build(boxes, cell);
  const size_t n = base_vertices_.size();
  base_->around_start.assign(n + 1, 0);
  for (const auto& tri : base_triangles_)
    for (const int v : tri) ++base_->around_start[static_cast<size_t>(v) + 1];
  for (size_t v = 0; v < n; ++v) base_->around_start[v + 1] += base_->around_start[v];
  base_->around.assign(static_cast<size_t>(base_->around_start[n]), 0);
  std::vector<int> fill(base_->around_start.begin(), base_->around_start.end() - 1);
  for (size_t s = 0; s < base_triangles_.size(); ++s)
    for (const int v : base_triangles_[s]) base_->around[static_cast<size_t>(fill[static_cast<size_t>(v)]++)] = static_cast<int>(s);
  base_->cut_face_slots.clear();
  for (size_t s = 0; s < base_cut_face_.size(); ++s)
    if (base_cut_face_[s]) base_->cut_face_slots.push_back(static_cast<int>(s));
}

std::span<const int> FrontSurface::base_triangles_around(int v) const {
  if (v < 0 || static_cast<size_t>(v) >= base_vertices_.size())
    throw std::invalid_argument("FrontSurface::base_triangles_around: vertex " + std::to_string(v) + " is not a base vertex");
  const auto first = static_cast<size_t>(base_->around_start[static_cast<size_t>(v)]);
  const auto last = static_cast<size_t>(base_->around_start[static_cast<size_t>(v) + 1]);
  return {base_->around.data() + first, last - first};
}

const std::vector<int>& FrontSurface::base_cut_face_slots() const { return base_->cut_face_slots; }

void FrontSurface::base_vertices_in(const Vec3& lo, const Vec3& hi, std::vector<int>& out) const {
  // Every vertex is a corner of a triangle whose box holds it.
  out.clear();
  base_->triangle_bins.near(lo, hi, [&](int t) {
    for (const int v : base_triangles_[static_cast<size_t>(t)]) {
      const Vec3& x = base_vertices_[static_cast<size_t>(v)];
      if ((x.array() >= lo.array()).all() && (x.array() <= hi.array()).all()) out.push_back(v);
    }
  });
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
}

FrontSurface::FrontSurface(std::vector<Vec3> vertices, std::vector<std::array<int, 3>> triangles, double front_width)
    : front_width_(front_width), base_vertices_(std::move(vertices)), base_triangles_(std::move(triangles)) {
  if (!(front_width_ > 0) || !std::isfinite(front_width_))
    throw std::invalid_argument("FrontSurface: front_width must be positive and finite, got " + std::to_string(front_width_));
  for (size_t v = 0; v < base_vertices_.size(); ++v)
    if (!finite(base_vertices_[v])) throw std::invalid_argument("FrontSurface: vertex " + std::to_string(v) + " is not finite");
  const int n = static_cast<int>(base_vertices_.size());
  for (size_t t = 0; t < base_triangles_.size(); ++t) {
    const auto& tri = base_triangles_[t];
    for (const int v : tri)
      if (v < 0 || v >= n)
        throw std::invalid_argument("FrontSurface: triangle " + std::to_string(t) + " names vertex " + std::to_string(v) +
                                    ", out of range [0, " + std::to_string(n) + ")");
    const Vec3 normal = (base_vertices_[static_cast<size_t>(tri[1])] - base_vertices_[static_cast<size_t>(tri[0])])
                            .cross(base_vertices_[static_cast<size_t>(tri[2])] - base_vertices_[static_cast<size_t>(tri[0])]);
    if (!(normal.norm() > 0)) throw std::invalid_argument("FrontSurface: triangle " + std::to_string(t) + " is degenerate");
  }
  if (base_triangles_.empty()) throw std::invalid_argument("FrontSurface: the mesh has no triangle");
  base_planes_.assign(base_vertices_.size(), {});
  base_cut_face_.assign(base_triangles_.size(), 0);
  base_crack_front_.assign(base_vertices_.size(), 0);
  index_base();
  show_base();
}

void FrontSurface::show_base() {
  // With room for a stroke's vertices and triangles: the first sample would otherwise move the
  // whole surface to a larger block, into fresh pages, on the stroke's first cutting step
  // (docs/physics-choices.md, "Threads and memory").
  const auto with_room = [](auto& to, const auto& from) {
    const std::size_t room = from.size() + from.size() / 4 + 256;
    if (to.capacity() < room) {
      to.clear();
      to.reserve(room);
    }
    to.assign(from.begin(), from.end());
  };
  with_room(vertices_, base_vertices_);
  with_room(triangles_, base_triangles_);
  vertex_planes_ = VertexPlanes(base_planes_);
  with_room(crack_front_, base_crack_front_);
  crack_front_.resize(vertices_.size(), 0);
  with_room(cut_face_, base_cut_face_);
  cut_face_.resize(triangles_.size(), 0);
  replaced_slots_.clear();
  planed_base_.clear();
}

void FrontSurface::restore_base() {
  // The output is the base's but for the replaced slots, the planed base vertices and what
  // follows the base's vertices and triangles (see the header).
  for (const int s : replaced_slots_) {
    triangles_[static_cast<size_t>(s)] = base_triangles_[static_cast<size_t>(s)];
    cut_face_[static_cast<size_t>(s)] = base_cut_face_[static_cast<size_t>(s)];
  }
  for (const int v : planed_base_) vertex_planes_.listed()[static_cast<size_t>(v)] = base_planes_[static_cast<size_t>(v)];
  replaced_slots_.clear();
  planed_base_.clear();
  triangles_.resize(base_triangles_.size());
  cut_face_.resize(base_triangles_.size());
  vertices_.resize(base_vertices_.size());
  vertex_planes_.set_singles(0);
  crack_front_.resize(base_vertices_.size());
}

FrontCutReport FrontSurface::advance(std::span<const Vec3> blade) {
  if (blade.size() < 2) throw std::invalid_argument("FrontSurface::advance: the blade needs at least two points");
  if (!samples_.empty() && blade.size() != samples_.front().size())
    throw std::invalid_argument("FrontSurface::advance: the blade has " + std::to_string(blade.size()) +
                                " points, the stroke's first sample had " + std::to_string(samples_.front().size()));
  for (size_t i = 0; i < blade.size(); ++i)
    if (!finite(blade[i])) throw std::invalid_argument("FrontSurface::advance: blade point " + std::to_string(i) + " is not finite");
  FrontCutReport report;
  if (samples_.empty()) {
    blade_s_.assign(1, 0.0);
    for (size_t i = 1; i < blade.size(); ++i) blade_s_.push_back(blade_s_.back() + (blade[i] - blade[i - 1]).norm());
    sample_t_.assign(1, 0.0);
    samples_.emplace_back(blade.begin(), blade.end());
    last_report_ = report;
    return report;  // a sheet needs two samples
  }
  double moved = 0;
  for (size_t i = 0; i < blade.size(); ++i) moved += (blade[i] - samples_.back()[i]).norm();
  moved /= static_cast<double>(blade.size());
  // Less than a hundredth of w from the last sample: the same cut (the motion adds up until
  // it is more). A blade that pauses in the body still moves at rest by what the solver's
  // roundoff moves the body (0.1-1 um per step in single precision on the GPU); such a sample
  // would set the direction the next ones must follow, at random (see below).
  if (!(moved > minimum_motion * front_width_)) return last_report_;
  if (samples_.size() >= 2) {
    // Back over what the stroke has cut (at rest the blade retreats when the body moves
    // onto it and back, or the hand does): nothing new to cut, and the sheet would fold
    // onto itself. The sample is left out; the front waits where it is.
    const auto& last = samples_.back();
    const auto& before = samples_[samples_.size() - 2];
    double forward = 0;
    for (size_t i = 0; i < blade.size(); ++i) forward += (blade[i] - last[i]).dot(last[i] - before[i]);
    if (forward < 0) {
      FrontCutReport held = last_report_;
      held.samples_held = 1;
      return held;
    }
  }
  // What the last good sample's stroke was, kept until this one is known to cut (its surface
  // follows from it: recompute gives it again).
  const bool keep = samples_.size() >= 2 && last_report_.ok();
  std::optional<Stroke> stroke_before;
  if (keep && stroke_) stroke_before = stroke_->snapshot();
  sample_t_.push_back(sample_t_.back() + moved);
  samples_.emplace_back(blade.begin(), blade.end());
  recompute(report);
  if (!report.ok() && keep) {
    // This sample cannot be cut (the problems say why): it is left out, and the surface
    // stays as the last good sample left it rather than going back to the stroke's base.
    samples_.pop_back();
    sample_t_.pop_back();
    if (stroke_before)
      stroke_->restore(std::move(*stroke_before));
    else
      drop_stroke();
    FrontCutReport again;
    recompute(again);
    FrontCutReport held = last_report_;
    held.problems = report.problems;
    held.samples_held = 1;
    return held;
  }
  last_report_ = report;
  if (report.ok() && report.crossings == 0 && report.tips == 0) {
    // Nothing touched: the stroke starts again from this sample.
    samples_.erase(samples_.begin(), samples_.end() - 1);
    sample_t_.assign(1, 0.0);
    blade_s_.assign(1, 0.0);
    for (size_t i = 1; i < blade.size(); ++i) blade_s_.push_back(blade_s_.back() + (blade[i] - blade[i - 1]).norm());
    drop_stroke();
  }
  return report;
}

bool FrontSurface::end_stroke(double reach) {
  if (!(reach >= 0) || !std::isfinite(reach))
    throw std::invalid_argument("FrontSurface::end_stroke: reach must be finite and not negative, got " + std::to_string(reach));
  bool carried = false;
  if (reach > 0 && samples_.size() >= 2 && last_report_.ok() && last_report_.front_in_body) {
    const std::vector<Vec3> last = samples_.back(), before = samples_[samples_.size() - 2];
    double mean = 0;
    for (size_t i = 0; i < last.size(); ++i) mean += (last[i] - before[i]).norm();
    mean /= static_cast<double>(last.size());
    if (mean > 0) {
      std::vector<Vec3> on(last.size());
      for (size_t i = 0; i < last.size(); ++i) on[i] = last[i] + (reach / mean) * (last[i] - before[i]);
      const FrontCutReport through = advance(on);
      if (through.samples_held == 0 && through.ok() && !through.front_in_body && samples_.size() >= 2) {
        carried = true;
      } else if (through.samples_held == 0 && samples_.size() >= 2 && samples_.back() == on) {
        // Taken, but the front is still in the body: back to the last sample, cut again from
        // the stroke's base.
        samples_.pop_back();
        sample_t_.pop_back();
        drop_stroke();
        FrontCutReport again;
        recompute(again);
        last_report_ = again;
      }
    }
  }
  FrontCutReport report;
  if (samples_.size() >= 2) recompute(report);
  end_problem_.clear();
  if (report.ok() && samples_.size() >= 2) {
    // The edge table first: a surface that is not closed and consistently oriented would
    // make every later stroke on it fail, so it is not taken (see the header).
    auto fresh = std::make_unique<Base>();
    try {
      fresh->edges = edge_table(triangles_);
    } catch (const std::invalid_argument& error) {
      end_problem_ = std::string("the stroke's surface was not kept: ") + error.what();
      fresh.reset();
    }
    if (fresh) {
      base_vertices_ = vertices_;
      base_triangles_ = triangles_;
      base_planes_ = vertex_planes_.lists();
      base_cut_face_ = cut_face_;
      base_crack_front_ = crack_front_;
      index_base(std::move(fresh));
    }
  }
  drop_stroke();
  last_report_ = FrontCutReport();
  show_base();
  samples_.clear();
  sample_t_.clear();
  blade_s_.clear();
  return carried;
}

void FrontSurface::drop_stroke() {
  if (!stroke_) return;
  // Its per-edge index is kept, reset where set, for the next stroke on the same base: a
  // stroke that touches nothing starts again at every sample until the blade meets the body,
  // and the index is as long as the base's edges.
  for (const int e : stroke_->cut_edges) stroke_->edge_cut[static_cast<size_t>(e)] = -1;
  spare_edge_cut_ = std::move(stroke_->edge_cut);
  stroke_.reset();
}

// recompute's stages (the header's comment describes them), one method each, called in this
// order; what a stage makes for a later one is a member. One lives for one call of recompute.
struct FrontSurface::Recompute {
  // A base triangle the outline crosses.
  struct Tip {
    int triangle;
    double position;  // segment index + fraction along the outline
    Vec3 point;
    Vec2 st;
    bool entering;
    int vertex = -1;
  };
  // A segment of the sheet's outline, between two point ids, and the base triangles it crosses.
  struct BoundarySegment {
    int from, to;
    const std::vector<OutlineHit>* hits;
  };
  // A touched triangle's cut ends: crossings in its edges' order, then tips in the outline's.
  // An end is a crossing (>= 0: index into cuts) or a tip (< 0: -1 - index into tips). Two
  // are handled; the count is kept whole for the report.
  struct Ends {
    int count = 0;
    std::array<int, 4> at{};
    void add(int end) {
      if (count < 4) at[static_cast<size_t>(count)] = end;
      ++count;
    }
  };

  Recompute(FrontSurface& s, FrontCutReport& r);

  // The stages. Those returning bool return false where recompute stops (the surface then
  // the base's when the report has a problem).
  void cross_base_edges();
  void trace_outline();
  bool place_tips();
  void add_cut_vertices();
  void gather_chord_ends();
  bool split_triangles();
  bool trace_inside_outline();
  void match_last_face();
  void bin_boundary();
  void lay_lattice();
  bool triangulate_cut_face();
  void split_shared_inner_edges();
  void lift_inner_points();
  void emit_triangles();
  void attach_planes();

  // What the stages share.
  static Stroke& stroke_of(FrontSurface& s);
  void problem(const std::string& what) { report.problems.push_back(what); }
  Vec2 st_of(int point, int sample) const {
    return Vec2(surface.blade_s_[static_cast<size_t>(point)], surface.sample_t_[static_cast<size_t>(sample)]);
  }
  Vec2 st_of_id(int id) const {
    const int local = id - points.base_count();
    return st_of(local % point_count, local / point_count);
  }
  std::array<Vec3, 2> box_of(std::initializer_list<int> ids) const;
  std::vector<OutlineHit> hits_of(int x, int y) const;
  bool first_sample_inside() const;
  int add_point(const Vec2& st, int minus, int plus);
  int point_of_end(int end);
  int copy_on_side_of(int cut_index, int base_vertex) const;
  void emit(int a, int b, int c);
  void split_at_chord(int t);
  void split_at_tip(int t, const std::array<int, 2>& ends);
  bool split_at_slit(int t, const std::array<int, 2>& ends);
  std::pair<Vec2, Vec3> outline_point(double position) const;
  void add_outline_run(int from_point, double from, double to, int to_point);
  static double distance_to_segment(const Vec2& p, const Vec2& a, const Vec2& b);
  Vec3 sheet_point(const Vec2& st) const;
  Vec3 lift(int p);

  FrontSurface& surface;
  FrontCutReport& report;
  const int point_count, sample_count;
  const int segments, intervals;
  const PointTable points;
  Stroke& stroke;
  std::vector<EdgeCut>& cuts;  // the stroke's; their output vertices are set at every call
  const std::vector<int>& edge_cut;
  const EdgeTable& edges;
  const double w;  // the front's width
  FaceCache& cache;  // the last sample's cut face, then this one's (with reuse_face_)

  // trace_outline: the sheet's outline, and the hits of the front (its other hits are the stroke's).
  std::vector<std::vector<OutlineHit>> front_hits;
  std::vector<BoundarySegment> outline;
  // place_tips: in order along the outline; with none, whether the outline is in the body.
  std::vector<Tip> tips;
  bool outline_inside = false;
  // add_cut_vertices, trace_inside_outline: the output vertices where the two sides meet.
  std::vector<int> front_vertices;
  // gather_chord_ends: base triangles with a cut end, increasing, and their ends.
  std::vector<int> touched;
  std::vector<Ends> ends_of;

  // The cut face's boundary in (s, t): directed edges, the face on their left.
  PlanarRegion region;
  std::vector<int> region_vertex;  // per region point: output vertex for the minus side (-1: lattice, filled in lift_inner_points)
  std::vector<int> region_vertex_plus;
  std::vector<int> cut_point, tip_point;  // per crossing and tip: its region point, or -1
  std::vector<int> slit_points;  // region points of the slits' middle pairs
  std::vector<std::array<int, 3>> split;  // the base triangles' replacements
  std::vector<std::array<int, 3>> split_ranges;  // per replaced base triangle: {slot, first, end} in split
  std::vector<std::uint8_t> split_on_face;  // per replacement: its base triangle was a cut face
  std::uint8_t splitting_face = 0;

  // The lattice (match_last_face, bin_boundary, lay_lattice): its row spacing, its gap to the
  // boundary, the (s, t) rectangle; the cut face as triangulate_face will keep it (next),
  // what changed since the last sample's (change), the first row made again (r_first), the
  // boundary's edges binned and where they cross each row.
  double row = 0, gap = 0;
  Vec2 extent = Vec2::Zero();
  FaceCache next;
  bool incremental = false;
  FaceChange change;
  double t_boundary = 0;
  int old_rows = 0, r_first = 1;
  GridCells frame;
  UniformGrid boundary_cells;
  std::vector<std::vector<std::pair<double, int>>> row_crossings;

  // triangulate_cut_face: the face, triangles of region points.
  std::vector<std::array<int, 3>> face;
  // lift_inner_points: lattice points below fixed_below are lifted once; the region points
  // with a vertex of each side's own, and the face's normal at each region point.
  double fixed_below = 0;
  std::vector<int> inner_points;
  std::vector<Vec3> face_normal;
};

FrontSurface::Recompute::Recompute(FrontSurface& s, FrontCutReport& r)
    : surface(s),
      report(r),
      point_count(static_cast<int>(s.samples_.front().size())),
      sample_count(static_cast<int>(s.samples_.size())),
      segments(point_count - 1),
      intervals(sample_count - 1),
      points{&s.base_vertices_, &s.samples_, point_count},
      stroke(stroke_of(s)),
      cuts(stroke.cuts),
      edge_cut(stroke.edge_cut),
      edges(s.base_->edges),
      w(s.front_width_),
      cache(stroke.face) {}

// The stroke's state, made at its first call (with a dropped stroke's per-edge index).
FrontSurface::Stroke& FrontSurface::Recompute::stroke_of(FrontSurface& s) {
  if (!s.stroke_) {
    s.stroke_ = std::make_unique<Stroke>();
    if (s.spare_edge_cut_.size() == s.base_->edges.ends.size())
      s.stroke_->edge_cut = std::move(s.spare_edge_cut_);  // all -1 (drop_stroke)
    else
      s.stroke_->edge_cut.assign(s.base_->edges.ends.size(), -1);
    s.spare_edge_cut_.clear();
  }
  return *s.stroke_;
}

std::array<Vec3, 2> FrontSurface::Recompute::box_of(std::initializer_list<int> ids) const {
  std::array<Vec3, 2> box{points[*ids.begin()], points[*ids.begin()]};
  for (const int id : ids) {
    box[0] = box[0].cwiseMin(points[id]);
    box[1] = box[1].cwiseMax(points[id]);
  }
  return box;
}

void FrontSurface::recompute(FrontCutReport& report) {
  restore_base();
  if (samples_.size() < 2) return;
  Recompute stages(*this, report);
  stages.cross_base_edges();
  stages.trace_outline();
  if (!stages.place_tips()) return;
  stages.add_cut_vertices();
  stages.gather_chord_ends();
  if (!stages.split_triangles()) return;
  if (!stages.trace_inside_outline()) return;
  stages.match_last_face();
  stages.bin_boundary();
  stages.lay_lattice();
  if (!stages.triangulate_cut_face()) return;
  stages.split_shared_inner_edges();
  stages.lift_inner_points();
  stages.emit_triangles();
  stages.attach_planes();
}

// Crossings: base edges through the sheet, searched once per sample interval, when it is
// added (the sheet behind the front does not change). Per cell (segment i, interval j) two
// triangles, (P00, P10, P11) and (P00, P11, P01), counter-clockwise in (s, t).
void FrontSurface::Recompute::cross_base_edges() {
  const Base& base = *surface.base_;
  for (int j = stroke.intervals_searched; j < intervals; ++j)
    for (int i = 0; i < segments; ++i) {
      const int p00 = points.sheet_id(i, j), p10 = points.sheet_id(i + 1, j), p01 = points.sheet_id(i, j + 1),
                p11 = points.sheet_id(i + 1, j + 1);
      for (const std::array<int, 3>& id : {std::array<int, 3>{p00, p10, p11}, std::array<int, 3>{p00, p11, p01}}) {
        const auto box = box_of({id[0], id[1], id[2]});
        base.edge_bins.near(box[0], box[1], [&](int e) {
          const int a = base.edges.ends[static_cast<size_t>(e)][0], b = base.edges.ends[static_cast<size_t>(e)][1];
          const auto hit = segment_crosses(points, a, b, id[0], id[1], id[2]);
          if (!hit) return;
          if (const int earlier = stroke.edge_cut[static_cast<size_t>(e)]; earlier >= 0) {
            const EdgeCut& first = stroke.cuts[static_cast<size_t>(earlier)];
            const Vec2 st = hit->weights[0] * st_of_id(id[0]) + hit->weights[1] * st_of_id(id[1]) + hit->weights[2] * st_of_id(id[2]);
            const Vec3 point = points[a] + hit->along * (points[b] - points[a]);
            if (first.lower_on_plus == (hit->p_sign < 0) || (st - first.st).norm() > w + 2 * (point - first.point).norm()) {
              // Crossed again the same way, or by a part of the sheet far from the first
              // crossing's (farther on the sheet than in space: the sweep turning back across
              // its own cut), which this stage does not cut.
              stroke.problems.push_back("base edge (" + std::to_string(a) + ", " + std::to_string(b) + ") is crossed twice by one stroke");
              return;
            }
            // Crossed again the other way, by a nearby part of the sheet: the sheet at rest
            // folds back over the edge (where the blade's mapping to rest wavers). Both ends
            // are on one side again and the edge is not cut; what the two crossings cut out of
            // the sheet between them is a sliver as wide as the fold, and the triangles around
            // it keep an even count of cut ends.
            stroke.cuts.erase(stroke.cuts.begin() + earlier);
            stroke.cut_edges.erase(stroke.cut_edges.begin() + earlier);
            stroke.edge_cut[static_cast<size_t>(e)] = -1;
            for (size_t c = static_cast<size_t>(earlier); c < stroke.cut_edges.size(); ++c)
              stroke.edge_cut[static_cast<size_t>(stroke.cut_edges[c])] = static_cast<int>(c);
            ++stroke.folded_edges;
            return;
          }
          EdgeCut cut;
          cut.point = points[a] + hit->along * (points[b] - points[a]);
          cut.st = hit->weights[0] * st_of_id(id[0]) + hit->weights[1] * st_of_id(id[1]) + hit->weights[2] * st_of_id(id[2]);
          cut.lower = a;
          cut.higher = b;
          cut.lower_on_plus = hit->p_sign < 0;
          cut.normal = (points[id[1]] - points[id[0]]).cross(points[id[2]] - points[id[0]]).normalized();
          stroke.edge_cut[static_cast<size_t>(e)] = static_cast<int>(stroke.cuts.size());
          stroke.cuts.push_back(cut);
          stroke.cut_edges.push_back(e);
        });
      }
    }
  stroke.intervals_searched = intervals;
  report.problems = stroke.problems;
  report.folded_edges = stroke.folded_edges;
  report.crossings = static_cast<int>(cuts.size());
}

// The base triangles the segment x -> y (point ids) crosses, in order along it.
std::vector<OutlineHit> FrontSurface::Recompute::hits_of(int x, int y) const {
  std::vector<OutlineHit> here;
  const auto box = box_of({x, y});
  surface.base_->triangle_bins.near(box[0], box[1], [&](int t) {
    const auto& tri = surface.base_triangles_[static_cast<size_t>(t)];
    const auto hit = segment_crosses(points, x, y, tri[0], tri[1], tri[2]);
    // x on the side opposite the outward normal is inside: the outline leaves the body.
    if (hit) here.push_back({t, hit->along, points[x] + hit->along * (points[y] - points[x]), hit->p_sign < 0});
  });
  std::sort(here.begin(), here.end(), [](const OutlineHit& l, const OutlineHit& r) {
    return l.along < r.along || (l.along == r.along && l.triangle < r.triangle);
  });
  return here;
}

// The sheet's outline, counter-clockwise in (s, t): the first sample, the far end's path,
// the last sample (the front) backwards, the near end's path backwards. Its segments other
// than the front's are fixed, their hits kept.
void FrontSurface::Recompute::trace_outline() {
  if (stroke.first_sample.empty())
    for (int i = 0; i < segments; ++i) stroke.first_sample.push_back(hits_of(points.sheet_id(i, 0), points.sheet_id(i + 1, 0)));
  for (int j = static_cast<int>(stroke.far_end.size()); j < intervals; ++j) {
    stroke.far_end.push_back(hits_of(points.sheet_id(segments, j), points.sheet_id(segments, j + 1)));
    stroke.near_end.push_back(hits_of(points.sheet_id(0, j + 1), points.sheet_id(0, j)));
  }
  front_hits.reserve(static_cast<size_t>(segments));  // outline points into it
  for (int i = 0; i < segments; ++i)
    outline.push_back({points.sheet_id(i, 0), points.sheet_id(i + 1, 0), &stroke.first_sample[static_cast<size_t>(i)]});
  for (int j = 0; j < intervals; ++j)
    outline.push_back({points.sheet_id(segments, j), points.sheet_id(segments, j + 1), &stroke.far_end[static_cast<size_t>(j)]});
  for (int i = segments; i > 0; --i) {
    front_hits.push_back(hits_of(points.sheet_id(i, intervals), points.sheet_id(i - 1, intervals)));
    outline.push_back({points.sheet_id(i, intervals), points.sheet_id(i - 1, intervals), &front_hits.back()});
  }
  for (int j = intervals; j > 0; --j)
    outline.push_back({points.sheet_id(0, j), points.sheet_id(0, j - 1), &stroke.near_end[static_cast<size_t>(j - 1)]});
}

// Tips: base triangles the outline crosses, in order along it. Whether the front is in the
// body follows from them; with none, a ray says whether the outline is all inside.
bool FrontSurface::Recompute::place_tips() {
  for (size_t o = 0; o < outline.size(); ++o) {
    const int x = outline[o].from, y = outline[o].to;
    for (const OutlineHit& hit : *outline[o].hits)
      tips.push_back({hit.triangle, static_cast<double>(o) + hit.along, hit.point, st_of_id(x) + hit.along * (st_of_id(y) - st_of_id(x)),
                      hit.entering});
  }
  report.tips = static_cast<int>(tips.size());
  {
    // The outline starts outside (else the stroke began inside, reported below): a point of it
    // is inside after an odd number of tips. The front is [front_first, front_last).
    const double front_first = segments + intervals, front_last = front_first + segments;
    int before = 0;
    for (const Tip& tip : tips) {
      if (tip.position >= front_first && tip.position < front_last) report.front_in_body = true;
      before += tip.position < front_first;
    }
    if (before % 2 == 1) report.front_in_body = true;
  }
  for (size_t k = 0; k < tips.size(); ++k)
    if (tips[k].entering == tips[(k + 1) % tips.size()].entering) {
      problem("the sheet's outline goes " + std::string(tips[k].entering ? "into" : "out of") +
              " the body twice in a row (at base triangles " + std::to_string(tips[k].triangle) + " and " +
              std::to_string(tips[(k + 1) % tips.size()].triangle) + ")");
      break;
    }
  // With no tip the outline is all inside or all outside: a ray from its first point says which.
  if (tips.empty()) {
    const BoxBins& triangle_bins = surface.base_->triangle_bins;
    const Vec3 p = points[outline.front().from];
    const Vec3 far = p + 4 * (triangle_bins.extent() + 1e-9) * Vec3(1, 0.0123, 0.0371).normalized();
    int crossings = 0;
    triangle_bins.near(p.cwiseMin(far), p.cwiseMax(far), [&](int t) {
      const auto& tri = surface.base_triangles_[static_cast<size_t>(t)];
      crossings += ray_crosses(p, far, points[tri[0]], points[tri[1]], points[tri[2]]);
    });
    outline_inside = crossings % 2 == 1;
  }
  if (first_sample_inside()) problem("the stroke began with the blade inside the body");
  if (!report.ok()) {
    surface.restore_base();
    return false;
  }
  return true;
}

// Inside parts of the first sample: the stroke began in the body (see the header).
bool FrontSurface::Recompute::first_sample_inside() const {
  if (tips.empty()) return outline_inside;
  // The outline starts on the first sample, inside if the first tip leaves the body.
  if (!tips.front().entering) return true;
  for (const Tip& tip : tips)
    if (tip.entering && tip.position < segments) return true;
  return false;
}

// The output's vertices: base, then a pair per crossing, then a vertex per tip.
void FrontSurface::Recompute::add_cut_vertices() {
  std::vector<Vec3>& vertices = surface.vertices_;
  for (EdgeCut& cut : cuts) {
    cut.copy_lower = static_cast<int>(vertices.size());
    vertices.push_back(cut.point);
    cut.copy_higher = static_cast<int>(vertices.size());
    vertices.push_back(cut.point);
  }
  for (Tip& tip : tips) {
    tip.vertex = static_cast<int>(vertices.size());
    front_vertices.push_back(tip.vertex);
    vertices.push_back(tip.point);
  }
}

// Chords: the two cut ends of every base triangle the sheet crosses.
void FrontSurface::Recompute::gather_chord_ends() {
  for (size_t c = 0; c < stroke.cut_edges.size(); ++c)
    for (const int t : edges.triangles[static_cast<size_t>(stroke.cut_edges[c])]) touched.push_back(t);
  for (const Tip& tip : tips) touched.push_back(tip.triangle);
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  ends_of.resize(touched.size());
  for (size_t i = 0; i < touched.size(); ++i)
    for (int k = 0; k < 3; ++k)
      if (const int c = edge_cut[static_cast<size_t>(edges.of_triangle[static_cast<size_t>(touched[i])][static_cast<size_t>(k)])]; c >= 0) ends_of[i].add(c);
  for (size_t k = 0; k < tips.size(); ++k)
    ends_of[static_cast<size_t>(std::lower_bound(touched.begin(), touched.end(), tips[k].triangle) - touched.begin())].add(-1 - static_cast<int>(k));
}

int FrontSurface::Recompute::add_point(const Vec2& st, int minus, int plus) {
  region.points.push_back(st);
  region_vertex.push_back(minus);
  region_vertex_plus.push_back(plus);
  return static_cast<int>(region.points.size()) - 1;
}

// The region point of a cut end (see Ends), added at its first use.
int FrontSurface::Recompute::point_of_end(int end) {
  if (end >= 0) {
    if (cut_point[static_cast<size_t>(end)] < 0) {
      const EdgeCut& cut = cuts[static_cast<size_t>(end)];
      const int minus = cut.lower_on_plus ? cut.copy_higher : cut.copy_lower;
      const int plus = cut.lower_on_plus ? cut.copy_lower : cut.copy_higher;
      cut_point[static_cast<size_t>(end)] = add_point(cut.st, minus, plus);
    }
    return cut_point[static_cast<size_t>(end)];
  }
  const size_t k = static_cast<size_t>(-1 - end);
  if (tip_point[k] < 0) tip_point[k] = add_point(tips[k].st, tips[k].vertex, tips[k].vertex);
  return tip_point[k];
}

int FrontSurface::Recompute::copy_on_side_of(int cut_index, int base_vertex) const {
  const EdgeCut& cut = cuts[static_cast<size_t>(cut_index)];
  return base_vertex == cut.lower ? cut.copy_lower : cut.copy_higher;
}

void FrontSurface::Recompute::emit(int a, int b, int c) {
  split.push_back({a, b, c});
  split_on_face.push_back(splitting_face);
}

// Each touched triangle split along its chord (three, four or five ways, by its ends), the
// chord added to the cut face's boundary.
bool FrontSurface::Recompute::split_triangles() {
  cut_point.assign(cuts.size(), -1);
  tip_point.assign(tips.size(), -1);
  for (size_t touched_index = 0; touched_index < touched.size(); ++touched_index) {
    const int t = touched[touched_index];
    const Ends& ends_here = ends_of[touched_index];
    if (ends_here.count != 2) {
      problem("base triangle " + std::to_string(t) + " has " + std::to_string(ends_here.count) +
              " cut ends in one stroke (this stage handles two)");
      continue;
    }
    const std::array<int, 2> ends{ends_here.at[0], ends_here.at[1]};
    const int split_first = static_cast<int>(split.size());
    splitting_face = surface.base_cut_face_[static_cast<size_t>(t)];
    ++report.split_triangles;
    const int crossings = (ends[0] >= 0) + (ends[1] >= 0);
    if (crossings == 2)
      split_at_chord(t);
    else if (crossings == 1)
      split_at_tip(t, ends);
    else if (!split_at_slit(t, ends))
      continue;
    split_ranges.push_back({t, split_first, static_cast<int>(split.size())});
  }
  if (!report.ok()) {
    surface.restore_base();
    return false;
  }
  return true;
}

// Two crossings: three triangles.
void FrontSurface::Recompute::split_at_chord(int t) {
  const std::vector<Vec3>& vertices = surface.vertices_;
  const auto& tri = surface.base_triangles_[static_cast<size_t>(t)];
  // Rotate so that the crossings are on (a, b) and (b, c): b is alone on its side.
  int k0 = -1;
  for (int k = 0; k < 3; ++k)
    if (edge_cut[static_cast<size_t>(edges.of_triangle[t][static_cast<size_t>(k)])] >= 0 &&
        edge_cut[static_cast<size_t>(edges.of_triangle[t][static_cast<size_t>((k + 1) % 3)])] >= 0)
      k0 = k;
  const int a = tri[static_cast<size_t>(k0)], b = tri[static_cast<size_t>((k0 + 1) % 3)], c = tri[static_cast<size_t>((k0 + 2) % 3)];
  const int p = edge_cut[static_cast<size_t>(edges.of_triangle[t][static_cast<size_t>(k0)])];
  const int q = edge_cut[static_cast<size_t>(edges.of_triangle[t][static_cast<size_t>((k0 + 1) % 3)])];
  const int pb = copy_on_side_of(p, b), qb = copy_on_side_of(q, b), pa = copy_on_side_of(p, a), qc = copy_on_side_of(q, c);
  emit(pb, b, qb);
  // The quad (a, p, q, c) is convex (a corner cut off a triangle): its shorter diagonal.
  if ((vertices[static_cast<size_t>(a)] - vertices[static_cast<size_t>(qc)]).norm() <=
      (vertices[static_cast<size_t>(pa)] - vertices[static_cast<size_t>(c)]).norm()) {
    emit(a, pa, qc);
    emit(a, qc, c);
  } else {
    emit(a, pa, c);
    emit(pa, qc, c);
  }
  // b on the normal side of the sheet: the body (inside, left of the chord in (s, t)) is
  // reached from q to p.
  const bool b_plus = cuts[static_cast<size_t>(p)].lower_on_plus == (b == std::min(a, b));
  const int from = point_of_end(b_plus ? q : p), to = point_of_end(b_plus ? p : q);
  region.boundary.push_back({from, to});
}

// A crossing and a tip: four triangles around the tip.
void FrontSurface::Recompute::split_at_tip(int t, const std::array<int, 2>& ends) {
  const auto& tri = surface.base_triangles_[static_cast<size_t>(t)];
  const int cut_index = ends[0] >= 0 ? ends[0] : ends[1];
  const int tip_end = ends[0] >= 0 ? ends[1] : ends[0];
  const Tip& tip = tips[static_cast<size_t>(-1 - tip_end)];
  int k0 = -1;
  for (int k = 0; k < 3; ++k)
    if (edge_cut[static_cast<size_t>(edges.of_triangle[t][static_cast<size_t>(k)])] == cut_index) k0 = k;
  const int a = tri[static_cast<size_t>(k0)], b = tri[static_cast<size_t>((k0 + 1) % 3)], c = tri[static_cast<size_t>((k0 + 2) % 3)];
  emit(a, copy_on_side_of(cut_index, a), tip.vertex);
  emit(copy_on_side_of(cut_index, b), b, tip.vertex);
  emit(b, c, tip.vertex);
  emit(c, a, tip.vertex);
  // Where the outline goes into the body, the face's boundary comes along the chord to the
  // tip and goes on along the outline.
  const int cut_end = point_of_end(cut_index), tip_end_point = point_of_end(tip_end);
  if (tip.entering)
    region.boundary.push_back({cut_end, tip_end_point});
  else
    region.boundary.push_back({tip_end_point, cut_end});
}

// Two tips: a slit between them, with a pair of vertices at its middle (so that its two lips
// are different edges), and seven triangles around it (see the header). False, with a
// problem, when the two tips go the same way.
bool FrontSurface::Recompute::split_at_slit(int t, const std::array<int, 2>& ends) {
  std::vector<Vec3>& vertices = surface.vertices_;
  const auto& tri = surface.base_triangles_[static_cast<size_t>(t)];
  const int i1 = -1 - ends[0], i2 = -1 - ends[1];
  if (tips[static_cast<size_t>(i1)].entering == tips[static_cast<size_t>(i2)].entering) {
    problem("base triangle " + std::to_string(t) + " holds two tips going the same way");
    return false;
  }
  const int enter = tips[static_cast<size_t>(i1)].entering ? i1 : i2, leave = enter == i1 ? i2 : i1;
  const Tip& t1 = tips[static_cast<size_t>(leave)];
  const Tip& t2 = tips[static_cast<size_t>(enter)];
  const Vec3 n = (vertices[static_cast<size_t>(tri[1])] - vertices[static_cast<size_t>(tri[0])])
                     .cross(vertices[static_cast<size_t>(tri[2])] - vertices[static_cast<size_t>(tri[0])]);
  const Vec3 direction = t2.point - t1.point;
  std::array<bool, 3> left{};
  for (int k = 0; k < 3; ++k)
    left[static_cast<size_t>(k)] = n.dot(direction.cross(vertices[static_cast<size_t>(tri[static_cast<size_t>(k)])] - t1.point)) >= 0;
  int lone = 0;
  for (int k = 0; k < 3; ++k)
    if (left[static_cast<size_t>(k)] != left[static_cast<size_t>((k + 1) % 3)] && left[static_cast<size_t>(k)] != left[static_cast<size_t>((k + 2) % 3)])
      lone = k;
  // v0 is alone on its side of the slit's line; (v0, va, vb) keeps the base triangle's
  // counter-clockwise order. That line crosses the edges (v0, va) and (v0, vb), and with v0 on
  // its left (about n) the crossing on (v0, vb) is the one ahead along t1 -> t2 (the triangle
  // v0 and the two crossings make turns the same way as the base triangle): the tip ahead, t2,
  // faces vb, and t1 faces va; with v0 on its right, the other way round. Taking the pairing
  // from the side, rather than from the vertices' own order along t1 -> t2 (which differs on
  // an obtuse triangle), and orienting the pieces by the base triangle's order rather than by
  // their area, every edge is used once each way whatever the rounding: the mesh stays closed
  // and consistently oriented.
  const int v0 = tri[static_cast<size_t>(lone)], va = tri[static_cast<size_t>((lone + 1) % 3)], vb = tri[static_cast<size_t>((lone + 2) % 3)];
  const bool v0_left = left[static_cast<size_t>(lone)];
  const int ta = v0_left ? t1.vertex : t2.vertex, tb = v0_left ? t2.vertex : t1.vertex;
  const int middle_a = static_cast<int>(vertices.size()), middle_b = middle_a + 1;
  vertices.push_back(0.5 * (t1.point + t2.point));
  vertices.push_back(0.5 * (t1.point + t2.point));
  ear_clip({v0, va, ta}, n, vertices, split);
  ear_clip({vb, v0, tb}, n, vertices, split);
  ear_clip({v0, ta, middle_a, tb}, n, vertices, split);  // v0's lip
  ear_clip({ta, va, vb, tb, middle_b}, n, vertices, split);
  split_on_face.resize(split.size(), splitting_face);
  // The face on the sheet's minus side runs leave -> middle -> enter, so the lip of the
  // minus side runs enter -> middle -> leave: v0's lip runs ta -> middle_a -> tb.
  const bool a_is_minus = ta == t2.vertex;
  const int middle_minus = a_is_minus ? middle_a : middle_b, middle_plus = a_is_minus ? middle_b : middle_a;
  const int middle_point = add_point(0.5 * (t1.st + t2.st), middle_minus, middle_plus);
  slit_points.push_back(middle_point);
  region.boundary.push_back({point_of_end(-1 - leave), middle_point});
  region.boundary.push_back({middle_point, point_of_end(-1 - enter)});
  return true;
}

// The outline's point at `position` (segment index + fraction), in (s, t) and at rest.
std::pair<Vec2, Vec3> FrontSurface::Recompute::outline_point(double position) const {
  const int o = std::min(static_cast<int>(position), static_cast<int>(outline.size()) - 1);
  const double f = position - o;
  const int x = outline[static_cast<size_t>(o)].from, y = outline[static_cast<size_t>(o)].to;
  return std::pair<Vec2, Vec3>{st_of_id(x) + f * (st_of_id(y) - st_of_id(x)), points[x] + f * (points[y] - points[x])};
}

// The outline from `from` to `to` (positions) as boundary edges, from region point
// from_point to to_point: corners of the outline between the two positions, then
// subdivisions of each piece, each a transient vertex of its own.
void FrontSurface::Recompute::add_outline_run(int from_point, double from, double to, int to_point) {
  std::vector<Vec3>& vertices = surface.vertices_;
  std::vector<double> stops{from};
  for (double corner = std::floor(from) + 1; corner < to; corner += 1) stops.push_back(corner);
  stops.push_back(to);
  int previous = from_point;
  for (size_t k = 0; k + 1 < stops.size(); ++k) {
    const auto [st0, x0] = outline_point(stops[k]);
    const auto [st1, x1] = outline_point(stops[k + 1]);
    const int pieces = std::max(1, static_cast<int>(std::ceil((st1 - st0).norm() / w)));
    for (int m = 1; m <= pieces; ++m) {
      int next_point;
      if (k + 2 == stops.size() && m == pieces) {
        next_point = to_point;
      } else {
        const double f = static_cast<double>(m) / pieces;
        const Vec3 x = x0 + f * (x1 - x0);
        next_point = add_point(st0 + f * (st1 - st0), static_cast<int>(vertices.size()), static_cast<int>(vertices.size()));
        front_vertices.push_back(static_cast<int>(vertices.size()));
        vertices.push_back(x);
        ++report.front_vertices;
      }
      region.boundary.push_back({previous, next_point});
      previous = next_point;
    }
  }
}

// The outline's inside parts: from each tip where it enters to the next tip, with points at
// most w apart (the transient front). False where there is no cut face (no boundary) or a
// problem.
bool FrontSurface::Recompute::trace_inside_outline() {
  const double perimeter = static_cast<double>(outline.size());
  for (size_t k = 0; k < tips.size(); ++k) {
    if (!tips[k].entering) continue;
    const size_t after = (k + 1) % tips.size();
    double to = tips[after].position;
    if (to <= tips[k].position) to += perimeter;
    // Positions past the perimeter wrap to its start.
    if (to > perimeter) {
      problem("the cut face's outline wraps past the first sample");
      break;
    }
    add_outline_run(point_of_end(-1 - static_cast<int>(k)), tips[k].position, to, point_of_end(-1 - static_cast<int>(after)));
  }
  if (tips.empty() && outline_inside) problem("the blade is inside the body for the whole stroke");
  if (!report.ok()) {
    surface.restore_base();
    return false;
  }
  return !region.boundary.empty();
}

// Fixed vertices: a triangular lattice of spacing w in (s, t), kept away from the boundary.
// First what changed since the last sample's region (FaceCache), for triangulate_face: the
// boundary's points matched by their exact (s, t) and its edges compared. The boundary
// changes only at and above t_boundary; a lattice row lower than that by more than the gap
// (and the jitter, in lay_lattice) sees the same boundary edges near it and across it, so it
// comes out as it was: it is taken from the last sample's instead of being made again.
void FrontSurface::Recompute::match_last_face() {
  row = w * std::sqrt(3.0) / 2;
  gap = 0.45 * w;
  extent = Vec2(surface.blade_s_.back(), surface.sample_t_.back());
  const size_t boundary_points = region.points.size();
  next.lattice_begin = static_cast<int>(boundary_points);
  next.sorted = sorted_points(region.points, boundary_points);
  incremental = surface.reuse_face_ && cache.valid;
  if (incremental) change = boundary_change(cache, region, next.sorted);
  t_boundary = change.t_change;  // infinite when not incremental
}

double FrontSurface::Recompute::distance_to_segment(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 d = b - a;
  const double length_squared = d.squaredNorm();
  const double f = length_squared > 0 ? std::clamp((p - a).dot(d) / length_squared, 0.0, 1.0) : 0.0;
  return (p - (a + f * d)).norm();
}

// Rows taken whole from the last sample's lattice: below t_boundary by the gap and the jitter
// (a thousandth of w) with room. The rows made again are those from r_first on: only they
// look at the boundary's edges (binned here) and at where it crosses them.
void FrontSurface::Recompute::bin_boundary() {
  old_rows = incremental ? static_cast<int>(cache.row_start.size()) - 1 : 0;
  const auto row_taken = [&](int r) { return r < old_rows && r * row + gap + 2e-3 * w < t_boundary; };
  r_first = 1;
  while (row_taken(r_first)) ++r_first;
  // The boundary's edges binned in cells of side w over the (s, t) rectangle (the cells below
  // the lowest one a point of row r_first falls in are never looked at: left empty).
  const int columns = std::max(1, static_cast<int>(std::ceil(extent.x() / w))), rows = std::max(1, static_cast<int>(std::ceil(extent.y() / w)));
  // One layer of cells, (s, t) as (x, y).
  frame.cell = w;
  frame.count = {columns, rows, 1};
  const int lowest_cell_row = static_cast<int>(frame.cell_of(1, r_first * row));
  boundary_cells.build(frame, static_cast<int>(region.boundary.size()), [&](int e, GridCell& from, GridCell& to) {
    const Vec2& a = region.points[static_cast<size_t>(region.boundary[static_cast<size_t>(e)][0])];
    const Vec2& b = region.points[static_cast<size_t>(region.boundary[static_cast<size_t>(e)][1])];
    frame.range(Vec3(std::min(a.x(), b.x()) - gap, std::min(a.y(), b.y()) - gap, 0),
                Vec3(std::max(a.x(), b.x()) + gap, std::max(a.y(), b.y()) + gap, 0), from, to);
    from[1] = std::max<long long>(from[1], lowest_cell_row);
    return true;
  });
  // Per lattice row, where the boundary crosses it (s, and +1 going up in t, -1 going down;
  // each edge taken half-open, from its lower end): a point is inside the region when the
  // crossings on its right wind round it (the region is on the edges' left). The points
  // outside (where the blade's sheet is outside the body) would only be triangulated away.
  row_crossings.resize(static_cast<size_t>(std::floor(extent.y() / row)) + 2);
  for (const auto& edge : region.boundary) {
    const Vec2& a = region.points[static_cast<size_t>(edge[0])];
    const Vec2& b = region.points[static_cast<size_t>(edge[1])];
    if (a.y() == b.y()) continue;
    const Vec2& low = a.y() < b.y() ? a : b;
    const Vec2& high = a.y() < b.y() ? b : a;
    for (int r = std::max(r_first, static_cast<int>(std::ceil(low.y() / row))); r < static_cast<int>(row_crossings.size()) && r * row < high.y(); ++r) {
      if (r * row < low.y()) continue;
      const double f = (r * row - low.y()) / (high.y() - low.y());
      row_crossings[static_cast<size_t>(r)].emplace_back(low.x() + f * (high.x() - low.x()), a.y() < b.y() ? 1 : -1);
    }
  }
}

// The lattice's points, row by row: rows below r_first copied from the last sample's, the
// others made inside the region and away from its boundary, each matched with the last
// sample's point of its row and column (change.to_new; change.t_change lowered where one is
// added or gone).
void FrontSurface::Recompute::lay_lattice() {
  next.row_start.assign(2, 0);  // rows 0 (empty) and, below, 1, 2, ...
  for (int r = 1; r * row < extent.y(); ++r) {
    const int old_first = r < old_rows ? cache.row_start[static_cast<size_t>(r)] : 0;
    const int old_last = r < old_rows ? cache.row_start[static_cast<size_t>(r) + 1] : 0;
    if (r < r_first) {
      for (int k = old_first; k < old_last; ++k) {
        const int old_index = cache.lattice_begin + k;
        change.to_new[static_cast<size_t>(old_index)] = add_point(cache.region.points[static_cast<size_t>(old_index)], -1, -1);
        next.column.push_back(cache.column[static_cast<size_t>(k)]);
        next.lifted.push_back(cache.lifted[static_cast<size_t>(k)]);
        next.lifted_final.push_back(cache.lifted_final[static_cast<size_t>(k)]);
      }
      next.row_start.push_back(static_cast<int>(next.column.size()));
      continue;
    }
    auto& crossings = row_crossings[static_cast<size_t>(r)];
    std::sort(crossings.begin(), crossings.end());
    int winding = 0;  // of the crossings right of the point
    for (const auto& crossing : crossings) winding += crossing.second;
    size_t passed = 0;
    int old_k = old_first;  // the last sample's points of this row, by column
    for (int c = 0; (c + 0.5 * (r % 2)) * w < extent.x(); ++c) {
      const Vec2 p((c + 0.5 * (r % 2)) * w, r * row);
      for (; passed < crossings.size() && crossings[passed].first <= p.x(); ++passed) winding -= crossings[passed].second;
      if (p.x() <= 0 || winding <= 0) continue;
      bool near = false;
      boundary_cells.visit_cells(frame.cell_of(Vec3(p.x(), p.y(), 0)), frame.cell_of(Vec3(p.x(), p.y(), 0)), [&](int e) {
        const auto& edge = region.boundary[static_cast<size_t>(e)];
        near = near || distance_to_segment(p, region.points[static_cast<size_t>(edge[0])], region.points[static_cast<size_t>(edge[1])]) < gap;
      });
      if (near) continue;
      // Moved off the lattice by a thousandth of w, the same way at every sample (a hash of
      // its row and column): six lattice neighbours lie on one circle around each point, and
      // every such empty-circle test would take the triangulation's exact (slow) path.
      const auto jitter = [&](std::uint64_t salt) {
        const std::uint64_t x = mix64((static_cast<std::uint64_t>(r) << 32) ^ static_cast<std::uint64_t>(c) ^ salt);
        return (static_cast<double>(x >> 11) / 9007199254740992.0 - 0.5) * 1e-3 * w;
      };
      const Vec2 jittered = p + Vec2(jitter(1), jitter(2));
      const int index = add_point(jittered, -1, -1);
      next.column.push_back(c);
      next.lifted.emplace_back(Vec3::Zero());
      next.lifted_final.push_back(0);
      if (!incremental) continue;
      // Against the last sample's row: the points it had at lower columns are gone, this one
      // (same row and column, same point) kept or added.
      for (; old_k < old_last && cache.column[static_cast<size_t>(old_k)] < c; ++old_k)
        change.t_change = std::min(change.t_change, cache.region.points[static_cast<size_t>(cache.lattice_begin + old_k)].y());
      if (old_k < old_last && cache.column[static_cast<size_t>(old_k)] == c) {
        change.to_new[static_cast<size_t>(cache.lattice_begin + old_k)] = index;
        next.lifted.back() = cache.lifted[static_cast<size_t>(old_k)];
        next.lifted_final.back() = cache.lifted_final[static_cast<size_t>(old_k)];
        ++old_k;
      } else {
        change.t_change = std::min(change.t_change, jittered.y());
      }
    }
    if (incremental)
      for (; old_k < old_last; ++old_k)
        change.t_change = std::min(change.t_change, cache.region.points[static_cast<size_t>(cache.lattice_begin + old_k)].y());
    next.row_start.push_back(static_cast<int>(next.column.size()));
  }
  // Rows the last sample had above this one's (none while the stroke goes forward): gone.
  if (const int new_rows = static_cast<int>(next.row_start.size()) - 1; incremental && new_rows < old_rows)
    for (int k = cache.row_start[static_cast<size_t>(new_rows)]; k < static_cast<int>(cache.column.size()); ++k)
      change.t_change = std::min(change.t_change, cache.region.points[static_cast<size_t>(cache.lattice_begin + k)].y());
}

// The cut face: the region triangulated (constrained Delaunay), keeping the last sample's
// triangles well behind the front with reuse_face_.
bool FrontSurface::Recompute::triangulate_cut_face() {
  try {
    if (surface.reuse_face_) {
      face = triangulate_face(region, cache, incremental ? &change : nullptr, std::move(next), 1e-6 * w, report.face_triangles_kept);
    } else {
      face = triangulate_region(region);
    }
  } catch (const std::invalid_argument& error) {
    problem(std::string("the cut face could not be triangulated: ") + error.what());
    surface.restore_base();
    return false;
  }
  return true;
}

// Where the blade still is, both sides' faces share the vertices (the crack closes there).
// An inner edge of the face joining two of them would be shared by four triangles: split
// it at its middle, with a vertex of each side's own.
void FrontSurface::Recompute::split_shared_inner_edges() {
  const auto shared = [&](int p) {
    return region_vertex[static_cast<size_t>(p)] >= 0 && region_vertex[static_cast<size_t>(p)] == region_vertex_plus[static_cast<size_t>(p)];
  };
  std::set<std::pair<int, int>> outline_edges;  // the outline's, between two shared vertices
  for (const auto& e : region.boundary)
    if (shared(e[0]) && shared(e[1])) outline_edges.insert({std::min(e[0], e[1]), std::max(e[0], e[1])});
  // Passes over the face's edges (sorted, not a map); a triangle split in a pass waits for
  // the next, so a triangle with two such edges is split twice.
  for (bool again = true; again;) {
    again = false;
    std::vector<std::array<int, 4>> uses;  // (lower, higher, triangle, corner before the edge)
    uses.reserve(3 * face.size());
    for (size_t f = 0; f < face.size(); ++f)
      for (int k = 0; k < 3; ++k) {
        const int u = face[f][static_cast<size_t>(k)], v = face[f][static_cast<size_t>((k + 1) % 3)];
        if (shared(u) && shared(v)) uses.push_back({std::min(u, v), std::max(u, v), static_cast<int>(f), k});
      }
    std::sort(uses.begin(), uses.end());
    std::vector<std::uint8_t> split_now(face.size(), 0);
    for (size_t n = 0; n + 1 < uses.size(); ++n) {
      const auto& x = uses[n];
      const auto& y = uses[n + 1];
      if (x[0] != y[0] || x[1] != y[1] || outline_edges.count({x[0], x[1]})) continue;
      if (split_now[static_cast<size_t>(x[2])] || split_now[static_cast<size_t>(y[2])]) {
        again = true;
        continue;
      }
      const int middle = add_point(0.5 * (region.points[static_cast<size_t>(x[0])] + region.points[static_cast<size_t>(x[1])]), -1, -1);
      for (const auto& use : {x, y}) {
        const size_t f = static_cast<size_t>(use[2]);
        const std::array<int, 3> old = face[f];
        const int k = use[3];
        const int u = old[static_cast<size_t>(k)], v = old[static_cast<size_t>((k + 1) % 3)], opposite = old[static_cast<size_t>((k + 2) % 3)];
        split_now[f] = 1;
        face[f] = {u, middle, opposite};
        face.push_back({middle, v, opposite});
      }
      split_now.resize(face.size(), 1);
      ++n;
    }
  }
}

// A point of the (s, t) rectangle on the sheet: in its cell's triangle.
Vec3 FrontSurface::Recompute::sheet_point(const Vec2& st) const {
  const std::vector<double>& blade_s = surface.blade_s_;
  const std::vector<double>& sample_t = surface.sample_t_;
  const std::vector<std::vector<Vec3>>& samples = surface.samples_;
  const int i = std::clamp(static_cast<int>(std::upper_bound(blade_s.begin(), blade_s.end(), st.x()) - blade_s.begin()) - 1, 0, segments - 1);
  const int j = std::clamp(static_cast<int>(std::upper_bound(sample_t.begin(), sample_t.end(), st.y()) - sample_t.begin()) - 1, 0, intervals - 1);
  const double alpha = (st.x() - blade_s[static_cast<size_t>(i)]) / (blade_s[static_cast<size_t>(i + 1)] - blade_s[static_cast<size_t>(i)]);
  const double beta = (st.y() - sample_t[static_cast<size_t>(j)]) / (sample_t[static_cast<size_t>(j + 1)] - sample_t[static_cast<size_t>(j)]);
  const Vec3& p00 = samples[static_cast<size_t>(j)][static_cast<size_t>(i)];
  const Vec3& p10 = samples[static_cast<size_t>(j)][static_cast<size_t>(i + 1)];
  const Vec3& p01 = samples[static_cast<size_t>(j + 1)][static_cast<size_t>(i)];
  const Vec3& p11 = samples[static_cast<size_t>(j + 1)][static_cast<size_t>(i + 1)];
  if (alpha >= beta) return Vec3(p00 + alpha * (p10 - p00) + beta * (p11 - p10));
  return Vec3(p00 + beta * (p01 - p00) + alpha * (p11 - p01));
}

// Region point p on the sheet. A lattice point in a cell of the sheet between two samples
// before the last is where the last sample put it (FaceCache::lifted: the cell's samples no
// longer change).
Vec3 FrontSurface::Recompute::lift(int p) {
  FaceCache& lattice = stroke.face;  // this sample's, with reuse_face_
  const Vec2& st = region.points[static_cast<size_t>(p)];
  const size_t k = static_cast<size_t>(p - lattice.lattice_begin);
  if (!surface.reuse_face_ || p < lattice.lattice_begin || k >= lattice.column.size()) return sheet_point(st);
  if (lattice.lifted_final[k]) return lattice.lifted[k];
  const Vec3 x = sheet_point(st);
  if (st.y() < fixed_below) {
    lattice.lifted[k] = x;
    lattice.lifted_final[k] = 1;
  }
  return x;
}

// Lift the lattice points the face uses onto the sheet, and take the face's normal at each
// region point.
void FrontSurface::Recompute::lift_inner_points() {
  std::vector<Vec3>& vertices = surface.vertices_;
  fixed_below = intervals >= 2 ? surface.sample_t_[static_cast<size_t>(intervals - 1)] : -std::numeric_limits<double>::infinity();
  for (const auto& triangle : face)
    for (const int p : triangle)
      if (region_vertex[static_cast<size_t>(p)] < 0) {
        // Each side's face has its own inner vertices: the two separate as the cut opens.
        const Vec3 x = lift(p);
        region_vertex[static_cast<size_t>(p)] = static_cast<int>(vertices.size());
        vertices.push_back(x);
        region_vertex_plus[static_cast<size_t>(p)] = static_cast<int>(vertices.size());
        vertices.push_back(x);
        inner_points.push_back(p);
        ++report.lattice_vertices;
      }
  // Their planes: the face's own normal there (the lifted triangles' around the point, as the
  // minus side's face is oriented), so that criterion 3 and the surface agree even where the
  // sheet at rest folds a little between two samples.
  face_normal.assign(region.points.size(), Vec3::Zero());
  for (const auto& triangle : face) {
    const Vec3& a = vertices[static_cast<size_t>(region_vertex[static_cast<size_t>(triangle[0])])];
    const Vec3& b = vertices[static_cast<size_t>(region_vertex[static_cast<size_t>(triangle[1])])];
    const Vec3& c = vertices[static_cast<size_t>(region_vertex[static_cast<size_t>(triangle[2])])];
    const Vec3 n = (b - a).cross(c - a);
    for (const int p : triangle) face_normal[static_cast<size_t>(p)] += n;
  }
  // The slits' middle pairs too: on the face's rim, each on one side (not the crack front).
  // (Their planes are attached in attach_planes, after the cut edges'.)
  inner_points.insert(inner_points.end(), slit_points.begin(), slit_points.end());
}

// The output's triangles: the base's (restore_base); each split's first triangle takes its
// base triangle's slot, the others follow the base's triangles; then the two cut faces.
void FrontSurface::Recompute::emit_triangles() {
  std::vector<std::array<int, 3>>& triangles = surface.triangles_;
  std::vector<std::uint8_t>& cut_face = surface.cut_face_;
  for (const auto& [slot, first, end] : split_ranges) {
    triangles[static_cast<size_t>(slot)] = split[static_cast<size_t>(first)];
    cut_face[static_cast<size_t>(slot)] = split_on_face[static_cast<size_t>(first)];
    surface.replaced_slots_.push_back(slot);
    for (int k = first + 1; k < end; ++k) {
      triangles.push_back(split[static_cast<size_t>(k)]);
      cut_face.push_back(split_on_face[static_cast<size_t>(k)]);
    }
  }
  // The body on the sheet's minus side sees the face with the sheet's normal; the plus side
  // the other way round.
  for (const auto& triangle : face)
    triangles.push_back({region_vertex[static_cast<size_t>(triangle[0])], region_vertex[static_cast<size_t>(triangle[1])],
                         region_vertex[static_cast<size_t>(triangle[2])]});
  for (const auto& triangle : face)
    triangles.push_back({region_vertex_plus[static_cast<size_t>(triangle[0])], region_vertex_plus[static_cast<size_t>(triangle[2])],
                         region_vertex_plus[static_cast<size_t>(triangle[1])]});
  report.cut_face_triangles = static_cast<int>(face.size());
  cut_face.resize(triangles.size(), 1);
}

// Constraint planes (seed 004 §2.6, criterion 3): each end of a cut edge and its copy of the
// pair face across the sheet; so do the cut faces' inner vertices, each on its side.
void FrontSurface::Recompute::attach_planes() {
  const std::vector<Vec3>& vertices = surface.vertices_;
  VertexPlanes& planes = surface.vertex_planes_;
  std::vector<int>& planed_base = surface.planed_base_;
  planes.set_singles(vertices.size() - surface.base_vertices_.size());
  surface.crack_front_.resize(vertices.size(), 0);  // the base's flags, then the stroke's vertices'
  for (const int v : front_vertices) surface.crack_front_[static_cast<size_t>(v)] = 1;
  for (const EdgeCut& cut : cuts) {
    const ConstraintPlane lower{cut.point, cut.lower_on_plus ? Vec3(-cut.normal) : cut.normal};
    const ConstraintPlane higher{cut.point, -lower.normal};
    planes.add(static_cast<size_t>(cut.lower), lower);
    planes.add(static_cast<size_t>(cut.higher), higher);
    planed_base.push_back(cut.lower);
    planed_base.push_back(cut.higher);
    planes.add(static_cast<size_t>(cut.copy_lower), lower);
    planes.add(static_cast<size_t>(cut.copy_higher), higher);
  }
  for (const int p : inner_points) {
    const Vec3& x = vertices[static_cast<size_t>(region_vertex[static_cast<size_t>(p)])];
    const Vec3 normal = face_normal[static_cast<size_t>(p)].normalized();
    planes.add(static_cast<size_t>(region_vertex[static_cast<size_t>(p)]), {x, normal});
    planes.add(static_cast<size_t>(region_vertex_plus[static_cast<size_t>(p)]), {x, -normal});
  }
  std::sort(planed_base.begin(), planed_base.end());
  planed_base.erase(std::unique(planed_base.begin(), planed_base.end()), planed_base.end());
}

}  // namespace incise::physics
