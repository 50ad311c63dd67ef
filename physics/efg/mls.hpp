// Linear moving least squares shape functions (Magnoux 2020, eqs. 4.3 to 4.6 and Annex A),
// with the quartic spline of kernel.hpp as weight.
#pragma once

#include "physics/core/model.hpp"

#include <span>

namespace incise::physics {

// Shape function values phi_i(point) and, if `gradients` is not empty, their gradients with
// respect to the evaluation point (Annex A, eqs. A.14 to A.21, with the first term of A.21
// read as w_I(x_i), the printed w_I,x being a typo; seed-004 §1.4). The support h is held
// constant. `particles`, `values` and `gradients` (if given) have the same length.
//
// The basis is p(y) = [1, (y - point) / scale]: shifted to the evaluation point and scaled by
// `scale` (the integration cube side) so that the 4x4 moment matrix has entries of order one.
// A linear change of basis leaves MLS unchanged, so this only improves conditioning.
//
// Returns false, leaving the outputs unspecified, if the moment matrix is singular to working
// precision: fewer than 4 particles with a positive weight, or all of them coplanar.
bool mls_shape_functions(const Vec3& point, std::span<const Vec3> particles, double support,
                         double scale, std::span<double> values, std::span<Vec3> gradients);

// True if the points span 3 dimensions: the smallest principal extent of the cloud is at
// least `relative_tolerance` times the largest. A linear basis needs this (seed-004 §1.3).
bool spans_three_dimensions(std::span<const Vec3> points, double relative_tolerance = 1e-6);

}  // namespace incise::physics
