// The render surface of a cuttable body, and its mapping onto the meshless model.
//
// Seed 004 §2.5 cuts an explicit triangle mesh: triangles crossed by the blade are split
// three or four ways, the new vertices come in pairs, and the exposed cut face is meshed by
// a moving "cutting front". The thesis reports where that breaks: slivers, bad normals and
// the mapping failures they cause (§4.3.3, §7.1.2), with no guarantee of triangle quality.
// This file takes another route to the same outcome, a closed 2-manifold surface that opens
// exactly where the blade passed and stays attached to the right side (front_surface.hpp is
// the thesis's route, chosen per body by the scene's efg.cut_surface):
//
// - The surface is the boundary of a voxel fill of the body (cubes of side `cell`, finer than
//   the integration grid as §5.3 requires), its outer nodes snapped onto the true surface.
// - The cut is kept as triangles in the rest configuration (the blade's sweep, mapped back
//   through the local deformation of the body; all topology edits happen at rest, §2.3).
// - Two cubes whose centre-to-centre segment crosses a cut triangle no longer share their
//   face. Each grid node gets one vertex per group of its cubes still joined through uncut
//   faces, so the faces either side of the cut have vertices of their own: the cut face of
//   each side is part of that side's boundary, and the surface is closed by construction.
//   Where the cut ends inside the body (the crack front), the cubes are joined around it and
//   the two sides meet in one vertex, closing the pocket.
// - The vertices of cut faces are projected onto the nearest cut triangle, so both sides'
//   faces lie on the cut itself (zero thickness at rest, like the thesis's vertex pairs).
// - Each vertex knows an anchor: the centre of one of its cubes, a point certainly on its
//   side. It is mapped (seed 004 §2.6: one integration point, MLS weights at the vertex) to
//   the nearest integration point visible from that anchor, i.e. whose segment to the anchor
//   crosses no cut triangle (this replaces the thesis's three eligibility criteria, which
//   need the triangle normals that slivers spoil). When none is visible within reach, the
//   nearest point is taken and the vertex is counted as a relaxed fallback.
// The cut advances by cube faces: its resolution is the surface cell (the volume's is
// about half an integration element, §4.3.1).
// A rebuild after a cut is local: only the grid nodes at the corners of the faces whose
// state changed (newly cut, or hidden or shown again by pinch closing) can change their
// groups, so only their vertices and the faces of the cubes around them are redone; every
// other vertex keeps its index, key, anchor and position (cut-face vertices are projected
// again only near the cut's new triangles). A vertex keeps its index as long as its key
// lives; new vertices take the lowest free index, else are appended. An index whose key
// died (groups merged again) stays allocated but unused: key -1, in no triangle, its last
// rest position and anchor kept so that it can stay mapped (vertex_count() counts only the
// used ones). The result equals a rebuild from scratch with the same cut, up to numbering.
// The lists are patched in place, not rewritten: the triangles are the surface cubes' in
// increasing cube order, each cube's contiguous, so only the redone cubes' are written and
// the part after the first cube whose count changed moves as a block; only the placed
// vertices' rest positions are written. The rebuild says what it wrote
// (changed_triangles(), placed_vertices()), so copies of the lists can take only that.
#pragma once

#include "physics/cut/broad_phase.hpp"
#include "physics/cut/point_bins.hpp"
#include "physics/efg/corotational_efg.hpp"

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <unordered_map>
#include <utility>
#include <vector>

