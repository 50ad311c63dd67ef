#include "physics/cut/front_mapping.hpp"

#include "physics/core/mix.hpp"

#include "physics/efg/mls.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

namespace incise::physics {
namespace {

[[noreturn]] void fail(const std::string& message) { throw std::invalid_argument("map_front_surface: " + message); }

// The triangles to look at for the vertices flagged in `only`: `subset` when given (every
// triangle with a flagged corner must be in it, in increasing order), else all of them.
template <typename Visit>
void for_each_triangle(const std::vector<std::array<int, 3>>& triangles, std::span<const int> subset, bool all, const Visit& visit) {
  if (all) {
    for (const auto& t : triangles) visit(t);
  } else {
    for (const int t : subset) visit(triangles[static_cast<size_t>(t)]);
  }
}

// Per vertex, the area-weighted normal: the sum of its triangles' cross products (each twice
// the triangle's area along its unit normal), not normalised; only the vertices flagged in
// `only` (the others' entries are left unset), from the triangles of `subset` (see
// for_each_triangle; `all` for every triangle).
std::vector<Vec3> area_weighted_normals(const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles,
                                        const std::vector<std::uint8_t>& only, std::span<const int> listed,
                                        std::span<const int> subset, bool all) {
  std::vector<Vec3> normals(vertices.size());  // not filled: only the listed vertices' are read
  for (const int v : listed) normals[static_cast<size_t>(v)].setZero();
  for_each_triangle(triangles, subset, all, [&](const std::array<int, 3>& t) {
    if (!only[static_cast<size_t>(t[0])] && !only[static_cast<size_t>(t[1])] && !only[static_cast<size_t>(t[2])]) return;
    const Vec3& a = vertices[static_cast<size_t>(t[0])];
    const Vec3 n = (vertices[static_cast<size_t>(t[1])] - a).cross(vertices[static_cast<size_t>(t[2])] - a);
    for (const int v : t)
      if (only[static_cast<size_t>(v)]) normals[static_cast<size_t>(v)] += n;
  });
  return normals;
}

// Per vertex, the angle-weighted normal (each triangle's unit normal times its angle at the
// vertex, not normalised): the pseudo-normal that points into the body at a rim, whatever the
// size of the triangles on either side.
// Only the vertices flagged in `only` (listed in `listed`) are formed, the others' entries are
// left unset (the angles' atan2 is most of the cost), from the triangles of `subset` (see
// for_each_triangle).
std::vector<Vec3> angle_weighted_normals(const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles,
                                         const std::vector<std::uint8_t>& only, std::span<const int> listed,
                                         std::span<const int> subset, bool all) {
  std::vector<Vec3> normals(vertices.size());
  for (const int v : listed) normals[static_cast<size_t>(v)].setZero();
  for_each_triangle(triangles, subset, all, [&](const std::array<int, 3>& t) {
    if (!only[static_cast<size_t>(t[0])] && !only[static_cast<size_t>(t[1])] && !only[static_cast<size_t>(t[2])]) return;
    const Vec3 n = (vertices[static_cast<size_t>(t[1])] - vertices[static_cast<size_t>(t[0])])
                       .cross(vertices[static_cast<size_t>(t[2])] - vertices[static_cast<size_t>(t[0])]);
    const double length = n.norm();
    if (!(length > 0)) return;
    for (int i = 0; i < 3; ++i) {
      if (!only[static_cast<size_t>(t[i])]) continue;
      const Vec3& x = vertices[static_cast<size_t>(t[i])];
      const Vec3 u = vertices[static_cast<size_t>(t[(i + 1) % 3])] - x, w = vertices[static_cast<size_t>(t[(i + 2) % 3])] - x;
      normals[static_cast<size_t>(t[i])] += std::atan2(u.cross(w).norm(), u.dot(w)) / length * n;
    }
  });
  return normals;
}

// One-ring neighbours of the listed vertices (increasing; each shares a triangle with them),
// compressed rows in the order of the list, from the triangles of `subset` (see
// for_each_triangle).
struct OneRing {
  std::vector<int> start;  // position in listed -> first entry; start[size] = end
  std::vector<int> neighbours;

