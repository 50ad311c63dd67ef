// Recompute's outline: the sheet's boundary, the tips where it crosses the base, and its
// inside parts as the cut face's transient boundary (front_recompute.hpp).
#include "physics/cut/front_recompute.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace incise::physics {

using namespace front;

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

// Inside parts of the first sample: the stroke began in the body (see front_surface.hpp).
bool FrontSurface::Recompute::first_sample_inside() const {
  if (tips.empty()) return outline_inside;
  // The outline starts on the first sample, inside if the first tip leaves the body.
  if (!tips.front().entering) return true;
  for (const Tip& tip : tips)
    if (tip.entering && tip.position < segments) return true;
  return false;
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

}  // namespace incise::physics
