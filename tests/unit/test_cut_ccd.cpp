// The continuous collision layer of cutting (physics/cut): Provot's edge-edge test (seed 004
// §2.3) against the three situations of seed 004 Figs. 5.2-5.4, the degenerate cases it must
// handle on purpose, analytic hit parameters, a brute-force reference over many random
// configurations, and the btDbvt broad phase against brute force.
//
// The references here are written independently of the library: segment distance from the
// normal equations with clamping (the library uses cross products and the square's border),
// and a dense sampling of t in place of the cubic.
#include "physics/cut/broad_phase.hpp"
#include "physics/cut/continuous_collision.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <random>
#include <set>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace incise::physics {
namespace {

MovingSegment moving(const Vec3& first_start, const Vec3& second_start, const Vec3& first_end,
                     const Vec3& second_end) {
  return {{first_start, second_start}, {first_end, second_end}};
}

MovingSegment fixed(const Vec3& first, const Vec3& second) { return moving(first, second, first, second); }

Vec3 lerp(const Vec3& a, const Vec3& b, double t) { return (1 - t) * a + t * b; }

Segment at(const MovingSegment& segment, double t) {
  return {lerp(segment.at_start.first, segment.at_end.first, t),
          lerp(segment.at_start.second, segment.at_end.second, t)};
}

Vec3 point_on(const Segment& segment, double parameter) { return lerp(segment.first, segment.second, parameter); }

// Reference segment distance, the textbook way: minimise |a(s) - b(u)|^2 from the normal
// equations, clamping s, then u, then s again.
double reference_distance(const Segment& a, const Segment& b) {
  const Vec3 d1 = a.second - a.first;
  const Vec3 d2 = b.second - b.first;
  const Vec3 r = a.first - b.first;
  const double aa = d1.dot(d1);
  const double ee = d2.dot(d2);
  const double f = d2.dot(r);
  double s = 0;
  double u = 0;
  if (aa <= 1e-300 && ee <= 1e-300) return r.norm();
  if (aa <= 1e-300) {
    u = std::clamp(f / ee, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (ee <= 1e-300) {
      s = std::clamp(-c / aa, 0.0, 1.0);
    } else {
      const double bb = d1.dot(d2);
      const double denominator = aa * ee - bb * bb;
      s = denominator > 0 ? std::clamp((bb * f - c * ee) / denominator, 0.0, 1.0) : 0.0;
      u = (bb * s + f) / ee;
      if (u < 0) {
        u = 0;
        s = std::clamp(-c / aa, 0.0, 1.0);
      } else if (u > 1) {
        u = 1;
        s = std::clamp((bb - c) / aa, 0.0, 1.0);
      }
    }
  }
  return ((a.first + s * d1) - (b.first + u * d2)).norm();
}

// Distance from a point to a segment, for the convex search below.
double point_segment_distance(const Vec3& p, const Segment& b) {
  const Vec3 d = b.second - b.first;
  const double length2 = d.squaredNorm();
  const double u = length2 > 0 ? std::clamp((p - b.first).dot(d) / length2, 0.0, 1.0) : 0.0;
  return (p - point_on(b, u)).norm();
}

// Segment distance by golden-section search over s of the distance from a(s) to b, which is
// convex in s (the distance to a convex set along a line).
double convex_search_distance(const Segment& a, const Segment& b) {
  const double ratio = (std::sqrt(5.0) - 1) / 2;
  double lo = 0;
  double hi = 1;
  for (int i = 0; i < 200 && hi - lo > 1e-15; ++i) {
    const double left = hi - ratio * (hi - lo);
    const double right = lo + ratio * (hi - lo);
    if (point_segment_distance(point_on(a, left), b) <= point_segment_distance(point_on(a, right), b)) {
      hi = right;
    } else {
      lo = left;
    }
  }
  double best = point_segment_distance(point_on(a, 0.5 * (lo + hi)), b);
  best = std::min({best, point_segment_distance(a.first, b), point_segment_distance(a.second, b)});
  return best;
}

// The chapter 4 method (seed 004 §2.2): the swept quad as two triangles, tested against the
// object edge in its end-of-step position only.
bool segment_crosses_triangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 normal = (b - a).cross(c - a);
  const double dp = normal.dot(p - a);
  const double dq = normal.dot(q - a);
  if (normal.squaredNorm() == 0 || dp * dq > 0 || dp == dq) return false;
  const Vec3 x = p + (dp / (dp - dq)) * (q - p);
  return normal.dot((b - a).cross(x - a)) >= 0 && normal.dot((c - b).cross(x - b)) >= 0 &&
         normal.dot((a - c).cross(x - c)) >= 0;
}

bool discrete_end_of_step_cut(const MovingSegment& blade, const MovingSegment& edge) {
  const Vec3& a = blade.at_start.first;
  const Vec3& b = blade.at_start.second;
  const Vec3& c = blade.at_end.second;
  const Vec3& d = blade.at_end.first;
  const Vec3& p = edge.at_end.first;
  const Vec3& q = edge.at_end.second;
  return segment_crosses_triangle(p, q, a, b, c) || segment_crosses_triangle(p, q, a, c, d);
}

// ---------------------------------------------------------------- the three situations

// Seed 004 Fig. 5.2: blade and edge both move; the edge crosses the whole swept quad.
TEST(ContinuousCollision, EdgeCrossingTheWholeSweptQuadIsHit) {
  const MovingSegment blade = moving({-1, 0, 0}, {1, 0, 0}, {-1, 1, 0}, {1, 1, 0});
  const MovingSegment edge = moving({0, 1.5, -0.5}, {0, 1.5, 0.5}, {0, -0.5, -0.5}, {0, -0.5, 0.5});
  EXPECT_FALSE(discrete_end_of_step_cut(blade, edge)) << "a discrete end-of-step test misses this cut";
  const auto hit = first_edge_hit(blade, edge);
  ASSERT_TRUE(hit.has_value());
  // Blade at y = t, edge at y = 1.5 - 2 t: they meet at t = 0.5, at x = 0 (s = 0.5), z = 0 (u = 0.5).
  EXPECT_NEAR(hit->time, 0.5, 1e-12);
  EXPECT_NEAR(hit->blade_parameter, 0.5, 1e-12);
  EXPECT_NEAR(hit->edge_parameter, 0.5, 1e-12);
  EXPECT_LT((hit->position - Vec3(0, 0.5, 0)).norm(), 1e-12);
  EXPECT_FALSE(hit->parallel);
}

// Seed 004 Fig. 5.3: the edge enters the swept area after the blade has passed.
TEST(ContinuousCollision, EdgeEnteringTheSweptAreaAfterTheBladeIsNotHit) {
  const MovingSegment blade = moving({-1, 0, 0}, {1, 0, 0}, {-1, 1, 0}, {1, 1, 0});
  // At y = 0.25, which the blade passes at t = 0.25; the edge reaches z = 0 only at t = 0.5.
  const MovingSegment edge = moving({0, 0.25, 0.5}, {0, 0.25, 1.5}, {0, 0.25, -0.5}, {0, 0.25, 0.5});
  EXPECT_TRUE(discrete_end_of_step_cut(blade, edge)) << "a discrete end-of-step test makes a false cut here";
  EXPECT_FALSE(first_edge_hit(blade, edge).has_value());
}

// Seed 004 Fig. 5.4: the blade does not move, the object moves onto it: zero swept area.
TEST(ContinuousCollision, StaticBladeWithTheObjectMovingOntoItIsHit) {
  const MovingSegment blade = fixed({-1, 0, 0}, {1, 0, 0});
  const MovingSegment edge = moving({0.3, -0.5, 0.5}, {0.3, 0.5, 0.5}, {0.3, -0.5, -0.5}, {0.3, 0.5, -0.5});
  EXPECT_FALSE(discrete_end_of_step_cut(blade, edge));
  const auto hit = first_edge_hit(blade, edge);
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->time, 0.5, 1e-12);
  EXPECT_NEAR(hit->blade_parameter, 0.65, 1e-12);
  EXPECT_NEAR(hit->edge_parameter, 0.5, 1e-12);

