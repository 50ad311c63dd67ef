// A rigid needle in a deformable body, without collision detection or remeshing (Marchal 2006;
// seed 002 §2.3, E.4 §4.2 Alg. 2). Each step, with the needle at its new pose and the tissue
// where the last step left it:
//   1. the zones (needle_zones.hpp) are updated through the neighbours of their members;
//   2. cutting / puncture, only while the needle advances (none on retraction): over the
//      cutting zone's n nodes at distances d_i from the tip,
//        C = sum_i k_c^i / d_i / sum_i 1/d_i,   C_i = k_c^i / d_i / sum_j 1/d_j   (sum C_i = C),
//      C_i pushes node i along the axis and -C resists the needle (a node at d = 0 takes it
//      all); the boundary's larger k_c is the puncture;
//   3. friction and stick-slip, per needle node j with a friction zone: its intensity
//      F = sum_i k_f^i / d_i / sum_i 1/d_i, and a virtual tissue particle, created where the
//      node entered the tissue and carried by the zone's nodes (their inverse-distance weights
//      w_i: A = sum_i w_i x_i + o, re-expressed over the new members every step). Its pull on
//      the node is F_v = k_v (A - p_j). The axial part a = F_v . axis is static friction while
//      |a| <= F: the node sticks, a goes to the needle and -a w_i to the tissue. Beyond F the node
//      slips: kinetic friction F sign(a) goes to the needle, -F_i sign(a) to the tissue
//      (F_i = k_f^i w_i), and the particle is put back beside the node on the shaft, where its
//      pull is F along the axis and nothing across. While the node sticks the lateral part of
//      F_v acts too (the seed's whole virtual force in stick; the shaft's lateral constraint).
// Every force on the tissue has its opposite on the needle: the needle's force is minus their
// sum (to round-off).
//
// [interp.] Where this departs from the seed's text: the virtual particle follows its zone
// through inverse-distance weights (a translation of the zone carries it exactly; its rotation
// is ignored) rather than the shape memory's triplet coordinates (§1.4), which need three
// non-collinear zone nodes; it is kept while the node sticks and re-anchored by the slip, rather
// than put back on the node every step, so that a needle at rest is held (stick) and a moving
// one slides with a friction of F, not of a sawtooth below it; and stick / slip compares the
// axial part of F_v with F (the seed: all of it).
#pragma once

#include "physics/needle/needle_settings.hpp"
#include "physics/needle/needle_tissue.hpp"
#include "physics/needle/needle_zones.hpp"

#include <cstdint>
#include <utility>
#include <vector>

namespace incise::physics {

enum class NodeGrip : std::uint8_t { none, stick, slip };

// A needle node's virtual tissue particle: A = sum_i weights_i x_{atoms_i} + offset.
struct VirtualParticle {
  std::vector<int> atoms;
  std::vector<double> weights;
  Vec3 offset = Vec3::Zero();
  Vec3 at(const Vector& x) const;
};

struct NeedleForces {
  std::vector<std::pair<int, Vec3>> tissue;  // force on each tissue node, increasing node, N
  Vec3 on_needle = Vec3::Zero();             // the tissue's force on the needle, N (= -sum of `tissue`)
  double cutting = 0;                        // C, N (0 when not advancing)
  double friction = 0;                       // the nodes' axial friction (static and kinetic) along the axis, N
  double axial = 0;                          // on_needle . axis, N (negative: resisting insertion)
  double lateral = 0;                        // |on_needle - axial axis|, N
  bool puncturing = false;                   // a boundary node takes part of the cutting force
  bool in_tissue = false;                    // some zone holds a tissue node
  int sticking = 0, slipping = 0;            // needle nodes in each state after the step
};

class Needle {
 public:
  // Throws std::invalid_argument naming the setting that is out of range.
  Needle(const NeedleSettings& settings, NeedleTissue tissue);

  // One step: the needle at `pose` (the step's end), advancing along its axis at
  // `axial_speed` (m/s; negative: retracting), the tissue at `x` (3n, the step's start).
  NeedleForces step(const NeedlePose& pose, double axial_speed, const Vector& x);

  const NeedleSettings& settings() const { return settings_; }
  const NeedleTissue& tissue() const { return tissue_; }
  const NeedleZones& zones() const { return zones_; }
  const std::vector<NodeGrip>& grips() const { return grips_; }
  const std::vector<VirtualParticle>& particles() const { return particles_; }
  long stick_to_slip() const { return stick_to_slip_; }
  long slip_to_stick() const { return slip_to_stick_; }
  long full_scans() const { return full_scans_; }

 private:
  void cut(const NeedlePose& pose, std::vector<Vec3>& on_tissue, NeedleForces& out) const;
  void grip(int j, const NeedlePose& pose, const Vector& x, std::vector<Vec3>& on_tissue, NeedleForces& out);

  NeedleSettings settings_;
  NeedleTissue tissue_;
  NeedleZones zones_;
  std::vector<NodeGrip> grips_;
  std::vector<VirtualParticle> particles_;
  long stick_to_slip_ = 0, slip_to_stick_ = 0, full_scans_ = 0;
};

// Inverse-distance shares of the zone's members: w_i = (1/d_i) / sum_j (1/d_j); a member at
// d = 0 (below 1e-12 m) takes the whole share (the first such). Empty for an empty zone.
std::vector<double> inverse_distance_shares(const std::vector<ZoneMember>& zone);

}  // namespace incise::physics
