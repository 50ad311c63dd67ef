#include "physics/mss/hex_mass_spring.hpp"

#include "physics/mss/baudet_stiffness.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace incise::physics {

namespace {

using Index = Eigen::Index;

Vec3 at(const Vector& x, int node) { return x.segment<3>(3 * static_cast<Index>(node)); }

void check_material(const MassSpringMaterial& m) {
  if (!(m.youngs_modulus > 0) || !std::isfinite(m.youngs_modulus))
    throw std::invalid_argument("mass-spring: E must be positive and finite");
  if (!(m.poisson_ratio >= 0 && m.poisson_ratio < 0.5))
    throw std::invalid_argument("mass-spring: nu must be in [0, 0.5)");
  if (!(m.density > 0) || !std::isfinite(m.density))
    throw std::invalid_argument("mass-spring: rho must be positive and finite");
  if (!(m.damping_ratio >= 0) || !std::isfinite(m.damping_ratio))
    throw std::invalid_argument("mass-spring: the damping ratio must be >= 0");
}

// The guard of digest C.2: a brick whose formulas give k <= 0 is refused, named.
[[noreturn]] void refuse_brick(std::size_t element, const Vec3& size, double nu, const std::string& problem) {
  std::ostringstream out;
  out.precision(4);
  out << "mass-spring: hexahedron " << element << " (" << size.x() << " x " << size.y() << " x " << size.z()
      << " m, aspect ratio " << brick_aspect_ratio(size) << "): " << problem
      << " at nu = " << nu << "; Baudet's formulas need near-cubic bricks (make the cells more cubic)";
  throw std::invalid_argument(out.str());
}

}  // namespace

double mass_spring_explicit_limit(const Vector& masses, const Vector& node_stiffness) {
  double ratio = std::numeric_limits<double>::infinity();
  for (Index i = 0; i < masses.size(); ++i)
    if (node_stiffness[i] > 0) ratio = std::min(ratio, masses[i] / node_stiffness[i]);
  return 2 * std::sqrt(ratio);
}

HexMassSpring::HexMassSpring(const HexMesh& mesh, const MassSpringMaterial& material)
    : rest_(mesh.rest), hexes_(mesh.hexes) {
  check_material(material);
  const Index nodes = rest_.size() / 3;
  if (rest_.size() % 3 != 0 || hexes_.empty()) throw std::invalid_argument("mass-spring: the mesh has no hexahedron");
  for (const auto& hex : hexes_)
    for (int node : hex)
      if (node < 0 || node >= nodes) throw std::invalid_argument("mass-spring: a hexahedron names a node outside the mesh");
  masses_ = Vector::Zero(nodes);
  // Parallel springs of neighbouring bricks are one spring with the summed k (Fléchon §5.3).
  std::map<std::pair<int, int>, double> stiffness;
  double spacing = 0;
  for (std::size_t e = 0; e < hexes_.size(); ++e) {
    const auto& hex = hexes_[e];
    const Vec3 size = hex_edge_lengths(rest_, hex);
    if (!(size.minCoeff() > 0)) refuse_brick(e, size, material.poisson_ratio, "an edge has no length");
    const BrickSprings k = baudet_brick_springs(size, material.youngs_modulus, material.poisson_ratio);
    if (const std::string problem = brick_problem(k); !problem.empty())
      refuse_brick(e, size, material.poisson_ratio, problem);
    bricks_.push_back(k);
    // The axial loads from the springs' resultants S: the corrections on a half-brick's 4 nodes
    // also cross its mid-plane, so the load balancing it is F = S - 8 C^T F (axial_loads).
    const Mat3 balance = Mat3::Identity() + 8 * k.correction.transpose();
    if (material.corrections && !(std::abs(balance.determinant()) > 1e-9))
      refuse_brick(e, size, material.poisson_ratio, "its correction forces leave its axial loads undetermined");
    load_from_springs_.push_back(balance.inverse());
    const auto add = [&](int a, int b, double value) { stiffness[{std::min(a, b), std::max(a, b)}] += value; };
    for (int s = 0; s < 12; ++s) add(hex[kHexEdges[s][0]], hex[kHexEdges[s][1]], k.edge[s / 4]);
    for (const auto& d : kHexDiagonals) add(hex[d[0]], hex[d[1]], k.diagonal);
    const double node_mass = material.density * hex_volume(rest_, hex) / 8;
    for (int node : hex) masses_[node] += node_mass;
    spacing += size.mean() / static_cast<double>(hexes_.size());
  }
  spacing_ = spacing;
  node_stiffness_ = Vector::Zero(nodes);
  springs_.reserve(stiffness.size());
  for (const auto& [pair, k] : stiffness) {
    Spring s;
    s.a = pair.first, s.b = pair.second;
    s.rest_length = (at(rest_, s.b) - at(rest_, s.a)).norm();
    s.stiffness = k;
    const double reduced_mass = masses_[s.a] * masses_[s.b] / (masses_[s.a] + masses_[s.b]);
    s.damping = material.damping_ratio * 2 * std::sqrt(reduced_mass * k);
    node_stiffness_[s.a] += k;
    node_stiffness_[s.b] += k;
    springs_.push_back(s);
  }
  corrections_ = material.corrections;
  tangent_mode_ = material.correction_tangent;
  explicit_limit_ = mass_spring_explicit_limit(masses_, node_stiffness_);
  update_rotations(rest_);
}

