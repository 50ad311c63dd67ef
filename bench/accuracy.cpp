// The error-against-run-time report (issue 3; Magnoux 2020 Table 4.1 with our dimensions).
//
// Cases: a beam of regular hexagonal section (circumradius 15 mm, vertices on +-y), 0.2 m
// along +x, clamped at x = 0, E = 10 MPa, nu = 0.3, rho = 1000, under a body force of 9.81
// m/s^2 along -z (`bend`) or +x (`stretch`); the `_cut` cases add a zero-thickness planar cut
// at x = 0.1 m from the top (z max) down to z = 0 across the whole width; `b1` is the square
// beam 0.2 x 0.02 x 0.02 under its own weight.
//
// The cut, made before any solve:
// - EFG with the cutter (variant suffix `_cutter`; physics/cut/volume_cut.hpp, issue 4): the
//   uncut model is cut by one step of a straight blade along y, wider than the beam, moving
//   from above the grid down to the crack front with the particles at rest; the cutter severs
//   the links the blade touches (continuous collision) and re-selects the broken
//   neighbourhoods (each severed corner replaced by its mirror through the nearest kept one,
//   then by graph distance), which gives the geometry cut's neighbourhoods exactly: the two
//   variants' errors agree to 0.01 %. (By graph distance alone the tie between the particle behind
//   the kept face and those beside or below it makes irregular neighbourhoods and a cut beam much
//   farther off: docs/physics-choices.md, "Cutting".) Where the cut lies, relative to the grids:
//   the cut cases use an odd number of particle cells along the beam, so x = 0.1 is a plane of
//   integration-cube faces, midway between the particle layers at 0.1 +- a and the integration
//   points at 0.1 +- a/2; the blade runs on it, no grid point within a/2. (With an even count a
//   particle layer lies on the plane and belongs to one side, the other side's crack face being a
//   spacing away from its particles: the cut beams' errors grow severalfold;
//   docs/physics-choices.md, "Accuracy references".) The blade's edge stops at z = 1e-3 a, just
//   above the particle row on the crack front z = 0 (see the grid alignment below): the links from
//   the integration points above the front to the front particles across the plane cross it a/3
//   above z = 0 and are cut, those from the points below it are not, and the row's own links along
//   x, which a blade ending exactly on z = 0 would touch at t = 1, stay (the front is shared by
//   both sides, as the reference's front nodes are).
// - EFG with the geometry cut (suffix `_geomcut`), for comparison: integration-point-to-particle
//   links that cross the cut rectangle are removed at build time and the neighbourhood
//   re-selected on the element's own side (EfgSettings::cuts);
// - FEM (suffix `_geomcut`): a conforming mesh whose nodes on the cut (x = 0.1, z > 0) are
//   duplicated for the tets on the x < 0.1 side.
//
// Error: |mean tip displacement - reference| / |reference| x 100, the mean taken over the tip
// face x = L (area-weighted: exact face integrals for the tets; for EFG, the MLS displacement
// at the centroids of a fine triangulation of the face, through the surface embedding).
// Reference: 10-node tets solved statically (CHOLMOD) on the finest mesh of a refinement
// sequence graded towards the clamp and the crack front, printed in the progress and written
// to references.json; for the cut cases with quarter-point elements at the crack front (the
// midside nodes of the edges leaving it at a quarter of the edge, isoparametric tets), which
// carry its 1 / sqrt r strain, on sections of graded rows (hexagon_row_section) with x layers
// matched to them near the crack (crack_layers): the tip still converges at about h^1.5, so
// the quick run goes to 12 rows, the full run to 16 (docs/physics-choices.md, "Accuracy
// references", has the mesh study and the solve sizes and times).
//
// Rows: efg nb8 (8 cell corners with the model's defaults: h = 1.1 x the farthest corner, 8^3 volume samples,
// partial-cube points at the inside centroid; corotational_efg.hpp says why), nb4, novolume
// (nb8 with every touched cube counted whole), nb8_support3 (h = 3 x the farthest corner, the
// literal reading of the thesis's constant) and nb8_thesis (that support, cube-centre points
// and 4^3 samples: the thesis's literal model), each `_geomcut` for the cut cases, plus
// nb8_cutter, nb4_cutter and novolume_cutter; for the cut cases the EFG grid's z extent is
// widened so that a particle row lies on the crack front (the cutter needs it as much as the
// geometry cut: with the front mid-cell, between particle rows at z = +-a, nb8_cutter's
// stretch_cut tip moves by +69 % at a = 5 mm and +21 % at 2 mm); fem tet4 (the
// corotational real-time baseline) and tet10 (the coarser reference meshes; timed with their
// assembled linear stiffness and HRZ-lumped masses, as no dynamic tet10 model exists);
// mass_spring and mass_spring_uncorrected (Baudet's bricks with and without their correction
// forces) on the uncut cases, and the `traction` case of the spring networks' measured E and nu
// with Van Gelder's springs beside (bench/accuracy_mass_spring.hpp).
//
// Equilibrium: each model's linear static solution (sparse direct solve of its stiffness at
// rest), i.e. the small-strain problem the reference solves. ms_per_step: the mean wall time
// of implicit Euler steps at dt = 1/60 from rest under the load (Rayleigh mass damping 2/s),
// with the scene-like CG (tolerance 1e-6, Jacobi preconditioner, at most 2000 iterations);
// cg_iterations is their mean iteration count.
#include "bench/accuracy.hpp"
#include "bench/accuracy_mass_spring.hpp"
#include "bench/bench_page.hpp"
#include "bench/plot.hpp"

#include "common/csv.hpp"
#include "common/progress_bar.hpp"

#include "physics/core/implicit_euler.hpp"
#include "physics/cut/volume_cut.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/efg/efg_static.hpp"
#include "physics/fem/corotational_fem.hpp"
#include "physics/fem/static_solve.hpp"
#include "physics/fem/tet_mesh.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/LU>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

