#include "physics/promayon/shape_memory.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

namespace incise::physics {

namespace {

Vec3 at(const Vector& x, int i) { return x.segment<3>(3 * i); }

// The rest coordinates of P against triplet (a, b, c), or nothing when the three are collinear
// (|N_aN_b x N_aN_c| below a relative 1e-9 of the squared edge, seed §1.4's rejection).
std::optional<Triplet> rest_triplet(const Vector& x, int p, int a, int b, int c) {
  const Vec3 na = at(x, a), e1 = at(x, b) - na, e2 = at(x, c) - na;
  const Vec3 n = e1.cross(e2);
  const double scale = std::max(e1.squaredNorm(), e2.squaredNorm());
  if (!(n.norm() > 1e-9 * scale)) return std::nullopt;
  const Vec3 unit = n.normalized();
  const Vec3 d = at(x, p) - na;
  Triplet t;
  t.atoms = {a, b, c};
  t.beta = d.dot(unit);
  // Q - N_a = s e1 + u e2 in the plane: the 2 x 2 Gram system.
  const Vec3 q = d - t.beta * unit;
  const double g11 = e1.dot(e1), g12 = e1.dot(e2), g22 = e2.dot(e2);
  const double det = g11 * g22 - g12 * g12;
  const double s = (g22 * q.dot(e1) - g12 * q.dot(e2)) / det;
  const double u = (g11 * q.dot(e2) - g12 * q.dot(e1)) / det;
  t.alpha = {1 - s - u, s, u};
  return t;
}

using Offset = std::array<long long, 3>;

// A neighbour's rest offset from P on a grid of 1e-6 of the spacing (exact comparisons).
Offset offset(const Vector& x, int p, int n, double spacing) {
  const Vec3 d = (at(x, n) - at(x, p)) / (1e-6 * spacing);
  return {std::llround(d.x()), std::llround(d.y()), std::llround(d.z())};
}

// TripletSelection::unmirrored: false when the mirror image of (a, b, c) through P is among P's
// neighbours and its sorted offsets are the larger.
bool keep_unmirrored(const Vector& x, int p, const std::vector<int>& nb, int a, int b, int c, double spacing) {
  std::array<Offset, 3> own{offset(x, p, a, spacing), offset(x, p, b, spacing), offset(x, p, c, spacing)};
  std::array<Offset, 3> mirror{};
  for (int k = 0; k < 3; ++k) {
    mirror[k] = {-own[k][0], -own[k][1], -own[k][2]};
    const bool present = std::any_of(nb.begin(), nb.end(), [&](int n) { return offset(x, p, n, spacing) == mirror[k]; });
    if (!present) return true;
  }
  std::sort(own.begin(), own.end());
  std::sort(mirror.begin(), mirror.end());
  return own > mirror;
}

}  // namespace

ShapeMemory::ShapeMemory(const Vector& rest, const std::vector<std::vector<int>>& neighbours, const Vector& masses,
                         double stiffness, double spacing, TripletSelection selection)
    : rest_(rest), masses_(masses), stiffness_(stiffness), spacing_(spacing), neighbours_(neighbours) {
  const auto n = static_cast<std::size_t>(masses.size());
  if (rest.size() != 3 * masses.size() || neighbours.size() != n)
    throw std::invalid_argument("ShapeMemory: rest, neighbours and masses disagree in size");
  if (!(stiffness > 0) || !std::isfinite(stiffness)) throw std::invalid_argument("ShapeMemory: stiffness k_e must be positive");
  if (selection == TripletSelection::unmirrored && !(spacing > 0))
    throw std::invalid_argument("ShapeMemory: the unmirrored triplet selection needs a positive spacing");
  weights_.resize(n);
  normal_.resize(n);
  triplets_per_atom_.assign(n, 0);
  diagonal_ = Vector::Ones(static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i) {
    if (!(masses[static_cast<Eigen::Index>(i)] > 0)) throw std::invalid_argument("ShapeMemory: atom " + std::to_string(i) + " has no mass");
    const auto& nb = neighbours[i];
    const std::size_t k = nb.size();
    if (k < 3) throw std::invalid_argument("ShapeMemory: atom " + std::to_string(i) + " has " + std::to_string(k) + " neighbours (3 needed)");
    std::vector<double> sum(k, 0.0);
    int m = 0;
    for (std::size_t a = 0; a < k; ++a)
      for (std::size_t b = a + 1; b < k; ++b)
        for (std::size_t c = b + 1; c < k; ++c) {
          if (selection == TripletSelection::unmirrored &&
              !keep_unmirrored(rest, static_cast<int>(i), nb, nb[a], nb[b], nb[c], spacing))
            continue;
          auto t = rest_triplet(rest, static_cast<int>(i), nb[a], nb[b], nb[c]);
          if (!t) continue;
          ++m;
          sum[a] += t->alpha[0];
          sum[b] += t->alpha[1];
          sum[c] += t->alpha[2];
          if (std::abs(t->beta) > 1e-12 * spacing) normal_[i].push_back(*t);
        }
    if (m == 0) throw std::invalid_argument("ShapeMemory: atom " + std::to_string(i) + " has no non-collinear triplet of neighbours");
    triplets_per_atom_[i] = m;
    for (double& s : sum) s /= m;
    for (auto& t : normal_[i]) t.beta /= m;  // stored pre-divided: the mean's share
    weights_[i] = std::move(sum);
  }
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t a = 0; a < neighbours_[i].size(); ++a) diagonal_[neighbours_[i][a]] += weights_[i][a] * weights_[i][a];
}

