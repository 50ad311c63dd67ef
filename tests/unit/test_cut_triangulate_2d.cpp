// The 2D constrained Delaunay triangulation of physics/cut/triangulate_2d.hpp, checked
// against properties rather than stored outputs: exact cover of the region (areas, edge
// pairing, boundary edges in their direction), every free point inside used and none
// outside, and the empty-circle test across every non-boundary edge.
//
// The checks are independent of the library: orientation, incircle and point-in-region
// are evaluated here in exact big-integer arithmetic (each double is an integer times a
// power of two), not with the library's floating-point expansions; point-in-region is a
// winding number over the boundary edges.
#include "physics/cut/triangulate_2d.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace incise::physics {
namespace {

// ---------------------------------------------------------------------------------------
// A small signed big integer: magnitude in 32-bit limbs, least significant first.
// ---------------------------------------------------------------------------------------
struct BigInt {
  bool negative = false;
  std::vector<std::uint32_t> limbs;  // no leading zero limbs; empty is zero

  int sign() const { return limbs.empty() ? 0 : (negative ? -1 : 1); }
};

void trim(std::vector<std::uint32_t>& limbs) {
  while (!limbs.empty() && limbs.back() == 0) limbs.pop_back();
}

int compare_magnitude(const std::vector<std::uint32_t>& a, const std::vector<std::uint32_t>& b) {
  if (a.size() != b.size()) return a.size() < b.size() ? -1 : 1;
  for (std::size_t i = a.size(); i-- > 0;) {
    if (a[i] != b[i]) return a[i] < b[i] ? -1 : 1;
  }
  return 0;
}

std::vector<std::uint32_t> add_magnitude(const std::vector<std::uint32_t>& a, const std::vector<std::uint32_t>& b) {
  std::vector<std::uint32_t> out(std::max(a.size(), b.size()) + 1, 0);
  std::uint64_t carry = 0;
  for (std::size_t i = 0; i < out.size(); ++i) {
    std::uint64_t s = carry;
    if (i < a.size()) s += a[i];
    if (i < b.size()) s += b[i];
    out[i] = static_cast<std::uint32_t>(s);
    carry = s >> 32;
  }
  trim(out);
  return out;
}

// |a| >= |b| required.
std::vector<std::uint32_t> subtract_magnitude(const std::vector<std::uint32_t>& a, const std::vector<std::uint32_t>& b) {
  std::vector<std::uint32_t> out(a.size(), 0);
  std::int64_t borrow = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    std::int64_t d = static_cast<std::int64_t>(a[i]) - borrow - (i < b.size() ? static_cast<std::int64_t>(b[i]) : 0);
    borrow = d < 0 ? 1 : 0;
    if (d < 0) d += (std::int64_t{1} << 32);
    out[i] = static_cast<std::uint32_t>(d);
  }
  trim(out);
  return out;
}

BigInt operator+(const BigInt& a, const BigInt& b) {
  BigInt out;
  if (a.negative == b.negative) {
    out.limbs = add_magnitude(a.limbs, b.limbs);
    out.negative = a.negative;
  } else if (compare_magnitude(a.limbs, b.limbs) >= 0) {
    out.limbs = subtract_magnitude(a.limbs, b.limbs);
    out.negative = a.negative;
  } else {
    out.limbs = subtract_magnitude(b.limbs, a.limbs);
    out.negative = b.negative;
  }
  if (out.limbs.empty()) out.negative = false;
  return out;
}

BigInt operator-(const BigInt& a) {
  BigInt out = a;
  if (!out.limbs.empty()) out.negative = !out.negative;
  return out;
}

BigInt operator-(const BigInt& a, const BigInt& b) { return a + (-b); }

BigInt operator*(const BigInt& a, const BigInt& b) {
  BigInt out;
  if (a.limbs.empty() || b.limbs.empty()) return out;
  out.limbs.assign(a.limbs.size() + b.limbs.size(), 0);
  for (std::size_t i = 0; i < a.limbs.size(); ++i) {
    std::uint64_t carry = 0;
    for (std::size_t j = 0; j < b.limbs.size(); ++j) {
      const std::uint64_t cur = out.limbs[i + j] + static_cast<std::uint64_t>(a.limbs[i]) * b.limbs[j] + carry;
      out.limbs[i + j] = static_cast<std::uint32_t>(cur);
      carry = cur >> 32;
    }
    std::size_t k = i + b.limbs.size();
    while (carry != 0) {
      const std::uint64_t cur = out.limbs[k] + carry;
      out.limbs[k] = static_cast<std::uint32_t>(cur);
      carry = cur >> 32;
      ++k;
    }
  }
  trim(out.limbs);
  out.negative = a.negative != b.negative;
  return out;
}

