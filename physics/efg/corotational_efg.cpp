#include "physics/efg/corotational_efg.hpp"

#include "physics/efg/efg_detail.hpp"
#include "physics/efg/kernel.hpp"
#include "physics/efg/mls.hpp"
#include "physics/fem/corotational_fem.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <utility>

namespace incise::physics {

namespace {

using Index = Eigen::Index;
using Quaternion = Eigen::Quaterniond;

// The longest row a neighbourhood may have; far more than the 8 to 12 that cuts produce, it
// only stops a runaway selection.
constexpr int longest_row = 64;

using efg_detail::fail;
using efg_detail::format_point;

}  // namespace

// The build's particle grid and its cut-visibility tests.
namespace efg_build {

// The particle grid (every other vertex of the integration grid, 2a apart): indices, positions
// and grid coordinates of its particles.
struct ParticleGrid {
  Vec3 origin;
  double a = 0;
  std::array<int, 3> counts{};
  int index(int i, int j, int k) const { return i + counts[0] * (j + counts[1] * k); }
  std::array<int, 3> coordinates(int index) const {
    return {index % counts[0], (index / counts[0]) % counts[1], index / (counts[0] * counts[1])};
  }
  Vec3 position(int index) const {
    const auto [i, j, k] = coordinates(index);
    return Vec3(origin + 2.0 * a * Vec3(i, j, k));
  }
  std::size_t size() const { return static_cast<std::size_t>(counts[0]) * counts[1] * counts[2]; }
};

// (s, r, signed distance) of a point in a cut's frame: corner + s edge_u + r edge_v + d n.
Vec3 cut_frame(const CutRectangle& cut, const Vec3& point) {
  const Vec3 normal = cut.edge_u.cross(cut.edge_v).normalized();
  const Vec3 relative = point - cut.corner;
  const double u_squared = cut.edge_u.squaredNorm(), v_squared = cut.edge_v.squaredNorm();
  const double edges_dot = cut.edge_u.dot(cut.edge_v);
  const double along_u = relative.dot(cut.edge_u), along_v = relative.dot(cut.edge_v);
  const double determinant = u_squared * v_squared - edges_dot * edges_dot;
  return Vec3((along_u * v_squared - along_v * edges_dot) / determinant,
              (along_v * u_squared - along_u * edges_dot) / determinant, normal.dot(relative));
}

// Whether the settings' build-time cuts hide `to` from `from` (EfgSettings::cuts,
// front_hidden_beyond).
bool is_blocked(const EfgSettings& s, const Vec3& from, const Vec3& to) {
  for (const CutRectangle& cut : s.cuts) {
    if (cut.blocks(from, to)) return true;
    if (!(s.front_hidden_beyond < std::numeric_limits<double>::infinity())) continue;
    // A particle on the crack front (the rim edge r = 0), seen from a point on the cut's
    // negative side and beside the cut (r > 0).
    const Vec3 particle = cut_frame(cut, to), point = cut_frame(cut, from);
    const double scale = std::sqrt(cut.edge_v.squaredNorm());
    if (std::abs(particle.z()) < 1e-9 * scale && std::abs(particle.y()) < 1e-9 &&
        particle.x() > 0 && particle.x() < 1 && point.z() < 0 &&
        point.y() * scale > s.front_hidden_beyond) {
      return true;
    }
  }
  return false;
}

// With 4, the nearest corner and its three edge neighbours in the cell: the 4 nearest
// corners when the point is inside the cell, and never coplanar when it is outside.
void nearest_corners(const ParticleGrid& grid, const Vec3& centre, std::array<int, 3> cell, int count,
                     std::vector<int>& row) {
  std::array<std::pair<double, int>, 8> corners;
  for (int c = 0; c < 8; ++c) {
    const int index = grid.index(cell[0] + (c & 1), cell[1] + ((c >> 1) & 1),
                                    cell[2] + ((c >> 2) & 1));
    corners[c] = {(grid.position(index) - centre).squaredNorm(), c};
  }
  const auto corner_index = [&](int c) {
    return grid.index(cell[0] + (c & 1), cell[1] + ((c >> 1) & 1), cell[2] + ((c >> 2) & 1));
  };
  const auto by_distance = [&](const std::pair<double, int>& left,
                               const std::pair<double, int>& right) {
    return left.first != right.first ? left.first < right.first
                                     : corner_index(left.second) < corner_index(right.second);
  };
  std::sort(corners.begin(), corners.end(), by_distance);
  row.clear();
  if (count == 8) {
    for (const auto& corner : corners) row.push_back(corner_index(corner.second));
    return;
  }
  const int nearest = corners[0].second;
  std::array<std::pair<double, int>, 4> tetrahedron{corners[0]};
  for (int bit = 0; bit < 3; ++bit) {
    const int c = nearest ^ (1 << bit);
    tetrahedron[bit + 1] = {(grid.position(corner_index(c)) - centre).squaredNorm(), c};
  }
  std::sort(tetrahedron.begin(), tetrahedron.end(), by_distance);
  for (const auto& corner : tetrahedron) row.push_back(corner_index(corner.second));
}

}  // namespace efg_build

using efg_build::ParticleGrid;
using efg_build::is_blocked;
using efg_build::nearest_corners;

bool CutRectangle::blocks(const Vec3& from, const Vec3& to) const {
  const Vec3 normal = edge_u.cross(edge_v);
  if (!(normal.squaredNorm() > 0)) return false;
  const double distance_from = normal.dot(from - corner);
  const double distance_to = normal.dot(to - corner);
  if ((distance_from >= 0) == (distance_to >= 0)) return false;
  const double t = distance_from / (distance_from - distance_to);
  const Vec3 relative = from + t * (to - from) - corner;
  // Coordinates (s, r) of the crossing point in the parallelogram's own frame.
  const double u_squared = edge_u.squaredNorm(), v_squared = edge_v.squaredNorm();
  const double edges_dot = edge_u.dot(edge_v);
  const double along_u = relative.dot(edge_u), along_v = relative.dot(edge_v);
  const double determinant = u_squared * v_squared - edges_dot * edges_dot;
  const double s = (along_u * v_squared - along_v * edges_dot) / determinant;
  const double r = (along_v * u_squared - along_u * edges_dot) / determinant;
  // Open parallelogram: a link through the rim is not cut, so particles on the crack front
  // stay shared by both sides, like the nodes of a conforming FEM cut.
  constexpr double tolerance = 1e-12;
  return s > tolerance && s < 1 - tolerance && r > tolerance && r < 1 - tolerance;
}

CorotationalEfg::CorotationalEfg(const std::function<bool(const Vec3&)>& inside, Vec3 box_min,
                                 Vec3 box_max, const Material& material,
                                 const EfgSettings& settings, Executor* executor)
    : building_(std::make_shared<EfgRestShape>()), rest_stiffness_cache_(make_efg_rest_stiffness_cache()) {
  building_->material = material;
  building_->settings = settings;
  shape_ = building_;
  set_executor(executor);
  build(inside, box_min, box_max);
  building_.reset();  // read-only from here on
  partition_nodes_stale_ = true;
}

CorotationalEfg::CorotationalEfg(Vec3 box_min, Vec3 box_max, const Material& material,
                                 const EfgSettings& settings, Executor* executor)
    : CorotationalEfg([](const Vec3&) { return true; }, box_min, box_max, material, settings,
                      executor) {}

CorotationalEfg::~CorotationalEfg() = default;
CorotationalEfg::CorotationalEfg(CorotationalEfg&&) noexcept = default;
CorotationalEfg& CorotationalEfg::operator=(CorotationalEfg&&) noexcept = default;
CorotationalEfg::CorotationalEfg(const CorotationalEfg&) = default;
CorotationalEfg& CorotationalEfg::operator=(const CorotationalEfg&) = default;

std::unique_ptr<DeformableModel> CorotationalEfg::clone() const { return std::make_unique<CorotationalEfg>(*this); }

void CorotationalEfg::set_executor(Executor* executor) {
  executor_ = executor ? executor : &serial_executor();
}

double CorotationalEfg::total_volume() const {
  return std::accumulate(volumes_.begin(), volumes_.end(), 0.0);
}

void CorotationalEfg::build(const std::function<bool(const Vec3&)>& inside, Vec3 box_min,
                            Vec3 box_max) {
  validate_settings(box_min, box_max);
  building_->lambda = lame_lambda(building_->material);
  building_->mu = lame_mu(building_->material);
  const ParticleGrid grid = lay_grids(box_min, box_max);
  sample_elements(inside);
  const std::vector<std::vector<int>> rows = select_neighbourhoods(grid);
  const std::vector<int> particle_of_grid = keep_used_particles(grid, rows);
  fill_rows(rows, particle_of_grid);
  make_masses_positive(grid, particle_of_grid);
  drop_unused_particles();
}

void CorotationalEfg::validate_settings(const Vec3& box_min, const Vec3& box_max) const {
  validate_material(building_->material);
  const EfgSettings& s = building_->settings;
  const double a = s.spacing;
  if (!(a > 0) || !std::isfinite(a)) fail("spacing must be positive, got " + std::to_string(a));
  if (s.neighbours != 4 && s.neighbours != 8) {
    fail("neighbours must be 4 or 8, got " + std::to_string(s.neighbours));
  }
  if (!(s.support_factor > 1) || !std::isfinite(s.support_factor)) {
    // At 1 the farthest neighbour would get a zero weight.
    fail("support_factor must be greater than 1, got " + std::to_string(s.support_factor));
  }
  if (s.samples_per_axis < 1 || s.samples_per_axis > 64) {
    fail("samples_per_axis must be in [1, 64], got " + std::to_string(s.samples_per_axis));
  }
  if (s.rotation != EfgRotation::shape_matching && s.rotation != EfgRotation::deformation_gradient) {
    fail("rotation must be shape_matching or deformation_gradient, got " +
         std::to_string(static_cast<int>(s.rotation)));
  }
  if (s.threaded_elements < 0) {
    fail("threaded_elements must not be negative, got " + std::to_string(s.threaded_elements));
  }
  if (s.row_capacity < 0 || s.row_capacity > longest_row) {
    fail("row_capacity must be in [0, " + std::to_string(longest_row) + "], got " +
         std::to_string(s.row_capacity));
  }
  if (!box_min.allFinite() || !box_max.allFinite() || !(box_max.array() > box_min.array()).all()) {
    fail("the box " + format_point(box_min) + " to " + format_point(box_max) + " is empty");
  }
}

ParticleGrid CorotationalEfg::lay_grids(const Vec3& box_min, const Vec3& box_max) {
  // Grids: an even number of cubes per axis, so the particle grid (every other vertex)
  // covers them; the small shrink keeps an exact multiple of a from gaining a cube.
  const double a = building_->settings.spacing;
  long long cube_total = 1;
  for (int axis = 0; axis < 3; ++axis) {
    const double count = std::ceil((box_max[axis] - box_min[axis]) / a * (1.0 - 1e-12));
    if (count > 1 << 20) fail("spacing " + std::to_string(a) + " is too small for the box");
    int cubes = std::max(1, static_cast<int>(count));
    cubes += cubes % 2;
    building_->cube_counts[axis] = cubes;
    cube_total *= cubes;
    // Centred on the box: a symmetric body gets a symmetric grid, and when the extent is a
    // multiple of 2a the particles lie on the box faces (where clamps usually are).
    building_->origin[axis] = 0.5 * (box_min[axis] + box_max[axis]) - 0.5 * cubes * a;
  }
  if (cube_total > 100'000'000) fail("spacing " + std::to_string(a) + " gives too many cubes");
  return ParticleGrid{building_->origin, a, {building_->cube_counts[0] / 2 + 1, building_->cube_counts[1] / 2 + 1, building_->cube_counts[2] / 2 + 1}};
}

void CorotationalEfg::sample_elements(const std::function<bool(const Vec3&)>& inside) {
  // Integration elements: the cubes with a part inside, V_e by sampling (seed-004 §1.2).
  const EfgSettings& s = building_->settings;
  const double a = s.spacing;
  const int samples = s.samples_per_axis;
  const double sample_volume = a * a * a / (samples * samples * samples);
  building_->element_of_cube.assign(static_cast<size_t>(building_->cube_counts[0]) * building_->cube_counts[1] * building_->cube_counts[2], -1);
  for (int k = 0; k < building_->cube_counts[2]; ++k) {
    for (int j = 0; j < building_->cube_counts[1]; ++j) {
      for (int i = 0; i < building_->cube_counts[0]; ++i) {
        const Vec3 cube_min = building_->origin + a * Vec3(i, j, k);
        int inside_count = 0;
        Vec3 sample_sum = Vec3::Zero();  // in sample units from cube_min, exact in doubles
        for (int w = 0; w < samples; ++w) {
          for (int v = 0; v < samples; ++v) {
            for (int u = 0; u < samples; ++u) {
              const Vec3 sample = cube_min + a / samples * Vec3(u + 0.5, v + 0.5, w + 0.5);
              if (inside(sample)) {
                ++inside_count;
                sample_sum += Vec3(u + 0.5, v + 0.5, w + 0.5);
              }
            }
          }
        }
        if (inside_count == 0) continue;
        building_->element_of_cube[i + static_cast<size_t>(building_->cube_counts[0]) * (j + building_->cube_counts[1] * k)] =
            static_cast<int>(volumes_.size());
        building_->element_cubes.push_back({i, j, k});
        // A full cube's centroid is its centre exactly (the sums are exact in doubles).
        building_->centres.push_back(s.centroid_points && s.estimate_volumes
                               ? Vec3(cube_min + a * sample_sum / (static_cast<double>(inside_count) * samples))
                               : Vec3(cube_min + Vec3::Constant(0.5 * a)));
        volumes_.push_back(s.estimate_volumes ? inside_count * sample_volume : a * a * a);
      }
    }
  }
  if (volumes_.empty()) fail("no sample point is inside the body (check the box and spacing)");
}

std::vector<std::vector<int>> CorotationalEfg::select_neighbourhoods(const ParticleGrid& grid) const {
  // Neighbourhoods in grid-particle indices: the corners of the element's particle cell,
  // nearest first (ties to the lower index), 8 or the 4 nearest (seed-004 §1.3).
  const EfgSettings& s = building_->settings;
  const int elements = element_count();
  std::vector<std::vector<int>> rows(elements);
  for (int e = 0; e < elements; ++e) {
    const std::array<int, 3>& cube = building_->element_cubes[e];
    const std::array<int, 3> cell{cube[0] / 2, cube[1] / 2, cube[2] / 2};
    nearest_corners(grid, building_->centres[e], cell, s.neighbours, rows[e]);
    if (s.cuts.empty()) continue;
    const auto visible = [&](int index) {
      return !is_blocked(s, building_->centres[e], grid.position(index));
    };
    if (std::all_of(rows[e].begin(), rows[e].end(), visible)) continue;
    rows[e] = visible_neighbourhood(grid, e, cell, rows[e]);
  }
  return rows;
}

// A cut hides some of element e's cell corners `corners` (EfgSettings::cuts).
std::vector<int> CorotationalEfg::visible_neighbourhood(const ParticleGrid& grid, int e, const std::array<int, 3>& cell,
                                                        const std::vector<int>& corners) const {
  const EfgSettings& s = building_->settings;
  const auto visible = [&](int index) { return !is_blocked(s, building_->centres[e], grid.position(index)); };
  std::vector<Vec3> positions;

  // A cut hides some corners. The visible ones stay (they carry the coupling across the
  // uncut part, e.g. below a crack front), and each hidden corner is replaced by the particle
  // one step beyond its neighbour in the cell along an axis (the nearest such one that is
  // visible and new). An element whose cell the cut cuts off entirely thus gets the
  // neighbouring cell on its own side, keeping a cell-shaped, well-conditioned neighbourhood.
  std::vector<int> kept;
  std::vector<int> hidden;
  for (int index : corners) (visible(index) ? kept : hidden).push_back(index);
  for (int index : hidden) {
    const std::array<int, 3> corner = grid.coordinates(index);
    // The axis nearest the normal of the cut that hides the corner: stepping along it moves
    // away from the cut on the element's side, rather than around the crack front.
    int normal_axis = -1;
    if (s.replace_along_cut_normal) {
      for (const CutRectangle& cut : s.cuts) {
        if (!cut.blocks(building_->centres[e], grid.position(index))) continue;
        const Vec3 normal = cut.edge_u.cross(cut.edge_v).cwiseAbs();
        normal.maxCoeff(&normal_axis);
        break;
      }
    }
    double best_distance = std::numeric_limits<double>::infinity();
    int best = -1;
    for (int pass = 0; pass < 2 && best < 0; ++pass) for (int axis = 0; axis < 3; ++axis) {
      if (pass == 0 && normal_axis >= 0 && axis != normal_axis) continue;
      // The in-cell neighbour is one step towards the cell's other face on this axis.
      const int step = corner[axis] == cell[axis] ? 1 : -1;
      std::array<int, 3> beyond = corner;
      beyond[axis] += 2 * step;
      if (beyond[axis] < 0 || beyond[axis] >= grid.counts[axis]) continue;
      const int candidate = grid.index(beyond[0], beyond[1], beyond[2]);
      if (std::find(kept.begin(), kept.end(), candidate) != kept.end() || !visible(candidate)) {
        continue;
      }
      const double distance = (grid.position(candidate) - building_->centres[e]).squaredNorm();
      if (distance < best_distance || (distance == best_distance && candidate < best)) {
        best_distance = distance;
        best = candidate;
      }
    }
    if (best >= 0) kept.push_back(best);
  }
  // Still too few, or coplanar: add the nearest visible particles (ties to the lower index)
  // until there are enough spanning 3 dimensions.
  std::vector<std::pair<double, int>> candidates;
  for (int k = std::max(0, cell[2] - 2); k <= std::min(grid.counts[2] - 1, cell[2] + 3); ++k) {
    for (int j = std::max(0, cell[1] - 2); j <= std::min(grid.counts[1] - 1, cell[1] + 3); ++j) {
      for (int i = std::max(0, cell[0] - 2); i <= std::min(grid.counts[0] - 1, cell[0] + 3); ++i) {
        const int index = grid.index(i, j, k);
        if (std::find(kept.begin(), kept.end(), index) != kept.end() || !visible(index)) continue;
        candidates.push_back({(grid.position(index) - building_->centres[e]).squaredNorm(), index});
      }
    }
  }
  std::sort(candidates.begin(), candidates.end());
  const auto spans = [&](const std::vector<int>& row) {
    positions.clear();
    for (int index : row) positions.push_back(grid.position(index));
    return spans_three_dimensions(positions);
  };
  size_t next = 0;
  while (static_cast<int>(kept.size()) < longest_row &&
         (static_cast<int>(kept.size()) < s.neighbours || !spans(kept)) &&
         next < candidates.size()) {
    kept.push_back(candidates[next++].second);
  }
  if (!spans(kept)) {
    fail("element " + std::to_string(e) + " at " + format_point(building_->centres[e]) +
         " is cut off: no neighbourhood of visible particles spans 3 dimensions");
  }
  return kept;
}

std::vector<int> CorotationalEfg::keep_used_particles(const ParticleGrid& grid, const std::vector<std::vector<int>>& rows) {
  // Particles that influence nothing are dropped; the others keep their grid order.
  std::vector<int> particle_of_grid(grid.size(), -1);
  for (const auto& row : rows) {
    for (int index : row) particle_of_grid[index] = 0;
  }
  int particles = 0;
  std::vector<Vec3> particle_positions;
  for (size_t index = 0; index < particle_of_grid.size(); ++index) {
    if (particle_of_grid[index] < 0) continue;
    particle_of_grid[index] = particles++;
    const int g = static_cast<int>(index);
    building_->particle_cells.push_back(grid.coordinates(g));
    particle_positions.push_back(grid.position(g));
  }
  building_->positions.resize(3 * static_cast<Index>(particles));
  for (int p = 0; p < particles; ++p) building_->positions.segment<3>(3 * p) = particle_positions[p];
  return particle_of_grid;
}

void CorotationalEfg::fill_rows(const std::vector<std::vector<int>>& rows, const std::vector<int>& particle_of_grid) {
  const int elements = element_count();
  // Rows (ELL).
  int longest = 0;
  for (const auto& row : rows) longest = std::max(longest, static_cast<int>(row.size()));
  stride_ = std::max(longest, building_->settings.row_capacity);
  const size_t slots = static_cast<size_t>(elements) * stride_;
  row_lengths_.assign(elements, 0);
  neighbours_.assign(slots, 0);
  shape_values_.assign(slots, 0.0);
  shape_gradients_.assign(slots, Vec3::Zero());
  matching_coefficients_.assign(slots, Vec3::Zero());
  for (int e = 0; e < elements; ++e) {
    row_lengths_[e] = static_cast<int>(rows[e].size());
    for (int k = 0; k < row_lengths_[e]; ++k) {
      neighbours_[static_cast<size_t>(e) * stride_ + k] = particle_of_grid[rows[e][k]];
    }
  }
  supports_.assign(elements, 0.0);
  rest_gradients_.assign(elements, Mat3::Identity());
  rotations_.assign(elements, Mat3::Identity());
  orientations_.assign(elements, Quaternion::Identity());
  element_energies_.assign(elements, 0.0);

  executor_->parallel_for(elements, [this](int begin, int end) {
    for (int e = begin; e < end; ++e) compute_element(e);
  }, 256);
}

void CorotationalEfg::make_masses_positive(const ParticleGrid& grid, const std::vector<int>& particle_of_grid) {
  // Lumped mass m_i = sum_e phi_i(x_e) rho V_e (seed-004 §1.5). phi is negative for far
  // corners, so a particle outside the body that only some elements reach as a far corner
  // can get a negative mass. Such particles are taken out of those neighbourhoods (as if they
  // influenced nothing) and the elements recomputed, until every mass is positive.
  const int elements = element_count();
  std::vector<Vec3> positions;
  std::vector<uint8_t> excluded(static_cast<size_t>(building_->positions.size() / 3), 0);  // per kept particle
  for (int round = 0;; ++round) {
    compute_masses();
    std::vector<uint8_t> used(node_count(), 0), negative(node_count(), 0);
    for (int e = 0; e < elements; ++e) {
      const size_t base = static_cast<size_t>(e) * stride_;
      for (int k = 0; k < row_lengths_[e]; ++k) used[neighbours_[base + k]] = 1;
    }
    int negative_count = 0;
    for (int p = 0; p < node_count(); ++p) {
      if (used[p] && !(masses_[p] > 0)) {
        negative[p] = 1;
        ++negative_count;
      }
    }
    if (negative_count == 0) break;
    const auto first_negative = static_cast<int>(std::find(negative.begin(), negative.end(), 1) - negative.begin());
    const auto cell = building_->particle_cells[first_negative];
    const std::string culprit =
        "particle " + std::to_string(first_negative) + " (grid " + std::to_string(cell[0]) + ", " +
        std::to_string(cell[1]) + ", " + std::to_string(cell[2]) + ", at " +
        format_point(building_->positions.segment<3>(3 * first_negative)) + ") has lumped mass " +
        std::to_string(masses_[first_negative]) + " <= 0";
    if (round == 8) fail(culprit + " and removing such particles does not settle");
    for (int p = 0; p < node_count(); ++p) excluded[p] = excluded[p] || negative[p];
    std::vector<int> changed;
    for (int e = 0; e < elements; ++e) {
      const size_t base = static_cast<size_t>(e) * stride_;
      int kept = 0;
      positions.clear();
      for (int k = 0; k < row_lengths_[e]; ++k) {
        const int p = neighbours_[base + k];
        if (negative[p]) continue;
        neighbours_[base + kept++] = p;
        positions.push_back(building_->positions.segment<3>(3 * p));
      }
      if (kept == row_lengths_[e]) continue;
      if (kept < 4 || !spans_three_dimensions(positions)) {
        // Too few left (with 4 neighbours, any loss): refill to the former length with the
        // nearest particles that are allowed and visible (ties to the lower index).
        const int target = row_lengths_[e];
        const auto& cube = building_->element_cubes[e];
        std::vector<std::pair<double, int>> candidates;
        for (int k = std::max(0, cube[2] / 2 - 2); k <= std::min(grid.counts[2] - 1, cube[2] / 2 + 3); ++k) {
          for (int j = std::max(0, cube[1] / 2 - 2); j <= std::min(grid.counts[1] - 1, cube[1] / 2 + 3); ++j) {
            for (int i = std::max(0, cube[0] / 2 - 2); i <= std::min(grid.counts[0] - 1, cube[0] / 2 + 3); ++i) {
              const int p = particle_of_grid[grid.index(i, j, k)];
              if (p < 0 || excluded[p] ||
                  std::find(neighbours_.begin() + base, neighbours_.begin() + base + kept, p) !=
                      neighbours_.begin() + base + kept ||
                  is_blocked(building_->settings, building_->centres[e], building_->positions.segment<3>(3 * p))) {
                continue;
              }
              candidates.push_back({(building_->positions.segment<3>(3 * p) - building_->centres[e]).squaredNorm(), p});
            }
          }
        }
        std::sort(candidates.begin(), candidates.end());
        std::vector<int> row(neighbours_.begin() + base, neighbours_.begin() + base + kept);
        for (const auto& candidate : candidates) {
          if (static_cast<int>(row.size()) >= target && spans_three_dimensions(positions)) break;
          if (static_cast<int>(row.size()) >= longest_row) break;
          row.push_back(candidate.second);
          positions.push_back(building_->positions.segment<3>(3 * candidate.second));
        }
        if (!spans_three_dimensions(positions)) {
          fail(culprit + ", and element " + std::to_string(e) + " at " +
               format_point(building_->centres[e]) + " cannot do without it");
        }
        if (static_cast<int>(row.size()) > stride_) restride(static_cast<int>(row.size()));
        const size_t new_base = static_cast<size_t>(e) * stride_;
        std::copy(row.begin(), row.end(), neighbours_.begin() + new_base);
        kept = static_cast<int>(row.size());
      }
      row_lengths_[e] = kept;
      changed.push_back(e);
    }
    executor_->parallel_for(static_cast<int>(changed.size()), [&](int begin, int end) {
      for (int c = begin; c < end; ++c) compute_element(changed[c]);
    });
  }
}

void CorotationalEfg::compute_element(int element) {
  const size_t base = static_cast<size_t>(element) * stride_;
  const int length = row_lengths_[element];
  const Vec3& centre = shape_->centres[element];
  std::array<Vec3, longest_row> positions;
  double farthest = 0;
  for (int k = 0; k < length; ++k) {
    positions[k] = shape_->positions.segment<3>(3 * static_cast<Index>(neighbours_[base + k]));
    farthest = std::max(farthest, (positions[k] - centre).norm());
  }
  // h = support factor x the distance to the farthest neighbour ([our interpretation] of the
  // thesis's "radius of the region of influence", seed-004 §1.4): every neighbour weighs > 0.
  const double support = shape_->settings.support_factor * farthest;
  supports_[element] = support;
  const std::span<const Vec3> neighbour_positions(positions.data(), length);
  if (!mls_shape_functions(centre, neighbour_positions, support, shape_->settings.spacing,
                           std::span<double>(&shape_values_[base], length),
                           std::span<Vec3>(&shape_gradients_[base], length))) {
    fail("element " + std::to_string(element) + " at " + format_point(centre) +
         ": singular MLS moment matrix (coplanar neighbourhood of " + std::to_string(length) +
         " particles)");
  }

  // Shape matching (seed-004 §1.6) as the weighted least-squares linear fit
  // F = A_pq A_qq^-1 (Mueller et al. 2005): its rotation is exactly Q under a rigid motion
  // and exactly I under a pure strain, which R = polar(A_pq) alone would not give for an
  // anisotropic neighbourhood. F = sum_n x_n (x) c_n, c_n = w_n A_qq^-1 (X_n - Xbar).
  std::array<double, longest_row> weights;
  double weight_sum = 0;
  Vec3 weighted_centre = Vec3::Zero();
  for (int k = 0; k < length; ++k) {
    weights[k] = quartic_spline((positions[k] - centre).norm(), support);
    weight_sum += weights[k];
    weighted_centre += weights[k] * positions[k];
  }
  weighted_centre /= weight_sum;
  Mat3 spread = Mat3::Zero();
  for (int k = 0; k < length; ++k) {
    const Vec3 offset = positions[k] - weighted_centre;
    spread += weights[k] * offset * offset.transpose();
  }
  const Mat3 spread_inverse = spread.inverse();
  Mat3 rest_gradient = Mat3::Zero();
  for (int k = 0; k < length; ++k) {
    matching_coefficients_[base + k] =
        weights[k] * spread_inverse * (positions[k] - weighted_centre);
    rest_gradient += positions[k] * shape_gradients_[base + k].transpose();
  }
  rest_gradients_[element] = rest_gradient;
}

void CorotationalEfg::compute_masses() {
  masses_ = Vector::Zero(shape_->positions.size() / 3);
  for (int e = 0; e < element_count(); ++e) {
    const size_t base = static_cast<size_t>(e) * stride_;
    const double element_mass = shape_->material.density * volumes_[e];
    for (int k = 0; k < row_lengths_[e]; ++k) {
      masses_[neighbours_[base + k]] += shape_values_[base + k] * element_mass;
    }
  }
}

void CorotationalEfg::drop_unused_particles() {
  std::vector<int> new_index(node_count(), -1);
  for (int e = 0; e < element_count(); ++e) {
    const size_t base = static_cast<size_t>(e) * stride_;
    for (int k = 0; k < row_lengths_[e]; ++k) new_index[neighbours_[base + k]] = 0;
  }
  int kept = 0;
  for (int p = 0; p < node_count(); ++p) {
    if (new_index[p] < 0) continue;
    new_index[p] = kept;
    building_->positions.segment<3>(3 * kept) = building_->positions.segment<3>(3 * p);
    masses_[kept] = masses_[p];
    building_->particle_cells[kept] = building_->particle_cells[p];
    ++kept;
  }
  building_->positions.conservativeResize(3 * static_cast<Index>(kept));
  masses_.conservativeResize(kept);
  building_->particle_cells.resize(kept);
  for (int e = 0; e < element_count(); ++e) {
    const size_t base = static_cast<size_t>(e) * stride_;
    for (int k = 0; k < row_lengths_[e]; ++k) neighbours_[base + k] = new_index[neighbours_[base + k]];
  }
}

void CorotationalEfg::restride(int stride) {
  const int elements = element_count();
  const size_t slots = static_cast<size_t>(elements) * stride;
  std::vector<int> neighbours(slots, 0);
  std::vector<double> values(slots, 0.0);
  std::vector<Vec3> gradients(slots, Vec3::Zero());
  std::vector<Vec3> coefficients(slots, Vec3::Zero());
  for (int e = 0; e < elements; ++e) {
    for (int k = 0; k < row_lengths_[e]; ++k) {
      const size_t from = static_cast<size_t>(e) * stride_ + k;
      const size_t to = static_cast<size_t>(e) * stride + k;
      neighbours[to] = neighbours_[from];
      values[to] = shape_values_[from];
      gradients[to] = shape_gradients_[from];
      coefficients[to] = matching_coefficients_[from];
    }
  }
  neighbours_.swap(neighbours);
  shape_values_.swap(values);
  shape_gradients_.swap(gradients);
  matching_coefficients_.swap(coefficients);
  stride_ = stride;
}

void CorotationalEfg::set_neighbourhood(int element, std::span<const int> particles) {
  if (element < 0 || element >= element_count()) {
    fail("set_neighbourhood: element " + std::to_string(element) + " outside [0, " +
         std::to_string(element_count()) + ")");
  }
  const int length = static_cast<int>(particles.size());
  if (length < 4 || length > longest_row) {
    fail("set_neighbourhood: element " + std::to_string(element) + " needs 4 to " +
         std::to_string(longest_row) + " particles, got " + std::to_string(length));
  }
  std::vector<Vec3> positions;
  for (int k = 0; k < length; ++k) {
    const int p = particles[k];
    if (p < 0 || p >= node_count()) {
      fail("set_neighbourhood: particle " + std::to_string(p) + " outside [0, " +
           std::to_string(node_count()) + ")");
    }
    if (std::find(particles.begin(), particles.begin() + k, p) != particles.begin() + k) {
      fail("set_neighbourhood: particle " + std::to_string(p) + " given twice");
    }
    positions.push_back(shape_->positions.segment<3>(3 * p));
  }
  if (!spans_three_dimensions(positions)) {
    fail("set_neighbourhood: the particles of element " + std::to_string(element) +
         " are coplanar");
  }
  if (length > stride_) restride(length);

  // Keep the old row to restore it if the new one is rejected.
  const size_t base = static_cast<size_t>(element) * stride_;
  const int old_length = row_lengths_[element];
  const std::vector<int> old_neighbours(neighbours_.begin() + base, neighbours_.begin() + base + old_length);
  const std::vector<double> old_values(shape_values_.begin() + base, shape_values_.begin() + base + old_length);
  const std::vector<Vec3> old_gradients(shape_gradients_.begin() + base, shape_gradients_.begin() + base + old_length);
  const std::vector<Vec3> old_coefficients(matching_coefficients_.begin() + base, matching_coefficients_.begin() + base + old_length);
  const double old_support = supports_[element];
  const Mat3 old_rest_gradient = rest_gradients_[element];
  const auto restore = [&] {
    row_lengths_[element] = old_length;
    std::copy(old_neighbours.begin(), old_neighbours.end(), neighbours_.begin() + base);
    std::copy(old_values.begin(), old_values.end(), shape_values_.begin() + base);
    std::copy(old_gradients.begin(), old_gradients.end(), shape_gradients_.begin() + base);
    std::copy(old_coefficients.begin(), old_coefficients.end(), matching_coefficients_.begin() + base);
    supports_[element] = old_support;
    rest_gradients_[element] = old_rest_gradient;
  };

  row_lengths_[element] = length;
  std::copy(particles.begin(), particles.end(), neighbours_.begin() + base);
  try {
    compute_element(element);
  } catch (...) {
    restore();
    throw;
  }
  // The element's mass rho V_e moves to its new neighbours (seed-004 §2.4 step 4), shared by
  // phi (the thesis's rule). phi is negative at far corners, so after cuts a particle whose
  // other elements are gone can be left with a negative mass: the element then shares its
  // mass by the positive part of phi instead (counted in positive_mass_elements()). A
  // particle no element uses any more keeps its last mass and is reported as orphaned: it
  // influences nothing, and the caller pins it.
  if (positive_mass_.size() != volumes_.size()) positive_mass_.assign(volumes_.size(), 0);
  if (references_.size() != static_cast<size_t>(masses_.size())) {
    references_.assign(masses_.size(), 0);
    for (int e = 0; e < element_count(); ++e)
      for (int k = 0; k < row_lengths_[e]; ++k) ++references_[neighbours_[static_cast<size_t>(e) * stride_ + k]];
  }
  const auto shares = [](std::span<const double> values, bool positive) {
    std::vector<double> weights(values.begin(), values.end());
    if (positive) {
      double sum = 0;
      for (double& w : weights) sum += (w = std::max(w, 0.0));
      for (double& w : weights) w /= sum;
    }
    return weights;
  };
  const double element_mass = shape_->material.density * volumes_[element];
  std::vector<int> references = references_;
  for (int p : old_neighbours) --references[p];
  for (int p : particles) ++references[p];
  const std::vector<double> old_shares = shares(old_values, positive_mass_[element] != 0);
  Vector masses;
  bool accepted = false;
  int bad = -1;
  for (const bool positive : {false, true}) {
    masses = masses_;
    for (int k = 0; k < old_length; ++k) masses[old_neighbours[k]] -= old_shares[k] * element_mass;
    const std::vector<double> new_shares =
        shares(std::span<const double>(&shape_values_[base], static_cast<size_t>(length)), positive);
    for (int k = 0; k < length; ++k) masses[particles[k]] += new_shares[k] * element_mass;
    bad = -1;
    for (int k = 0; k < old_length + length && bad < 0; ++k) {
      const int p = k < old_length ? old_neighbours[k] : particles[k - old_length];
      if (references[p] == 0) {
        masses[p] = masses_[p];  // orphaned: keeps its mass
      } else if (!(masses[p] > 0)) {
        bad = p;
      }
    }
    if (bad < 0) {
      positive_mass_[element] = positive ? 1 : 0;
      accepted = true;
      break;
    }
  }
  if (!accepted) {
    // Even the positive shares leave a particle without mass: its other elements weigh it
    // negatively. It keeps a floor of 1e-3 of this element's mass (counted): the DOF must stay
    // a DOF, and the mass this adds is far below the sampling error of the volumes.
    positive_mass_[element] = 1;
    for (int k = 0; k < old_length + length; ++k) {
      const int p = k < old_length ? old_neighbours[k] : particles[k - old_length];
      if (references[p] > 0 && !(masses[p] > 0)) {
        masses[p] = 1e-3 * element_mass;
        ++masses_floored_;
      }
    }
  }
  for (int p : old_neighbours)
    if (references[p] == 0 && references_[p] > 0) orphans_.push_back(p);
  references_.swap(references);
  masses_.swap(masses);
  rotations_[element] = Mat3::Identity();
  orientations_[element] = Quaternion::Identity();
  if (static_cast<size_t>(element) < energy_valid_.size()) energy_valid_[element] = 0;
  partition_nodes_stale_ = true;
}

}  // namespace incise::physics

