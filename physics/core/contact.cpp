#include "physics/core/contact.hpp"

#include "physics/core/nearest_triangles.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace incise::physics {

Vec3 closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + (d1 / (d1 - d3)) * ab;
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + (d2 / (d2 - d6)) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  const double denominator = 1.0 / (va + vb + vc);
  return a + ab * (vb * denominator) + ac * (vc * denominator);
}

namespace {

Vec3 closest_point_on_segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double length2 = ab.squaredNorm();
  if (length2 <= 0) return a;
  return a + std::clamp((p - a).dot(ab) / length2, 0.0, 1.0) * ab;
}

// Barycentric weights of q (a point of the triangle).
Vec3 barycentric(const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 v0 = b - a, v1 = c - a, v2 = q - a;
  const double d00 = v0.dot(v0), d01 = v0.dot(v1), d11 = v1.dot(v1), d20 = v2.dot(v0), d21 = v2.dot(v1);
  const double denominator = d00 * d11 - d01 * d01;
  if (!(std::abs(denominator) > 0)) return Vec3::Constant(1.0 / 3.0);
  const double v = (d11 * d20 - d01 * d21) / denominator;
  const double w = (d00 * d21 - d01 * d20) / denominator;
  return {std::clamp(1.0 - v - w, 0.0, 1.0), std::clamp(v, 0.0, 1.0), std::clamp(w, 0.0, 1.0)};
}

// A penalty force on the tissue at a point of triangle t (its barycentric weights) shared by
// the triangle's free nodes, with its stiffness along the normal.
void spread_to_nodes(std::map<int, NodalSpring>& by_node, const std::array<int, 3>& t, const Vec3& weights,
                     const Vec3& force, const Vec3& normal, double stiffness, const std::vector<std::uint8_t>& fixed) {
  for (int k = 0; k < 3; ++k) {
    const int node = t[k];
    if (weights[k] <= 0 || (!fixed.empty() && fixed[node])) continue;
    NodalSpring& spring = by_node[node];
    spring.node = node;
    spring.force += weights[k] * force;
    spring.stiffness += weights[k] * stiffness * normal * normal.transpose();
  }
}

}  // namespace

ProbeContact probe_contact(const Vector& x, const std::vector<std::array<int, 3>>& surface,
                           const std::vector<std::uint8_t>& fixed, const Vec3& tip, const Vec3& tail,
                           double radius, double stiffness) {
  ProbeContact contact;
  const Vec3 box_min = tip.cwiseMin(tail) - Vec3::Constant(radius);
  const Vec3 box_max = tip.cwiseMax(tail) + Vec3::Constant(radius);
  std::map<int, NodalSpring> by_node;  // ordered: the springs come out in node order
  for (const auto& t : surface) {
    const Vec3 a = x.segment<3>(3 * t[0]), b = x.segment<3>(3 * t[1]), c = x.segment<3>(3 * t[2]);
    if ((a.cwiseMax(b).cwiseMax(c).array() < box_min.array()).any() ||
        (a.cwiseMin(b).cwiseMin(c).array() > box_max.array()).any())
      continue;
    // Closest pair between the probe's axis and the triangle, by two alternations of
    // closest-point queries (exact for a sphere; close enough for a capsule, whose axis is
    // long against the triangles).
    Vec3 centre = closest_point_on_segment((a + b + c) / 3.0, tip, tail);
    Vec3 q = closest_point_on_triangle(centre, a, b, c);
    centre = closest_point_on_segment(q, tip, tail);
    q = closest_point_on_triangle(centre, a, b, c);
    const Vec3 face_normal = (b - a).cross(c - a);
    const double face_area2 = face_normal.norm();
    if (!(face_area2 > 0)) continue;
    const Vec3 outward = face_normal / face_area2;
    const Vec3 separation = centre - q;  // from the surface to the probe's centre
    const double distance = separation.norm();
    if (distance >= radius) continue;
    const Vec3 weights = barycentric(q, a, b, c);
    Vec3 normal;  // from the tissue towards the probe
    double depth;
    if (separation.dot(outward) >= 0) {
      normal = distance > 1e-12 * radius ? Vec3(separation / distance) : outward;
      depth = radius - distance;
    } else if (weights.minCoeff() > 1e-9) {
      // The centre went through the face itself: push the probe back out along its normal.
      normal = outward;
      depth = radius + distance;
    } else {
      // Behind the face's plane but beside it (the rim of a dimple the probe sits in): the
      // neighbouring faces that the centre is really in front of carry this contact.
      continue;
    }
    const Vec3 force = -stiffness * depth * normal;  // on the tissue
    contact.force_on_tool -= force;
    ++contact.triangles_touched;
    spread_to_nodes(by_node, t, weights, force, normal, stiffness, fixed);
  }
  contact.springs.reserve(by_node.size());
  for (auto& [node, spring] : by_node) contact.springs.push_back(spring);
  return contact;
}

ProbeContact held_contact(const Vector& x, const std::vector<std::array<int, 3>>& surface,
                          const std::vector<std::uint8_t>& fixed, const std::vector<Vec3>& points, double radius,
                          double stiffness, std::vector<int>* hint) {
  ProbeContact contact;
  if (points.empty()) return contact;
  // Each point's nearest triangle (its closest point and the face normal there), from only the
  // triangles near it (physics/core/nearest_triangles.hpp).
  const std::vector<NearestTriangle> found = nearest_triangles(x, surface, {}, points, hint);
  std::vector<double> nearest(points.size());
  std::vector<int> triangle(points.size());
  std::vector<Vec3> closest(points.size()), outward(points.size(), Vec3::Zero());
  for (std::size_t i = 0; i < points.size(); ++i) {
    nearest[i] = found[i].distance, triangle[i] = found[i].triangle, closest[i] = found[i].closest;
    if (triangle[i] >= 0) outward[i] = face_normal(x, surface[static_cast<std::size_t>(triangle[i])]).normalized();
  }
  std::map<int, NodalSpring> by_node;  // ordered: the springs come out in node order
  for (std::size_t i = 0; i < points.size(); ++i) {
    // Within a radius of the surface probe_contact holds the capsule (outside, or through a face).
    if (triangle[i] < 0 || nearest[i] < radius) continue;
    const Vec3 offset = points[i] - closest[i];
    if (offset.dot(outward[i]) >= 0) continue;  // outside
    const Vec3 normal = offset / -nearest[i];   // from the tissue towards the probe: out
    const double depth = radius + nearest[i];
    const Vec3 force = -stiffness * depth * normal;  // on the tissue
    contact.force_on_tool -= force;
    ++contact.triangles_touched;
    const auto& tri = surface[static_cast<std::size_t>(triangle[i])];
    const Vec3 weights = barycentric(closest[i], x.segment<3>(3 * tri[0]), x.segment<3>(3 * tri[1]), x.segment<3>(3 * tri[2]));
    spread_to_nodes(by_node, tri, weights, force, normal, stiffness, fixed);
  }
  contact.springs.reserve(by_node.size());
  for (auto& [node, spring] : by_node) contact.springs.push_back(spring);
  return contact;
}

}  // namespace incise::physics