// Coordinates as exact integers on a common power-of-two grid: x = m 2^e with an integer
// mantissa m, shifted onto the smallest exponent among the inputs of one predicate.
std::vector<BigInt> to_common_grid(const std::vector<double>& values) {
  int lowest = std::numeric_limits<int>::max();
  for (double v : values) {
    if (v == 0.0) continue;
    int exponent = 0;
    std::frexp(v, &exponent);
    lowest = std::min(lowest, exponent - 53);
  }
  std::vector<BigInt> out(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) {
    const double v = values[i];
    if (v == 0.0) continue;
    int exponent = 0;
    const double fraction = std::frexp(std::abs(v), &exponent);
    const auto mantissa = static_cast<std::uint64_t>(std::ldexp(fraction, 53));  // exact, < 2^53
    const int shift = exponent - 53 - lowest;
    BigInt m;
    m.limbs = {static_cast<std::uint32_t>(mantissa), static_cast<std::uint32_t>(mantissa >> 32)};
    trim(m.limbs);
    BigInt power;
    power.limbs.assign(static_cast<std::size_t>(shift / 32) + 1, 0);
    power.limbs.back() = std::uint32_t{1} << (shift % 32);
    out[i] = m * power;
    out[i].negative = v < 0.0;
  }
  return out;
}

int exact_orient(const Vec2& a, const Vec2& b, const Vec2& c) {
  const auto g = to_common_grid({a.x(), a.y(), b.x(), b.y(), c.x(), c.y()});
  return ((g[0] - g[4]) * (g[3] - g[5]) - (g[1] - g[5]) * (g[2] - g[4])).sign();
}

// > 0 when d is strictly inside the circle through the counter-clockwise a, b, c.
int exact_incircle(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  const auto g = to_common_grid({a.x(), a.y(), b.x(), b.y(), c.x(), c.y(), d.x(), d.y()});
  const BigInt adx = g[0] - g[6], ady = g[1] - g[7];
  const BigInt bdx = g[2] - g[6], bdy = g[3] - g[7];
  const BigInt cdx = g[4] - g[6], cdy = g[5] - g[7];
  const BigInt det = (adx * adx + ady * ady) * (bdx * cdy - cdx * bdy) +
                     (bdx * bdx + bdy * bdy) * (cdx * ady - adx * cdy) +
                     (cdx * cdx + cdy * cdy) * (adx * bdy - bdx * ady);
  return det.sign();
}

// Winding number of the boundary around p (exact orientation; p must not be on it).
int winding_number(const PlanarRegion& region, const Vec2& p) {
  int winding = 0;
  for (const auto& [from, to] : region.boundary) {
    const Vec2& a = region.points[from];
    const Vec2& b = region.points[to];
    if (a.y() <= p.y()) {
      if (b.y() > p.y() && exact_orient(a, b, p) > 0) ++winding;
    } else if (b.y() <= p.y() && exact_orient(a, b, p) < 0) {
      --winding;
    }
  }
  return winding;
}

// Relative to one of its points, so a region far from the origin keeps its digits.
double shoelace_area(const PlanarRegion& region) {
  double area = 0.0;
  if (region.boundary.empty()) return area;
  const Vec2 reference = region.points[region.boundary[0][0]];
  for (const auto& [from, to] : region.boundary) {
    const Vec2 a = region.points[from] - reference;
    const Vec2 b = region.points[to] - reference;
    area += 0.5 * (a.x() * b.y() - a.y() * b.x());
  }
  return area;
}