  // The edge sliding down its own line onto the blade: its line always meets the blade's, so
  // the four points are coplanar throughout and the cubic vanishes identically; contact
  // starts when its lower end reaches the blade.
  const MovingSegment sliding = moving({0.3, 0, 0.5}, {0.3, 0, 1.5}, {0.3, 0, -0.5}, {0.3, 0, 0.5});
  const auto slid = first_edge_hit(blade, sliding);
  ASSERT_TRUE(slid.has_value());
  EXPECT_NEAR(slid->time, 0.5, 1e-12);
  EXPECT_NEAR(slid->blade_parameter, 0.65, 1e-12);
  EXPECT_EQ(slid->edge_parameter, 0.0);
}

// The convention: a hit at any t in the closed step [0, 1], so a static crossing is at t = 0.
TEST(ContinuousCollision, StaticCoplanarCrossingIsHitAtTimeZero) {
  const MovingSegment blade = fixed({-1, 0, 0}, {1, 0, 0});
  const MovingSegment edge = fixed({0.2, -1, 0}, {0.2, 1, 0});
  const auto hit = first_edge_hit(blade, edge);
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->time, 0.0);
  EXPECT_NEAR(hit->blade_parameter, 0.6, 1e-12);
  EXPECT_NEAR(hit->edge_parameter, 0.5, 1e-12);

  // The same in a tilted, shifted plane, where rounding leaves the cubic at about 1e-16.
  const Mat3 rotation = (Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()) *
                         Eigen::AngleAxisd(1.9, Vec3(-2, 0.5, 1).normalized()))
                            .toRotationMatrix();
  const Vec3 shift(0.123, -4.56, 7.89);
  auto place = [&](const Vec3& p) -> Vec3 { return rotation * p + shift; };
  const auto tilted = first_edge_hit(fixed(place({-1, 0, 0}), place({1, 0, 0})),
                                     fixed(place({0.2, -1, 0}), place({0.2, 1, 0})));
  ASSERT_TRUE(tilted.has_value());
  EXPECT_EQ(tilted->time, 0.0);
  EXPECT_NEAR(tilted->blade_parameter, 0.6, 1e-9);
  EXPECT_NEAR(tilted->edge_parameter, 0.5, 1e-9);

  // Coplanar but apart, and crossing in projection but apart out of plane: no hit.
  EXPECT_FALSE(first_edge_hit(blade, fixed({1.2, -1, 0}, {1.2, 1, 0})).has_value());
  EXPECT_FALSE(first_edge_hit(blade, fixed({0.2, -1, 1e-3}, {0.2, 1, 1e-3})).has_value());
}

// ---------------------------------------------------------------- tolerance and degeneracies

// Blade along x; the edge, nearly parallel to it (rising by `tilt` over its length), sweeps
// across it in y, `height` above it at its first end, which is its closest point.
TEST(ContinuousCollision, NearParallelEdgesHitAndMissEitherSideOfTheTolerance) {
  const MovingSegment blade = fixed({0, 0, 0}, {1, 0, 0});
  auto edge = [](double height, double tilt) {
    return moving({0.25, 1, height}, {0.75, 1, height + tilt}, {0.25, -1, height}, {0.75, -1, height + tilt});
  };
  for (double tilt : {1e-5, 1e-7, 1e-13, 0.0}) {
    const double touching = touching_distance(blade, edge(0, tilt));
    ASSERT_GT(touching, 0.0);
    const auto hit = first_edge_hit(blade, edge(0.5 * touching, tilt));
    ASSERT_TRUE(hit.has_value()) << "tilt " << tilt;
    EXPECT_NEAR(hit->time, 0.5, 1e-9) << "tilt " << tilt;
    EXPECT_NEAR(hit->distance, 0.5 * touching, 1e-3 * touching) << "tilt " << tilt;
    // Parallel below a sine of 1e-12 (tilt 1e-13 over a length 0.5): the overlap's middle.
    const bool parallel = tilt < 1e-12;
    EXPECT_EQ(hit->parallel, parallel) << "tilt " << tilt;
    EXPECT_NEAR(hit->blade_parameter, parallel ? 0.5 : 0.25, 1e-9) << "tilt " << tilt;
    EXPECT_NEAR(hit->edge_parameter, parallel ? 0.5 : 0.0, 1e-9) << "tilt " << tilt;
    EXPECT_FALSE(first_edge_hit(blade, edge(2 * touching, tilt)).has_value()) << "tilt " << tilt;
  }
  // Static and in one plane, `offset` to the side: a hit at t = 0 only within the tolerance.
  for (double tilt : {1e-6, 0.0}) {
    auto side = [&](double offset) { return fixed({0.25, offset, 0}, {0.75, offset + tilt, 0}); };
    const double touching = touching_distance(blade, side(0));
    const auto hit = first_edge_hit(blade, side(0.5 * touching));
    ASSERT_TRUE(hit.has_value()) << "tilt " << tilt;
    EXPECT_EQ(hit->time, 0.0);
    EXPECT_FALSE(first_edge_hit(blade, side(2 * touching)).has_value()) << "tilt " << tilt;
  }
}

