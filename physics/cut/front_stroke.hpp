// What FrontSurface keeps between calls (front_surface.hpp): its base's index (Base) and what
// the stroke's fixed part crossed (Stroke), with the cuts and outline hits they hold.
#pragma once

#include "physics/cut/front_binning.hpp"
#include "physics/cut/front_edge_table.hpp"
#include "physics/cut/front_face_reuse.hpp"
#include "physics/cut/front_surface.hpp"

#include <array>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace incise::physics::front {

// A base edge the stroke's sheet crosses: a pair of coincident vertices, one per side.
struct EdgeCut {
  Vec3 point;
  Vec2 st;
  int lower = -1, higher = -1;             // the edge's ends
  bool lower_on_plus = false;              // the lower end is on the sheet's normal side
  Vec3 normal = Vec3::Zero();              // the sheet's there (unit)
  int copy_lower = -1, copy_higher = -1;   // the output vertices on each end's side
};

// A base triangle an outline segment crosses, `along` it from its first point.
struct OutlineHit {
  int triangle;
  double along;
  Vec3 point;
  bool entering;  // the outline goes into the body here
};

}  // namespace incise::physics::front

namespace incise::physics {

struct FrontSurface::Base {
  front::EdgeTable edges;
  front::BoxBins edge_bins, triangle_bins;
  std::vector<int> around_start, around;  // per base vertex, its triangles (compressed rows)
  std::vector<int> cut_face_slots;        // the base's cut-face triangles
};

struct FrontSurface::Stroke {
  int intervals_searched = 0;  // sample intervals whose sheet was searched for crossings
  std::vector<int> edge_cut;   // per base edge: index into cuts, or -1
  std::vector<front::EdgeCut> cuts;
  std::vector<int> cut_edges;  // the base edge of each cut
  std::vector<std::string> problems;  // found in the fixed part, kept for the stroke
  int folded_edges = 0;               // crossings cancelled by a second one (see recompute)
  // Hits of the outline's fixed segments: the first sample's, and each interval's segment of
  // the far end's path (first to last) and the near end's (last to first).
  std::vector<std::vector<front::OutlineHit>> first_sample, far_end, near_end;
  // The last sample's cut face (triangulate_face), not kept by a snapshot: a stroke undone
  // to one triangulates its next face whole.
  front::FaceCache face;

  // What a sample may have to be undone to: all but edge_cut (as long as the base's edges),
  // which follows from cut_edges, and the face's cache.
  Stroke snapshot() const {
    Stroke copy;
    copy.intervals_searched = intervals_searched;
    copy.cuts = cuts;
    copy.cut_edges = cut_edges;
    copy.problems = problems;
    copy.folded_edges = folded_edges;
    copy.first_sample = first_sample;
    copy.far_end = far_end;
    copy.near_end = near_end;
    return copy;
  }
  void restore(Stroke&& from) {
    for (const int e : cut_edges) edge_cut[static_cast<size_t>(e)] = -1;
    std::vector<int> keep = std::move(edge_cut);
    *this = std::move(from);
    edge_cut = std::move(keep);
    for (size_t c = 0; c < cut_edges.size(); ++c) edge_cut[static_cast<size_t>(cut_edges[c])] = static_cast<int>(c);
  }
};

}  // namespace incise::physics