// Every property the header promises, checked independently of the library.
::testing::AssertionResult is_constrained_delaunay_cover(const PlanarRegion& region,
                                                        const std::vector<std::array<int, 3>>& triangles) {
  const int n = static_cast<int>(region.points.size());
  double area = 0.0;
  std::map<std::pair<int, int>, int> directed;
  std::map<std::pair<int, int>, int> opposite_vertex;
  std::vector<char> used(n, 0);
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    const auto& tri = triangles[t];
    for (int v : tri) {
      if (v < 0 || v >= n) return ::testing::AssertionFailure() << "triangle " << t << " has index " << v;
      used[v] = 1;
    }
    const Vec2& a = region.points[tri[0]];
    const Vec2& b = region.points[tri[1]];
    const Vec2& c = region.points[tri[2]];
    if (exact_orient(a, b, c) <= 0)
      return ::testing::AssertionFailure() << "triangle " << t << " (" << tri[0] << ", " << tri[1] << ", " << tri[2]
                                           << ") is not counter-clockwise with positive area";
    area += 0.5 * ((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x());
    for (int k = 0; k < 3; ++k) {
      const std::pair<int, int> edge(tri[k], tri[(k + 1) % 3]);
      ++directed[edge];
      opposite_vertex[edge] = tri[(k + 2) % 3];
    }
  }
  const double expected_area = shoelace_area(region);
  if (!(std::abs(area - expected_area) <= 1e-12 * std::abs(expected_area)))
    return ::testing::AssertionFailure() << "area " << area << " differs from the region's " << expected_area;

  std::set<std::pair<int, int>> boundary;
  std::vector<char> on_boundary(n, 0);
  for (const auto& [from, to] : region.boundary) {
    boundary.emplace(from, to);
    on_boundary[from] = on_boundary[to] = 1;
    const auto forward = directed.find({from, to});
    if (forward == directed.end() || forward->second != 1)
      return ::testing::AssertionFailure() << "boundary edge " << from << " -> " << to << " is not used exactly once";
    if (directed.count({to, from}) != 0)
      return ::testing::AssertionFailure() << "boundary edge " << from << " -> " << to << " is used reversed";
  }
  for (const auto& [edge, count] : directed) {
    if (boundary.count(edge) != 0) continue;
    const auto reverse = directed.find({edge.second, edge.first});
    if (count != 1 || reverse == directed.end() || reverse->second != 1)
      return ::testing::AssertionFailure() << "edge " << edge.first << " -> " << edge.second << " is used " << count
                                           << " times and its reverse "
                                           << (reverse == directed.end() ? 0 : reverse->second) << " times";
    // Constrained Delaunay: the vertex across the edge is not strictly inside this
    // triangle's circumcircle.
    const int across = opposite_vertex.at({edge.second, edge.first});
    const Vec2& a = region.points[edge.first];
    const Vec2& b = region.points[edge.second];
    const Vec2& c = region.points[opposite_vertex.at(edge)];
    if (exact_incircle(a, b, c, region.points[across]) > 0)
      return ::testing::AssertionFailure() << "edge " << edge.first << " -> " << edge.second << " fails the empty-circle test: "
                                           << across << " is inside the circle of (" << edge.first << ", " << edge.second
                                           << ", " << opposite_vertex.at(edge) << ")";
  }
  for (int v = 0; v < n; ++v) {
    if (on_boundary[v]) continue;
    const bool inside = winding_number(region, region.points[v]) > 0;
    if (inside && !used[v]) return ::testing::AssertionFailure() << "point " << v << " is inside but not a vertex";
    if (!inside && used[v]) return ::testing::AssertionFailure() << "point " << v << " is outside but used";
  }
  return ::testing::AssertionSuccess();
}

// Appends a closed loop through the given points (in order) to the region.
void add_loop(PlanarRegion& region, const std::vector<Vec2>& loop) {
  const int first = static_cast<int>(region.points.size());
  const int count = static_cast<int>(loop.size());
  for (int i = 0; i < count; ++i) {
    region.points.push_back(loop[i]);
    region.boundary.push_back({first + i, first + (i + 1) % count});
  }
}

std::vector<Vec2> reversed(std::vector<Vec2> loop) {
  std::reverse(loop.begin(), loop.end());
  return loop;
}

std::vector<Vec2> rectangle(double x0, double y0, double x1, double y1) {
  return {Vec2(x0, y0), Vec2(x1, y0), Vec2(x1, y1), Vec2(x0, y1)};
}

// Triangulates, checks, and checks that a second run gives the same output.
void expect_valid(const PlanarRegion& region) {
  const auto triangles = triangulate_region(region);
  EXPECT_FALSE(triangles.empty());
  EXPECT_TRUE(is_constrained_delaunay_cover(region, triangles));
  EXPECT_EQ(triangles, triangulate_region(region)) << "not deterministic";
}

std::string message_of(const PlanarRegion& region) {
  try {
    triangulate_region(region);
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  return "(no exception)";
}

// ---------------------------------------------------------------------------------------
// The predicates.
// ---------------------------------------------------------------------------------------
TEST(Triangulate2d, PredicatesGiveTheExactSignOnNearlyDegenerateInput) {
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int zero_orient = 0;
  int zero_incircle = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    // Points on a line (or circle) then nudged by a few ulps, or not at all.
    Vec2 a(unit(random), unit(random));
    Vec2 direction(unit(random) - 0.5, unit(random) - 0.5);
    double nudge = std::ldexp(unit(random) - 0.5, -50);
    if (trial % 3 == 0) {  // on a 2^-10 grid the points below are exactly collinear
      a = (a * 1024.0).array().round() / 1024.0;
      direction = (direction * 1024.0).array().round() / 1024.0;
      nudge = 0.0;
    }
    const Vec2 b = a + 0.75 * direction;
    const Vec2 c = a + 0.25 * direction + Vec2(nudge, 0.0);
    const int expected = exact_orient(a, b, c);
    zero_orient += expected == 0;
    const double got = orient2d(a, b, c);
    ASSERT_EQ((got > 0) - (got < 0), expected) << "orient2d, trial " << trial;

    const double angle0 = 2.0 * std::numbers::pi * unit(random);
    const Vec2 centre(unit(random), unit(random));
    auto on_circle = [&](double angle) { return Vec2(centre + Vec2(std::cos(angle), std::sin(angle))); };
    const Vec2 p = on_circle(angle0), q = on_circle(angle0 + 1.0), r = on_circle(angle0 + 2.5);
    const Vec2 s = on_circle(angle0 + 4.0) + Vec2(nudge, -nudge);
    const int expected_circle = exact_incircle(p, q, r, s);
    const double got_circle = incircle(p, q, r, s);
    ASSERT_EQ((got_circle > 0) - (got_circle < 0), expected_circle) << "incircle, trial " << trial;
  }
  // Lattice points are cocircular exactly: the filter cannot decide, the exact path must say 0.
  for (int i = 0; i < 100; ++i) {
    const Vec2 base(0.1 * i, 0.3 * i);
    const double h = 0.1;
    const int expected = exact_incircle(base, base + Vec2(h, 0), base + Vec2(h, h), base + Vec2(0, h));
    zero_incircle += expected == 0;
    EXPECT_EQ(incircle(base, base + Vec2(h, 0), base + Vec2(h, h), base + Vec2(0, h)) == 0.0, expected == 0);
  }
  EXPECT_GT(zero_orient, 0) << "no exactly collinear case was exercised";
  EXPECT_GT(zero_incircle, 0) << "no exactly cocircular case was exercised";
}

