// The constrained Delaunay triangulation of physics/cut/triangulate_2d.hpp; the header
// gives the algorithm, the predicates, the tie rule and the complexity.
#include "physics/cut/triangulate_2d.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>

namespace incise::physics {
namespace {

// ---------------------------------------------------------------------------------------
// Exact arithmetic on floating-point expansions (Shewchuk 1997): a value is held as a sum
// of doubles of increasing magnitude that do not overlap, so the sign of the sum is the
// sign of its last (largest) component. Zero components are dropped as they appear, which
// keeps lattice-like inputs (whose differences are exact) at one or two components.
// ---------------------------------------------------------------------------------------
using Expansion = std::vector<double>;

// a + b = sum + error exactly (Knuth's two-sum, no precondition on magnitudes).
inline void two_sum(double a, double b, double& sum, double& error) {
  sum = a + b;
  const double b_virtual = sum - a;
  const double a_virtual = sum - b_virtual;
  error = (a - a_virtual) + (b - b_virtual);
}

// a * b = product + error exactly. With hardware FMA the error is one fused operation;
// without it (the default x86-64 target) std::fma is a slow library call, so Dekker's
// splitting into 26-bit halves is used instead.
inline void two_product(double a, double b, double& product, double& error) {
  product = a * b;
#if defined(__FMA__)
  error = std::fma(a, b, -product);
#else
  constexpr double splitter = 134217729.0;  // 2^27 + 1
  const double ca = splitter * a;
  const double a_high = ca - (ca - a);
  const double a_low = a - a_high;
  const double cb = splitter * b;
  const double b_high = cb - (cb - b);
  const double b_low = b - b_high;
  error = ((a_high * b_high - product) + a_high * b_low + a_low * b_high) + a_low * b_low;
#endif
}

Expansion difference(double a, double b) {
  double sum = 0.0;
  double error = 0.0;
  two_sum(a, -b, sum, error);
  Expansion e;
  if (error != 0.0) e.push_back(error);
  if (sum != 0.0) e.push_back(sum);
  return e;
}

// Merge by magnitude, then one sweep of two-sums (Shewchuk's FAST-EXPANSION-SUM with zero
// elimination).
Expansion sum(const Expansion& e, const Expansion& f) {
  Expansion merged;
  merged.reserve(e.size() + f.size());
  std::merge(e.begin(), e.end(), f.begin(), f.end(), std::back_inserter(merged),
             [](double x, double y) { return std::abs(x) < std::abs(y); });
  Expansion h;
  if (merged.empty()) return h;
  h.reserve(merged.size());
  double q = merged[0];
  for (std::size_t i = 1; i < merged.size(); ++i) {
    double error = 0.0;
    two_sum(q, merged[i], q, error);
    if (error != 0.0) h.push_back(error);
  }
  if (q != 0.0) h.push_back(q);
  return h;
}

Expansion negated(Expansion e) {
  for (double& x : e) x = -x;
  return e;
}

// e * b (Shewchuk's SCALE-EXPANSION with zero elimination).
Expansion scaled(const Expansion& e, double b) {
  Expansion h;
  if (e.empty() || b == 0.0) return h;
  h.reserve(2 * e.size());
  double q = 0.0;
  double error = 0.0;
  two_product(e[0], b, q, error);
  if (error != 0.0) h.push_back(error);
  for (std::size_t i = 1; i < e.size(); ++i) {
    double product = 0.0;
    double product_error = 0.0;
    two_product(e[i], b, product, product_error);
    double partial = 0.0;
    two_sum(q, product_error, partial, error);
    if (error != 0.0) h.push_back(error);
    two_sum(product, partial, q, error);
    if (error != 0.0) h.push_back(error);
  }
  if (q != 0.0) h.push_back(q);
  return h;
}

Expansion product(const Expansion& e, const Expansion& f) {
  Expansion h;
  for (double component : f) h = sum(h, scaled(e, component));
  return h;
}

double sign_of(const Expansion& e) {
  if (e.empty()) return 0.0;
  return e.back() > 0.0 ? 1.0 : -1.0;
}

// Shewchuk's bounds A, with his epsilon = 2^-53 (half an ulp of 1).
constexpr double epsilon = 1.1102230246251565e-16;
constexpr double orient_error_bound = (3.0 + 16.0 * epsilon) * epsilon;
constexpr double incircle_error_bound = (10.0 + 96.0 * epsilon) * epsilon;

double orient2d_exact(const Vec2& a, const Vec2& b, const Vec2& c) {
  const Expansion acx = difference(a.x(), c.x());
  const Expansion acy = difference(a.y(), c.y());
  const Expansion bcx = difference(b.x(), c.x());
  const Expansion bcy = difference(b.y(), c.y());
  return sign_of(sum(product(acx, bcy), negated(product(acy, bcx))));
}

double incircle_exact(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  const Expansion adx = difference(a.x(), d.x());
  const Expansion ady = difference(a.y(), d.y());
  const Expansion bdx = difference(b.x(), d.x());
  const Expansion bdy = difference(b.y(), d.y());
  const Expansion cdx = difference(c.x(), d.x());
  const Expansion cdy = difference(c.y(), d.y());
  const Expansion a_lift = sum(product(adx, adx), product(ady, ady));
  const Expansion b_lift = sum(product(bdx, bdx), product(bdy, bdy));
  const Expansion c_lift = sum(product(cdx, cdx), product(cdy, cdy));
  const Expansion bc = sum(product(bdx, cdy), negated(product(bdy, cdx)));
  const Expansion ca = sum(product(cdx, ady), negated(product(cdy, adx)));
  const Expansion ab = sum(product(adx, bdy), negated(product(ady, bdx)));
  return sign_of(sum(sum(product(a_lift, bc), product(b_lift, ca)), product(c_lift, ab)));
}

}  // namespace

double orient2d(const Vec2& a, const Vec2& b, const Vec2& c) {
  const double left = (a.x() - c.x()) * (b.y() - c.y());
  const double right = (a.y() - c.y()) * (b.x() - c.x());
  const double det = left - right;
  // Opposite signs (or a zero) cannot cancel: the rounded difference has the right sign.
  if ((left > 0.0 && right <= 0.0) || (left < 0.0 && right >= 0.0) || left == 0.0) return det;
  const double bound = orient_error_bound * (std::abs(left) + std::abs(right));
  if (det > bound || -det > bound) return det;
  return orient2d_exact(a, b, c);
}

double incircle(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  const double adx = a.x() - d.x(), ady = a.y() - d.y();
  const double bdx = b.x() - d.x(), bdy = b.y() - d.y();
  const double cdx = c.x() - d.x(), cdy = c.y() - d.y();
  const double bdxcdy = bdx * cdy, cdxbdy = cdx * bdy;
  const double cdxady = cdx * ady, adxcdy = adx * cdy;
  const double adxbdy = adx * bdy, bdxady = bdx * ady;
  const double a_lift = adx * adx + ady * ady;
  const double b_lift = bdx * bdx + bdy * bdy;
  const double c_lift = cdx * cdx + cdy * cdy;
  const double det = a_lift * (bdxcdy - cdxbdy) + b_lift * (cdxady - adxcdy) + c_lift * (adxbdy - bdxady);
  const double permanent = (std::abs(bdxcdy) + std::abs(cdxbdy)) * a_lift +
                           (std::abs(cdxady) + std::abs(adxcdy)) * b_lift +
                           (std::abs(adxbdy) + std::abs(bdxady)) * c_lift;
  const double bound = incircle_error_bound * permanent;
  if (det > bound || -det > bound) return det;
  return incircle_exact(a, b, c, d);
}

namespace {

// ---------------------------------------------------------------------------------------
// The triangulation: triangles with counter-clockwise vertices; edge i is the one opposite
// vertex i, running from vertex i+1 to vertex i+2 (mod 3), with the neighbour across it and
// the index of the boundary edge it carries (-1 for none).
// ---------------------------------------------------------------------------------------
struct Triangle {
  std::array<int, 3> vertex{};
  std::array<int, 3> neighbour{-1, -1, -1};
  std::array<int, 3> constraint{-1, -1, -1};
};

inline int next(int i) { return i == 2 ? 0 : i + 1; }
inline int prev(int i) { return i == 0 ? 2 : i - 1; }

std::string edge_name(int index, const std::array<int, 2>& edge) {
  return "boundary edge " + std::to_string(index) + " (" + std::to_string(edge[0]) + " -> " +
         std::to_string(edge[1]) + ")";
}

// Hilbert curve index of (x, y) on a 2^16 grid, for a spatially coherent insertion order.
std::uint64_t hilbert_index(std::uint32_t x, std::uint32_t y) {
  constexpr std::uint32_t side = 1u << 16;
  std::uint64_t d = 0;
  for (std::uint32_t s = side / 2; s > 0; s /= 2) {
    const std::uint32_t rx = (x & s) ? 1 : 0;
    const std::uint32_t ry = (y & s) ? 1 : 0;
    d += static_cast<std::uint64_t>(s) * s * ((3 * rx) ^ ry);
    if (ry == 0) {  // rotate the quadrant so the curve stays continuous
      if (rx == 1) {
        x = side - 1 - x;
        y = side - 1 - y;
      }
      std::swap(x, y);
    }
  }
  return d;
}

class Triangulator {
 public:
  explicit Triangulator(const PlanarRegion& region) : region_(region), points_(region.points) {}

