// The EFG elements' rotation extraction (efg_step.cpp): the rotation maximising tr(R^T F), which
// is the polar rotation of F when det F > 0, by the axis-angle updates of Mueller, Bender,
// Chentanez and Macklin 2016 ("A robust method to extract the rotational part of
// deformations"), warm-started with the previous rotation. Their step omega = g / |tr N|
// (N = F R^T, g = sum_i r_i x f_i the axial vector of N - N^T) converges linearly (by about a
// factor 3 per iteration at small strain); taking the Newton step omega = (tr(N) I - sym N)^-1 g
// instead, whenever that matrix is positive definite, converges quadratically, so a warm start
// needs one or two iterations. Falls back to the SVD polar decomposition if it has not settled.
#pragma once

#include "physics/core/model.hpp"

#include <Eigen/Geometry>

namespace incise::physics {

Eigen::Quaterniond extract_rotation(const Mat3& f, Eigen::Quaterniond q);

// extract_rotation of f[i] from the warm start q[i] (replaced by the result), i < count <=
// rotation_lanes, each bitwise as its own call gives it. A full set of lanes runs as two AVX2
// vectors of 4 lanes per quantity, iterated side by side, where the CPU has AVX2: the same IEEE
// operations in the same order as the scalar code's Eigen expressions, the same libm sincos per
// lane (skipped below 2^-27, where it returns (x, 1)). Otherwise, and for fewer lanes, the
// scalar iterations of the lanes are interleaved. Either way the core overlaps the lanes'
// chains of divisions, square roots and sincos calls, which one element's iterations, each
// waiting on the last, leave idle.
constexpr int rotation_lanes = 8;
void extract_rotations(const Mat3* f, Eigen::Quaterniond* q, int count);

// Whether full sets of lanes run the AVX2 kernel on this CPU.
bool rotation_extraction_vectorised();
// Tests: force the scalar lanes (false) or the CPU's best (true).
void set_rotation_extraction_vectorised(bool allowed);

}  // namespace incise::physics