// ---------------------------------------------------------------------------------------
// Regions.
// ---------------------------------------------------------------------------------------
TEST(Triangulate2d, CoversAConvexPolygonWithFreePointsInside) {
  PlanarRegion region;
  std::vector<Vec2> loop;
  for (int i = 0; i < 12; ++i) {
    const double angle = 2.0 * std::numbers::pi * i / 12.0;
    loop.emplace_back(std::cos(angle), std::sin(angle));
  }
  add_loop(region, loop);
  region.points.emplace_back(0.1, 0.2);
  region.points.emplace_back(-0.4, 0.3);
  region.points.emplace_back(0.0, -0.5);
  expect_valid(region);
  // A convex polygon with h free points inside: 2 (boundary + free) - boundary - 2 triangles.
  EXPECT_EQ(triangulate_region(region).size(), 12u + 2u * 3u - 2u);
}

TEST(Triangulate2d, CoversANonConvexCombWithDeepNotches) {
  PlanarRegion region;
  // Bottom and right side, then the top from right to left with a V notch down to y = 1
  // in the middle of each of five 2-wide teeth' gaps.
  std::vector<Vec2> loop = {Vec2(0, 0), Vec2(10, 0), Vec2(10, 5)};
  for (int tooth = 4; tooth >= 0; --tooth) {
    const double x = 2.0 * tooth;
    loop.emplace_back(x + 1.5, 5.0);
    loop.emplace_back(x + 1.0, 1.0);
    loop.emplace_back(x + 0.5, 5.0);
    loop.emplace_back(x, 5.0);
  }
  add_loop(region, loop);
  for (int tooth = 0; tooth < 5; ++tooth) {
    region.points.emplace_back(2.0 * tooth + 0.25, 4.0);  // between two notches: inside
    region.points.emplace_back(2.0 * tooth + 1.0, 4.0);   // in a notch: outside
  }
  expect_valid(region);
}

TEST(Triangulate2d, CoversASpiralBandWoundTwice) {
  PlanarRegion region;
  std::vector<Vec2> outer;
  std::vector<Vec2> inner;
  const int steps = 160;
  for (int i = 0; i <= steps; ++i) {
    const double angle = 4.0 * std::numbers::pi * i / steps;
    const double radius = 1.0 + 0.3 * angle;  // gains 1.88 a turn; the band is 1.2 wide
    outer.emplace_back((radius + 1.2) * std::cos(angle), (radius + 1.2) * std::sin(angle));
    inner.emplace_back(radius * std::cos(angle), radius * std::sin(angle));
  }
  std::vector<Vec2> loop = outer;
  for (int i = steps; i >= 0; --i) loop.push_back(inner[i]);
  add_loop(region, loop);
  ASSERT_GT(shoelace_area(region), 0.0);
  expect_valid(region);
}

TEST(Triangulate2d, CoversASquareWithAHoleExactly) {
  PlanarRegion region;
  add_loop(region, rectangle(0, 0, 4, 4));
  add_loop(region, reversed(rectangle(1, 1, 2, 3)));
  add_loop(region, reversed(rectangle(2.5, 0.5, 3.5, 1.5)));
  region.points.emplace_back(1.5, 2.0);  // inside the first hole: unused
  region.points.emplace_back(3.0, 3.0);  // inside the region
  expect_valid(region);
}

TEST(Triangulate2d, CoversTwoDisjointComponentsOneWithAnIsland) {
  PlanarRegion region;
  add_loop(region, rectangle(0, 0, 3, 3));
  add_loop(region, reversed(rectangle(1, 1, 2, 2)));
  add_loop(region, rectangle(1.25, 1.25, 1.75, 1.75));  // an island in the hole
  add_loop(region, rectangle(5, 0, 6, 1));
  region.points.emplace_back(4.0, 0.5);  // between the components
  expect_valid(region);
}

