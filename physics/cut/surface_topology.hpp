// Whether a triangle mesh is closed: the edges used by one triangle (holes) and by more than
// two (non-manifold). A cut surface must stay closed after every cut event (seed 004 §2.5).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace incise::physics {

// Edges of a triangle mesh used by one triangle (holes) and by more than two (non-manifold).
struct SurfaceTopology {
  int boundary_edges = 0;
  int nonmanifold_edges = 0;
  bool watertight() const { return boundary_edges == 0 && nonmanifold_edges == 0; }
};
SurfaceTopology surface_topology(const std::vector<std::array<int, 3>>& triangles);
// The same over the edges whose two ends are flagged in `among` (a vertex past its end is
// not): where a surface changed, so that the whole count can be kept up to date by taking
// these edges' count off before the change and adding it after (the front surface's cut).
SurfaceTopology surface_topology(const std::vector<std::array<int, 3>>& triangles, std::span<const std::uint8_t> among);

}  // namespace incise::physics
