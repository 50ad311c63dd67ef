// Continuous collision detection between the blade and the object's edges: the primitive
// test of progressive cutting (seed 004 §2.3, after Provot 1997, "Collision and
// self-collision handling in cloth model dedicated to design garments").
//
// Over one step every point moves on a straight line from its position at t = 0 to its
// position at t = 1 (seed 004 §2.2: the blade polyline's points and the object's edge
// endpoints alike). A blade segment and an object edge can only touch when their four
// endpoints are coplanar, which is a cubic equation in t; at each of its roots in [0, 1],
// in increasing order, the segments are tested for an actual intersection. The first one is
// the hit, reported as a fraction along the object edge, which the caller applies in the rest
// configuration (all topology edits are done there, seed 004 §2.3).
//
// Conventions (the tests in tests/unit/test_cut_ccd.cpp hold them):
// - The step is the closed interval [0, 1]. Segments already touching at t = 0 are a hit at
//   t = 0 (a static blade lying across a static edge is cut at once); touching first at t = 1
//   is a hit at t = 1. The caller, who removes or splits a cut edge, makes sure the same
//   contact is not reported again at t = 0 of the next step.
// - "Touching" means the closest points of the two segments are within the touching distance
//   (touching_distance below): relative_distance times the size of the problem, the largest
//   distance of the eight positions from their centroid. Rounding makes exact contact (a
//   blade through an existing vertex, along an existing edge, in the plane of a flat face)
//   unreliable without it; it is far below anything a surgeon or a mesh can resolve.
// - Parameters within the touching distance of a segment's end are snapped to exactly 0 or 1,
//   so a cut through an existing vertex reads edge_parameter == 0 or 1 without the caller
//   needing its own epsilon.
// - Parallel segments (the sine of their angle below 1e-12) that overlap have no single
//   closest pair: the hit is reported at the middle of their overlap, with `parallel` set.
//   A blade lying along an existing edge is therefore a hit at u = the middle of the shared
//   part; the topology layer decides what cutting along an edge means.
// - A segment shorter than the touching distance is treated as a point, its middle
//   (parameter 0.5).
// - Non-finite input throws std::invalid_argument naming the input; nothing non-finite is
//   ever returned.
#pragma once

#include "physics/core/model.hpp"

#include <optional>
#include <span>

namespace incise::physics {

// A straight segment between two points.
struct Segment {
  Vec3 first = Vec3::Zero();
  Vec3 second = Vec3::Zero();
};

// A segment whose endpoints move linearly over a step, from at_start (t = 0) to at_end (t = 1).
struct MovingSegment {
  Segment at_start;
  Segment at_end;
};

struct ContinuousCollisionTolerances {
  // Touching distance as a fraction of the size of the problem (see above). 1e-8 is six
  // orders of magnitude above the rounding of the coplanarity cubic and of the closest-point
  // computation (about 1e-16 relative), and, for a 10 cm organ, 1 nm.
  double relative_distance = 1e-8;
};

// The first contact of a blade segment with an object edge during the step.
struct EdgeHit {
  double time = 0;              // t in [0, 1]
  double blade_parameter = 0;   // s in [0, 1]: blade point = first + s (second - first) at t
  double edge_parameter = 0;    // u in [0, 1]: from the edge's first endpoint to its second
  double distance = 0;          // between the two closest points at t (<= touching distance)
  Vec3 position = Vec3::Zero(); // the blade point at the hit, in the input's coordinates
  bool parallel = false;        // overlapping parallel segments: s and u are the overlap's middle
};

// The touching distance used for this pair (relative_distance times the size of the problem).
double touching_distance(const MovingSegment& blade, const MovingSegment& edge,
                         const ContinuousCollisionTolerances& tolerances = {});

// Provot's edge-edge test: the earliest t in [0, 1] at which the blade segment and the object
// edge touch, or nothing. Candidate times are the roots of the coplanarity cubic, plus
// t = 0 and t = 1 (contact at the ends of the step), plus the cubic's turning points (a
// tangent root, where the four points become coplanar without crossing, has no sign change
// to bracket), plus, when the four points stay coplanar throughout the step (the cubic
// vanishes identically: everything in one plane, parallel segments, a point-like segment),
// the times an endpoint of one segment crosses the line of the other, since coplanarity
// then says nothing about contact and two segments in a plane first touch when an endpoint of
// one reaches the other. Every candidate is checked by the true closest distance, so an extra
// candidate can never create a false hit.
std::optional<EdgeHit> first_edge_hit(const MovingSegment& blade, const MovingSegment& edge,
                                      const ContinuousCollisionTolerances& tolerances = {});

// A hit of a polyline blade: which of its segments (segment i joins points i and i + 1), and
// the hit on that segment.
struct PolylineHit {
  int segment = 0;
  EdgeHit hit;
};

// Sweeps a polyline blade, given by its points at t = 0 and at t = 1 (same count, at least
// two), against one object edge: the earliest hit over the blade's segments; at equal times
// the lowest segment (a hit exactly at a joint is reported on the segment before it).
std::optional<PolylineHit> first_polyline_hit(std::span<const Vec3> blade_at_start,
                                              std::span<const Vec3> blade_at_end,
                                              const MovingSegment& edge,
                                              const ContinuousCollisionTolerances& tolerances = {});

// Closest points of two static segments, the narrow test run at each candidate time.
struct SegmentProximity {
  double first_parameter = 0;   // along segment a
  double second_parameter = 0;  // along segment b
  double distance = 0;
  bool parallel = false;
};

// Segments shorter than point_length count as points (parameter 0.5); parallel segments
// (sine of the angle below 1e-12) take the middle of their overlap when they overlap.
SegmentProximity closest_points(const Segment& a, const Segment& b, double point_length = 0);

}  // namespace incise::physics