TEST(Triangulate2d, UsesHundredsOfRandomFreePointsInsideAndIgnoresThoseOutside) {
  std::mt19937_64 random(11);
  std::uniform_real_distribution<double> coordinate(-0.5, 1.5);
  PlanarRegion region;
  add_loop(region, rectangle(0, 0, 1, 1));
  add_loop(region, reversed(rectangle(0.3, 0.3, 0.6, 0.5)));
  for (int i = 0; i < 600; ++i) region.points.emplace_back(coordinate(random), coordinate(random));
  int inside = 0;
  for (std::size_t v = 8; v < region.points.size(); ++v) inside += winding_number(region, region.points[v]) > 0;
  ASSERT_GT(inside, 100);
  ASSERT_LT(inside, 500);
  expect_valid(region);
}

TEST(Triangulate2d, TriangulatesASquareLatticeWhereEveryQuadIsCocircular) {
  PlanarRegion region;
  const int size = 12;
  std::vector<Vec2> loop;
  for (int i = 0; i < size; ++i) loop.emplace_back(i, 0);
  for (int i = 0; i < size; ++i) loop.emplace_back(size, i);
  for (int i = size; i > 0; --i) loop.emplace_back(i, size);
  for (int i = size; i > 0; --i) loop.emplace_back(0, i);
  add_loop(region, loop);
  add_loop(region, reversed(rectangle(4, 4, 6, 7)));  // a hole on lattice lines too
  for (int x = -2; x <= size + 2; ++x) {
    for (int y = -2; y <= size + 2; ++y) {
      const bool on_outer = (x >= 0 && x <= size && (y == 0 || y == size)) || (y >= 0 && y <= size && (x == 0 || x == size));
      const bool on_hole = (x >= 4 && x <= 6 && (y == 4 || y == 7)) || (y >= 4 && y <= 7 && (x == 4 || x == 6));
      if (!on_outer && !on_hole) region.points.emplace_back(x, y);
    }
  }
  expect_valid(region);
  // Scaled by a non-power of two the lattice is no longer exact in binary: still valid.
  for (Vec2& p : region.points) p *= 0.1;
  expect_valid(region);
}

TEST(Triangulate2d, HandlesBoundaryPointsNearlyCollinearToOneUlp) {
  std::mt19937_64 random(5);
  std::uniform_int_distribution<int> choice(-1, 1);
  PlanarRegion region;
  std::vector<Vec2> loop;
  const int count = 60;
  // The bottom and the right side: many points within 1e-15 (relative) of the straight line.
  for (int i = 0; i < count; ++i) loop.emplace_back(static_cast<double>(i) / count, 1e-15 * choice(random));
  for (int i = 0; i < count; ++i) loop.emplace_back(1.0 + 1e-15 * choice(random), static_cast<double>(i) / count);
  loop.emplace_back(1.0, 1.0);
  loop.emplace_back(0.0, 1.0);
  add_loop(region, loop);
  // Free points just above and below the bottom line.
  for (int i = 0; i < 20; ++i) {
    region.points.emplace_back((i + 0.5) / 20.0, 2e-15 * choice(random) + 1e-16);
    region.points.emplace_back((i + 0.5) / 20.0, 0.5);
  }
  expect_valid(region);
}

// Free points rounded onto a circle and onto a line: nearly every quadruple is cocircular
// and every triple collinear to within rounding, where only the exact predicates decide.
TEST(Triangulate2d, HandlesFreePointsRoundedOntoACircleAndALine) {
  PlanarRegion region;
  add_loop(region, rectangle(-2, -2, 2, 2));
  const int count = 256;
  for (int i = 0; i < count; ++i) {
    const double angle = 2.0 * std::numbers::pi * i / count + 0.1;
    region.points.emplace_back(1.3 * std::cos(angle), 1.3 * std::sin(angle));
  }
  for (int i = 0; i < 100; ++i) {
    const double x = -1.9 + 3.8 * i / 100.0 + 0.001;
    region.points.emplace_back(x, 0.3 * x + 0.1);
  }
  expect_valid(region);
}

TEST(Triangulate2d, CoversAThinSliverOfAspectOneInAMillion) {
  PlanarRegion region;
  std::vector<Vec2> loop;
  const int count = 50;
  const double height = 1e-6;
  for (int i = 0; i < count; ++i) loop.emplace_back(static_cast<double>(i) / count, 0.0);
  for (int i = count; i > 0; --i) loop.emplace_back(static_cast<double>(i) / count - 0.5 / count, height);
  add_loop(region, loop);
  for (int i = 0; i < 30; ++i) region.points.emplace_back((i + 0.3) / 30.0, 0.5 * height);
  expect_valid(region);
}

