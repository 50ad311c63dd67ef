#include "physics/fem/surface_snap.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <numbers>
#include <optional>

namespace incise::physics {

namespace {

double signed_volume(const Vector& x, const std::array<int, 4>& t) {
  Vec3 a = x.segment<3>(3 * t[0]);
  Vec3 b = x.segment<3>(3 * t[1]);
  Vec3 c = x.segment<3>(3 * t[2]);
  Vec3 d = x.segment<3>(3 * t[3]);
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

// Parameter s in [lo, hi] where inside(p + s n) changes, given it differs at the two ends.
double bisect(const std::function<bool(const Vec3&)>& inside, const Vec3& p, const Vec3& n, double lo,
              double hi, bool inside_at_lo, int bisections) {
  for (int k = 0; k < bisections; ++k) {
    double mid = 0.5 * (lo + hi);
    if (inside(p + mid * n) == inside_at_lo)
      lo = mid;
    else
      hi = mid;
  }
  return 0.5 * (lo + hi);
}

// Where the line p + s n crosses the boundary of `inside` within |s| <= reach: a coarse march
// (so that a thin feature is not jumped over), then bisection. With `along`, the points of the
// line are classified from its section, the same march and bisection.
std::optional<double> crossing(const std::function<bool(const Vec3&)>& inside, const Vec3& p, const Vec3& n,
                               double reach, int steps, int bisections, const LineQuery& along = {}) {
  const std::optional<LineSection> section = along ? along(p, n, reach) : std::nullopt;
  const auto inside_at = [&](double s) { return section ? section->inside_at(s) : inside(p + s * n); };
  const bool p_inside = inside_at(0);
  const double sign = p_inside ? 1.0 : -1.0;  // inside: the boundary is further out
  double previous = 0;
  for (int k = 1; k <= steps; ++k) {
    const double s = sign * reach * k / steps;
    if (inside_at(s) != p_inside) {
      double lo = previous, hi = s;
      for (int b = 0; b < bisections; ++b) {
        const double mid = 0.5 * (lo + hi);
        (inside_at(mid) == p_inside ? lo : hi) = mid;
      }
      return 0.5 * (lo + hi);
    }
    previous = s;
  }
  return std::nullopt;
}

}  // namespace

bool LineSection::inside_at(double s) const {
  // The winding number at s: the one at 0 and the changes passed on the way (backwards,
  // undone).
  int w = winding;
  for (const auto& [t, change] : crossings) {
    if (s > 0 && t > 0 && t < s) w += change;
    if (s < 0 && t < 0 && t > s) w -= change;
  }
  return w > 0;
}

SnapReport snap_boundary_to_surface(TetMesh& mesh, const std::function<bool(const Vec3&)>& inside,
                                    double reach, double min_volume_ratio, int bisections) {
  SnapReport report;
  const int n = static_cast<int>(mesh.rest.size() / 3);
  const auto boundary = boundary_triangles(mesh.tets);
  std::vector<Vec3> normal(n, Vec3::Zero());
  std::vector<uint8_t> on_boundary(n, 0);
  for (const auto& f : boundary) {
    Vec3 a = mesh.rest.segment<3>(3 * f[0]);
    Vec3 area = (mesh.rest.segment<3>(3 * f[1]) - a).cross(mesh.rest.segment<3>(3 * f[2]) - a);
    for (int v : f) {
      normal[v] += area;
      on_boundary[v] = 1;
    }
  }
  std::vector<std::vector<int>> tets_of(n);
  for (std::size_t t = 0; t < mesh.tets.size(); ++t)
    for (int v : mesh.tets[t]) tets_of[v].push_back(static_cast<int>(t));

  // Quality is judged against the voxel elements, so that successive moves of the corners of
  // one element cannot flatten it step by step.
  std::vector<double> original_volume(mesh.tets.size());
  for (std::size_t t = 0; t < mesh.tets.size(); ++t) original_volume[t] = signed_volume(mesh.rest, mesh.tets[t]);

  // Two passes: a node held back because a neighbour had not moved yet gets a second try
  // once its neighbours sit on the surface.
  enum Status : uint8_t { interior, left, partly, moved };
  std::vector<uint8_t> status(n, interior);
  for (int v = 0; v < n; ++v)
    if (on_boundary[v]) status[v] = left;
  const int steps = 12;  // coarse march before bisection, so a thin feature is not jumped over
  for (int pass = 0; pass < 2; ++pass) {
    for (int v = 0; v < n; ++v) {
      if (status[v] == interior || status[v] == moved) continue;
      double length = normal[v].norm();
      if (!(length > 0)) continue;
      Vec3 direction = normal[v] / length;
      Vec3 p = mesh.rest.segment<3>(3 * v);
      bool p_inside = inside(p);
      // Inside: the surface is further out; outside: it is back in along -normal.
      double sign = p_inside ? 1.0 : -1.0;
      double found = std::nan("");
      double previous = 0;
      for (int k = 1; k <= steps; ++k) {
        double s = sign * reach * k / steps;
        if (inside(p + s * direction) != p_inside) {
          found = bisect(inside, p, direction, previous, s, p_inside, bisections);
          break;
        }
        previous = s;
      }
      if (std::isnan(found)) continue;
      for (double fraction : {1.0, 0.5, 0.25}) {
        mesh.rest.segment<3>(3 * v) = p + fraction * found * direction;
        double worst = 1;
        for (int t : tets_of[v])
          worst = std::min(worst, signed_volume(mesh.rest, mesh.tets[t]) / original_volume[t]);
        if (worst >= min_volume_ratio) {
          status[v] = fraction == 1.0 ? moved : partly;
          break;
        }
        mesh.rest.segment<3>(3 * v) = p;
      }
    }
  }
  for (int v = 0; v < n; ++v) {
    report.moved += status[v] == moved;
    report.moved_partly += status[v] == partly;
    report.left += status[v] == left;
    report.boundary_nodes += status[v] != interior;
  }
  for (std::size_t t = 0; t < mesh.tets.size(); ++t)
    report.min_volume_ratio =
        std::min(report.min_volume_ratio, signed_volume(mesh.rest, mesh.tets[t]) / original_volume[t]);
  return report;
}


namespace {

// fair_surface_onto_shape's state: the surface, its adjacency in compressed rows (per vertex
// its triangles and its one-ring's vertices), and per vertex whether its boundary crossing was
// found, whether it sits on the shape, and whether it is on a crease.
class SurfaceFairing {
 public:
  SurfaceFairing(std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles,
                 const std::function<bool(const Vec3&)>& inside, double cell, const LineQuery& along)
      : vertices_(vertices), triangles_(triangles), inside_(inside), along_(along), cell_(cell),
        n_(static_cast<int>(vertices.size())), crease_(static_cast<std::size_t>(n_), 0),
        found_(static_cast<std::size_t>(n_), 0), on_shape_(static_cast<std::size_t>(n_), 0) {
    build_adjacency();
  }

