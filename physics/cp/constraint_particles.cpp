#include "physics/cp/constraint_particles.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>

namespace incise::physics {

namespace {

using Index = Eigen::Index;

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("constraint particles: " + what);
}

void check_settings(const ConstraintParticleSettings& s) {
  auto non_negative = [](double v) { return std::isfinite(v) && v >= 0; };
  require(std::isfinite(s.density) && s.density > 0, "density must be positive");
  require(non_negative(s.distance_stiffness), "distance_stiffness must be finite and >= 0");
  require(non_negative(s.area_stiffness), "area_stiffness must be finite and >= 0");
  require(non_negative(s.volume_stiffness), "volume_stiffness must be finite and >= 0");
  require(non_negative(s.damping_coefficient), "damping must be finite and >= 0");
}

// Appends the constraint with its rest measure; `stiffness` is its k, times the rest measure
// when `times_rest` (per_volume's area and volume constraints: k_A A0, k_V V0).
void add_kind(std::vector<Constraint>& out, ConstraintKind kind, const std::array<int, 4>& nodes, double stiffness,
              bool times_rest, const Vector& rest, const char* what, std::size_t index) {
  Constraint c{kind, nodes, 0, stiffness};
  c.rest = constraint_measure(c, rest);
  if (!(c.rest > 0)) {
    std::ostringstream message;
    message << what << " " << index << " has rest measure " << c.rest << " (a degenerate or inverted tet)";
    require(false, message.str());
  }
  if (times_rest) c.stiffness *= c.rest;
  out.push_back(c);
}

}  // namespace

std::vector<std::array<int, 2>> unique_tet_edges(const std::vector<std::array<int, 4>>& tets) {
  static constexpr std::array<std::array<int, 2>, 6> pairs{{{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}}};
  std::map<std::pair<int, int>, int> seen;
  std::vector<std::array<int, 2>> edges;
  for (const auto& t : tets)
    for (const auto& p : pairs) {
      const int a = t[p[0]], b = t[p[1]];
      if (seen.emplace(std::minmax(a, b), 0).second) edges.push_back({a, b});
    }
  return edges;
}

std::vector<std::array<int, 3>> unique_tet_faces(const std::vector<std::array<int, 4>>& tets) {
  static constexpr std::array<std::array<int, 3>, 4> faces{{{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}}};
  std::map<std::array<int, 3>, int> seen;
  std::vector<std::array<int, 3>> out;
  for (const auto& t : tets)
    for (const auto& f : faces) {
      std::array<int, 3> face{t[f[0]], t[f[1]], t[f[2]]};
      std::array<int, 3> key = face;
      std::sort(key.begin(), key.end());
      if (seen.emplace(key, 0).second) out.push_back(face);
    }
  return out;
}

std::vector<double> shared_edge_weights(const std::vector<std::array<int, 4>>& tets, const std::vector<double>& tet_weights) {
  static constexpr std::array<std::array<int, 2>, 6> pairs{{{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}}};
  std::map<std::pair<int, int>, std::size_t> index;
  std::vector<double> out;
  for (std::size_t t = 0; t < tets.size(); ++t)
    for (const auto& p : pairs) {
      const auto [it, fresh] = index.emplace(std::minmax(tets[t][p[0]], tets[t][p[1]]), out.size());
      if (fresh) out.push_back(0);
      out[it->second] += tet_weights[t];
    }
  return out;
}

TetMesh make_box_tets5(Vec3 min, Vec3 max, std::array<int, 3> cells) {
  for (int c : cells) require(c >= 1, "a box needs at least one cell per axis");
  const int nx = cells[0] + 1, ny = cells[1] + 1, nz = cells[2] + 1;
  TetMesh mesh;
  mesh.rest.resize(3 * static_cast<Index>(nx) * ny * nz);
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const Vec3 s(double(i) / cells[0], double(j) / cells[1], double(k) / cells[2]);
        mesh.rest.segment<3>(3 * (i + nx * (j + static_cast<Index>(ny) * k))) = min + s.cwiseProduct(max - min);
      }
  // Corner c = a + 2b + 4d of a cell is its node (i + a, j + b, k + d). Even cells: the central
  // tet on corners 0, 3, 5, 6 and one tet at each of the corners 1, 2, 4, 7; odd cells mirrored.
  static constexpr std::array<std::array<int, 4>, 5> even{{{0, 3, 5, 6}, {1, 0, 3, 5}, {2, 0, 6, 3}, {4, 0, 5, 6}, {7, 3, 6, 5}}};
  static constexpr std::array<std::array<int, 4>, 5> odd{{{1, 2, 4, 7}, {0, 1, 2, 4}, {3, 1, 7, 2}, {5, 1, 4, 7}, {6, 2, 7, 4}}};
  for (int k = 0; k < cells[2]; ++k)
    for (int j = 0; j < cells[1]; ++j)
      for (int i = 0; i < cells[0]; ++i) {
        std::array<int, 8> corner{};
        for (int c = 0; c < 8; ++c) corner[c] = (i + (c & 1)) + nx * ((j + ((c >> 1) & 1)) + ny * (k + ((c >> 2) & 1)));
        for (const auto& local : ((i + j + k) % 2 == 0 ? even : odd)) {
          std::array<int, 4> t{corner[local[0]], corner[local[1]], corner[local[2]], corner[local[3]]};
          const Constraint v{ConstraintKind::volume, t, 0, 0};
          if (constraint_measure(v, mesh.rest) < 0) std::swap(t[2], t[3]);
          mesh.tets.push_back(t);
        }
      }
  return mesh;
}