// Through an existing vertex: the edge parameter is exactly 0 or 1 (snapped within the
// touching distance), so the topology layer can recognise a cut through a vertex.
TEST(ContinuousCollision, BladeThroughAnExistingVertexReportsTheEdgeEnd) {
  const MovingSegment blade = moving({-0.5, 1, 0}, {0.5, 1, 0}, {-0.5, -1, 0}, {0.5, -1, 0});
  const auto through_first = first_edge_hit(blade, fixed({0.2, 0, 0}, {0.2, 0, 1}));
  ASSERT_TRUE(through_first.has_value());
  EXPECT_NEAR(through_first->time, 0.5, 1e-12);
  EXPECT_NEAR(through_first->blade_parameter, 0.7, 1e-12);
  EXPECT_EQ(through_first->edge_parameter, 0.0);

  const auto through_second = first_edge_hit(blade, fixed({0.2, 0, -1}, {0.2, 0, 0}));
  ASSERT_TRUE(through_second.has_value());
  EXPECT_NEAR(through_second->time, 0.5, 1e-12);
  EXPECT_EQ(through_second->edge_parameter, 1.0);

  // Crossing the edge a third of a touching distance from its end: snapped to the vertex.
  const MovingSegment near_vertex_probe = fixed({0.2, 0, 0}, {0.2, 0, 1});
  const double touching = touching_distance(blade, near_vertex_probe);
  const auto near_vertex = first_edge_hit(blade, fixed({0.2, 0, -touching / 3}, {0.2, 0, 1}));
  ASSERT_TRUE(near_vertex.has_value());
  EXPECT_EQ(near_vertex->edge_parameter, 0.0);
  // ...but three touching distances away it is an ordinary crossing.
  const auto past_vertex = first_edge_hit(blade, fixed({0.2, 0, -3 * touching}, {0.2, 0, 1}));
  ASSERT_TRUE(past_vertex.has_value());
  EXPECT_GT(past_vertex->edge_parameter, 0.0);
  EXPECT_NEAR(past_vertex->edge_parameter, 3 * touching / (1 + 3 * touching), 1e-3 * touching);

  // Missing the vertex by twice the touching distance: no hit.
  EXPECT_FALSE(first_edge_hit(blade, fixed({0.2, 0, 2 * touching}, {0.2, 0, 1})).has_value());
}

// Along an existing edge (collinear): the documented outcome is a hit flagged parallel, at
// the middle of the shared part; collinear but apart is no hit.
TEST(ContinuousCollision, BladeAlongAnExistingEdgeIsAParallelHitAtTheOverlapMiddle) {
  const MovingSegment blade = fixed({0, 0, 0}, {1, 0, 0});
  const auto along = first_edge_hit(blade, fixed({0.25, 0, 0}, {0.75, 0, 0}));
  ASSERT_TRUE(along.has_value());
  EXPECT_EQ(along->time, 0.0);
  EXPECT_TRUE(along->parallel);
  EXPECT_NEAR(along->blade_parameter, 0.5, 1e-12);
  EXPECT_NEAR(along->edge_parameter, 0.5, 1e-12);

  // Partly shared: [0.6, 1] of the blade is [0, 0.4 / 0.8] of the edge.
  const auto partly = first_edge_hit(blade, fixed({0.6, 0, 0}, {1.4, 0, 0}));
  ASSERT_TRUE(partly.has_value());
  EXPECT_TRUE(partly->parallel);
  EXPECT_NEAR(partly->blade_parameter, 0.8, 1e-12);
  EXPECT_NEAR(partly->edge_parameter, 0.25, 1e-12);

  // A blade moving onto the edge's line, staying parallel to it.
  const MovingSegment arriving = moving({0, 1, 0}, {1, 1, 0}, {0, -1, 0}, {1, -1, 0});
  const auto arrived = first_edge_hit(arriving, fixed({0.25, 0, 0}, {0.75, 0, 0}));
  ASSERT_TRUE(arrived.has_value());
  EXPECT_NEAR(arrived->time, 0.5, 1e-12);
  EXPECT_TRUE(arrived->parallel);
  EXPECT_NEAR(arrived->edge_parameter, 0.5, 1e-12);

  // End to end the shared part is one point: the two ends.
  const auto end_to_end = first_edge_hit(blade, fixed({1, 0, 0}, {2, 0, 0}));
  ASSERT_TRUE(end_to_end.has_value());
  EXPECT_TRUE(end_to_end->parallel);
  EXPECT_EQ(end_to_end->blade_parameter, 1.0);
  EXPECT_EQ(end_to_end->edge_parameter, 0.0);

  EXPECT_FALSE(first_edge_hit(blade, fixed({1.5, 0, 0}, {2, 0, 0})).has_value());
}