  std::vector<std::array<int, 3>> run();

 private:
  void validate_points() const;
  void validate_boundary();
  void build_enclosing_triangle();
  void insert_points();
  void insert_point(int p);
  int locate(int p, int start);
  void split_fan(int p, const std::array<int, 4>& ring, const std::array<int, 4>& outer,
                 const std::array<int, 4>& outer_constraint, const std::array<int, 4>& ids, int count);
  void flip(int t, int i);
  int neighbour_edge(int t, int i) const;
  void legalize(int p);
  void recover_constraint(int index);
  bool find_edge(int a, int b, int& t, int& i) const;
  // Visits the triangles around vertex a in turn, each with a's corner k in it, until
  // `visit(triangle, k)` returns true (then true) or the fan closes or ends (false).
  template <typename Visit>
  bool around(int a, const Visit& visit) const {
    const int first = vertex_triangle_[a];
    int current = first;
    do {
      const Triangle& tri = triangles_[current];
      int k = 0;
      while (tri.vertex[k] != a) ++k;
      if (visit(current, k)) return true;
      current = tri.neighbour[next(k)];
    } while (current >= 0 && current != first);
    return false;
  }
  void mark_constraint(int t, int i, int index);
  void classify();
  void restore_delaunay();
  double orient(int a, int b, int c) const { return orient2d(points_[a], points_[b], points_[c]); }
  bool beyond_along(int a, int b, int c) const;
  [[noreturn]] void throw_point_on_edge(int point, int index) const;

