// What a rest-shape preconditioner needs from the tetrahedral model (physics/solve/): K0 and
// the warp.
#include "physics/fem/corotational_fem.hpp"
#include "physics/solve/warped_preconditioner.hpp"

#include <memory>

namespace incise::physics {

std::function<BlockMatrix()> CorotationalTetFem::rest_stiffness_job() const {
  struct Elements {
    int nodes;
    std::vector<std::array<int, 4>> tets;
    std::vector<EdgeStiffness> stiffness;
  };
  auto copy = std::make_shared<const Elements>(Elements{node_count(), elements_, edge_stiffness_});
  return [copy] {
    const auto& c = *copy;
    BlockMatrix stiffness(c.nodes, [&](const std::function<void(std::span<const int>)>& visit) {
      for (const auto& tet : c.tets) visit(tet);
    });
    // The edge stiffness holds corners 1..3; translation invariance gives corner 0's blocks:
    // K_0b = -sum_a K_ab, K_00 = sum_ab K_ab (corotational_fem.hpp).
    for (size_t e = 0; e < c.tets.size(); ++e) {
      const auto& tet = c.tets[e];
      const EdgeStiffness& k = c.stiffness[e];
      Mat3 corner_zero = Mat3::Zero();
      for (int a = 0; a < 3; ++a) {
        Mat3 column_sum = Mat3::Zero();  // sum_b K_ab
        for (int b = 0; b < 3; ++b) {
          const Mat3 block = k.block<3, 3>(3 * a, 3 * b);
          stiffness.at(tet[a + 1], tet[b + 1]) += block;
          column_sum += block;
        }
        stiffness.at(tet[a + 1], tet[0]) -= column_sum;
        stiffness.at(tet[0], tet[a + 1]) -= column_sum.transpose();
        corner_zero += column_sum;
      }
      stiffness.at(tet[0], tet[0]) += corner_zero;
    }
    return stiffness;
  };
}

void CorotationalTetFem::node_rotations(std::vector<Eigen::Quaterniond>& out) const {
  NodeRotations mean;
  mean.reset(node_count());
  for (size_t e = 0; e < elements_.size(); ++e) {
    const Eigen::Quaterniond rotation(rotations_[e]);
    for (int node : elements_[e]) mean.add(node, rotation, volumes_[e]);
  }
  mean.finish(out);
}

double CorotationalTetFem::node_spacing() const {
  // The mean edge length (each tet's six edges; shared edges counted once per tet).
  double sum = 0;
  long long count = 0;
  for (const auto& tet : elements_) {
    for (int a = 0; a < 4; ++a) {
      for (int b = a + 1; b < 4; ++b) {
        sum += (rest_.segment<3>(3 * tet[a]) - rest_.segment<3>(3 * tet[b])).norm();
        ++count;
      }
    }
  }
  return count > 0 ? sum / static_cast<double>(count) : 0.0;
}

}  // namespace incise::physics
