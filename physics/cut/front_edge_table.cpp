#include "physics/cut/front_edge_table.hpp"

#include <algorithm>
#include <sstream>
#include <stdexcept>
#include <string>

namespace incise::physics::front {

EdgeTable edge_table(const std::vector<std::array<int, 3>>& triangles) {
  struct Use {
    int lower, higher, triangle, corner;
    bool forward;  // lower -> higher
  };
  std::vector<Use> uses;
  uses.reserve(3 * triangles.size());
  for (size_t t = 0; t < triangles.size(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = triangles[t][static_cast<size_t>(k)], b = triangles[t][static_cast<size_t>((k + 1) % 3)];
      uses.push_back({std::min(a, b), std::max(a, b), static_cast<int>(t), k, a < b});
    }
  std::sort(uses.begin(), uses.end(), [](const Use& l, const Use& r) {
    return l.lower != r.lower ? l.lower < r.lower : l.higher != r.higher ? l.higher < r.higher : l.forward > r.forward;
  });
  EdgeTable table;
  table.of_triangle.assign(triangles.size(), {-1, -1, -1});
  for (size_t u = 0; u < uses.size();) {
    size_t v = u;
    while (v < uses.size() && uses[v].lower == uses[u].lower && uses[v].higher == uses[u].higher) ++v;
    if (v - u != 2 || !uses[u].forward || uses[u + 1].forward) {
      std::ostringstream message;
      message << "FrontSurface: edge (" << uses[u].lower << ", " << uses[u].higher
              << ") is not used exactly once in each direction: the mesh must be closed and consistently oriented";
      throw std::invalid_argument(message.str());
    }
    const int e = static_cast<int>(table.ends.size());
    table.ends.push_back({uses[u].lower, uses[u].higher});
    table.triangles.push_back({uses[u].triangle, uses[u + 1].triangle});
    table.of_triangle[static_cast<size_t>(uses[u].triangle)][static_cast<size_t>(uses[u].corner)] = e;
    table.of_triangle[static_cast<size_t>(uses[u + 1].triangle)][static_cast<size_t>(uses[u + 1].corner)] = e;
    u = v;
  }
  return table;
}

}  // namespace incise::physics::front