  const PlanarRegion& region_;
  std::vector<Vec2> points_;  // the region's points, then the enclosing triangle's three
  std::vector<Triangle> triangles_;
  std::vector<int> vertex_triangle_;  // one triangle holding each vertex
  std::vector<int> stack_;            // flip work list: triangle * 3 + edge
  std::vector<char> inside_;
  int last_triangle_ = 0;  // where the next point location starts: next to the last point
  std::uint32_t random_state_ = 2463534242u;  // fixed seed: the walk, and so the output, is deterministic
};

void Triangulator::validate_points() const {
  const int n = static_cast<int>(region_.points.size());
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(region_.points[i].x()) || !std::isfinite(region_.points[i].y()))
      throw std::invalid_argument("triangulate_region: point " + std::to_string(i) + " has a non-finite coordinate");
  }
  std::vector<int> order(n);
  for (int i = 0; i < n; ++i) order[i] = i;
  const auto& p = region_.points;
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    if (p[a].x() != p[b].x()) return p[a].x() < p[b].x();
    if (p[a].y() != p[b].y()) return p[a].y() < p[b].y();
    return a < b;
  });
  for (int k = 1; k < n; ++k) {
    if (p[order[k - 1]] == p[order[k]])
      throw std::invalid_argument("triangulate_region: points " + std::to_string(order[k - 1]) + " and " +
                                  std::to_string(order[k]) + " coincide");
  }
}

