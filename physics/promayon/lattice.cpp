#include "physics/promayon/lattice.hpp"

#include <algorithm>

namespace incise::physics {

std::string_view neighbourhood_name(Neighbourhood n) { return n == Neighbourhood::vn1 ? "vn1" : "moore"; }

std::optional<Neighbourhood> neighbourhood_from_name(std::string_view name) {
  if (name == "vn1") return Neighbourhood::vn1;
  if (name == "moore") return Neighbourhood::moore;
  return std::nullopt;
}

std::vector<std::vector<int>> lattice_neighbours(const HexMesh& mesh, Neighbourhood n) {
  std::vector<std::vector<int>> out(mesh.rest.size() / 3);
  for (const auto& hex : mesh.hexes) {
    if (n == Neighbourhood::vn1) {
      for (const auto& e : kHexEdges) {
        out[hex[e[0]]].push_back(hex[e[1]]);
        out[hex[e[1]]].push_back(hex[e[0]]);
      }
    } else {
      for (int a = 0; a < 8; ++a)
        for (int b = 0; b < 8; ++b)
          if (a != b) out[hex[a]].push_back(hex[b]);
    }
  }
  for (auto& list : out) {
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
  }
  return out;
}

Vector lattice_masses(const HexMesh& mesh, double density) {
  Vector m = Vector::Zero(static_cast<Eigen::Index>(mesh.rest.size() / 3));
  for (const auto& hex : mesh.hexes) {
    const double share = density * std::abs(hex_volume(mesh.rest, hex)) / 8;
    for (int v : hex) m[v] += share;
  }
  return m;
}

}  // namespace incise::physics
