// The implicit step's `multigrid` preconditioner: the rest system's V-cycle V0 warped as a
// whole, M^-1 r = R V0 R^T r (multigrid.hpp's cycle with B = A0, its products the assembled
// rest system's, block_system.hpp), with its vector work fused into as few passes as it
// allows:
//   - the warp R^T with the first smoothing step (s = D0^-1 R^T r / theta),
//   - each Chebyshev step's recurrence with the update of x,
//   - each product with the residual's update (residual -= A0 s, row by row),
//   - the warp R with the last step (z = R (x + s)).
// The operations per entry are VcyclePreconditioner's on R^T r, in the same order, so the
// result has the same bits as R VcyclePreconditioner(A0)(R^T r) (test_rest_preconditioner).
//
// The fixed nodes' rows of A0 are the identity's, their entries of R^T r are zeroed, and no
// free row reads a fixed column: their residual, steps and correction stay zero without
// VcyclePreconditioner's zeroing of every product.
#pragma once

#include "physics/core/executor.hpp"
#include "physics/core/model.hpp"
#include "physics/solve/multigrid.hpp"
#include "physics/solve/rest_factor.hpp"

#include <Eigen/Geometry>

#include <vector>

namespace incise::physics {

class RestVcycle {
 public:
  // `factor`: a V-cycle's (smoothing_degree() > 0); `rotations`: one per node (empty: none);
  // `smoother`: its degree and interval; the products run on `executor`'s threads.
  RestVcycle(const RestFactor& factor, const std::vector<Eigen::Quaterniond>& rotations, ChebyshevSmoother smoother,
             Executor& executor);

  // z = R V0 R^T r. Not re-entrant (workspace).
  void operator()(const Vector& r, Vector& z);

 private:
  // x += S residual, residual -= A0 (that increment), except that the last step's product is
  // skipped when `output` is given and the last x + s goes, warped, to *output instead.
  void smooth(Vector* output);

  const RestFactor& factor_;
  const std::vector<Eigen::Quaterniond>& rotations_;
  ChebyshevSmoother smoother_;
  Executor& executor_;
  ChebyshevSteps steps_;
  Vector residual_, step_, x_, correction_;
};

}  // namespace incise::physics