void HexMassSpring::update_rotations(const Vector& x) {
  tangent_.resize(springs_.size());
  direction_.resize(springs_.size());
  for (std::size_t s = 0; s < springs_.size(); ++s) {
    const Spring& spring = springs_[s];
    const Vec3 d = at(x, spring.b) - at(x, spring.a);
    const double length = d.norm();
    // A spring crushed to a point keeps its rest direction (any direction would do).
    const Vec3 u = length > 1e-12 * spring.rest_length ? Vec3(d / length)
                                                        : Vec3((at(rest_, spring.b) - at(rest_, spring.a)) / spring.rest_length);
    const Mat3 axial = u * u.transpose();
    // Tangent k [u u^T + (1 - L0 / L)(I - u u^T)]; the transverse term is negative under
    // compression and is dropped there, keeping K positive semi-definite for CG.
    const double transverse = length > spring.rest_length ? 1 - spring.rest_length / length : 0.0;
    tangent_[s] = spring.stiffness * (axial + transverse * (Mat3::Identity() - axial));
    direction_[s] = u;
  }
  if (corrections_) {
    frozen_ = x;
    correction_tangent_stale_ = true;
  }
}

const std::vector<HexMassSpring::BrickMatrix>& HexMassSpring::correction_tangents() const {
  if (!corrections_ || !correction_tangent_stale_) return correction_tangent_;
  correction_tangent_.resize(hexes_.size());
  Vector probe = frozen_;
  const double h = 1e-7 * spacing_;
  for (std::size_t e = 0; e < hexes_.size(); ++e) {
    const auto& hex = hexes_[e];
    for (int column = 0; column < 24; ++column) {
      const Index d = 3 * static_cast<Index>(hex[column / 3]) + column % 3;
      probe[d] = frozen_[d] + h;
      const Eigen::Matrix<double, 24, 1> plus = brick_correction_forces(probe, e);
      probe[d] = frozen_[d] - h;
      const Eigen::Matrix<double, 24, 1> minus = brick_correction_forces(probe, e);
      probe[d] = frozen_[d];
      correction_tangent_[e].col(column) = -(plus - minus) / (2 * h);
    }
  }
  correction_tangent_stale_ = false;
  return correction_tangent_;
}

bool HexMassSpring::has_extra_stiffness() const {
  return corrections_ && tangent_mode_ != CorrectionTangent::explicit_forces;
}

