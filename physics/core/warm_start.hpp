// CG's start for an implicit step's velocity change dv, from the last steps' solutions
// (issue 29): the solutions kept (WarmStart, part of a body's data) and the start CG takes from
// them (galerkin_start).
//
// The previous step's dv alone is a poor start once a blade moves or a body swings: scaled to
// its best multiple it still leaves most of |b| in the residual, and CG spends its first
// iterations on motion the last steps already found. The best start in the span of the last
// `depth` solutions d_j, in A's norm, is the Galerkin projection
//   G c = g,  G_ij = d_i . A d_j,  g_i = d_i . b,  x0 = sum_j c_j d_j,  A x0 = sum_j c_j A d_j,
// one product per solution, of the system itself (also where CG iterates on a float copy of
// it, cg.cpp), so CG's first residual needs none more. With one solution it is the scaling of the single dv that came before (a truncated CG
// needs at least that: started from the last dv as given, its stale smooth part was applied
// again at every step and a real-time session that stopped CG early gained energy). Products
// with the older matrices (d_j . b_j, no product at all) were tried: the steps' matrices differ
// by their rotations, and on swinging or stiff bodies the start became worse than the scaled
// dv (docs/status.md).
//
// The history is part of the body's data (copied, hashed, zeroed where a cut orphans a node):
// a replay or a copy starts its steps from the same bits.
#pragma once

#include "physics/core/cg.hpp"
#include "physics/core/model.hpp"

#include <span>
#include <vector>

namespace incise::physics {

class WarmStart {
 public:
  // Solutions kept by default: four took most of what more would give (docs/status.md). A
  // depth of one starts from the newest solution alone, scaled.
  static constexpr int default_depth = 4;
  explicit WarmStart(int depth = default_depth) : depth_(depth < 1 ? 1 : depth) {}

  // The newest solution for a system of `size` entries, or zero: CG's x on entry.
  Vector newest(Eigen::Index size) const;
  // The ones before it (newest first), for a system of `size` entries: CgSettings::start_space.
  std::span<const Vector> older(Eigen::Index size) const;
  // Records a step's solution. One of another size than the history's clears it first.
  void record(const Vector& solution);
  // A node left the system (an orphaned particle, pinned): its entries become zero everywhere.
  void zero_node(int node);
  void clear() { solutions_.clear(); }
  // Newest first (the state hash).
  const std::vector<Vector>& solutions() const { return solutions_; }

 private:
  int depth_;
  std::vector<Vector> solutions_;  // newest first
};

// x (on entry the newest solution, fixed entries zero) becomes the Galerkin start over x and
// `older`'s vectors, and product its A x. `apply` is CG's operator; b has its fixed entries
// zeroed. Directions of G's eigenvalues under a relative floor (nearly parallel solutions, or
// round-off of a float product) are left out. Without older vectors it is x scaled by
// x.b / x.A x; a zero or non-positive x.A x leaves x as it is. `several` (optional): the same
// products, bitwise, in one pass (CgSettings::start_products).
void galerkin_start(const LinearOperator& apply, const Vector& b,
                    const std::vector<std::uint8_t>& fixed_nodes, std::span<const Vector> older, Vector& x,
                    Vector& product, const SeveralOperator* several = nullptr);

}  // namespace incise::physics