std::size_t ShapeMemory::triplet_count() const {
  std::size_t total = 0;
  for (int m : triplets_per_atom_) total += static_cast<std::size_t>(m);
  return total;
}

Vec3 ShapeMemory::attractor(const Vector& x, int i) const {
  Vec3 p = Vec3::Zero();
  const auto& nb = neighbours_[static_cast<std::size_t>(i)];
  const auto& w = weights_[static_cast<std::size_t>(i)];
  for (std::size_t a = 0; a < nb.size(); ++a) p += w[a] * at(x, nb[a]);
  for (const Triplet& t : normal_[static_cast<std::size_t>(i)]) {
    const Vec3 na = at(x, t.atoms[0]);
    const Vec3 n = (at(x, t.atoms[1]) - na).cross(at(x, t.atoms[2]) - na);
    const double len = n.norm();
    if (len > 0) p += (t.beta / len) * n;  // a flattened triplet contributes its plane only
  }
  return p;
}

void ShapeMemory::add_elastic_forces(const Vector& x, Vector& f) const {
  for (int i = 0; i < node_count(); ++i) {
    const Vec3 force = stiffness_ * (attractor(x, i) - at(x, i));
    f.segment<3>(3 * i) += force;
    const auto& nb = neighbours_[static_cast<std::size_t>(i)];
    const auto& w = weights_[static_cast<std::size_t>(i)];
    for (std::size_t a = 0; a < nb.size(); ++a) f.segment<3>(3 * nb[a]) -= w[a] * force;
  }
}

void ShapeMemory::add_stiffness_product(const Vector& p, Vector& out) const {
  for (int i = 0; i < node_count(); ++i) {
    Vec3 r = at(p, i);
    const auto& nb = neighbours_[static_cast<std::size_t>(i)];
    const auto& w = weights_[static_cast<std::size_t>(i)];
    for (std::size_t a = 0; a < nb.size(); ++a) r -= w[a] * at(p, nb[a]);
    out.segment<3>(3 * i) += stiffness_ * r;
    for (std::size_t a = 0; a < nb.size(); ++a) out.segment<3>(3 * nb[a]) -= stiffness_ * w[a] * r;
  }
}

void ShapeMemory::add_stiffness_diagonal(Vector& diag) const {
  for (int i = 0; i < node_count(); ++i) diag.segment<3>(3 * i).array() += stiffness_ * diagonal_[i];
}

double ShapeMemory::elastic_energy(const Vector& x) const {
  double e = 0;
  for (int i = 0; i < node_count(); ++i) e += 0.5 * stiffness_ * (attractor(x, i) - at(x, i)).squaredNorm();
  return e;
}

}  // namespace incise::physics
