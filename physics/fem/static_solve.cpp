#include "physics/fem/static_solve.hpp"

#include "physics/solve/rest_factor.hpp"
#include "physics/solve/supernodal_factor.hpp"

#include <Eigen/SparseCholesky>
#include <cmath>
#include <vector>
#include <stdexcept>
#include <string>

#include "physics/fem/tet_element.hpp"

namespace incise::physics {

namespace {

using Index = Eigen::Index;
using Triplet = Eigen::Triplet<double>;

// 4-point Gauss rule on the tetrahedron, degree 2 exact: barycentric (a, b, b, b) and its
// permutations, a = (5 + 3 sqrt 5) / 20, b = (5 - sqrt 5) / 20, weights V / 4.
constexpr double gauss_a = 0.58541019662496845446;
constexpr double gauss_b = 0.13819660112501051518;
constexpr int gauss_points = 4;

Eigen::Vector4d gauss_barycentric(int point) {
  Eigen::Vector4d coordinates = Eigen::Vector4d::Constant(gauss_b);
  coordinates[point] = gauss_a;
  return coordinates;
}

void check_nodes(const Vector& rest, const int* nodes, int count, size_t element) {
  const Index node_count = rest.size() / 3;
  for (int c = 0; c < count; ++c) {
    if (nodes[c] < 0 || nodes[c] >= node_count) {
      throw std::invalid_argument("tet element " + std::to_string(element) + " refers to node " +
                                  std::to_string(nodes[c]) + " outside [0, " +
                                  std::to_string(node_count) + ")");
    }
  }
}

TetRestGeometry corner_geometry(const Vector& rest, const int* nodes, size_t element) {
  return tet_rest_geometry(rest.segment<3>(3 * nodes[0]), rest.segment<3>(3 * nodes[1]),
                           rest.segment<3>(3 * nodes[2]), rest.segment<3>(3 * nodes[3]),
                           static_cast<long long>(element));
}

// grad L_0..3 of the barycentric coordinates: rows of Dm^-1 for 1..3, L_0 = 1 - L_1 - L_2 - L_3.
std::array<Vec3, 4> barycentric_gradients(const Mat3& inverse_shape) {
  std::array<Vec3, 4> gradients;
  for (int a = 0; a < 3; ++a) gradients[a + 1] = inverse_shape.row(a).transpose();
  gradients[0] = -(gradients[1] + gradients[2] + gradients[3]);
  return gradients;
}

// Shape functions of the 10-node tet in barycentric coordinates L:
// corner i: N = L_i (2 L_i - 1); edge (i, j): N = 4 L_i L_j.
std::array<double, 10> quadratic_shape_values(const Eigen::Vector4d& l) {
  std::array<double, 10> values;
  for (int i = 0; i < 4; ++i) values[i] = l[i] * (2 * l[i] - 1);
  for (int e = 0; e < 6; ++e) {
    values[4 + e] = 4 * l[quadratic_tet_edges[e][0]] * l[quadratic_tet_edges[e][1]];
  }
  return values;
}

// grad N by the chain rule through L: corner i: (4 L_i - 1) grad L_i;
// edge (i, j): 4 (L_i grad L_j + L_j grad L_i).
std::array<Vec3, 10> quadratic_shape_gradients(const Eigen::Vector4d& l,
                                               const std::array<Vec3, 4>& barycentric) {
  std::array<Vec3, 10> gradients;
  for (int i = 0; i < 4; ++i) gradients[i] = (4 * l[i] - 1) * barycentric[i];
  for (int e = 0; e < 6; ++e) {
    const int i = quadratic_tet_edges[e][0], j = quadratic_tet_edges[e][1];
    gradients[4 + e] = 4 * (l[i] * barycentric[j] + l[j] * barycentric[i]);
  }
  return gradients;
}

// Edges must be straight; a midside node may sit anywhere in the middle half of its edge
// (the quarter-point position puts the 1 / sqrt r strain of a crack front into the element,
// Barsoum 1976). Returns whether every midside node is at its midpoint (the element is then
// affine and the exact 4-point rule applies); otherwise the element is isoparametric.
bool check_straight_edges(const Vector& rest, const std::array<int, 10>& tet, size_t element) {
  bool affine = true;
  for (int e = 0; e < 6; ++e) {
    const Vec3 a = rest.segment<3>(3 * tet[quadratic_tet_edges[e][0]]);
    const Vec3 b = rest.segment<3>(3 * tet[quadratic_tet_edges[e][1]]);
    const Vec3 node = rest.segment<3>(3 * tet[4 + e]);
    const Vec3 edge = b - a;
    const double t = (node - a).dot(edge) / edge.squaredNorm();
    if ((node - (a + t * edge)).norm() > 1e-9 * edge.norm()) {
      throw std::invalid_argument("quadratic tet element " + std::to_string(element) + ": node " +
                                  std::to_string(tet[4 + e]) +
                                  " is off the straight line of its edge (curved edges are not "
                                  "supported)");
    }
    if (t < 0.25 - 1e-9 || t > 0.75 + 1e-9) {
      throw std::invalid_argument("quadratic tet element " + std::to_string(element) + ": node " +
                                  std::to_string(tet[4 + e]) + " is at " + std::to_string(t) +
                                  " along its edge, outside the middle half [0.25, 0.75]");
    }
    affine = affine && std::abs(t - 0.5) <= 1e-9;
  }
  return affine;
}

// The isoparametric 10-node tet: reference coordinates r = (L_1, L_2, L_3), L_0 = 1 - sum.
// dN/dr through L as in quadratic_shape_gradients, with grad L_0 = -(1, 1, 1).
std::array<Vec3, 10> quadratic_reference_gradients(const Eigen::Vector4d& l) {
  const std::array<Vec3, 4> reference{Vec3(-1, -1, -1), Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  return quadratic_shape_gradients(l, reference);
}

// A conical (collapsed Gauss-Legendre, 4 x 4 x 4) rule on the reference tet: r_1 = u,
// r_2 = (1 - u) v, r_3 = (1 - u)(1 - v) w, dr = (1 - u)^2 (1 - v) du dv dw. Exact for
// polynomials of degree 7; the quarter-point element's rational integrand needs more than the
// 4-point rule.
struct ReferencePoint {
  Eigen::Vector4d l;
  double weight;  // sums to 1/6, the reference volume
};
std::vector<ReferencePoint> conical_rule() {
  const double x[4] = {0.8611363115940526, 0.3399810435848563, -0.3399810435848563, -0.8611363115940526};
  const double w[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461, 0.3478548451374538};
  std::vector<ReferencePoint> points;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      for (int k = 0; k < 4; ++k) {
        const double u = 0.5 * (1 + x[i]), v = 0.5 * (1 + x[j]), t = 0.5 * (1 + x[k]);
        const double r1 = u, r2 = (1 - u) * v, r3 = (1 - u) * (1 - v) * t;
        points.push_back({Eigen::Vector4d(1 - r1 - r2 - r3, r1, r2, r3),
                          0.125 * w[i] * w[j] * w[k] * (1 - u) * (1 - u) * (1 - v)});
      }
  return points;
}

// At a reference point: the shape gradients in x and dV / dr (det J), J = sum_a x_a (x) dN_a/dr.
double isoparametric_gradients(const Vector& rest, const std::array<int, 10>& tet, const Eigen::Vector4d& l,
                               std::array<Vec3, 10>& gradients, size_t element) {
  const std::array<Vec3, 10> reference = quadratic_reference_gradients(l);
  Mat3 jacobian = Mat3::Zero();
  for (int a = 0; a < 10; ++a) jacobian += rest.segment<3>(3 * tet[a]) * reference[a].transpose();
  const double determinant = jacobian.determinant();
  if (!(determinant > 0)) {
    throw std::invalid_argument("quadratic tet element " + std::to_string(element) +
                                ": the isoparametric map folds (det J = " + std::to_string(determinant) + ")");
  }
  const Mat3 inverse_transpose = jacobian.inverse().transpose();
  for (int a = 0; a < 10; ++a) gradients[a] = inverse_transpose * reference[a];
  return determinant;
}

template <int Nodes>
void push_element(const std::array<int, Nodes>& nodes,
                  const Eigen::Matrix<double, 3 * Nodes, 3 * Nodes>& element_stiffness,
                  std::vector<Triplet>& triplets) {
  for (int a = 0; a < Nodes; ++a) {
    for (int b = 0; b < Nodes; ++b) {
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
          triplets.emplace_back(3 * nodes[a] + i, 3 * nodes[b] + j,
                                element_stiffness(3 * a + i, 3 * b + j));
        }
      }
    }
  }
}

}  // namespace