void Triangulator::validate_boundary() {
  const int n = static_cast<int>(region_.points.size());
  std::vector<int> balance(n, 0);
  std::map<std::pair<int, int>, int> boundary_by_vertices;  // (min, max) -> boundary edge
  for (int k = 0; k < static_cast<int>(region_.boundary.size()); ++k) {
    const auto& edge = region_.boundary[k];
    for (int end : edge) {
      if (end < 0 || end >= n)
        throw std::invalid_argument("triangulate_region: " + edge_name(k, edge) + " has index " +
                                    std::to_string(end) + " out of range [0, " + std::to_string(n) + ")");
    }
    if (edge[0] == edge[1])
      throw std::invalid_argument("triangulate_region: " + edge_name(k, edge) + " starts and ends at the same point");
    const auto key = std::minmax(edge[0], edge[1]);
    const auto [it, inserted] = boundary_by_vertices.emplace(std::pair<int, int>(key.first, key.second), k);
    if (!inserted)
      throw std::invalid_argument("triangulate_region: " + edge_name(it->second, region_.boundary[it->second]) +
                                  " and " + edge_name(k, edge) + " overlap (the same two points)");
    ++balance[edge[0]];
    --balance[edge[1]];
  }
  for (int v = 0; v < n; ++v) {
    if (balance[v] != 0)
      throw std::invalid_argument("triangulate_region: the boundary does not form closed loops: point " +
                                  std::to_string(v) + " has " + std::to_string(balance[v]) +
                                  " more outgoing than incoming boundary edges");
  }
}

void Triangulator::build_enclosing_triangle() {
  Eigen::AlignedBox2d box;
  for (const Vec2& p : region_.points) box.extend(p);
  const Vec2 centre = box.center();
  double size = box.sizes().maxCoeff();
  // A single point (or none) has no extent; the triangle must still be far larger than the
  // rounding of the centre, so size it on the coordinates' magnitude.
  if (!(size > 0.0)) size = std::max({std::abs(centre.x()), std::abs(centre.y()), 1.0});
  const int n = static_cast<int>(region_.points.size());
  // Every point is within size/2 of the centre; the rounding of these corners is far below
  // the margin, so all points are strictly inside.
  points_.push_back(centre + Vec2(-20.0 * size, -10.0 * size));
  points_.push_back(centre + Vec2(20.0 * size, -10.0 * size));
  points_.push_back(centre + Vec2(0.0, 20.0 * size));
  Triangle t;
  t.vertex = {n, n + 1, n + 2};
  triangles_.push_back(t);
  vertex_triangle_.assign(n + 3, -1);
  vertex_triangle_[n] = vertex_triangle_[n + 1] = vertex_triangle_[n + 2] = 0;
}

void Triangulator::insert_points() {
  const int n = static_cast<int>(region_.points.size());
  if (n == 0) return;
  Eigen::AlignedBox2d box;
  for (const Vec2& p : region_.points) box.extend(p);
  const Vec2 low = box.min();
  const Vec2 size = box.sizes();
  std::vector<std::pair<std::uint64_t, int>> order(n);
  for (int i = 0; i < n; ++i) {
    auto cell = [](double value, double low_value, double extent) {
      if (!(extent > 0.0)) return std::uint32_t{0};
      const double scaled_value = (value - low_value) / extent * 65535.0;
      return static_cast<std::uint32_t>(std::clamp(scaled_value, 0.0, 65535.0));
    };
    const std::uint32_t x = cell(region_.points[i].x(), low.x(), size.x());
    const std::uint32_t y = cell(region_.points[i].y(), low.y(), size.y());
    order[i] = {hilbert_index(x, y), i};
  }
  std::sort(order.begin(), order.end());
  triangles_.reserve(2 * n + 8);
  for (const auto& [key, p] : order) insert_point(p);
}

// Visibility walk: step across any edge that has p strictly on its far side. Which of two
// such edges is taken is chosen by a fixed-seed generator, which rules out cycles in the
// degenerate (cocircular) configurations and keeps the result deterministic.
int Triangulator::locate(int p, int start) {
  int t = start;
  const std::size_t limit = 8 * triangles_.size() + 64;
  for (std::size_t step = 0; step < limit; ++step) {
    random_state_ ^= random_state_ << 13;
    random_state_ ^= random_state_ >> 17;
    random_state_ ^= random_state_ << 5;
    const int offset = static_cast<int>(random_state_ % 3);
    bool moved = false;
    for (int k = 0; k < 3; ++k) {
      const int i = (offset + k) % 3;
      const Triangle& tri = triangles_[t];
      if (orient(tri.vertex[next(i)], tri.vertex[prev(i)], p) < 0.0) {
        t = tri.neighbour[i];
        moved = true;
        break;
      }
    }
    if (!moved) return t;
  }
  throw std::logic_error("triangulate_region: point location did not terminate for point " + std::to_string(p));
}