// Zero-length segments: a point blade (a needle tip) and a collapsed edge.
TEST(ContinuousCollision, PointLikeSegmentsAreTreatedAsPoints) {
  const MovingSegment tip = moving({0.3, 0, 1}, {0.3, 0, 1}, {0.3, 0, -1}, {0.3, 0, -1});
  const auto pierced = first_edge_hit(tip, fixed({-1, 0, 0}, {1, 0, 0}));
  ASSERT_TRUE(pierced.has_value());
  EXPECT_NEAR(pierced->time, 0.5, 1e-12);
  EXPECT_EQ(pierced->blade_parameter, 0.5);
  EXPECT_NEAR(pierced->edge_parameter, 0.65, 1e-12);
  EXPECT_FALSE(first_edge_hit(tip, fixed({-1, 0.01, 0}, {1, 0.01, 0})).has_value());

  const MovingSegment blade = moving({-1, 1, 0}, {1, 1, 0}, {-1, -1, 0}, {1, -1, 0});
  const auto collapsed = first_edge_hit(blade, fixed({0.5, 0, 0}, {0.5, 0, 0}));
  ASSERT_TRUE(collapsed.has_value());
  EXPECT_NEAR(collapsed->time, 0.5, 1e-12);
  EXPECT_NEAR(collapsed->blade_parameter, 0.75, 1e-12);
  EXPECT_EQ(collapsed->edge_parameter, 0.5);

  // Everything at one point.
  const Vec3 p(1, 2, 3);
  const auto everything = first_edge_hit(fixed(p, p), fixed(p, p));
  ASSERT_TRUE(everything.has_value());
  EXPECT_EQ(everything->time, 0.0);
}

// A constructed contact: pick t, s, u and the blade's motion; build the edge so that its
// point u meets the blade's point s at t, with a generic motion of its own.
TEST(ContinuousCollision, HitParametersMatchAConstructedContact) {
  const double t = 0.3;
  const double s = 0.4;
  const double u = 0.7;
  const MovingSegment blade = moving({0.1, -0.2, 0.05}, {0.9, 0.3, -0.1}, {0.3, 0.6, 0.2}, {1.2, 0.9, 0.4});
  const Vec3 contact = point_on(at(blade, t), s);
  const Vec3 direction(0.15, -0.35, 0.6);  // the edge at t, from its first to its second end
  const Vec3 first_velocity(0.2, 0.5, -1.1);
  const Vec3 second_velocity(-0.3, 0.4, -0.9);
  const Vec3 first_at_t = contact - u * direction;
  const Vec3 second_at_t = contact + (1 - u) * direction;
  const MovingSegment edge = moving(first_at_t - t * first_velocity, second_at_t - t * second_velocity,
                                    first_at_t + (1 - t) * first_velocity, second_at_t + (1 - t) * second_velocity);
  // No earlier contact: the reference distance stays above zero before t.
  double closest_before = 1e300;
  for (int k = 0; k <= 3000; ++k) closest_before = std::min(closest_before, reference_distance(at(blade, t * k / 3100.0), at(edge, t * k / 3100.0)));
  ASSERT_GT(closest_before, 1e-3);

  const auto hit = first_edge_hit(blade, edge);
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->time, t, 1e-12);
  EXPECT_NEAR(hit->blade_parameter, s, 1e-10);
  EXPECT_NEAR(hit->edge_parameter, u, 1e-10);
  EXPECT_LT((hit->position - contact).norm(), 1e-10);
  EXPECT_LT(hit->distance, 1e-10);
  // Reversing the edge's direction mirrors u; the hit is otherwise the same.
  const MovingSegment reversed = moving(edge.at_start.second, edge.at_start.first, edge.at_end.second,
                                        edge.at_end.first);
  const auto mirrored = first_edge_hit(blade, reversed);
  ASSERT_TRUE(mirrored.has_value());
  EXPECT_NEAR(mirrored->time, t, 1e-12);
  EXPECT_NEAR(mirrored->edge_parameter, 1 - u, 1e-10);
}

TEST(ContinuousCollision, PolylineSweepReportsTheEarliestSegment) {
  const std::vector<Vec3> blade = {{-1, 0, 0}, {0, 0, 0}, {1, 0, 0}};
  // Crossing the second segment half way, at t = 0.5.
  const auto second = first_polyline_hit(blade, blade, moving({0.5, -0.5, 0.5}, {0.5, 0.5, 0.5},
                                                              {0.5, -0.5, -0.5}, {0.5, 0.5, -0.5}));
  ASSERT_TRUE(second.has_value());
  EXPECT_EQ(second->segment, 1);
  EXPECT_NEAR(second->hit.time, 0.5, 1e-12);
  EXPECT_NEAR(second->hit.blade_parameter, 0.5, 1e-12);
  // Through the joint: both segments touch at the same time; the first is reported, at its end.
  const auto joint = first_polyline_hit(blade, blade, moving({0, -0.5, 0.5}, {0, 0.5, 0.5},
                                                             {0, -0.5, -0.5}, {0, 0.5, -0.5}));
  ASSERT_TRUE(joint.has_value());
  EXPECT_EQ(joint->segment, 0);
  EXPECT_EQ(joint->hit.blade_parameter, 1.0);
  // A moving, bent blade whose far segment reaches the edge first.
  const std::vector<Vec3> bent_start = {{-1, 0, 0}, {0, 0, 0}, {1, 0, 0.3}};
  const std::vector<Vec3> bent_end = {{-1, 0, -1}, {0, 0, -1}, {1, 0, -0.7}};
  const MovingSegment low = fixed({-0.5, -1, -0.4}, {-0.5, 1, -0.4});  // under the first segment
  const MovingSegment lower = fixed({0.5, -1, -0.2}, {0.5, 1, -0.2});  // under the second, reached at t = 0.35
  const auto first_low = first_polyline_hit(bent_start, bent_end, low);
  ASSERT_TRUE(first_low.has_value());
  EXPECT_EQ(first_low->segment, 0);
  EXPECT_NEAR(first_low->hit.time, 0.4, 1e-12);
  const auto first_lower = first_polyline_hit(bent_start, bent_end, lower);
  ASSERT_TRUE(first_lower.has_value());
  EXPECT_EQ(first_lower->segment, 1);
  EXPECT_NEAR(first_lower->hit.time, 0.35, 1e-12);
}

