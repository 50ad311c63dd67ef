// Mapping a FrontSurface's vertices onto the EFG model's integration points by the thesis's
// three eligibility criteria (seed 004 §2.6, Magnoux 2020 §5.2.2-5.2.3, fallback §7.1.2).
// The caller decides what to remap (the triggers of §2.6: vertices a cut created or
// touched, vertices mapped to an element whose neighbourhood a volume cut changed, vertices
// whose link to their point the blade crossed); this file only says where each one goes.
// Free functions over plain arrays (STYLE.md, libigl): the surface is its rest vertices and
// triangles, the constraint planes come from FrontSurface::vertex_planes() or the caller.
#pragma once

#include "physics/cut/front_surface.hpp"
#include "physics/cut/uniform_grid.hpp"
#include "physics/efg/corotational_efg.hpp"

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

namespace incise::physics {

struct FrontMappingReport {
  int mapped = 0;             // vertices whose row was computed in this call
  int relaxed_fallbacks = 0;  // vertices for which no candidate met all three criteria (counted, never silent)
  int unseen = 0;             // with FrontVisibility::inside: vertices left on a point they do not see
                              // through the body (none within reach did)
};

// Rows sized for `vertices` at `stride`: the existing ones kept (moved to the new stride if
// it changed), those beyond `vertices` dropped, new ones zero.
void fit_rows(SurfaceEmbedding& embedding, int vertices, int stride);

// (Re)maps the vertices listed in `remap` (strictly increasing; indices at or above the
// embedding's row count are appended, and every one of them must be listed) onto one active
// integration point each. The candidates are the elements whose rest integration point lies
// in the integration cubes within front_mapping_reach_rings rings of the vertex's cube,
// nearest first (rest configuration); the first valid one is taken:
//  1. its neighbourhood shares at least one particle with the neighbourhood of the element
//     each one-ring neighbour of the vertex is mapped to (neighbours not mapped are skipped);
//  2. it lies below the tangent plane at the vertex, (X_e - X_v) . n_v <= 0, n_v the
//     area-weighted normal of the vertex's triangles (a vertex with no triangle, or whose
//     normal vanishes, has no tangent plane and this criterion holds for every candidate);
//  3. it lies below each plane of `planes[v]` (missing entries have none).
// Criterion 1 and the order of the list: the neighbours' mappings are read from snapshots,
// never from rows written earlier in the same pass, so the result depends on the set of
// listed vertices, the embedding's other rows and the inputs, not on the order in which the
// vertices are visited. Two passes: the first checks criterion 1 against the neighbours that
// are not listed (their rows as given); the second against every neighbour, listed ones at
// their first-pass element. The second pass is the result (and alone counts fallbacks).
// What this costs: a listed neighbour's final point may differ from its first-pass one, so
// criterion 1 between two listed vertices holds against first-pass points, not always the
// final ones; and a vertex whose planes exclude every point sharing a particle with a listed
// neighbour's first-pass point (found without that vertex's constraint) is relaxed, and
// counted (test_cut_front_mapping.cpp, ChecksCriterionOneAgainstNeighboursRemappedInTheSameCall).
// When no candidate within reach is valid, the criteria are relaxed in this order, and the
// vertex counted in relaxed_fallbacks: drop 1 (keep 2 and 3), then drop 2 (keep 3: the cut
// planes are what keeps a vertex off the other side of a cut), then the nearest candidate
// within reach, then the nearest active element of all. With `visibility` (FrontVisibility
// below) it is a fourth criterion, kept with 3: drop 1, drop 2, drop 3 (keep it alone), then
// 3 alone, then the nearest.
// The row is the MLS weights at the vertex of the chosen element's neighbourhood, with the
// element's support widened as embed_surface does (support_factor x the farthest neighbour
// from the vertex) so that every neighbour weighs. The embedding takes the model's row
// stride if it is larger (existing rows are moved).
// Throws std::invalid_argument naming the vertex or triangle, before anything changes: an
// index out of range, a non-finite position, the remap list not increasing or missing an
// index at or above the row count, more rows than vertices. Throws std::runtime_error naming
// the vertex if no MLS weights exist for it (a degenerate neighbourhood).
// With `around` (see TrianglesAround) the listed vertices' triangles are read from it instead
// of scanning the surface, and only they and their corners are checked.
struct FrontVisibility;
// Per vertex, the triangles it is a corner of (indices into the triangle list, in increasing
// order, each once), appended to `triangles`: for a caller that keeps them, so that
// map_front_surface and count_wrong_side read the listed vertices' triangles instead of
// scanning the whole surface. It must give every triangle of each vertex it is asked for.
using TrianglesAround = std::function<void(int vertex, std::vector<int>& triangles)>;
// The model's active elements binned by their integration cube (one per cube): where the
// candidates are looked for. A caller mapping at every cut event keeps one between calls
// (`cubes` below); it is taken again when the model's count of deactivated elements changed
// (deactivation is final, so the count tells).
struct ElementCubes {
  const CorotationalEfg* model = nullptr;
  int deactivated = -1;
  UniformGrid grid;  // cells: the model's integration cubes; items: the active elements
  void update(const CorotationalEfg& from);
};
void map_front_surface(const CorotationalEfg& model, const std::vector<Vec3>& vertices,
                       const std::vector<std::array<int, 3>>& triangles,
                       const VertexPlanes& planes, std::span<const int> remap,
                       SurfaceEmbedding& embedding, FrontMappingReport& report,
                       const FrontVisibility* visibility = nullptr, const TrianglesAround* around = nullptr,
                       ElementCubes* cubes = nullptr);

// Cut faces (rest positions, each face once) binned on the model's integration grid, for
// counting the faces a segment crosses: its ends strictly on both sides of a face's plane,
// the crossing inside the face or on its rim.
class CutFaceIndex {
 public:
  CutFaceIndex(const CorotationalEfg& model, std::vector<std::array<Vec3, 3>> faces);
  // `skip_near_p` > 0: faces whose plane passes within that distance of p are not counted.
  int crossings(const Vec3& p, const Vec3& q, double skip_near_p = 0) const;

