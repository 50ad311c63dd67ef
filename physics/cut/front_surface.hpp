// The thesis's explicit surface cut (seed 004 §2.5, Fig. 4.3-4.4): a closed triangle mesh in
// the rest configuration, split where the blade's sweep crosses it, its exposed cut face
// meshed behind a moving front: the surface of every cuttable body. The cut stages
// (apply_topology.hpp) feed it the blade mapped to rest at each moment of the sweep and end a
// stroke when the blade disengages or the front has left the body; remap_surface.hpp maps its
// vertices by front_mapping.hpp (what is left to do: docs/status.md, "Cutting").
//
// A stroke is a sequence of blade samples (polylines at rest, same point count). Between two
// samples each blade segment sweeps a quad, split into two triangles; together they form the
// sheet, whose parameter plane (s, t) is exact: s is the arc length along the blade (fixed
// from the first sample) and t the accumulated sweep (the mean distance the blade's points
// moved), so the sheet is the rectangle [0, S] x [0, T] made of one cell per segment and
// sample interval, and its boundary is the first sample (t = 0), the paths of the blade's two
// ends and the last sample, the front (t = T).
//
// Each call recomputes the stroke's cut of the mesh as it was when the stroke began (the
// base): what is behind the front does not depend on the front, so it comes out the same at
// every call, and only the front's part moves (the thesis's transient vertices):
// - Crossings: a base edge crossed by the sheet gets a pair of coincident vertices, one for
//   each side (Fig. 4.3); an edge crossed again the other way by a nearby part of the sheet
//   (within w plus twice the two crossings' distance in space, in (s, t): the sheet at rest
//   folds back over it, where the blade's mapping to rest wavers) is left uncut, a third crossing cuts it again (FrontCutReport::folded_edges); a base triangle crossed by the sheet's boundary holds a
//   tip, one vertex where the two sides meet.
// - Chords: the sheet crosses a base triangle along the straight segment between its two cut
//   ends. Two crossings: the triangle is split three ways; a crossing and a tip: four ways
//   around the tip, which moves with the blade until it crosses the next edge; two tips (a
//   stab that enters and leaves within one triangle): five ways around the slit.
// - Cut face: the chords and the parts of the sheet's boundary inside the body bound a
//   region of the (s, t) plane; it is triangulated (constrained Delaunay,
//   triangulate_2d.hpp) with fixed vertices on a triangular lattice of spacing w behind the
//   front and transient vertices at most w apart along the front and the other parts of
//   the boundary, and lifted onto the sheet. Each side of the body gets a copy: on chords
//   with that side's vertices of the pairs, along the front with the shared ones, so the
//   crack closes where the blade still is and the surface stays a closed 2-manifold. The
//   front widens and narrows (its points re-spaced), splits and merges (several regions)
//   with the region.
// Orientation predicates are evaluated on the four points in a canonical order (sorted by
// id, the sign fixed up by the permutation, zero taken as positive), so every test that
// shares four points sees the same sign and the ends of every triangle pair up: the
// crossings and tips are consistent by construction, whatever the rounding.
//
// What it does not do yet, and reports (FrontCutReport::problems, never silent; the sample
// is left out and the surface stays as the last good sample left it, closed): a base
// triangle with more than two cut ends in one stroke (the sweep turning within one triangle,
// or crossing its own earlier part), a base edge crossed twice otherwise (the sweep
// passing over it again), a stroke starting with the blade inside the body (a cut
// continued from an earlier stroke's front), chords that cross in the (s, t) plane.
//
// Cost: each call keeps the last call's cut-face triangles that lie well behind the front
// (their circumcircle below the lowest t the sample changed) and triangulates only the rest,
// takes the lattice's rows below that t from the last call, and keeps the lift of lattice
// points in the sheet's fixed cells; the rest of the stroke's work (matching the face's
// points, the planes, the output, renumbered at every call) still grows with its face:
// docs/status.md has figures.
//
// The implementation, a file per idea: front_surface.cpp (the strokes: samples taken or left
// out, the base a stroke leaves), front_edge_table.cpp and front_binning.cpp (the base's index),
// front_recompute.hpp (a sample's stages, in front_crossings.cpp, front_outline.cpp,
// front_split.cpp, front_lattice.cpp and front_cut_face.cpp), front_face_reuse.cpp (the cut
// face kept between samples), front_geometry.hpp (the orientation predicates).
#pragma once

#include "physics/core/model.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace incise::physics {

// A plane a surface vertex's integration point must lie below, (x - point) . normal <= 0
// (seed 004 §2.6, criterion 3): attached where a nearby cut was made, its normal pointing
// across the cut, away from the vertex's side.
struct ConstraintPlane {
  Vec3 point = Vec3::Zero();
  Vec3 normal = Vec3::Zero();
};

