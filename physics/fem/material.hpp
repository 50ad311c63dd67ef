// Isotropic linear elastic material (SI units).
#pragma once

#include <cmath>
#include <stdexcept>
#include <string>

namespace incise::physics {

struct Material {
  double youngs_modulus = 0;  // E, Pa
  double poisson_ratio = 0;   // nu, dimensionless, in (-1, 0.5)
  double density = 0;         // rho, kg/m^3
};

// First Lame parameter lambda = E nu / ((1 + nu)(1 - 2 nu)).
inline double lame_lambda(const Material& material) {
  const double nu = material.poisson_ratio;
  return material.youngs_modulus * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
}

// Shear modulus mu = E / (2 (1 + nu)).
inline double lame_mu(const Material& material) {
  return material.youngs_modulus / (2.0 * (1.0 + material.poisson_ratio));
}

// Throws std::invalid_argument unless E > 0, -1 < nu < 0.5 and rho > 0 (all finite).
inline void validate_material(const Material& material) {
  const bool valid = std::isfinite(material.youngs_modulus) && material.youngs_modulus > 0 &&
                     std::isfinite(material.poisson_ratio) && material.poisson_ratio > -1.0 &&
                     material.poisson_ratio < 0.5 && std::isfinite(material.density) &&
                     material.density > 0;
  if (!valid) {
    throw std::invalid_argument(
        "Material: need youngs_modulus > 0, -1 < poisson_ratio < 0.5 and density > 0; got E = " +
        std::to_string(material.youngs_modulus) + ", nu = " +
        std::to_string(material.poisson_ratio) + ", rho = " + std::to_string(material.density));
  }
}

}  // namespace incise::physics
