#include "physics/cut/surface_topology.hpp"

#include <algorithm>
#include <utility>

namespace incise::physics {

SurfaceTopology surface_topology(const std::vector<std::array<int, 3>>& triangles) {
  // Edges bucketed by their lower vertex (a counting sort, linear in the triangles), then
  // each bucket's few upper vertices counted.
  int vertices = 0;
  for (const auto& t : triangles)
    for (int v : t) vertices = std::max(vertices, v + 1);
  std::vector<int> start(static_cast<size_t>(vertices) + 1, 0);
  for (const auto& t : triangles)
    for (int e = 0; e < 3; ++e) ++start[static_cast<size_t>(std::min(t[e], t[(e + 1) % 3])) + 1];
  for (int v = 0; v < vertices; ++v) start[v + 1] += start[v];
  std::vector<int> upper(static_cast<size_t>(start[vertices]));
  std::vector<int> fill(start.begin(), start.end() - 1);
  for (const auto& t : triangles)
    for (int e = 0; e < 3; ++e) {
      const int a = t[e], b = t[(e + 1) % 3];
      upper[static_cast<size_t>(fill[std::min(a, b)]++)] = std::max(a, b);
    }
  SurfaceTopology topology;
  for (int v = 0; v < vertices; ++v) {
    const auto first = upper.begin() + start[v], last = upper.begin() + start[v + 1];
    std::sort(first, last);
    for (auto it = first; it != last;) {
      auto next = it;
      while (next != last && *next == *it) ++next;
      const auto count = next - it;
      topology.boundary_edges += count == 1 ? 1 : 0;
      topology.nonmanifold_edges += count > 2 ? 1 : 0;
      it = next;
    }
  }
  return topology;
}

SurfaceTopology surface_topology(const std::vector<std::array<int, 3>>& triangles, std::span<const std::uint8_t> among) {
  const auto in = [&](int v) { return v >= 0 && static_cast<size_t>(v) < among.size() && among[static_cast<size_t>(v)] != 0; };
  std::vector<std::pair<int, int>> edges;
  for (const auto& t : triangles)
    for (int e = 0; e < 3; ++e) {
      const int a = t[static_cast<size_t>(e)], b = t[static_cast<size_t>((e + 1) % 3)];
      if (in(a) && in(b)) edges.emplace_back(std::min(a, b), std::max(a, b));
    }
  std::sort(edges.begin(), edges.end());
  SurfaceTopology topology;
  for (size_t k = 0; k < edges.size();) {
    size_t next = k;
    while (next < edges.size() && edges[next] == edges[k]) ++next;
    topology.boundary_edges += next - k == 1 ? 1 : 0;
    topology.nonmanifold_edges += next - k > 2 ? 1 : 0;
    k = next;
  }
  return topology;
}

}  // namespace incise::physics
