#include "physics/promayon/spring_network.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace incise::physics {

namespace {
Vec3 at(const Vector& x, int i) { return x.segment<3>(3 * i); }
}  // namespace

SpringNetwork::SpringNetwork(const Vector& rest, const std::vector<std::vector<int>>& neighbours, const Vector& masses,
                             double stiffness, double dashpot, double spacing)
    : rest_(rest), masses_(masses), stiffness_(stiffness), dashpot_(dashpot), spacing_(spacing) {
  if (rest.size() != 3 * masses.size() || neighbours.size() != static_cast<std::size_t>(masses.size()))
    throw std::invalid_argument("SpringNetwork: rest, neighbours and masses disagree in size");
  if (!(stiffness > 0) || !std::isfinite(stiffness)) throw std::invalid_argument("SpringNetwork: stiffness k_r must be positive");
  if (!(dashpot >= 0) || !std::isfinite(dashpot)) throw std::invalid_argument("SpringNetwork: dashpot must be >= 0");
  for (std::size_t i = 0; i < neighbours.size(); ++i) {
    if (!(masses[static_cast<Eigen::Index>(i)] > 0)) throw std::invalid_argument("SpringNetwork: atom " + std::to_string(i) + " has no mass");
    for (int j : neighbours[i]) {
      if (j <= static_cast<int>(i)) continue;  // each pair once
      const double l = (at(rest, j) - at(rest, static_cast<int>(i))).norm();
      if (!(l > 0)) throw std::invalid_argument("SpringNetwork: atoms " + std::to_string(i) + " and " + std::to_string(j) + " coincide");
      springs_.push_back({static_cast<int>(i), j, l});
    }
  }
  update_rotations(rest_);
}

void SpringNetwork::update_rotations(const Vector& x) {
  tangent_.resize(springs_.size());
  direction_.resize(springs_.size());
  for (std::size_t s = 0; s < springs_.size(); ++s) {
    const Vec3 d = at(x, springs_[s].b) - at(x, springs_[s].a);
    const double l = d.norm();
    const Vec3 u = l > 0 ? Vec3(d / l) : Vec3::UnitX();
    direction_[s] = u;
    const double transverse = l > 0 ? std::max(0.0, 1 - springs_[s].rest_length / l) : 0.0;
    tangent_[s] = stiffness_ * (u * u.transpose() + transverse * (Mat3::Identity() - u * u.transpose()));
  }
}

void SpringNetwork::add_elastic_forces(const Vector& x, Vector& f) const {
  for (const auto& s : springs_) {
    const Vec3 d = at(x, s.b) - at(x, s.a);
    const double l = d.norm();
    if (!(l > 0)) continue;
    const Vec3 force = stiffness_ * (l - s.rest_length) / l * d;  // on a, towards b when stretched
    f.segment<3>(3 * s.a) += force;
    f.segment<3>(3 * s.b) -= force;
  }
}

void SpringNetwork::add_stiffness_product(const Vector& p, Vector& out) const {
  for (std::size_t k = 0; k < springs_.size(); ++k) {
    const Vec3 r = tangent_[k] * (at(p, springs_[k].a) - at(p, springs_[k].b));
    out.segment<3>(3 * springs_[k].a) += r;
    out.segment<3>(3 * springs_[k].b) -= r;
  }
}

void SpringNetwork::add_stiffness_diagonal(Vector& diag) const {
  for (std::size_t k = 0; k < springs_.size(); ++k) {
    diag.segment<3>(3 * springs_[k].a) += tangent_[k].diagonal();
    diag.segment<3>(3 * springs_[k].b) += tangent_[k].diagonal();
  }
}

double SpringNetwork::elastic_energy(const Vector& x) const {
  double e = 0;
  for (const auto& s : springs_) {
    const double stretch = (at(x, s.b) - at(x, s.a)).norm() - s.rest_length;
    e += 0.5 * stiffness_ * stretch * stretch;
  }
  return e;
}

void SpringNetwork::add_damping_product(const Vector& p, Vector& out) const {
  for (std::size_t k = 0; k < springs_.size(); ++k) {
    const Vec3& u = direction_[k];
    const Vec3 r = dashpot_ * u.dot(at(p, springs_[k].a) - at(p, springs_[k].b)) * u;
    out.segment<3>(3 * springs_[k].a) += r;
    out.segment<3>(3 * springs_[k].b) -= r;
  }
}

void SpringNetwork::add_damping_diagonal(Vector& diag) const {
  for (std::size_t k = 0; k < springs_.size(); ++k) {
    const Vec3 d = dashpot_ * direction_[k].cwiseProduct(direction_[k]);
    diag.segment<3>(3 * springs_[k].a) += d;
    diag.segment<3>(3 * springs_[k].b) += d;
  }
}

}  // namespace incise::physics
