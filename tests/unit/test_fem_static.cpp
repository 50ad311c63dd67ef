#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <stdexcept>

#include "physics/fem/static_solve.hpp"
#include "physics/fem/tet_mesh.hpp"

namespace incise::physics {
namespace {

const Material material{2.5e5, 0.35, 1000};
const Vec3 box_min(-0.1, 0.2, 0.05), box_max(0.3, 0.5, 0.35);

std::vector<uint8_t> surface_nodes(const Vector& rest) {
  std::vector<uint8_t> mask(rest.size() / 3, 0);
  for (size_t node = 0; node < mask.size(); ++node) {
    const Vec3 x = rest.segment<3>(3 * static_cast<Eigen::Index>(node));
    for (int axis = 0; axis < 3; ++axis) {
      if (std::abs(x[axis] - box_min[axis]) < 1e-12 || std::abs(x[axis] - box_max[axis]) < 1e-12)
        mask[node] = 1;
    }
  }
  return mask;
}

// u = A X + c, a uniform strain (and a rotation part: A is not symmetric).
Vec3 affine_field(const Vec3& x) {
  const Mat3 a = (Mat3() << 1e-3, 4e-4, -2e-4, -3e-4, -7e-4, 5e-4, 6e-4, 1e-4, 8e-4).finished();
  return a * x + Vec3(1e-3, -2e-3, 5e-4);
}

// u_i = sum_jk Q_ijk X_j X_k + A X + c (Q symmetric in j, k): sigma is linear in X, so
// -div sigma is a constant body force b_i = -[(lambda + mu) d_i (div u) + mu Laplacian u_i]
//   = -[(lambda + mu) 2 sum_j Q_jji + mu 2 sum_j Q_ijj].
struct QuadraticField {
  std::array<Mat3, 3> q;  // q[i](j, k)

  QuadraticField() {
    q[0] << 2e-3, 1e-3, -5e-4, 1e-3, -1e-3, 3e-4, -5e-4, 3e-4, 1.5e-3;
    q[1] << -7e-4, 4e-4, 2e-4, 4e-4, 1.2e-3, -9e-4, 2e-4, -9e-4, 6e-4;
    q[2] << 5e-4, -3e-4, 8e-4, -3e-4, -4e-4, 2e-4, 8e-4, 2e-4, -1.1e-3;
  }

  Vec3 operator()(const Vec3& x) const {
    return Vec3(x.dot(q[0] * x), x.dot(q[1] * x), x.dot(q[2] * x)) + affine_field(x);
  }