int Triangulator::neighbour_edge(int t, int i) const {
  const int u = triangles_[t].neighbour[i];
  const int from = triangles_[t].vertex[next(i)];
  for (int j = 0; j < 3; ++j) {
    if (triangles_[u].vertex[prev(j)] == from) return j;  // u runs the edge the other way
  }
  throw std::logic_error("triangulate_region: broken adjacency");
}

// Replaces the triangles in ids[0..count) by the fan (p, ring[m], ring[m+1]) around p.
void Triangulator::split_fan(int p, const std::array<int, 4>& ring, const std::array<int, 4>& outer,
                             const std::array<int, 4>& outer_constraint, const std::array<int, 4>& ids,
                             int count) {
  for (int m = 0; m < count; ++m) {
    Triangle& tri = triangles_[ids[m]];
    const int m_next = (m + 1) % count;
    tri.vertex = {p, ring[m], ring[m_next]};
    tri.neighbour = {outer[m], ids[m_next], ids[(m + count - 1) % count]};
    tri.constraint = {outer_constraint[m], -1, -1};
    vertex_triangle_[ring[m]] = ids[m];
    if (outer[m] >= 0) {
      Triangle& o = triangles_[outer[m]];
      for (int k = 0; k < 3; ++k) {
        if (o.vertex[next(k)] == ring[m_next] && o.vertex[prev(k)] == ring[m]) o.neighbour[k] = ids[m];
      }
    }
  }
  vertex_triangle_[p] = ids[0];
}

void Triangulator::insert_point(int p) {
  const int t = locate(p, last_triangle_);
  const Triangle tri = triangles_[t];
  // p is inside or on t; exactly on one edge (orientation zero) it splits that edge.
  int zeros = 0;
  int zero_edge = -1;
  for (int i = 0; i < 3; ++i) {
    if (orient(tri.vertex[next(i)], tri.vertex[prev(i)], p) == 0.0) {
      ++zeros;
      zero_edge = i;
    }
  }
  if (zeros >= 2) throw std::logic_error("triangulate_region: point " + std::to_string(p) + " located on a vertex");
  if (zeros == 0) {
    const int t1 = static_cast<int>(triangles_.size());
    triangles_.emplace_back();
    triangles_.emplace_back();
    split_fan(p, {tri.vertex[1], tri.vertex[2], tri.vertex[0], 0}, {tri.neighbour[0], tri.neighbour[1], tri.neighbour[2], 0},
              {tri.constraint[0], tri.constraint[1], tri.constraint[2], 0}, {t, t1, t1 + 1, 0}, 3);
  } else {
    // On edge i = a -> b of t = (r, a, b); u = (q, b, a) across it. Four triangles around p.
    const int i = zero_edge;
    const int u = tri.neighbour[i];
    const int j = neighbour_edge(t, i);
    const Triangle other = triangles_[u];
    const int r = tri.vertex[i], a = tri.vertex[next(i)], b = tri.vertex[prev(i)];
    const int q = other.vertex[j];
    const int t2 = static_cast<int>(triangles_.size());
    triangles_.emplace_back();
    triangles_.emplace_back();
    split_fan(p, {r, a, q, b}, {tri.neighbour[prev(i)], other.neighbour[next(j)], other.neighbour[prev(j)], tri.neighbour[next(i)]},
              {tri.constraint[prev(i)], other.constraint[next(j)], other.constraint[prev(j)], tri.constraint[next(i)]},
              {t, u, t2, t2 + 1}, 4);
  }
  last_triangle_ = t;
  // Every triangle of the fan has p as vertex 0: the edges to test are their edges 0.
  stack_.clear();
  const int first_new = static_cast<int>(triangles_.size()) - 2;
  stack_.push_back(t * 3);
  if (zeros == 1) stack_.push_back(tri.neighbour[zero_edge] * 3);
  stack_.push_back(first_new * 3);
  stack_.push_back((first_new + 1) * 3);
  legalize(p);
}

