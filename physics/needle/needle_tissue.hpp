// What the needle needs of the tissue it enters (seed 002 §2.3): the body's nodes as particles,
// each with its neighbours (the zones grow through them), whether it is on the body's boundary,
// and its own cutting and friction intensities (k_c, k_f: "may vary locally, e.g. for a
// tumour"; the boundary's k_c is the puncture's).
#pragma once

#include "physics/core/model.hpp"
#include "physics/needle/needle_settings.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace incise::physics {

struct NeedleTissue {
  std::vector<std::vector<int>> neighbours;  // per node, the nodes within `reach` at rest, increasing
  std::vector<std::uint8_t> boundary;        // per node, 1 on the body's surface
  std::vector<double> cutting;               // k_c per node, N
  std::vector<double> friction;              // k_f per node, N
  int size() const { return static_cast<int>(boundary.size()); }
};

// From the rest positions (3n), the nodes' spacing and the body's surface triangles (node
// indices): neighbours within 1.8 spacings (a lattice's Moore neighbours, its cube diagonals
// included), the surface's nodes the boundary, k_c the settings' cutting force inside and
// puncture force on the boundary, k_f the friction force everywhere. Throws
// std::invalid_argument for a spacing that is not positive or a triangle naming no node.
NeedleTissue make_needle_tissue(const Vector& rest, double spacing, const std::vector<std::array<int, 3>>& surface,
                                const NeedleSettings& settings);

// make_needle_tissue with the boundary given per node (1 on the body's surface): a meshless body's
// integration points (needle_efg.hpp), which no triangle names.
NeedleTissue make_needle_tissue_with_boundary(const Vector& rest, double spacing, std::vector<std::uint8_t> boundary,
                                              const NeedleSettings& settings);

}  // namespace incise::physics
