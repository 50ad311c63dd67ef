#include "engine/surface_queries.hpp"

#include "physics/core/contact.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace incise::engine {

namespace {

using Eigen::Vector3d;

constexpr int kLeafSize = 8;

// Signed solid angle of triangle (a, b, c) seen from p (Van Oosterom–Strackee), the term
// engine::winding_number sums: the same arithmetic, so that near clusters add exactly what
// the brute-force sum adds.
double solid_angle(const Vector3d& pa, const Vector3d& pb, const Vector3d& pc, const Vector3d& p) {
  const Vector3d a = pa - p, b = pb - p, c = pc - p;
  const double la = a.norm(), lb = b.norm(), lc = c.norm();
  const double det = a.dot(b.cross(c));
  const double denominator = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
  return 2 * std::atan2(det, denominator);
}

// Whether the segment p + t d, t in [t_lo, t_hi], meets the box (slabs; a zero component of
// d gives infinities that compare correctly).
bool segment_meets_box(const Vector3d& p, const Vector3d& inverse_d, double t_lo, double t_hi, const Vector3d& lo,
                       const Vector3d& hi) {
  for (int i = 0; i < 3; ++i) {
    double t0 = (lo[i] - p[i]) * inverse_d[i], t1 = (hi[i] - p[i]) * inverse_d[i];
    if (std::isnan(t0) || std::isnan(t1)) {  // d[i] = 0 with p on the slab's plane
      if (p[i] < lo[i] || p[i] > hi[i]) return false;
      continue;
    }
    if (t0 > t1) std::swap(t0, t1);
    t_lo = std::max(t_lo, t0);
    t_hi = std::min(t_hi, t1);
    if (t_lo > t_hi) return false;
  }
  return true;
}

double box_distance_squared(const Vector3d& p, const Vector3d& lo, const Vector3d& hi) {
  return (lo - p).cwiseMax(p - hi).cwiseMax(0.0).squaredNorm();
}

}  // namespace

SurfaceQueries::SurfaceQueries(const TriangleSoup& mesh, double accuracy) : accuracy_(accuracy) {
  triangles_.reserve(mesh.triangles.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& v = mesh.vertices;
    const auto& c = mesh.triangles[t];
    triangles_.push_back({Vector3d(v[c[0]][0], v[c[0]][1], v[c[0]][2]), Vector3d(v[c[1]][0], v[c[1]][1], v[c[1]][2]),
                          Vector3d(v[c[2]][0], v[c[2]][1], v[c[2]][2]), static_cast<int>(t)});
  }
  nodes_.reserve(2 * triangles_.size() / kLeafSize + 2);
  if (!triangles_.empty()) build(0, static_cast<int>(triangles_.size()));
}

// Builds the node over triangles [first, first + count) and returns its index.
int SurfaceQueries::build(int first, int count) {
  const int index = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  Node node;
  node.first = first;
  node.count = count;
  node.lo = Vector3d::Constant(std::numeric_limits<double>::infinity());
  node.hi = -node.lo;
  Vector3d centroid_lo = node.lo, centroid_hi = node.hi, weighted = Vector3d::Zero();
  double area = 0;
  for (int t = first; t < first + count; ++t) {
    const Triangle& tri = triangles_[static_cast<std::size_t>(t)];
    for (const Vector3d* v : {&tri.a, &tri.b, &tri.c}) {
      node.lo = node.lo.cwiseMin(*v);
      node.hi = node.hi.cwiseMax(*v);
    }
    const Vector3d centroid = (tri.a + tri.b + tri.c) / 3;
    centroid_lo = centroid_lo.cwiseMin(centroid);
    centroid_hi = centroid_hi.cwiseMax(centroid);
    const double a = 0.5 * (tri.b - tri.a).cross(tri.c - tri.a).norm();
    weighted += a * centroid;
    area += a;
  }
  node.centre = area > 0 ? Vector3d(weighted / area) : Vector3d(0.5 * (node.lo + node.hi));
  // The expansion about the centre (Barill et al. 2018, eq. 11 to order 2): the integrals of
  // n and of (x - centre) n^T over each triangle, the second exact with its centroid since
  // it is linear in x. The vector area 0.5 (b - a) x (c - a) is area times unit normal.
  node.dipole.setZero();
  node.moment.setZero();
  for (int t = first; t < first + count; ++t) {
    const Triangle& tri = triangles_[static_cast<std::size_t>(t)];
    const Vector3d vector_area = 0.5 * (tri.b - tri.a).cross(tri.c - tri.a);
    node.dipole += vector_area;
    node.moment += ((tri.a + tri.b + tri.c) / 3 - node.centre) * vector_area.transpose();
    for (const Vector3d* v : {&tri.a, &tri.b, &tri.c}) node.radius = std::max(node.radius, (*v - node.centre).norm());
  }
  if (count > kLeafSize) {
    int axis = 0;
    (centroid_hi - centroid_lo).maxCoeff(&axis);
    const int half = count / 2;
    const auto begin = triangles_.begin() + first;
    // Ties broken by the mesh's triangle index, so that the hierarchy does not depend on the
    // standard library's nth_element.
    std::nth_element(begin, begin + half, begin + count, [axis](const Triangle& x, const Triangle& y) {
      const double cx = x.a[axis] + x.b[axis] + x.c[axis], cy = y.a[axis] + y.b[axis] + y.c[axis];
      return cx < cy || (cx == cy && x.index < y.index);
    });
    node.left = build(first, half);
    node.right = build(first + half, count - half);
  }
  nodes_[static_cast<std::size_t>(index)] = node;
  return index;
}