SparseMatrix assemble_stiffness(const TetMesh& mesh, const Material& material) {
  validate_material(material);
  const double lambda = lame_lambda(material), mu = lame_mu(material);
  std::vector<Triplet> triplets;
  triplets.reserve(144 * mesh.tets.size());
  Eigen::Matrix<double, 12, 12> element_stiffness;
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    const auto& tet = mesh.tets[e];
    check_nodes(mesh.rest, tet.data(), 4, e);
    const TetRestGeometry geometry = corner_geometry(mesh.rest, tet.data(), e);
    const auto gradients = barycentric_gradients(geometry.inverse_shape);
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) {
        element_stiffness.block<3, 3>(3 * a, 3 * b) =
            geometry.volume * isotropic_stiffness_block(gradients[a], gradients[b], lambda, mu);
      }
    }
    push_element<4>(tet, element_stiffness, triplets);
  }
  const Index size = mesh.rest.size();
  SparseMatrix stiffness(size, size);
  stiffness.setFromTriplets(triplets.begin(), triplets.end());
  return stiffness;
}

SparseMatrix assemble_stiffness(const QuadraticTetMesh& mesh, const Material& material) {
  validate_material(material);
  const double lambda = lame_lambda(material), mu = lame_mu(material);
  std::vector<Triplet> triplets;
  triplets.reserve(900 * mesh.tets.size());
  Eigen::Matrix<double, 30, 30> element_stiffness;
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    const auto& tet = mesh.tets[e];
    check_nodes(mesh.rest, tet.data(), 10, e);
    const TetRestGeometry geometry = corner_geometry(mesh.rest, tet.data(), e);
    element_stiffness.setZero();
    if (!check_straight_edges(mesh.rest, tet, e)) {
      static const std::vector<ReferencePoint> rule = conical_rule();
      std::array<Vec3, 10> gradients;
      for (const ReferencePoint& point : rule) {
        const double weight = point.weight * isoparametric_gradients(mesh.rest, tet, point.l, gradients, e);
        for (int a = 0; a < 10; ++a)
          for (int b = 0; b < 10; ++b)
            element_stiffness.block<3, 3>(3 * a, 3 * b) +=
                weight * isotropic_stiffness_block(gradients[a], gradients[b], lambda, mu);
      }
      push_element<10>(tet, element_stiffness, triplets);
      continue;
    }
    const auto barycentric = barycentric_gradients(geometry.inverse_shape);
    for (int q = 0; q < gauss_points; ++q) {
      const auto gradients = quadratic_shape_gradients(gauss_barycentric(q), barycentric);
      const double weight = geometry.volume / gauss_points;
      for (int a = 0; a < 10; ++a) {
        for (int b = 0; b < 10; ++b) {
          element_stiffness.block<3, 3>(3 * a, 3 * b) +=
              weight * isotropic_stiffness_block(gradients[a], gradients[b], lambda, mu);
        }
      }
    }
    push_element<10>(tet, element_stiffness, triplets);
  }
  const Index size = mesh.rest.size();
  SparseMatrix stiffness(size, size);
  stiffness.setFromTriplets(triplets.begin(), triplets.end());
  return stiffness;
}