 private:
  static constexpr long long large_cells = 4096;  // faces over more cells are tested against every segment
  static constexpr double most_cells = 1 << 22;  // the grid's cells double in size until it has no more
  static constexpr double box_slack = 1e-9;  // m: far beyond roundoff at body scale
  std::vector<std::array<Vec3, 3>> faces_;
  std::vector<std::array<Vec3, 2>> boxes_;  // per face
  // Cells of side a on the model's integration lattice (coarser for a cut spread wide), over
  // the box of the faces binned.
  UniformGrid grid_;
};

// A fourth criterion for map_front_surface, the one wrong_side measures: the segment from the
// vertex, moved inward by `inset` along its angle-weighted normal (as count_wrong_side does;
// by less, halved until it crosses none, where a cut face passes nearer than that),
// to the candidate's rest integration point crosses `faces` an even number of times. Vertices
// flagged in `exempt` (the crack front's, where both sides meet) are not held to it. It is
// kept wherever criterion 3 is when relaxing (see map_front_surface), then dropped before the
// nearest candidate is taken.
// With `inside` (the body's rest shape), the segment from the vertex itself to the candidate's
// rest integration point must also stay inside the body (CorotationalEfg::sees_through_body):
// a vertex on a thin feature (a fin, an organ's folded edge, thinner than the particle spacing)
// beside another part of the body across a gap then follows a point of its own feature, not one
// across the gap (issue 32). `faces` may then be null (a first mapping, nothing cut yet). The
// inside test costs up to 3 a / (a / 8) queries per candidate, so only the first mapping (at
// the build, make_cut_data) takes it; the remaps after a cut touch the cut's surroundings and
// keep those vertices' first criteria plus the cut faces'.
struct FrontVisibility {
  const CutFaceIndex* faces = nullptr;
  double inset = 0;
  std::span<const std::uint8_t> exempt;
  // Per vertex, 1 on a cut face: pulled in by the full inset (the shortening is for vertices
  // off the faces that a cut passes near; a face's own wavy neighbours would shorten it).
  std::span<const std::uint8_t> on_face;
  const std::function<bool(const Vec3&)>* inside = nullptr;
};

// How far the candidate search reaches: integration cubes up to this Chebyshev distance from
// the vertex's cube (a candidate in ring r is at least (r - 1) a away).
inline constexpr int front_mapping_reach_rings = 3;

// The vertices whose integration point lies across a cut from them: the segment from the
// vertex, moved inward by `inset` along -n_v (by less where that would cross a cut face), to
// its element's rest integration point crosses `cut_triangles` an odd number of times (rest positions, each face once, e.g. one
// side's cut faces of the FrontSurface; a wavy face crossed and crossed back is the same
// side): its ends strictly on both sides of a triangle's plane, the crossing inside the
// triangle or on its rim. n_v here is the
// unit angle-weighted normal (a vertex without one is not moved), not the area-weighted one
// of criterion 2: at the rim of a cut a vertex pair's copy has tiny cut-face triangles next
// to large ones of the original surface, and the area-weighted normal, leaning outward from
// the original surface, moves the start point across the cut (8 of 1756 correctly mapped
// vertices counted in the cut-ball test); the angle-weighted one stays in the wedge. The issue's
// metric mapping.wrong_side. Vertices without a row (index >= row count) are not counted.
int count_wrong_side(const CorotationalEfg& model, const std::vector<Vec3>& vertices,
                     const std::vector<std::array<int, 3>>& triangles, const SurfaceEmbedding& embedding,
                     const std::vector<std::array<Vec3, 3>>& cut_triangles, double inset,
                     std::vector<int>* which = nullptr);  // the vertices, when given
class CutFaceIndex;
// The same against faces already indexed, over the vertices of `subset` only (increasing;
// empty: every vertex with a row), which are the ones counted and listed; `on_face` as in
// FrontVisibility; `around` as for map_front_surface (with a subset only).
int count_wrong_side(const CorotationalEfg& model, const std::vector<Vec3>& vertices,
                     const std::vector<std::array<int, 3>>& triangles, const SurfaceEmbedding& embedding,
                     const CutFaceIndex& faces, double inset, std::span<const int> subset,
                     std::vector<int>* which = nullptr, std::span<const std::uint8_t> on_face = {},
                     const TrianglesAround* around = nullptr);

// Which vertices of a FrontSurface are the same as at the last mapping. The stroke's vertices
// are numbered anew at every sample, but what lies behind the front comes out the same
// (front_surface.hpp): a vertex with the same rest position, constraint planes and
// crack-front flag, whose triangles join it to the same vertices, is the same vertex and
// keeps its row (its mapping inputs are those of the last time: position, normal, planes).
// Vertices below `first` are the base's, the same index in both; the others are told apart by
// content hashes (64-bit; two vertices of one surface with the same key match nothing).
// `among`: the triangles to look at (increasing), when the caller knows which have a corner
// at or above `first` (it may list more); empty: all.
struct FrontVertexIdentity {
  int first = 0;
  std::vector<std::uint64_t> key;   // per vertex at or above first: position, planes, flag
  std::vector<std::uint64_t> ring;  // per vertex at or above first: its triangles' other corners
  // (key, vertex) of every vertex at or above first, sorted: made once, as match_front_vertices
  // looks each identity up twice (as `now`, then as the next call's `before`).
  std::vector<std::pair<std::uint64_t, int>> sorted;
};
FrontVertexIdentity front_vertex_identity(const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles,
                                          const VertexPlanes& planes,
                                          std::span<const std::uint8_t> crack_front, int first,
                                          std::span<const int> among = {});
// Per vertex of `now` (indices from now.first on; the vector has now.first + now.key.size()
// entries, -1 below now.first): the index in `before` of the same vertex, -1 when it is new,
// its triangles changed or its key is not unique. Nothing matches when the two `first`
// differ. `same_point` (when given, the same size): the match by key alone, whatever the
// triangles: the same rest position, planes and flag, so the same mapping inputs but the
// normal (seed 004 §2.6 does not remap a vertex whose triangles changed, only on its four
// triggers).
std::vector<int> match_front_vertices(const FrontVertexIdentity& before, const FrontVertexIdentity& now,
                                      std::vector<int>* same_point = nullptr);

}  // namespace incise::physics