  OneRing(std::span<const int> listed, const std::vector<std::array<int, 3>>& triangles,
          const std::vector<std::uint8_t>& only, std::span<const int> subset, bool all) {
    const size_t count = listed.size();
    const auto position = [&](int v) { return static_cast<size_t>(std::lower_bound(listed.begin(), listed.end(), v) - listed.begin()); };
    start.assign(count + 1, 0);
    for_each_triangle(triangles, subset, all, [&](const std::array<int, 3>& t) {
      for (const int v : t)
        if (only[static_cast<size_t>(v)]) start[position(v) + 1] += 2;
    });
    for (size_t k = 0; k < count; ++k) start[k + 1] += start[k];
    std::vector<int> fill(start.begin(), start.end() - 1);
    std::vector<int> all_entries(static_cast<size_t>(start.back()));
    for_each_triangle(triangles, subset, all, [&](const std::array<int, 3>& t) {
      for (int i = 0; i < 3; ++i) {
        if (!only[static_cast<size_t>(t[i])]) continue;
        const size_t k = position(t[i]);
        all_entries[static_cast<size_t>(fill[k]++)] = t[(i + 1) % 3];
        all_entries[static_cast<size_t>(fill[k]++)] = t[(i + 2) % 3];
      }
    });
    // Each vertex's list sorted, without repeats or itself, compacted in place.
    size_t out = 0;
    for (size_t k = 0; k < count; ++k) {
      const auto first = all_entries.begin() + start[k], last = all_entries.begin() + start[k + 1];
      std::sort(first, last);
      start[k] = static_cast<int>(out);
      for (auto it = first; it != last; ++it)
        if (*it != listed[k] && (it == first || *it != *(it - 1))) all_entries[out++] = *it;
    }
    start[count] = static_cast<int>(out);
    all_entries.resize(out);
    neighbours.swap(all_entries);
  }
  // The neighbours of the k-th listed vertex.
  std::span<const int> of_listed(size_t k) const {
    return {neighbours.data() + start[k], neighbours.data() + start[k + 1]};
  }
};

bool share_a_particle(const CorotationalEfg& model, int e, int f) {
  const int stride = model.row_stride();
  const int* a = model.neighbours().data() + static_cast<size_t>(e) * stride;
  const int* b = model.neighbours().data() + static_cast<size_t>(f) * stride;
  const int la = model.row_lengths()[static_cast<size_t>(e)], lb = model.row_lengths()[static_cast<size_t>(f)];
  for (int i = 0; i < la; ++i)
    for (int j = 0; j < lb; ++j)
      if (a[i] == b[j]) return true;
  return false;
}

bool flagged(std::span<const std::uint8_t> flags, int v) { return static_cast<size_t>(v) < flags.size() && flags[static_cast<size_t>(v)] != 0; }

// `skip_near_p`: a triangle whose plane passes within that distance of p is not crossed (p
// lies on it, up to rounding).
bool segment_crosses_triangle(const Vec3& p, const Vec3& q, const std::array<Vec3, 3>& t, double skip_near_p = 0) {
  const Vec3 m = (t[1] - t[0]).cross(t[2] - t[0]);
  const double sp = (p - t[0]).dot(m), sq = (q - t[0]).dot(m);
  if (!((sp < 0 && sq > 0) || (sp > 0 && sq < 0))) return false;
  if (skip_near_p > 0 && std::abs(sp) <= skip_near_p * m.norm()) return false;
  const Vec3 x = p + (sp / (sp - sq)) * (q - p);
  for (int i = 0; i < 3; ++i) {
    const Vec3& a = t[static_cast<size_t>(i)];
    const Vec3& b = t[static_cast<size_t>((i + 1) % 3)];
    if ((b - a).cross(x - a).dot(m) < 0) return false;
  }
  return true;
}

// The vertex moved inward by `inset` along its angle-weighted normal (not moved without one),
// by less where that would cross a cut face (a cut passing nearer the vertex than the inset:
// from across it every point on the vertex's side would look hidden): halved until it does
// not, down to the vertex itself.
// A vertex on a cut face (`on_face`) is always pulled in by the full inset: its own face's
// neighbours at rest are wavy by more than any tolerance would allow for.
Vec3 inset_point(const Vec3& vertex, const Vec3& normal, double inset, const CutFaceIndex& faces, bool on_face) {
  const double length = normal.norm();
  if (!(length > 0)) return vertex;
  if (on_face) return vertex - (inset / length) * normal;
  for (int k = 0; k < 16; ++k, inset *= 0.5) {
    const Vec3 p = vertex - (inset / length) * normal;
    // The faces through the vertex itself (its own, on a cut face) are not in the way.
    if (faces.crossings(vertex, p, 1e-6 * inset) == 0) return p;
  }
  return vertex;
}

class Mapper {
 public:
  Mapper(const CorotationalEfg& model, const std::vector<Vec3>& vertices, const std::vector<Vec3>& normals,
         const VertexPlanes& planes, const FrontVisibility* visibility,
         const std::vector<Vec3>* inward, const ElementCubes& bins)
      : model_(model), vertices_(vertices), normals_(normals), planes_(planes), visibility_(visibility), inward_(inward), bins_(bins) {}