void HexMassSpring::add_extra_stiffness_product(const Vector& p, Vector& out) const {
  if (!has_extra_stiffness()) return;
  const auto& tangents = correction_tangents();
  Eigen::Matrix<double, 24, 1> local, product;
  for (std::size_t e = 0; e < hexes_.size(); ++e) {
    for (int a = 0; a < 8; ++a) local.segment<3>(3 * a) = p.segment<3>(3 * static_cast<Index>(hexes_[e][a]));
    product = tangents[e] * local;
    if (tangent_mode_ == CorrectionTangent::symmetric) product = 0.5 * (product + tangents[e].transpose() * local);
    for (int a = 0; a < 8; ++a) out.segment<3>(3 * static_cast<Index>(hexes_[e][a])) += product.segment<3>(3 * a);
  }
}

void HexMassSpring::add_extra_stiffness_diagonal(Vector& diag) const {
  if (!has_extra_stiffness()) return;
  const auto& tangents = correction_tangents();
  for (std::size_t e = 0; e < hexes_.size(); ++e)
    for (int a = 0; a < 8; ++a)
      diag.segment<3>(3 * static_cast<Index>(hexes_[e][a])) += tangents[e].diagonal().segment<3>(3 * a);
}

void HexMassSpring::add_correction_triplets(std::vector<Eigen::Triplet<double>>& out) const {
  if (!corrections_) return;
  const auto& tangents = correction_tangents();
  out.reserve(out.size() + 576 * hexes_.size());
  const auto dof = [&](std::size_t e, int local) { return 3 * static_cast<Index>(hexes_[e][local / 3]) + local % 3; };
  for (std::size_t e = 0; e < hexes_.size(); ++e)
    for (int c = 0; c < 24; ++c)
      for (int r = 0; r < 24; ++r) out.emplace_back(dof(e, r), dof(e, c), tangents[e](r, c));
}

void HexMassSpring::add_elastic_forces(const Vector& x, Vector& f) const {
  for (const Spring& spring : springs_) {
    const Vec3 d = at(x, spring.b) - at(x, spring.a);
    const double length = d.norm();
    if (!(length > 0)) continue;  // no direction: no force (crushed onto itself)
    // Restoring sign (digest B.1.1: the printed f^e lacks its minus): a stretched spring pulls a towards b.
    const Vec3 force = spring.stiffness * (length - spring.rest_length) / length * d;
    f.segment<3>(3 * static_cast<Index>(spring.a)) += force;
    f.segment<3>(3 * static_cast<Index>(spring.b)) -= force;
  }
  if (corrections_) add_correction_forces(x, f);
}

