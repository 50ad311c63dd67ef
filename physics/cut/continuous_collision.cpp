#include "physics/cut/continuous_collision.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace incise::physics {

namespace {

// Below this sine of their angle two segments are treated as parallel. Past it the closest
// point of the two lines is computed from cross products, whose rounding is relative to
// |a x b| itself, so a sine of 1e-12 still gives parameters good to about 1e-4 and distances
// good to rounding; at or below it the overlap rule is exact to 1e-12 times the length, far
// under any touching distance in use.
constexpr double parallel_sine = 1e-12;

// The four points count as coplanar throughout the step when the coplanarity cubic (six
// times the volume of their tetrahedron, in coordinates scaled to the problem size) stays
// below this many touching distances: points within a touching distance of one plane give a
// volume of at most (2 * 2) * (4 * touching distance) there, as segments are at most 2 long
// after scaling. Too generous costs only extra candidate times, never a false hit.
constexpr double coplanar_volume_factor = 64;
// Floor of that threshold: rounding of the cubic's coefficients, with a margin, so that a
// caller asking for relative_distance = 0 still gets the coplanar treatment of exactly planar
// input.
constexpr double coplanar_volume_floor = 1e-12;

std::string describe(const Vec3& v) {
  std::ostringstream out;
  out << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return out.str();
}

// The names are assembled only on failure: this runs for every pair, every step.
void require_finite(const Vec3& v, const char* name, const char* part) {
  if (!v.allFinite()) {
    throw std::invalid_argument(std::string("continuous collision: ") + name + part + " is not finite " + describe(v));
  }
}

void require_finite(const MovingSegment& segment, const char* name) {
  require_finite(segment.at_start.first, name, ".at_start.first");
  require_finite(segment.at_start.second, name, ".at_start.second");
  require_finite(segment.at_end.first, name, ".at_end.first");
  require_finite(segment.at_end.second, name, ".at_end.second");
}

void require_finite_point(const Vec3& v, std::size_t index, const char* when) {
  if (!v.allFinite()) {
    throw std::invalid_argument("continuous collision: blade point " + std::to_string(index) + " at the " + when +
                                " of the step is not finite " + describe(v));
  }
}

void require_valid(const ContinuousCollisionTolerances& tolerances) {
  if (!std::isfinite(tolerances.relative_distance) || tolerances.relative_distance < 0) {
    throw std::invalid_argument("continuous collision: tolerances.relative_distance must be finite and >= 0, not " +
                                std::to_string(tolerances.relative_distance));
  }
}

// (1 - t) a + t b is exactly a at t = 0 and exactly b at t = 1, unlike a + t (b - a).
Vec3 lerp(const Vec3& a, const Vec3& b, double t) { return (1 - t) * a + t * b; }

Segment at_time(const MovingSegment& segment, double t) {
  return {lerp(segment.at_start.first, segment.at_end.first, t),
          lerp(segment.at_start.second, segment.at_end.second, t)};
}

double project_onto(const Vec3& point, const Segment& segment, const Vec3& direction, double length_squared) {
  return std::clamp((point - segment.first).dot(direction) / length_squared, 0.0, 1.0);
}

// The eight positions of a pair, centred on their centroid and divided by their size, so that
// every tolerance below is relative and the cubic's coefficients are of order one.
struct ScaledPair {
  MovingSegment blade;
  MovingSegment edge;
  double size = 0;  // largest distance of the eight positions from their centroid
};

ScaledPair scale_pair(const MovingSegment& blade, const MovingSegment& edge) {
  const std::array<const Vec3*, 8> points = {&blade.at_start.first, &blade.at_start.second,
                                             &blade.at_end.first,   &blade.at_end.second,
                                             &edge.at_start.first,  &edge.at_start.second,
                                             &edge.at_end.first,    &edge.at_end.second};
  Vec3 centroid = Vec3::Zero();
  for (const Vec3* p : points) centroid += *p / 8.0;
  double size = 0;
  for (const Vec3* p : points) size = std::max(size, (*p - centroid).norm());
  if (!std::isfinite(size)) {
    throw std::invalid_argument("continuous collision: coordinates too large to subtract (" + describe(centroid) + ")");
  }
  const double scale = size > 0 ? 1 / size : 1;
  auto scaled = [&](const MovingSegment& s) {
    return MovingSegment{{(s.at_start.first - centroid) * scale, (s.at_start.second - centroid) * scale},
                         {(s.at_end.first - centroid) * scale, (s.at_end.second - centroid) * scale}};
  };
  return {scaled(blade), scaled(edge), size};
}

// Candidate times of one pair: a fixed-capacity set, so the test never allocates.
class CandidateTimes {
 public:
  void add(double t) {
    // Outside [0, 1] (or NaN from a vanishing leading coefficient) is not in this step.
    if (!(t >= 0 && t <= 1)) return;
    if (count_ < static_cast<int>(times_.size())) times_[count_++] = t;
  }
  // Real roots of a t^2 + b t + c, with the vertex of the parabola: a root of even
  // multiplicity whose rounded discriminant came out negative is still a candidate.
  void add_quadratic(double a, double b, double c) {
    if (a == 0) {
      if (b != 0) add(-c / b);
      return;
    }
    add(-b / (2 * a));
    const double discriminant = b * b - 4 * a * c;
    if (discriminant < 0) return;
    // The root of larger magnitude from q, the other from c / q: no cancellation.
    const double q = -0.5 * (b + std::copysign(std::sqrt(discriminant), b));
    add(q / a);
    if (q != 0) add(c / q);
  }
  void add_linear(double a, double b) {  // a t + b
    if (a != 0) add(-b / a);
  }
  void sort() { std::sort(times_.begin(), times_.begin() + count_); }
  const double* begin() const { return times_.data(); }
  const double* end() const { return times_.data() + count_; }

