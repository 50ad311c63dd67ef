// The report's beams (bench/accuracy_beams.hpp): the cases, their sections (the hexagon's
// triangular lattice, the square's grid, the graded rows of the cut references) extruded along
// x into tets, the 10-node tets made from them, the opened cut and the tip face's mean.
#include "bench/accuracy_beams.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

namespace incise::bench::accuracy {

using physics::QuadraticTetMesh;
using physics::TetMesh;
using Index = Eigen::Index;

double hexagon_half_height() { return hexagon_radius * std::sqrt(3.0) / 2; }


std::vector<Case> all_cases() {
  return {{"bend", Shape::hexagon, Vec3(0, 0, -gravity), false},
          {"stretch", Shape::hexagon, Vec3(gravity, 0, 0), false},
          {"bend_cut", Shape::hexagon, Vec3(0, 0, -gravity), true},
          {"stretch_cut", Shape::hexagon, Vec3(gravity, 0, 0), true},
          {"b1", Shape::square, Vec3(0, 0, -gravity), false}};
}

bool inside_shape(Shape shape, const Vec3& p) {
  if (p.x() < 0 || p.x() > beam_length) return false;
  if (shape == Shape::square) {
    return std::abs(p.y()) <= square_half_side && std::abs(p.z()) <= square_half_side;
  }
  // Regular hexagon with vertices (+-R, 0) and (+-R/2, +-R sqrt(3)/2).
  const double y = std::abs(p.y()), z = std::abs(p.z());
  return z <= hexagon_half_height() && std::sqrt(3.0) * y + z <= std::sqrt(3.0) * hexagon_radius;
}

Vec3 box_min(Shape shape) {
  return shape == Shape::square ? Vec3(0, -square_half_side, -square_half_side)
                                : Vec3(0, -hexagon_radius, -hexagon_half_height());
}

Vec3 box_max(Shape shape) {
  return shape == Shape::square ? Vec3(beam_length, square_half_side, square_half_side)
                                : Vec3(beam_length, hexagon_radius, hexagon_half_height());
}

// ---------------------------------------------------------------------------------------------
// Sections and meshes.


// The hexagon filled with a triangular lattice of spacing R / m: lattice point (i, j) at
// R/m (i + j/2, j sqrt(3)/2) for |i|, |j|, |i + j| <= m. Its lines j = const include z = 0,
// where the cut ends, and its border is exactly the hexagon.
Section hexagon_section(int m) {
  Section section;
  std::map<std::pair<int, int>, int> index;
  for (int j = -m; j <= m; ++j) {
    for (int i = -m; i <= m; ++i) {
      if (std::abs(i + j) > m) continue;
      index[{i, j}] = static_cast<int>(section.points.size());
      section.points.emplace_back(hexagon_radius / m * (i + 0.5 * j),
                                  hexagon_radius / m * (std::sqrt(3.0) / 2 * j));
    }
  }
  const auto find = [&](int i, int j) {
    const auto it = index.find({i, j});
    return it == index.end() ? -1 : it->second;
  };
  for (int j = -m; j < m; ++j) {
    for (int i = -m; i < m; ++i) {
      const int a = find(i, j), b = find(i + 1, j), c = find(i, j + 1), d = find(i + 1, j + 1);
      if (a >= 0 && b >= 0 && c >= 0) section.triangles.push_back({a, b, c});
      if (b >= 0 && d >= 0 && c >= 0) section.triangles.push_back({b, d, c});
    }
  }
  return section;
}

// The square section as a grid of cells x cells squares, two triangles each.
Section square_section(int cells) {
  Section section;
  const double step = 2 * square_half_side / cells;
  for (int j = 0; j <= cells; ++j) {
    for (int i = 0; i <= cells; ++i) {
      section.points.emplace_back(-square_half_side + i * step, -square_half_side + j * step);
    }
  }
  for (int j = 0; j < cells; ++j) {
    for (int i = 0; i < cells; ++i) {
      const int a = i + (cells + 1) * j, b = a + 1, c = a + cells + 1, d = c + 1;
      section.triangles.push_back({a, b, d});
      section.triangles.push_back({a, d, c});
    }
  }
  return section;
}

double triangle_area(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  const Eigen::Vector2d u = b - a, v = c - a;
  return 0.5 * std::abs(u.x() * v.y() - u.y() * v.x());
}

// The cut references' section: rows of constant z graded towards z = 0, where the cut ends
// (z_j = H sign(j) |j / nz|^power, j = -nz..nz), each row split into `ny` equal intervals
// across the hexagon's width there (|y| <= R - |z| / sqrt 3), neighbouring rows joined by two
// triangles per interval. Unlike the lattice, the resolution across the crack front (z) is
// independent of the one along it (y): the crack's field varies along y only near the
// section's corners, so y needs few intervals while the reference needs many rows (see
// crack_layers; the mesh study: docs/physics-choices.md, "Accuracy references").
Section hexagon_row_section(int ny, int nz, double power) {
  const double h = hexagon_half_height();
  Section section;
  for (int j = -nz; j <= nz; ++j) {
    const double z = std::copysign(h * std::pow(std::abs(static_cast<double>(j)) / nz, power), j);
    const double half_width = hexagon_radius - std::abs(z) / std::sqrt(3.0);
    for (int i = 0; i <= ny; ++i) section.points.emplace_back(half_width * (2.0 * i / ny - 1), z);
  }
  const auto at = [ny](int row, int i) { return row * (ny + 1) + i; };
  for (int row = 0; row < 2 * nz; ++row) {
    for (int i = 0; i < ny; ++i) {
      section.triangles.push_back({at(row, i), at(row, i + 1), at(row + 1, i)});
      section.triangles.push_back({at(row, i + 1), at(row + 1, i + 1), at(row + 1, i)});
    }
  }
  return section;
}

// The cut references' layers along x: within H of the crack plane, the section's rows mirrored
// (x = cut_x +- z_j), so the elements around the crack front are as long in x as in z; beyond,
// layers twice the size of the outermost graded one, graded towards the clamp with `power`
// and uniform towards the tip (their count barely matters against the rows': the mesh study
// in docs/physics-choices.md, "Accuracy references").
std::vector<double> crack_layers(int nz, double power) {
  const double h = hexagon_half_height();
  std::vector<double> offsets;  // from the crack plane, 0 .. H
  for (int j = 0; j <= nz; ++j) offsets.push_back(h * std::pow(static_cast<double>(j) / nz, power));
  const double far = 2 * (offsets[nz] - offsets[nz - 1]);
  std::vector<double> x;
  const int clamp_side = std::max(1, static_cast<int>(std::ceil((cut_x - h) / far)));
  for (int k = 0; k < clamp_side; ++k) x.push_back((cut_x - h) * std::pow(static_cast<double>(k) / clamp_side, power));
  for (int j = nz; j >= 1; --j) x.push_back(cut_x - offsets[j]);
  for (int j = 0; j <= nz; ++j) x.push_back(cut_x + offsets[j]);
  const int tip_side = std::max(1, static_cast<int>(std::ceil((beam_length - cut_x - h) / far)));
  for (int k = 1; k <= tip_side; ++k) x.push_back(cut_x + h + (beam_length - cut_x - h) * k / tip_side);
  return x;
}
// (crack_section_ny, the intervals along y in the cut references' sections: accuracy_beams.hpp.)

// Layer positions along x, graded with the power law `power` towards the singular lines: the
// clamped end x = 0 and, for the cut, both sides of x = cut_x (`layers` even, so that x = cut_x
// is a layer). On an interval graded at both ends, x = t^p / (t^p + (1 - t)^p).
std::vector<double> layer_positions(int layers, bool cut, double power) {
  std::vector<double> x(layers + 1);
  const auto towards_start = [power](double t) { return std::pow(t, power); };
  const auto towards_both = [power](double t) {
    return std::pow(t, power) / (std::pow(t, power) + std::pow(1 - t, power));
  };
  for (int k = 0; k <= layers; ++k) {
    if (!cut) {
      // Milder: only the clamp is singular.
      x[k] = beam_length * std::pow(static_cast<double>(k) / layers, std::sqrt(power));
      continue;
    }
    const int half = layers / 2;
    x[k] = k <= half ? cut_x * towards_both(static_cast<double>(k) / half)
                     : cut_x + (beam_length - cut_x) * towards_start(static_cast<double>(k - half) / half);
  }
  return x;
}

// The section extruded into slabs along x, each triangular prism split into 3 tets by the
// usual rule on sorted corner indices (the quad faces get the same diagonal from both sides,
// so the mesh is conforming).
TetMesh extrude(const Section& section, const std::vector<double>& layer_x) {
  TetMesh mesh;
  const int count = static_cast<int>(section.points.size());
  const int layers = static_cast<int>(layer_x.size()) - 1;
  mesh.rest.resize(3 * static_cast<Index>(count) * (layers + 1));
  for (int k = 0; k <= layers; ++k) {
    for (int s = 0; s < count; ++s) {
      mesh.rest.segment<3>(3 * (s + static_cast<Index>(count) * k)) =
          Vec3(layer_x[k], section.points[s].x(), section.points[s].y());
    }
  }
  for (int k = 0; k < layers; ++k) {
    for (auto triangle : section.triangles) {
      std::sort(triangle.begin(), triangle.end());
      const int bottom = count * k, top = count * (k + 1);
      const int a0 = triangle[0] + bottom, b0 = triangle[1] + bottom, c0 = triangle[2] + bottom;
      const int a1 = triangle[0] + top, b1 = triangle[1] + top, c1 = triangle[2] + top;
      for (std::array<int, 4> tet : {std::array{a0, b0, c0, a1}, std::array{b0, c0, a1, b1},
                                     std::array{c0, a1, b1, c1}}) {
        physics::Mat3 shape;
        for (int c = 0; c < 3; ++c) {
          shape.col(c) = mesh.rest.segment<3>(3 * tet[c + 1]) - mesh.rest.segment<3>(3 * tet[0]);
        }
        if (shape.determinant() < 0) std::swap(tet[1], tet[2]);
        mesh.tets.push_back(tet);
      }
    }
  }
  return mesh;
}


QuadraticMesh make_quadratic(const TetMesh& linear) {
  QuadraticMesh result;
  std::vector<Vec3> nodes;
  for (Index n = 0; n < linear.rest.size() / 3; ++n) nodes.push_back(linear.rest.segment<3>(3 * n));
  for (const auto& tet : linear.tets) {
    std::array<int, 10> quadratic{};
    for (int c = 0; c < 4; ++c) quadratic[c] = tet[c];
    for (int e = 0; e < 6; ++e) {
      const int a = tet[physics::quadratic_tet_edges[e][0]];
      const int b = tet[physics::quadratic_tet_edges[e][1]];
      const std::pair<int, int> key{std::min(a, b), std::max(a, b)};
      auto it = result.midpoints.find(key);
      if (it == result.midpoints.end()) {
        it = result.midpoints.emplace(key, static_cast<int>(nodes.size())).first;
        nodes.push_back(0.5 * (nodes[a] + nodes[b]));
      }
      quadratic[4 + e] = it->second;
    }
    result.mesh.tets.push_back(quadratic);
  }
  result.mesh.rest.resize(3 * static_cast<Index>(nodes.size()));
  for (size_t n = 0; n < nodes.size(); ++n) result.mesh.rest.segment<3>(3 * n) = nodes[n];
  return result;
}

// Quarter-point elements at the crack front (Barsoum 1976): on every edge with one end on the
// front (x = cut_x, z = 0) the midside node moves to a quarter of the edge from that end, so
// the elements around the front carry the 1 / sqrt r strain of a crack tip instead of
// smoothing it; edges along the front keep their midpoints.
void quarter_points_at_crack_front(QuadraticMesh& quadratic) {
  Vector& rest = quadratic.mesh.rest;
  const auto on_front = [&](int node) {
    return std::abs(rest[3 * node] - cut_x) < 1e-12 && std::abs(rest[3 * node + 2]) < 1e-12;
  };
  for (const auto& tet : quadratic.mesh.tets) {
    for (int e = 0; e < 6; ++e) {
      const int a = tet[physics::quadratic_tet_edges[e][0]], b = tet[physics::quadratic_tet_edges[e][1]];
      if (on_front(a) == on_front(b)) continue;
      const int front = on_front(a) ? a : b, other = on_front(a) ? b : a;
      rest.segment<3>(3 * tet[4 + e]) = rest.segment<3>(3 * front) + 0.25 * (rest.segment<3>(3 * other) - rest.segment<3>(3 * front));
    }
  }
}

// Opens the cut: nodes on x = cut_x with z > 0 get a twin used by the tets on the x < cut_x
// side. Nodes at z = 0 stay shared: they are the crack front.
template <std::size_t corners>
void open_cut(Vector& rest, std::vector<std::array<int, corners>>& tets) {
  std::map<int, int> twin;
  std::vector<Vec3> added;
  const Index original = rest.size() / 3;
  for (auto& tet : tets) {
    double centroid_x = 0;
    for (int c = 0; c < 4; ++c) centroid_x += rest[3 * tet[c]] / 4;
    if (centroid_x >= cut_x) continue;
    for (int& node : tet) {
      const Vec3 p = rest.segment<3>(3 * node);
      if (std::abs(p.x() - cut_x) > 1e-12 || p.z() <= 1e-12) continue;
      auto it = twin.find(node);
      if (it == twin.end()) {
        it = twin.emplace(node, static_cast<int>(original + added.size())).first;
        added.push_back(p);
      }
      node = it->second;
    }
  }
  rest.conservativeResize(3 * (original + static_cast<Index>(added.size())));
  for (size_t n = 0; n < added.size(); ++n) rest.segment<3>(3 * (original + n)) = added[n];
}
template void open_cut<4>(Vector&, std::vector<std::array<int, 4>>&);
template void open_cut<10>(Vector&, std::vector<std::array<int, 10>>&);

// Triangles of the tip face (x = L) of a linear mesh, with their areas.
std::vector<std::pair<std::array<int, 3>, double>> tip_triangles(const TetMesh& mesh) {
  std::vector<std::pair<std::array<int, 3>, double>> result;
  for (const auto& triangle : physics::boundary_triangles(mesh.tets)) {
    bool on_tip = true;
    for (int node : triangle) on_tip = on_tip && std::abs(mesh.rest[3 * node] - beam_length) < 1e-12;
    if (!on_tip) continue;
    const Vec3 a = mesh.rest.segment<3>(3 * triangle[0]), b = mesh.rest.segment<3>(3 * triangle[1]),
               c = mesh.rest.segment<3>(3 * triangle[2]);
    result.push_back({triangle, 0.5 * (b - a).cross(c - a).norm()});
  }
  return result;
}

// Area-weighted mean over the tip face of a linear field (the mean of the corners per
// triangle) or of a quadratic one (the 6-node triangle integrates to the mean of its
// midpoints: its corner functions integrate to zero).
Vec3 tip_mean(const TetMesh& linear, const Vector& u, const QuadraticMesh* quadratic) {
  Vec3 sum = Vec3::Zero();
  double area = 0;
  for (const auto& [triangle, triangle_area] : tip_triangles(linear)) {
    Vec3 mean = Vec3::Zero();
    for (int e = 0; e < 3; ++e) {
      if (quadratic != nullptr) {
        const int a = triangle[e], b = triangle[(e + 1) % 3];
        mean += u.segment<3>(3 * quadratic->midpoints.at({std::min(a, b), std::max(a, b)})) / 3;
      } else {
        mean += u.segment<3>(3 * triangle[e]) / 3;
      }
    }
    sum += triangle_area * mean;
    area += triangle_area;
  }
  return sum / area;
}

std::vector<uint8_t> clamped_nodes(const Vector& rest) {
  return physics::nodes_in_box(rest, Vec3::Constant(-1), Vec3(1e-9, 1, 1));
}

// A tet mesh of a case's body at a resolution: `section` lattice subdivisions (hexagon) or
// cells per side (square), `layers` along x. `graded`: refined towards the clamp, and for the
// cut cases (their references) towards the crack front: then `section` is the number of rows
// on either side of z = 0 (hexagon_row_section, crack_layers) and `layers` is not used. The
// real-time tet4 rows stay uniform.
constexpr double grading_power = 2.0;
// crack_grading_power (accuracy_beams.hpp), 1.5 for the cut references: quarter-point elements
// take the crack front's singularity, so a milder grading does better (stretch_cut on 3 lattice
// rows, the tip: power 1 -91.6, 1.5 -92.3, 2.5 -91.5 um; without quarter points, at the same
// rows, -86.7 um).
TetMesh case_mesh(const Case& c, int section, int layers, bool graded) {
  const double power = graded ? (c.cut ? crack_grading_power : grading_power) : 1.0;
  if (c.shape == Shape::square) {
    return extrude(square_section(section), layer_positions(layers, false, power));
  }
  if (graded && c.cut) {
    return extrude(hexagon_row_section(crack_section_ny, section, power), crack_layers(section, power));
  }
  return extrude(hexagon_section(section), layer_positions(layers, c.cut, power));
}

}  // namespace incise::bench::accuracy