// per_volume (StiffnessScaling): why a block's stiffness then does not depend on its size.
// Linearised at rest (every C is 0 there) under a homogeneous strain eps, u = eps X, the
// constraints of A.1.3 measure C_D = n^T eps n on an edge of rest direction n (eq. 3.1),
// C_V = tr eps on a tet (eq. 3.6, the 1/V0 of A.5.1 restored) and C_A = the in-plane trace of
// eps on a triangle (eq. 3.3). The energy sum k C^2 / 2 (eq. 1.8) with the per_volume k regroups
// tet by tet:
//   E = sum_t V_t [k_D sum_{e in t} (n_e^T eps n_e)^2 + k_V (tr eps)^2] / 2
//       + sum_f A_f k_A (tr_f eps)^2 / 2,
// each tet's energy density fixed by its own shape, whatever the tets around it: a box of n^3
// cells, a one-cell beam and the periodic lattice have the same energy per volume in the affine
// field, skin and interior alike, and the membrane the same energy per area. With one k per
// constraint instead, an edge's k is shared by the tets around it (4 cubes round an axis edge
// inside, 1 on a box's edge), so per tet the skin's springs are up to 4 x the bulk's. What is
// left is the relaxation away from the affine field (each tet's six springs are anisotropic and
// the 5-tet split alternates), which the skin constrains less than the bulk: a few % on a
// one-cell beam (test_constraint_particles_accuracy). Moduli of the lattice from k_D and k_V:
// bench/accuracy_constraint_particles.hpp's homogenisation.
ConstraintParticles::ConstraintParticles(const TetMesh& mesh, const ConstraintParticleSettings& settings)
    : settings_(settings), rest_(mesh.rest), tets_(mesh.tets) {
  check_settings(settings);
  require(!tets_.empty(), "the mesh has no tetrahedra");
  const Index n = rest_.size() / 3;
  masses_ = Vector::Zero(n);
  std::vector<double> volumes(tets_.size());
  for (std::size_t t = 0; t < tets_.size(); ++t) {
    for (int a : tets_[t]) require(a >= 0 && a < n, "tet " + std::to_string(t) + " names a node out of range");
    const double v = constraint_measure({ConstraintKind::volume, tets_[t], 0, 0}, rest_);
    require(v > 0, "tet " + std::to_string(t) + " has signed volume " + std::to_string(v) + " at rest");
    volumes[t] = v;
    for (int a : tets_[t]) masses_[a] += settings.density * v / 4;  // Alg. 3.1: |V| rho split equally
  }
  for (Index i = 0; i < n; ++i) require(masses_[i] > 0, "node " + std::to_string(i) + " is in no tet");

  const bool per_volume = settings.scaling == StiffnessScaling::per_volume;
  const auto edges = unique_tet_edges(tets_);
  const std::vector<double> shared = per_volume ? shared_edge_weights(tets_, volumes) : std::vector<double>(edges.size(), 1.0);
  double length = 0;
  for (std::size_t e = 0; e < edges.size(); ++e) {
    const std::array<int, 4> nodes{edges[e][0], edges[e][1], 0, 0};
    const double d0 = constraint_measure({ConstraintKind::distance, nodes, 0, 0}, rest_);
    require(d0 > 0, "edge " + std::to_string(e) + " has zero length");
    edges_.push_back({edges[e][0], edges[e][1], d0});
    length += d0;
    if (settings.distance_stiffness > 0)
      add_kind(constraints_, ConstraintKind::distance, nodes, settings.distance_stiffness * shared[e], false, rest_, "edge", e);
  }
  spacing_ = length / static_cast<double>(edges_.size());
  if (settings.area_stiffness > 0) {
    const auto faces = settings.area_on_every_face ? unique_tet_faces(tets_) : boundary_triangles(tets_);
    for (std::size_t f = 0; f < faces.size(); ++f)
      add_kind(constraints_, ConstraintKind::area, {faces[f][0], faces[f][1], faces[f][2], 0}, settings.area_stiffness,
               per_volume, rest_, "triangle", f);
  }
  if (settings.volume_stiffness > 0)
    for (std::size_t t = 0; t < tets_.size(); ++t)
      add_kind(constraints_, ConstraintKind::volume, tets_[t], settings.volume_stiffness, per_volume, rest_, "tet", t);
  update_rotations(rest_);
  Vector node_stiffness = Vector::Zero(n);
  for (std::size_t c = 0; c < constraints_.size(); ++c)
    for (int a = 0; a < constraint_arity(constraints_[c].kind); ++a)
      node_stiffness[constraints_[c].nodes[a]] += constraints_[c].stiffness * gradient_[c][a].squaredNorm();
  explicit_limit_ = std::numeric_limits<double>::infinity();
  for (Index i = 0; i < n; ++i)
    if (node_stiffness[i] > 0) explicit_limit_ = std::min(explicit_limit_, 2 * std::sqrt(masses_[i] / node_stiffness[i]));
}