namespace incise::physics {

struct RestTriangle {
  Vec3 a = Vec3::Zero();
  Vec3 b = Vec3::Zero();
  Vec3 c = Vec3::Zero();
};

// The parameter along [p, q] where the segment crosses the triangle (closed), or nothing.
// Degenerate triangles are never crossed.
std::optional<double> segment_crosses_triangle(const Vec3& p, const Vec3& q, const RestTriangle& triangle);

// The cut surface in the rest configuration: triangles with their boxes, for segment tests.
class RestCut {
 public:
  // `cell`: the side of the hash grid the triangles are binned in (about the size of the
  // segments tested: an integration cube).
  explicit RestCut(double cell = 0.005) : cell_(cell) {}
  void add(const RestTriangle& triangle);
  int size() const { return static_cast<int>(triangles_.size()); }
  const std::vector<RestTriangle>& triangles() const { return triangles_; }
  // True if [p, q] crosses any triangle (any of those added at or after index `from`).
  bool crosses(const Vec3& p, const Vec3& q, int from = 0) const;
  // The nearest point on the cut to p within `reach`, or nothing.
  std::optional<Vec3> nearest_point(const Vec3& p, double reach) const;
  // Whether anything lies within `reach` of the box [lo, hi].
  bool near_box(const Vec3& lo, const Vec3& hi, double reach) const;

 private:
  template <typename Visit>
  void for_each_near(const Vec3& lo, const Vec3& hi, double reach, const Visit& visit) const;

  // The bin range covering every triangle's box, grown (by doubling, re-binning) as the cut
  // grows; bins are a dense array over it, so a query costs array reads, not hash lookups.
  std::vector<int>* bin(long long i, long long j, long long k);
  const std::vector<int>* bin(long long i, long long j, long long k) const;
  void cover(const std::array<long long, 3>& first, const std::array<long long, 3>& last);

  double cell_;
  std::vector<RestTriangle> triangles_;
  std::vector<std::array<Vec3, 2>> boxes_;
  std::array<long long, 3> bins_lo_{0, 0, 0}, bins_count_{0, 0, 0};
  std::vector<std::vector<int>> bins_;  // grid cell -> triangles overlapping it
  mutable std::vector<int> stamp_;                         // per triangle: last query that saw it
  mutable int query_ = 0;
};

// Edges of a triangle mesh used by one triangle (holes) and by more than two (non-manifold).
struct SurfaceTopology {
  int boundary_edges = 0;
  int nonmanifold_edges = 0;
  bool watertight() const { return boundary_edges == 0 && nonmanifold_edges == 0; }
};
SurfaceTopology surface_topology(const std::vector<std::array<int, 3>>& triangles);
// The same over the edges whose two ends are flagged in `among` (a vertex past its end is
// not): where a surface changed, so that the whole count can be kept up to date by taking
// these edges' count off before the change and adding it after (engine/world.cpp, front mode).
SurfaceTopology surface_topology(const std::vector<std::array<int, 3>>& triangles, std::span<const std::uint8_t> among);

class CutSurface {
 public:
  // The body {inside} within [lo, hi], filled with cubes of side `cell` whose centres are
  // inside. Throws std::invalid_argument if the cell is not positive or nothing is inside.
  CutSurface(const std::function<bool(const Vec3&)>& inside, Vec3 lo, Vec3 hi, double cell);

  // Separates the cubes whose centre-to-centre segment crosses one of `triangles` (added to
  // the cut). Returns the number of faces newly cut; rebuild() makes them visible.
  int cut(std::span<const RestTriangle> triangles);
  // Recomputes the vertices and triangles from the cubes and the cut. Where two cubes joined
  // elsewhere touch along an edge whose other two cubes are empty or cut away (a pinch,
  // which would make that edge non-manifold), the pinch is closed: an empty cube there is
  // filled (at build); a cut face there is not shown (after a cut: a crack one face wide
  // whose rim is still joined all round, e.g. the first faces the blade enters). The cut
  // itself is kept, so the face appears once the cut has grown around it;
  // pinches_closed() counts the faces hidden by the last rebuild. Every rebuild shows the
  // faces hidden before again and closes the pinches anew (the outcome depends on the cut,
  // not on its history); only the nodes around the changed faces are redone (file comment).
  void rebuild();
  int pinches_closed() const { return pinches_closed_; }
  // surface_topology(triangles()), kept up to date by each rebuild: the edges with an end at
  // a redone node are counted again, the others keep their triangles and so their count.
  SurfaceTopology topology() const;