 private:
  // 2 step ends + 2 turning points + 3 cubic roots, then in the coplanar case 4 endpoint-line
  // pairs x 3 components x 3 (two roots and a vertex) + 4 pairs x 2 endpoints x 3 components.
  std::array<double, 80> times_{};
  int count_ = 0;
};

struct Cubic {
  std::array<double, 4> c{};  // c[0] + c[1] t + c[2] t^2 + c[3] t^3
  double operator()(double t) const { return ((c[3] * t + c[2]) * t + c[1]) * t + c[0]; }
};

// Six times the signed volume of the tetrahedron of the four endpoints, as a cubic in t:
// (d1 x d2) . r with d1 = p1 - p0, d2 = q1 - q0, r = q0 - p0, each linear in t (Provot 1997).
Cubic coplanarity_cubic(const MovingSegment& blade, const MovingSegment& edge) {
  const Vec3 a = blade.at_start.second - blade.at_start.first;
  const Vec3 da = (blade.at_end.second - blade.at_end.first) - a;
  const Vec3 b = edge.at_start.second - edge.at_start.first;
  const Vec3 db = (edge.at_end.second - edge.at_end.first) - b;
  const Vec3 r = edge.at_start.first - blade.at_start.first;
  const Vec3 dr = (edge.at_end.first - blade.at_end.first) - r;
  const Vec3 ab = a.cross(b);
  const Vec3 dab = da.cross(b) + a.cross(db);
  const Vec3 dadb = da.cross(db);
  Cubic cubic;
  cubic.c[0] = ab.dot(r);
  cubic.c[1] = dab.dot(r) + ab.dot(dr);
  cubic.c[2] = dadb.dot(r) + dab.dot(dr);
  cubic.c[3] = dadb.dot(dr);
  return cubic;
}

// The root of a monotone piece [lo, hi] whose ends have strictly opposite signs, by bisection
// to adjacent doubles: robust whatever the multiplicity, and about 60 cheap evaluations.
double bracketed_root(const Cubic& cubic, double lo, double hi, double f_lo) {
  for (int i = 0; i < 200; ++i) {
    const double middle = 0.5 * (lo + hi);
    if (middle <= lo || middle >= hi) break;
    const double f_middle = cubic(middle);
    if (f_middle == 0) return middle;
    if ((f_middle < 0) == (f_lo < 0)) {
      lo = middle;
      f_lo = f_middle;
    } else {
      hi = middle;
    }
  }
  return std::abs(cubic(lo)) <= std::abs(cubic(hi)) ? lo : hi;
}

// Provot's candidates, and whether the four points stay coplanar throughout the step.
bool add_coplanarity_candidates(const Cubic& cubic, double coplanar_volume, CandidateTimes& candidates) {
  candidates.add(0);
  candidates.add(1);
  // Turning points: they split [0, 1] into monotone pieces (at most one root each), and are
  // candidates themselves for tangent roots, which no sign change brackets.
  CandidateTimes turning;
  turning.add_quadratic(3 * cubic.c[3], 2 * cubic.c[2], cubic.c[1]);
  turning.sort();
  std::array<double, 6> breaks{};
  int break_count = 0;
  breaks[break_count++] = 0;
  for (double t : turning) {
    candidates.add(t);
    if (t > breaks[break_count - 1] && t < 1) breaks[break_count++] = t;
  }
  breaks[break_count++] = 1;
  double largest = 0;
  for (int i = 0; i < break_count; ++i) largest = std::max(largest, std::abs(cubic(breaks[i])));
  for (int i = 0; i + 1 < break_count; ++i) {
    const double f_lo = cubic(breaks[i]);
    const double f_hi = cubic(breaks[i + 1]);
    if ((f_lo < 0 && f_hi > 0) || (f_lo > 0 && f_hi < 0)) {
      candidates.add(bracketed_root(cubic, breaks[i], breaks[i + 1], f_lo));
    }
  }
  return largest <= coplanar_volume;
}

// For four points that stay coplanar, contact starts when an endpoint of one segment reaches
// the other segment: the times `point` crosses the line of `segment` (the components of
// (e1 - e0) x (x - e0), quadratics in t, all vanish then), and, should `point` stay on that
// line, the times it passes either end (components of x - e0 and x - e1, linear in t).
void add_endpoint_candidates(const Vec3& point_start, const Vec3& point_end, const MovingSegment& segment,
                             CandidateTimes& candidates) {
  const Vec3 e = segment.at_start.second - segment.at_start.first;
  const Vec3 de = (segment.at_end.second - segment.at_end.first) - e;
  const Vec3 x = point_start - segment.at_start.first;
  const Vec3 dx = (point_end - segment.at_end.first) - x;
  const Vec3 constant = e.cross(x);
  const Vec3 linear = de.cross(x) + e.cross(dx);
  const Vec3 quadratic = de.cross(dx);
  for (int k = 0; k < 3; ++k) candidates.add_quadratic(quadratic[k], linear[k], constant[k]);
  const Vec3 y = point_start - segment.at_start.second;
  const Vec3 dy = (point_end - segment.at_end.second) - y;
  for (int k = 0; k < 3; ++k) {
    candidates.add_linear(dx[k], x[k]);
    candidates.add_linear(dy[k], y[k]);
  }
}

double snap_to_ends(double parameter, double length, double touching) {
  if (length <= touching) return parameter;  // a point: its parameter is 0.5 by convention
  if (parameter * length <= touching && parameter <= 0.5) return 0;
  if ((1 - parameter) * length <= touching) return 1;
  return parameter;
}

}  // namespace