// Flips edge i of t = (p, a, b) with u = (q, b, a) across it: t becomes (p, a, q) and u
// becomes (q, b, p). The layout is fixed so callers know where the new edges are: p-q is
// edge 1 of both; the edges opposite p are t's edge 0 and u's edge 2.
void Triangulator::flip(int t, int i) {
  const int u = triangles_[t].neighbour[i];
  const int j = neighbour_edge(t, i);
  Triangle& tt = triangles_[t];
  Triangle& uu = triangles_[u];
  const int p = tt.vertex[i], a = tt.vertex[next(i)], b = tt.vertex[prev(i)];
  const int q = uu.vertex[j];
  const int n_bp = tt.neighbour[next(i)], c_bp = tt.constraint[next(i)];
  const int n_pa = tt.neighbour[prev(i)], c_pa = tt.constraint[prev(i)];
  const int n_aq = uu.neighbour[next(j)], c_aq = uu.constraint[next(j)];
  const int n_qb = uu.neighbour[prev(j)], c_qb = uu.constraint[prev(j)];
  tt.vertex = {p, a, q};
  tt.neighbour = {n_aq, u, n_pa};
  tt.constraint = {c_aq, -1, c_pa};
  uu.vertex = {q, b, p};
  uu.neighbour = {n_bp, t, n_qb};
  uu.constraint = {c_bp, -1, c_qb};
  auto repoint = [&](int outer, int from, int to) {
    if (outer < 0) return;
    for (int& n : triangles_[outer].neighbour) {
      if (n == from) n = to;
    }
  };
  repoint(n_aq, u, t);
  repoint(n_bp, t, u);
  vertex_triangle_[p] = t;
  vertex_triangle_[a] = t;
  vertex_triangle_[q] = t;
  vertex_triangle_[b] = u;
}

void Triangulator::legalize(int p) {
  while (!stack_.empty()) {
    const int t = stack_.back() / 3;
    const int i = stack_.back() % 3;
    stack_.pop_back();
    const Triangle& tri = triangles_[t];
    if (tri.vertex[i] != p || tri.neighbour[i] < 0 || tri.constraint[i] >= 0) continue;
    const int q = triangles_[tri.neighbour[i]].vertex[neighbour_edge(t, i)];
    if (incircle(points_[tri.vertex[0]], points_[tri.vertex[1]], points_[tri.vertex[2]], points_[q]) > 0.0) {
      const int u = tri.neighbour[i];
      flip(t, i);
      stack_.push_back(t * 3 + 0);
      stack_.push_back(u * 3 + 2);
    }
  }
}

// True when c (collinear with a and b, and not a) lies on the same side of a as b. Exact:
// only comparisons of coordinates.
bool Triangulator::beyond_along(int a, int b, int c) const {
  const Vec2& pa = points_[a];
  const Vec2& pb = points_[b];
  const Vec2& pc = points_[c];
  if (pb.x() != pa.x()) return (pc.x() > pa.x()) == (pb.x() > pa.x()) && pc.x() != pa.x();
  return (pc.y() > pa.y()) == (pb.y() > pa.y()) && pc.y() != pa.y();
}

void Triangulator::throw_point_on_edge(int point, int index) const {
  const auto& edge = region_.boundary[index];
  // A point inside the edge that starts or ends a boundary edge along the same line means
  // the two boundary edges overlap (the other one runs into this one from its interior
  // point); say so, it is the more useful message. Only on the error path, so a plain scan.
  for (int k = 0; k < static_cast<int>(region_.boundary.size()); ++k) {
    const auto& candidate = region_.boundary[k];
    const int other = candidate[0] == point ? candidate[1] : candidate[1] == point ? candidate[0] : -1;
    if (other >= 0 && orient(edge[0], edge[1], other) == 0.0)
      throw std::invalid_argument("triangulate_region: " + edge_name(index, edge) + " and " +
                                  edge_name(k, candidate) + " overlap (point " + std::to_string(point) +
                                  " lies on the first)");
  }
  throw std::invalid_argument("triangulate_region: point " + std::to_string(point) + " lies on " +
                              edge_name(index, edge) + " without being one of its endpoints");
}

bool Triangulator::find_edge(int a, int b, int& t, int& i) const {
  return around(a, [&](int current, int k) {
    if (triangles_[current].vertex[next(k)] != b) return false;
    t = current;
    i = prev(k);
    return true;
  });
}

