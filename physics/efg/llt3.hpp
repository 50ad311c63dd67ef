// Eigen::LLT<Mat3>(a).solve(b) written out for 3x3: the rotation extraction's Newton step
// (efg_step.cpp) solves one per element and iteration, and Eigen's LLT walks dynamic blocks
// whose bookkeeping costs more than the arithmetic. The same operations in the same order as
// Eigen 3.4's llt_inplace::unblocked (lower triangle) and its unrolled triangular solves, so the
// same bits (test_efg's Llt3 compares them).
#pragma once

#include "physics/core/model.hpp"

#include <cmath>

namespace incise::physics {

// false where Eigen's LLT reports a failure (a pivot <= 0; a NaN pivot passes, as there).
inline bool llt3_solve(const Mat3& a, const Vec3& b, Vec3& x) {
  double l00 = a(0, 0);
  if (l00 <= 0) return false;
  l00 = std::sqrt(l00);
  const double l10 = a(1, 0) / l00;
  const double l20 = a(2, 0) / l00;
  double l11 = a(1, 1);
  l11 -= l10 * l10;
  if (l11 <= 0) return false;
  l11 = std::sqrt(l11);
  const double l21 = (a(2, 1) - l20 * l10) / l11;
  double l22 = a(2, 2);
  l22 -= l20 * l20 + l21 * l21;
  if (l22 <= 0) return false;
  l22 = std::sqrt(l22);
  // L y = b, then L^T x = y.
  double y0 = b(0), y1 = b(1), y2 = b(2);
  y0 /= l00;
  y1 -= l10 * y0;
  y1 /= l11;
  y2 -= l20 * y0 + l21 * y1;
  y2 /= l22;
  y2 /= l22;
  y1 -= l21 * y2;
  y1 /= l11;
  y0 -= l10 * y1 + l20 * y2;
  y0 /= l00;
  x = Vec3(y0, y1, y2);
  return true;
}

}  // namespace incise::physics