SegmentProximity closest_points(const Segment& a, const Segment& b, double point_length) {
  const Vec3 da = a.second - a.first;
  const Vec3 db = b.second - b.first;
  const double la2 = da.squaredNorm();
  const double lb2 = db.squaredNorm();
  const double point2 = point_length * point_length;
  const bool a_point = la2 <= point2;
  const bool b_point = lb2 <= point2;

  SegmentProximity result;
  auto finish = [&](double s, double u, bool parallel) {
    result.first_parameter = s;
    result.second_parameter = u;
    result.distance = (lerp(a.first, a.second, s) - lerp(b.first, b.second, u)).norm();
    result.parallel = parallel;
    return result;
  };
  if (a_point && b_point) return finish(0.5, 0.5, false);
  if (a_point) return finish(0.5, project_onto(lerp(a.first, a.second, 0.5), b, db, lb2), false);
  if (b_point) return finish(project_onto(lerp(b.first, b.second, 0.5), a, da, la2), 0.5, false);

  const Vec3 normal = da.cross(db);
  const double n2 = normal.squaredNorm();
  if (n2 <= parallel_sine * parallel_sine * la2 * lb2) {
    // Parallel: the closest pairs, if the projections overlap, fill the overlap at one
    // distance; take its middle (symmetric, and far from both ends when the overlap is long).
    const double s0 = (b.first - a.first).dot(da) / la2;
    const double s1 = (b.second - a.first).dot(da) / la2;
    const double lo = std::max(0.0, std::min(s0, s1));
    const double hi = std::min(1.0, std::max(s0, s1));
    if (lo <= hi) {
      const double s = 0.5 * (lo + hi);
      return finish(s, project_onto(lerp(a.first, a.second, s), b, db, lb2), true);
    }
    // Disjoint along the line: the two nearest ends.
    if (std::max(s0, s1) < 0) return finish(0, s0 >= s1 ? 0 : 1, false);
    return finish(1, s0 <= s1 ? 0 : 1, false);
  }

  // Closest points of the two lines from cross products: (w x db) . n / |n|^2 and
  // (w x da) . n / |n|^2 with w = b0 - a0, which keep their accuracy when the lines are
  // nearly parallel (the normal-equation form a c - b^2 cancels catastrophically there).
  const Vec3 w = b.first - a.first;
  const double s_line = w.cross(db).dot(normal) / n2;
  const double u_line = w.cross(da).dot(normal) / n2;
  if (s_line >= 0 && s_line <= 1 && u_line >= 0 && u_line <= 1) return finish(s_line, u_line, false);

  // Otherwise the minimum of the (convex) squared distance over the unit square lies on its
  // border: one end of one segment against the other segment.
  std::array<std::array<double, 2>, 4> border = {{
      {0.0, project_onto(a.first, b, db, lb2)},
      {1.0, project_onto(a.second, b, db, lb2)},
      {project_onto(b.first, a, da, la2), 0.0},
      {project_onto(b.second, a, da, la2), 1.0},
  }};
  SegmentProximity best = finish(border[0][0], border[0][1], false);
  for (int i = 1; i < 4; ++i) {
    const SegmentProximity candidate = finish(border[i][0], border[i][1], false);
    if (candidate.distance < best.distance) best = candidate;
  }
  return best;
}