  // Onto the boundary, every vertex along its normal.
  void project(FairReport& report) {
    report.vertices = 0;
    for (int v = 0; v < n_; ++v) {
      if (tri_start_[at(v)] == tri_start_[at(v) + 1]) continue;  // on no triangle
      ++report.vertices;
      const Vec3 normal = normal_at(v);
      const Vec3 p = vertices_[at(v)];
      const auto s = normal.isZero() ? std::nullopt : crossing(inside_, p, normal, 1.5 * cell_, kSteps, kBisections, along_);
      if (!s) {
        ++report.not_found;
        continue;
      }
      found_[at(v)] = 1;
      if (move_to(v, p + *s * normal)) {
        ++report.projected;
        on_shape_[at(v)] = 1;
      }
    }
    // A vertex that could not go straight onto the boundary (the tip of a bump where the voxel
    // build filled a pinch: going in along its normal would turn its triangles over) goes to
    // its one-ring's centroid first, then onto the boundary.
    for (int v = 0; v < n_; ++v)
      if (found_[at(v)] && !on_shape_[at(v)] && onto_shape_from_centroid(v)) {
        on_shape_[at(v)] = 1;
        ++report.projected;
      }
  }

  // Creases: the boundary half a cell away leaves the tangent plane by more than cell / 8.
  void mark_creases(FairReport& report) {
    const double r = 0.5 * cell_;
    for (int v = 0; v < n_; ++v) {
      if (!found_[at(v)]) continue;
      const Vec3 normal = normal_at(v);
      if (normal.isZero()) {
        crease_[at(v)] = 1;
        continue;
      }
      const Vec3 t1 = normal.unitOrthogonal(), t2 = normal.cross(t1);
      const Vec3& p = vertices_[at(v)];
      for (int k = 0; k < 8 && !crease_[at(v)]; ++k) {
        const double angle = k * std::numbers::pi / 4;
        const Vec3 q = p + r * (std::cos(angle) * t1 + std::sin(angle) * t2);
        const auto s = crossing(inside_, q, normal, r, 8, 24, along_);
        if (!s || std::abs(*s) > 0.25 * r) crease_[at(v)] = 1;
      }
      report.creases += crease_[at(v)];
    }
  }

