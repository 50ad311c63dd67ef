// The EFG model's current corotated stiffness K(x) in 3x3 blocks (DeformableModel::
// current_stiffness): what add_stiffness_product applies matrix-free, assembled once per step
// so that a solve's products read each node pair's block once instead of visiting every
// integration point's neighbourhood twice (issue 29).
#include "physics/efg/corotational_efg.hpp"

#include <algorithm>

namespace incise::physics {

void CorotationalEfg::plan_current_stiffness() const {
  if (planned_revision_ == topology_revision_) return;  // no row edited since the plan was laid
  if (planned_revision_ < 0) {
    assembly_.build(node_count(), stride_, row_lengths_, neighbours_);
  } else if (!rows_edited_.empty()) {
    // The plan edited in the rows set_neighbourhood listed, none compared (ElementAssembly::edit).
    std::sort(rows_edited_.begin(), rows_edited_.end());
    rows_edited_.erase(std::unique(rows_edited_.begin(), rows_edited_.end()), rows_edited_.end());
    assembly_.build(node_count(), stride_, row_lengths_, neighbours_, &rows_edited_);
  }  // else only elements were taken out: their weights, which the refill reads, are 0
  rows_edited_.clear();
  planned_revision_ = topology_revision_;
}

const BlockMatrix* CorotationalEfg::current_stiffness() const {
  plan_current_stiffness();  // done already where a cut laid it beside its surface work
  // add_stiffness_product's element term V R sigma(sym(R^T p g^T)) g_a, for p = p_b at node b
  // alone, is V R (lambda g_a g_b^T + mu g_b g_a^T + mu (g_a . g_b) I) R^T p_b: with h = R g
  // (R orthogonal, so h_a . h_b = g_a . g_b) and S = V h_a h_b^T, the block
  // lambda S + mu S^T + mu tr(S) I, the rest block of efg_rest_stiffness.cpp turned. It is
  // linear in S, so the assembly sums S over the integration points of a particle cell (one
  // neighbourhood) and turns the sum into a block once per cell and pair (element_assembly.hpp).
  const int elements = element_count();
  executor_->parallel_for(elements, [&](int begin, int end) {
    for (int e = begin; e < end; ++e) {
      const size_t base = static_cast<size_t>(e) * stride_;
      assembly_.weight(e) = volumes_[static_cast<size_t>(e)] > 0 ? volumes_[static_cast<size_t>(e)] : 0.0;
      double* turned = assembly_.gradients(e);
      for (int k = 0; k < row_lengths_[static_cast<size_t>(e)]; ++k)
        Eigen::Map<Vec3>(turned + 3 * assembly_.local(e, k)) = rotations_[static_cast<size_t>(e)] * shape_gradients_[base + k];
    }
  }, std::max(1, shape_->settings.threaded_elements / 2));
  const double lambda = shape_->lambda, mu = shape_->mu;
  const BlockMatrix& stiffness = assembly_.assemble(*executor_, [&](const Mat3& s, Mat3& out) {
    out.noalias() += lambda * s + mu * s.transpose();
    out.diagonal().array() += mu * s.trace();
  });
  return &stiffness;
}

}  // namespace incise::physics
