#include "physics/needle/needle_tissue.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

namespace incise::physics {

namespace {

// Neighbours by a uniform grid of cell `reach`: each node looks in its cell and the 26 around it.
std::vector<std::vector<int>> neighbours_within(const Vector& rest, double reach) {
  const int n = static_cast<int>(rest.size() / 3);
  const auto cell_of = [&](int i) {
    std::array<long long, 3> c{};
    for (int k = 0; k < 3; ++k) c[k] = static_cast<long long>(std::floor(rest[3 * i + k] / reach));
    return c;
  };
  const auto key = [](const std::array<long long, 3>& c) {
    return (static_cast<unsigned long long>(c[0]) * 73856093ull) ^ (static_cast<unsigned long long>(c[1]) * 19349663ull) ^
           (static_cast<unsigned long long>(c[2]) * 83492791ull);
  };
  std::unordered_map<unsigned long long, std::vector<int>> grid;
  for (int i = 0; i < n; ++i) grid[key(cell_of(i))].push_back(i);
  std::vector<std::vector<int>> out(n);
  for (int i = 0; i < n; ++i) {
    const auto c = cell_of(i);
    for (long long dx = -1; dx <= 1; ++dx)
      for (long long dy = -1; dy <= 1; ++dy)
        for (long long dz = -1; dz <= 1; ++dz) {
          const auto it = grid.find(key({c[0] + dx, c[1] + dy, c[2] + dz}));
          if (it == grid.end()) continue;
          for (int j : it->second)
            if (j != i && (rest.segment<3>(3 * j) - rest.segment<3>(3 * i)).norm() <= reach) out[i].push_back(j);
        }
    std::sort(out[i].begin(), out[i].end());
    out[i].erase(std::unique(out[i].begin(), out[i].end()), out[i].end());  // hash collisions
  }
  return out;
}

}  // namespace

NeedleTissue make_needle_tissue(const Vector& rest, double spacing, const std::vector<std::array<int, 3>>& surface,
                                const NeedleSettings& settings) {
  const int n = static_cast<int>(rest.size() / 3);
  std::vector<std::uint8_t> boundary(n, 0);
  for (const auto& triangle : surface)
    for (int v : triangle) {
      if (v < 0 || v >= n) throw std::invalid_argument("needle: a surface triangle names node " + std::to_string(v) + " of " + std::to_string(n));
      boundary[v] = 1;
    }
  return make_needle_tissue_with_boundary(rest, spacing, std::move(boundary), settings);
}

NeedleTissue make_needle_tissue_with_boundary(const Vector& rest, double spacing, std::vector<std::uint8_t> boundary,
                                              const NeedleSettings& settings) {
  if (!(spacing > 0)) throw std::invalid_argument("needle: the body's node spacing " + std::to_string(spacing) + " is not positive");
  const int n = static_cast<int>(rest.size() / 3);
  if (static_cast<int>(boundary.size()) != n)
    throw std::invalid_argument("needle: " + std::to_string(boundary.size()) + " boundary flags for " + std::to_string(n) + " nodes");
  NeedleTissue tissue;
  tissue.neighbours = neighbours_within(rest, 1.8 * spacing);
  tissue.boundary = std::move(boundary);
  tissue.cutting.resize(n);
  for (int i = 0; i < n; ++i) tissue.cutting[i] = tissue.boundary[i] ? settings.puncture_force : settings.cutting_force;
  tissue.friction.assign(n, settings.friction_force);
  return tissue;
}

}  // namespace incise::physics