TEST(ContinuousCollision, NonFiniteInputIsReportedByName) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const MovingSegment good = fixed({0, 0, 0}, {1, 0, 0});
  MovingSegment bad = good;
  bad.at_end.second.y() = nan;
  auto message = [](auto&& call) -> std::string {
    try {
      call();
    } catch (const std::invalid_argument& error) {
      return error.what();
    }
    return "no exception";
  };
  EXPECT_NE(message([&] { first_edge_hit(good, bad); }).find("edge.at_end.second"), std::string::npos);
  EXPECT_NE(message([&] { first_edge_hit(bad, good); }).find("blade.at_end.second"), std::string::npos);
  bad = good;
  bad.at_start.first.x() = inf;
  EXPECT_NE(message([&] { first_edge_hit(bad, good); }).find("blade.at_start.first"), std::string::npos);
  EXPECT_NE(message([&] { touching_distance(good, bad); }).find("edge.at_start.first"), std::string::npos);
  EXPECT_NE(message([&] { first_edge_hit(good, good, {-1}); }).find("relative_distance"), std::string::npos);
  EXPECT_NE(message([&] { first_edge_hit(good, good, {nan}); }).find("relative_distance"), std::string::npos);

  std::vector<Vec3> start = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  std::vector<Vec3> end = start;
  end[2].z() = nan;
  EXPECT_NE(message([&] { first_polyline_hit(start, end, good); }).find("blade point 2 at the end"), std::string::npos);
  EXPECT_NE(message([&] { first_polyline_hit(start, std::span<const Vec3>(start).first(2), good); }).find("3 points"),
            std::string::npos);
  EXPECT_NE(message([&] { first_polyline_hit(std::span<const Vec3>(start).first(1),
                                             std::span<const Vec3>(start).first(1), good); })
                .find("at least 2"),
            std::string::npos);

  EdgeBroadPhase broad(0.01);
  EXPECT_NE(message([&] { broad.set_edge(7, bad); }).find("edge 7"), std::string::npos);
  EXPECT_NE(message([&] { EdgeBroadPhase negative(-1); }).find("margin"), std::string::npos);
  std::vector<int> candidates;
  EXPECT_NE(message([&] { broad.query(start, end, candidates); }).find("blade segment 1"), std::string::npos);
  EXPECT_THROW(broad.remove_edge(3), std::out_of_range);
}

TEST(ContinuousCollision, ClosestPointsMatchAConvexSearch) {
  std::mt19937_64 random(20240611);
  std::uniform_real_distribution<double> coordinate(-1, 1);
  auto point = [&] { return Vec3(coordinate(random), coordinate(random), coordinate(random)); };
  double worst = 0;
  for (int i = 0; i < 3000; ++i) {
    Segment a{point(), point()};
    Segment b{point(), point()};
    if (i % 3 == 1) b.second = b.first + (a.second - a.first) * coordinate(random) + 1e-9 * point();  // near-parallel
    if (i % 3 == 2) b.second = b.first + (a.second - a.first) * coordinate(random);                   // parallel
    const SegmentProximity near = closest_points(a, b);
    const double reference = convex_search_distance(a, b);
    worst = std::max(worst, std::abs(near.distance - reference));
    ASSERT_NEAR(near.distance, reference, 1e-12) << "pair " << i;
    // The reported parameters are where that distance is.
    ASSERT_NEAR((point_on(a, near.first_parameter) - point_on(b, near.second_parameter)).norm(), near.distance, 1e-15);
  }
  std::printf("closest points: largest difference from the convex search over 3000 pairs %.3g\n", worst);
}

// ---------------------------------------------------------------- brute force over random configurations

struct Agreement {
  int configurations = 0;
  int hits = 0;            // by the CCD
  int agreed = 0;          // same verdict, and a hit lies in the first dip of the sampled distance
  int near_misses = 0;     // band: the sampled distance dips under the sampling threshold, never
                           // under the touching distance, and the CCD reports no contact there
  int failures = 0;
  double largest_time_gap = 0;  // |CCD time - first time within the touching distance|, agreed hits
  int time_gaps_over_1e6 = 0;
};