TEST(Triangulate2d, CoversRandomStarShapedPolygonsWithFreePointsForManySeeds) {
  for (unsigned seed = 0; seed < 150; ++seed) {
    std::mt19937_64 random(seed);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    // One angle per equal sector keeps every angular gap below pi, so the polygon is
    // simple and star-shaped around the origin.
    const int count = 4 + static_cast<int>(unit(random) * 60);
    std::vector<Vec2> loop;
    for (int i = 0; i < count; ++i) {
      const double angle = 2.0 * std::numbers::pi * (i + unit(random)) / count;
      const double radius = 0.1 + unit(random);
      loop.emplace_back(radius * std::cos(angle), radius * std::sin(angle));
    }
    PlanarRegion region;
    add_loop(region, loop);
    ASSERT_GT(shoelace_area(region), 0.0);
    const int free_points = static_cast<int>(unit(random) * 80);
    for (int i = 0; i < free_points; ++i) region.points.emplace_back(2.2 * unit(random) - 1.1, 2.2 * unit(random) - 1.1);
    SCOPED_TRACE("seed " + std::to_string(seed));
    expect_valid(region);
  }
}

// Star-shaped loops through random points of a small integer lattice, all other lattice
// points free: collinear and cocircular quadruples everywhere, and often a free point
// exactly on a boundary edge. Either the result passes every check, or the error names a
// point that really lies on a boundary edge (found here by exact orientation).
TEST(Triangulate2d, OnALatticeEitherTriangulatesOrNamesAPointLyingOnAnEdge) {
  int triangulated = 0;
  int rejected = 0;
  for (unsigned seed = 0; seed < 300; ++seed) {
    std::mt19937_64 random(seed);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    const int side = 8;
    const Vec2 centre(3.5 + 0.0123, 3.5 + 0.0377);  // on no lattice line: no two angles tie
    std::vector<Vec2> lattice;
    for (int x = 0; x < side; ++x) {
      for (int y = 0; y < side; ++y) lattice.emplace_back(x, y);
    }
    std::shuffle(lattice.begin(), lattice.end(), random);
    const int count = 4 + static_cast<int>(unit(random) * 16);
    std::vector<Vec2> loop(lattice.begin(), lattice.begin() + count);
    auto angle_of = [&](const Vec2& p) { return std::atan2(p.y() - centre.y(), p.x() - centre.x()); };
    std::sort(loop.begin(), loop.end(), [&](const Vec2& a, const Vec2& b) { return angle_of(a) < angle_of(b); });
    double largest_gap = 2.0 * std::numbers::pi + angle_of(loop.front()) - angle_of(loop.back());
    for (int i = 1; i < count; ++i) largest_gap = std::max(largest_gap, angle_of(loop[i]) - angle_of(loop[i - 1]));
    if (largest_gap >= 0.99 * std::numbers::pi) continue;  // not star-shaped around the centre
    PlanarRegion region;
    add_loop(region, loop);
    region.points.insert(region.points.end(), lattice.begin() + count, lattice.end());
    // Points on a boundary edge (free points only: the loop is simple).
    std::set<int> on_edge;
    for (const auto& [from, to] : region.boundary) {
      const Vec2& a = region.points[from];
      const Vec2& b = region.points[to];
      for (int v = 0; v < static_cast<int>(region.points.size()); ++v) {
        const Vec2& p = region.points[v];
        if (v == from || v == to || exact_orient(a, b, p) != 0) continue;
        if (p.x() >= std::min(a.x(), b.x()) && p.x() <= std::max(a.x(), b.x()) && p.y() >= std::min(a.y(), b.y()) &&
            p.y() <= std::max(a.y(), b.y()))
          on_edge.insert(v);
      }
    }
    SCOPED_TRACE("seed " + std::to_string(seed));
    if (!on_edge.empty()) {
      const std::string message = message_of(region);
      EXPECT_NE(message.find("lies on"), std::string::npos) << message;
      bool names_one = false;
      for (int v : on_edge) names_one = names_one || message.find("point " + std::to_string(v) + " ") != std::string::npos;
      EXPECT_TRUE(names_one) << message;
      ++rejected;
      // Without those points the same loop must triangulate.
      PlanarRegion kept;
      kept.boundary = region.boundary;
      for (int v = 0; v < static_cast<int>(region.points.size()); ++v) {
        if (on_edge.count(v) == 0) kept.points.push_back(region.points[v]);
      }
      expect_valid(kept);
    } else {
      expect_valid(region);
    }
    ++triangulated;
  }
  EXPECT_GT(triangulated, 20);
  EXPECT_GT(rejected, 20);
}

