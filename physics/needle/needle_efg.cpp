#include "physics/needle/needle_efg.hpp"

#include <cmath>
#include <map>

namespace incise::physics {

std::vector<std::uint8_t> efg_boundary_points(const CorotationalEfg& efg) {
  const EfgRestShape& shape = *efg.rest_shape();
  const double full = std::pow(efg.spacing(), 3);
  const auto& counts = shape.cube_counts;
  const auto element_at = [&](std::array<int, 3> c) {
    for (int k = 0; k < 3; ++k)
      if (c[k] < 0 || c[k] >= counts[k]) return -1;
    return shape.element_of_cube[(static_cast<std::size_t>(c[2]) * counts[1] + c[1]) * counts[0] + c[0]];
  };
  std::vector<std::uint8_t> boundary(efg.element_count(), 0);
  for (int e = 0; e < efg.element_count(); ++e) {
    // A partial cube: the surface crosses it (its volume sampled below a^3).
    if (efg.element_volumes()[e] < full * (1 - 1e-9)) {
      boundary[e] = 1;
      continue;
    }
    const auto& cube = shape.element_cubes[e];
    for (int axis = 0; axis < 3 && !boundary[e]; ++axis)
      for (int side : {-1, 1}) {
        auto next = cube;
        next[axis] += side;
        if (element_at(next) < 0) boundary[e] = 1;
      }
  }
  return boundary;
}

NeedleTissue make_efg_needle_tissue(const CorotationalEfg& efg, const NeedleSettings& settings) {
  Vector rest(3 * efg.element_count());
  for (int e = 0; e < efg.element_count(); ++e) rest.segment<3>(3 * e) = efg.element_centres()[e];
  return make_needle_tissue_with_boundary(rest, efg.spacing(), efg_boundary_points(efg), settings);
}

void efg_point_positions(const CorotationalEfg& efg, const Vector& x, Vector& out) {
  const int elements = efg.element_count(), stride = efg.row_stride();
  out.resize(3 * elements);
  for (int e = 0; e < elements; ++e) {
    Vec3 p = Vec3::Zero();
    const std::size_t row = static_cast<std::size_t>(e) * stride;
    for (int k = 0; k < efg.row_lengths()[e]; ++k)
      p += efg.shape_values()[row + k] * x.segment<3>(3 * efg.neighbours()[row + k]);
    out.segment<3>(3 * e) = p;
  }
}

std::vector<NodalSpring> efg_point_forces_on_particles(const CorotationalEfg& efg,
                                                       const std::vector<std::pair<int, Vec3>>& point_forces,
                                                       const std::vector<std::uint8_t>& fixed) {
  // Ordered by particle so that the sums, and the springs' order, do not depend on a hash.
  std::map<int, Vec3> on;
  const int stride = efg.row_stride();
  for (const auto& [e, force] : point_forces) {
    const std::size_t row = static_cast<std::size_t>(e) * stride;
    for (int k = 0; k < efg.row_lengths()[e]; ++k) {
      const int particle = efg.neighbours()[row + k];
      if (fixed[particle]) continue;
      auto [it, added] = on.try_emplace(particle, Vec3::Zero());
      it->second += efg.shape_values()[row + k] * force;
    }
  }
  std::vector<NodalSpring> springs;
  springs.reserve(on.size());
  for (const auto& [particle, force] : on) springs.push_back({particle, force, Mat3::Zero()});
  return springs;
}

}  // namespace incise::physics
