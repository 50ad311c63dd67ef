#include "physics/efg/efg_static.hpp"

#include "physics/fem/tet_element.hpp"

#include <vector>

namespace incise::physics {

SparseMatrix assemble_stiffness(const CorotationalEfg& model) {
  const double lambda = lame_lambda(model.material());
  const double mu = lame_mu(model.material());
  const int stride = model.row_stride();
  const auto& lengths = model.row_lengths();
  const auto& neighbours = model.neighbours();
  const auto& gradients = model.shape_gradients();
  std::vector<Eigen::Triplet<double>> triplets;
  size_t count = 0;
  for (int length : lengths) count += 9 * static_cast<size_t>(length) * length;
  triplets.reserve(count);
  for (int e = 0; e < model.element_count(); ++e) {
    const size_t base = static_cast<size_t>(e) * stride;
    const Mat3& rotation = model.rotations()[e];
    const double volume = model.element_volumes()[e];
    for (int a = 0; a < lengths[e]; ++a) {
      for (int b = 0; b < lengths[e]; ++b) {
        const Mat3 block = volume * rotation *
                           isotropic_stiffness_block(gradients[base + a], gradients[base + b],
                                                     lambda, mu) *
                           rotation.transpose();
        for (int i = 0; i < 3; ++i) {
          for (int j = 0; j < 3; ++j) {
            triplets.emplace_back(3 * neighbours[base + a] + i, 3 * neighbours[base + b] + j,
                                  block(i, j));
          }
        }
      }
    }
  }
  const Eigen::Index size = 3 * static_cast<Eigen::Index>(model.node_count());
  SparseMatrix stiffness(size, size);
  stiffness.setFromTriplets(triplets.begin(), triplets.end());
  return stiffness;
}

}  // namespace incise::physics
