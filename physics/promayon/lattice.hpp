// The atoms of Promayon's discrete models on a regular lattice (seed 002 §1.2, §5.1: the Truth
// Cube's 9 x 9 x 9 atoms): the nodes of a brick mesh (physics/mss/hex_mesh.hpp, the shape
// voxelised as the mass-spring does), each with the neighbour list its model reads.
#pragma once

#include "physics/core/model.hpp"
#include "physics/mss/hex_mesh.hpp"

#include <optional>
#include <string_view>
#include <vector>

namespace incise::physics {

// Von Neumann (VN1): the atoms one lattice step away along an axis, at most 6 (the brick
// edges). Moore: every atom within one step per component, at most 26 (the atoms sharing a
// brick); the seed's "about 14" counts each spring once (digest §9.6).
enum class Neighbourhood { vn1, moore };

std::string_view neighbourhood_name(Neighbourhood n);
std::optional<Neighbourhood> neighbourhood_from_name(std::string_view name);

// Per atom, its neighbours in increasing order.
std::vector<std::vector<int>> lattice_neighbours(const HexMesh& mesh, Neighbourhood n);

// Lumped masses: rho V / 8 of each brick to each of its nodes.
Vector lattice_masses(const HexMesh& mesh, double density);

}  // namespace incise::physics
