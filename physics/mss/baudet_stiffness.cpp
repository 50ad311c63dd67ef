#include "physics/mss/baudet_stiffness.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

namespace incise::physics {

BrickSprings baudet_brick_springs(const Vec3& size, double youngs_modulus, double poisson_ratio) {
  const double E = youngs_modulus, nu = poisson_ratio;
  const double volume = size.prod();
  const double sum_squares = size.squaredNorm();  // x0^2 + y0^2 + z0^2
  BrickSprings springs;
  // Digest B.1.3 "reconstructed": the mean of Annexe A.2's three shear stiffnesses. §4.2's
  // printed (x0 + y0 + z0) / (24 ...) lost its squares; this form gives the cube's 3 E h / (8 (1 + nu)).
  springs.diagonal = E * sum_squares * sum_squares / (24 * (1 + nu) * volume);
  for (int i = 0; i < 3; ++i) {
    const double a = size[i], b = size[(i + 1) % 3], c = size[(i + 2) % 3];
    // The printed numerator "(nu (j^2 + k^2)_i^2)" is a garbled nu (j^2 + k^2) - i^2 (B.1.3).
    springs.edge[i] =
        E * (6 * b * b * c * c * (1 + nu) + (nu * (b * b + c * c) - a * a) * sum_squares) / (24 * (1 + nu) * volume);
    for (int j = 0; j < 3; ++j) {
      if (j == i) continue;
      const double lj = size[j], lk = size[3 - i - j];
      // F_ij = -[S (nu (k^2 + i^2) - i^2) + 6 i^2 k^2 nu] F_i / (48 i j k^2), k the third axis.
      springs.correction(i, j) =
          -(sum_squares * (nu * (lk * lk + a * a) - a * a) + 6 * a * a * lk * lk * nu) / (48 * a * lj * lk * lk);
    }
  }
  return springs;
}

double brick_aspect_ratio(const Vec3& size) { return size.maxCoeff() / size.minCoeff(); }

std::string brick_problem(const BrickSprings& springs) {
  static constexpr const char* kAxis = "xyz";
  std::ostringstream out;
  out.precision(4);
  for (int i = 0; i < 3; ++i)
    if (!(springs.edge[i] > 0)) {
      out << "edge stiffness along " << kAxis[i] << " is " << springs.edge[i] << " N/m";
      return out.str();
    }
  if (!(springs.diagonal > 0)) out << "diagonal stiffness is " << springs.diagonal << " N/m";
  return out.str();
}

}  // namespace incise::physics