namespace incise::bench {

namespace {

using physics::CorotationalEfg;
using physics::CorotationalTetFem;
using physics::DeformableModel;
using physics::EfgSettings;
using physics::Material;
using physics::QuadraticTetMesh;
using physics::SparseMatrix;
using physics::TetMesh;
using physics::Vec3;
using physics::Vector;
using Index = Eigen::Index;
using Clock = std::chrono::steady_clock;

constexpr double beam_length = 0.2;
constexpr double hexagon_radius = 0.015;
constexpr double square_half_side = 0.01;
constexpr double cut_x = 0.1;
constexpr double gravity = 9.81;
const Material beam_material{10e6, 0.3, 1000};
// Euler-Bernoulli q L^4 / (8 E I) plus the Timoshenko shear term, as in the FEM tests.
constexpr double b1_beam_theory_tip = 5.947e-3;

double hexagon_half_height() { return hexagon_radius * std::sqrt(3.0) / 2; }

enum class Shape { hexagon, square };

struct Case {
  std::string name;
  Shape shape;
  Vec3 acceleration;
  bool cut;
};

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

struct Section {
  std::vector<Eigen::Vector2d> points;  // (y, z)
  std::vector<std::array<int, 3>> triangles;
};

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
// Intervals along y in the cut references' sections.
constexpr int crack_section_ny = 8;

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

// 10-node tets from 4-node ones: a midpoint node per edge, shared between tets.
struct QuadraticMesh {
  QuadraticTetMesh mesh;
  std::map<std::pair<int, int>, int> midpoints;  // sorted corner pair -> node
};

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
template <size_t corners>
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
// The cut references: quarter-point elements take the crack front's singularity, so a milder
// grading does better (stretch_cut on 3 lattice rows, the tip: power 1 -91.6, 1.5 -92.3, 2.5
// -91.5 um; without quarter points, at the same rows, -86.7 um).
constexpr double crack_grading_power = 1.5;
TetMesh case_mesh(const Case& c, int section, int layers, bool graded = false) {
  const double power = graded ? (c.cut ? crack_grading_power : grading_power) : 1.0;
  if (c.shape == Shape::square) {
    return extrude(square_section(section), layer_positions(layers, false, power));
  }
  if (graded && c.cut) {
    return extrude(hexagon_row_section(crack_section_ny, section, power), crack_layers(section, power));
  }
  return extrude(hexagon_section(section), layer_positions(layers, c.cut, power));
}

// ---------------------------------------------------------------------------------------------
// A linear model from an assembled stiffness (the 10-node tets have no corotational model):
// drives the same implicit Euler integrator for the timing of the tet10 rows.

class AssembledLinearModel final : public DeformableModel {
 public:
  AssembledLinearModel(SparseMatrix stiffness, Vector rest, Vector masses)
      : stiffness_(std::move(stiffness)), rest_(std::move(rest)), masses_(std::move(masses)) {}
  int node_count() const override { return static_cast<int>(masses_.size()); }
  const Vector& rest_positions() const override { return rest_; }
  const Vector& lumped_masses() const override { return masses_; }
  void update_rotations(const Vector&) override {}
  void add_elastic_forces(const Vector& x, Vector& f) const override { f -= stiffness_ * (x - rest_); }
  void add_stiffness_product(const Vector& p, Vector& out) const override { out += stiffness_ * p; }
  void add_stiffness_diagonal(Vector& diagonal) const override { diagonal += stiffness_.diagonal(); }
  double elastic_energy(const Vector& x) const override {
    const Vector u = x - rest_;
    return 0.5 * u.dot(stiffness_ * u);
  }

