// The corotated EFG model's build (physics/efg/corotational_efg.hpp): the settings checked, the
// grids laid, the elements sampled, the rows filled and their shape functions computed, the
// masses made positive. The neighbourhood selection is in efg_neighbourhoods.cpp, the cut test
// in efg_cut_visibility.cpp, the cut's edits in efg_cut_edits.cpp, the step in efg_step.cpp.
#include "physics/efg/corotational_efg.hpp"

#include "physics/efg/efg_build.hpp"
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

using efg_detail::fail;
using efg_detail::format_point;
using efg_detail::longest_row;

}  // namespace

using efg_build::ParticleGrid;
using efg_build::is_blocked;

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
  ++topology_revision_;
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

}  // namespace incise::physics