  // The element for vertex v, given the elements its one-ring neighbours are mapped to (for
  // criterion 1). Sets `relaxed` if no candidate met all three criteria, and `seen` whether the
  // one returned meets the visibility criterion.
  int choose(int v, std::span<const int> neighbour_elements, bool& relaxed, bool& seen) {
    const Vec3& vertex = vertices_[static_cast<size_t>(v)];
    const GridCell cube = bins_.grid.cells.unclamped_cell_of(vertex);  // the lattice's: first is 0
    const double a = model_.spacing();
    candidates_.clear();
    size_t checked = 0;
    relaxed = false;
    seen = true;
    // Ring by ring, nearest first: after ring r the candidates nearer than the bound below
    // are final (a farther ring holds none nearer), so they are checked in order as soon as
    // they are.
    // Every point outside the block of cubes within r rings is at least r a + slack away,
    // slack the vertex's distance to the nearest face of its own cube.
    double slack = a;
    for (int axis = 0; axis < 3; ++axis) {
      const double offset = vertex[axis] - (model_.grid_origin()[axis] + static_cast<double>(cube[axis]) * a);
      slack = std::min({slack, offset, a - offset});
    }
    slack = std::max(slack, 0.0);
    for (long long r = 0; r <= front_mapping_reach_rings; ++r) {
      // The ring's candidates are sorted (distance, then index): the shell's visit order does
      // not matter.
      bins_.grid.visit_shell(cube, r, [&](int e) {
        candidates_.emplace_back((model_.element_centres()[static_cast<size_t>(e)] - vertex).squaredNorm(), e);
      });
      std::sort(candidates_.begin() + static_cast<std::ptrdiff_t>(checked), candidates_.end());
      const double bound = static_cast<double>(r) * a + slack;
      for (; checked < candidates_.size(); ++checked) {
        const auto [distance, e] = candidates_[checked];
        if (r < front_mapping_reach_rings && !(distance < bound * bound)) break;
        if (below_planes(v, e) && below_tangent(v, e) && shares_with_neighbours(e, neighbour_elements) && visible(v, e)) return e;
      }
    }
    // Relaxed (§7.1.2), in the documented order, over every candidate within reach.
    relaxed = true;
    for (const auto& [distance, e] : candidates_)
      if (below_planes(v, e) && below_tangent(v, e) && visible(v, e)) return e;
    for (const auto& [distance, e] : candidates_)
      if (below_planes(v, e) && visible(v, e)) return e;
    if (visibility_ != nullptr) {
      for (const auto& [distance, e] : candidates_)
        if (visible(v, e)) return e;
      seen = false;
      for (const auto& [distance, e] : candidates_)
        if (below_planes(v, e)) return e;
    }
    if (!candidates_.empty()) return candidates_.front().second;
    int best = -1;
    double best_distance = 0;
    for (int e = 0; e < model_.element_count(); ++e) {
      if (!model_.element_active(e)) continue;
      const double d = (model_.element_centres()[static_cast<size_t>(e)] - vertex).squaredNorm();
      if (best < 0 || d < best_distance) best = e, best_distance = d;
    }
    if (best < 0) throw std::runtime_error("map_front_surface: the model has no active element for vertex " + std::to_string(v));
    return best;
  }

  // Writes v's row: the MLS weights of e's neighbourhood at the vertex.
  void write_row(int v, int e, SurfaceEmbedding& embedding) {
    const Vec3& vertex = vertices_[static_cast<size_t>(v)];
    const size_t base = static_cast<size_t>(e) * model_.row_stride();
    const int length = model_.row_lengths()[static_cast<size_t>(e)];
    positions_.clear();
    double farthest = 0;
    for (int k = 0; k < length; ++k) {
      positions_.push_back(model_.rest_positions().segment<3>(3 * static_cast<Eigen::Index>(model_.neighbours()[base + k])));
      farthest = std::max(farthest, (positions_.back() - vertex).norm());
    }
    const double support = std::max(model_.element_supports()[static_cast<size_t>(e)], model_.settings().support_factor * farthest);
    const size_t row = static_cast<size_t>(v) * embedding.stride;
    if (!mls_shape_functions(vertex, positions_, support, model_.spacing(), std::span<double>(&embedding.weights[row], length), {})) {
      throw std::runtime_error("map_front_surface: no MLS weights for vertex " + std::to_string(v) + " on element " +
                               std::to_string(e));
    }
    std::fill(embedding.weights.begin() + static_cast<std::ptrdiff_t>(row + length),
              embedding.weights.begin() + static_cast<std::ptrdiff_t>(row + embedding.stride), 0.0);
    std::fill(embedding.particles.begin() + static_cast<std::ptrdiff_t>(row),
              embedding.particles.begin() + static_cast<std::ptrdiff_t>(row + embedding.stride), 0);
    std::copy_n(model_.neighbours().begin() + static_cast<std::ptrdiff_t>(base), length,
                embedding.particles.begin() + static_cast<std::ptrdiff_t>(row));
    embedding.elements[static_cast<size_t>(v)] = e;
    embedding.row_lengths[static_cast<size_t>(v)] = length;
  }

 private:
  bool below_tangent(int v, int e) const {
    const Vec3& n = normals_[static_cast<size_t>(v)];
    return (model_.element_centres()[static_cast<size_t>(e)] - vertices_[static_cast<size_t>(v)]).dot(n) <= 0;
  }
  bool below_planes(int v, int e) const {
    if (static_cast<size_t>(v) >= planes_.size()) return true;
    const Vec3& x = model_.element_centres()[static_cast<size_t>(e)];
    for (const ConstraintPlane& plane : planes_[static_cast<size_t>(v)])
      if ((x - plane.point).dot(plane.normal) > 0) return false;
    return true;
  }
  bool visible(int v, int e) const {
    if (visibility_ == nullptr) return true;
    const Vec3& point = model_.element_centres()[static_cast<size_t>(e)];
    if (visibility_->inside != nullptr &&
        !CorotationalEfg::sees_through_body(*visibility_->inside, vertices_[static_cast<size_t>(v)], point, model_.spacing()))
      return false;
    if (visibility_->faces == nullptr || flagged(visibility_->exempt, v)) return true;
    return visibility_->faces->crossings((*inward_)[static_cast<size_t>(v)], point) % 2 == 0;
  }
  bool shares_with_neighbours(int e, std::span<const int> neighbour_elements) const {
    for (const int f : neighbour_elements)
      if (!share_a_particle(model_, e, f)) return false;
    return true;
  }

