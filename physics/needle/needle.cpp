#include "physics/needle/needle.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace incise::physics {

Vec3 VirtualParticle::at(const Vector& x) const {
  Vec3 a = offset;
  for (std::size_t k = 0; k < atoms.size(); ++k) a += weights[k] * x.segment<3>(3 * atoms[k]);
  return a;
}

std::vector<double> inverse_distance_shares(const std::vector<ZoneMember>& zone) {
  std::vector<double> w(zone.size(), 0.0);
  for (std::size_t i = 0; i < zone.size(); ++i)
    if (zone[i].distance < 1e-12) {  // seed §2.3: "if d = 0, only that particle is used"
      w[i] = 1;
      return w;
    }
  double sum = 0;
  for (const auto& m : zone) sum += 1 / m.distance;
  for (std::size_t i = 0; i < zone.size(); ++i) w[i] = (1 / zone[i].distance) / sum;
  return w;
}

Needle::Needle(const NeedleSettings& s, NeedleTissue tissue) : settings_(s), tissue_(std::move(tissue)) {
  const auto positive = [](double v, const char* name) {
    if (!(v > 0) || !std::isfinite(v)) throw std::invalid_argument(std::string("needle: ") + name + " must be positive");
  };
  positive(s.length, "length");
  positive(s.cutting_radius, "cutting_radius");
  positive(s.friction_radius, "friction_radius");
  positive(s.stick_stiffness, "stick_stiffness");
  if (s.nodes < 2) throw std::invalid_argument("needle: nodes must be 2 or more");
  if (!(s.cutting_force >= 0) || !(s.puncture_force >= 0) || !(s.friction_force >= 0))
    throw std::invalid_argument("needle: cutting_force, puncture_force and friction_force must be >= 0");
  grips_.assign(s.nodes, NodeGrip::none);
  particles_.resize(s.nodes);
  zones_.friction.resize(s.nodes);
}

void Needle::cut(const NeedlePose& pose, std::vector<Vec3>& on_tissue, NeedleForces& out) const {
  const auto w = inverse_distance_shares(zones_.cutting);
  for (std::size_t i = 0; i < w.size(); ++i) {
    const int atom = zones_.cutting[i].atom;
    const double share = tissue_.cutting[atom] * w[i];  // C_i
    if (share == 0) continue;
    on_tissue[atom] += share * pose.axis;
    out.cutting += share;
    if (tissue_.boundary[atom]) out.puncturing = true;
  }
}

void Needle::grip(int j, const NeedlePose& pose, const Vector& x, std::vector<Vec3>& on_tissue, NeedleForces& out) {
  const auto& zone = zones_.friction[j];
  VirtualParticle& particle = particles_[j];
  const NodeGrip was = grips_[j];
  if (zone.empty()) {  // the node has left the tissue
    grips_[j] = NodeGrip::none;
    particle = {};
    return;
  }
  const Vec3 node = pose.node(j);
  // Where the virtual particle is now (carried by its last zone), or the node where it enters.
  const Vec3 anchor = was == NodeGrip::none ? node : particle.at(x);
  const auto w = inverse_distance_shares(zone);
  particle.atoms.clear();
  particle.weights.clear();
  Vec3 carried = Vec3::Zero();
  double friction = 0;  // F, the node's friction intensity
  for (std::size_t i = 0; i < zone.size(); ++i) {
    particle.atoms.push_back(zone[i].atom);
    particle.weights.push_back(w[i]);
    carried += w[i] * x.segment<3>(3 * zone[i].atom);
    friction += tissue_.friction[zone[i].atom] * w[i];
  }
  particle.offset = anchor - carried;
  const Vec3 pull = settings_.stick_stiffness * (anchor - node);  // F_v
  const double a = pull.dot(pose.axis);
  const Vec3 lateral = pull - a * pose.axis;
  // A particle the last slip left at |pull| = F holds (its pull recomputed may round above F).
  const bool stick = std::abs(a) <= friction * (1 + 1e-9);
  // The axial force on the needle node and, to the tissue, its opposite by each node's share.
  const double axial = stick ? a : std::copysign(friction, a);
  for (std::size_t i = 0; i < zone.size(); ++i) {
    const int atom = zone[i].atom;
    const double share = stick ? w[i] : (friction > 0 ? tissue_.friction[atom] * w[i] / friction : w[i]);
    on_tissue[atom] -= share * axial * pose.axis + (stick ? w[i] : 0.0) * lateral;
  }
  // Slip: the particle is put back on the shaft beside the node, where its pull is the kinetic
  // friction along the axis and nothing across it.
  if (!stick) particle.offset -= ((a - axial) / settings_.stick_stiffness) * pose.axis + lateral / settings_.stick_stiffness;
  out.friction += axial;
  grips_[j] = stick ? NodeGrip::stick : NodeGrip::slip;
  if (was == NodeGrip::stick && !stick) ++stick_to_slip_;
  if (was == NodeGrip::slip && stick) ++slip_to_stick_;
  (stick ? out.sticking : out.slipping) += 1;
}

NeedleForces Needle::step(const NeedlePose& pose, double axial_speed, const Vector& x) {
  if (pose.nodes != settings_.nodes) throw std::invalid_argument("needle: the pose has " + std::to_string(pose.nodes) + " nodes, the needle " + std::to_string(settings_.nodes));
  if (update_zones(zones_, pose, x, tissue_, settings_)) ++full_scans_;
  NeedleForces out;
  out.in_tissue = !zones_.empty();
  std::vector<Vec3> on_tissue(tissue_.size(), Vec3::Zero());
  std::vector<std::uint8_t> touched(tissue_.size(), 0);
  for (const auto& m : zones_.cutting) touched[m.atom] = 1;
  for (const auto& zone : zones_.friction)
    for (const auto& m : zone) touched[m.atom] = 1;
  if (axial_speed > settings_.rest_speed) cut(pose, on_tissue, out);  // seed: no cutting on retraction
  for (int j = 0; j < settings_.nodes; ++j) grip(j, pose, x, on_tissue, out);
  for (int i = 0; i < tissue_.size(); ++i) {
    if (!touched[i]) continue;
    out.tissue.emplace_back(i, on_tissue[i]);
    out.on_needle -= on_tissue[i];
  }
  out.axial = out.on_needle.dot(pose.axis);
  out.lateral = (out.on_needle - out.axial * pose.axis).norm();
  return out;
}

}  // namespace incise::physics