  const Vector& rest_vertices() const { return rest_vertices_; }
  const std::vector<std::array<int, 3>>& triangles() const { return triangles_; }
  // The triangles the last rebuild wrote, [first, last) in triangles(): the others are those
  // of the list before it at the same index (when the count changed, last is the new count).
  // Each rebuild patches the list in place: the redone cubes' triangles are written over
  // their old ones, and the part after the first cube whose count changed moves as a block.
  std::pair<int, int> changed_triangles() const { return changed_triangles_; }
  // The vertex indices whose rest position the last rebuild wrote (each once; appended
  // indices are among them): the others keep their row of rest_vertices().
  const std::vector<int>& placed_vertices() const { return placed_; }
  // Per vertex index (used or not, see the file comment; rest_vertices() has as many).
  const std::vector<Vec3>& anchors() const { return anchors_; }
  const std::vector<std::uint8_t>& on_cut() const { return on_cut_; }  // 0 for unused indices
  // Per vertex: grid node x 8 + its group there, -1 for an unused index. A vertex keeps its
  // key and its index across rebuilds as long as the cut does not split its group, which
  // lets a mapping (and the GPU's copy of its rows) be reused.
  const std::vector<long long>& vertex_keys() const { return vertex_keys_; }
  bool vertex_used(int v) const { return vertex_keys_[static_cast<size_t>(v)] >= 0; }
  int vertex_count() const { return used_vertices_; }  // the used indices
  // Keys are below this bound (grid nodes x 8): a table indexed by key can replace a map.
  long long key_space() const {
    return 8LL * (counts_[0] + 1) * (counts_[1] + 1) * (counts_[2] + 1);
  }
  // Counts the rebuilds (the construction's is 1). Per vertex index: the revision that last
  // wrote its key, rest position or anchor, so that a copy taken at revision r needs taking
  // again only at the indices above r.
  int revision() const { return revision_; }
  const std::vector<int>& vertex_revisions() const { return vertex_revision_; }
  // The indices the last rebuild wrote so (each once): those whose revision is revision().
  const std::vector<int>& written_vertices() const { return written_; }
  const RestCut& rest_cut() const { return rest_cut_; }
  int cut_faces() const { return cut_faces_; }
  int cubes() const { return cube_count_; }
  double cell() const { return cell_; }

 private:
  int cube_index(int i, int j, int k) const { return i + counts_[0] * (j + counts_[1] * k); }
  int node_index(int i, int j, int k) const { return i + (counts_[0] + 1) * (j + (counts_[1] + 1) * k); }
  // The grid node at corner `corner` (bits x = 1, y = 2, z = 4) of cube (i, j, k).
  int corner_node(int i, int j, int k, int corner) const {
    return node_index(i + (corner & 1), j + ((corner >> 1) & 1), k + ((corner >> 2) & 1));
  }
  Vec3 cube_centre(int i, int j, int k) const;
  // At construction: one pass over every cube filling the empty cubes at pinches; returns
  // the number filled (0: the voxel set is final).
  int fill_pinches();
  // The groups of a node's 8 cubes (slot s = dx + 2 dy + 4 dz), cached until marked stale.
  const std::array<std::int8_t, 8>& node_groups(int node);
  // Redoes the vertices of `nodes` and the faces of the cubes around them, closing the
  // pinches this makes (see rebuild()); the rest of the surface is kept.
  void refresh(std::vector<int> nodes);
  void add_face_corners(int face, std::vector<int>& nodes);

