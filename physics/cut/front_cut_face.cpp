// Recompute's cut face: the region triangulated, lifted onto the sheet, emitted on both sides
// with the constraint planes (front_recompute.hpp).
#include "physics/cut/front_recompute.hpp"

#include <algorithm>
#include <limits>
#include <set>
#include <stdexcept>
#include <string>

namespace incise::physics {

using namespace front;

// The cut face: the region triangulated (constrained Delaunay), keeping the last sample's
// triangles well behind the front with reuse_face_.
bool FrontSurface::Recompute::triangulate_cut_face() {
  try {
    if (surface.reuse_face_) {
      face = triangulate_face(region, cache, incremental ? &change : nullptr, std::move(next), 1e-6 * w, report.face_triangles_kept);
    } else {
      face = triangulate_region(region);
    }
  } catch (const std::invalid_argument& error) {
    problem(std::string("the cut face could not be triangulated: ") + error.what());
    surface.restore_base();
    return false;
  }
  return true;
}

// Where the blade still is, both sides' faces share the vertices (the crack closes there).
// An inner edge of the face joining two of them would be shared by four triangles: split
// it at its middle, with a vertex of each side's own.
void FrontSurface::Recompute::split_shared_inner_edges() {
  const auto shared = [&](int p) {
    return region_vertex[static_cast<size_t>(p)] >= 0 && region_vertex[static_cast<size_t>(p)] == region_vertex_plus[static_cast<size_t>(p)];
  };
  std::set<std::pair<int, int>> outline_edges;  // the outline's, between two shared vertices
  for (const auto& e : region.boundary)
    if (shared(e[0]) && shared(e[1])) outline_edges.insert({std::min(e[0], e[1]), std::max(e[0], e[1])});
  // Passes over the face's edges (sorted, not a map); a triangle split in a pass waits for
  // the next, so a triangle with two such edges is split twice.
  for (bool again = true; again;) {
    again = false;
    std::vector<std::array<int, 4>> uses;  // (lower, higher, triangle, corner before the edge)
    uses.reserve(3 * face.size());
    for (size_t f = 0; f < face.size(); ++f)
      for (int k = 0; k < 3; ++k) {
        const int u = face[f][static_cast<size_t>(k)], v = face[f][static_cast<size_t>((k + 1) % 3)];
        if (shared(u) && shared(v)) uses.push_back({std::min(u, v), std::max(u, v), static_cast<int>(f), k});
      }
    std::sort(uses.begin(), uses.end());
    std::vector<std::uint8_t> split_now(face.size(), 0);
    for (size_t n = 0; n + 1 < uses.size(); ++n) {
      const auto& x = uses[n];
      const auto& y = uses[n + 1];
      if (x[0] != y[0] || x[1] != y[1] || outline_edges.count({x[0], x[1]})) continue;
      if (split_now[static_cast<size_t>(x[2])] || split_now[static_cast<size_t>(y[2])]) {
        again = true;
        continue;
      }
      const int middle = add_point(0.5 * (region.points[static_cast<size_t>(x[0])] + region.points[static_cast<size_t>(x[1])]), -1, -1);
      for (const auto& use : {x, y}) {
        const size_t f = static_cast<size_t>(use[2]);
        const std::array<int, 3> old = face[f];
        const int k = use[3];
        const int u = old[static_cast<size_t>(k)], v = old[static_cast<size_t>((k + 1) % 3)], opposite = old[static_cast<size_t>((k + 2) % 3)];
        split_now[f] = 1;
        face[f] = {u, middle, opposite};
        face.push_back({middle, v, opposite});
      }
      split_now.resize(face.size(), 1);
      ++n;
    }
  }
}

// A point of the (s, t) rectangle on the sheet: in its cell's triangle.
Vec3 FrontSurface::Recompute::sheet_point(const Vec2& st) const {
  const std::vector<double>& blade_s = surface.blade_s_;
  const std::vector<double>& sample_t = surface.sample_t_;
  const std::vector<std::vector<Vec3>>& samples = surface.samples_;
  const int i = std::clamp(static_cast<int>(std::upper_bound(blade_s.begin(), blade_s.end(), st.x()) - blade_s.begin()) - 1, 0, segments - 1);
  const int j = std::clamp(static_cast<int>(std::upper_bound(sample_t.begin(), sample_t.end(), st.y()) - sample_t.begin()) - 1, 0, intervals - 1);
  const double alpha = (st.x() - blade_s[static_cast<size_t>(i)]) / (blade_s[static_cast<size_t>(i + 1)] - blade_s[static_cast<size_t>(i)]);
  const double beta = (st.y() - sample_t[static_cast<size_t>(j)]) / (sample_t[static_cast<size_t>(j + 1)] - sample_t[static_cast<size_t>(j)]);
  const Vec3& p00 = samples[static_cast<size_t>(j)][static_cast<size_t>(i)];
  const Vec3& p10 = samples[static_cast<size_t>(j)][static_cast<size_t>(i + 1)];
  const Vec3& p01 = samples[static_cast<size_t>(j + 1)][static_cast<size_t>(i)];
  const Vec3& p11 = samples[static_cast<size_t>(j + 1)][static_cast<size_t>(i + 1)];
  if (alpha >= beta) return Vec3(p00 + alpha * (p10 - p00) + beta * (p11 - p10));
  return Vec3(p00 + beta * (p01 - p00) + alpha * (p11 - p01));
}

// Region point p on the sheet. A lattice point in a cell of the sheet between two samples
// before the last is where the last sample put it (FaceCache::lifted: the cell's samples no
// longer change).
Vec3 FrontSurface::Recompute::lift(int p) {
  FaceCache& lattice = stroke.face;  // this sample's, with reuse_face_
  const Vec2& st = region.points[static_cast<size_t>(p)];
  const size_t k = static_cast<size_t>(p - lattice.lattice_begin);
  if (!surface.reuse_face_ || p < lattice.lattice_begin || k >= lattice.column.size()) return sheet_point(st);
  if (lattice.lifted_final[k]) return lattice.lifted[k];
  const Vec3 x = sheet_point(st);
  if (st.y() < fixed_below) {
    lattice.lifted[k] = x;
    lattice.lifted_final[k] = 1;
  }
  return x;
}

// Lift the lattice points the face uses onto the sheet, and take the face's normal at each
// region point.
void FrontSurface::Recompute::lift_inner_points() {
  std::vector<Vec3>& vertices = surface.vertices_;
  fixed_below = intervals >= 2 ? surface.sample_t_[static_cast<size_t>(intervals - 1)] : -std::numeric_limits<double>::infinity();
  for (const auto& triangle : face)
    for (const int p : triangle)
      if (region_vertex[static_cast<size_t>(p)] < 0) {
        // Each side's face has its own inner vertices: the two separate as the cut opens.
        const Vec3 x = lift(p);
        region_vertex[static_cast<size_t>(p)] = static_cast<int>(vertices.size());
        vertices.push_back(x);
        region_vertex_plus[static_cast<size_t>(p)] = static_cast<int>(vertices.size());
        vertices.push_back(x);
        inner_points.push_back(p);
        ++report.lattice_vertices;
      }
  // Their planes: the face's own normal there (the lifted triangles' around the point, as the
  // minus side's face is oriented), so that criterion 3 and the surface agree even where the
  // sheet at rest folds a little between two samples.
  face_normal.assign(region.points.size(), Vec3::Zero());
  for (const auto& triangle : face) {
    const Vec3& a = vertices[static_cast<size_t>(region_vertex[static_cast<size_t>(triangle[0])])];
    const Vec3& b = vertices[static_cast<size_t>(region_vertex[static_cast<size_t>(triangle[1])])];
    const Vec3& c = vertices[static_cast<size_t>(region_vertex[static_cast<size_t>(triangle[2])])];
    const Vec3 n = (b - a).cross(c - a);
    for (const int p : triangle) face_normal[static_cast<size_t>(p)] += n;
  }
  // The slits' middle pairs too: on the face's rim, each on one side (not the crack front).
  // (Their planes are attached in attach_planes, after the cut edges'.)
  inner_points.insert(inner_points.end(), slit_points.begin(), slit_points.end());
}

// The output's triangles: the base's (restore_base); each split's first triangle takes its
// base triangle's slot, the others follow the base's triangles; then the two cut faces.
void FrontSurface::Recompute::emit_triangles() {
  std::vector<std::array<int, 3>>& triangles = surface.triangles_;
  std::vector<std::uint8_t>& cut_face = surface.cut_face_;
  for (const auto& [slot, first, end] : split_ranges) {
    triangles[static_cast<size_t>(slot)] = split[static_cast<size_t>(first)];
    cut_face[static_cast<size_t>(slot)] = split_on_face[static_cast<size_t>(first)];
    surface.replaced_slots_.push_back(slot);
    for (int k = first + 1; k < end; ++k) {
      triangles.push_back(split[static_cast<size_t>(k)]);
      cut_face.push_back(split_on_face[static_cast<size_t>(k)]);
    }
  }
  // The body on the sheet's minus side sees the face with the sheet's normal; the plus side
  // the other way round.
  for (const auto& triangle : face)
    triangles.push_back({region_vertex[static_cast<size_t>(triangle[0])], region_vertex[static_cast<size_t>(triangle[1])],
                         region_vertex[static_cast<size_t>(triangle[2])]});
  for (const auto& triangle : face)
    triangles.push_back({region_vertex_plus[static_cast<size_t>(triangle[0])], region_vertex_plus[static_cast<size_t>(triangle[2])],
                         region_vertex_plus[static_cast<size_t>(triangle[1])]});
  report.cut_face_triangles = static_cast<int>(face.size());
  cut_face.resize(triangles.size(), 1);
}

// Constraint planes (seed 004 §2.6, criterion 3): each end of a cut edge and its copy of the
// pair face across the sheet; so do the cut faces' inner vertices, each on its side.
void FrontSurface::Recompute::attach_planes() {
  const std::vector<Vec3>& vertices = surface.vertices_;
  VertexPlanes& planes = surface.vertex_planes_;
  std::vector<int>& planed_base = surface.planed_base_;
  planes.set_singles(vertices.size() - surface.base_vertices_.size());
  surface.crack_front_.resize(vertices.size(), 0);  // the base's flags, then the stroke's vertices'
  for (const int v : front_vertices) surface.crack_front_[static_cast<size_t>(v)] = 1;
  for (const EdgeCut& cut : cuts) {
    const ConstraintPlane lower{cut.point, cut.lower_on_plus ? Vec3(-cut.normal) : cut.normal};
    const ConstraintPlane higher{cut.point, -lower.normal};
    planes.add(static_cast<size_t>(cut.lower), lower);
    planes.add(static_cast<size_t>(cut.higher), higher);
    planed_base.push_back(cut.lower);
    planed_base.push_back(cut.higher);
    planes.add(static_cast<size_t>(cut.copy_lower), lower);
    planes.add(static_cast<size_t>(cut.copy_higher), higher);
  }
  for (const int p : inner_points) {
    const Vec3& x = vertices[static_cast<size_t>(region_vertex[static_cast<size_t>(p)])];
    const Vec3 normal = face_normal[static_cast<size_t>(p)].normalized();
    planes.add(static_cast<size_t>(region_vertex[static_cast<size_t>(p)]), {x, normal});
    planes.add(static_cast<size_t>(region_vertex_plus[static_cast<size_t>(p)]), {x, -normal});
  }
  std::sort(planed_base.begin(), planed_base.end());
  planed_base.erase(std::unique(planed_base.begin(), planed_base.end()), planed_base.end());
}

}  // namespace incise::physics
