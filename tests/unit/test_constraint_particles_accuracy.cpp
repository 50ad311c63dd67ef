// The constraint particles' set-up in `incise bench accuracy` (bench/accuracy_constraint_particles.hpp):
// k_D and k_V (per tet volume) calibrated on the periodic lattice of the beam's voxels.
#include "bench/accuracy_constraint_particles.hpp"

#include "physics/cp/constraint_particles.hpp"
#include "physics/mss/mss_static.hpp"

#include <gtest/gtest.h>

#include <array>
#include <iostream>
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

incise::physics::TractionMeasure measure(const ParticleCalibration& c, const Vec3& cell, const std::array<int, 3>& cells,
                                         incise::physics::StiffnessScaling scaling) {
  const Vec3 size = cell.cwiseProduct(Vec3(cells[0], cells[1], cells[2]));
  const incise::physics::TetMesh block = incise::physics::make_box_tets5(Vec3::Zero(), size, cells);
  incise::physics::ConstraintParticleSettings settings;
  settings.distance_stiffness = c.distance_stiffness;
  settings.area_stiffness = 0;
  settings.volume_stiffness = c.volume_stiffness;
  settings.scaling = scaling;
  incise::physics::ConstraintParticles model(block, settings);
  return incise::physics::measure_traction(dense_stiffness(model), block.rest, size, cells);
}

}  // namespace

// On cubes the lattice is cubic and its moduli have a closed form (the derivation in
// constraint_particles.cpp, per cube of side h): each axis edge is in one tet of each of the 4
// cubes round it, a corner tet (h^3 / 6), and each face diagonal in the central tet (h^3 / 3)
// and a corner tet of each of its 2 cubes, so per cube the springs' sum of V (n.n.n.n) is 2/3 on
// each axis direction and 2/3 on each of the 6 face-diagonal directions: C11 = 4/3 k_D + k_V,
// C12 = k_D / 3 + k_V, C44 = k_D / 3. E and nu along an axis are the target's when C11 - C12 =
// 2 mu and C12 = lambda: k_D = 2 mu, k_V = lambda - 2 mu / 3 (the shear modulus is then 2/3 of
// mu: the network is cubic, not isotropic).
TEST(ConstraintParticlesAccuracy, CubeCalibrationHasTheClosedForm) {
  for (const double nu : {0.25, 0.3, 0.45}) {
    const Material material{1e4, nu, 1000};
    const double mu = material.youngs_modulus / (2 * (1 + nu));
    const double lambda = material.youngs_modulus * nu / ((1 + nu) * (1 - 2 * nu));
    const ParticleCalibration c = calibrate_constraint_particles(Vec3::Constant(0.01), material);
    EXPECT_NEAR(c.distance_stiffness / (2 * mu), 1, 1e-9) << nu;
    EXPECT_NEAR(c.volume_stiffness / (lambda - 2 * mu / 3), 1, 1e-9) << nu;
  }
}

// The calibration homogenises the periodic lattice. With the stiffness per tet volume, blocks of
// it in traction (the rollers of measure_traction, through the model's own stiffness products)
// have the lattice's E within a few %, the n x n x n cubes and a beam one voxel thick alike (with
// one k per constraint a 3 x 3 x 3 block had 1.6 x the bulk's E): slightly soft, as the skin's
// voxels relax more freely away from the affine field, approaching the bulk as n grows (not
// smoothly in 1 / n: the split alternates, so odd and even n differ).
TEST(ConstraintParticlesAccuracy, BlocksOfAnySizeHaveTheCalibratedModulus) {
  const Vec3 cell = Vec3::Constant(0.01);
  const Material material{1e4, 0.3, 1000};
  const ParticleCalibration c = calibrate_constraint_particles(cell, material);
  EXPECT_NEAR(c.measured_E / material.youngs_modulus, 1, 1e-9);
  EXPECT_NEAR(c.measured_nu / material.poisson_ratio, 1, 1e-9);
  const auto per_volume = incise::physics::StiffnessScaling::per_volume;
  const std::array<int, 3> sizes{3, 4, 5};
  std::array<incise::physics::TractionMeasure, 3> m;
  for (int i = 0; i < 3; ++i) {
    m[i] = measure(c, cell, {sizes[i], sizes[i], sizes[i]}, per_volume);
    EXPECT_NEAR(m[i].youngs_modulus / material.youngs_modulus, 1, 0.06) << sizes[i];
    EXPECT_NEAR(m[i].poisson_ratio / material.poisson_ratio, 1, 0.12) << sizes[i];
  }
  EXPECT_LT(m[0].youngs_modulus, m[1].youngs_modulus);
  EXPECT_LT(m[1].youngs_modulus, m[2].youngs_modulus);
  // A beam 10 voxels long and one across: the whole body is skin.
  const incise::physics::TractionMeasure beam = measure(c, cell, {10, 1, 1}, per_volume);
  EXPECT_NEAR(beam.youngs_modulus / material.youngs_modulus, 1, 0.05);
}