  double cell_ = 0;
  Vec3 origin_ = Vec3::Zero();
  std::array<int, 3> counts_{};
  std::vector<std::uint8_t> inside_;         // per cube
  std::vector<std::uint8_t> face_cut_;       // per cube x 3: its +x, +y, +z face
  std::vector<std::uint8_t> face_shown_;     // the cut faces the surface shows (pinches hidden)
  // The inside cubes with a face on the surface (an outside neighbour or a cut face), by
  // increasing index: after the build only these can hold faces, so a rebuild walks them
  // instead of every cube, in the same order. cut() adds the cubes of the faces it cuts.
  std::vector<int> surface_cubes_;
  std::vector<int> new_surface_cubes_;
  std::vector<int> merged_cubes_;  // scratch of the merge
  std::vector<Vec3> node_rest_;              // per grid node, snapped onto the surface
  int cube_count_ = 0;
  int cut_faces_ = 0;
  int pinches_closed_ = 0;
  // Binned at twice the surface cell: the cut advances by cube faces, so its triangles are
  // about that size (the bins do not change any answer, only what a query reads; at 20k
  // elements and s = 0.6 mm this took ms_ccd from 3.0 to 2.5 ms against 5 mm bins).
  RestCut rest_cut_;
  std::vector<int> pending_faces_;  // faces cut since the last rebuild (cube x 3 + axis)
  std::vector<int> hidden_faces_;   // cut faces the last rebuild hid (pinches)
  std::map<std::pair<int, int>, int> bad_edges_;  // vertex pairs used by other than 2 triangles
  int projected_triangles_ = 0;     // rest-cut triangles the cut-face vertices were projected on
  std::vector<int> vertex_node_;  // grid node of each vertex
  std::vector<long long> vertex_keys_;  // node * 8 + group: the same vertex across rebuilds
  std::vector<std::array<std::int8_t, 8>> node_groups_;  // per grid node, see node_groups()
  std::vector<std::uint8_t> node_groups_done_;
  std::vector<int> vertex_of_;      // per key (node x 8 + group): its vertex, or -1
  std::vector<int> free_vertices_;  // unused indices, a min-heap
  int used_vertices_ = 0;
  std::vector<int> cube_first_;                // per cube: its first triangle in triangles_
  std::vector<std::uint8_t> cube_triangles_;   // per cube: how many triangles it has there
  // Scratch of refresh, kept to avoid reallocating.
  std::vector<std::uint8_t> node_mark_, cube_mark_;
  std::vector<int> vertex_stamp_;
  int stamp_ = 0;
  std::vector<Vec3> positions_;     // per vertex index, as rest_vertices_
  std::vector<int> placed_;         // the vertices the last rebuild placed (rest position written)
  std::vector<std::array<int, 3>> moved_;  // scratch: the triangles' tail while it moves
  std::pair<int, int> changed_triangles_{0, 0};
  int revision_ = 0;
  std::vector<int> vertex_revision_;  // per vertex index, see vertex_revisions()
  std::vector<int> written_;          // see written_vertices()

