// The corotated EFG model as a DeformableModel: patch test, rotations, stiffness, mass,
// thread independence, neighbourhood edits and the surface embedding.
#include "engine/thread_pool.hpp"
#include "physics/core/implicit_euler.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/efg/efg_static.hpp"
#include "physics/fem/static_solve.hpp"
#include "physics/fem/tet_element.hpp"
#include "physics/solve/block_matrix.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <vector>

namespace incise::physics {
namespace {

const Material tissue{30e3, 0.45, 1050};

EfgSettings settings_with(int neighbours) {
  EfgSettings settings;
  settings.spacing = 0.005;
  settings.neighbours = neighbours;
  settings.threaded_elements = 0;  // small test bodies still use every thread
  return settings;
}

// The models below run on two threads unless told otherwise, as a World's do by default.
Executor* two_threads() {
  static engine::ThreadPoolExecutor executor(2, false);
  return &executor;
}

// Box [0, 0.04] x [0, 0.03] x [0, 0.02] on an aligned grid: 8 x 6 x 4 full cubes, 5 x 4 x 3
// particles, 6 of them interior.
CorotationalEfg box_model(int neighbours, Executor* executor = two_threads()) {
  return CorotationalEfg(Vec3(0, 0, 0), Vec3(0.04, 0.03, 0.02), tissue,
                         settings_with(neighbours), executor);
}

// A rounded, irregular body (partial cubes everywhere on its surface).
CorotationalEfg blob_model(int neighbours, Executor* executor = two_threads()) {
  const auto inside = [](const Vec3& p) {
    const Vec3 q(p.x() / 0.035, p.y() / 0.025, p.z() / 0.02);
    return q.squaredNorm() + 0.3 * std::sin(40 * p.x()) * q.y() <= 1;
  };
  return CorotationalEfg(inside, Vec3(-0.04, -0.03, -0.025), Vec3(0.04, 0.03, 0.025), tissue,
                         settings_with(neighbours), executor);
}

Vector transform(const Vector& x, const Mat3& linear, const Vec3& translation = Vec3::Zero()) {
  Vector result(x.size());
  for (Eigen::Index node = 0; node < x.size() / 3; ++node) {
    result.segment<3>(3 * node) = linear * x.segment<3>(3 * node) + translation;
  }
  return result;
}

// Smooth non-affine deformation of a few percent.
Vector deform(const Vector& rest) {
  Vector x = rest;
  for (Eigen::Index node = 0; node < rest.size() / 3; ++node) {
    const Vec3 p = rest.segment<3>(3 * node);
    x.segment<3>(3 * node) += 0.002 * Vec3(std::sin(60 * p.y() + 1), std::cos(50 * p.z()) + 30 * p.x(),
                                           std::sin(40 * p.x() - 30 * p.y()));
  }
  return x;
}

Vector forces_at(CorotationalEfg& model, const Vector& x) {
  model.update_rotations(x);
  Vector f = Vector::Zero(x.size());
  model.add_elastic_forces(x, f);
  return f;
}

Vector stiffness_times(const CorotationalEfg& model, const Vector& p) {
  Vector out = Vector::Zero(p.size());
  model.add_stiffness_product(p, out);
  return out;
}

Mat3 rotation_about(const Vec3& axis, double degrees) {
  return Eigen::AngleAxisd(degrees * std::numbers::pi / 180, axis.normalized()).toRotationMatrix();
}

bool interior(const std::array<int, 3>& cell) {
  return cell[0] > 0 && cell[0] < 4 && cell[1] > 0 && cell[1] < 3 && cell[2] > 0 && cell[2] < 2;
}

class EfgModel : public testing::TestWithParam<int> {};

TEST_P(EfgModel, PatchTestUniformStrainLeavesInteriorParticlesUnloaded) {
  CorotationalEfg model = box_model(GetParam());
  ASSERT_EQ(model.node_count(), 60);
  // A uniform strain, then a 35 degree rotation: the corotated strain is uniform, so the
  // interior particles (all their 64 integration points full and symmetric) feel no force.
  Mat3 strain;
  strain << 0.010, 0.003, -0.002, 0.003, -0.006, 0.004, -0.002, 0.004, 0.008;
  const Mat3 deformation = rotation_about(Vec3(1, 2, -1), 35) * (Mat3::Identity() + strain);
  const Vector x = transform(model.rest_positions(), deformation, Vec3(0.01, -0.02, 0.005));
  const Vector f = forces_at(model, x);
  double interior_force = 0, boundary_force = 0;
  int interior_count = 0;
  for (int p = 0; p < model.node_count(); ++p) {
    const double norm = f.segment<3>(3 * p).norm();
    if (interior(model.particle_grid_coordinates()[p])) {
      interior_force = std::max(interior_force, norm);
      ++interior_count;
    } else {
      boundary_force = std::max(boundary_force, norm);
    }
  }
  std::printf("patch %d neighbours: interior |f| %.2e N, boundary |f| up to %.2e N\n", GetParam(),
              interior_force, boundary_force);
  EXPECT_EQ(interior_count, 6);
  EXPECT_GT(boundary_force, 1e-4);
  EXPECT_LT(interior_force, 1e-10 * boundary_force);
  // The forces of a body sum to zero (translation invariance).
  Vec3 total = Vec3::Zero();
  for (int p = 0; p < model.node_count(); ++p) total += f.segment<3>(3 * p);
  EXPECT_LT(total.norm(), 1e-10 * boundary_force);
}

TEST_P(EfgModel, PatchTestStaticSolveReproducesAffineField) {
  CorotationalEfg model = box_model(GetParam());
  model.update_rotations(model.rest_positions());
  Mat3 gradient;
  gradient << 0.02, -0.01, 0.005, 0.004, -0.015, 0.01, -0.003, 0.007, 0.012;
  const Vector affine = transform(model.rest_positions(), gradient, Vec3(1e-3, 0, -2e-3));
  std::vector<uint8_t> boundary(model.node_count(), 0);
  for (int p = 0; p < model.node_count(); ++p) {
    boundary[p] = interior(model.particle_grid_coordinates()[p]) ? 0 : 1;
  }
  const Vector u = solve_static(assemble_stiffness(model), Vector::Zero(affine.size()), boundary,
                                affine);
  double worst = 0;
  for (int p = 0; p < model.node_count(); ++p) {
    worst = std::max(worst, (u.segment<3>(3 * p) - affine.segment<3>(3 * p)).norm());
  }
  EXPECT_LT(worst, 1e-12 * affine.cwiseAbs().maxCoeff());
}

TEST_P(EfgModel, RigidMotionGivesZeroForceAndEnergy) {
  CorotationalEfg model = blob_model(GetParam());
  const Vector& rest = model.rest_positions();
  const double deformed_force = forces_at(model, deform(rest)).cwiseAbs().maxCoeff();
  for (double degrees : {0.0, 30.0, 120.0, 179.0}) {
    const Vector x = transform(rest, rotation_about(Vec3(0.3, -1, 0.5), degrees), Vec3(0.1, 0.2, -0.3));
    const double force = forces_at(model, x).cwiseAbs().maxCoeff();
    EXPECT_LT(force, 1e-9 * deformed_force) << degrees << " degrees";
    EXPECT_LT(model.elastic_energy(x), 1e-18) << degrees << " degrees";
  }
}

TEST_P(EfgModel, RotatingTheDeformedBodyRotatesForcesAndKeepsEnergy) {
  CorotationalEfg model = blob_model(GetParam());
  const Vector x = deform(model.rest_positions());
  const Vector f = forces_at(model, x);
  const double energy = model.elastic_energy(x);
  ASSERT_GT(energy, 0);
  const Mat3 rotation = rotation_about(Vec3(1, 1, 0.2), 70);
  const Vector turned = transform(x, rotation, Vec3(0.05, 0, 0.02));
  const Vector turned_forces = forces_at(model, turned);
  const double difference = (turned_forces - transform(f, rotation)).cwiseAbs().maxCoeff();
  std::printf("rotation %d neighbours: energy %.6e J -> %.6e J, |f' - R f| / |f| = %.1e\n",
              GetParam(), energy, model.elastic_energy(turned),
              difference / f.cwiseAbs().maxCoeff());
  EXPECT_LT(difference, 1e-9 * f.cwiseAbs().maxCoeff());
  EXPECT_NEAR(model.elastic_energy(turned), energy, 1e-10 * energy);
}

TEST_P(EfgModel, StiffnessProductMatchesFiniteDifferencesAtRest) {
  CorotationalEfg model = blob_model(GetParam());
  const Vector& rest = model.rest_positions();
  const Vector p = deform(rest) - rest;  // a smooth direction, |p| ~ 2 mm
  model.update_rotations(rest);
  const Vector product = stiffness_times(model, p);
  const double step = 1e-4;
  // True forces (rotations recomputed) on both sides: at rest the stress is zero, so K with
  // frozen rotations is the whole derivative.
  const Vector difference =
      -(forces_at(model, rest + step * p) - forces_at(model, rest - step * p)) / (2 * step);
  const double error = (product - difference).cwiseAbs().maxCoeff() / product.cwiseAbs().maxCoeff();
  std::printf("K p %d neighbours: relative difference to finite differences %.1e\n", GetParam(), error);
  EXPECT_LT(error, 1e-6);
}

TEST_P(EfgModel, StiffnessIsSymmetricAndMatchesAssembly) {
  CorotationalEfg model = blob_model(GetParam());
  model.update_rotations(transform(deform(model.rest_positions()), rotation_about(Vec3(0, 1, 1), 40)));
  const Vector p = deform(model.rest_positions()) - model.rest_positions();
  Vector q = p;
  for (Eigen::Index i = 0; i < q.size(); ++i) q[i] = std::cos(0.37 * static_cast<double>(i)) * 1e-3;
  const Vector kp = stiffness_times(model, p), kq = stiffness_times(model, q);
  EXPECT_NEAR(q.dot(kp), p.dot(kq), 1e-12 * std::abs(q.dot(kp)) + 1e-18);
  EXPECT_GT(p.dot(kp), 0);
  const SparseMatrix assembled = assemble_stiffness(model);
  EXPECT_LT((assembled * p - kp).cwiseAbs().maxCoeff(), 1e-12 * kp.cwiseAbs().maxCoeff());
  const SparseMatrix transpose = assembled.transpose();
  const SparseMatrix asymmetry = assembled - transpose;
  EXPECT_LT(asymmetry.coeffs().cwiseAbs().maxCoeff(), 1e-12 * assembled.coeffs().cwiseAbs().maxCoeff());
  Vector diagonal = Vector::Zero(p.size());
  model.add_stiffness_diagonal(diagonal);
  EXPECT_LT((diagonal - Vector(assembled.diagonal())).cwiseAbs().maxCoeff(),
            1e-12 * diagonal.cwiseAbs().maxCoeff());
}

TEST_P(EfgModel, LumpedMassesArePositiveAndSumToDensityTimesVolume) {
  for (const CorotationalEfg& model : {box_model(GetParam()), blob_model(GetParam())}) {
    const Vector& masses = model.lumped_masses();
    EXPECT_GT(masses.minCoeff(), 0);
    EXPECT_NEAR(masses.sum(), tissue.density * model.total_volume(), 1e-12 * masses.sum());
  }
  EXPECT_NEAR(box_model(GetParam()).total_volume(), 0.04 * 0.03 * 0.02, 1e-15);
}

TEST(EfgModelVolume, SampledVolumeOfASphereConverges) {
  const double radius = 0.02;
  const auto sphere = [radius](const Vec3& p) { return p.norm() <= radius; };
  const double exact = 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
  EfgSettings settings;
  settings.spacing = 0.004;
  double previous_error = 1;
  for (int samples : {2, 4, 8}) {
    settings.samples_per_axis = samples;
    const CorotationalEfg model(sphere, Vec3::Constant(-radius), Vec3::Constant(radius), tissue, settings);
    const double error = std::abs(model.total_volume() / exact - 1);
    std::printf("sphere volume with %d^3 samples per cube: error %.3f %%\n", samples, 100 * error);
    EXPECT_LT(error, previous_error);
    previous_error = error;
  }
  EXPECT_LT(previous_error, 0.005);
  settings.estimate_volumes = false;  // every touched cube counts whole: too much volume
  const CorotationalEfg whole(sphere, Vec3::Constant(-radius), Vec3::Constant(radius), tissue, settings);
  EXPECT_GT(whole.total_volume(), 1.2 * exact);
}

TEST(EfgModelVolume, PartialCubesIntegrateAtTheCentroidOfTheirInsidePart) {
  // A slab z <= 0.013 in a grid of 4 mm cubes from z = -0.016: the top cubes span [0.012,
  // 0.016] and are 1/4 inside, exactly 2 of the 8 sample rows. Their points sit at the middle
  // of the inside part, z = 0.0125 (the cube centre is outside, at 0.014), and then
  // sum_e V_e z_e is the slab's exact first moment.
  const auto slab = [](const Vec3& p) { return p.z() <= 0.013; };
  EfgSettings settings;
  settings.spacing = 0.004;
  settings.samples_per_axis = 8;
  const CorotationalEfg model(slab, Vec3(0, 0, -0.016), Vec3(0.016, 0.016, 0.016), tissue, settings);
  double first_moment = 0;
  for (int e = 0; e < model.element_count(); ++e) {
    const Vec3& point = model.element_centres()[e];
    const double volume = model.element_volumes()[e];
    if (volume < 0.999 * std::pow(0.004, 3)) {
      EXPECT_NEAR(point.z(), 0.0125, 1e-15) << "element " << e;
      EXPECT_NEAR(volume, 0.25 * std::pow(0.004, 3), 1e-20);
    } else {
      const auto& cube = model.element_grid_coordinates()[e];
      const Vec3 centre = model.grid_origin() + 0.004 * Vec3(cube[0] + 0.5, cube[1] + 0.5, cube[2] + 0.5);
      EXPECT_LT((point - centre).norm(), 1e-15) << "element " << e;
    }
    first_moment += volume * point.z();
  }
  const double area = 0.016 * 0.016;
  const double exact = area * (0.013 * 0.013 - 0.016 * 0.016) / 2;
  EXPECT_NEAR(first_moment, exact, 1e-12 * std::abs(exact));
  // The thesis's placement, at the cube centre, for comparison: the first moment is off.
  settings.centroid_points = false;
  const CorotationalEfg centred(slab, Vec3(0, 0, -0.016), Vec3(0.016, 0.016, 0.016), tissue, settings);
  double centred_moment = 0;
  for (int e = 0; e < centred.element_count(); ++e) {
    centred_moment += centred.element_volumes()[e] * centred.element_centres()[e].z();
  }
  EXPECT_GT(std::abs(centred_moment - exact), 0.01 * std::abs(exact));
}

TEST_P(EfgModel, OneAndTwoThreadsGiveBitwiseIdenticalResults) {
  struct Results {
    Vector masses, forces, product, diagonal;
    double energy = 0;
    std::vector<Mat3> rotations;
  };
  // A fresh model per executor: the build (shape functions, masses) runs on it too, and the
  // rotations' warm starts must match. threads 0: none given (serial_executor).
  const auto evaluate = [&](int threads) {
    std::optional<engine::ThreadPoolExecutor> pool;
    if (threads > 0) pool.emplace(threads, false);
    CorotationalEfg model = blob_model(GetParam(), pool ? &*pool : nullptr);
    EXPECT_EQ(model.executor().thread_count(), std::max(threads, 1));
    EXPECT_EQ(&model.executor(), pool ? static_cast<Executor*>(&*pool) : &serial_executor());
    const Vector x = transform(deform(model.rest_positions()), rotation_about(Vec3(1, 0, 1), 25));
    const Vector p = deform(model.rest_positions()) - model.rest_positions();
    Results results;
    results.masses = model.lumped_masses();
    results.forces = forces_at(model, x);
    results.product = stiffness_times(model, p);
    results.diagonal = Vector::Zero(p.size());
    model.add_stiffness_diagonal(results.diagonal);
    results.energy = model.elastic_energy(x);
    results.rotations = model.rotations();
    return results;
  };
  const Results two = evaluate(2), one = evaluate(1), three = evaluate(3), serial = evaluate(0);
  const auto same = [](const Vector& left, const Vector& right) {
    return left.size() == right.size() &&
           std::memcmp(left.data(), right.data(), sizeof(double) * left.size()) == 0;
  };
  for (const Results* other : {&one, &three, &serial}) {
    EXPECT_TRUE(same(two.masses, other->masses));
    EXPECT_TRUE(same(two.forces, other->forces));
    EXPECT_TRUE(same(two.product, other->product));
    EXPECT_TRUE(same(two.diagonal, other->diagonal));
    EXPECT_EQ(std::memcmp(&two.energy, &other->energy, sizeof(double)), 0);
    ASSERT_EQ(two.rotations.size(), other->rotations.size());
    EXPECT_EQ(std::memcmp(two.rotations.data(), other->rotations.data(),
                          sizeof(Mat3) * two.rotations.size()),
              0);
  }
  EXPECT_GT(two.forces.cwiseAbs().maxCoeff(), 0);
}

INSTANTIATE_TEST_SUITE_P(Neighbours, EfgModel, testing::Values(8, 4));

TEST(EfgModelTopology, CutLinksAreReplacedOnTheSameSide) {
  EfgSettings settings = settings_with(8);
  settings.spacing = 0.0025;
  // Across the whole width, from the top down to z = 0, at x = 0.02.
  const CutRectangle cut{Vec3(0.02, -1, 0.0), Vec3(0, 2, 0), Vec3(0, 0, 1)};
  settings.cuts.push_back(cut);
  const CorotationalEfg model(Vec3(0, -0.01, -0.01), Vec3(0.04, 0.01, 0.01), tissue, settings);
  const CorotationalEfg uncut(Vec3(0, -0.01, -0.01), Vec3(0.04, 0.01, 0.01), tissue, settings_with(8));
  int changed = 0;
  for (int e = 0; e < model.element_count(); ++e) {
    const size_t base = static_cast<size_t>(e) * model.row_stride();
    for (int k = 0; k < model.row_lengths()[e]; ++k) {
      const Vec3 particle = model.rest_positions().segment<3>(3 * model.neighbours()[base + k]);
      EXPECT_FALSE(cut.blocks(model.element_centres()[e], particle)) << "element " << e;
      if (std::abs(particle.x() - 0.02) < 1e-12 && model.element_centres()[e].x() < 0.02 &&
          particle.z() > 1e-12) {
        ADD_FAILURE() << "element " << e << " still uses a particle on the cut";
      }
    }
    if (model.element_centres()[e].x() > 0.0175 && model.element_centres()[e].x() < 0.02 &&
        model.element_centres()[e].z() > 0) {
      ++changed;
    }
  }
  EXPECT_GT(changed, 0);
  EXPECT_NEAR(model.lumped_masses().sum(), tissue.density * 0.04 * 0.02 * 0.02, 1e-12);
  // A tip load bends the cut beam more than the uncut one.
  const auto tip_deflection = [](CorotationalEfg& body) {
    body.update_rotations(body.rest_positions());
    const Vector load = gravity_forces(body.lumped_masses(), Vec3(0, 0, -9.81));
    const Vector u = solve_static(assemble_stiffness(body), load,
                                  nodes_in_box(body.rest_positions(), Vec3::Constant(-1), Vec3(1e-9, 1, 1)));
    return -u.segment<3>(u.size() - 3).z();
  };
  CorotationalEfg cut_model = CorotationalEfg(Vec3(0, -0.01, -0.01), Vec3(0.04, 0.01, 0.01), tissue, settings);
  CorotationalEfg uncut_model = CorotationalEfg(Vec3(0, -0.01, -0.01), Vec3(0.04, 0.01, 0.01), tissue, settings_with(8));
  EXPECT_GT(tip_deflection(cut_model), 1.05 * tip_deflection(uncut_model));
  EXPECT_EQ(uncut.row_stride(), 8);
}

TEST(EfgModelTopology, FrontParticlesAreHiddenBesideTheCutOnly) {
  // The cut of the test above; particles 5 mm apart, so a row lies on the front z = 0.
  EfgSettings settings = settings_with(8);
  settings.spacing = 0.0025;
  settings.cuts.push_back({Vec3(0.02, -1, 0.0), Vec3(0, 2, 0), Vec3(0, 0, 1)});
  const auto count_front_links = [](const CorotationalEfg& model, bool beside) {
    int links = 0;
    for (int e = 0; e < model.element_count(); ++e) {
      const Vec3& point = model.element_centres()[e];
      if (!(point.x() < 0.02) || (point.z() > 0) != beside) continue;
      const size_t base = static_cast<size_t>(e) * model.row_stride();
      for (int k = 0; k < model.row_lengths()[e]; ++k) {
        const Vec3 particle = model.rest_positions().segment<3>(3 * model.neighbours()[base + k]);
        if (std::abs(particle.x() - 0.02) < 1e-12 && std::abs(particle.z()) < 1e-12) ++links;
      }
    }
    return links;
  };
  const CorotationalEfg strict(Vec3(0, -0.01, -0.01), Vec3(0.04, 0.01, 0.01), tissue, settings);
  EXPECT_EQ(count_front_links(strict, true), 0);  // beside the cut, on its -x side
  EXPECT_GT(count_front_links(strict, false), 0);  // below the front: the uncut ligament
  settings.front_hidden_beyond = std::numeric_limits<double>::infinity();
  const CorotationalEfg open_rim(Vec3(0, -0.01, -0.01), Vec3(0.04, 0.01, 0.01), tissue, settings);
  EXPECT_GT(count_front_links(open_rim, true), 0);
  EXPECT_EQ(count_front_links(open_rim, false), count_front_links(strict, false));
}

TEST(EfgModelTopology, SetNeighbourhoodKeepsConsistencyAndMass) {
  CorotationalEfg model = box_model(8);
  const double total = model.lumped_masses().sum();
  const int element = 17;
  const size_t base = static_cast<size_t>(element) * model.row_stride();
  std::vector<int> row(model.neighbours().begin() + base, model.neighbours().begin() + base + 8);
  // Add a ninth particle (the stride grows) and check consistency and mass.
  int extra = 0;
  while (std::find(row.begin(), row.end(), extra) != row.end()) ++extra;
  row.push_back(extra);
  model.set_neighbourhood(element, row);
  EXPECT_GE(model.row_stride(), 9);
  EXPECT_EQ(model.row_lengths()[element], 9);
  EXPECT_NEAR(model.lumped_masses().sum(), total, 1e-12 * total);
  const size_t new_base = static_cast<size_t>(element) * model.row_stride();
  double sum = 0;
  for (int k = 0; k < 9; ++k) sum += model.shape_values()[new_base + k];
  EXPECT_NEAR(sum, 1.0, 1e-12);
  // The rigid-motion check still holds with the edited row.
  const Vector x = transform(model.rest_positions(), rotation_about(Vec3(0, 0, 1), 50));
  EXPECT_LT(forces_at(model, x).cwiseAbs().maxCoeff(), 1e-12);
  // Four coplanar particles are refused and the model is unchanged.
  const Vector masses = model.lumped_masses();
  const std::vector<int> coplanar{0, 1, 5, 6};  // grid (0,0,0), (1,0,0), (0,1,0), (1,1,0)
  EXPECT_THROW(model.set_neighbourhood(element, coplanar), std::invalid_argument);
  EXPECT_EQ(model.row_lengths()[element], 9);
  EXPECT_TRUE(masses == model.lumped_masses());
}

// K0 element by element, as BlockMatrix's pattern and at() add it: the reference for the job,
// which assembles by block rows and reuses the rows no edited element touches.
BlockMatrix rest_stiffness_by_elements(const CorotationalEfg& model) {
  const auto row = [&](int e) {
    return std::span<const int>(model.neighbours().data() + static_cast<size_t>(e) * model.row_stride(),
                                static_cast<size_t>(model.row_lengths()[e]));
  };
  BlockMatrix stiffness(model.node_count(), [&](const std::function<void(std::span<const int>)>& visit) {
    for (int e = 0; e < model.element_count(); ++e)
      if (model.element_active(e)) visit(row(e));
  });
  const EfgRestShape& shape = *model.rest_shape();
  for (int e = 0; e < model.element_count(); ++e) {
    if (!model.element_active(e)) continue;
    const size_t base = static_cast<size_t>(e) * model.row_stride();
    for (int a = 0; a < model.row_lengths()[e]; ++a)
      for (int b = 0; b < model.row_lengths()[e]; ++b)
        stiffness.at(model.neighbours()[base + a], model.neighbours()[base + b]) +=
            model.element_volumes()[e] * isotropic_stiffness_block(model.shape_gradients()[base + a],
                                                                    model.shape_gradients()[base + b], shape.lambda, shape.mu);
  }
  return stiffness;
}

bool same_bits(const BlockMatrix& left, const BlockMatrix& right) {
  return left.nodes() == right.nodes() && left.row_start() == right.row_start() && left.columns() == right.columns() &&
         std::memcmp(left.blocks().data(), right.blocks().data(), sizeof(Mat3) * left.blocks().size()) == 0;
}

TEST(EfgModelTopology, RestStiffnessAfterEditsIsTheWholeAssemblysBits) {
  CorotationalEfg model = box_model(8);
  ASSERT_TRUE(same_bits(model.rest_stiffness_job()(), rest_stiffness_by_elements(model)));
  const int element = 17;
  const size_t base = static_cast<size_t>(element) * model.row_stride();
  std::vector<int> row(model.neighbours().begin() + base, model.neighbours().begin() + base + 8);
  // Swap one neighbour for another particle (the stride stays): only the rows of the old and
  // new particles' nodes change.
  int extra = 0;
  while (std::find(row.begin(), row.end(), extra) != row.end()) ++extra;
  const std::vector<int> before = row;
  row.back() = extra;
  const auto job = model.rest_stiffness_job();  // a job taken before the edit reads the rows as they were
  model.set_neighbourhood(element, row);
  const BlockMatrix swapped = model.rest_stiffness_job()();
  EXPECT_TRUE(same_bits(swapped, rest_stiffness_by_elements(model)));
  EXPECT_FALSE(same_bits(swapped, job()));
  // The stale job ran last: the next one still gets the edited rows right.
  EXPECT_TRUE(same_bits(model.rest_stiffness_job()(), rest_stiffness_by_elements(model)));
  // A copy shares the cache; a ninth neighbour grows the stride (every row recomputed).
  CorotationalEfg copy = model;
  row.push_back(before.back());
  copy.set_neighbourhood(element, row);
  EXPECT_TRUE(same_bits(copy.rest_stiffness_job()(), rest_stiffness_by_elements(copy)));
  EXPECT_TRUE(same_bits(model.rest_stiffness_job()(), rest_stiffness_by_elements(model)));
}

TEST(EfgModelEmbedding, VerticesFollowAffineMotionsExactly) {
  CorotationalEfg model = blob_model(8);
  // Points on and near the surface of the body.
  std::vector<Vec3> points;
  for (int i = 0; i < 200; ++i) {
    const double t = 0.1 * i, s = 0.37 * i;
    points.push_back(Vec3(0.033 * std::cos(t) * std::sin(s), 0.023 * std::sin(t) * std::sin(s),
                          0.019 * std::cos(s)));
  }
  Vector vertices(3 * points.size());
  for (size_t v = 0; v < points.size(); ++v) vertices.segment<3>(3 * v) = points[v];
  const SurfaceEmbedding embedding = model.embed_surface(vertices);
  ASSERT_EQ(embedding.vertex_count(), 200);
  for (int v = 0; v < embedding.vertex_count(); ++v) {
    // The chosen integration point is the nearest one.
    const double chosen = (model.element_centres()[embedding.elements[v]] - points[v]).norm();
    for (int e = 0; e < model.element_count(); ++e) {
      ASSERT_LE(chosen, (model.element_centres()[e] - points[v]).norm() + 1e-15) << "vertex " << v;
    }
  }
  Vector out;
  CorotationalEfg::surface_positions(embedding, model.rest_positions(), out);
  EXPECT_LT((out - vertices).cwiseAbs().maxCoeff(), 1e-14);
  Mat3 linear = rotation_about(Vec3(1, -1, 2), 60);
  linear(0, 1) += 0.1;
  CorotationalEfg::surface_positions(embedding, transform(model.rest_positions(), linear, Vec3(0.1, 0, 0)), out);
  EXPECT_LT((out - transform(vertices, linear, Vec3(0.1, 0, 0))).cwiseAbs().maxCoeff(), 1e-14);
}

TEST(EfgModelSettings, InvalidSettingsAreRefused) {
  EfgSettings settings;
  settings.neighbours = 6;
  EXPECT_THROW(CorotationalEfg(Vec3::Zero(), Vec3::Ones() * 0.01, tissue, settings), std::invalid_argument);
  settings.neighbours = 8;
  settings.support_factor = 1.0;
  EXPECT_THROW(CorotationalEfg(Vec3::Zero(), Vec3::Ones() * 0.01, tissue, settings), std::invalid_argument);
  settings.support_factor = 3.0;
  EXPECT_THROW(CorotationalEfg([](const Vec3&) { return false; }, Vec3::Zero(), Vec3::Ones() * 0.01, tissue, settings),
               std::invalid_argument);
}

// ---- Rotation of the corotation after a cut (issue 7, thesis §7.1.1) -------------------------
//
// A block 0.04 x 0.04 x 0.02 with a horizontal build-time cut at z = 0.0135 from x = 0.0115 to
// beyond the free face: a slice one integration element thick (one particle layer, z = 0.02)
// hinged to the block along x < 0.0115. Its elements' neighbourhoods are re-selected around the
// cut, far from the regular cells, which is where the shape-matching fit and the MLS
// deformation gradient differ.
CorotationalEfg sliced_block(EfgRotation rotation) {
  EfgSettings settings = settings_with(8);
  settings.rotation = rotation;
  settings.cuts.push_back({Vec3(0.0115, -1, 0.0185), Vec3(1, 0, 0), Vec3(0, 2, 0)});
  return CorotationalEfg(Vec3(0, 0, 0), Vec3(0.04, 0.04, 0.03), tissue, settings);
}

// The slice bent down about the hinge line x = 0.0115 (rotation growing with x - 0.0115) and
// the whole turned by 30 degrees: large rotations that vary over each neighbourhood.
Vector bent_slice(const Vector& rest) {
  Vector x = rest;
  for (Eigen::Index node = 0; node < rest.size() / 3; ++node) {
    const Vec3 p = rest.segment<3>(3 * node);
    const double beyond = std::max(0.0, p.x() - 0.0115);
    const double angle = p.z() > 0.0185 ? 18 * beyond : 2 * beyond;  // radians per metre
    const Vec3 pivot(0.0115, p.y(), 0.0185);
    x.segment<3>(3 * node) = pivot + rotation_about(Vec3(0, 1, 0), angle * 180 / std::numbers::pi) * (p - pivot);
  }
  return transform(x, rotation_about(Vec3(1, -2, 0.5), 30), Vec3(0.01, 0, 0));
}

// Net torque of the elastic forces over the scale sum |x_n| |f_n|: internal forces exert none
// (angular momentum balance). With R = polar(F) for the F the strain is taken from, R^T F is
// symmetric, so each element's F (R sigma)^T = R (R^T F) sigma R^T is symmetric: no torque.
// With R from another fit, R^T F is not symmetric and each element twists itself.
double relative_torque(CorotationalEfg& model, const Vector& x) {
  const Vector f = forces_at(model, x);
  Vec3 torque = Vec3::Zero();
  double scale = 0;
  for (int p = 0; p < model.node_count(); ++p) {
    torque += x.segment<3>(3 * p).cross(f.segment<3>(3 * p));
    scale += x.segment<3>(3 * p).norm() * f.segment<3>(3 * p).norm();
  }
  return torque.norm() / scale;
}

TEST(EfgRotation, DeformationGradientRotationGivesNoNetTorqueOnABentSlice) {
  CorotationalEfg gradient = sliced_block(EfgRotation::deformation_gradient);
  CorotationalEfg matching = sliced_block(EfgRotation::shape_matching);
  const Vector x = bent_slice(gradient.rest_positions());
  const double with_gradient = relative_torque(gradient, x);
  const double with_matching = relative_torque(matching, x);
  std::printf("bent slice: net elastic torque / sum |x||f| = %.2e (deformation gradient), %.2e "
              "(shape matching)\n", with_gradient, with_matching);
  EXPECT_LT(with_gradient, 1e-9);
  EXPECT_GT(with_matching, 1e3 * with_gradient);  // the defect the option removes
}

TEST(EfgRotation, DeformationGradientForcesAreTheGradientOfTheEnergy) {
  // f = -dW/dx: the force field is conservative, so it cannot feed energy into a slice at rest.
  // Central differences of elastic_energy along a fixed direction d against -f . d.
  for (EfgRotation rotation : {EfgRotation::deformation_gradient, EfgRotation::shape_matching}) {
    CorotationalEfg model = sliced_block(rotation);
    const Vector x = bent_slice(model.rest_positions());
    const Vector f = forces_at(model, x);
    Vector direction = deform(model.rest_positions()) - model.rest_positions();
    direction /= direction.norm();
    const double step = 1e-6;
    const double difference =
        (model.elastic_energy(x + step * direction) - model.elastic_energy(x - step * direction)) /
        (2 * step);
    const double work = -f.dot(direction);
    const double error = std::abs(difference - work) / std::abs(difference);
    std::printf("%s: dW/ds %.6e, -f.d %.6e, relative difference %.2e\n",
                rotation == EfgRotation::shape_matching ? "shape matching" : "deformation gradient",
                difference, work, error);
    // Measured: 6.7e-10 (the differences' rounding) and 1.6e-4.
    if (rotation == EfgRotation::deformation_gradient) {
      EXPECT_LT(error, 1e-7);
    } else {
      EXPECT_GT(error, 1e-5);
    }
  }
}

TEST(EfgRotation, RigidlyTurnedSliceHasNoElasticForce) {
  CorotationalEfg model = sliced_block(EfgRotation::deformation_gradient);
  const Vector& rest = model.rest_positions();
  const Vector x = transform(rest, rotation_about(Vec3(0.2, 1, -0.7), 120), Vec3(0.3, -0.1, 0.2));
  const Vector f = forces_at(model, x);
  // The scale: the forces of a 1 % stretch.
  const Vector stretched = transform(rest, Mat3(Vec3(1.01, 1, 1).asDiagonal()), Vec3::Zero());
  const double scale = forces_at(model, stretched).cwiseAbs().maxCoeff();
  EXPECT_LT(f.cwiseAbs().maxCoeff(), 1e-9 * scale);
  EXPECT_LT(model.elastic_energy(x), 1e-20);
}

}  // namespace
}  // namespace incise::physics
