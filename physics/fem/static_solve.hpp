// Small-strain linear elastic statics on tetrahedral meshes: sparse assembly and a direct
// solve (CHOLMOD's supernodal Cholesky, solved in double by SupernodalFactor). The reference
// against which the dynamic models are checked.
#pragma once

#include <Eigen/SparseCore>
#include <cstdint>
#include <vector>

#include "physics/core/model.hpp"
#include "physics/fem/material.hpp"
#include "physics/fem/tet_mesh.hpp"

namespace incise::physics {

using SparseMatrix = Eigen::SparseMatrix<double>;

// Global stiffness (3n x 3n, symmetric, column-major). Linear tets are integrated exactly with
// their constant gradients; 10-node tets with the 4-point Gauss rule, exact for the degree-2
// integrand of straight-edged elements. Throw std::invalid_argument on a bad element.
SparseMatrix assemble_stiffness(const TetMesh& mesh, const Material& material);
SparseMatrix assemble_stiffness(const QuadraticTetMesh& mesh, const Material& material);

// Consistent nodal load of a constant body force b (N/m^3): f_a = b integral(N_a) dV.
// Linear tets: V/4 per corner. 10-node tets: -V/20 per corner and V/5 per midpoint.
Vector assemble_body_load(const TetMesh& mesh, const Vec3& body_force_per_volume);
Vector assemble_body_load(const QuadraticTetMesh& mesh, const Vec3& body_force_per_volume);

// Solves K u = load for u with u prescribed (all 3 components) on the fixed nodes.
// `prescribed_displacements` is 3n, read only at fixed nodes (empty = zero). Returns u (3n).
// Throws std::runtime_error if the factorisation fails or the free system is singular
// (for instance an unconstrained body).
Vector solve_static(const SparseMatrix& stiffness, const Vector& load,
                    const std::vector<uint8_t>& fixed_nodes,
                    const Vector& prescribed_displacements = Vector());

// Displacements (3n) of a body clamped at the fixed nodes under a constant body force.
Vector solve_static_linear(const TetMesh& mesh, const Material& material,
                           const std::vector<uint8_t>& fixed_nodes,
                           const Vec3& body_force_per_volume);
Vector solve_static_quadratic(const QuadraticTetMesh& mesh, const Material& material,
                              const std::vector<uint8_t>& fixed_nodes,
                              const Vec3& body_force_per_volume);

// The same with displacements prescribed at the fixed nodes (3n, read only there) and extra
// nodal forces (3n, or empty for none), e.g. for patch tests.
Vector solve_static_linear(const TetMesh& mesh, const Material& material,
                           const std::vector<uint8_t>& fixed_nodes,
                           const Vector& prescribed_displacements,
                           const Vec3& body_force_per_volume, const Vector& nodal_forces);
Vector solve_static_quadratic(const QuadraticTetMesh& mesh, const Material& material,
                              const std::vector<uint8_t>& fixed_nodes,
                              const Vector& prescribed_displacements,
                              const Vec3& body_force_per_volume, const Vector& nodal_forces);

}  // namespace incise::physics