Vector assemble_body_load(const TetMesh& mesh, const Vec3& body_force_per_volume) {
  Vector load = Vector::Zero(mesh.rest.size());
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    const auto& tet = mesh.tets[e];
    check_nodes(mesh.rest, tet.data(), 4, e);
    const double volume = corner_geometry(mesh.rest, tet.data(), e).volume;
    for (int node : tet) load.segment<3>(3 * node) += 0.25 * volume * body_force_per_volume;
  }
  return load;
}

Vector assemble_body_load(const QuadraticTetMesh& mesh, const Vec3& body_force_per_volume) {
  // integral(N_a) with the degree-2 rule (exact: N_a is quadratic).
  std::array<double, 10> integral_per_volume{};
  for (int q = 0; q < gauss_points; ++q) {
    const auto values = quadratic_shape_values(gauss_barycentric(q));
    for (int a = 0; a < 10; ++a) integral_per_volume[a] += values[a] / gauss_points;
  }
  Vector load = Vector::Zero(mesh.rest.size());
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    const auto& tet = mesh.tets[e];
    check_nodes(mesh.rest, tet.data(), 10, e);
    const double volume = corner_geometry(mesh.rest, tet.data(), e).volume;
    if (!check_straight_edges(mesh.rest, tet, e)) {
      static const std::vector<ReferencePoint> rule = conical_rule();
      std::array<Vec3, 10> gradients;
      for (const ReferencePoint& point : rule) {
        const double weight = point.weight * isoparametric_gradients(mesh.rest, tet, point.l, gradients, e);
        const auto values = quadratic_shape_values(point.l);
        for (int a = 0; a < 10; ++a) load.segment<3>(3 * tet[a]) += weight * values[a] * body_force_per_volume;
      }
      continue;
    }
    for (int a = 0; a < 10; ++a) {
      load.segment<3>(3 * tet[a]) += integral_per_volume[a] * volume * body_force_per_volume;
    }
  }
  return load;
}