  Vector rest_vertices_;
  std::vector<std::array<int, 3>> triangles_;
  std::vector<Vec3> anchors_;
  std::vector<std::uint8_t> on_cut_;
};

// The mapping of a cut surface's vertices onto the model (see the file comment).
struct SurfaceMappingReport {
  int mapped = 0;             // vertices whose mapping was computed (the others were reused)
  int relaxed_fallbacks = 0;  // no visible integration point within reach
  int wrong_side = 0;         // chosen point across the cut from the vertex's anchor
};
SurfaceEmbedding map_surface(const CorotationalEfg& model, const CutSurface& surface, SurfaceMappingReport& report);
// Rows sized for `vertices` at `stride`: the existing ones kept (moved to the new stride if
// it changed), those beyond `vertices` dropped, new ones zero.
void fit_rows(SurfaceEmbedding& embedding, int vertices, int stride);
// Keeping a mapping up to date across cuts, in place. Vertex indices are stable (file
// comment), so a row is reused by index: a used index keeps its row when its key, rest
// position and anchor are those of the last mapping, its integration point's neighbourhood
// did not change (element_changed) and no triangle the cut gained since then crosses the
// segment from its anchor to that point. That row is then the one map_surface would find:
// the cut only grows, so the points hidden from the anchor before stay hidden, and the
// chosen point, still visible, still has the same neighbourhood. An unused index (key -1)
// keeps the row it had, so that it stays where it was (it is mapped, not counted, only when
// it has none).
struct ElementCubes;  // cut_surface.cpp
struct MappingReuse {
  std::vector<long long> keys;  // per index at the last mapping, updated by remap_surface
  Vector rest_vertices;         // the same for the rest positions
  std::vector<Vec3> anchors;    // and the anchors
  int triangles_mapped = 0;     // rest-cut triangles at the last mapping
  // The surface's revision() the copies above were taken at, -1 if unknown: then every
  // index is compared, else only those the surface wrote since (vertex_revisions()).
  int revision = -1;
  // The rows by element, kept by remap_surface (taken from every row when the sizes do not
  // match): per element the indices whose row is on it, and a box holding the segments from
  // their anchors to its point (grown, never shrunk). With them, and at most one rebuild
  // since the copies, only the indices that can be dirty are looked at: appended, written by
  // that rebuild, on an element marked changed, or on one whose box meets the new triangles'.
  std::vector<std::vector<int>> by_element;
  std::vector<std::array<Vec3, 2>> element_boxes;
  // The same boxes in a btDbvt (the elements with rows), refit as they grow: the elements
  // whose box meets the new triangles' are found without testing every element's box.
  std::unique_ptr<EdgeBroadPhase> element_tree;
  // The table of elements by integration cube the vertex search uses (built once: the
  // elements' cubes never change).
  std::shared_ptr<const ElementCubes> element_cubes;
  int stride = 0;  // the model's row stride at the last mapping
  const std::vector<std::uint8_t>* element_changed = nullptr;  // per element, may be null
  std::vector<int> remapped;  // out: the indices whose row was recomputed, increasing
};
// `embedding` is the mapping of the surface's last state (as many rows as `reuse.keys`);
// the rows the surface's indices gained are appended. Throws std::invalid_argument when
// the sizes disagree.
void remap_surface(const CorotationalEfg& model, const CutSurface& surface, SurfaceEmbedding& embedding,
                   SurfaceMappingReport& report, MappingReuse& reuse);

// Elements with a neighbour across the rest cut (its link to the integration point crosses a
// cut triangle): zero when the volume cut agrees with the surface's.
int elements_linked_across(const CorotationalEfg& model, const RestCut& cut);
// The same kept up to date after a cut grew by triangles inside the rest box [lo, hi]:
// `linked` (per element, 1 = linked across) is recomputed for the elements whose links reach
// into the box or that `changed` marks (may be null), all of them when its size is not the
// element count; returns the count. Equal to the full count as long as every triangle added
// since the last call lies in [lo, hi]. `boxes` (may be null) caches each element's link box
// at rest between calls: taken again for the elements `changed` marks, for all when its size
// is not the element count or `changed` is null (also while the cut is empty, so a first call
// can take them before any cut). `seen` (may be null; used with `boxes` and
// `changed`) keeps per element the cut's size when its flag was last taken: an unchanged
// element is then tested against the triangles added since only (it keeps its links and the
// cut only grows: linked before, linked still), with the same outcome as the whole cut's.
// `index` (may be null; used with `boxes` and `changed`) finds the elements whose links can
// reach into [lo, hi] from their centres (at rest, which never move) binned, within the
// largest reach of a cached link box from its centre, instead of looking at every element's
// box: the same elements, the same flags.
struct LinkedAcrossIndex {
  PointBins centres;     // the elements' centres; no items: to be built
  double reach = 0;      // per axis, over the cached boxes (kept as they change: only grows)
  int deactivated = -1;  // the model's deactivated elements when their flags were last cleared
};
int update_elements_linked_across(const CorotationalEfg& model, const RestCut& cut, std::vector<std::uint8_t>& linked,
                                  const Vec3& lo, const Vec3& hi, const std::vector<std::uint8_t>* changed,
                                  std::vector<std::array<Vec3, 2>>* boxes = nullptr, std::vector<int>* seen = nullptr,
                                  LinkedAcrossIndex* index = nullptr);

}  // namespace incise::physics
