#include "physics/solve/galerkin.hpp"

#include <algorithm>
#include <stdexcept>

namespace incise::physics {

namespace {

// A sparse accumulator of 3x3 blocks over `size` slots: the first value a slot gets in a pass
// is assigned (as Eigen's product does), later ones added; `touched` lists the slots in the
// order first reached.
struct BlockAccumulator {
  explicit BlockAccumulator(int size) : sums(static_cast<size_t>(size)), pass(static_cast<size_t>(size), -1) {}
  void add(int slot, int current_pass, const Mat3& value) {
    Mat3& sum = sums[static_cast<size_t>(slot)];
    if (pass[static_cast<size_t>(slot)] != current_pass) {
      pass[static_cast<size_t>(slot)] = current_pass;
      touched.push_back(slot);
      sum = value;
    } else {
      sum += value;
    }
  }
  std::vector<Mat3> sums;
  std::vector<int> pass;
  std::vector<int> touched;
};

// W^T: per coarse vertex, the nodes weighting it (increasing) and their weights.
struct CoarseColumns {
  std::vector<int> start;
  std::vector<CoarseWeight> nodes;  // `vertex` holds the fine node here
};

CoarseColumns transpose_weights(const CoarseSpace& coarse, int nodes) {
  CoarseColumns columns;
  columns.start.assign(static_cast<size_t>(coarse.coarse_nodes) + 1, 0);
  for (const CoarseWeight& w : coarse.weights) ++columns.start[static_cast<size_t>(w.vertex) + 1];
  for (size_t v = 0; v < static_cast<size_t>(coarse.coarse_nodes); ++v) columns.start[v + 1] += columns.start[v];
  columns.nodes.resize(coarse.weights.size());
  std::vector<int> next(columns.start.begin(), columns.start.end() - 1);
  for (int node = 0; node < nodes; ++node)
    for (int k = coarse.weight_start[static_cast<size_t>(node)]; k < coarse.weight_start[static_cast<size_t>(node) + 1]; ++k) {
      const CoarseWeight& w = coarse.weights[static_cast<size_t>(k)];
      columns.nodes[static_cast<size_t>(next[static_cast<size_t>(w.vertex)]++)] = {node, w.weight};
    }
  return columns;
}

}  // namespace

Eigen::SparseMatrix<double> galerkin_lower(const BlockMatrix& stiffness, const Eigen::VectorXd& masses,
                                           const std::vector<std::uint8_t>& fixed, double mass_coefficient,
                                           double stiffness_coefficient, const CoarseSpace& coarse) {
  const int nodes = stiffness.nodes(), vertices = coarse.coarse_nodes;
  if (masses.size() != nodes || (!fixed.empty() && static_cast<int>(fixed.size()) != nodes) ||
      static_cast<int>(coarse.weight_start.size()) != nodes + 1)
    throw std::invalid_argument("galerkin_lower: masses, fixed and the coarse space's weights need one entry per node");
  auto is_fixed = [&](int node) { return !fixed.empty() && fixed[static_cast<size_t>(node)] != 0; };
  const std::vector<int>& start = stiffness.row_start();
  const std::vector<int>& columns = stiffness.columns();
  const std::vector<Mat3>& blocks = stiffness.blocks();
  const CoarseColumns by_vertex = transpose_weights(coarse, nodes);

  BlockAccumulator fine(nodes), coarse_sums(vertices);
  Eigen::SparseMatrix<double> lower(3 * vertices, 3 * vertices);
  lower.reserve(static_cast<Eigen::Index>(coarse.weights.size()) * 9 * 8);
  for (int a = 0; a < vertices; ++a) {
    // T_ia = (A0 P)_ia = sum_j A0_ij w_ja, j increasing. Block column j of A0 is block row j
    // transposed (A0(3i+r, 3j+c) = stiffness_coefficient K_ji(c, r), plus the mass on the
    // diagonal), as BlockMatrix::system lays it out.
    fine.touched.clear();
    for (int s = by_vertex.start[static_cast<size_t>(a)]; s < by_vertex.start[static_cast<size_t>(a) + 1]; ++s) {
      const int j = by_vertex.nodes[static_cast<size_t>(s)].vertex;
      const double w = by_vertex.nodes[static_cast<size_t>(s)].weight;
      for (int k = start[static_cast<size_t>(j)]; k < start[static_cast<size_t>(j) + 1]; ++k) {
        const int i = columns[static_cast<size_t>(k)];
        if (is_fixed(i)) continue;
        Mat3 entry = stiffness_coefficient * blocks[static_cast<size_t>(k)].transpose();
        if (i == j) entry.diagonal().array() += mass_coefficient * masses[j];
        fine.add(i, a, entry * w);
      }
    }
    // C_ba = sum_i w_ib T_ia over i increasing, for b >= a (the lower triangle).
    std::sort(fine.touched.begin(), fine.touched.end());
    coarse_sums.touched.clear();
    for (int i : fine.touched) {
      const Mat3& t = fine.sums[static_cast<size_t>(i)];
      for (int k = coarse.weight_start[static_cast<size_t>(i)]; k < coarse.weight_start[static_cast<size_t>(i) + 1]; ++k) {
        const CoarseWeight& w = coarse.weights[static_cast<size_t>(k)];
        if (w.vertex >= a) coarse_sums.add(w.vertex, a, w.weight * t);
      }
    }
    std::sort(coarse_sums.touched.begin(), coarse_sums.touched.end());
    for (int c = 0; c < 3; ++c) {
      lower.startVec(3 * a + c);
      for (int b : coarse_sums.touched) {
        const Mat3& sum = coarse_sums.sums[static_cast<size_t>(b)];
        for (int r = b == a ? c : 0; r < 3; ++r) lower.insertBack(3 * b + r, 3 * a + c) = sum(r, c);
      }
    }
  }
  lower.finalize();
  return lower;
}

}  // namespace incise::physics
