// What the build's files of CorotationalEfg share (physics/efg/corotational_efg.cpp,
// efg_neighbourhoods.cpp, efg_cut_visibility.cpp): the particle grid and the cut-visibility test.
#pragma once

#include "physics/efg/corotational_efg.hpp"

#include <array>
#include <cstddef>

namespace incise::physics::efg_build {

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

// Whether the settings' build-time cuts hide `to` from `from` (EfgSettings::cuts,
// front_hidden_beyond).
bool is_blocked(const EfgSettings& s, const Vec3& from, const Vec3& to);

}  // namespace incise::physics::efg_build