  Vec3 body_force(const Material& m) const {
    const double lambda = lame_lambda(m), mu = lame_mu(m);
    Vec3 b;
    for (int i = 0; i < 3; ++i) {
      double gradient_of_divergence = 0, laplacian = 0;
      for (int j = 0; j < 3; ++j) {
        gradient_of_divergence += 2 * q[j](j, i);
        laplacian += 2 * q[i](j, j);
      }
      b[i] = -((lambda + mu) * gradient_of_divergence + mu * laplacian);
    }
    return b;
  }
};

// Moves the interior grid corners by up to 10 % of the cell size (boundary nodes stay on the
// box faces), so the patch tests do not profit from the symmetry of a uniform grid, on which
// even linear tets reproduce a quadratic field at the nodes.
void distort_interior(Vector& rest, const std::vector<uint8_t>& boundary, const Vec3& cell_size) {
  for (size_t node = 0; node < boundary.size(); ++node) {
    if (boundary[node]) continue;
    const Eigen::Index offset = 3 * static_cast<Eigen::Index>(node);
    const Vec3 x = rest.segment<3>(offset);
    const Vec3 wobble(std::sin(91 * x.x() + 37 * x.y() + 13 * x.z()),
                      std::sin(17 * x.x() - 71 * x.y() + 29 * x.z() + 1),
                      std::sin(53 * x.x() + 11 * x.y() - 43 * x.z() + 2));
    rest.segment<3>(offset) += 0.1 * wobble.cwiseProduct(cell_size);
  }
}

TetMesh distorted_linear_mesh() {
  TetMesh mesh = make_box_tets(box_min, box_max, {3, 3, 3});
  distort_interior(mesh.rest, surface_nodes(mesh.rest), (box_max - box_min) / 3);
  return mesh;
}

// Corners move as in distort_interior; midpoints follow so the edges stay straight.
QuadraticTetMesh distorted_quadratic_mesh() {
  QuadraticTetMesh mesh = make_box_quadratic_tets(box_min, box_max, {3, 3, 3});
  const std::vector<uint8_t> boundary = surface_nodes(mesh.rest);
  std::vector<uint8_t> keep = boundary;  // only interior corners move
  for (const auto& tet : mesh.tets) {
    for (int e = 0; e < 6; ++e) keep[tet[4 + e]] = 1;
  }
  distort_interior(mesh.rest, keep, (box_max - box_min) / 3);
  for (const auto& tet : mesh.tets) {
    for (int e = 0; e < 6; ++e) {
      mesh.rest.segment<3>(3 * tet[4 + e]) =
          0.5 * (mesh.rest.segment<3>(3 * tet[quadratic_tet_edges[e][0]]) +
                 mesh.rest.segment<3>(3 * tet[quadratic_tet_edges[e][1]]));
    }
  }
  return mesh;
}

template <class Field>
Vector sample(const Vector& rest, const Field& field) {
  Vector u(rest.size());
  for (Eigen::Index node = 0; node < rest.size() / 3; ++node)
    u.segment<3>(3 * node) = field(Vec3(rest.segment<3>(3 * node)));
  return u;
}

TEST(StaticPatch, LinearTetsReproduceAffineField) {
  const TetMesh mesh = distorted_linear_mesh();
  const std::vector<uint8_t> boundary = surface_nodes(mesh.rest);
  const Vector exact = sample(mesh.rest, affine_field);
  const Vector u = solve_static_linear(mesh, material, boundary, exact, Vec3::Zero(), Vector());
  int interior = 0;
  for (size_t node = 0; node < boundary.size(); ++node) {
    if (boundary[node]) continue;
    ++interior;
    const Eigen::Index offset = 3 * static_cast<Eigen::Index>(node);
    EXPECT_LE((u.segment<3>(offset) - exact.segment<3>(offset)).norm(),
              1e-10 * exact.cwiseAbs().maxCoeff())
        << "node " << node;
  }
  EXPECT_EQ(interior, 8);
}

TEST(StaticPatch, QuadraticTetsReproduceQuadraticFieldUnderItsBodyForce) {
  const QuadraticTetMesh mesh = distorted_quadratic_mesh();
  const QuadraticField field;
  const std::vector<uint8_t> boundary = surface_nodes(mesh.rest);
  const Vector exact = sample(mesh.rest, field);
  const Vec3 body_force = field.body_force(material);
  ASSERT_GT(body_force.norm(), 100.0);  // the load is not negligible
  const Vector u = solve_static_quadratic(mesh, material, boundary, exact, body_force, Vector());
  int interior = 0;
  for (size_t node = 0; node < boundary.size(); ++node) {
    if (boundary[node]) continue;
    ++interior;
    const Eigen::Index offset = 3 * static_cast<Eigen::Index>(node);
    EXPECT_LE((u.segment<3>(offset) - exact.segment<3>(offset)).norm(),
              1e-9 * exact.cwiseAbs().maxCoeff())
        << "node " << node;
  }
  EXPECT_EQ(interior, 5 * 5 * 5);  // corners and midpoints inside the 7x7x7 node grid

  // Without the body force the same boundary data gives a different interior: the load matters.
  const Vector unloaded =
      solve_static_quadratic(mesh, material, boundary, exact, Vec3::Zero(), Vector());
  EXPECT_GT((unloaded - exact).cwiseAbs().maxCoeff(), 1e-3 * exact.cwiseAbs().maxCoeff());
}

TEST(StaticPatch, LinearTetsFailTheQuadraticPatch) {
  // A check of the test itself: on the distorted mesh linear tets cannot represent the
  // quadratic field.
  const TetMesh mesh = distorted_linear_mesh();
  const QuadraticField field;
  const Vector exact = sample(mesh.rest, field);
  const Vector u = solve_static_linear(mesh, material, surface_nodes(mesh.rest), exact,
                                       field.body_force(material), Vector());
  EXPECT_GT((u - exact).cwiseAbs().maxCoeff(), 1e-6 * exact.cwiseAbs().maxCoeff());
}

template <class Mesh>
void expect_rigid_kernel(const Mesh& mesh) {
  const SparseMatrix k = assemble_stiffness(mesh, material);
  const SparseMatrix transposed = k.transpose();
  EXPECT_LE((k - transposed).norm(), 1e-12 * k.norm());
  const Eigen::Index nodes = mesh.rest.size() / 3;
  for (int mode = 0; mode < 6; ++mode) {
    Vector u(mesh.rest.size());
    for (Eigen::Index node = 0; node < nodes; ++node) {
      const Vec3 x = mesh.rest.template segment<3>(3 * node);
      u.segment<3>(3 * node) =
          mode < 3 ? Vec3(Vec3::Unit(mode)) : Vec3(Vec3::Unit(mode - 3).cross(x));
    }
    EXPECT_LE((k * u).norm(), 1e-10 * k.norm() * u.norm()) << "rigid mode " << mode;
  }
}

TEST(StaticAssembly, StiffnessIsSymmetricWithRigidModesInKernel) {
  expect_rigid_kernel(distorted_linear_mesh());
  expect_rigid_kernel(distorted_quadratic_mesh());
}

TEST(StaticAssembly, QuadraticBodyLoadIsConsistent) {
  const QuadraticTetMesh mesh = make_box_quadratic_tets(Vec3::Zero(), Vec3::Ones(), {1, 1, 1});
  const Vec3 b(1.0, -2.0, 3.0);
  const Vector load = assemble_body_load(mesh, b);
  Vec3 total = Vec3::Zero();
  for (Eigen::Index node = 0; node < load.size() / 3; ++node) total += load.segment<3>(3 * node);
  EXPECT_LE((total - b).norm(), 1e-14);  // unit volume
  // One cell, 6 tets of volume 1/6: a corner used only by tets of one kind gets -V/20 per tet.
  // Node (0,0,0) belongs to all 6 tets as a corner: -6 (1/6) / 20.
  EXPECT_NEAR(load[2] / b.z(), -1.0 / 20.0, 1e-15);
  // The cell centre (1,1,1) on the fine grid is the midpoint of the main diagonal, shared by all
  // 6 tets: 6 (1/6) / 5.
  const Eigen::Index centre = 1 + 3 * (1 + 3 * 1);
  EXPECT_NEAR(load[3 * centre + 2] / b.z(), 1.0 / 5.0, 1e-15);
}

TEST(StaticSolve, UnconstrainedBodyThrows) {
  const TetMesh mesh = make_box_tets(Vec3::Zero(), Vec3::Ones(), {2, 2, 2});
  EXPECT_THROW(solve_static_linear(mesh, material, {}, Vec3(0, 0, -1)), std::runtime_error);
  // Fixing a single node leaves the rotations free.
  std::vector<uint8_t> one(mesh.rest.size() / 3, 0);
  one[0] = 1;
  EXPECT_THROW(solve_static_linear(mesh, material, one, Vec3(0, 0, -1)), std::runtime_error);
}

TEST(StaticSolve, CurvedQuadraticEdgeIsRejected) {
  QuadraticTetMesh mesh = make_box_quadratic_tets(Vec3::Zero(), Vec3::Ones(), {1, 1, 1});
  const auto& tet = mesh.tets[0];
  const Vec3 a = mesh.rest.segment<3>(3 * tet[quadratic_tet_edges[0][0]]);
  const Vec3 b = mesh.rest.segment<3>(3 * tet[quadratic_tet_edges[0][1]]);
  // Off the line of its edge: a curved edge.
  QuadraticTetMesh curved = mesh;
  curved.rest.segment<3>(3 * tet[4]) += 0.1 * (b - a).unitOrthogonal();
  EXPECT_THROW(assemble_stiffness(curved, material), std::invalid_argument);
  EXPECT_THROW(assemble_body_load(curved, Vec3(0, 0, -1)), std::invalid_argument);
  // On the line but outside its middle half: the map would fold.
  QuadraticTetMesh folded = mesh;
  folded.rest.segment<3>(3 * tet[4]) = a + 0.2 * (b - a);
  EXPECT_THROW(assemble_stiffness(folded, material), std::invalid_argument);
}

// Moves every interior midside node along its (straight) edge to 0.3 or 0.7 of it: the
// elements become isoparametric, as quarter-point crack-front elements are.
QuadraticTetMesh shifted_midside_mesh() {
  QuadraticTetMesh mesh = distorted_quadratic_mesh();
  const std::vector<uint8_t> boundary = surface_nodes(mesh.rest);
  std::vector<uint8_t> done(boundary.size(), 0);
  int shifted = 0;
  for (const auto& tet : mesh.tets) {
    for (int e = 0; e < 6; ++e) {
      const int node = tet[4 + e];
      if (boundary[node] || done[node]) continue;
      done[node] = 1;
      const Vec3 a = mesh.rest.segment<3>(3 * tet[quadratic_tet_edges[e][0]]);
      const Vec3 b = mesh.rest.segment<3>(3 * tet[quadratic_tet_edges[e][1]]);
      mesh.rest.segment<3>(3 * node) = a + (shifted++ % 2 ? 0.3 : 0.7) * (b - a);
    }
  }
  return mesh;
}

TEST(StaticPatch, IsoparametricQuadraticTetsReproduceAffineField) {
  // An isoparametric element reproduces every affine field whatever its midside nodes (its
  // shape functions still sum to 1 and interpolate x): the patch test with shifted nodes.
  const QuadraticTetMesh mesh = shifted_midside_mesh();
  const std::vector<uint8_t> boundary = surface_nodes(mesh.rest);
  const Vector exact = sample(mesh.rest, affine_field);
  const Vector u = solve_static_quadratic(mesh, material, boundary, exact, Vec3::Zero(), Vector());
  double worst = 0;
  for (size_t node = 0; node < boundary.size(); ++node) {
    if (boundary[node]) continue;
    const Eigen::Index offset = 3 * static_cast<Eigen::Index>(node);
    worst = std::max(worst, (u.segment<3>(offset) - exact.segment<3>(offset)).norm());
  }
  EXPECT_LE(worst, 1e-9 * exact.cwiseAbs().maxCoeff());
  // The shift matters: with the nodes moved the quadratic patch is no longer passed.
  const QuadraticField field;
  const Vector quadratic = sample(mesh.rest, field);
  const Vector v = solve_static_quadratic(mesh, material, boundary, quadratic, field.body_force(material), Vector());
  EXPECT_GT((v - quadratic).cwiseAbs().maxCoeff(), 1e-6 * quadratic.cwiseAbs().maxCoeff());
  expect_rigid_kernel(mesh);
  // The body load still integrates to the volume (the edges are straight: the same volume).
  const Vec3 g(1.0, -2.0, 3.0);
  const Vector load = assemble_body_load(mesh, g);
  Vec3 total = Vec3::Zero();
  for (Eigen::Index node = 0; node < load.size() / 3; ++node) total += load.segment<3>(3 * node);
  EXPECT_LE((total - (box_max - box_min).prod() * g).norm(), 1e-12 * g.norm());
}

}  // namespace
}  // namespace incise::physics