void ConstraintParticles::update_rotations(const Vector& x) {
  gradient_.resize(constraints_.size());
  for (std::size_t c = 0; c < constraints_.size(); ++c) constraint_gradient(constraints_[c], x, gradient_[c]);
}

void ConstraintParticles::add_elastic_forces(const Vector& x, Vector& f) const {
  std::array<Vec3, 4> g;
  for (const Constraint& c : constraints_) {
    const double value = constraint_gradient(c, x, g);
    for (int a = 0; a < constraint_arity(c.kind); ++a) f.segment<3>(3 * c.nodes[a]) -= c.stiffness * value * g[a];
  }
}

double ConstraintParticles::elastic_energy(const Vector& x) const {
  double energy = 0;
  std::array<Vec3, 4> g;
  for (const Constraint& c : constraints_) {
    const double value = constraint_gradient(c, x, g);
    energy += 0.5 * c.stiffness * value * value;
  }
  return energy;
}

// out += scale g (g . p) for one constraint's frozen gradient g.
namespace {
void add_rank_one(const Constraint& c, const std::array<Vec3, 4>& g, double scale, const Vector& p, Vector& out) {
  const int arity = constraint_arity(c.kind);
  double dot = 0;
  for (int a = 0; a < arity; ++a) dot += g[a].dot(p.segment<3>(3 * c.nodes[a]));
  for (int a = 0; a < arity; ++a) out.segment<3>(3 * c.nodes[a]) += scale * dot * g[a];
}
}  // namespace

void ConstraintParticles::add_stiffness_product(const Vector& p, Vector& out) const {
  for (std::size_t c = 0; c < constraints_.size(); ++c) add_rank_one(constraints_[c], gradient_[c], constraints_[c].stiffness, p, out);
}

void ConstraintParticles::add_stiffness_diagonal(Vector& diag) const {
  for (std::size_t c = 0; c < constraints_.size(); ++c)
    for (int a = 0; a < constraint_arity(constraints_[c].kind); ++a)
      diag.segment<3>(3 * constraints_[c].nodes[a]) += constraints_[c].stiffness * gradient_[c][a].cwiseAbs2();
}

void ConstraintParticles::add_damping_product(const Vector& p, Vector& out) const {
  const double k = settings_.damping_coefficient;
  if (k <= 0) return;
  if (settings_.damping == ParticleDamping::relative) {
    for (const StretchEdge& e : edges_) {
      const Vec3 d = k * (p.segment<3>(3 * e.a) - p.segment<3>(3 * e.b));
      out.segment<3>(3 * e.a) += d;
      out.segment<3>(3 * e.b) -= d;
    }
    return;
  }
  for (std::size_t c = 0; c < constraints_.size(); ++c) add_rank_one(constraints_[c], gradient_[c], k, p, out);
}

void ConstraintParticles::add_damping_diagonal(Vector& diag) const {
  const double k = settings_.damping_coefficient;
  if (k <= 0) return;
  if (settings_.damping == ParticleDamping::relative) {
    for (const StretchEdge& e : edges_) {
      diag.segment<3>(3 * e.a).array() += k;
      diag.segment<3>(3 * e.b).array() += k;
    }
    return;
  }
  for (std::size_t c = 0; c < constraints_.size(); ++c)
    for (int a = 0; a < constraint_arity(constraints_[c].kind); ++a)
      diag.segment<3>(3 * constraints_[c].nodes[a]) += k * gradient_[c][a].cwiseAbs2();
}

int ConstraintParticles::inverted_tets(const Vector& x) const {
  int count = 0;
  for (const auto& t : tets_)
    if (constraint_measure({ConstraintKind::volume, t, 0, 0}, x) < 0) ++count;
  return count;
}

double ConstraintParticles::volume(const Vector& x) const {
  double total = 0;
  for (const auto& t : tets_) total += constraint_measure({ConstraintKind::volume, t, 0, 0}, x);
  return total;
}

}  // namespace incise::physics