// Dense sampling of t (`samples` points) of the reference segment distance, against the CCD.
// Since every point moves at most `speed` (the blade's largest endpoint displacement plus the
// edge's), the distance is Lipschitz with constant `speed` in t, so a contact at t* shows up
// as a sample within threshold = touching + speed * spacing / 2 of it. Runs of samples under
// that threshold ("dips") are refined by golden section around their lowest sample.
void compare_with_brute_force(const MovingSegment& blade, const MovingSegment& edge, int samples, Agreement& tally,
                              const std::string& label) {
  ++tally.configurations;
  const double touching = touching_distance(blade, edge);
  auto displacement = [](const MovingSegment& m) {
    return std::max((m.at_end.first - m.at_start.first).norm(), (m.at_end.second - m.at_start.second).norm());
  };
  const double speed = displacement(blade) + displacement(edge);
  const double spacing = 1.0 / (samples - 1);
  const double threshold = touching + 0.5 * speed * spacing + 1e-12;
  auto distance_at = [&](double t) { return reference_distance(at(blade, t), at(edge, t)); };

  struct Dip {
    double start = 0;
    double end = 0;
    double lowest = 0;       // refined
    double lowest_time = 0;  // refined
  };
  std::vector<Dip> dips;
  int run_start = -1;
  int run_best = -1;
  double run_best_distance = 0;
  auto close_run = [&](int last) {
    const double ratio = (std::sqrt(5.0) - 1) / 2;
    double lo = std::max(0.0, (run_best - 1) * spacing);
    double hi = std::min(1.0, (run_best + 1) * spacing);
    for (int i = 0; i < 200 && hi - lo > 1e-16; ++i) {
      const double left = hi - ratio * (hi - lo);
      const double right = lo + ratio * (hi - lo);
      if (distance_at(left) <= distance_at(right)) hi = right; else lo = left;
    }
    Dip dip{run_start * spacing, last * spacing, std::min(distance_at(0.5 * (lo + hi)), run_best_distance),
            0.5 * (lo + hi)};
    if (run_best_distance <= dip.lowest) dip.lowest_time = run_best * spacing;
    dips.push_back(dip);
    run_start = -1;
  };
  for (int k = 0; k < samples; ++k) {
    const double d = distance_at(k * spacing);
    if (d <= threshold) {
      if (run_start < 0) {
        run_start = k;
        run_best = k;
        run_best_distance = d;
      } else if (d < run_best_distance) {
        run_best = k;
        run_best_distance = d;
      }
    } else if (run_start >= 0) {
      close_run(k - 1);
    }
  }
  if (run_start >= 0) close_run(samples - 1);

  const auto hit = first_edge_hit(blade, edge);
  auto fail = [&](const std::string& why) {
    ++tally.failures;
    if (tally.failures <= 5) ADD_FAILURE() << label << ": " << why;
  };
  if (hit) {
    ++tally.hits;
    if (!(distance_at(hit->time) <= touching * (1 + 1e-6) + 1e-15)) {
      fail("CCD hit at t = " + std::to_string(hit->time) + " where the distance is " +
           std::to_string(distance_at(hit->time)));
      return;
    }
    const double t = hit->time;
    auto holds = [&](const Dip& dip) { return t >= dip.start - spacing && t <= dip.end + spacing; };
    const auto containing = std::find_if(dips.begin(), dips.end(), holds);
    if (containing == dips.end()) {
      fail("CCD hit at t = " + std::to_string(t) + " with no sampled dip there");
      return;
    }
    for (auto earlier = dips.begin(); earlier != containing; ++earlier) {
      if (earlier->lowest <= touching) {
        fail("CCD hit at t = " + std::to_string(t) + " but contact already at t = " +
             std::to_string(earlier->lowest_time));
        return;
      }
    }
    if (containing != dips.begin()) {
      ++tally.near_misses;  // an earlier dip that never comes within the touching distance
      return;
    }
    ++tally.agreed;
    // The first time the distance comes within the touching distance, by bisection from the
    // dip's start, where it is above the sampling threshold (or t = 0), to the CCD's time.
    double before = std::max(0.0, containing->start - spacing);
    double after = t;
    if (distance_at(before) <= touching) {
      after = before;
    } else {
      for (int i = 0; i < 200 && after - before > 1e-16; ++i) {
        const double middle = 0.5 * (before + after);
        if (distance_at(middle) <= touching) after = middle; else before = middle;
      }
    }
    const double gap = std::abs(t - after);
    tally.largest_time_gap = std::max(tally.largest_time_gap, gap);
    if (gap > 1e-6) ++tally.time_gaps_over_1e6;
    return;
  }
  if (dips.empty()) {
    ++tally.agreed;
    return;
  }
  for (const Dip& dip : dips) {
    if (dip.lowest <= touching) {
      fail("CCD missed a contact at t = " + std::to_string(dip.lowest_time) + " (distance " +
           std::to_string(dip.lowest) + ", touching distance " + std::to_string(touching) + ")");
      return;
    }
  }
  ++tally.near_misses;
}

TEST(ContinuousCollision, AgreesWithDenseSamplingOnRandomConfigurations) {
  constexpr int samples = 20000;
  constexpr int per_family = 300;
  std::mt19937_64 random(4004);
  std::uniform_real_distribution<double> coordinate(-1, 1);
  auto point = [&] { return Vec3(coordinate(random), coordinate(random), coordinate(random)); };
  auto flat = [](Vec3 p) { p.z() = 0; return p; };

  struct Family {
    const char* name;
    std::function<std::pair<MovingSegment, MovingSegment>()> make;
  };
  const std::vector<Family> families = {
      {"general", [&] { return std::pair{moving(point(), point(), point(), point()), moving(point(), point(), point(), point())}; }},
      {"static blade", [&] {
         const Vec3 a = point(), b = point();
         return std::pair{fixed(a, b), moving(point(), point(), point(), point())};
       }},
      {"small motion", [&] {
         const Vec3 a = point(), b = point(), c = point(), d = point();
         return std::pair{moving(a, b, a + 0.2 * point(), b + 0.2 * point()), moving(c, d, c + 0.2 * point(), d + 0.2 * point())};
       }},
      {"planar", [&] {
         return std::pair{moving(flat(point()), flat(point()), flat(point()), flat(point())),
                          moving(flat(point()), flat(point()), flat(point()), flat(point()))};
       }},
      {"near-planar (z noise 1e-10)", [&] {
         auto noisy = [&] { Vec3 p = flat(point()); p.z() = 1e-10 * coordinate(random); return p; };
         return std::pair{moving(noisy(), noisy(), noisy(), noisy()), moving(noisy(), noisy(), noisy(), noisy())};
       }},
      {"parallel, planar", [&] {
         const Vec3 a0 = flat(point()), b0 = flat(point()), a1 = flat(point()), b1 = flat(point());
         const double ratio = coordinate(random);
         const Vec3 q0 = flat(point()), q1 = flat(point());
         return std::pair{moving(a0, b0, a1, b1), moving(q0, q0 + ratio * (b0 - a0), q1, q1 + ratio * (b1 - a1))};
       }},
      {"parallel, 3D", [&] {
         const Vec3 a0 = point(), b0 = point(), a1 = point(), b1 = point();
         const double ratio = coordinate(random);
         const Vec3 q0 = point(), q1 = point();
         return std::pair{moving(a0, b0, a1, b1), moving(q0, q0 + ratio * (b0 - a0), q1, q1 + ratio * (b1 - a1))};
       }},
      {"point blade, planar", [&] {
         const Vec3 a = flat(point()), b = flat(point());
         return std::pair{moving(a, a, b, b), moving(flat(point()), flat(point()), flat(point()), flat(point()))};
       }},
  };
  int total_hits = 0;
  for (const Family& family : families) {
    Agreement tally;
    for (int i = 0; i < per_family; ++i) {
      const auto [blade, edge] = family.make();
      compare_with_brute_force(blade, edge, samples, tally, std::string(family.name) + " #" + std::to_string(i));
    }
    std::printf("brute force, %-28s %d configurations: %d CCD hits, %d agree, %d near misses (band), %d failures; "
                "largest |t_ccd - t_first_touch| %.2g (%d over 1e-6)\n",
                family.name, tally.configurations, tally.hits, tally.agreed, tally.near_misses, tally.failures,
                tally.largest_time_gap, tally.time_gaps_over_1e6);
    EXPECT_EQ(tally.failures, 0) << family.name;
    EXPECT_EQ(tally.agreed + tally.near_misses, tally.configurations) << family.name;
    // The band is the set of configurations whose sampled distance comes within
    // speed * spacing / 2 (about 1e-4 here) without touching: a small fraction.
    EXPECT_LE(tally.near_misses, per_family / 50) << family.name;
    // The CCD's time is the exact contact's, the reference's the first within the touching
    // distance: apart by touching distance / approach speed, except for grazing contacts.
    EXPECT_LE(tally.time_gaps_over_1e6, per_family / 50) << family.name;
    total_hits += tally.hits;
  }
  EXPECT_GT(total_hits, per_family);  // the families do exercise hits, not only misses
}

