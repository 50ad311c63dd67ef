// The EFG model's current corotated stiffness K(x) in 3x3 blocks (DeformableModel::
// current_stiffness): what add_stiffness_product applies matrix-free, assembled once per step
// so that a solve's products read each node pair's block once instead of visiting every
// integration point's neighbourhood twice (issue 29).
#include "physics/efg/corotational_efg.hpp"

namespace incise::physics {

const BlockMatrix* CorotationalEfg::current_stiffness() const {
  if (!assembly_.matches(node_count(), stride_, row_lengths_, neighbours_))
    assembly_.build(node_count(), stride_, row_lengths_, neighbours_);
  // add_stiffness_product's element term V R sigma(sym(R^T p g^T)) g_a, for p = p_b at node b
  // alone, is V R (lambda g_a g_b^T + mu g_b g_a^T + mu (g_a . g_b) I) R^T p_b: with h = R g
  // (R orthogonal, so h_a . h_b = g_a . g_b), the block V (lambda h_a h_b^T + mu h_b h_a^T +
  // mu (h_a . h_b) I), the rest block of efg_rest_stiffness.cpp turned.
  // Per row entry: h, V lambda h and V mu h (zero for an element taken out), so that a block
  // costs two outer products and a dot.
  const size_t entries = shape_gradients_.size();
  turned_gradients_.resize(3 * entries);
  const int elements = element_count();
  const double lambda = shape_->lambda, mu = shape_->mu;
  executor_->parallel_for(elements, [&](int begin, int end) {
    for (int e = begin; e < end; ++e) {
      const size_t base = static_cast<size_t>(e) * stride_;
      const double volume = volumes_[static_cast<size_t>(e)] > 0 ? volumes_[static_cast<size_t>(e)] : 0.0;
      for (int k = 0; k < row_lengths_[static_cast<size_t>(e)]; ++k) {
        const Vec3 turned = rotations_[static_cast<size_t>(e)] * shape_gradients_[base + k];
        turned_gradients_[base + k] = turned;
        turned_gradients_[entries + base + k] = (volume * lambda) * turned;
        turned_gradients_[2 * entries + base + k] = (volume * mu) * turned;
      }
    }
  }, std::max(1, shape_->settings.threaded_elements / 2));
  const Vec3* h = turned_gradients_.data();
  const Vec3* lambda_h = h + entries;
  const Vec3* mu_h = h + 2 * entries;
  const BlockMatrix& stiffness = assembly_.assemble(*executor_, [&](int e, int a, int b, Mat3& out) {
    const size_t base = static_cast<size_t>(e) * stride_;
    const size_t ia = base + static_cast<size_t>(a), ib = base + static_cast<size_t>(b);
    out.noalias() += lambda_h[ia] * h[ib].transpose() + mu_h[ib] * h[ia].transpose();
    out.diagonal().array() += mu_h[ia].dot(h[ib]);
  });
  return &stiffness;
}

}  // namespace incise::physics