Vector solve_static(const SparseMatrix& stiffness, const Vector& load,
                    const std::vector<uint8_t>& fixed_nodes,
                    const Vector& prescribed_displacements) {
  const Index size = stiffness.rows();
  if (stiffness.cols() != size || load.size() != size || size % 3 != 0) {
    throw std::invalid_argument("solve_static: stiffness " + std::to_string(stiffness.rows()) +
                                "x" + std::to_string(stiffness.cols()) + " and load " +
                                std::to_string(load.size()) + " do not match");
  }
  if (!fixed_nodes.empty() && static_cast<Index>(3 * fixed_nodes.size()) != size) {
    throw std::invalid_argument("solve_static: fixed_nodes has " +
                                std::to_string(fixed_nodes.size()) + " entries, expected " +
                                std::to_string(size / 3));
  }
  if (prescribed_displacements.size() != 0 && prescribed_displacements.size() != size) {
    throw std::invalid_argument("solve_static: prescribed_displacements has " +
                                std::to_string(prescribed_displacements.size()) +
                                " entries, expected " + std::to_string(size) + " or 0");
  }

  Vector displacements = Vector::Zero(size);
  std::vector<Index> free_index(static_cast<size_t>(size), -1);
  Index free_count = 0;
  for (Index component = 0; component < size; ++component) {
    const bool fixed = !fixed_nodes.empty() && fixed_nodes[static_cast<size_t>(component / 3)] != 0;
    if (fixed) {
      if (prescribed_displacements.size() != 0)
        displacements[component] = prescribed_displacements[component];
    } else {
      free_index[static_cast<size_t>(component)] = free_count++;
    }
  }
  if (free_count == 0) return displacements;

  // K_ff u_f = f_f - K_fc u_c.
  std::vector<Triplet> triplets;
  triplets.reserve(static_cast<size_t>(stiffness.nonZeros()));
  Vector right_hand_side(free_count);
  for (Index component = 0; component < size; ++component) {
    if (free_index[static_cast<size_t>(component)] >= 0)
      right_hand_side[free_index[static_cast<size_t>(component)]] = load[component];
  }
  for (Index column = 0; column < stiffness.outerSize(); ++column) {
    const Index free_column = free_index[static_cast<size_t>(column)];
    for (SparseMatrix::InnerIterator entry(stiffness, column); entry; ++entry) {
      const Index free_row = free_index[static_cast<size_t>(entry.row())];
      if (free_row < 0) continue;
      if (free_column >= 0) {
        triplets.emplace_back(free_row, free_column, entry.value());
      } else if (displacements[column] != 0.0) {
        right_hand_side[free_row] -= entry.value() * displacements[column];
      }
    }
  }
  SparseMatrix reduced(free_count, free_count);
  reduced.setFromTriplets(triplets.begin(), triplets.end());
  triplets = {};

  // CHOLMOD's supernodal Cholesky (Eigen's simplicial one under ThreadSanitizer), solved by
  // SupernodalFactor in double: a settled start of the 76k-element lobe (33k unknowns) took
  // Eigen's simplicial LDLT most of a minute. BLAS on one thread, so the bits do not depend on
  // whether a rest factor was built before (rest_factor.hpp).
  const SparseMatrix lower = reduced.triangularView<Eigen::Lower>();
  reduced = SparseMatrix();
  auto singular = [](const std::string& detail) {
    return std::runtime_error("solve_static: the stiffness restricted to the free nodes is singular or indefinite (" +
                              detail + "); is the body constrained?");
  };
  SupernodalFactor factor;
  try {
    if (default_factor_backend() == FactorBackend::cholmod) {
      use_single_threaded_blas();
      factor = SupernodalFactor::with_cholmod(lower, false);
    } else {
      factor = SupernodalFactor::with_simplicial(lower, false);
    }
  } catch (const std::runtime_error& e) {
    throw singular(std::string("its Cholesky factorisation failed: ") + e.what());
  }
  // A rigid mode left free shows as a pivot at round-off level against the largest one.
  const auto [smallest, largest] = factor.pivot_range();
  if (!(smallest > 1e-12 * largest))
    throw singular("smallest Cholesky pivot " + std::to_string(smallest) + ", largest " + std::to_string(largest));
  Vector solution = right_hand_side;
  SupernodalFactor::Workspace work;
  factor.solve(solution.data(), work);
  if (!solution.allFinite()) {
    throw std::runtime_error("solve_static: the Cholesky solve produced non-finite displacements");
  }
  for (Index component = 0; component < size; ++component) {
    const Index free = free_index[static_cast<size_t>(component)];
    if (free >= 0) displacements[component] = solution[free];
  }
  return displacements;
}