  // One pass: each vertex off a crease slides half way to its one-ring's centroid in its
  // tangent plane, then back onto the boundary; one still off the shape tries again.
  void slide(FairReport& report) {
    for (int v = 0; v < n_; ++v) {
      if (!found_[at(v)]) continue;
      if (!on_shape_[at(v)]) {
        if (onto_shape_from_centroid(v)) {
          on_shape_[at(v)] = 1;
          ++report.projected;
        }
        continue;
      }
      if (crease_[at(v)]) continue;
      const int first = ring_start_[at(v)], last = ring_start_[at(v) + 1];
      if (last == first) continue;
      Vec3 centroid = Vec3::Zero();
      for (int k = first; k < last; ++k) centroid += vertices_[at(ring_[at(k)])];
      centroid /= last - first;
      const Vec3 normal = normal_at(v);
      if (normal.isZero()) continue;
      const Vec3& p = vertices_[at(v)];
      Vec3 step = 0.5 * (centroid - p);
      step -= normal.dot(step) * normal;
      const Vec3 q = p + step;
      const auto s = crossing(inside_, q, normal, cell_, kSteps, kBisections, along_);
      if (s && move_to(v, q + *s * normal))
        ++report.slid;
      else
        ++report.refused;
    }
  }

  int off_shape() const {
    int count = 0;
    for (int v = 0; v < n_; ++v) count += found_[at(v)] && !on_shape_[at(v)];
    return count;
  }

 private:
  static constexpr int kSteps = 12, kBisections = 40;
  static std::size_t at(int i) { return static_cast<std::size_t>(i); }

  void build_adjacency() {
    tri_start_.assign(at(n_) + 1, 0);
    for (const auto& t : triangles_)
      for (const int v : t) ++tri_start_[at(v) + 1];
    for (int v = 0; v < n_; ++v) tri_start_[at(v) + 1] += tri_start_[at(v)];
    tris_.resize(at(tri_start_.back()));
    std::vector<int> fill(tri_start_.begin(), tri_start_.end() - 1);
    for (std::size_t t = 0; t < triangles_.size(); ++t)
      for (const int v : triangles_[t]) tris_[at(fill[at(v)]++)] = static_cast<int>(t);
    ring_start_.assign(at(n_) + 1, 0);
    for (int v = 0; v < n_; ++v) {
      std::vector<int> around;
      for (const int t : triangles_of(v))
        for (const int u : triangles_[at(t)])
          if (u != v) around.push_back(u);
      std::sort(around.begin(), around.end());
      around.erase(std::unique(around.begin(), around.end()), around.end());
      ring_.insert(ring_.end(), around.begin(), around.end());
      ring_start_[at(v) + 1] = static_cast<int>(ring_.size());
    }
  }

  std::span<const int> triangles_of(int v) const {
    return std::span<const int>(tris_.data() + tri_start_[at(v)], tris_.data() + tri_start_[at(v) + 1]);
  }

  Vec3 area_normal(int t) const {
    const auto& c = triangles_[at(t)];
    const Vec3& a = vertices_[at(c[0])];
    return Vec3((vertices_[at(c[1])] - a).cross(vertices_[at(c[2])] - a));
  }

