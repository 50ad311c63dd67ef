// The constraint particles' set-up in `incise bench accuracy` (bench/accuracy_constraint_particles.hpp):
// k_D and k_V calibrated on a traction block of the beam's voxels.
#include "bench/accuracy_constraint_particles.hpp"

#include "physics/cp/constraint_particles.hpp"
#include "physics/mss/mss_static.hpp"

#include <gtest/gtest.h>

#include <array>
#include <stdexcept>

using incise::bench::accuracy::calibrate_constraint_particles;
using incise::bench::accuracy::ParticleCalibration;
using incise::physics::Material;
using incise::physics::Vec3;

namespace {

// The network's dense stiffness at rest, from its products with the unit vectors (independent of
// the bench's assembly from the constraints' gradients).
Eigen::MatrixXd dense_stiffness(incise::physics::ConstraintParticles& model) {
  const Eigen::Index n = model.rest_positions().size();
  model.update_rotations(model.rest_positions());
  Eigen::MatrixXd k(n, n);
  for (Eigen::Index d = 0; d < n; ++d) {
    incise::physics::Vector unit = incise::physics::Vector::Zero(n), out = incise::physics::Vector::Zero(n);
    unit[d] = 1;
    model.add_stiffness_product(unit, out);
    k.col(d) = out;
  }
  return k;
}

incise::physics::TractionMeasure measure(const ParticleCalibration& c, const Vec3& cell, int cells) {
  const Vec3 size = cells * cell;
  const incise::physics::TetMesh block = incise::physics::make_box_tets5(Vec3::Zero(), size, {cells, cells, cells});
  incise::physics::ConstraintParticleSettings settings;
  settings.distance_stiffness = c.distance_stiffness;
  settings.area_stiffness = 0;
  settings.volume_stiffness = c.volume_stiffness;
  incise::physics::ConstraintParticles model(block, settings);
  return incise::physics::measure_traction(dense_stiffness(model), block.rest, size, {cells, cells, cells});
}

}  // namespace

// The calibration homogenises the periodic lattice; blocks of n x n x n voxels in traction (the
// rollers of measure_traction, through the model's own stiffness products) are stiffer, their
// surface layer more than the bulk, and approach it as 1 / n: a quadratic in 1 / n through the
// blocks of 3, 4 and 5 voxels, taken to 1 / n = 0, gives back the targets.
TEST(ConstraintParticlesAccuracy, BlocksConvergeToTheCalibratedModuli) {
  const Vec3 cell = Vec3::Constant(0.01);
  const Material material{1e4, 0.3, 1000};
  const ParticleCalibration c = calibrate_constraint_particles(cell, material);
  EXPECT_NEAR(c.measured_E / material.youngs_modulus, 1, 1e-9);
  EXPECT_NEAR(c.measured_nu / material.poisson_ratio, 1, 1e-9);
  const std::array<int, 3> sizes{3, 4, 5};
  std::array<incise::physics::TractionMeasure, 3> m;
  for (int i = 0; i < 3; ++i) m[i] = measure(c, cell, sizes[i]);
  EXPECT_GT(m[0].youngs_modulus, m[1].youngs_modulus);
  EXPECT_GT(m[1].youngs_modulus, m[2].youngs_modulus);
  EXPECT_GT(m[2].youngs_modulus, material.youngs_modulus);
  // Lagrange's quadratic through (1 / n, value) at 0.
  const auto at_zero = [&](auto value) {
    double sum = 0;
    for (int i = 0; i < 3; ++i) {
      double weight = 1;
      for (int j = 0; j < 3; ++j)
        if (j != i) weight *= (0 - 1.0 / sizes[j]) / (1.0 / sizes[i] - 1.0 / sizes[j]);
      sum += weight * value(m[i]);
    }
    return sum;
  };
  EXPECT_NEAR(at_zero([](const auto& t) { return t.youngs_modulus; }) / material.youngs_modulus, 1, 0.01);
  EXPECT_NEAR(at_zero([](const auto& t) { return t.poisson_ratio; }) / material.poisson_ratio, 1, 0.05);
}

// C is dimensionless, so K ~ k / h^2 and E ~ k / h^3: voxels twice as large need 8 x k, and E
// twice as large 2 x k, with the same k_V / k_D.
TEST(ConstraintParticlesAccuracy, StiffnessesScaleAsEHCubed) {
  const Material material{10e6, 0.3, 1000};
  const Vec3 cell(0.01, 0.008, 0.012);
  const ParticleCalibration base = calibrate_constraint_particles(cell, material);
  const ParticleCalibration larger = calibrate_constraint_particles(2 * cell, material);
  const ParticleCalibration stiffer = calibrate_constraint_particles(cell, {2 * material.youngs_modulus, 0.3, 1000});
  EXPECT_NEAR(larger.distance_stiffness / base.distance_stiffness, 8, 1e-6);
  EXPECT_NEAR(larger.volume_stiffness / base.volume_stiffness, 8, 1e-6);
  EXPECT_NEAR(stiffer.distance_stiffness / base.distance_stiffness, 2, 1e-6);
  EXPECT_NEAR(stiffer.volume_stiffness / base.volume_stiffness, 2, 1e-6);
}

// The volume constraints stiffen the bulk only, so a more nearly incompressible target needs a
// larger k_V / k_D; a nu below the edge network's own cannot be reached and is refused.
TEST(ConstraintParticlesAccuracy, VolumeShareGrowsWithPoissonRatio) {
  const Vec3 cell = Vec3::Constant(0.01);
  const ParticleCalibration at_03 = calibrate_constraint_particles(cell, {1e4, 0.3, 1000});
  const ParticleCalibration at_045 = calibrate_constraint_particles(cell, {1e4, 0.45, 1000});
  EXPECT_GT(at_045.volume_stiffness / at_045.distance_stiffness, 2 * at_03.volume_stiffness / at_03.distance_stiffness);
  EXPECT_THROW(calibrate_constraint_particles(cell, {1e4, 0.01, 1000}), std::runtime_error);
}
