// FrontSurface::recompute: a sample's cut, its stages (front_recompute.hpp) run in order.
#include "physics/cut/front_recompute.hpp"

#include <memory>

namespace incise::physics {

using namespace front;

FrontSurface::Recompute::Recompute(FrontSurface& s, FrontCutReport& r)
    : surface(s),
      report(r),
      point_count(static_cast<int>(s.samples_.front().size())),
      sample_count(static_cast<int>(s.samples_.size())),
      segments(point_count - 1),
      intervals(sample_count - 1),
      points{&s.base_vertices_, &s.samples_, point_count},
      stroke(stroke_of(s)),
      cuts(stroke.cuts),
      edge_cut(stroke.edge_cut),
      edges(s.base_->edges),
      w(s.front_width_),
      cache(stroke.face) {}

// The stroke's state, made at its first call (with a dropped stroke's per-edge index).
FrontSurface::Stroke& FrontSurface::Recompute::stroke_of(FrontSurface& s) {
  if (!s.stroke_) {
    s.stroke_ = std::make_unique<Stroke>();
    if (s.spare_edge_cut_.size() == s.base_->edges.ends.size())
      s.stroke_->edge_cut = std::move(s.spare_edge_cut_);  // all -1 (drop_stroke)
    else
      s.stroke_->edge_cut.assign(s.base_->edges.ends.size(), -1);
    s.spare_edge_cut_.clear();
  }
  return *s.stroke_;
}

void FrontSurface::recompute(FrontCutReport& report) {
  restore_base();
  if (samples_.size() < 2) return;
  Recompute stages(*this, report);
  stages.cross_base_edges();
  stages.trace_outline();
  if (!stages.place_tips()) return;
  stages.add_cut_vertices();
  stages.gather_chord_ends();
  if (!stages.split_triangles()) return;
  if (!stages.trace_inside_outline()) return;
  stages.match_last_face();
  stages.bin_boundary();
  stages.lay_lattice();
  if (!stages.triangulate_cut_face()) return;
  stages.split_shared_inner_edges();
  stages.lift_inner_points();
  stages.emit_triangles();
  stages.attach_planes();
}

}  // namespace incise::physics