  const CorotationalEfg& model_;
  const std::vector<Vec3>& vertices_;
  const std::vector<Vec3>& normals_;
  const VertexPlanes& planes_;
  const FrontVisibility* visibility_;
  const std::vector<Vec3>* inward_;  // per vertex, its start point for visibility
  const ElementCubes& bins_;  // each rest integration point lies in its cube, so a point in the
                              // cube r rings from the vertex's is at least (r - 1) a away
  std::vector<std::pair<double, int>> candidates_;
  std::vector<Vec3> positions_;
};

void check_surface(const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles,
                   const std::string& caller) {
  const auto fail = [&](const std::string& message) { throw std::invalid_argument(caller + ": " + message); };
  const int n = static_cast<int>(vertices.size());
  // One pass each without branches (this runs on every cut event), then the culprit looked
  // for only when there is one: x - x is 0 for a finite x and NaN otherwise.
  double sum = 0;
  for (const Vec3& x : vertices) sum += (x - x).sum();
  if (sum != 0)
    for (int v = 0; v < n; ++v)
      if (!vertices[static_cast<size_t>(v)].allFinite()) fail("vertex " + std::to_string(v) + " is not finite");
  unsigned outside = 0;
  for (const auto& t : triangles)
    for (const int v : t) outside |= static_cast<unsigned>(v < 0) | static_cast<unsigned>(v >= n);
  if (outside != 0)
    for (size_t t = 0; t < triangles.size(); ++t)
      for (const int v : triangles[t])
        if (v < 0 || v >= n) fail("triangle " + std::to_string(t) + " has vertex " + std::to_string(v) + ", out of range [0, " + std::to_string(n) + ")");
}

// The triangles of the listed vertices (increasing, each once) from `around`, checked as
// check_surface checks the whole surface: the listed vertices and these triangles' corners
// finite, the triangles and their corners in range. Without `around`, check_surface and an
// empty list (every triangle is looked at).
std::vector<int> triangles_of(const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles,
                              std::span<const int> listed, const TrianglesAround* around, const std::string& caller) {
  std::vector<int> subset;
  if (around == nullptr) {
    check_surface(vertices, triangles, caller);
    return subset;
  }
  const auto fail = [&](const std::string& message) { throw std::invalid_argument(caller + ": " + message); };
  const int n = static_cast<int>(vertices.size());
  const auto finite_vertex = [&](int v) {
    if (v < 0 || v >= n) return false;
    if (!vertices[static_cast<size_t>(v)].allFinite()) fail("vertex " + std::to_string(v) + " is not finite");
    return true;
  };
  std::vector<int> found;
  for (const int v : listed) {
    if (!finite_vertex(v)) continue;  // the caller names a listed vertex out of range
    found.clear();
    (*around)(v, found);
    subset.insert(subset.end(), found.begin(), found.end());
  }
  std::sort(subset.begin(), subset.end());
  subset.erase(std::unique(subset.begin(), subset.end()), subset.end());
  for (const int t : subset) {
    if (t < 0 || static_cast<size_t>(t) >= triangles.size())
      fail("triangle " + std::to_string(t) + " is out of range [0, " + std::to_string(triangles.size()) + ")");
    for (const int v : triangles[static_cast<size_t>(t)])
      if (!finite_vertex(v)) fail("triangle " + std::to_string(t) + " has vertex " + std::to_string(v) + ", out of range [0, " + std::to_string(n) + ")");
  }
  return subset;
}

}  // namespace

void ElementCubes::update(const CorotationalEfg& from) {
  if (model == &from && deactivated == from.deactivated_elements()) return;
  model = &from;
  deactivated = from.deactivated_elements();
  const auto& cubes = from.element_grid_coordinates();
  GridCells frame;
  frame.origin = from.grid_origin();
  frame.cell = from.spacing();
  for (const auto& c : cubes)
    for (int axis = 0; axis < 3; ++axis) frame.count[axis] = std::max<long long>(frame.count[axis], c[axis] + 1);
  grid.build(frame, from.element_count(), [&](int e, GridCell& first, GridCell& last) {
    const auto& c = cubes[static_cast<size_t>(e)];
    first = last = {c[0], c[1], c[2]};
    return from.element_active(e);
  });
}

void fit_rows(SurfaceEmbedding& embedding, int vertices, int stride) {
  // A list that must grow gets room for a quarter more: a cut adds vertices at every event,
  // and moving these lists (tens of MB at organ resolution) costs milliseconds.
  const auto fit = [](auto& list, size_t size) {
    if (size > list.capacity()) list.reserve(size + size / 4);
    list.resize(size, {});
  };
  if (embedding.stride != stride && !embedding.elements.empty()) {
    const size_t rows = embedding.elements.size(), wanted = std::max(rows, static_cast<size_t>(std::max(vertices, 0)));
    std::vector<int> particles;
    std::vector<double> weights;
    particles.reserve((wanted + wanted / 4) * static_cast<size_t>(stride));
    weights.reserve(particles.capacity());
    particles.resize(rows * static_cast<size_t>(stride), 0);
    weights.resize(particles.size(), 0.0);
    for (size_t v = 0; v < rows; ++v) {
      const int length = std::min(embedding.row_lengths[v], stride);
      std::copy_n(embedding.particles.begin() + static_cast<std::ptrdiff_t>(v * embedding.stride), length,
                  particles.begin() + static_cast<std::ptrdiff_t>(v * stride));
      std::copy_n(embedding.weights.begin() + static_cast<std::ptrdiff_t>(v * embedding.stride), length,
                  weights.begin() + static_cast<std::ptrdiff_t>(v * stride));
    }
    embedding.particles.swap(particles);
    embedding.weights.swap(weights);
  }
  embedding.stride = stride;
  fit(embedding.elements, static_cast<size_t>(vertices));
  fit(embedding.row_lengths, static_cast<size_t>(vertices));
  fit(embedding.particles, static_cast<size_t>(vertices) * stride);
  fit(embedding.weights, static_cast<size_t>(vertices) * stride);
}

void map_front_surface(const CorotationalEfg& model, const std::vector<Vec3>& vertices,
                       const std::vector<std::array<int, 3>>& triangles,
                       const VertexPlanes& planes, std::span<const int> remap,
                       SurfaceEmbedding& embedding, FrontMappingReport& report, const FrontVisibility* visibility,
                       const TrianglesAround* around, ElementCubes* cubes) {
  const int n = static_cast<int>(vertices.size());
  if (visibility != nullptr && visibility->faces == nullptr && visibility->inside == nullptr)
    fail("the visibility criterion has neither cut faces nor an inside test");
  if (visibility != nullptr && !(visibility->inset >= 0 && std::isfinite(visibility->inset)))
    fail("the visibility criterion's inset must be finite and not negative");
  const int rows = embedding.vertex_count();
  if (rows > n) fail("the embedding has " + std::to_string(rows) + " rows for " + std::to_string(n) + " vertices");
  for (size_t k = 0; k < remap.size(); ++k) {
    const int v = remap[k];
    if (v < 0 || v >= n) fail("remap entry " + std::to_string(k) + ": vertex " + std::to_string(v) + " out of range [0, " + std::to_string(n) + ")");
    if (k > 0 && v <= remap[k - 1]) fail("remap entry " + std::to_string(k) + ": vertex " + std::to_string(v) + " does not follow vertex " + std::to_string(remap[k - 1]) + " (the list must increase)");
  }
  // Increasing, so the indices at or above the row count are a suffix; all must be there.
  const auto first_new = std::lower_bound(remap.begin(), remap.end(), rows);
  if (static_cast<int>(remap.end() - first_new) != n - rows) {
    int missing = rows;
    for (auto it = first_new; it != remap.end() && *it == missing; ++it) ++missing;
    fail("vertex " + std::to_string(missing) + " has no row and is not in the remap list");
  }
  // Only the listed vertices' planes, triangles and one-rings are read, and their neighbours'
  // rows (whose elements are checked where they are read).
  for (const int v : remap)
    if (static_cast<size_t>(v) < planes.size())
      for (const ConstraintPlane& plane : planes[static_cast<size_t>(v)])
        if (!plane.point.allFinite() || !plane.normal.allFinite()) fail("a constraint plane of vertex " + std::to_string(v) + " is not finite");
  const std::vector<int> subset = triangles_of(vertices, triangles, remap, around, "map_front_surface");
  const bool all = around == nullptr;
  std::vector<std::uint8_t> wanted(vertices.size(), 0);
  for (const int v : remap) wanted[static_cast<size_t>(v)] = 1;
  const OneRing ring(remap, triangles, wanted, subset, all);
  for (size_t k = 0; k < remap.size(); ++k)
    for (const int u : ring.of_listed(k)) {
      if (u >= rows || wanted[static_cast<size_t>(u)]) continue;
      const int e = embedding.elements[static_cast<size_t>(u)];
      if (e < 0 || e >= model.element_count()) fail("vertex " + std::to_string(u) + " is mapped to element " + std::to_string(e) + ", out of range");
    }

  fit_rows(embedding, n, std::max(embedding.stride, model.row_stride()));
  const std::vector<Vec3> normals = area_weighted_normals(vertices, triangles, wanted, remap, subset, all);
  std::vector<Vec3> inward;
  if (visibility != nullptr && visibility->faces != nullptr) {
    const std::vector<Vec3> pseudo = angle_weighted_normals(vertices, triangles, wanted, remap, subset, all);
    inward.resize(vertices.size());
    for (const int v : remap) inward[static_cast<size_t>(v)] = inset_point(vertices[static_cast<size_t>(v)], pseudo[static_cast<size_t>(v)], visibility->inset, *visibility->faces,
                                                             flagged(visibility->on_face, v));
  }
  ElementCubes own;
  if (cubes == nullptr) cubes = &own;
  cubes->update(model);
  Mapper mapper(model, vertices, normals, planes, visibility, &inward, *cubes);

  // A neighbour that is listed is read at its first-pass element (second pass only), the
  // others at their row's.
  std::vector<int> first(remap.size());
  std::vector<int> neighbour_elements;
  const auto gather = [&](size_t k, bool second_pass) {
    neighbour_elements.clear();
    for (const int u : ring.of_listed(k)) {
      // The crack front's vertices belong to neither side: criterion 1 does not follow them.
      if (visibility != nullptr && flagged(visibility->exempt, u)) continue;
      if (!wanted[static_cast<size_t>(u)]) {
        neighbour_elements.push_back(embedding.elements[static_cast<size_t>(u)]);
      } else if (second_pass) {
        neighbour_elements.push_back(first[static_cast<size_t>(std::lower_bound(remap.begin(), remap.end(), u) - remap.begin())]);
      }
    }
    std::sort(neighbour_elements.begin(), neighbour_elements.end());
    neighbour_elements.erase(std::unique(neighbour_elements.begin(), neighbour_elements.end()), neighbour_elements.end());
  };
  bool relaxed = false, seen = true;
  // First pass: only the neighbours not being remapped, whose rows are as given.
  std::vector<std::uint8_t> first_relaxed(remap.size(), 0);
  for (size_t k = 0; k < remap.size(); ++k) {
    gather(k, false);
    first[k] = mapper.choose(remap[k], neighbour_elements, relaxed, seen);
    first_relaxed[k] = relaxed ? 1 : 0;
  }
  // Second pass: every neighbour, the remapped ones at their first-pass element (a snapshot:
  // nothing this pass writes is read by it).
  // The second pass only adds constraints (criterion 1 against more neighbours), so a
  // first-pass point that met all three criteria and meets the new ones is still the first
  // valid candidate in the same order: it is kept without a new search.
  for (size_t k = 0; k < remap.size(); ++k) {
    gather(k, true);
    int e = first[k];
    seen = true;  // a first-pass point kept met every criterion, visibility among them
    if (first_relaxed[k] || !std::all_of(neighbour_elements.begin(), neighbour_elements.end(),
                                         [&](int f) { return share_a_particle(model, e, f); })) {
      e = mapper.choose(remap[k], neighbour_elements, relaxed, seen);
      if (relaxed) ++report.relaxed_fallbacks;
    }
    mapper.write_row(remap[k], e, embedding);
    ++report.mapped;
    if (visibility != nullptr && visibility->inside != nullptr && !seen) ++report.unseen;
  }
}

CutFaceIndex::CutFaceIndex(const CorotationalEfg& model, std::vector<std::array<Vec3, 3>> faces) : faces_(std::move(faces)) {
  // The faces' boxes, and the box of those to bin (faces over more than large_cells cells of
  // side a are kept apart); the cells grow until the grid over it is small enough (a cut's
  // faces span a few hundred cells of side a).
  GridCells lattice;
  lattice.origin = model.grid_origin();
  lattice.cell = model.spacing();
  Vec3 lo_all = Vec3::Constant(1e300), hi_all = Vec3::Constant(-1e300);
  boxes_.reserve(faces_.size());
  std::vector<std::uint8_t> large(faces_.size(), 0);
  for (size_t t = 0; t < faces_.size(); ++t) {
    const auto& tri = faces_[t];
    const Vec3 lo = tri[0].cwiseMin(tri[1]).cwiseMin(tri[2]), hi = tri[0].cwiseMax(tri[1]).cwiseMax(tri[2]);
    boxes_.push_back({lo, hi});
    GridCells own = lattice;
    own.cover(lo, hi);
    large[t] = static_cast<double>(own.count[0]) * static_cast<double>(own.count[1]) * static_cast<double>(own.count[2]) >
               static_cast<double>(large_cells);
    if (!large[t]) lo_all = lo_all.cwiseMin(lo), hi_all = hi_all.cwiseMax(hi);
  }
  const bool any_binned = std::find(large.begin(), large.end(), 0) != large.end();
  const GridCells frame = any_binned ? GridCells::fit(lattice.origin, lo_all, hi_all, lattice.cell, most_cells) : GridCells{};
  grid_.build(frame, static_cast<int>(faces_.size()), [&](int t, GridCell& from, GridCell& to) {
    if (large[static_cast<size_t>(t)]) return 2;  // tested against every segment
    frame.range(boxes_[static_cast<size_t>(t)][0], boxes_[static_cast<size_t>(t)][1], from, to);
    return 1;
  });
}

int CutFaceIndex::crossings(const Vec3& p, const Vec3& q, double skip_near_p) const {
  int count = 0;
  // A face crossed holds the crossing point, which lies in the segment's box: faces whose box
  // misses it (by more than roundoff) are not tested.
  const Vec3 lo = p.cwiseMin(q).array() - box_slack, hi = p.cwiseMax(q).array() + box_slack;
  grid_.visit_box_once(p.cwiseMin(q), p.cwiseMax(q), [&](int t) {
    const auto& box = boxes_[static_cast<size_t>(t)];
    if ((box[0].array() > hi.array()).any() || (box[1].array() < lo.array()).any()) return;
    if (segment_crosses_triangle(p, q, faces_[static_cast<size_t>(t)], skip_near_p)) ++count;
  });
  return count;
}

int count_wrong_side(const CorotationalEfg& model, const std::vector<Vec3>& vertices,
                     const std::vector<std::array<int, 3>>& triangles, const SurfaceEmbedding& embedding,
                     const std::vector<std::array<Vec3, 3>>& cut_triangles, double inset, std::vector<int>* which) {
  return count_wrong_side(model, vertices, triangles, embedding, CutFaceIndex(model, cut_triangles), inset, {}, which);
}

int count_wrong_side(const CorotationalEfg& model, const std::vector<Vec3>& vertices,
                     const std::vector<std::array<int, 3>>& triangles, const SurfaceEmbedding& embedding,
                     const CutFaceIndex& faces, double inset, std::span<const int> subset, std::vector<int>* which,
                     std::span<const std::uint8_t> on_face, const TrianglesAround* around) {
  if (around != nullptr && subset.empty()) throw std::invalid_argument("count_wrong_side: the triangles around the vertices are given, but not the vertices");
  const int rows = std::min(embedding.vertex_count(), static_cast<int>(vertices.size()));
  std::vector<int> all;
  if (subset.empty()) {
    all.resize(static_cast<size_t>(rows));
    for (int v = 0; v < rows; ++v) all[static_cast<size_t>(v)] = v;
    subset = all;
  }
  std::vector<std::uint8_t> wanted(vertices.size(), 0);
  for (size_t k = 0; k < subset.size(); ++k) {
    const int v = subset[k];
    if (v < 0 || v >= static_cast<int>(vertices.size()) || (k > 0 && v <= subset[k - 1]))
      throw std::invalid_argument("count_wrong_side: subset entry " + std::to_string(k) + " (vertex " + std::to_string(v) +
                                  ") is out of range or out of order");
    if (v >= rows) continue;
    const int e = embedding.elements[static_cast<size_t>(v)];
    if (e < 0 || e >= model.element_count())
      throw std::invalid_argument("count_wrong_side: vertex " + std::to_string(v) + " is mapped to element " + std::to_string(e) + ", out of range");
    wanted[static_cast<size_t>(v)] = 1;
  }
  const std::vector<int> triangle_subset = triangles_of(vertices, triangles, subset, around, "count_wrong_side");
  const std::vector<Vec3> normals = angle_weighted_normals(vertices, triangles, wanted, subset, triangle_subset, around == nullptr);
  int wrong = 0;
  for (const int v : subset) {
    if (v >= rows) continue;
    const Vec3 p = inset_point(vertices[static_cast<size_t>(v)], normals[static_cast<size_t>(v)], inset, faces, flagged(on_face, v));
    const Vec3& q = model.element_centres()[static_cast<size_t>(embedding.elements[static_cast<size_t>(v)])];
    // Across means an odd number of crossings: a wavy cut face (the blade mapped to rest
    // moment by moment) can be crossed and crossed back on the way to a point on the same
    // side. The faces must be each face once (not both sides' coincident copies).
    const bool crosses = faces.crossings(p, q) % 2 == 1;
    wrong += crosses ? 1 : 0;
    if (crosses && which) which->push_back(v);
  }
  return wrong;
}

namespace {

std::uint64_t bits(double x) {
  std::uint64_t b = 0;
  std::memcpy(&b, &x, sizeof b);
  return b;
}

// Sorts (key, index) pairs whose keys are mixed (uniform) 64-bit values: bucketed by the
// keys' top bits (about one pair per bucket), each bucket then sorted. The same order as
// std::sort, in linear time.
void sort_mixed_keys(std::vector<std::pair<std::uint64_t, int>>& pairs) {
  const size_t n = pairs.size();
  if (n < 64) {
    std::sort(pairs.begin(), pairs.end());
    return;
  }
  int bits_used = 1;
  while (bits_used < 16 && (size_t{1} << bits_used) < n) ++bits_used;
  const int shift = 64 - bits_used;
  std::vector<int> start((size_t{1} << bits_used) + 1, 0);
  for (const auto& pair : pairs) ++start[static_cast<size_t>(pair.first >> shift) + 1];
  for (size_t b = 1; b < start.size(); ++b) start[b] += start[b - 1];
  std::vector<std::pair<std::uint64_t, int>> out(n);
  std::vector<int> fill(start.begin(), start.end() - 1);
  for (const auto& pair : pairs) out[static_cast<size_t>(fill[static_cast<size_t>(pair.first >> shift)]++)] = pair;
  for (size_t b = 0; b + 1 < start.size(); ++b)
    if (start[b + 1] - start[b] > 1) std::sort(out.begin() + start[b], out.begin() + start[b + 1]);
  pairs.swap(out);
}

}  // namespace

FrontVertexIdentity front_vertex_identity(const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles,
                                          const VertexPlanes& planes,
                                          std::span<const std::uint8_t> crack_front, int first,
                                          std::span<const int> among) {
  const int n = static_cast<int>(vertices.size());
  if (first < 0 || first > n)
    throw std::invalid_argument("front_vertex_identity: first " + std::to_string(first) + " is out of range [0, " + std::to_string(n) + "]");
  if (among.empty()) {
    check_surface(vertices, triangles, "front_vertex_identity");
  } else {
    for (int v = first; v < n; ++v)
      if (!vertices[static_cast<size_t>(v)].allFinite()) throw std::invalid_argument("front_vertex_identity: vertex " + std::to_string(v) + " is not finite");
    for (size_t k = 0; k < among.size(); ++k) {
      const int t = among[k];
      if (t < 0 || static_cast<size_t>(t) >= triangles.size() || (k > 0 && t <= among[k - 1]))
        throw std::invalid_argument("front_vertex_identity: triangle entry " + std::to_string(k) + " (" + std::to_string(t) + ") is out of range or out of order");
      for (const int v : triangles[static_cast<size_t>(t)])
        if (v < 0 || v >= n)
          throw std::invalid_argument("front_vertex_identity: triangle " + std::to_string(t) + " has vertex " + std::to_string(v) + ", out of range [0, " + std::to_string(n) + ")");
    }
  }
  FrontVertexIdentity identity;
  identity.first = first;
  identity.key.resize(static_cast<size_t>(n - first));
  identity.ring.assign(static_cast<size_t>(n - first), 0);
  // Each number mixed on its own with its place in the list, and the mixes summed: the same
  // content gives the same key, and the mixes are independent (not one chain per vertex).
  constexpr std::uint64_t step = 0x9e3779b97f4a7c15ULL;
  for (int v = first; v < n; ++v) {
    std::uint64_t h = mix64(flagged(crack_front, v) ? 1 : 2);
    std::uint64_t place = 0;
    for (int d = 0; d < 3; ++d) h += mix64(bits(vertices[static_cast<size_t>(v)][d]) + (place += step));
    if (static_cast<size_t>(v) < planes.size())
      for (const ConstraintPlane& plane : planes[static_cast<size_t>(v)])
        for (int d = 0; d < 3; ++d) {
          h += mix64(bits(plane.point[d]) + (place += step));
          h += mix64(bits(plane.normal[d]) + (place += step));
        }
    identity.key[static_cast<size_t>(v - first)] = mix64(h);
  }
  // A base vertex is its index (salted apart from the content keys).
  const auto key_of = [&](int v) { return v < first ? mix64(0x5eedULL + static_cast<std::uint64_t>(v)) : identity.key[static_cast<size_t>(v - first)]; };
  const auto visit = [&](const std::array<int, 3>& tri) {
    if (tri[0] < first && tri[1] < first && tri[2] < first) return;
    for (int k = 0; k < 3; ++k) {
      const int v = tri[static_cast<size_t>(k)];
      if (v < first) continue;
      // The two other corners in order (the triangle's orientation counts); summed over the
      // triangles, so their order does not.
      identity.ring[static_cast<size_t>(v - first)] +=
          mix64(mix64(key_of(tri[static_cast<size_t>((k + 1) % 3)])) ^ key_of(tri[static_cast<size_t>((k + 2) % 3)]));
    }
  };
  if (among.empty()) {
    for (const auto& tri : triangles) visit(tri);
  } else {
    for (const int t : among) visit(triangles[static_cast<size_t>(t)]);
  }
  identity.sorted.resize(identity.key.size());
  for (size_t k = 0; k < identity.key.size(); ++k) identity.sorted[k] = {identity.key[k], first + static_cast<int>(k)};
  sort_mixed_keys(identity.sorted);
  return identity;
}

std::vector<int> match_front_vertices(const FrontVertexIdentity& before, const FrontVertexIdentity& now, std::vector<int>* same_point) {
  std::vector<int> match(static_cast<size_t>(now.first) + now.key.size(), -1);
  if (same_point != nullptr) same_point->assign(match.size(), -1);
  if (before.first != now.first) return match;
  // Sorted (key, index) of each side (made by front_vertex_identity; made here for an identity
  // put together otherwise); a key found twice on a side matches nothing.
  std::vector<std::pair<std::uint64_t, int>> made_old, made_new;
  const auto sorted = [](const FrontVertexIdentity& side, std::vector<std::pair<std::uint64_t, int>>& made)
      -> const std::vector<std::pair<std::uint64_t, int>>& {
    if (side.sorted.size() == side.key.size()) return side.sorted;
    made.resize(side.key.size());
    for (size_t k = 0; k < side.key.size(); ++k) made[k] = {side.key[k], side.first + static_cast<int>(k)};
    std::sort(made.begin(), made.end());
    return made;
  };
  const auto& old_keys = sorted(before, made_old);
  const auto& new_keys = sorted(now, made_new);
  const auto unique_at = [](const std::vector<std::pair<std::uint64_t, int>>& keys, size_t k) {
    return (k == 0 || keys[k - 1].first != keys[k].first) && (k + 1 == keys.size() || keys[k + 1].first != keys[k].first);
  };
  size_t o = 0;
  for (size_t k = 0; k < new_keys.size(); ++k) {
    if (!unique_at(new_keys, k)) continue;
    while (o < old_keys.size() && old_keys[o].first < new_keys[k].first) ++o;
    if (o == old_keys.size() || old_keys[o].first != new_keys[k].first || !unique_at(old_keys, o)) continue;
    const int u = old_keys[o].second, v = new_keys[k].second;
    if (same_point != nullptr) (*same_point)[static_cast<size_t>(v)] = u;
    if (before.ring[static_cast<size_t>(u - before.first)] == now.ring[static_cast<size_t>(v - now.first)]) match[static_cast<size_t>(v)] = u;
  }
  return match;
}

}  // namespace incise::physics