void Triangulator::mark_constraint(int t, int i, int index) {
  triangles_[t].constraint[i] = index;
  const int j = neighbour_edge(t, i);
  triangles_[triangles_[t].neighbour[i]].constraint[j] = index;
}

void Triangulator::recover_constraint(int index) {
  const int a = region_.boundary[index][0];
  const int b = region_.boundary[index][1];
  // Around a: either b is a neighbour already, or one triangle's corner at a holds the
  // direction to b strictly inside, or a neighbour lies exactly on the way (an error).
  int t = -1;
  int e = -1;
  int left = -1;
  int right = -1;
  bool joined = false;
  around(a, [&](int current, int k) {
    const Triangle& tri = triangles_[current];
    const int x = tri.vertex[next(k)];
    const int y = tri.vertex[prev(k)];
    if (x == b) {
      mark_constraint(current, prev(k), index);
      joined = true;
      return true;
    }
    const double side_x = orient(a, b, x);
    if (side_x == 0.0 && beyond_along(a, b, x)) throw_point_on_edge(x, index);
    if (side_x < 0.0 && orient(a, b, y) > 0.0) {
      t = current;
      e = k;
      right = x;
      left = y;
      return true;
    }
    return false;
  });
  if (joined) return;
  if (t < 0) throw std::logic_error("triangulate_region: no triangle at the start of " + edge_name(index, region_.boundary[index]));

  // Walk to b, collecting the crossed edges; a boundary edge crossed or a point met is an error.
  std::deque<std::pair<int, int>> crossed;
  for (;;) {
    const Triangle& tri = triangles_[t];
    if (tri.constraint[e] >= 0)
      throw std::invalid_argument("triangulate_region: " + edge_name(index, region_.boundary[index]) + " and " +
                                  edge_name(tri.constraint[e], region_.boundary[tri.constraint[e]]) + " cross");
    crossed.emplace_back(left, right);
    const int u = tri.neighbour[e];
    const Triangle& other = triangles_[u];
    const int z = other.vertex[neighbour_edge(t, e)];
    if (z == b) break;
    const double side_z = orient(a, b, z);
    if (side_z == 0.0) throw_point_on_edge(z, index);
    int k = 0;
    if (side_z > 0.0) {
      while (other.vertex[k] != left) ++k;
      left = z;
    } else {
      while (other.vertex[k] != right) ++k;
      right = z;
    }
    t = u;
    e = k;
  }

  // Sloan's flips: a crossed edge in a strictly convex quad is flipped; if the new diagonal
  // still crosses a-b it goes back in the queue, as do the edges that could not be flipped.
  while (!crossed.empty()) {
    const auto [s, w] = crossed.front();
    crossed.pop_front();
    int tri = -1;
    int i = -1;
    if (!find_edge(s, w, tri, i)) throw std::logic_error("triangulate_region: lost a crossed edge");
    const int p = triangles_[tri].vertex[i];
    const int q = triangles_[triangles_[tri].neighbour[i]].vertex[neighbour_edge(tri, i)];
    // The quad p, s, q, w is counter-clockwise; p-q is a diagonal when s and w are on
    // strictly opposite sides of it.
    if (orient(p, q, s) < 0.0 && orient(p, q, w) > 0.0) {
      flip(tri, i);
      const double side_p = orient(a, b, p);
      const double side_q = orient(a, b, q);
      if ((side_p > 0.0 && side_q < 0.0) || (side_p < 0.0 && side_q > 0.0)) crossed.emplace_back(p, q);
    } else {
      crossed.emplace_back(s, w);
    }
  }
  int tri = -1;
  int i = -1;
  if (!find_edge(a, b, tri, i)) throw std::logic_error("triangulate_region: flips did not recover " + edge_name(index, region_.boundary[index]));
  mark_constraint(tri, i, index);
}