  std::unique_ptr<DeformableModel> clone() const override { return std::make_unique<AssembledLinearModel>(*this); }
 private:
  SparseMatrix stiffness_;
  Vector rest_;
  Vector masses_;
};

// HRZ lumping of the 10-node tet (the row sums give negative corner masses): the consistent
// diagonal, integral N_a^2 = V/70 (corner) and 8V/105 (midpoint), scaled to the element mass,
// gives rho V/36 per corner and 4 rho V/27 per midpoint.
Vector quadratic_lumped_masses(const QuadraticTetMesh& mesh, double density) {
  Vector masses = Vector::Zero(mesh.rest.size() / 3);
  for (const auto& tet : mesh.tets) {
    physics::Mat3 shape;
    for (int c = 0; c < 3; ++c) {
      shape.col(c) = mesh.rest.segment<3>(3 * tet[c + 1]) - mesh.rest.segment<3>(3 * tet[0]);
    }
    const double mass = density * shape.determinant() / 6;
    for (int c = 0; c < 4; ++c) masses[tet[c]] += mass / 36;
    for (int e = 4; e < 10; ++e) masses[tet[e]] += 4 * mass / 27;
  }
  return masses;
}

// Solves K u = load for several loads with one factorisation, u = 0 on the fixed nodes.
std::vector<Vector> solve_static_loads(const SparseMatrix& stiffness, const std::vector<Vector>& loads,
                                       const std::vector<uint8_t>& fixed) {
  std::vector<Index> free_of(stiffness.rows(), -1);
  Index free_count = 0;
  for (Index i = 0; i < stiffness.rows(); ++i) {
    if (fixed[i / 3] == 0) free_of[i] = free_count++;
  }
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(stiffness.nonZeros());
  for (Index column = 0; column < stiffness.outerSize(); ++column) {
    for (SparseMatrix::InnerIterator it(stiffness, column); it; ++it) {
      if (free_of[it.row()] >= 0 && free_of[it.col()] >= 0) {
        triplets.emplace_back(free_of[it.row()], free_of[it.col()], it.value());
      }
    }
  }
  SparseMatrix reduced(free_count, free_count);
  reduced.setFromTriplets(triplets.begin(), triplets.end());
  // CHOLMOD's supernodal Cholesky (dense BLAS on supernodes): on the references many times
  // faster than SimplicialLDLT (docs/physics-choices.md, "Accuracy references"), which stays
  // as the fallback for a matrix that is not positive definite, and is used under
  // ThreadSanitizer: CHOLMOD's OpenMP threads and OpenBLAS's synchronise in code TSan does not
  // see (libgomp, spin waits), which it reports as races (test_cut_beam_accuracy's solves are
  // small enough for either).
#if defined(__SANITIZE_THREAD__)
  constexpr bool use_cholmod = false;
#else
  constexpr bool use_cholmod = true;
#endif
  Eigen::CholmodSupernodalLLT<SparseMatrix> cholmod;
  if (use_cholmod) cholmod.compute(reduced);
  std::unique_ptr<Eigen::SimplicialLDLT<SparseMatrix>> ldlt;
  if (!use_cholmod || cholmod.info() != Eigen::Success) {
    ldlt = std::make_unique<Eigen::SimplicialLDLT<SparseMatrix>>(reduced);
    if (ldlt->info() != Eigen::Success) throw std::runtime_error("static solve: factorisation failed");
  }
  std::vector<Vector> solutions;
  for (const Vector& load : loads) {
    Vector reduced_load(free_count);
    for (Index i = 0; i < stiffness.rows(); ++i) {
      if (free_of[i] >= 0) reduced_load[free_of[i]] = load[i];
    }
    const Vector reduced_solution = ldlt ? Vector(ldlt->solve(reduced_load)) : Vector(cholmod.solve(reduced_load));
    Vector u = Vector::Zero(stiffness.rows());
    for (Index i = 0; i < stiffness.rows(); ++i) {
      if (free_of[i] >= 0) u[i] = reduced_solution[free_of[i]];
    }
    if (!u.allFinite()) throw std::runtime_error("static solve: the solution is not finite");
    solutions.push_back(std::move(u));
  }
  return solutions;
}

struct Timing {
  double ms_per_step = 0;
  double cg_iterations = 0;
  bool converged = true;
};

// Implicit Euler from rest under the load at dt = 1/60 with the scene-like CG.
Timing time_steps(DeformableModel& model, const std::vector<uint8_t>& fixed, const Vector& load,
                  int steps) {
  physics::State state{model.rest_positions(), Vector::Zero(model.rest_positions().size())};
  physics::ImplicitEulerSettings settings;
  settings.dt = 1.0 / 60;
  settings.rayleigh_mass = 2;  // the scenes' default damping
  settings.cg.tolerance = 1e-6;
  settings.cg.max_iterations = 2000;
  Timing timing;
  const auto start = Clock::now();
  for (int step = 0; step < steps; ++step) {
    const physics::StepReport report =
        physics::implicit_euler_step(model, state, fixed, load, {}, settings);
    timing.cg_iterations += report.cg.iterations;
    timing.converged = timing.converged && report.cg.converged && !report.nonfinite;
  }
  const std::chrono::duration<double, std::milli> elapsed = Clock::now() - start;
  timing.ms_per_step = elapsed.count() / steps;
  timing.cg_iterations /= steps;
  return timing;
}

// ---------------------------------------------------------------------------------------------
// The models of a case, shared by the report and by the tests' entry points (accuracy.hpp).

// One reference mesh: 10-node tets (quarter points and the opened cut for the cut cases),
// solved statically for each case's load; `tips` per case.
struct ReferenceLevel {
  QuadraticMesh quadratic;
  TetMesh linear;
  std::vector<uint8_t> fixed;
  std::vector<Vec3> tips;
};
ReferenceLevel solve_reference_level(const std::vector<Case>& cases, int section, int layers) {
  const Case& first = cases.front();
  ReferenceLevel level;
  level.linear = case_mesh(first, section, layers, true);
  level.quadratic = make_quadratic(level.linear);
  if (first.cut) {
    quarter_points_at_crack_front(level.quadratic);
    open_cut(level.quadratic.mesh.rest, level.quadratic.mesh.tets);
  }
  level.fixed = clamped_nodes(level.quadratic.mesh.rest);
  std::vector<Vector> loads;
  for (const Case& c : cases) {
    loads.push_back(physics::assemble_body_load(level.quadratic.mesh, beam_material.density * c.acceleration));
  }
  const std::vector<Vector> solutions =
      solve_static_loads(physics::assemble_stiffness(level.quadratic.mesh, beam_material), loads, level.fixed);
  for (const Vector& u : solutions) level.tips.push_back(tip_mean(level.linear, u, &level.quadratic));
  return level;
}

// The EFG models' tip face: the centroids of a fine triangulation, with their areas.
struct TipFace {
  Vector points;
  std::vector<double> weights;
  double area = 0;
};
TipFace make_tip_face(Shape shape) {
  const Section face = shape == Shape::hexagon ? hexagon_section(8) : square_section(10);
  TipFace result;
  result.points.resize(3 * static_cast<Index>(face.triangles.size()));
  for (size_t t = 0; t < face.triangles.size(); ++t) {
    const auto& corners = face.triangles[t];
    const Eigen::Vector2d centroid = (face.points[corners[0]] + face.points[corners[1]] + face.points[corners[2]]) / 3;
    result.points.segment<3>(3 * static_cast<Index>(t)) = Vec3(beam_length, centroid.x(), centroid.y());
    result.weights.push_back(triangle_area(face.points[corners[0]], face.points[corners[1]], face.points[corners[2]]));
    result.area += result.weights.back();
  }
  return result;
}

// The area-weighted mean displacement over the tip face, through the surface embedding.
Vec3 efg_tip_mean(const CorotationalEfg& model, const physics::SurfaceEmbedding& embedding, const TipFace& face,
                  const Vector& u) {
  Vector moved;
  CorotationalEfg::surface_positions(embedding, model.rest_positions() + u, moved);
  Vec3 tip = Vec3::Zero();
  for (size_t t = 0; t < face.weights.size(); ++t) {
    const Index at = 3 * static_cast<Index>(t);
    tip += face.weights[t] / face.area * (moved.segment<3>(at) - face.points.segment<3>(at));
  }
  return tip;
}

// An EFG model of a case's body (settings.spacing set), the cut cases cut by the geometry
// (`cutter` false: settings.cuts) or by the cutter (the report in `cut_report`).
std::unique_ptr<CorotationalEfg> make_case_efg(Shape shape, bool cut, bool cutter, EfgSettings settings,
                                               physics::VolumeCutReport* cut_report = nullptr) {
  const double spacing = settings.spacing;
  if (cut && !cutter) {
    // From the top down to z = 0 across the whole width. Particles on the plane count on
    // the +x side; links through the rim z = 0 stay (the crack front is shared).
    settings.cuts.push_back({Vec3(cut_x, -1, 0), Vec3(0, 2, 0), Vec3(0, 0, 1)});
  }
  Vec3 grid_min = box_min(shape), grid_max = box_max(shape);
  if (cut) {
    // The grid's z extent widened to a multiple of 4a, so that a row of particles lies on
    // the crack front z = 0 (shared by both sides, like the conforming FEM's front nodes).
    // Otherwise the front falls mid-cell at every other resolution and the effective
    // crack depth jumps by about a between sizes (stretch_cut: +220 %, -28 %, +46 % at
    // a = 5, 3.3, 2 mm against -37 %, -28 % aligned).
    const int cubes = static_cast<int>(std::ceil((grid_max.z() - grid_min.z()) / spacing * (1 - 1e-12)));
    const int aligned = (cubes + 3) / 4 * 4;
    grid_min.z() = -0.5 * aligned * spacing;
    grid_max.z() = 0.5 * aligned * spacing;
  }
  auto model = std::make_unique<CorotationalEfg>([shape](const Vec3& p) { return inside_shape(shape, p); },
                                                 grid_min, grid_max, beam_material, settings);
  if (cut && cutter) {
    // One step of a straight blade along y (twice the beam's width), on the plane x =
    // cut_x, from 2a above the grid down to 1e-3 a above the front row z = 0; the
    // particles at rest (start = end). The file comment says why there.
    const double width = 2 * hexagon_radius;
    const std::vector<Vec3> blade_start{Vec3(cut_x, -width, grid_max.z() + 2 * spacing),
                                        Vec3(cut_x, width, grid_max.z() + 2 * spacing)};
    const std::vector<Vec3> blade_end{Vec3(cut_x, -width, 1e-3 * spacing), Vec3(cut_x, width, 1e-3 * spacing)};
    // Broad-phase margin 1 um (well above the CCD's touching distance, 1e-8 of the
    // problem's size), no slack: one refit only.
    physics::VolumeCutter volume_cutter(*model, 1e-6, 0);
    const Vector rest = model->rest_positions();
    const physics::VolumeCutReport report = volume_cutter.cut(blade_start, blade_end, rest, rest);
    if (cut_report != nullptr) *cut_report = report;
  }
  model->update_rotations(model->rest_positions());
  return model;
}

// ---------------------------------------------------------------------------------------------
// Output.

struct Row {
  std::string case_name, model, variant;
  std::string resolution;
  long long dofs = 0, elements = 0;
  double ms_per_step = 0, cg_iterations = 0, error_pct = 0;
  bool converged = true;
  Vec3 tip = Vec3::Zero();  // the mean tip displacement (printed, not in the CSV)
  double measured_E = std::numeric_limits<double>::quiet_NaN();  // the traction case only
  double measured_nu = std::numeric_limits<double>::quiet_NaN();
};

struct Reference {
  Vec3 tip = Vec3::Zero();
  std::string element;
  struct Level {
    std::string mesh;
    long long dofs = 0;
    Vec3 tip = Vec3::Zero();
    double change_pct = 0;  // against the previous level
  };
  std::vector<Level> levels;
};

Row from_mass_spring(const MassSpringRow& r) {
  Row row{r.case_name, r.model, r.variant, r.resolution, r.dofs, r.elements, r.ms_per_step, r.cg_iterations,
          r.error_pct, r.converged, r.tip};
  row.measured_E = r.measured_E;
  row.measured_nu = r.measured_nu;
  return row;
}

// This report's figures: 4 significant digits unless a caller asks for others.
std::string format(double value, int digits = 4) { return common::significant(value, digits); }

std::string json_vector(const Vec3& v) {
  std::ostringstream stream;
  stream << std::setprecision(10) << "[" << v.x() << ", " << v.y() << ", " << v.z() << "]";
  return stream.str();
}

void write_csv(const std::filesystem::path& path, const std::vector<Row>& rows) {
  common::CsvWriter csv(path, {"case", "model", "variant", "resolution", "dofs", "elements", "ms_per_step",
                               "cg_iterations", "error_pct", "measured_E", "measured_nu"});
  const auto optional = [](double value, int digits) { return std::isnan(value) ? std::string() : format(value, digits); };
  for (const Row& row : rows) {
    csv.row(row.case_name, row.model, row.variant, row.resolution, row.dofs, row.elements,
            common::fixed(row.ms_per_step, 3), common::fixed(row.cg_iterations, 1), common::fixed(row.error_pct, 4),
            optional(row.measured_E, 8), optional(row.measured_nu, 8));
  }
}

void write_references(const std::filesystem::path& path, const std::vector<Case>& cases,
                      const std::map<std::string, Reference>& references) {
  std::ofstream json(path);
  json << "{\n  \"units\": \"metres\",\n  \"tip\": \"area-weighted mean displacement over the face x = 0.2\",\n"
       << "  \"cases\": {\n";
  for (size_t i = 0; i < cases.size(); ++i) {
    const Reference& reference = references.at(cases[i].name);
    json << "    \"" << cases[i].name << "\": {\n      \"element\": \"" << reference.element
         << "\",\n      \"reference_tip_displacement\": " << json_vector(reference.tip) << ",\n";
    if (cases[i].name == "b1") {
      json << "      \"beam_theory_tip_z\": " << -b1_beam_theory_tip << ",\n";
    }
    json << "      \"meshes\": [\n";
    for (size_t l = 0; l < reference.levels.size(); ++l) {
      const auto& level = reference.levels[l];
      json << "        {\"mesh\": \"" << level.mesh << "\", \"dofs\": " << level.dofs
           << ", \"tip_displacement\": " << json_vector(level.tip)
           << ", \"change_from_previous_pct\": " << format(level.change_pct) << "}"
           << (l + 1 < reference.levels.size() ? "," : "") << "\n";
    }
    json << "      ]\n    }" << (i + 1 < cases.size() ? "," : "") << "\n";
  }
  json << "  }\n}\n";
}

// gnuplot script with the data inline: one panel per case, one series per model and variant.
std::string plot_script(const std::string& png, const std::vector<Case>& cases, const std::vector<Row>& rows) {
  std::ostringstream script;
  std::vector<std::string> series;
  for (const Row& row : rows) {
    std::string key = row.model + " " + row.variant;
    // The cut cases carry the cut in the variant; plot them under the same series names.
    const size_t suffix = key.find("_geomcut");
    if (suffix != std::string::npos) key.erase(suffix);
    if (std::find(series.begin(), series.end(), key) == series.end()) series.push_back(key);
  }
  script << "# Written by incise bench accuracy: error against time per step, log-log.\n"
         << "set terminal pngcairo size 1500,950 font ',10'\n"
         << "set termoption noenhanced\n"
         << "set output '" << png << "'\n"
         << "set logscale xy\nset grid\nset key bottom left font ',8'\n"
         << "set xlabel 'ms per implicit Euler step (dt = 1/60, CG 1e-6)'\n"
         << "set ylabel 'tip error %'\n";
  for (const Case& c : cases) {
    for (size_t s = 0; s < series.size(); ++s) {
      script << "$" << c.name << "_" << s << " << EOD\n";
      for (const Row& row : rows) {
        std::string key = row.model + " " + row.variant;
        const size_t suffix = key.find("_geomcut");
        if (suffix != std::string::npos) key.erase(suffix);
        if (row.case_name != c.name || key != series[s] || row.ms_per_step <= 0) continue;
        // Log axes: errors below 1e-3 % are drawn at 1e-3 %.
        script << row.ms_per_step << " " << std::max(row.error_pct, 1e-3) << "\n";
      }
      script << "EOD\n";
    }
  }
  script << "set multiplot layout 2,3 title 'incise accuracy: tip error against run time (Magnoux Table 4.1 cases)'\n";
  for (const Case& c : cases) {
    script << "set title '" << c.name << (c.cut ? " (geometry cut; _cutter: the cutter)" : "") << "'\n" << "plot ";
    // Only the series with rows in this case (the cutter variants exist for the cut cases only).
    std::vector<size_t> present;
    for (size_t s = 0; s < series.size(); ++s) {
      const bool any = std::any_of(rows.begin(), rows.end(), [&](const Row& row) {
        std::string key = row.model + " " + row.variant;
        const size_t suffix = key.find("_geomcut");
        if (suffix != std::string::npos) key.erase(suffix);
        return row.case_name == c.name && key == series[s] && row.ms_per_step > 0;
      });
      if (any) present.push_back(s);
    }
    for (size_t i = 0; i < present.size(); ++i) {
      const size_t s = present[i];
      script << "$" << c.name << "_" << s << " using 1:2 with linespoints lw 1.5 pt " << (s % 10) + 1
             << " title '" << series[s] << "'" << (i + 1 < present.size() ? ", \\\n     " : "\n");
    }
  }
  script << "unset multiplot\n";
  return script.str();
}

}  // namespace

int run_accuracy_bench(bool quick, const std::filesystem::path& out_dir, std::ostream& progress_stream) {
  try {
    std::filesystem::create_directories(out_dir);
    const auto bench_start = Clock::now();
    const std::vector<Case> cases = all_cases();
    const int timed_steps = quick ? 1 : 4;

    // Resolutions. Reference levels (10-node tets): hexagon (lattice m, layers), square (cells
    // per side, layers); the finest is the reference, the refinement check compares the last two.
    using Levels = std::vector<std::pair<int, int>>;
    const Levels hexagon_levels = quick ? Levels{{1, 10}, {2, 20}, {3, 30}}
                                        : Levels{{1, 10}, {2, 20}, {3, 30}, {4, 40}};
    const Levels square_levels = quick ? Levels{{2, 10}, {3, 15}, {4, 20}}
                                       : Levels{{2, 10}, {4, 20}, {6, 30}, {8, 40}};
    // The cut cases (rows either side of the crack front, layers from crack_layers): their
    // tip converges at about h^1.5 even with quarter points, so they need finer meshes (sizes
    // and solve times: docs/physics-choices.md, "Accuracy references").
    const Levels crack_levels = quick ? Levels{{2, 0}, {3, 0}, {6, 0}, {9, 0}, {12, 0}}
                                      : Levels{{2, 0}, {3, 0}, {4, 0}, {6, 0}, {8, 0}, {12, 0}, {16, 0}};
    // Linear tets (the real-time baseline), uniform, about 1k, 3k and 10k dofs (more in full).
    const Levels hexagon_linear = quick ? Levels{{2, 20}, {3, 30}, {4, 50}}
                                        : Levels{{2, 20}, {3, 30}, {4, 50}, {6, 80}};
    const Levels square_linear = quick ? Levels{{2, 20}, {4, 40}, {6, 60}}
                                       : Levels{{2, 20}, {4, 40}, {6, 60}, {10, 100}};
    // EFG: particle cells along the beam (spacing a = L / (2 cells)).
    const std::vector<int> efg_cells = quick ? std::vector<int>{20, 30, 50}
                                             : std::vector<int>{20, 30, 50, 70};
    // The cut cases: an odd count, so that the crack plane x = 0.1 (= cells x a) falls on
    // integration-cube faces, midway between two particle layers, instead of on a particle
    // layer that one side would own (see the file comment).
    std::vector<int> efg_cells_cut;
    for (int cells : efg_cells) efg_cells_cut.push_back(cells + 1);
    struct EfgVariant {
      std::string name;
      int neighbours;
      bool estimate_volumes;
      double support_factor;
      bool centroid_points;
      int samples_per_axis;
    };
    const EfgSettings defaults;
    const std::vector<EfgVariant> efg_variants{
        {"nb8", 8, true, defaults.support_factor, true, defaults.samples_per_axis},
        {"nb4", 4, true, defaults.support_factor, true, defaults.samples_per_axis},
        {"novolume", 8, false, defaults.support_factor, true, defaults.samples_per_axis},
        {"nb8_support3", 8, true, 3.0, true, defaults.samples_per_axis},
        {"nb8_thesis", 8, true, 3.0, false, 4}};
    // The mass-spring (uncut bodies only: it cannot be cut): bricks across the beam's y extent.
    const std::vector<int> mass_spring_across = quick ? std::vector<int>{2, 4, 6} : std::vector<int>{2, 4, 6, 8};
    // The cut cases also run these with the cutter (suffix `_cutter`).
    const std::vector<std::string> cutter_variants{"nb8", "nb4", "novolume"};

    // Cases sharing a body share meshes, models and factorisations.
    struct Body {
      Shape shape;
      bool cut;
      std::vector<Case> cases;
    };
    std::vector<Body> bodies;
    for (const Case& c : cases) {
      auto it = std::find_if(bodies.begin(), bodies.end(),
                             [&](const Body& b) { return b.shape == c.shape && b.cut == c.cut; });
      if (it == bodies.end()) {
        bodies.push_back({c.shape, c.cut, {}});
        it = bodies.end() - 1;
      }
      it->cases.push_back(c);
    }
    int total = 0;
    for (const Body& body : bodies) {
      const bool hexagon = body.shape == Shape::hexagon;
      total += static_cast<int>((body.cut ? crack_levels : hexagon ? hexagon_levels : square_levels).size() +
                                (hexagon ? hexagon_linear : square_linear).size() +
                                efg_cells.size() * (efg_variants.size() + (body.cut ? cutter_variants.size() : 0)) +
                                (body.cut ? 0 : mass_spring_beam_runs(mass_spring_across)));
    }
    total += traction_runs();
    common::ProgressBar progress(progress_stream, total);
    progress.note(std::string("incise bench accuracy") + (quick ? " --quick" : "") + ": " +
                  std::to_string(cases.size()) + " cases, output in " + out_dir.string());

    std::vector<Row> rows;
    std::map<std::string, Reference> references;
    const TimeSteps timer = [timed_steps](DeformableModel& model, const std::vector<uint8_t>& fixed, const Vector& load) {
      const Timing timing = time_steps(model, fixed, load, timed_steps);
      return StepTiming{timing.ms_per_step, timing.cg_iterations, timing.converged};
    };
    // What the cutter did, per variant and resolution ("nb8_cutter a2mm").
    std::map<std::string, physics::VolumeCutReport> cut_reports;
    const auto relative_error_pct = [](const Vec3& tip, const Vec3& reference) {
      return 100 * (tip - reference).norm() / reference.norm();
    };
    const auto mm = [](const Vec3& v) {
      std::ostringstream stream;
      stream << std::fixed << std::setprecision(5) << "(" << 1e3 * v.x() << ", " << 1e3 * v.y()
             << ", " << 1e3 * v.z() << ") mm";
      return stream.str();
    };

    for (const Body& body : bodies) {
      const auto body_start = Clock::now();
      const bool hexagon = body.shape == Shape::hexagon;
      const Case& first = body.cases.front();
      const std::string body_name = std::string(hexagon ? "hexagon" : "square") + (body.cut ? " cut" : "");
      const std::string cut_suffix = body.cut ? "_geomcut" : "";
      const auto describe = [&](int section, int layers, bool graded) {
        if (body.cut && graded) {
          return "hexagon_rows" + std::to_string(section) + "_y" + std::to_string(crack_section_ny) + "_x" +
                 std::to_string(layers) + "_graded";
        }
        return hexagon ? "hexagon_lattice" + std::to_string(section) + "_x" + std::to_string(layers) +
                             (graded ? "_graded" : "")
                       : "square_" + std::to_string(section) + "x" + std::to_string(section) + "_x" +
                             std::to_string(layers) + (graded ? "_graded" : "");
      };

      // References: 10-node tets on a refinement sequence graded towards the singular lines
      // (clamp, crack front); the finest is the reference.
      struct Level : ReferenceLevel {
        std::string name;
        int section = 0;  // the mesh size is proportional to 1 / section
      };
      std::vector<Level> levels;
      const Levels& reference_levels = body.cut ? crack_levels : hexagon ? hexagon_levels : square_levels;
      for (const auto& [section, layers] : reference_levels) {
        const std::string name = describe(section, body.cut ? static_cast<int>(crack_layers(section, crack_grading_power).size()) - 1 : layers, true);
        progress.draw(body_name + " reference tet10 " + name);
        Level level;
        static_cast<ReferenceLevel&>(level) = solve_reference_level(body.cases, section, layers);
        level.name = name;
        level.section = section;
        levels.push_back(std::move(level));
        progress.step(body_name + " reference tet10 " + levels.back().name);
      }
      for (size_t i = 0; i < body.cases.size(); ++i) {
        const Case& c = body.cases[i];
        Reference reference;
        reference.element = body.cut ? "tet10 static, conforming cut (nodes on x = 0.1, z > 0 duplicated)"
                                     : "tet10 static";
        for (size_t l = 0; l < levels.size(); ++l) {
          Reference::Level entry{levels[l].name,
                                 3 * static_cast<long long>(levels[l].quadratic.mesh.rest.size() / 3),
                                 levels[l].tips[i], 0};
          if (l > 0) entry.change_pct = relative_error_pct(levels[l - 1].tips[i], levels[l].tips[i]);
          reference.levels.push_back(entry);
          progress.note("  " + c.name + " reference tet10 " + entry.mesh + " (" + std::to_string(entry.dofs) +
                        " dofs): tip " + mm(entry.tip) +
                        (l > 0 ? ", change from the coarser mesh " + format(entry.change_pct, 3) + " %" : ""));
        }
        reference.tip = levels.back().tips[i];
        const double last_change = reference.levels.back().change_pct;
        if (levels.size() >= 3) {
          // Richardson: the three finest levels along the finest tip's direction, s(h) = s0 + C h^p
          // with h = 1 / section; the observed rate p by bisection.
          const size_t n = levels.size();
          const Vec3 direction = levels[n - 1].tips[i].normalized();
          const double s1 = levels[n - 3].tips[i].dot(direction), s2 = levels[n - 2].tips[i].dot(direction),
                       s3 = levels[n - 1].tips[i].dot(direction);
          const double h1 = 1.0 / levels[n - 3].section, h2 = 1.0 / levels[n - 2].section,
                       h3 = 1.0 / levels[n - 1].section;
          const double ratio = (s2 - s1) / (s3 - s2);
          const auto model_ratio = [&](double p) {
            return (std::pow(h1, p) - std::pow(h2, p)) / (std::pow(h2, p) - std::pow(h3, p));
          };
          if (ratio > model_ratio(0.25) && ratio < model_ratio(8.0)) {
            double low = 0.25, high = 8.0;
            for (int it = 0; it < 100; ++it) {
              const double mid = 0.5 * (low + high);
              (model_ratio(mid) < ratio ? low : high) = mid;
            }
            const double p = 0.5 * (low + high);
            const double extrapolated = s3 + (s3 - s2) * std::pow(h3, p) / (std::pow(h2, p) - std::pow(h3, p));
            progress.note("  " + c.name + " reference Richardson (three finest, observed rate " + format(p, 3) +
                          "): extrapolated tip " + format(1e3 * extrapolated, 6) + " mm along the finest tip; the finest differs from it by " +
                          format(100 * std::abs(s3 / extrapolated - 1), 3) + " %");
          } else {
            progress.note("  " + c.name + " reference Richardson: the three finest levels do not converge monotonically at a rate in [0.25, 8] (ratio " +
                          format(ratio, 3) + ")");
          }
        }
        progress.note("  " + c.name + " reference: " + (last_change < 0.2 ? "converged" : "NOT converged") +
                      " to 0.2 % (the two finest differ by " + format(last_change, 3) + " %)" +
                      (c.name == "b1" ? "; beam theory tip z " + format(-1e3 * b1_beam_theory_tip, 4) + " mm" : ""));
        references[c.name] = reference;
      }

      // tet10 rows: the coarser reference levels up to 40k dofs (beyond, one implicit step
      // with Jacobi-CG takes minutes), timed with the assembled linear model.
      for (size_t l = 0; l + 1 < levels.size(); ++l) {
        const Level& level = levels[l];
        const QuadraticTetMesh& mesh = level.quadratic.mesh;
        if (mesh.rest.size() > 40000) continue;
        AssembledLinearModel model(physics::assemble_stiffness(mesh, beam_material), mesh.rest,
                                   quadratic_lumped_masses(mesh, beam_material.density));
        for (size_t i = 0; i < body.cases.size(); ++i) {
          const Case& c = body.cases[i];
          const Timing timing = time_steps(
              model, level.fixed, physics::assemble_body_load(mesh, beam_material.density * c.acceleration),
              timed_steps);
          rows.push_back({c.name, "fem", "tet10" + cut_suffix, level.name,
                          3 * static_cast<long long>(mesh.rest.size() / 3),
                          static_cast<long long>(mesh.tets.size()), timing.ms_per_step,
                          timing.cg_iterations, relative_error_pct(level.tips[i], references[c.name].tip),
                          timing.converged});
        }
      }

      // tet4 rows: the corotational linear tets on uniform meshes.
      for (const auto& [section, layers] : hexagon ? hexagon_linear : square_linear) {
        const std::string name = describe(section, layers, false);
        progress.draw(body_name + " fem tet4 " + name);
        TetMesh mesh = case_mesh(first, section, layers, false);
        if (body.cut) open_cut(mesh.rest, mesh.tets);
        const std::vector<uint8_t> fixed = clamped_nodes(mesh.rest);
        CorotationalTetFem model(mesh, beam_material);
        std::vector<Vector> loads;
        for (const Case& c : body.cases) loads.push_back(physics::gravity_forces(model.lumped_masses(), c.acceleration));
        const std::vector<Vector> solutions =
            solve_static_loads(physics::assemble_stiffness(mesh, beam_material), loads, fixed);
        for (size_t i = 0; i < body.cases.size(); ++i) {
          const Case& c = body.cases[i];
          const Timing timing = time_steps(model, fixed, loads[i], timed_steps);
          rows.push_back({c.name, "fem", "tet4" + cut_suffix, name,
                          3 * static_cast<long long>(mesh.rest.size() / 3),
                          static_cast<long long>(mesh.tets.size()), timing.ms_per_step, timing.cg_iterations,
                          relative_error_pct(tip_mean(mesh, solutions[i], nullptr), references[c.name].tip),
                          timing.converged});
        }
        progress.step(body_name + " fem tet4 " + name);
      }

      // EFG rows. The tip face is sampled at the centroids of a fine triangulation.
      const TipFace face = make_tip_face(body.shape);
      // The EFG runs: every variant (with the geometry cut for the cut cases), then for the cut
      // cases the cutter variants on the uncut model.
      struct EfgRun {
        const EfgVariant* variant;
        bool cutter;
      };
      std::vector<EfgRun> runs;
      for (const EfgVariant& variant : efg_variants) runs.push_back({&variant, false});
      if (body.cut) {
        for (const std::string& name : cutter_variants) {
          const auto it = std::find_if(efg_variants.begin(), efg_variants.end(),
                                       [&](const EfgVariant& v) { return v.name == name; });
          runs.push_back({&*it, true});
        }
      }
      for (int cells : body.cut ? efg_cells_cut : efg_cells) {
        for (const EfgRun& run : runs) {
          const EfgVariant& variant = *run.variant;
          const std::string variant_name = variant.name + (run.cutter ? "_cutter" : cut_suffix);
          const double spacing = beam_length / (2 * cells);
          const std::string resolution = "a" + format(1e3 * spacing, 3) + "mm";
          progress.draw(body_name + " efg " + variant_name + " " + resolution);
          EfgSettings settings;
          settings.spacing = spacing;
          settings.neighbours = variant.neighbours;
          settings.estimate_volumes = variant.estimate_volumes;
          settings.support_factor = variant.support_factor;
          settings.centroid_points = variant.centroid_points;
          settings.samples_per_axis = variant.samples_per_axis;
          physics::VolumeCutReport report;
          const std::unique_ptr<CorotationalEfg> built = make_case_efg(body.shape, body.cut, run.cutter, settings, &report);
          CorotationalEfg& model = *built;
          if (run.cutter) {
            progress.note("  " + body_name + " efg " + variant_name + " " + resolution + ": the cutter severed " +
                          std::to_string(report.particle_links_severed) + " particle links and " +
                          std::to_string(report.element_links_severed) + " element links (" +
                          std::to_string(report.candidates) + " candidates), re-selected " +
                          std::to_string(report.elements_reselected) + " elements, " +
                          std::to_string(report.elements_isolated) + " isolated, " +
                          std::to_string(report.reselection_failures) + " failures (CCD " +
                          format(report.ms_ccd, 3) + " ms, topology " + format(report.ms_topology, 3) + " ms)");
            cut_reports[variant_name + " " + resolution] = report;
          }
          const std::vector<uint8_t> fixed = clamped_nodes(model.rest_positions());
          std::vector<Vector> loads;
          for (const Case& c : body.cases) loads.push_back(physics::gravity_forces(model.lumped_masses(), c.acceleration));
          const std::vector<Vector> solutions =
              solve_static_loads(physics::assemble_stiffness(model), loads, fixed);
          const physics::SurfaceEmbedding embedding = model.embed_surface(face.points);
          for (size_t i = 0; i < body.cases.size(); ++i) {
            const Case& c = body.cases[i];
            const Vec3 tip = efg_tip_mean(model, embedding, face, solutions[i]);
            const Timing timing = time_steps(model, fixed, loads[i], timed_steps);
            rows.push_back({c.name, "efg", variant_name, resolution,
                            3 * static_cast<long long>(model.node_count()), model.element_count(),
                            timing.ms_per_step, timing.cg_iterations,
                            relative_error_pct(tip, references[c.name].tip), timing.converged, tip});
          }
          progress.step(body_name + " efg " + variant_name + " " + resolution);
        }
      }
      if (!body.cut) {
        MassSpringBeam beam{[shape = body.shape](const Vec3& p) { return inside_shape(shape, p); },
                            box_min(body.shape), box_max(body.shape), !hexagon,
                            beam_material.youngs_modulus, beam_material.poisson_ratio, beam_material.density};
        std::vector<MassSpringCase> spring_cases;
        for (const Case& c : body.cases) spring_cases.push_back({c.name, c.acceleration, references[c.name].tip});
        for (const MassSpringRow& r : mass_spring_beam_rows(beam, spring_cases, mass_spring_across, timer, progress)) {
          rows.push_back(from_mass_spring(r));
        }
      }
      const std::chrono::duration<double> body_time = Clock::now() - body_start;
      progress.note("  " + body_name + " body done in " + format(body_time.count(), 3) + " s");
    }
    for (const MassSpringRow& r : traction_rows(timer, progress)) rows.push_back(from_mass_spring(r));
    progress.finish();

    // Rows in case order, then model, variant and size.
    const auto case_index = [&](const std::string& name) {
      return std::find_if(cases.begin(), cases.end(), [&](const Case& c) { return c.name == name; }) - cases.begin();
    };
    std::stable_sort(rows.begin(), rows.end(), [&](const Row& left, const Row& right) {
      return std::make_tuple(case_index(left.case_name), left.model, left.variant, left.dofs) <
             std::make_tuple(case_index(right.case_name), right.model, right.variant, right.dofs);
    });
    write_csv(out_dir / "accuracy.csv", rows);
    // The figures: efg nb8 at its largest size per case (about 10k dofs in --quick).
    // For the cut cases, nb8 with the geometry cut and with the cutter, side by side.
    for (const Case& c : cases) {
      for (const std::string& variant : c.cut ? std::vector<std::string>{"nb8_geomcut", "nb8_cutter"}
                                             : std::vector<std::string>{"nb8"}) {
        const Row* largest = nullptr;
        for (const Row& row : rows) {
          if (row.case_name == c.name && row.model == "efg" && row.variant == variant &&
              (largest == nullptr || row.dofs > largest->dofs)) {
            largest = &row;
          }
        }
        if (largest == nullptr) continue;
        progress_stream << c.name << " efg " << variant << " at " << largest->dofs << " dofs: "
                        << format(largest->ms_per_step, 4) << " ms per step ("
                        << format(1000 / largest->ms_per_step, 3) << " steps/s, " << format(largest->cg_iterations, 4)
                        << " CG iterations), error " << format(largest->error_pct, 3) << " %, tip " << mm(largest->tip)
                        << " against " << mm(references.at(c.name).tip);
        const auto report = cut_reports.find(variant + " " + largest->resolution);
        if (report != cut_reports.end()) {
          const physics::VolumeCutReport& r = report->second;
          progress_stream << "; cutter: " << r.particle_links_severed + r.element_links_severed << " links severed ("
                          << r.particle_links_severed << " particle, " << r.element_links_severed << " element), "
                          << r.elements_reselected << " elements re-selected, " << r.elements_isolated << " isolated, "
                          << r.reselection_failures << " failures";
        }
        progress_stream << "\n";
      }
    }
    write_references(out_dir / "references.json", cases, references);
    int unconverged = 0;
    for (const Row& row : rows) unconverged += row.converged ? 0 : 1;
    if (unconverged > 0) {
      progress_stream << unconverged << " rows had a timed step whose CG stopped at its iteration "
                      << "limit (2000): their ms_per_step is a lower bound\n";
    }
    draw_with_gnuplot(out_dir, "accuracy.gnuplot", plot_script("accuracy.png", cases, rows), "accuracy.png",
                      progress_stream);
    const std::chrono::duration<double> elapsed = Clock::now() - bench_start;
    progress_stream << "wrote " << (out_dir / "accuracy.csv").string() << " (" << rows.size()
                    << " rows), references.json and accuracy.png in " << format(elapsed.count(), 3) << " s\n";
    progress_stream << "report: "
                    << write_bench_page(out_dir, {"incise bench accuracy" + std::string(quick ? " --quick" : ""),
                                                  "Error against run time per step, per model, variant and "
                                                  "resolution, against converged references (bench/accuracy.cpp).",
                                                  {{"accuracy.png", "Error against time per step"}}, "",
                                                  "accuracy.csv"})
                           .string()
                    << "\n";
    return 0;
  } catch (const std::exception& error) {
    progress_stream << "\nbench accuracy failed: " << error.what() << "\n";
    return 1;
  }
}

CutBeamTips cut_beam_reference(int rows) {
  const std::vector<Case> all = all_cases();
  std::vector<Case> cut;
  for (const Case& c : all) {
    if (c.cut) cut.push_back(c);
  }
  const ReferenceLevel level = solve_reference_level(cut, rows, 0);
  return {level.tips[0], level.tips[1], 3 * static_cast<long long>(level.quadratic.mesh.rest.size() / 3)};
}

CutBeamTips cut_beam_efg(int cells, bool cutter) {
  const std::vector<Case> all = all_cases();
  EfgSettings settings;
  settings.spacing = beam_length / (2 * cells);
  const std::unique_ptr<CorotationalEfg> model = make_case_efg(Shape::hexagon, true, cutter, settings);
  const std::vector<uint8_t> fixed = clamped_nodes(model->rest_positions());
  std::vector<Vector> loads;
  for (const Case& c : all) {
    if (c.cut) loads.push_back(physics::gravity_forces(model->lumped_masses(), c.acceleration));
  }
  const std::vector<Vector> solutions = solve_static_loads(physics::assemble_stiffness(*model), loads, fixed);
  const TipFace face = make_tip_face(Shape::hexagon);
  const physics::SurfaceEmbedding embedding = model->embed_surface(face.points);
  return {efg_tip_mean(*model, embedding, face, solutions[0]), efg_tip_mean(*model, embedding, face, solutions[1]),
          3 * static_cast<long long>(model->node_count())};
}

}  // namespace incise::bench