  // The angle-weighted normal at v (zero when its triangles are degenerate).
  Vec3 normal_at(int v) const {
    Vec3 sum = Vec3::Zero();
    for (const int t : triangles_of(v)) {
      const auto& c = triangles_[at(t)];
      const int corner = c[0] == v ? 0 : c[1] == v ? 1 : 2;
      const Vec3& p = vertices_[at(v)];
      const Vec3 e1 = vertices_[at(c[at((corner + 1) % 3)])] - p;
      const Vec3 e2 = vertices_[at(c[at((corner + 2) % 3)])] - p;
      const Vec3 face = e1.cross(e2);
      const double length = face.norm();
      if (!(length > 0)) continue;
      sum += std::atan2(length, e1.dot(e2)) * face / length;
    }
    const double length = sum.norm();
    return length > 0 ? Vec3(sum / length) : Vec3::Zero();
  }

  // Moves v to `to` unless that turns one of its triangles over or collapses one; says
  // whether it did. Over is judged against the vector area of v's one-ring, which does not
  // depend on where v is: a star folded already (the snap can leave one) may unfold.
  bool move_to(int v, const Vec3& to) {
    Vec3 ring_area = Vec3::Zero();
    for (const int t : triangles_of(v)) ring_area += area_normal(t);
    const auto over = [&] {
      int count = 0;
      for (const int t : triangles_of(v)) count += !(area_normal(t).dot(ring_area) > 0);
      return count;
    };
    const int over_before = over();
    const Vec3 from = vertices_[at(v)];
    vertices_[at(v)] = to;
    bool collapsed = false;
    for (const int t : triangles_of(v)) collapsed = collapsed || !(area_normal(t).squaredNorm() > 1e-12 * ring_area.squaredNorm());
    if (collapsed || over() > over_before) {
      vertices_[at(v)] = from;
      return false;
    }
    return true;
  }

  Vec3 centroid_of(int v) const {
    const int first = ring_start_[at(v)], last = ring_start_[at(v) + 1];
    Vec3 centroid = Vec3::Zero();
    for (int k = first; k < last; ++k) centroid += vertices_[at(ring_[at(k)])];
    return last > first ? Vec3(centroid / (last - first)) : vertices_[at(v)];
  }

  bool onto_shape_from_centroid(int v) {
    const Vec3 from = vertices_[at(v)];
    vertices_[at(v)] = centroid_of(v);
    const Vec3 normal = normal_at(v);
    const Vec3 q = vertices_[at(v)];
    vertices_[at(v)] = from;
    const auto s = normal.isZero() ? std::nullopt : crossing(inside_, q, normal, 1.5 * cell_, kSteps, kBisections, along_);
    return s && move_to(v, q + *s * normal);
  }

  std::vector<Vec3>& vertices_;
  const std::vector<std::array<int, 3>>& triangles_;
  const std::function<bool(const Vec3&)>& inside_;
  const LineQuery& along_;
  double cell_;
  int n_;
  std::vector<int> tri_start_, tris_, ring_start_, ring_;
  std::vector<std::uint8_t> crease_, found_, on_shape_;
};

}  // namespace

FairReport fair_surface_onto_shape(std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles,
                                   const std::function<bool(const Vec3&)>& inside, double cell, int passes,
                                   const LineQuery& along) {
  const int n = static_cast<int>(vertices.size());
  if (!(cell > 0) || !std::isfinite(cell))
    throw std::invalid_argument("fair_surface_onto_shape: cell " + std::to_string(cell) + " is not a positive number");
  if (passes < 0) throw std::invalid_argument("fair_surface_onto_shape: passes " + std::to_string(passes) + " is negative");
  for (std::size_t t = 0; t < triangles.size(); ++t)
    for (const int v : triangles[t]) {
      if (v < 0 || v >= n)
        throw std::invalid_argument("fair_surface_onto_shape: triangle " + std::to_string(t) + " has vertex " +
                                    std::to_string(v) + ", out of range [0, " + std::to_string(n) + ")");
      if (!vertices[static_cast<std::size_t>(v)].allFinite())
        throw std::invalid_argument("fair_surface_onto_shape: vertex " + std::to_string(v) + " is not finite");
    }
  FairReport report;
  SurfaceFairing fairing(vertices, triangles, inside, cell, along);
  fairing.project(report);
  fairing.mark_creases(report);
  for (int pass = 0; pass < passes; ++pass) fairing.slide(report);
  report.off_shape = fairing.off_shape();
  return report;
}

}  // namespace incise::physics