// ---------------------------------------------------------------- broad phase

struct EdgeSet {
  std::vector<MovingSegment> edges;
};

EdgeSet random_edges(std::mt19937_64& random, int count, double length, double motion) {
  std::uniform_real_distribution<double> unit(-1, 1);
  auto point = [&] { return Vec3(unit(random), unit(random), unit(random)); };
  EdgeSet set;
  for (int i = 0; i < count; ++i) {
    const Vec3 a = point();
    const Vec3 b = a + length * point();
    set.edges.push_back(moving(a, b, a + motion * point(), b + motion * point()));
  }
  return set;
}

// Moves every edge on: its end becomes its start, and it moves again by up to `motion`.
void advance(std::mt19937_64& random, EdgeSet& set, double motion) {
  std::uniform_real_distribution<double> unit(-1, 1);
  for (MovingSegment& edge : set.edges) {
    edge.at_start = edge.at_end;
    edge.at_end.first += motion * Vec3(unit(random), unit(random), unit(random));
    edge.at_end.second += motion * Vec3(unit(random), unit(random), unit(random));
  }
}

bool boxes_overlap(const MovingSegment& a, const MovingSegment& b, double grow) {
  auto lower = [](const MovingSegment& m) {
    return m.at_start.first.cwiseMin(m.at_start.second).cwiseMin(m.at_end.first).cwiseMin(m.at_end.second);
  };
  auto upper = [](const MovingSegment& m) {
    return m.at_start.first.cwiseMax(m.at_start.second).cwiseMax(m.at_end.first).cwiseMax(m.at_end.second);
  };
  return ((lower(a).array() <= upper(b).array() + grow) && (lower(b).array() - grow <= upper(a).array())).all();
}

TEST(EdgeBroadPhase, CandidatesContainEveryHitBeforeAndAfterRefitting) {
  std::mt19937_64 random(77);
  std::uniform_real_distribution<double> unit(-1, 1);
  EdgeSet set = random_edges(random, 600, 0.15, 0.05);
  const double margin = 1e-6;  // above the touching distance (1e-8 of a size below 2)
  const double slack = 0.02;
  EdgeBroadPhase broad(margin, slack);
  for (int id = 0; id < static_cast<int>(set.edges.size()); ++id) EXPECT_TRUE(broad.set_edge(3 * id + 1, set.edges[id]));
  EXPECT_EQ(broad.edge_count(), 600);

  std::vector<int> candidates;
  std::vector<int> polyline_candidates;
  int hits = 0;
  int candidate_total = 0;
  int refits = 0;
  for (int step = 0; step < 6; ++step) {
    // A three-segment blade sweeping through the middle of the cloud.
    std::vector<Vec3> blade_start;
    std::vector<Vec3> blade_end;
    for (int i = 0; i < 4; ++i) {
      const Vec3 p(-0.6 + 0.4 * i, 0.3 * unit(random), 0.2 * unit(random));
      blade_start.push_back(p);
      blade_end.push_back(p + Vec3(0.1 * unit(random), 0.3, 0.1 * unit(random)));
    }
    std::set<int> union_of_hits;
    for (int segment = 0; segment < 3; ++segment) {
      const MovingSegment blade = moving(blade_start[segment], blade_start[segment + 1], blade_end[segment],
                                         blade_end[segment + 1]);
      broad.query(blade, candidates);
      ASSERT_TRUE(std::is_sorted(candidates.begin(), candidates.end()));
      ASSERT_TRUE(std::adjacent_find(candidates.begin(), candidates.end()) == candidates.end());
      candidate_total += static_cast<int>(candidates.size());
      for (int index = 0; index < static_cast<int>(set.edges.size()); ++index) {
        const int id = 3 * index + 1;
        const bool candidate = std::binary_search(candidates.begin(), candidates.end(), id);
        if (first_edge_hit(blade, set.edges[index])) {
          ++hits;
          union_of_hits.insert(id);
          EXPECT_TRUE(candidate) << "step " << step << ", blade segment " << segment << ": edge " << id
                                 << " is hit but not a candidate";
        }
        // Every box that overlaps is a candidate; on the first step, when the stored boxes are
        // the fresh ones grown by margin + slack, only those (up to float rounding).
        if (boxes_overlap(blade, set.edges[index], margin)) {
          EXPECT_TRUE(candidate) << "edge " << id;
        }
        if (step == 0 && candidate) {
          EXPECT_TRUE(boxes_overlap(blade, set.edges[index], margin + slack + 1e-5)) << "edge " << id;
        }
      }
    }
    broad.query(blade_start, blade_end, polyline_candidates);
    ASSERT_TRUE(std::is_sorted(polyline_candidates.begin(), polyline_candidates.end()));
    ASSERT_TRUE(std::adjacent_find(polyline_candidates.begin(), polyline_candidates.end()) == polyline_candidates.end());
    for (int id : union_of_hits) {
      EXPECT_TRUE(std::binary_search(polyline_candidates.begin(), polyline_candidates.end(), id));
    }
    EXPECT_LT(static_cast<int>(polyline_candidates.size()), broad.edge_count() / 2) << "the tree prunes";

    // Next step: every edge moves on; the tree is refitted where the fat boxes no longer hold.
    advance(random, set, 0.05);
    for (int index = 0; index < static_cast<int>(set.edges.size()); ++index) {
      refits += broad.set_edge(3 * index + 1, set.edges[index]) ? 1 : 0;
    }
    broad.rebalance(2);
  }
  std::printf("broad phase: 600 edges, 6 steps x 3 blade segments: %d CCD hits, %.1f candidates per query, "
              "%d refits of %d edge updates\n",
              hits, candidate_total / 18.0, refits, 6 * 600);
  EXPECT_GT(hits, 0);
  EXPECT_LT(refits, 6 * 600) << "the slack spares some updates";

  // A removed edge is never a candidate again.
  const MovingSegment everywhere = moving({-2, -2, -2}, {2, 2, 2}, {-2, -2, -2}, {2, 2, 2});
  broad.query(everywhere, candidates);
  EXPECT_EQ(static_cast<int>(candidates.size()), 600);
  broad.remove_edge(4);
  EXPECT_FALSE(broad.contains(4));
  EXPECT_TRUE(broad.contains(7));
  broad.query(everywhere, candidates);
  EXPECT_EQ(static_cast<int>(candidates.size()), 599);
  EXPECT_FALSE(std::binary_search(candidates.begin(), candidates.end(), 4));
}

