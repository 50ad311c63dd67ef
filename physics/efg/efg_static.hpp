// The assembled stiffness of the EFG model, for static solves (physics/fem/static_solve.hpp
// takes it) and for checking the matrix-free products.
#pragma once

#include "physics/efg/corotational_efg.hpp"
#include "physics/fem/static_solve.hpp"

namespace incise::physics {

// K (3n x 3n, symmetric) with the model's current frozen rotations: the matrix whose product
// add_stiffness_product computes, K_ab = sum_e V_e R_e (lambda g_a g_b^T + mu g_b g_a^T +
// mu (g_a . g_b) I) R_e^T with g = grad phi at the element's integration point.
SparseMatrix assemble_stiffness(const CorotationalEfg& model);

}  // namespace incise::physics
