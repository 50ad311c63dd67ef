#include "physics/mss/van_gelder.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <utility>

namespace incise::physics {

std::vector<Spring> van_gelder_springs(const TetMesh& mesh, double youngs_modulus, double poisson_ratio) {
  if (!(youngs_modulus > 0) || !std::isfinite(youngs_modulus))
    throw std::invalid_argument("van_gelder_springs: E must be positive and finite");
  if (!(poisson_ratio >= 0 && poisson_ratio < 0.5))
    throw std::invalid_argument("van_gelder_springs: nu must be in [0, 0.5)");
  const auto at = [&](int node) { return Vec3(mesh.rest.segment<3>(3 * static_cast<Eigen::Index>(node))); };
  std::map<std::pair<int, int>, double> volume;  // per edge, the summed volume of its tets
  for (const auto& tet : mesh.tets) {
    Mat3 edges;
    edges << at(tet[1]) - at(tet[0]), at(tet[2]) - at(tet[0]), at(tet[3]) - at(tet[0]);
    const double v = std::abs(edges.determinant()) / 6;
    if (!(v > 0)) throw std::invalid_argument("van_gelder_springs: a tetrahedron has no volume");
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) volume[{std::min(tet[a], tet[b]), std::max(tet[a], tet[b])}] += v;
  }
  std::vector<Spring> springs;
  springs.reserve(volume.size());
  for (const auto& [edge, v] : volume) {
    Spring s;
    s.a = edge.first, s.b = edge.second;
    s.rest_length = (at(s.b) - at(s.a)).norm();
    s.stiffness = youngs_modulus / (1 + poisson_ratio) * v / (s.rest_length * s.rest_length);
    springs.push_back(s);
  }
  return springs;
}

}  // namespace incise::physics
