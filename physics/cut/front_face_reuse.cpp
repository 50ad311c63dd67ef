#include "physics/cut/front_face_reuse.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <stdexcept>
#include <tuple>

namespace incise::physics::front {

std::vector<std::pair<StKey, int>> sorted_points(const std::vector<Vec2>& points, size_t count) {
  std::vector<std::pair<StKey, int>> sorted(count);
  for (size_t k = 0; k < count; ++k) sorted[k] = {st_key(points[k]), static_cast<int>(k)};
  std::sort(sorted.begin(), sorted.end());
  return sorted;
}

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

namespace {

// triangulate_face's steps on a valid cache (front_face_reuse.hpp): which of the last triangles to keep,
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

}  // namespace

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

}  // namespace incise::physics::front
