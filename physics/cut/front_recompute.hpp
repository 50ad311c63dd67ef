// FrontSurface::recompute's stages (front_surface.hpp describes them), one method each, in
// files by idea: front_crossings.cpp (the base edges through the sheet, the cut vertices),
// front_outline.cpp (the sheet's outline, its tips, its inside parts), front_split.cpp (the
// touched triangles split along their chords, the slits), front_lattice.cpp (the cut face's
// fixed vertices), front_cut_face.cpp (the face triangulated, lifted onto the sheet, emitted
// with its planes); front_recompute.cpp runs them in order.
#pragma once

#include "physics/cut/front_geometry.hpp"
#include "physics/cut/front_stroke.hpp"
#include "physics/cut/triangulate_2d.hpp"
#include "physics/cut/uniform_grid.hpp"

#include <array>
#include <cstdint>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

namespace incise::physics {

// recompute's stages, one method each, called in this order; what a stage makes for a later
// one is a member. One lives for one call of recompute.
struct FrontSurface::Recompute {
  // A base triangle the outline crosses.
  struct Tip {
    int triangle;
    double position;  // segment index + fraction along the outline
    Vec3 point;
    Vec2 st;
    bool entering;
    int vertex = -1;
  };
  // A segment of the sheet's outline, between two point ids, and the base triangles it crosses.
  struct BoundarySegment {
    int from, to;
    const std::vector<front::OutlineHit>* hits;
  };
  // A touched triangle's cut ends: crossings in its edges' order, then tips in the outline's.
  // An end is a crossing (>= 0: index into cuts) or a tip (< 0: -1 - index into tips). Two
  // are handled; the count is kept whole for the report.
  struct Ends {
    int count = 0;
    std::array<int, 4> at{};
    void add(int end) {
      if (count < 4) at[static_cast<size_t>(count)] = end;
      ++count;
    }
  };

  Recompute(FrontSurface& s, FrontCutReport& r);

  // The stages. Those returning bool return false where recompute stops (the surface then
  // the base's when the report has a problem).
  void cross_base_edges();
  void trace_outline();
  bool place_tips();
  void add_cut_vertices();
  void gather_chord_ends();
  bool split_triangles();
  bool trace_inside_outline();
  void match_last_face();
  void bin_boundary();
  void lay_lattice();
  bool triangulate_cut_face();
  void split_shared_inner_edges();
  void lift_inner_points();
  void emit_triangles();
  void attach_planes();

  // What the stages share.
  static Stroke& stroke_of(FrontSurface& s);
  void problem(const std::string& what) { report.problems.push_back(what); }
  Vec2 st_of(int point, int sample) const {
    return Vec2(surface.blade_s_[static_cast<size_t>(point)], surface.sample_t_[static_cast<size_t>(sample)]);
  }
  Vec2 st_of_id(int id) const {
    const int local = id - points.base_count();
    return st_of(local % point_count, local / point_count);
  }
  std::array<Vec3, 2> box_of(std::initializer_list<int> ids) const;
  std::vector<front::OutlineHit> hits_of(int x, int y) const;
  bool first_sample_inside() const;
  int add_point(const Vec2& st, int minus, int plus);
  int point_of_end(int end);
  int copy_on_side_of(int cut_index, int base_vertex) const;
  void emit(int a, int b, int c);
  void split_at_chord(int t);
  void split_at_tip(int t, const std::array<int, 2>& ends);
  bool split_at_slit(int t, const std::array<int, 2>& ends);
  std::pair<Vec2, Vec3> outline_point(double position) const;
  void add_outline_run(int from_point, double from, double to, int to_point);
  static double distance_to_segment(const Vec2& p, const Vec2& a, const Vec2& b);
  Vec3 sheet_point(const Vec2& st) const;
  Vec3 lift(int p);

  FrontSurface& surface;
  FrontCutReport& report;
  const int point_count, sample_count;
  const int segments, intervals;
  const front::PointTable points;
  Stroke& stroke;
  std::vector<front::EdgeCut>& cuts;  // the stroke's; their output vertices are set at every call
  const std::vector<int>& edge_cut;
  const front::EdgeTable& edges;
  const double w;  // the front's width
  front::FaceCache& cache;  // the last sample's cut face, then this one's (with reuse_face_)

  // trace_outline: the sheet's outline, and the hits of the front (its other hits are the stroke's).
  std::vector<std::vector<front::OutlineHit>> front_hits;
  std::vector<BoundarySegment> outline;
  // place_tips: in order along the outline; with none, whether the outline is in the body.
  std::vector<Tip> tips;
  bool outline_inside = false;
  // add_cut_vertices, trace_inside_outline: the output vertices where the two sides meet.
  std::vector<int> front_vertices;
  // gather_chord_ends: base triangles with a cut end, increasing, and their ends.
  std::vector<int> touched;
  std::vector<Ends> ends_of;

  // The cut face's boundary in (s, t): directed edges, the face on their left.
  PlanarRegion region;
  std::vector<int> region_vertex;  // per region point: output vertex for the minus side (-1: lattice, filled in lift_inner_points)
  std::vector<int> region_vertex_plus;
  std::vector<int> cut_point, tip_point;  // per crossing and tip: its region point, or -1
  std::vector<int> slit_points;  // region points of the slits' middle pairs
  std::vector<std::array<int, 3>> split;  // the base triangles' replacements
  std::vector<std::array<int, 3>> split_ranges;  // per replaced base triangle: {slot, first, end} in split
  std::vector<std::uint8_t> split_on_face;  // per replacement: its base triangle was a cut face
  std::uint8_t splitting_face = 0;

  // The lattice (match_last_face, bin_boundary, lay_lattice): its row spacing, its gap to the
  // boundary, the (s, t) rectangle; the cut face as triangulate_face will keep it (next),
  // what changed since the last sample's (change), the first row made again (r_first), the
  // boundary's edges binned and where they cross each row.
  double row = 0, gap = 0;
  Vec2 extent = Vec2::Zero();
  front::FaceCache next;
  bool incremental = false;
  front::FaceChange change;
  double t_boundary = 0;
  int old_rows = 0, r_first = 1;
  GridCells frame;
  UniformGrid boundary_cells;
  std::vector<std::vector<std::pair<double, int>>> row_crossings;

  // triangulate_cut_face: the face, triangles of region points.
  std::vector<std::array<int, 3>> face;
  // lift_inner_points: lattice points below fixed_below are lifted once; the region points
  // with a vertex of each side's own, and the face's normal at each region point.
  double fixed_below = 0;
  std::vector<int> inner_points;
  std::vector<Vec3> face_normal;
};

inline std::array<Vec3, 2> FrontSurface::Recompute::box_of(std::initializer_list<int> ids) const {
  std::array<Vec3, 2> box{points[*ids.begin()], points[*ids.begin()]};
  for (const int id : ids) {
    box[0] = box[0].cwiseMin(points[id]);
    box[1] = box[1].cwiseMax(points[id]);
  }
  return box;
}

inline int FrontSurface::Recompute::add_point(const Vec2& st, int minus, int plus) {
  region.points.push_back(st);
  region_vertex.push_back(minus);
  region_vertex_plus.push_back(plus);
  return static_cast<int>(region.points.size()) - 1;
}

}  // namespace incise::physics