TEST(EdgeBroadPhase, ResultsAreDeterministicAndQueriesReuseMemory) {
  std::mt19937_64 random(5);
  const EdgeSet set = random_edges(random, 400, 0.2, 0.1);
  EdgeBroadPhase forward(1e-6);
  EdgeBroadPhase backward(1e-6);
  for (int i = 0; i < 400; ++i) forward.set_edge(i, set.edges[i]);
  for (int i = 399; i >= 0; --i) backward.set_edge(i, set.edges[i]);
  backward.rebalance(5);

  const std::vector<Vec3> start = {{-1, -0.2, 0}, {0, -0.2, 0.1}, {1, -0.2, 0}};
  const std::vector<Vec3> end = {{-1, 0.2, 0}, {0, 0.2, -0.1}, {1, 0.2, 0}};
  std::vector<int> first;
  std::vector<int> again;
  std::vector<int> other;
  forward.query(start, end, first);
  forward.query(start, end, again);
  backward.query(start, end, other);
  EXPECT_FALSE(first.empty());
  EXPECT_EQ(first, again);
  EXPECT_EQ(first, other) << "the candidate set does not depend on the tree's shape";

  // Warm: the same queries again use the same buffer (no reallocation) and give the same ids.
  const int* buffer = again.data();
  const std::size_t capacity = again.capacity();
  for (int repeat = 0; repeat < 100; ++repeat) forward.query(start, end, again);
  EXPECT_EQ(again.data(), buffer);
  EXPECT_EQ(again.capacity(), capacity);
  EXPECT_EQ(first, again);

  // Moving the whole broad phase keeps its edges.
  EdgeBroadPhase moved = std::move(forward);
  moved.query(start, end, again);
  EXPECT_EQ(first, again);
}

// A copy holds the same fat boxes in a tree of its own: after refits (some edges re-boxed,
// some not), a removal and a rebalance, it answers every query and set_edge as the original
// does, and changing one leaves the other as it was.
TEST(EdgeBroadPhase, ACopyAnswersAsTheOriginalAndIsIndependent) {
  std::mt19937_64 random(11);
  EdgeSet set = random_edges(random, 300, 0.2, 0.05);
  EdgeBroadPhase original(1e-6, 0.02);
  for (int i = 0; i < 300; ++i) original.set_edge(2 * i, set.edges[i]);
  advance(random, set, 0.05);
  for (int i = 0; i < 300; ++i) original.set_edge(2 * i, set.edges[i]);
  original.remove_edge(10);
  original.rebalance(3);

  EdgeBroadPhase copy(original);
  EXPECT_EQ(copy.edge_count(), original.edge_count());
  EXPECT_FALSE(copy.contains(10));
  const auto same_answers = [&](EdgeBroadPhase& a, EdgeBroadPhase& b) {
    std::vector<int> from_a, from_b;
    for (int q = 0; q < 20; ++q) {
      const Vec3 p(0.8 * (q / 10.0 - 1), 0.1 * q / 20.0, 0);
      const std::vector<Vec3> start = {p + Vec3(0, -0.3, 0), p + Vec3(0.3, -0.3, 0.1)};
      const std::vector<Vec3> end = {p + Vec3(0, 0.3, 0), p + Vec3(0.3, 0.3, -0.1)};
      a.query(start, end, from_a);
      b.query(start, end, from_b);
      if (from_a != from_b) return false;
    }
    return true;
  };
  EXPECT_TRUE(same_answers(original, copy));
  // The next refit: the same edges need a new box in both (set_edge compares with the stored one).
  advance(random, set, 0.05);
  for (int i = 0; i < 300; ++i) {
    if (i == 5) continue;  // edge 10 is gone from both
    EXPECT_EQ(copy.set_edge(2 * i, set.edges[i]), original.set_edge(2 * i, set.edges[i])) << "edge " << 2 * i;
  }
  EXPECT_TRUE(same_answers(original, copy));
  // Independent: what the copy removes the original keeps.
  copy.remove_edge(0);
  EXPECT_TRUE(original.contains(0));
  EXPECT_EQ(original.edge_count(), copy.edge_count() + 1);
  EdgeBroadPhase assigned(1.0);
  assigned = original;
  EXPECT_TRUE(same_answers(original, assigned));
}

}  // namespace
}  // namespace incise::physics
