// The probe's contact with a body (penalty springs, physics/core/contact.hpp) as forces and
// stiffnesses on its nodes: the touched surface nodes of a tetrahedral body, or, for an
// embedded surface, the particles each touched vertex follows (seed 004 §2.6).
#pragma once

#include "physics/core/body.hpp"
#include "physics/core/model.hpp"

#include <vector>

namespace incise::physics {

// The capsule [tip, tail] of `radius` (a sphere when they coincide) against the body's surface;
// `triangles_touched` grows by the surface triangles it touches.
std::vector<NodalSpring> body_contact(const BodyData& body, const Vec3& tip, const Vec3& tail, double radius,
                                      double stiffness, int& triangles_touched);

// A pressed blade's edge (a polyline of capsules of `radius`) against the body's surface: each
// segment's capsule (probe_contact), and where a piece of the edge went more than a radius
// inside, the hold of held_contact at its points (the edge's vertices and every `spacing`
// along it), whatever the depth; `spacing` 0: the capsules only.
std::vector<NodalSpring> body_edge_contact(const BodyData& body, const std::vector<Vec3>& edge, double radius,
                                           double stiffness, double spacing, int& triangles_touched);

}  // namespace incise::physics
