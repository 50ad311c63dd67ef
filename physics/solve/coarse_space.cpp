#include "physics/solve/coarse_space.hpp"

#include <array>
#include <cmath>
#include <stdexcept>

namespace incise::physics {

namespace {

struct Corner {
  long long vertex;  // index in the grid
  double weight;
};

}  // namespace

CoarseSpace make_coarse_space(const Eigen::VectorXd& rest, double spacing, const std::vector<std::uint8_t>& fixed) {
  if (!(spacing > 0)) throw std::invalid_argument("make_coarse_space: the spacing must be positive");
  const Eigen::Index nodes = rest.size() / 3;
  const Eigen::Map<const Eigen::Matrix3Xd> points(rest.data(), 3, nodes);
  const Eigen::Vector3d origin = points.rowwise().minCoeff();
  std::array<long long, 3> counts{};
  for (int axis = 0; axis < 3; ++axis)
    counts[axis] = static_cast<long long>(std::floor((points.row(axis).maxCoeff() - origin[axis]) / spacing)) + 2;
  auto is_fixed = [&](Eigen::Index node) { return !fixed.empty() && fixed[static_cast<size_t>(node)] != 0; };

  // Each node's 8 corners and weights; the weight each vertex holds from a single node.
  std::vector<std::array<Corner, 8>> corners(static_cast<size_t>(nodes));
  std::vector<double> best(static_cast<size_t>(counts[0] * counts[1] * counts[2]), 0.0);
  for (Eigen::Index node = 0; node < nodes; ++node) {
    std::array<long long, 3> cell{};
    std::array<double, 3> t{};
    for (int axis = 0; axis < 3; ++axis) {
      const double s = (points(axis, node) - origin[axis]) / spacing;
      cell[axis] = std::min(static_cast<long long>(std::floor(s)), counts[axis] - 2);
      t[axis] = s - static_cast<double>(cell[axis]);
    }
    for (int c = 0; c < 8; ++c) {
      const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
      const double w = (dx ? t[0] : 1 - t[0]) * (dy ? t[1] : 1 - t[1]) * (dz ? t[2] : 1 - t[2]);
      const long long vertex = ((cell[2] + dz) * counts[1] + (cell[1] + dy)) * counts[0] + (cell[0] + dx);
      corners[static_cast<size_t>(node)][static_cast<size_t>(c)] = {vertex, w};
      if (!is_fixed(node)) best[static_cast<size_t>(vertex)] = std::max(best[static_cast<size_t>(vertex)], w);
    }
  }
  // Keep the vertices some free node leans on with half its weight or more; number them.
  std::vector<int> index(best.size(), -1);
  int kept = 0;
  for (size_t v = 0; v < best.size(); ++v)
    if (best[v] >= 0.5) index[v] = kept++;

  CoarseSpace space;
  space.weight_start.assign(static_cast<size_t>(nodes) + 1, 0);
  space.weights.reserve(static_cast<size_t>(nodes) * 8);
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<size_t>(nodes) * 24);
  for (Eigen::Index node = 0; node < nodes; ++node) {
    space.weight_start[static_cast<size_t>(node)] = static_cast<int>(space.weights.size());
    if (is_fixed(node)) continue;
    double sum = 0;
    for (const Corner& corner : corners[static_cast<size_t>(node)])
      if (index[static_cast<size_t>(corner.vertex)] >= 0) sum += corner.weight;
    if (!(sum > 1e-9)) continue;  // a node no kept vertex reaches: the fine smoother's alone
    // The corners come in increasing vertex order (x fastest), and so do their columns.
    for (const Corner& corner : corners[static_cast<size_t>(node)]) {
      const int column = index[static_cast<size_t>(corner.vertex)];
      if (column < 0 || corner.weight <= 0) continue;
      const double weight = corner.weight / sum;
      space.weights.push_back({column, weight});
      for (int k = 0; k < 3; ++k) triplets.emplace_back(static_cast<int>(3 * node + k), 3 * column + k, weight);
    }
  }
  space.weight_start.back() = static_cast<int>(space.weights.size());
  space.coarse_nodes = kept;
  space.prolongation.resize(3 * nodes, 3 * kept);
  space.prolongation.setFromTriplets(triplets.begin(), triplets.end());
  return space;
}

}  // namespace incise::physics
