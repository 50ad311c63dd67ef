// What a rest-shape preconditioner needs from the EFG model (physics/solve/): K0 and the warp.
#include "physics/efg/corotational_efg.hpp"
#include "physics/fem/tet_element.hpp"
#include "physics/solve/warped_preconditioner.hpp"

namespace incise::physics {

std::function<BlockMatrix()> CorotationalEfg::rest_stiffness_job() const {
  // A copy of the rows: the job runs beside the steps, which a cut may re-select meanwhile.
  struct Rows {
    int nodes, stride;
    double lambda, mu;
    std::vector<int> lengths, neighbours;
    std::vector<Vec3> gradients;
    std::vector<double> volumes;
  };
  auto rows = std::make_shared<const Rows>(
      Rows{node_count(), stride_, shape_->lambda, shape_->mu, row_lengths_, neighbours_, shape_gradients_, volumes_});
  return [rows] {
    const auto& r = *rows;
    const int elements = static_cast<int>(r.volumes.size());
    auto row = [&](int e) {
      return std::span<const int>(r.neighbours.data() + static_cast<size_t>(e) * r.stride,
                                  static_cast<size_t>(r.lengths[static_cast<size_t>(e)]));
    };
    BlockMatrix stiffness(r.nodes, [&](const std::function<void(std::span<const int>)>& visit) {
      for (int e = 0; e < elements; ++e)
        if (r.volumes[static_cast<size_t>(e)] > 0) visit(row(e));
    });
    // The corotated K p of add_stiffness_product with R = I: block (n, m) of element e is
    // V_e (lambda g_n g_m^T + mu g_m g_n^T + mu (g_n . g_m) I), the isotropic block.
    for (int e = 0; e < elements; ++e) {
      const double volume = r.volumes[static_cast<size_t>(e)];
      if (!(volume > 0)) continue;
      const size_t base = static_cast<size_t>(e) * r.stride;
      const int length = r.lengths[static_cast<size_t>(e)];
      for (int a = 0; a < length; ++a) {
        for (int b = 0; b < length; ++b) {
          stiffness.at(r.neighbours[base + a], r.neighbours[base + b]) +=
              volume * isotropic_stiffness_block(r.gradients[base + a], r.gradients[base + b], r.lambda, r.mu);
        }
      }
    }
    return stiffness;
  };
}

void CorotationalEfg::node_rotations(std::vector<Eigen::Quaterniond>& out) const {
  NodeRotations mean;
  mean.reset(node_count());
  for (int e = 0; e < element_count(); ++e) {
    if (!(volumes_[static_cast<size_t>(e)] > 0)) continue;
    const size_t base = static_cast<size_t>(e) * stride_;
    for (int k = 0; k < row_lengths_[static_cast<size_t>(e)]; ++k)
      mean.add(neighbours_[base + k], orientations_[static_cast<size_t>(e)], volumes_[static_cast<size_t>(e)]);
  }
  mean.finish(out);
}

double CorotationalEfg::node_spacing() const { return 2 * shape_->settings.spacing; }  // the particle grid's

}  // namespace incise::physics