namespace incise::physics {

void CorotationalEfg::deactivate_element(int element) {
  if (element < 0 || element >= element_count()) {
    fail("deactivate_element: element " + std::to_string(element) + " outside [0, " +
         std::to_string(element_count()) + ")");
  }
  if (!(volumes_[element] > 0)) return;
  if (positive_mass_.size() != volumes_.size()) positive_mass_.assign(volumes_.size(), 0);
  if (references_.size() != static_cast<size_t>(masses_.size())) {
    references_.assign(masses_.size(), 0);
    for (int e = 0; e < element_count(); ++e)
      for (int k = 0; k < row_lengths_[e]; ++k) ++references_[neighbours_[static_cast<size_t>(e) * stride_ + k]];
  }
  const size_t base = static_cast<size_t>(element) * stride_;
  const int length = row_lengths_[element];
  std::vector<double> shares(shape_values_.begin() + base, shape_values_.begin() + base + length);
  if (positive_mass_[element]) {
    double sum = 0;
    for (double& w : shares) sum += (w = std::max(w, 0.0));
    for (double& w : shares) w /= sum;
  }
  const double element_mass = shape_->material.density * volumes_[element];
  for (int k = 0; k < length; ++k) {
    const int p = neighbours_[base + k];
    --references_[p];
    if (references_[p] == 0) {
      orphans_.push_back(p);  // keeps its mass
      continue;
    }
    masses_[p] -= shares[k] * element_mass;
    if (!(masses_[p] > 0)) {
      masses_[p] = 1e-3 * element_mass;
      ++masses_floored_;
    }
  }
  volumes_[element] = 0;  // no force, no stiffness, no energy from now on
  // The energy's force matrix had the old volume (its rotation, extracted afresh, comes out
  // the same).
  if (static_cast<size_t>(element) < energy_valid_.size()) energy_valid_[element] = 0;
  ++deactivated_;
}

}  // namespace incise::physics
