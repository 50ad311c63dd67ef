#include "physics/solve/coarse_space.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <stdexcept>

namespace incise::physics {

namespace {

struct Corner {
  long long vertex;  // index in the grid
  double weight;
};

// The cut as the grid's vertices see it: a vertex's support splits where the segment from the
// vertex to a node crosses the cut.
struct Separation {
  const CutSeparation& cut;
  const Eigen::Map<const Eigen::Matrix3Xd>& points;
  Eigen::Vector3d origin;
  std::array<long long, 3> counts;
  double spacing;
  Eigen::Vector3d vertex(long long v) const {
    const long long x = v % counts[0], y = (v / counts[0]) % counts[1], z = v / (counts[0] * counts[1]);
    return origin + spacing * Eigen::Vector3d(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z));
  }
  Eigen::Vector3d node(int i) const { return points.col(i); }
  // Whether the cut lies between the vertex and the node: the segment between them, less a
  // millionth at either end, crosses it. A node (or vertex) on the cut itself is hidden from
  // nothing: the closed segment would hide it from every vertex, and a node midway between two
  // vertices would give each an identical column of that node alone.
  std::uint8_t hides(const Eigen::Vector3d& vertex, const Eigen::Vector3d& node) const {
    const Eigen::Vector3d d = node - vertex;
    return cut.crosses(vertex + 1e-6 * d, node - 1e-6 * d) ? 1 : 0;
  }
};

// Splits each grid vertex into the pieces of its support (the free nodes of weight > 0 on it)
// that `coupling`'s nonzero blocks connect inside that support: copy_of[node][c] is the copy
// node's corner c leans on (-1 where the node is fixed or the weight 0), copy_best per copy the
// largest weight a node gives it. With `separation`, the nodes the cut hides from the vertex
// are never joined to those it sees; copy_hidden marks the copies that only this made (hidden
// nodes the coupling alone joins to seen ones). Copies are numbered vertex by vertex, a
// vertex's pieces in the order of their first nodes, so an unsplit grid keeps its vertices'
// order.
void split_cut_vertices(const BlockMatrix& coupling, const std::vector<std::array<Corner, 8>>& corners, size_t vertices,
                        const std::vector<std::uint8_t>& fixed, const Separation* separation,
                        std::vector<std::array<int, 8>>& copy_of, std::vector<double>& copy_best,
                        std::vector<std::uint8_t>& copy_hidden) {
  const size_t nodes = corners.size();
  if (static_cast<size_t>(coupling.nodes()) != nodes)
    throw std::invalid_argument("make_coarse_space: the coupling has another node count than the rest positions");
  std::vector<int> start(vertices + 1, 0);
  auto on_vertex = [&](size_t node, int c) {
    return (fixed.empty() || fixed[node] == 0) && corners[node][static_cast<size_t>(c)].weight > 0;
  };
  for (size_t node = 0; node < nodes; ++node)
    for (int c = 0; c < 8; ++c)
      if (on_vertex(node, c)) ++start[static_cast<size_t>(corners[node][static_cast<size_t>(c)].vertex) + 1];
  for (size_t v = 0; v < vertices; ++v) start[v + 1] += start[v];
  std::vector<std::pair<int, int>> support(static_cast<size_t>(start.back()));  // (node, corner), nodes increasing
  {
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (size_t node = 0; node < nodes; ++node)
      for (int c = 0; c < 8; ++c)
        if (on_vertex(node, c))
          support[static_cast<size_t>(fill[static_cast<size_t>(corners[node][static_cast<size_t>(c)].vertex)]++)] = {
              static_cast<int>(node), c};
  }
  copy_of.assign(nodes, std::array<int, 8>{-1, -1, -1, -1, -1, -1, -1, -1});
  copy_best.clear();
  copy_hidden.clear();
  // parent: the pieces (coupled, and alike seen or hidden); joined: coupled alone.
  std::vector<int> slot(nodes, -1), parent, joined, label;
  std::vector<std::uint8_t> hidden, joined_seen;
  auto find = [](std::vector<int>& p, int k) {
    while (p[static_cast<size_t>(k)] != k) k = p[static_cast<size_t>(k)] = p[static_cast<size_t>(p[static_cast<size_t>(k)])];
    return k;
  };
  auto unite = [&](std::vector<int>& p, int k, int other) {
    const int a = find(p, k), c = find(p, other);
    if (a != c) p[static_cast<size_t>(std::max(a, c))] = std::min(a, c);
  };
  auto root = [&](int k) { return find(parent, k); };
  const std::vector<int>& row_start = coupling.row_start();
  const std::vector<int>& columns = coupling.columns();
  const std::vector<Mat3>& blocks = coupling.blocks();
  for (size_t v = 0; v < vertices; ++v) {
    const int first = start[v], count = start[v + 1] - start[v];
    if (count == 0) continue;
    parent.resize(static_cast<size_t>(count));
    joined.resize(static_cast<size_t>(count));
    for (int k = 0; k < count; ++k) {
      parent[static_cast<size_t>(k)] = joined[static_cast<size_t>(k)] = k;
      slot[static_cast<size_t>(support[static_cast<size_t>(first + k)].first)] = k;
    }
    hidden.assign(static_cast<size_t>(count), 0);
    if (separation) {
      // The support lies within H of its vertex along each axis.
      const Eigen::Vector3d at = separation->vertex(static_cast<long long>(v));
      const Eigen::Vector3d reach = Eigen::Vector3d::Constant(separation->spacing);
      if (separation->cut.near(at - reach, at + reach))
        for (int k = 0; k < count; ++k)
          hidden[static_cast<size_t>(k)] = separation->hides(at, separation->node(support[static_cast<size_t>(first + k)].first));
    }
    for (int k = 0; k < count; ++k) {
      const int node = support[static_cast<size_t>(first + k)].first;
      for (int b = row_start[static_cast<size_t>(node)]; b < row_start[static_cast<size_t>(node) + 1]; ++b) {
        const int other = slot[static_cast<size_t>(columns[static_cast<size_t>(b)])];
        if (other < 0 || !(blocks[static_cast<size_t>(b)].array() != 0).any()) continue;
        unite(joined, k, other);
        if (hidden[static_cast<size_t>(k)] == hidden[static_cast<size_t>(other)]) unite(parent, k, other);
      }
    }
    // A hidden piece that the coupling alone would have left joined to nodes the vertex sees.
    joined_seen.assign(static_cast<size_t>(count), 0);
    for (int k = 0; k < count; ++k)
      if (!hidden[static_cast<size_t>(k)]) joined_seen[static_cast<size_t>(find(joined, k))] = 1;
    label.assign(static_cast<size_t>(count), -1);
    for (int k = 0; k < count; ++k) {
      const auto [node, c] = support[static_cast<size_t>(first + k)];
      int& copy = label[static_cast<size_t>(root(k))];
      if (copy < 0) {
        copy = static_cast<int>(copy_best.size());
        copy_best.push_back(0.0);
        copy_hidden.push_back(hidden[static_cast<size_t>(k)] && joined_seen[static_cast<size_t>(find(joined, k))] ? 1 : 0);
      }
      copy_of[static_cast<size_t>(node)][static_cast<size_t>(c)] = copy;
      copy_best[static_cast<size_t>(copy)] = std::max(copy_best[static_cast<size_t>(copy)], corners[static_cast<size_t>(node)][static_cast<size_t>(c)].weight);
      slot[static_cast<size_t>(node)] = -1;
    }
  }
}

}  // namespace

