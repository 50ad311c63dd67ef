// A 2D constrained Delaunay triangulation of a planar region bounded by directed loops.
//
// What it is for: meshing the exposed face of a cut, the part of the blade's swept sheet
// inside the body flattened into the sheet's 2D parameter plane, and later surface
// triangles that hold several cut chords. Both give a few closed loops (an outer boundary,
// perhaps holes, perhaps several pieces) and maybe free points that the mesh must use.
//
// Algorithm (physics/cut/triangulate_2d.cpp):
// 1. Validation, with every error naming the offending indices (see triangulate_region).
// 2. An unconstrained Delaunay triangulation of all points inside a large enclosing
//    triangle, by incremental insertion with Lawson flips. Points are inserted in Hilbert
//    curve order, so the visibility walk that locates each one starts next to it; the walk
//    picks among the edges it may cross with a fixed-seed generator so it cannot cycle.
// 3. Constraint recovery, edge by edge in input order: walk from one end to the other
//    collecting the crossed edges (finding here, exactly, any boundary edge it crosses and
//    any point lying on it), then flip them away (Sloan 1993: a crossed edge whose quad is
//    convex is flipped, the others are queued again; this always terminates).
// 4. Removal of what is not the region: the triangles are split into components across
//    boundary edges; the component on an edge's left is inside, on its right outside.
// 5. Lawson flips of the inside's non-boundary edges until each passes the empty-circle
//    test: locally Delaunay everywhere inside means constrained Delaunay.
//
// Predicates: orient2d and incircle return the exact sign. Each is first evaluated in
// double precision with Shewchuk's a-priori error bound (Shewchuk 1997, "Adaptive
// precision floating-point arithmetic and fast robust geometric predicates", bounds A);
// when the value is below the bound the determinant is recomputed exactly as a
// floating-point expansion (two-sum and two-product error-free transformations, summed and
// scaled without loss). The sign is exact under the default round-to-nearest mode as long
// as no intermediate product overflows or underflows: differences between coordinates
// within about 1e-60 .. 1e75 (incircle's exact path multiplies four of them). The bounds are
// for separately rounded operations; the project does not build with -march/-mfma, so the
// compiler fuses nothing (with hardware FMA the error-free product uses it, see two_product).
//
// Tie rule: an edge is flipped only when the opposite point is strictly inside the
// circumcircle. Four cocircular points (a square lattice) keep whichever diagonal the
// deterministic insertion order made first; both are valid constrained Delaunay edges, and
// strict flips cannot cycle. A point exactly on an edge during insertion splits that edge.
//
// Complexity: O(n log n) for the sort, expected O(1) per point location on the Hilbert
// order and O(1) expected flips per insertion for well-spread points, so about O(n log n)
// in total for the triangulation; recovering a boundary edge costs the number of edges it
// crosses (squared in the worst case, linear in practice). Boundary edges that are already
// short relative to the point spacing cross few edges.
#pragma once

#include <Eigen/Core>

#include <array>
#include <vector>

namespace incise::physics {

using Vec2 = Eigen::Vector2d;

struct PlanarRegion {
  std::vector<Vec2> points;                  // loop vertices and free (Steiner) points
  std::vector<std::array<int, 2>> boundary;  // directed edges (from, to); the region is on the LEFT
};

// Triangles (counter-clockwise, indices into region.points) covering exactly the region:
// the union of the areas left of the boundary loops (outer loops counter-clockwise, holes
// clockwise, several components allowed). Every boundary edge is an edge of exactly one
// output triangle, in its direction; every other edge is shared by exactly two triangles,
// in opposite directions; every point strictly inside the region is a vertex; points
// outside are ignored. The triangulation is constrained Delaunay (each non-boundary edge
// passes the empty-circle test against the points visible from it). Deterministic: the same
// input gives the same output, element for element (sorted, each triangle starting at its
// smallest index).
//
// Throws std::invalid_argument naming the offending index/indices when: a coordinate is not
// finite; two points coincide; an index is out of range; an edge starts and ends at the
// same point; the boundary edges do not form closed loops (each vertex must have as many
// outgoing as incoming boundary edges); two boundary edges cross or overlap (the same edge
// twice, in either direction, included); a point lies on a boundary edge it is not an
// endpoint of; the loops are not oriented so that one side of each edge is inside and the
// other outside (an outer loop clockwise, two nested loops both counter-clockwise).
// An empty boundary is an empty region: no triangles.
std::vector<std::array<int, 3>> triangulate_region(const PlanarRegion& region);

// The exact predicates the triangulation uses, exposed for its tests and for cut code that
// must agree with it. orient2d: > 0 when a, b, c turn counter-clockwise, < 0 clockwise,
// 0 collinear. incircle: > 0 when d is strictly inside the circle through a, b, c taken
// counter-clockwise (the sign flips for clockwise a, b, c), 0 when cocircular. Only the
// sign is exact; the magnitude is an approximation of the determinant.
double orient2d(const Vec2& a, const Vec2& b, const Vec2& c);
double incircle(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d);

}  // namespace incise::physics