// A small region far from the origin: near 1e7 doubles are 1.9e-9 apart, so a region of
// size 1e-6 sits on a grid of about 500 steps across, where exactly collinear and
// cocircular points occur and absolute coordinates would cancel (the checks here work in
// differences, which are exact).
TEST(Triangulate2d, CoversASmallRegionFarFromTheOrigin) {
  std::mt19937_64 random(17);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Vec2 offset(1.0e7, -3.0e7);
  const double scale = 1e-6;
  PlanarRegion region;
  std::vector<Vec2> loop;
  for (int i = 0; i < 40; ++i) {
    const double angle = 2.0 * std::numbers::pi * (i + unit(random)) / 40.0;
    const double radius = scale * (0.5 + unit(random));
    loop.push_back(offset + radius * Vec2(std::cos(angle), std::sin(angle)));
  }
  add_loop(region, loop);
  for (int i = 0; i < 200; ++i) region.points.push_back(offset + scale * Vec2(3.0 * unit(random) - 1.5, 3.0 * unit(random) - 1.5));
  // Rounding onto the coarse grid near 1e7 can merge points or put one on an edge; keep
  // only inputs the contract accepts, the point here is the predicates.
  std::sort(region.points.begin() + 40, region.points.end(),
            [](const Vec2& a, const Vec2& b) { return a.x() != b.x() ? a.x() < b.x() : a.y() < b.y(); });
  region.points.erase(std::unique(region.points.begin() + 40, region.points.end()), region.points.end());
  std::vector<Vec2> kept(region.points.begin(), region.points.begin() + 40);
  for (std::size_t v = 40; v < region.points.size(); ++v) {
    const Vec2& p = region.points[v];
    bool acceptable = std::find(kept.begin(), kept.begin() + 40, p) == kept.begin() + 40;
    for (const auto& [from, to] : region.boundary) {
      const Vec2& a = region.points[from];
      const Vec2& b = region.points[to];
      if (exact_orient(a, b, p) == 0 && p.x() >= std::min(a.x(), b.x()) && p.x() <= std::max(a.x(), b.x()) &&
          p.y() >= std::min(a.y(), b.y()) && p.y() <= std::max(a.y(), b.y()))
        acceptable = false;
    }
    if (acceptable) kept.push_back(p);
  }
  region.points = kept;
  ASSERT_GT(region.points.size(), 150u);
  expect_valid(region);
}

