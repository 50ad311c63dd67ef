// Recompute's crossings: the base edges through the stroke's sheet, and the output vertices
// they and the tips add (front_recompute.hpp).
#include "physics/cut/front_recompute.hpp"

#include <string>

namespace incise::physics {

using namespace front;

// Crossings: base edges through the sheet, searched once per sample interval, when it is
// added (the sheet behind the front does not change). Per cell (segment i, interval j) two
// triangles, (P00, P10, P11) and (P00, P11, P01), counter-clockwise in (s, t).
void FrontSurface::Recompute::cross_base_edges() {
  const Base& base = *surface.base_;
  for (int j = stroke.intervals_searched; j < intervals; ++j)
    for (int i = 0; i < segments; ++i) {
      const int p00 = points.sheet_id(i, j), p10 = points.sheet_id(i + 1, j), p01 = points.sheet_id(i, j + 1),
                p11 = points.sheet_id(i + 1, j + 1);
      for (const std::array<int, 3>& id : {std::array<int, 3>{p00, p10, p11}, std::array<int, 3>{p00, p11, p01}}) {
        const auto box = box_of({id[0], id[1], id[2]});
        base.edge_bins.near(box[0], box[1], [&](int e) {
          const int a = base.edges.ends[static_cast<size_t>(e)][0], b = base.edges.ends[static_cast<size_t>(e)][1];
          const auto hit = segment_crosses(points, a, b, id[0], id[1], id[2]);
          if (!hit) return;
          if (const int earlier = stroke.edge_cut[static_cast<size_t>(e)]; earlier >= 0) {
            const EdgeCut& first = stroke.cuts[static_cast<size_t>(earlier)];
            const Vec2 st = hit->weights[0] * st_of_id(id[0]) + hit->weights[1] * st_of_id(id[1]) + hit->weights[2] * st_of_id(id[2]);
            const Vec3 point = points[a] + hit->along * (points[b] - points[a]);
            if (first.lower_on_plus == (hit->p_sign < 0) || (st - first.st).norm() > w + 2 * (point - first.point).norm()) {
              // Crossed again the same way, or by a part of the sheet far from the first
              // crossing's (farther on the sheet than in space: the sweep turning back across
              // its own cut), which this stage does not cut.
              stroke.problems.push_back("base edge (" + std::to_string(a) + ", " + std::to_string(b) + ") is crossed twice by one stroke");
              return;
            }
            // Crossed again the other way, by a nearby part of the sheet: the sheet at rest
            // folds back over the edge (where the blade's mapping to rest wavers). Both ends
            // are on one side again and the edge is not cut; what the two crossings cut out of
            // the sheet between them is a sliver as wide as the fold, and the triangles around
            // it keep an even count of cut ends.
            stroke.cuts.erase(stroke.cuts.begin() + earlier);
            stroke.cut_edges.erase(stroke.cut_edges.begin() + earlier);
            stroke.edge_cut[static_cast<size_t>(e)] = -1;
            for (size_t c = static_cast<size_t>(earlier); c < stroke.cut_edges.size(); ++c)
              stroke.edge_cut[static_cast<size_t>(stroke.cut_edges[c])] = static_cast<int>(c);
            ++stroke.folded_edges;
            return;
          }
          EdgeCut cut;
          cut.point = points[a] + hit->along * (points[b] - points[a]);
          cut.st = hit->weights[0] * st_of_id(id[0]) + hit->weights[1] * st_of_id(id[1]) + hit->weights[2] * st_of_id(id[2]);
          cut.lower = a;
          cut.higher = b;
          cut.lower_on_plus = hit->p_sign < 0;
          cut.normal = (points[id[1]] - points[id[0]]).cross(points[id[2]] - points[id[0]]).normalized();
          stroke.edge_cut[static_cast<size_t>(e)] = static_cast<int>(stroke.cuts.size());
          stroke.cuts.push_back(cut);
          stroke.cut_edges.push_back(e);
        });
      }
    }
  stroke.intervals_searched = intervals;
  report.problems = stroke.problems;
  report.folded_edges = stroke.folded_edges;
  report.crossings = static_cast<int>(cuts.size());
}

// The output's vertices: base, then a pair per crossing, then a vertex per tip.
void FrontSurface::Recompute::add_cut_vertices() {
  std::vector<Vec3>& vertices = surface.vertices_;
  for (EdgeCut& cut : cuts) {
    cut.copy_lower = static_cast<int>(vertices.size());
    vertices.push_back(cut.point);
    cut.copy_higher = static_cast<int>(vertices.size());
    vertices.push_back(cut.point);
  }
  for (Tip& tip : tips) {
    tip.vertex = static_cast<int>(vertices.size());
    front_vertices.push_back(tip.vertex);
    vertices.push_back(tip.point);
  }
}

}  // namespace incise::physics
