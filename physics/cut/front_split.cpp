// Recompute's splitting: each base triangle the sheet crosses split along its chord, three,
// four or five ways, a slit where two tips share it (front_recompute.hpp).
#include "physics/cut/front_recompute.hpp"

#include <algorithm>
#include <string>

namespace incise::physics {

using namespace front;

namespace {

// Triangulates a small polygon lying in a plane of normal n by clipping ears. The polygon
// comes in the order its triangles must keep (the base triangle's, so that they share each
// edge with their neighbours the other way round), and every triangle keeps it, whatever the
// geometry says: an ear is taken where the polygon turns counter-clockwise about n, and where
// none does (a sliver, rounding) one is clipped anyway, still in that order. A vertex on the
// line of its neighbours (the slit's middle) is never an ear: it is clipped last, with a
// vertex off that line.
void ear_clip(std::vector<int> polygon, const Vec3& n, const std::vector<Vec3>& positions, std::vector<std::array<int, 3>>& out) {
  const auto at = [&](int id) -> const Vec3& { return positions[static_cast<size_t>(id)]; };
  const auto turn = [&](int a, int b, int c) { return (at(b) - at(a)).cross(at(c) - at(a)).dot(n); };
  while (polygon.size() > 3) {
    const size_t m = polygon.size();
    size_t best = m;
    double best_turn = 0;
    for (size_t k = 0; k < m; ++k) {
      const int a = polygon[(k + m - 1) % m], b = polygon[k], c = polygon[(k + 1) % m];
      const double area = turn(a, b, c);
      if (!(area > 0)) continue;
      bool empty = true;
      for (size_t j = 0; j < m && empty; ++j) {
        const int p = polygon[j];
        if (p == a || p == b || p == c) continue;
        empty = !(turn(a, b, p) >= 0 && turn(b, c, p) >= 0 && turn(c, a, p) >= 0);
      }
      // The fattest ear, so that slivers are left for last.
      if (empty && (best == m || area > best_turn)) {
        best = k;
        best_turn = area;
      }
    }
    if (best == m) best = 0;  // no ear (a degenerate polygon): clip anyway
    out.push_back({polygon[(best + m - 1) % m], polygon[best], polygon[(best + 1) % m]});
    polygon.erase(polygon.begin() + static_cast<long>(best));
  }
  out.push_back({polygon[0], polygon[1], polygon[2]});
}

}  // namespace

// Chords: the two cut ends of every base triangle the sheet crosses.
void FrontSurface::Recompute::gather_chord_ends() {
  for (size_t c = 0; c < stroke.cut_edges.size(); ++c)
    for (const int t : edges.triangles[static_cast<size_t>(stroke.cut_edges[c])]) touched.push_back(t);
  for (const Tip& tip : tips) touched.push_back(tip.triangle);
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  ends_of.resize(touched.size());
  for (size_t i = 0; i < touched.size(); ++i)
    for (int k = 0; k < 3; ++k)
      if (const int c = edge_cut[static_cast<size_t>(edges.of_triangle[static_cast<size_t>(touched[i])][static_cast<size_t>(k)])]; c >= 0) ends_of[i].add(c);
  for (size_t k = 0; k < tips.size(); ++k)
    ends_of[static_cast<size_t>(std::lower_bound(touched.begin(), touched.end(), tips[k].triangle) - touched.begin())].add(-1 - static_cast<int>(k));
}

// The region point of a cut end (see Ends), added at its first use.
int FrontSurface::Recompute::point_of_end(int end) {
  if (end >= 0) {
    if (cut_point[static_cast<size_t>(end)] < 0) {
      const EdgeCut& cut = cuts[static_cast<size_t>(end)];
      const int minus = cut.lower_on_plus ? cut.copy_higher : cut.copy_lower;
      const int plus = cut.lower_on_plus ? cut.copy_lower : cut.copy_higher;
      cut_point[static_cast<size_t>(end)] = add_point(cut.st, minus, plus);
    }
    return cut_point[static_cast<size_t>(end)];
  }
  const size_t k = static_cast<size_t>(-1 - end);
  if (tip_point[k] < 0) tip_point[k] = add_point(tips[k].st, tips[k].vertex, tips[k].vertex);
  return tip_point[k];
}

int FrontSurface::Recompute::copy_on_side_of(int cut_index, int base_vertex) const {
  const EdgeCut& cut = cuts[static_cast<size_t>(cut_index)];
  return base_vertex == cut.lower ? cut.copy_lower : cut.copy_higher;
}

void FrontSurface::Recompute::emit(int a, int b, int c) {
  split.push_back({a, b, c});
  split_on_face.push_back(splitting_face);
}

// Each touched triangle split along its chord (three, four or five ways, by its ends), the
// chord added to the cut face's boundary.
bool FrontSurface::Recompute::split_triangles() {
  cut_point.assign(cuts.size(), -1);
  tip_point.assign(tips.size(), -1);
  for (size_t touched_index = 0; touched_index < touched.size(); ++touched_index) {
    const int t = touched[touched_index];
    const Ends& ends_here = ends_of[touched_index];
    if (ends_here.count != 2) {
      problem("base triangle " + std::to_string(t) + " has " + std::to_string(ends_here.count) +
              " cut ends in one stroke (this stage handles two)");
      continue;
    }
    const std::array<int, 2> ends{ends_here.at[0], ends_here.at[1]};
    const int split_first = static_cast<int>(split.size());
    splitting_face = surface.base_cut_face_[static_cast<size_t>(t)];
    ++report.split_triangles;
    const int crossings = (ends[0] >= 0) + (ends[1] >= 0);
    if (crossings == 2)
      split_at_chord(t);
    else if (crossings == 1)
      split_at_tip(t, ends);
    else if (!split_at_slit(t, ends))
      continue;
    split_ranges.push_back({t, split_first, static_cast<int>(split.size())});
  }
  if (!report.ok()) {
    surface.restore_base();
    return false;
  }
  return true;
}

// Two crossings: three triangles.
void FrontSurface::Recompute::split_at_chord(int t) {
  const std::vector<Vec3>& vertices = surface.vertices_;
  const auto& tri = surface.base_triangles_[static_cast<size_t>(t)];
  // Rotate so that the crossings are on (a, b) and (b, c): b is alone on its side.
  int k0 = -1;
  for (int k = 0; k < 3; ++k)
    if (edge_cut[static_cast<size_t>(edges.of_triangle[t][static_cast<size_t>(k)])] >= 0 &&
        edge_cut[static_cast<size_t>(edges.of_triangle[t][static_cast<size_t>((k + 1) % 3)])] >= 0)
      k0 = k;
  const int a = tri[static_cast<size_t>(k0)], b = tri[static_cast<size_t>((k0 + 1) % 3)], c = tri[static_cast<size_t>((k0 + 2) % 3)];
  const int p = edge_cut[static_cast<size_t>(edges.of_triangle[t][static_cast<size_t>(k0)])];
  const int q = edge_cut[static_cast<size_t>(edges.of_triangle[t][static_cast<size_t>((k0 + 1) % 3)])];
  const int pb = copy_on_side_of(p, b), qb = copy_on_side_of(q, b), pa = copy_on_side_of(p, a), qc = copy_on_side_of(q, c);
  emit(pb, b, qb);
  // The quad (a, p, q, c) is convex (a corner cut off a triangle): its shorter diagonal.
  if ((vertices[static_cast<size_t>(a)] - vertices[static_cast<size_t>(qc)]).norm() <=
      (vertices[static_cast<size_t>(pa)] - vertices[static_cast<size_t>(c)]).norm()) {
    emit(a, pa, qc);
    emit(a, qc, c);
  } else {
    emit(a, pa, c);
    emit(pa, qc, c);
  }
  // b on the normal side of the sheet: the body (inside, left of the chord in (s, t)) is
  // reached from q to p.
  const bool b_plus = cuts[static_cast<size_t>(p)].lower_on_plus == (b == std::min(a, b));
  const int from = point_of_end(b_plus ? q : p), to = point_of_end(b_plus ? p : q);
  region.boundary.push_back({from, to});
}

// A crossing and a tip: four triangles around the tip.
void FrontSurface::Recompute::split_at_tip(int t, const std::array<int, 2>& ends) {
  const auto& tri = surface.base_triangles_[static_cast<size_t>(t)];
  const int cut_index = ends[0] >= 0 ? ends[0] : ends[1];
  const int tip_end = ends[0] >= 0 ? ends[1] : ends[0];
  const Tip& tip = tips[static_cast<size_t>(-1 - tip_end)];
  int k0 = -1;
  for (int k = 0; k < 3; ++k)
    if (edge_cut[static_cast<size_t>(edges.of_triangle[t][static_cast<size_t>(k)])] == cut_index) k0 = k;
  const int a = tri[static_cast<size_t>(k0)], b = tri[static_cast<size_t>((k0 + 1) % 3)], c = tri[static_cast<size_t>((k0 + 2) % 3)];
  emit(a, copy_on_side_of(cut_index, a), tip.vertex);
  emit(copy_on_side_of(cut_index, b), b, tip.vertex);
  emit(b, c, tip.vertex);
  emit(c, a, tip.vertex);
  // Where the outline goes into the body, the face's boundary comes along the chord to the
  // tip and goes on along the outline.
  const int cut_end = point_of_end(cut_index), tip_end_point = point_of_end(tip_end);
  if (tip.entering)
    region.boundary.push_back({cut_end, tip_end_point});
  else
    region.boundary.push_back({tip_end_point, cut_end});
}

// Two tips: a slit between them, with a pair of vertices at its middle (so that its two lips
// are different edges), and seven triangles around it (see front_surface.hpp). False, with a
// problem, when the two tips go the same way.
bool FrontSurface::Recompute::split_at_slit(int t, const std::array<int, 2>& ends) {
  std::vector<Vec3>& vertices = surface.vertices_;
  const auto& tri = surface.base_triangles_[static_cast<size_t>(t)];
  const int i1 = -1 - ends[0], i2 = -1 - ends[1];
  if (tips[static_cast<size_t>(i1)].entering == tips[static_cast<size_t>(i2)].entering) {
    problem("base triangle " + std::to_string(t) + " holds two tips going the same way");
    return false;
  }
  const int enter = tips[static_cast<size_t>(i1)].entering ? i1 : i2, leave = enter == i1 ? i2 : i1;
  const Tip& t1 = tips[static_cast<size_t>(leave)];
  const Tip& t2 = tips[static_cast<size_t>(enter)];
  const Vec3 n = (vertices[static_cast<size_t>(tri[1])] - vertices[static_cast<size_t>(tri[0])])
                     .cross(vertices[static_cast<size_t>(tri[2])] - vertices[static_cast<size_t>(tri[0])]);
  const Vec3 direction = t2.point - t1.point;
  std::array<bool, 3> left{};
  for (int k = 0; k < 3; ++k)
    left[static_cast<size_t>(k)] = n.dot(direction.cross(vertices[static_cast<size_t>(tri[static_cast<size_t>(k)])] - t1.point)) >= 0;
  int lone = 0;
  for (int k = 0; k < 3; ++k)
    if (left[static_cast<size_t>(k)] != left[static_cast<size_t>((k + 1) % 3)] && left[static_cast<size_t>(k)] != left[static_cast<size_t>((k + 2) % 3)])
      lone = k;
  // v0 is alone on its side of the slit's line; (v0, va, vb) keeps the base triangle's
  // counter-clockwise order. That line crosses the edges (v0, va) and (v0, vb), and with v0 on
  // its left (about n) the crossing on (v0, vb) is the one ahead along t1 -> t2 (the triangle
  // v0 and the two crossings make turns the same way as the base triangle): the tip ahead, t2,
  // faces vb, and t1 faces va; with v0 on its right, the other way round. Taking the pairing
  // from the side, rather than from the vertices' own order along t1 -> t2 (which differs on
  // an obtuse triangle), and orienting the pieces by the base triangle's order rather than by
  // their area, every edge is used once each way whatever the rounding: the mesh stays closed
  // and consistently oriented.
  const int v0 = tri[static_cast<size_t>(lone)], va = tri[static_cast<size_t>((lone + 1) % 3)], vb = tri[static_cast<size_t>((lone + 2) % 3)];
  const bool v0_left = left[static_cast<size_t>(lone)];
  const int ta = v0_left ? t1.vertex : t2.vertex, tb = v0_left ? t2.vertex : t1.vertex;
  const int middle_a = static_cast<int>(vertices.size()), middle_b = middle_a + 1;
  vertices.push_back(0.5 * (t1.point + t2.point));
  vertices.push_back(0.5 * (t1.point + t2.point));
  ear_clip({v0, va, ta}, n, vertices, split);
  ear_clip({vb, v0, tb}, n, vertices, split);
  ear_clip({v0, ta, middle_a, tb}, n, vertices, split);  // v0's lip
  ear_clip({ta, va, vb, tb, middle_b}, n, vertices, split);
  split_on_face.resize(split.size(), splitting_face);
  // The face on the sheet's minus side runs leave -> middle -> enter, so the lip of the
  // minus side runs enter -> middle -> leave: v0's lip runs ta -> middle_a -> tb.
  const bool a_is_minus = ta == t2.vertex;
  const int middle_minus = a_is_minus ? middle_a : middle_b, middle_plus = a_is_minus ? middle_b : middle_a;
  const int middle_point = add_point(0.5 * (t1.st + t2.st), middle_minus, middle_plus);
  slit_points.push_back(middle_point);
  region.boundary.push_back({point_of_end(-1 - leave), middle_point});
  region.boundary.push_back({middle_point, point_of_end(-1 - enter)});
  return true;
}

}  // namespace incise::physics