// The thesis's one k per constraint, whatever its value, makes a beam one voxel thick far stiffer
// than a block of the same voxels: its edges are shared by fewer tets than a block's interior
// ones. Per tet volume the two agree.
TEST(ConstraintParticlesAccuracy, OneStiffnessPerConstraintStiffensAThinBeam) {
  const Vec3 cell = Vec3::Constant(0.01);
  const ParticleCalibration c = calibrate_constraint_particles(cell, {1e4, 0.3, 1000});
  const auto ratio = [&](incise::physics::StiffnessScaling scaling) {
    return measure(c, cell, {10, 1, 1}, scaling).youngs_modulus / measure(c, cell, {5, 5, 5}, scaling).youngs_modulus;
  };
  const double per_constraint = ratio(incise::physics::StiffnessScaling::per_constraint);
  const double per_volume = ratio(incise::physics::StiffnessScaling::per_volume);
  EXPECT_GT(per_constraint, 1.3);
  EXPECT_NEAR(per_volume, 1, 0.03);
  std::cout << "E of the 10 x 1 x 1 beam over the 5^3 block's: per_constraint " << per_constraint << ", per_volume "
            << per_volume << "\n";
}

// k_D and k_V are moduli: E ~ k, whatever the voxels' size; E twice as large needs 2 x k, with
// the same k_V / k_D.
TEST(ConstraintParticlesAccuracy, StiffnessesScaleAsE) {
  const Material material{10e6, 0.3, 1000};
  const Vec3 cell(0.01, 0.008, 0.012);
  const ParticleCalibration base = calibrate_constraint_particles(cell, material);
  const ParticleCalibration larger = calibrate_constraint_particles(2 * cell, material);
  const ParticleCalibration stiffer = calibrate_constraint_particles(cell, {2 * material.youngs_modulus, 0.3, 1000});
  EXPECT_NEAR(larger.distance_stiffness / base.distance_stiffness, 1, 1e-6);
  EXPECT_NEAR(larger.volume_stiffness / base.volume_stiffness, 1, 1e-6);
  EXPECT_NEAR(stiffer.distance_stiffness / base.distance_stiffness, 2, 1e-6);
  EXPECT_NEAR(stiffer.volume_stiffness / base.volume_stiffness, 2, 1e-6);
}

// The volume constraints stiffen the bulk only, so a more nearly incompressible target needs a
// larger k_V / k_D; a nu below the edge network's own (0.2 on cubes, where k_V = lambda - 2 mu / 3
// reaches 0) cannot be reached and is refused.
TEST(ConstraintParticlesAccuracy, VolumeShareGrowsWithPoissonRatio) {
  const Vec3 cell = Vec3::Constant(0.01);
  const ParticleCalibration at_03 = calibrate_constraint_particles(cell, {1e4, 0.3, 1000});
  const ParticleCalibration at_045 = calibrate_constraint_particles(cell, {1e4, 0.45, 1000});
  EXPECT_GT(at_045.volume_stiffness / at_045.distance_stiffness, 2 * at_03.volume_stiffness / at_03.distance_stiffness);
  EXPECT_THROW(calibrate_constraint_particles(cell, {1e4, 0.01, 1000}), std::runtime_error);
}
