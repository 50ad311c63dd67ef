// The cut's edits of a built CorotationalEfg: an element's neighbourhood replaced
// (set_neighbourhood, its mass moved to the new row) and an element removed (deactivate_element).
#include "physics/efg/corotational_efg.hpp"
#include "physics/efg/efg_detail.hpp"
#include "physics/efg/mls.hpp"

#include <algorithm>
#include <string>
#include <vector>

namespace incise::physics {

namespace {

using Quaternion = Eigen::Quaterniond;

using efg_detail::fail;
using efg_detail::longest_row;

}  // namespace

void CorotationalEfg::set_neighbourhood(int element, std::span<const int> particles) {
  if (element < 0 || element >= element_count()) {
    fail("set_neighbourhood: element " + std::to_string(element) + " outside [0, " +
         std::to_string(element_count()) + ")");
  }
  // node_rotations' incidence and current_stiffness's plan follow (a refused edit restores the
  // row: listed anyway, the plan finds it unchanged).
  ++topology_revision_;
  rows_edited_.push_back(element);
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
  ++topology_revision_;
  // The energy's force matrix had the old volume (its rotation, extracted afresh, comes out
  // the same).
  if (static_cast<size_t>(element) < energy_valid_.size()) energy_valid_[element] = 0;
  ++deactivated_;
}

}  // namespace incise::physics