double touching_distance(const MovingSegment& blade, const MovingSegment& edge,
                         const ContinuousCollisionTolerances& tolerances) {
  require_valid(tolerances);
  require_finite(blade, "blade");
  require_finite(edge, "edge");
  return tolerances.relative_distance * scale_pair(blade, edge).size;
}

std::optional<EdgeHit> first_edge_hit(const MovingSegment& blade, const MovingSegment& edge,
                                      const ContinuousCollisionTolerances& tolerances) {
  require_valid(tolerances);
  require_finite(blade, "blade");
  require_finite(edge, "edge");
  const ScaledPair pair = scale_pair(blade, edge);
  // In scaled coordinates the touching distance is the relative one (zero-size input: every
  // point coincides, and the distance 0 is still a hit).
  const double touching = pair.size > 0 ? tolerances.relative_distance : 0;

  CandidateTimes candidates;
  const Cubic cubic = coplanarity_cubic(pair.blade, pair.edge);
  const double coplanar_volume = std::max(coplanar_volume_factor * touching, coplanar_volume_floor);
  if (add_coplanarity_candidates(cubic, coplanar_volume, candidates)) {
    add_endpoint_candidates(pair.blade.at_start.first, pair.blade.at_end.first, pair.edge, candidates);
    add_endpoint_candidates(pair.blade.at_start.second, pair.blade.at_end.second, pair.edge, candidates);
    add_endpoint_candidates(pair.edge.at_start.first, pair.edge.at_end.first, pair.blade, candidates);
    add_endpoint_candidates(pair.edge.at_start.second, pair.edge.at_end.second, pair.blade, candidates);
  }
  candidates.sort();

  for (double t : candidates) {
    const Segment blade_now = at_time(pair.blade, t);
    const Segment edge_now = at_time(pair.edge, t);
    const SegmentProximity near = closest_points(blade_now, edge_now, touching);
    if (near.distance > touching) continue;
    EdgeHit hit;
    hit.time = t;
    hit.blade_parameter = snap_to_ends(near.first_parameter, (blade_now.second - blade_now.first).norm(), touching);
    hit.edge_parameter = snap_to_ends(near.second_parameter, (edge_now.second - edge_now.first).norm(), touching);
    hit.distance = near.distance * (pair.size > 0 ? pair.size : 1);
    hit.parallel = near.parallel;
    const Segment blade_world = at_time(blade, t);
    hit.position = lerp(blade_world.first, blade_world.second, hit.blade_parameter);
    return hit;
  }
  return std::nullopt;
}

std::optional<PolylineHit> first_polyline_hit(std::span<const Vec3> blade_at_start,
                                              std::span<const Vec3> blade_at_end, const MovingSegment& edge,
                                              const ContinuousCollisionTolerances& tolerances) {
  if (blade_at_start.size() != blade_at_end.size()) {
    throw std::invalid_argument("continuous collision: the blade has " + std::to_string(blade_at_start.size()) +
                                " points at the start of the step but " + std::to_string(blade_at_end.size()) +
                                " at the end");
  }
  if (blade_at_start.size() < 2) {
    throw std::invalid_argument("continuous collision: a blade polyline needs at least 2 points, not " +
                                std::to_string(blade_at_start.size()));
  }
  for (std::size_t i = 0; i < blade_at_start.size(); ++i) {
    require_finite_point(blade_at_start[i], i, "start");
    require_finite_point(blade_at_end[i], i, "end");
  }
  std::optional<PolylineHit> first;
  for (std::size_t i = 0; i + 1 < blade_at_start.size(); ++i) {
    const MovingSegment segment{{blade_at_start[i], blade_at_start[i + 1]}, {blade_at_end[i], blade_at_end[i + 1]}};
    const std::optional<EdgeHit> hit = first_edge_hit(segment, edge, tolerances);
    if (hit && (!first || hit->time < first->hit.time)) first = PolylineHit{static_cast<int>(i), *hit};
  }
  return first;
}

}  // namespace incise::physics