namespace {

template <class Mesh>
Vector solve_with_loads(const Mesh& mesh, const Material& material,
                        const std::vector<uint8_t>& fixed_nodes,
                        const Vector& prescribed_displacements, const Vec3& body_force_per_volume,
                        const Vector& nodal_forces) {
  Vector load = assemble_body_load(mesh, body_force_per_volume);
  if (nodal_forces.size() != 0) {
    if (nodal_forces.size() != load.size()) {
      throw std::invalid_argument("solve_static: nodal_forces has " +
                                  std::to_string(nodal_forces.size()) + " entries, expected " +
                                  std::to_string(load.size()) + " or 0");
    }
    load += nodal_forces;
  }
  return solve_static(assemble_stiffness(mesh, material), load, fixed_nodes,
                      prescribed_displacements);
}

}  // namespace

Vector solve_static_linear(const TetMesh& mesh, const Material& material,
                           const std::vector<uint8_t>& fixed_nodes,
                           const Vec3& body_force_per_volume) {
  return solve_with_loads(mesh, material, fixed_nodes, Vector(), body_force_per_volume, Vector());
}

Vector solve_static_quadratic(const QuadraticTetMesh& mesh, const Material& material,
                              const std::vector<uint8_t>& fixed_nodes,
                              const Vec3& body_force_per_volume) {
  return solve_with_loads(mesh, material, fixed_nodes, Vector(), body_force_per_volume, Vector());
}

Vector solve_static_linear(const TetMesh& mesh, const Material& material,
                           const std::vector<uint8_t>& fixed_nodes,
                           const Vector& prescribed_displacements,
                           const Vec3& body_force_per_volume, const Vector& nodal_forces) {
  return solve_with_loads(mesh, material, fixed_nodes, prescribed_displacements,
                          body_force_per_volume, nodal_forces);
}

Vector solve_static_quadratic(const QuadraticTetMesh& mesh, const Material& material,
                              const std::vector<uint8_t>& fixed_nodes,
                              const Vector& prescribed_displacements,
                              const Vec3& body_force_per_volume, const Vector& nodal_forces) {
  return solve_with_loads(mesh, material, fixed_nodes, prescribed_displacements,
                          body_force_per_volume, nodal_forces);
}

}  // namespace incise::physics