// Per vertex, its constraint planes: a list each for the first vertices (all of them when
// made from lists), then at most one each for those after. FrontSurface keeps its base's
// vertices in lists (a base vertex at the end of several cut edges has a plane per edge)
// and its stroke's vertices, which get one plane or none and are all made again at every
// sample, in one flat array (no list per vertex to allocate, fill and clear).
class VertexPlanes {
 public:
  VertexPlanes() = default;
  VertexPlanes(std::vector<std::vector<ConstraintPlane>> lists) : lists_(std::move(lists)) {}  // NOLINT: implicit on purpose
  std::size_t size() const { return lists_.size() + singles_; }
  std::span<const ConstraintPlane> operator[](std::size_t v) const {
    if (v < lists_.size()) return lists_[v];
    const std::size_t k = v - lists_.size();
    return {single_.data() + k, has_single_[k] ? std::size_t{1} : std::size_t{0}};
  }
  // Every vertex's planes as lists.
  std::vector<std::vector<ConstraintPlane>> lists() const;

  // For FrontSurface: the listed vertices' lists, and the one-plane vertices after them.
  std::vector<std::vector<ConstraintPlane>>& listed() { return lists_; }
  void set_singles(std::size_t count);  // `count` vertices after the listed ones, with no plane
  void add(std::size_t v, const ConstraintPlane& plane);  // to a list, or a one-plane vertex's only one

 private:
  std::vector<std::vector<ConstraintPlane>> lists_;
  std::vector<ConstraintPlane> single_;  // may be longer than singles_ (kept between samples)
  std::vector<std::uint8_t> has_single_;
  std::size_t singles_ = 0;
};

struct FrontCutReport {
  int crossings = 0;           // base edges the stroke's sheet crosses
  int tips = 0;                // base triangles the sheet's boundary crosses
  int split_triangles = 0;     // base triangles replaced by their three-, four- or five-way split
  int cut_face_triangles = 0;  // per side
  int front_vertices = 0;      // transient vertices on the front and the other inside boundary
  int lattice_vertices = 0;    // fixed vertices inside the cut face
  int face_triangles_kept = 0; // of the last sample's cut face (FrontSurface::reuse_face), per side
  bool front_in_body = false;  // part of the last sample (the front) is inside the body
  int samples_held = 0;        // 1: this sample was left out (back over the cut, or a problem)
  // Base edges the stroke's sheet crossed twice (it folds back over them at rest): left uncut,
  // their two crossings cancelling (an odd count would cut them once).
  int folded_edges = 0;
  // What the cut could not handle (each an explanation naming the triangle or edge). When
  // not empty the sample was left out (samples_held): the surface stays as the stroke's last
  // good sample left it, or the base mesh when there is none.
  std::vector<std::string> problems;
  bool ok() const { return problems.empty(); }
};

class FrontSurface {
 public:
  // A closed, consistently oriented (counter-clockwise seen from outside) triangle mesh at
  // rest. `front_width`: the thesis's w, the largest width of the cut face's triangles (m).
  // Throws std::invalid_argument naming the vertex, triangle or value at fault: a coordinate
  // not finite, an index out of range, a degenerate triangle, w not positive, an edge not
  // used exactly once in each direction.
  FrontSurface(std::vector<Vec3> vertices, std::vector<std::array<int, 3>> triangles, double front_width);
  ~FrontSurface();
  FrontSurface(FrontSurface&&) noexcept;
  FrontSurface& operator=(FrontSurface&&) noexcept;
  // A deep copy: the same surface, stroke and caches, so it cuts on as this one would.
  FrontSurface(const FrontSurface& other);
  FrontSurface& operator=(const FrontSurface& other);

  // A sample whose points moved less than this times w on average since the stroke's last
  // sample is not taken (the cut stays as it is).
  static constexpr double minimum_motion = 0.01;
  // Appends a blade sample to the stroke (the polyline at rest, at least two points, as many
  // as the stroke's first sample) and recomputes the stroke's cut. While the stroke's sheet
  // touches nothing, it starts again from the latest sample, so that a stroke begins at the
  // last sample before the blade meets the body. A sample that moves back over the
  // stroke's cut (against the last sample's motion) is left out: the front waits for the
  // blade to come forward again (FrontCutReport::samples_held). Throws
  // std::invalid_argument naming the point when a coordinate is not finite or the count
  // differs, before anything changes.
  FrontCutReport advance(std::span<const Vec3> blade);
  // Ends the stroke: the surface as cut becomes the base of the next one (its front stays
  // where it is, a crack that closes inside the body). With `reach` > 0 and the front still
  // in the body, the front is first carried on along the stroke's last motion, each blade
  // point by `reach` on average: kept if that takes the whole front out of the body (the
  // cut goes through), else the stroke ends where it was. This is for a blade that left the
  // body while its image at rest, which extrapolates outside the body, stops short of the
  // far side (the world passes w: docs/status.md, cut_torus). Returns whether it was carried
  // through.
  //
  // A stroke whose surface is not a closed, consistently oriented mesh (which the cut's stages
  // are built never to make) does not become the base: the stroke is dropped, the surface
  // stays the last base, and end_problem() says why, for the caller to count with the
  // samples' problems.
  bool end_stroke(double reach = 0);
  // Why the last end_stroke kept the old base rather than the stroke's surface; empty when it
  // did not.
  const std::string& end_problem() const { return end_problem_; }
  int stroke_samples() const { return static_cast<int>(samples_.size()); }
  // Whether a sample keeps the last one's cut-face triangles that lie well behind the front
  // (the default) or triangulates the stroke's whole face again: the same surface either way
  // (its tests compare them), the first's cost following the front rather than the stroke.
  void reuse_face(bool on) { reuse_face_ = on; }