TEST(Triangulate2d, TriangulatesFiveThousandPointsQuickly) {
  std::mt19937_64 random(3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  PlanarRegion region;
  std::vector<Vec2> loop;
  const int boundary_count = 500;
  for (int i = 0; i < boundary_count; ++i) {
    const double angle = 2.0 * std::numbers::pi * i / boundary_count;
    const double radius = 1.0 + 0.2 * std::sin(7.0 * angle);
    loop.emplace_back(radius * std::cos(angle), radius * std::sin(angle));
  }
  add_loop(region, loop);
  add_loop(region, reversed(rectangle(-0.3, -0.2, 0.3, 0.2)));
  while (region.points.size() < 5000) region.points.emplace_back(2.4 * unit(random) - 1.2, 2.4 * unit(random) - 1.2);
  const auto start = std::chrono::steady_clock::now();
  const auto triangles = triangulate_region(region);
  const double milliseconds = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  std::printf("triangulate_region: %zu points, %zu boundary edges -> %zu triangles in %.2f ms\n", region.points.size(),
              region.boundary.size(), triangles.size(), milliseconds);
  EXPECT_TRUE(is_constrained_delaunay_cover(region, triangles));
}

TEST(Triangulate2d, GivesNoTrianglesForAnEmptyBoundary) {
  PlanarRegion region;
  region.points = {Vec2(0, 0), Vec2(1, 0), Vec2(0, 1)};
  EXPECT_TRUE(triangulate_region(region).empty());
}

// ---------------------------------------------------------------------------------------
// Errors: each names the offending indices.
// ---------------------------------------------------------------------------------------
PlanarRegion unit_square() {
  PlanarRegion region;
  add_loop(region, rectangle(0, 0, 1, 1));
  return region;
}

TEST(Triangulate2d, RejectsANonFiniteCoordinateNamingThePoint) {
  PlanarRegion region = unit_square();
  region.points.emplace_back(0.5, std::numeric_limits<double>::quiet_NaN());
  EXPECT_THROW(triangulate_region(region), std::invalid_argument);
  EXPECT_NE(message_of(region).find("point 4"), std::string::npos) << message_of(region);
  region.points[4] = Vec2(std::numeric_limits<double>::infinity(), 0.5);
  EXPECT_NE(message_of(region).find("point 4"), std::string::npos) << message_of(region);
}

TEST(Triangulate2d, RejectsCoincidentPointsNamingBoth) {
  PlanarRegion region = unit_square();
  region.points.emplace_back(0.5, 0.5);
  region.points.emplace_back(0.2, 0.2);
  region.points.emplace_back(0.5, 0.5);
  EXPECT_THROW(triangulate_region(region), std::invalid_argument);
  EXPECT_NE(message_of(region).find("points 4 and 6"), std::string::npos) << message_of(region);
}

TEST(Triangulate2d, RejectsAnIndexOutOfRangeNamingTheEdgeAndIndex) {
  PlanarRegion region = unit_square();
  region.boundary[2][1] = 9;
  EXPECT_THROW(triangulate_region(region), std::invalid_argument);
  const std::string message = message_of(region);
  EXPECT_NE(message.find("boundary edge 2"), std::string::npos) << message;
  EXPECT_NE(message.find("index 9"), std::string::npos) << message;
  region.boundary[2][1] = -1;
  EXPECT_NE(message_of(region).find("index -1"), std::string::npos) << message_of(region);
}

TEST(Triangulate2d, RejectsBoundaryEdgesThatDoNotCloseNamingThePoint) {
  PlanarRegion region = unit_square();
  region.points.emplace_back(0.5, 0.5);
  region.boundary[3] = {3, 4};  // 3 -> 4 in place of 3 -> 0: 0 has no incoming edge
  EXPECT_THROW(triangulate_region(region), std::invalid_argument);
  EXPECT_NE(message_of(region).find("point 0"), std::string::npos) << message_of(region);
}

TEST(Triangulate2d, RejectsADegenerateEdgeNamingIt) {
  PlanarRegion region = unit_square();
  region.boundary.push_back({2, 2});
  EXPECT_NE(message_of(region).find("boundary edge 4"), std::string::npos) << message_of(region);
}

TEST(Triangulate2d, RejectsCrossingBoundaryEdgesNamingBoth) {
  PlanarRegion region;  // a bow tie: 0 -> 1 and 2 -> 3 cross at (0.5, 0.5)
  region.points = {Vec2(0, 0), Vec2(1, 1), Vec2(1, 0), Vec2(0, 1)};
  region.boundary = {{0, 1}, {1, 2}, {2, 3}, {3, 0}};
  EXPECT_THROW(triangulate_region(region), std::invalid_argument);
  const std::string message = message_of(region);
  EXPECT_NE(message.find("boundary edge 0"), std::string::npos) << message;
  EXPECT_NE(message.find("boundary edge 2"), std::string::npos) << message;
  EXPECT_NE(message.find("cross"), std::string::npos) << message;
}

TEST(Triangulate2d, RejectsOverlappingBoundaryEdgesNamingBoth) {
  PlanarRegion region;
  add_loop(region, rectangle(0, 0, 2, 2));
  add_loop(region, {Vec2(1, 0), Vec2(3, -1), Vec2(3, 0)});  // its edge 6 runs along edge 0 from (3, 0) to (1, 0)
  EXPECT_THROW(triangulate_region(region), std::invalid_argument);
  std::string message = message_of(region);
  EXPECT_NE(message.find("overlap"), std::string::npos) << message;
  EXPECT_NE(message.find("boundary edge 0"), std::string::npos) << message;
  EXPECT_NE(message.find("boundary edge 6"), std::string::npos) << message;
  // The same edge twice (in opposite directions): also an overlap.
  PlanarRegion doubled = unit_square();
  doubled.boundary.push_back({1, 0});
  doubled.boundary.push_back({0, 1});
  message = message_of(doubled);
  EXPECT_NE(message.find("overlap"), std::string::npos) << message;
  EXPECT_NE(message.find("boundary edge 0"), std::string::npos) << message;
  EXPECT_NE(message.find("boundary edge 4"), std::string::npos) << message;
}

TEST(Triangulate2d, RejectsAPointOnABoundaryEdgeNamingThePointAndEdge) {
  PlanarRegion region = unit_square();
  region.points.emplace_back(0.25, 0.5);
  region.points.emplace_back(1.0, 0.375);  // exactly on edge 1, (1, 0) -> (1, 1)
  EXPECT_THROW(triangulate_region(region), std::invalid_argument);
  const std::string message = message_of(region);
  EXPECT_NE(message.find("point 5"), std::string::npos) << message;
  EXPECT_NE(message.find("boundary edge 1"), std::string::npos) << message;
}

TEST(Triangulate2d, RejectsAClockwiseOuterLoopNamingAnEdge) {
  PlanarRegion region;
  add_loop(region, reversed(rectangle(0, 0, 1, 1)));
  EXPECT_THROW(triangulate_region(region), std::invalid_argument);
  EXPECT_NE(message_of(region).find("boundary edge"), std::string::npos) << message_of(region);
  // Two nested counter-clockwise loops: the ring between them is left of one, right of the other.
  PlanarRegion nested;
  add_loop(nested, rectangle(0, 0, 3, 3));
  add_loop(nested, rectangle(1, 1, 2, 2));
  EXPECT_THROW(triangulate_region(nested), std::invalid_argument);
}

}  // namespace
}  // namespace incise::physics