Vec3 HexMassSpring::axial_loads(const Vector& x, std::size_t e) const {
  const auto& hex = hexes_[e];
  const BrickSprings& k = bricks_[e];
  const auto tension = [&](int a, int b, double stiffness, Vec3& d) {
    d = at(x, hex[b]) - at(x, hex[a]);
    return stiffness * (d.norm() - (at(rest_, hex[b]) - at(rest_, hex[a])).norm());
  };
  Vec3 loads = Vec3::Zero();
  std::array<Vec3, 3> axis{Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  for (int s = 0; s < 12; ++s) {
    Vec3 d;
    loads[s / 4] += tension(kHexEdges[s][0], kHexEdges[s][1], k.edge[s / 4], d);
    axis[s / 4] += d;
  }
  for (auto& a : axis) a.normalize();
  // Each diagonal crosses all three mid-planes: its tension's component along each axis.
  for (const auto& diagonal : kHexDiagonals) {
    Vec3 d;
    const double t = tension(diagonal[0], diagonal[1], k.diagonal, d);
    for (int i = 0; i < 3; ++i) loads[i] += t * std::abs(d.dot(axis[i])) / d.norm();
  }
  return load_from_springs_[e] * loads;
}

Eigen::Matrix<double, 24, 1> HexMassSpring::brick_correction_forces(const Vector& x, std::size_t e) const {
  Eigen::Matrix<double, 24, 1> f = Eigen::Matrix<double, 24, 1>::Zero();
  const auto& hex = hexes_[e];
  const Vec3 loads = axial_loads(x, e);
  for (int j = 0; j < 3; ++j) {
    double along_j = 0;  // 2 sum_i F_ij on every node, outward along j
    for (int i = 0; i < 3; ++i)
      if (i != j) along_j += 2 * bricks_[e].correction(i, j) * loads[i];
    // Local node a's neighbour along x, y, z is a ^ 1, a ^ 3, a ^ 4 (hex_mesh.hpp's order).
    static constexpr int kFlip[3] = {1, 3, 4};
    for (int a = 0; a < 8; ++a) {
      const Vec3 outward = (at(x, hex[a]) - at(x, hex[a ^ kFlip[j]])).normalized();
      f.segment<3>(3 * a) += along_j * outward;
    }
  }
  return f;
}

void HexMassSpring::add_correction_forces(const Vector& x, Vector& f) const {
  for (std::size_t e = 0; e < hexes_.size(); ++e) {
    const Eigen::Matrix<double, 24, 1> brick = brick_correction_forces(x, e);
    for (int a = 0; a < 8; ++a) f.segment<3>(3 * static_cast<Index>(hexes_[e][a])) += brick.segment<3>(3 * a);
  }
}

void HexMassSpring::add_stiffness_product(const Vector& p, Vector& out) const {
  for (std::size_t s = 0; s < springs_.size(); ++s) {
    const Index a = 3 * static_cast<Index>(springs_[s].a), b = 3 * static_cast<Index>(springs_[s].b);
    const Vec3 product = tangent_[s] * (p.segment<3>(a) - p.segment<3>(b));
    out.segment<3>(a) += product;
    out.segment<3>(b) -= product;
  }
}

void HexMassSpring::add_stiffness_triplets(std::vector<Eigen::Triplet<double>>& out) const {
  out.reserve(out.size() + 36 * springs_.size());
  for (std::size_t s = 0; s < springs_.size(); ++s) {
    const Index a = 3 * static_cast<Index>(springs_[s].a), b = 3 * static_cast<Index>(springs_[s].b);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        const double k = tangent_[s](r, c);
        out.emplace_back(a + r, a + c, k);
        out.emplace_back(b + r, b + c, k);
        out.emplace_back(a + r, b + c, -k);
        out.emplace_back(b + r, a + c, -k);
      }
  }
}

void HexMassSpring::add_stiffness_diagonal(Vector& diag) const {
  for (std::size_t s = 0; s < springs_.size(); ++s) {
    diag.segment<3>(3 * static_cast<Index>(springs_[s].a)) += tangent_[s].diagonal();
    diag.segment<3>(3 * static_cast<Index>(springs_[s].b)) += tangent_[s].diagonal();
  }
}

void HexMassSpring::add_damping_product(const Vector& p, Vector& out) const {
  // Damping on the relative velocity projected on the spring, gamma ((v_a - v_b) . u) u
  // (digest B.1.1: the printed f^v uses the norm of the relative velocity, which is no force).
  for (std::size_t s = 0; s < springs_.size(); ++s) {
    const Index a = 3 * static_cast<Index>(springs_[s].a), b = 3 * static_cast<Index>(springs_[s].b);
    const Vec3& u = direction_[s];
    const Vec3 product = springs_[s].damping * u.dot(p.segment<3>(a) - p.segment<3>(b)) * u;
    out.segment<3>(a) += product;
    out.segment<3>(b) -= product;
  }
}

void HexMassSpring::add_damping_diagonal(Vector& diag) const {
  for (std::size_t s = 0; s < springs_.size(); ++s) {
    const Vec3 d = springs_[s].damping * direction_[s].cwiseProduct(direction_[s]);
    diag.segment<3>(3 * static_cast<Index>(springs_[s].a)) += d;
    diag.segment<3>(3 * static_cast<Index>(springs_[s].b)) += d;
  }
}

double HexMassSpring::elastic_energy(const Vector& x) const {
  double energy = 0;
  for (const Spring& spring : springs_) {
    const double stretch = (at(x, spring.b) - at(x, spring.a)).norm() - spring.rest_length;
    energy += 0.5 * spring.stiffness * stretch * stretch;
  }
  return energy;
}

}  // namespace incise::physics