  // The current surface: the base split by the stroke, with its two cut faces.
  const std::vector<Vec3>& vertices() const { return vertices_; }
  const std::vector<std::array<int, 3>>& triangles() const { return triangles_; }
  // Per vertex of vertices(): the constraint planes of the cuts next to it. A base vertex
  // at the end of a cut edge gets the sheet's plane there (facing away from its side) and
  // keeps it across strokes; each vertex of a pair, of a slit's middle pair, and each inner
  // vertex of a cut face, gets the plane of the sheet on its side; the shared vertices along
  // the front get none.
  const VertexPlanes& vertex_planes() const { return vertex_planes_; }
  // Per vertex: 1 where the two sides of a cut meet (the stroke's tips, and the vertices
  // along the front and the other parts of the sheet's outline inside the body; and those
  // of the cracks earlier strokes left inside the body), which belong to neither side.
  const std::vector<std::uint8_t>& crack_front() const { return crack_front_; }
  // Per triangle of triangles(): 1 on a cut face (this stroke's or an earlier one's).
  const std::vector<std::uint8_t>& on_cut_face() const { return cut_face_; }
  // Base vertices keep their index; the stroke's vertices come after them.
  int base_vertex_count() const { return static_cast<int>(base_vertices_.size()); }
  double front_width() const { return front_width_; }

  // What the stroke changed, so that a user can follow the change instead of the surface
  // (the cost of a sample then grows with the stroke, not with the mesh). The base's
  // triangles keep their slots: triangles()[t] for t < base_triangle_count() is the base's
  // triangle t, but for the slots in replaced_slots() (increasing), which hold the first
  // triangle of their split; the splits' other triangles and the cut faces follow the base's.
  // The base's vertices keep their index and rest position, their crack flag and their planes
  // but for those of planed_base_vertices() (the ends of the stroke's cut edges, which gain
  // the sheet's plane).
  int base_triangle_count() const { return static_cast<int>(base_triangles_.size()); }
  const std::vector<int>& replaced_slots() const { return replaced_slots_; }
  const std::vector<int>& planed_base_vertices() const { return planed_base_; }
  // The base's triangles with vertex v (< base_vertex_count()) as a corner, increasing (slots
  // of the base, some of which a stroke may have replaced since), and the base's cut-face
  // triangles.
  std::span<const int> base_triangles_around(int v) const;
  const std::vector<int>& base_cut_face_slots() const;
  // The base's vertices whose rest position lies in the box [lo, hi], increasing (appended
  // to `out`, which is cleared first).
  void base_vertices_in(const Vec3& lo, const Vec3& hi, std::vector<int>& out) const;

 private:
  struct Base;    // the base mesh's edges, and its edges and triangles binned
  struct Stroke;  // what the stroke's fixed part crossed, kept between calls
  struct Recompute;  // recompute's stages, and what they share within one call
  // Indexes the base: `with_edges` holds its edge table already (end_stroke builds it before
  // it adopts a new base); null, it is built here.
  void index_base(std::unique_ptr<Base> with_edges = nullptr);
  void show_base();     // the surface is the base's (copied whole: after a new base)
  void restore_base();  // the same from an output of the base's (undoing only what a stroke changed)
  void recompute(FrontCutReport& report);
  void drop_stroke();  // stroke_.reset(), keeping its per-edge index (all -1) for the next

  double front_width_;
  std::vector<Vec3> base_vertices_;
  std::vector<std::array<int, 3>> base_triangles_;
  std::unique_ptr<Base> base_;
  std::unique_ptr<Stroke> stroke_;
  std::vector<int> spare_edge_cut_;  // a dropped stroke's Stroke::edge_cut, all -1
  std::vector<std::vector<Vec3>> samples_;
  std::vector<double> sample_t_;  // t of each sample
  std::vector<double> blade_s_;   // s of each blade point
  std::vector<std::vector<ConstraintPlane>> base_planes_;
  std::vector<Vec3> vertices_;
  std::vector<std::array<int, 3>> triangles_;
  VertexPlanes vertex_planes_;  // the base's vertices listed, the stroke's one plane or none each
  std::vector<std::uint8_t> crack_front_, base_crack_front_;
  std::vector<std::uint8_t> base_cut_face_, cut_face_;
  std::vector<int> replaced_slots_, planed_base_;
  FrontCutReport last_report_;  // of the last sample taken
  std::string end_problem_;      // why the last end_stroke kept the old base (empty: it did not)
  bool reuse_face_ = true;
};

}  // namespace incise::physics