CoarseSpace make_coarse_space(const Eigen::VectorXd& rest, double spacing, const std::vector<std::uint8_t>& fixed,
                              const BlockMatrix* coupling, const CutSeparation* separation) {
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
  // A vertex whose free nodes fall into pieces that no stiffness couples (a cut through its
  // support) becomes one vertex per piece; each node leans on its own piece's copy.
  std::vector<std::array<int, 8>> copy_of;
  std::vector<double> copy_best;
  std::vector<std::uint8_t> copy_hidden;
  std::optional<Separation> seen;
  if (separation && *separation) seen.emplace(Separation{*separation, points, origin, counts, spacing});
  if (coupling) split_cut_vertices(*coupling, corners, best.size(), fixed, seen ? &*seen : nullptr, copy_of, copy_best, copy_hidden);
  // Keep the vertices (or copies) some free node leans on with half its weight or more; number
  // them in the grid's order (a vertex's copies in the order of their first nodes).
  const std::vector<double>& kept_best = coupling ? copy_best : best;
  std::vector<int> index(kept_best.size(), -1);
  int kept = 0;
  // A copy that only the cut's visibility made needs a node of more than half its weight: that
  // node can lean so on no other column, so no two such copies share their pivot (two copies of
  // one node midway between two vertices, each holding half of it, would be one column twice).
  for (size_t v = 0; v < kept_best.size(); ++v)
    if (kept_best[v] > 0.5 || (kept_best[v] == 0.5 && !(coupling && copy_hidden[v]))) index[v] = kept++;
  auto column_of = [&](Eigen::Index node, int c) {
    const long long slot = coupling ? copy_of[static_cast<size_t>(node)][static_cast<size_t>(c)]
                                    : corners[static_cast<size_t>(node)][static_cast<size_t>(c)].vertex;
    return slot < 0 ? -1 : index[static_cast<size_t>(slot)];
  };

  CoarseSpace space;
  space.weight_start.assign(static_cast<size_t>(nodes) + 1, 0);
  space.weights.reserve(static_cast<size_t>(nodes) * 8);
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<size_t>(nodes) * 24);
  for (Eigen::Index node = 0; node < nodes; ++node) {
    space.weight_start[static_cast<size_t>(node)] = static_cast<int>(space.weights.size());
    if (is_fixed(node)) continue;
    double sum = 0;
    for (int c = 0; c < 8; ++c)
      if (column_of(node, c) >= 0) sum += corners[static_cast<size_t>(node)][static_cast<size_t>(c)].weight;
    if (!(sum > 1e-9)) continue;  // a node no kept vertex reaches: the fine smoother's alone
    // The corners come in increasing vertex order (x fastest), and so do their columns.
    for (int c = 0; c < 8; ++c) {
      const Corner& corner = corners[static_cast<size_t>(node)][static_cast<size_t>(c)];
      const int column = column_of(node, c);
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