// The cluster's winding number seen from p through its expansion: grad G(r) . dipole +
// tr(hess G(r) moment), with G the Laplace Green's function, r = centre - p.
double SurfaceQueries::far_field(const Node& node, const Vector3d& p) const {
  const Vector3d r = node.centre - p;
  const double r2 = r.squaredNorm(), inv = 1 / std::sqrt(r2), inv3 = inv * inv * inv, inv5 = inv3 * inv * inv;
  const double order1 = r.dot(node.dipole) * inv3;
  const double order2 = node.moment.trace() * inv3 - 3 * r.dot(node.moment * r) * inv5;
  return (order1 + order2) / (4 * std::numbers::pi);
}

double SurfaceQueries::winding_number(const Vector3d& p) const {
  if (nodes_.empty()) return 0;
  double solid = 0, far = 0;
  int stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[static_cast<std::size_t>(stack[--top])];
    if ((p - node.centre).squaredNorm() > accuracy_ * accuracy_ * node.radius * node.radius) {
      far += far_field(node, p);
    } else if (node.left < 0) {
      for (int t = node.first; t < node.first + node.count; ++t) {
        const Triangle& tri = triangles_[static_cast<std::size_t>(t)];
        solid += solid_angle(tri.a, tri.b, tri.c, p);
      }
    } else {
      stack[top++] = node.right;
      stack[top++] = node.left;
    }
  }
  return solid / (4 * std::numbers::pi) + far;
}

bool SurfaceQueries::crossings(const Vector3d& p, const Vector3d& d, double t_lo, double t_hi,
                               std::vector<Crossing>& out) const {
  out.clear();
  if (nodes_.empty()) return true;
  const Vector3d inverse_d = d.cwiseInverse();
  // Margins, relative: a hit closer than this to an edge (in barycentric terms) or a segment
  // this close to parallel is degenerate; a hit this close to an end of the segment too,
  // since the caller's classification at that end is then in doubt.
  constexpr double kEdge = 1e-9, kParallel = 1e-12;
  int stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[static_cast<std::size_t>(stack[--top])];
    // Slightly enlarged, so that a hit on the box's face is not lost to rounding.
    const Vector3d margin = Vector3d::Constant(1e-12 * (node.hi - node.lo).maxCoeff());
    if (!segment_meets_box(p, inverse_d, t_lo, t_hi, node.lo - margin, node.hi + margin)) continue;
    if (node.left >= 0) {
      stack[top++] = node.right;
      stack[top++] = node.left;
      continue;
    }
    for (int k = node.first; k < node.first + node.count; ++k) {
      const Triangle& tri = triangles_[static_cast<std::size_t>(k)];
      // Moller-Trumbore, with the determinant's sign kept for the direction of the crossing.
      const Vector3d e1 = tri.b - tri.a, e2 = tri.c - tri.a, q = d.cross(e2);
      const double det = e1.dot(q);
      const double scale = e1.norm() * e2.norm() * d.norm();
      if (std::abs(det) <= kParallel * scale) {
        // In the plane's direction: degenerate only if the segment lies in the plane.
        const Vector3d normal = e1.cross(e2);
        if (std::abs(normal.dot(p + t_lo * d - tri.a)) <= kParallel * scale * (t_hi - t_lo + 1) &&
            std::abs(normal.dot(p + t_hi * d - tri.a)) <= kParallel * scale * (t_hi - t_lo + 1))
          return false;
        continue;
      }
      const double inverse = 1 / det;
      const Vector3d s = p - tri.a;
      const double u = s.dot(q) * inverse;
      const Vector3d r = s.cross(e1);
      const double v = d.dot(r) * inverse, w = 1 - u - v;
      const double t = e2.dot(r) * inverse;
      if (u < -kEdge || v < -kEdge || w < -kEdge) continue;
      const double length = t_hi - t_lo;
      if (t < t_lo - kEdge * length || t > t_hi + kEdge * length) continue;
      if (u <= kEdge || v <= kEdge || w <= kEdge) return false;
      if (t <= t_lo + kEdge * length || t >= t_hi - kEdge * length) return false;
      // det > 0: d runs against the outward normal (e1 x e2 . d < 0), into the body.
      out.push_back({t, det > 0 ? 1 : -1, tri.index});
    }
  }
  std::sort(out.begin(), out.end(), [](const Crossing& x, const Crossing& y) {
    return x.t < y.t || (x.t == y.t && x.triangle < y.triangle);
  });
  return true;
}

SurfaceQueries::Nearest SurfaceQueries::nearest(const Vector3d& p) const {
  Nearest best;
  double best2 = std::numeric_limits<double>::infinity();
  if (nodes_.empty()) return best;
  int stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[static_cast<std::size_t>(stack[--top])];
    if (box_distance_squared(p, node.lo, node.hi) >= best2) continue;
    if (node.left < 0) {
      for (int t = node.first; t < node.first + node.count; ++t) {
        const Triangle& tri = triangles_[static_cast<std::size_t>(t)];
        const Vector3d q = physics::closest_point_on_triangle(p, tri.a, tri.b, tri.c);
        const double d2 = (q - p).squaredNorm();
        if (d2 < best2) {
          best2 = d2;
          best.point = q;
          best.triangle = tri.index;
        }
      }
      continue;
    }
    // The nearer child first, so that the farther one is more often pruned.
    const Node& left = nodes_[static_cast<std::size_t>(node.left)];
    const Node& right = nodes_[static_cast<std::size_t>(node.right)];
    const bool left_first = box_distance_squared(p, left.lo, left.hi) <= box_distance_squared(p, right.lo, right.hi);
    stack[top++] = left_first ? node.right : node.left;
    stack[top++] = left_first ? node.left : node.right;
  }
  best.distance = std::sqrt(best2);
  return best;
}

}  // namespace incise::engine
