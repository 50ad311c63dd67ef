#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>
#include <stdexcept>
#include <string>

#include "physics/fem/corotational_fem.hpp"
#include "physics/fem/static_solve.hpp"
#include "physics/fem/tet_mesh.hpp"

namespace incise::physics {
namespace {

const Material tissue{30e3, 0.45, 1050};

TetMesh one_irregular_tet() {
  TetMesh mesh;
  mesh.rest.resize(12);
  mesh.rest << 0.01, 0.02, -0.01, 0.11, 0.0, 0.01, 0.03, 0.09, 0.0, 0.02, 0.03, 0.12;
  mesh.tets = {{0, 1, 2, 3}};
  return mesh;
}

TetMesh box_mesh() {
  return make_box_tets(Vec3(-0.05, 0, 0.01), Vec3(0.05, 0.04, 0.07), {3, 2, 2});
}

// Smooth deterministic non-affine deformation, a few percent of the size.
Vector deform(const Vector& rest) {
  Vector x = rest;
  for (Eigen::Index node = 0; node < rest.size() / 3; ++node) {
    const Vec3 p = rest.segment<3>(3 * node);
    x.segment<3>(3 * node) +=
        0.004 * Vec3(std::sin(50 * p.y() + 1), std::cos(40 * p.z()) + p.x() * 30,
                     std::sin(30 * p.x() - 20 * p.y()));
  }
  return x;
}

Vector rotate(const Vector& x, const Mat3& rotation, const Vec3& translation = Vec3::Zero()) {
  Vector result(x.size());
  for (Eigen::Index node = 0; node < x.size() / 3; ++node) {
    result.segment<3>(3 * node) = rotation * x.segment<3>(3 * node) + translation;
  }
  return result;
}

Vector forces_at(CorotationalTetFem& model, const Vector& x) {
  model.update_rotations(x);
  Vector f = Vector::Zero(x.size());
  model.add_elastic_forces(x, f);
  return f;
}

Vector stiffness_times(const CorotationalTetFem& model, const Vector& p) {
  Vector out = Vector::Zero(p.size());
  model.add_stiffness_product(p, out);
  return out;
}

Vector pattern(Eigen::Index size, double phase) {
  Vector p(size);
  for (Eigen::Index i = 0; i < size; ++i)
    p[i] = std::sin(1.7 * i + phase) + 0.3 * std::cos(0.3 * i * i);
  return p;
}

const Mat3 some_rotation =
    Eigen::AngleAxisd(2.1, Vec3(0.3, -0.8, 0.52).normalized()).toRotationMatrix();

class CorotationalMeshes : public ::testing::TestWithParam<int> {
 protected:
  TetMesh mesh() const { return GetParam() == 0 ? one_irregular_tet() : box_mesh(); }
};

TEST_P(CorotationalMeshes, RotatingDeformedShapeRotatesForcesAndKeepsEnergy) {
  CorotationalTetFem model(mesh(), tissue);
  const Vector x = deform(model.rest_positions());
  const Vector f = forces_at(model, x);
  const double energy = model.elastic_energy(x);
  ASSERT_GT(f.norm(), 0);
  ASSERT_GT(energy, 0);

  const Vector rotated_x = rotate(x, some_rotation, Vec3(0.3, -1.0, 2.0));
  const Vector rotated_f = forces_at(model, rotated_x);
  EXPECT_LE((rotated_f - rotate(f, some_rotation)).norm(), 1e-9 * f.norm());
  EXPECT_NEAR(model.elastic_energy(rotated_x), energy, 1e-9 * energy);
}

TEST_P(CorotationalMeshes, RigidMotionOfRestShapeGivesNoForce) {
  CorotationalTetFem model(mesh(), tissue);
  const Vector rest = model.rest_positions();
  const Vector reference = forces_at(model, deform(rest));  // the scale to judge round-off by
  const Vector x = rotate(rest, some_rotation, Vec3(1.0, 2.0, -3.0));
  const Vector f = forces_at(model, x);
  EXPECT_LE(f.norm(), 1e-9 * reference.norm());
  EXPECT_LE(model.elastic_energy(x), 1e-9 * model.elastic_energy(deform(rest)));
  for (const Mat3& rotation : model.rotations()) {
    EXPECT_LE((rotation - some_rotation).norm(), 1e-12);
  }
}

TEST_P(CorotationalMeshes, StiffnessMatchesFiniteDifferenceAtRest) {
  CorotationalTetFem model(mesh(), tissue);
  const Vector rest = model.rest_positions();
  const Vector direction = pattern(rest.size(), 0.4);
  const double step = 1e-7;
  // At rest R^T x - X = 0, so freezing R loses nothing: K = -df/dx exactly.
  const Vector difference =
      -(forces_at(model, rest + step * direction) - forces_at(model, rest - step * direction)) /
      (2 * step);
  model.update_rotations(rest);
  const Vector product = stiffness_times(model, direction);
  EXPECT_LE((product - difference).norm(), 1e-6 * product.norm());
}

TEST_P(CorotationalMeshes, StiffnessIsSymmetricPositiveAndDiagonalMatches) {
  CorotationalTetFem model(mesh(), tissue);
  model.update_rotations(rotate(deform(model.rest_positions()), some_rotation));
  const Eigen::Index size = model.rest_positions().size();
  const Vector p = pattern(size, 0.1), q = pattern(size, 2.3);
  const Vector stiffness_p = stiffness_times(model, p), stiffness_q = stiffness_times(model, q);
  EXPECT_NEAR(p.dot(stiffness_q), q.dot(stiffness_p), 1e-12 * stiffness_p.norm() * q.norm());
  EXPECT_GT(p.dot(stiffness_p), 0);

  Vector diagonal = Vector::Zero(size);
  model.add_stiffness_diagonal(diagonal);
  for (Eigen::Index i = 0; i < size; ++i) {
    const Vector column = stiffness_times(model, Vector::Unit(size, i));
    EXPECT_NEAR(diagonal[i], column[i], 1e-12 * column.norm()) << "component " << i;
  }
}

TEST_P(CorotationalMeshes, RestStiffnessEqualsAssembledLinearStiffness) {
  const TetMesh tets = mesh();
  CorotationalTetFem model(tets, tissue);
  model.update_rotations(model.rest_positions());
  const SparseMatrix assembled = assemble_stiffness(tets, tissue);
  const Vector p = pattern(model.rest_positions().size(), 1.1);
  const Vector expected = assembled * p;
  EXPECT_LE((stiffness_times(model, p) - expected).norm(), 1e-12 * expected.norm());
}

INSTANTIATE_TEST_SUITE_P(OneTetAndBox, CorotationalMeshes, ::testing::Values(0, 1),
                         [](const auto& info) { return info.param == 0 ? "OneTet" : "Box"; });

TEST(CorotationalTetFem, LumpedMassesSumToTotalMass) {
  const TetMesh mesh = box_mesh();
  CorotationalTetFem model(mesh, tissue);
  const double volume = 0.1 * 0.04 * 0.06;
  EXPECT_NEAR(model.lumped_masses().sum(), tissue.density * volume,
              1e-12 * tissue.density * volume);
  EXPECT_GT(model.lumped_masses().minCoeff(), 0);
}

TEST(CorotationalTetFem, InvertedElementGetsProperRotationAndRestoringForce) {
  CorotationalTetFem model(one_irregular_tet(), tissue);
  Vector x = model.rest_positions();
  // Push corner 3 through the opposite face to 20 % of its height on the other side:
  // F = I - 1.2 n n^T has singular values (1, 1, 0.2) and det < 0; flipping the smallest
  // singular direction gives R = I, so the element is pushed back rather than reflected.
  const Vec3 x0 = x.segment<3>(0), x1 = x.segment<3>(3), x2 = x.segment<3>(6);
  const Vec3 normal = (x1 - x0).cross(x2 - x0).normalized();
  Vec3 x3 = x.segment<3>(9);
  x3 -= 1.2 * normal.dot(x3 - x0) * normal;
  x.segment<3>(9) = x3;
  const Vector f = forces_at(model, x);
  const Mat3& rotation = model.rotations()[0];
  EXPECT_NEAR(rotation.determinant(), 1.0, 1e-12);
  EXPECT_LE((rotation - Mat3::Identity()).norm(), 1e-12);
  ASSERT_TRUE(f.allFinite());
  // Corner 3 is pulled back towards the side it came from.
  EXPECT_GT(f.segment<3>(9).dot(normal), 0);
}

TEST(CorotationalTetFem, PolarRotationOfRotatedStretch) {
  const Mat3 stretch = (Mat3() << 1.2, 0.1, 0.0, 0.1, 0.9, 0.05, 0.0, 0.05, 1.1).finished();
  EXPECT_LE((CorotationalTetFem::polar_rotation(some_rotation * stretch) - some_rotation).norm(),
            1e-12);
}

TEST(CorotationalTetFem, RejectsDegenerateAndInvertedElementsByIndex) {
  TetMesh mesh = make_box_tets(Vec3::Zero(), Vec3::Ones(), {1, 1, 1});
  TetMesh inverted = mesh;
  std::swap(inverted.tets[4][1], inverted.tets[4][2]);
  try {
    CorotationalTetFem model(inverted, tissue);
    FAIL() << "an inverted element was accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("element 4"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("inverted"), std::string::npos) << error.what();
  }
  TetMesh flat = mesh;
  flat.tets[2] = {flat.tets[2][0], flat.tets[2][1], flat.tets[2][2], flat.tets[2][1]};
  try {
    CorotationalTetFem model(flat, tissue);
    FAIL() << "a degenerate element was accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("element 2"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("degenerate"), std::string::npos) << error.what();
  }
  EXPECT_THROW(CorotationalTetFem(mesh, Material{1e3, 0.5, 1000}), std::invalid_argument);
  TetMesh orphan = mesh;
  orphan.rest.conservativeResize(orphan.rest.size() + 3);
  orphan.rest.tail<3>() = Vec3(5, 5, 5);
  EXPECT_THROW(CorotationalTetFem(orphan, tissue), std::invalid_argument);
}

}  // namespace
}  // namespace incise::physics
