// The implicit step's `multigrid_current` preconditioner: multigrid.hpp's V-cycle on the
// assembled current system A (current_system.hpp), its Chebyshev smoother on D^-1 A and its
// coarse correction C = R P (P^T A0 P)^-1 P^T R^T (warped_solve), with the cycle's vector work
// fused into its products' passes, each one executor region over rows of nodes:
//   - each product with the residual's update, the next Chebyshev step (into a second
//     buffer: the product still reads the current one) and x += step,
//   - the pre-smoothing's last product with the warp R^T of the residual,
//   - the restriction P^T as a gather over the coarse nodes (coarse_transfer.hpp),
//   - the prolongation P with the warp R and x += correction, a gather over the nodes,
//   - the correction's product with the post-smoothing's first step.
// With CycleEntries::single, the smoother's and the correction's products are float products
// on K's blocks in pairs (paired_blocks.hpp, made once in the constructor), their operands
// rounded to float in the passes that write them; the masses, springs, fixed rows, D and every
// vector of the cycle stay double. With CycleEntries::half_smoother they read the copy's
// halves instead (half the bytes again, for a K too large for the caches). The copy is
// symmetric bit for bit, so the cycle is symmetric to float round-off (CG's own product,
// multiply(), is the float product on the single-precision entries, its convergence confirmed
// on the double A). The coarse solve runs the two halves of its elimination tree beside each
// other (supernodal_factor.hpp). Every entry is computed by one thread in the order
// VcyclePreconditioner computes it, so the result
// has its bits whatever the threads (test_current_vcycle).
//
// The fixed nodes' rows of A are the identity's and r is zeroed on them, so their residual,
// steps and correction stay +0 without VcyclePreconditioner's zeroing of every product (the
// correction, which R may turn to -0, is written as +0).
#pragma once

#include "physics/core/executor.hpp"
#include "physics/core/model.hpp"
#include "physics/solve/current_system.hpp"
#include "physics/solve/jacobi_scaling.hpp"
#include "physics/solve/multigrid.hpp"
#include "physics/solve/paired_blocks.hpp"
#include "physics/solve/rest_factor.hpp"

#include <Eigen/Geometry>

#include <memory>
#include <vector>

namespace incise::physics {

// K's entries as the cycle's products read them.
enum class CycleEntries { double_precision, single, half_smoother };

class CurrentVcycle {
 public:
  // `system`: A; `factor`: a coarse V-cycle's (coarse(), smoothing_degree() > 0) of the same
  // nodes; `rotations`: its warp, one per node (empty: none); the passes run on `executor`'s
  // threads; `entries`: the products on K's blocks rounded (above), the paired copy built into
  // `workspace` where one is given (its storage kept from cycle to cycle, PairedBlocks::build).
  // All referenced arguments must outlive the cycle.
  CurrentVcycle(const CurrentSystem& system, const RestFactor& factor, const std::vector<Eigen::Quaterniond>& rotations,
                ChebyshevSmoother smoother, Executor& executor, CycleEntries entries = CycleEntries::double_precision,
                PairedBlocks* workspace = nullptr);

  // z = M^-1 r. Not re-entrant (workspace).
  void operator()(const Vector& r, Vector& z);
  // out = A p, on K's paired float copy (single_precision; A's own product without it).
  void multiply(const Vector& p, Vector& out);
  bool single_precision() const { return paired_ != nullptr; }

 private:
  // Over ranges of nodes: the product of `from` (`operand`: it rounded, single_precision),
  // residual -= it, then finish(begin, end) (entries).
  template <class Finish>
  void product_pass(const Vector& from, const std::vector<float>& operand, const Finish& finish);
  // Entries [begin, end) (whole nodes) of v rounded into `operand` (single_precision).
  void round(const Vector& v, std::vector<float>& operand, Eigen::Index begin, Eigen::Index end) const;
  // x += the Chebyshev steps 1 .. degree - 1 (step 0 in step_), from residual_.
  void smooth_steps(Vector& x);
  void coarse_correction(Vector& x);

  const CurrentSystem& system_;
  const RestFactor& factor_;
  const std::vector<Eigen::Quaterniond>& rotations_;
  ChebyshevSmoother smoother_;
  Executor& executor_;
  ChebyshevSteps steps_;
  JacobiScaling scaling_;  // the smoother's D^-1 (smoother.node_blocks: A's node blocks')
  CurrentRows rows_;
  // K's blocks in float pairs (single_precision: the workspace or own_paired_), null: the
  // double blocks.
  PairedBlocks own_paired_;
  PairedBlocks* paired_ = nullptr;
  // The smoother's entries: half for a large K (current_vcycle.cpp).
  PairedPrecision smoother_precision_ = PairedPrecision::single;
  Vector residual_, step_, next_step_, product_, turned_, coarse_;
  // step_, next_step_ and multiply()'s p rounded (single_precision).
  std::vector<float> step_operand_, next_operand_, product_operand_;
};

}  // namespace incise::physics
