// Penalty contact between a rigid probe (a sphere, or a capsule: a swept sphere along a
// segment) and a body's surface triangles: the first contact model of the foundation; the
// haptics issue turns it into the ContactModel the 1 kHz loop evaluates.
#pragma once

#include "physics/core/model.hpp"

#include <array>
#include <vector>

namespace incise::physics {

struct ProbeContact {
  std::vector<NodalSpring> springs;  // one per touched node, forces and stiffnesses summed
  Vec3 force_on_tool = Vec3::Zero();
  int triangles_touched = 0;
};

// Closest point of triangle (a, b, c) to p (exact, by the Voronoi regions of its vertices,
// edges and face).
Vec3 closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

// Every surface triangle within `radius` of the probe axis [tip, tail] pushes back with
// force k * depth along the separation direction, shared among its corners by the
// barycentric weights of its closest point. A probe whose centre has crossed a triangle
// (tunnelled: centre behind the face, its closest point inside the face) is still pushed
// out along the face normal, so a fast stroke cannot leave the probe stuck inside; a face
// whose plane the centre is behind but whose closest point is on its border (the rim of a
// dimple) is left to its neighbours. Each node's stiffness is
// w k n n^T (the lumped, positive semi-definite part of the exact Jacobian), which keeps
// the implicit system symmetric positive definite. Fixed nodes take no force.
ProbeContact probe_contact(const Vector& positions, const std::vector<std::array<int, 3>>& surface,
                           const std::vector<std::uint8_t>& fixed, const Vec3& tip, const Vec3& tail,
                           double radius, double stiffness);

// The hold of a pressed blade's edge (engine/contact.cpp): each of `points` that is behind its
// nearest surface triangle (inside the body) by a radius or more, where probe_contact lets go
// of a capsule (its axis a radius past the face), is pushed out towards that triangle's
// closest point q with k (radius + depth), whatever the depth (at a radius, the force
// probe_contact gave a face the axis went through): an edge
// pressed further in a step than its width cannot slip through the surface, and the tissue
// goes on being pressed until the crack's onset. The side is the nearest triangle's (its face normal against the offset from q; exact
// for a closed surface away from its convex creases): a point more than half the body's
// thickness in would be pushed out of the far side, which pressing never reaches. Each point
// is one probe's worth of stiffness; its force goes to q's triangle by barycentric weights.
// hint (optional, in and out): the points' nearest triangles at the previous call, which only
// spare work (physics/core/nearest_triangles.hpp).
ProbeContact held_contact(const Vector& positions, const std::vector<std::array<int, 3>>& surface,
                          const std::vector<std::uint8_t>& fixed, const std::vector<Vec3>& points, double radius,
                          double stiffness, std::vector<int>* hint = nullptr);

}  // namespace incise::physics