void Triangulator::classify() {
  const int count = static_cast<int>(triangles_.size());
  const int n = static_cast<int>(region_.points.size());
  std::vector<int> component(count, -1);
  int components = 0;
  std::vector<int> queue;
  for (int seed = 0; seed < count; ++seed) {
    if (component[seed] >= 0) continue;
    component[seed] = components;
    queue.assign(1, seed);
    while (!queue.empty()) {
      const int t = queue.back();
      queue.pop_back();
      for (int i = 0; i < 3; ++i) {
        const int u = triangles_[t].neighbour[i];
        if (u >= 0 && triangles_[t].constraint[i] < 0 && component[u] < 0) {
          component[u] = components;
          queue.push_back(u);
        }
      }
    }
    ++components;
  }
  // Each boundary edge says its left side is inside and its right side outside; the
  // enclosing triangle's corners are outside. Any disagreement is a wrongly oriented loop.
  std::vector<int> side(components, 0);  // +1 inside, -1 outside, 0 not yet known
  std::vector<int> decided_by(components, -1);
  for (int t = 0; t < count; ++t) {
    for (int i = 0; i < 3; ++i) {
      const int k = triangles_[t].constraint[i];
      if (k < 0) continue;
      const int verdict = triangles_[t].vertex[next(i)] == region_.boundary[k][0] ? 1 : -1;
      const int c = component[t];
      if (side[c] == 0) {
        side[c] = verdict;
        decided_by[c] = k;
      } else if (side[c] != verdict) {
        throw std::invalid_argument("triangulate_region: the loops are not consistently oriented: the same area lies left of " +
                                    edge_name(verdict > 0 ? k : decided_by[c], region_.boundary[verdict > 0 ? k : decided_by[c]]) +
                                    " and right of " +
                                    edge_name(verdict > 0 ? decided_by[c] : k, region_.boundary[verdict > 0 ? decided_by[c] : k]) +
                                    " (outer loops run counter-clockwise, holes clockwise)");
      }
    }
  }
  inside_.assign(count, 0);
  for (int t = 0; t < count; ++t) {
    const Triangle& tri = triangles_[t];
    const bool unbounded = tri.vertex[0] >= n || tri.vertex[1] >= n || tri.vertex[2] >= n;
    if (unbounded && side[component[t]] > 0)
      throw std::invalid_argument("triangulate_region: the area left of " +
                                  edge_name(decided_by[component[t]], region_.boundary[decided_by[component[t]]]) +
                                  " is unbounded (an outer loop runs clockwise?)");
    inside_[t] = side[component[t]] > 0 ? 1 : 0;
  }
}

void Triangulator::restore_delaunay() {
  stack_.clear();
  const int count = static_cast<int>(triangles_.size());
  for (int t = 0; t < count; ++t) {
    if (!inside_[t]) continue;
    for (int i = 0; i < 3; ++i) {
      if (triangles_[t].constraint[i] < 0 && triangles_[t].neighbour[i] > t) stack_.push_back(t * 3 + i);
    }
  }
  while (!stack_.empty()) {
    const int t = stack_.back() / 3;
    const int i = stack_.back() % 3;
    stack_.pop_back();
    const Triangle& tri = triangles_[t];
    if (tri.constraint[i] >= 0) continue;
    const int u = tri.neighbour[i];
    const int q = triangles_[u].vertex[neighbour_edge(t, i)];
    if (incircle(points_[tri.vertex[0]], points_[tri.vertex[1]], points_[tri.vertex[2]], points_[q]) > 0.0) {
      flip(t, i);
      // The quad's four sides may now fail the test: t = (p, a, q) edges 0, 2; u = (q, b, p) edges 0, 2.
      for (const int side : {t * 3 + 0, t * 3 + 2, u * 3 + 0, u * 3 + 2}) {
        if (triangles_[side / 3].constraint[side % 3] < 0) stack_.push_back(side);
      }
    }
  }
}

std::vector<std::array<int, 3>> Triangulator::run() {
  validate_points();
  validate_boundary();
  if (region_.boundary.empty()) return {};
  build_enclosing_triangle();
  insert_points();
  for (int k = 0; k < static_cast<int>(region_.boundary.size()); ++k) recover_constraint(k);
  classify();
  restore_delaunay();
  std::vector<std::array<int, 3>> result;
  for (int t = 0; t < static_cast<int>(triangles_.size()); ++t) {
    if (!inside_[t]) continue;
    std::array<int, 3> v = triangles_[t].vertex;
    std::rotate(v.begin(), std::min_element(v.begin(), v.end()), v.end());
    result.push_back(v);
  }
  std::sort(result.begin(), result.end());
  return result;
}

}  // namespace

std::vector<std::array<int, 3>> triangulate_region(const PlanarRegion& region) {
  return Triangulator(region).run();
}

}  // namespace incise::physics
