// What the physics thread tells the haptic thread each step: a local linearisation of the
// tool-tissue contact around the tool's current pose, small enough to evaluate at 1 kHz with
// the device's newest pose between two physics steps (DESIGN.md; seed 004 §7.1.4 proposes
// penalty or compliance contact forces and extrapolation).
//
// Each contact is a half-space: the tissue surface through `point` with outward `normal`. The
// tool reaches `reach` metres past the device's reference point towards the tissue (a probe's
// radius, 0 for a point tool), so the penetration at device position x is
//     depth = reach - (x - point) . normal,
// and the force on the hand, when depth > 0, is along +normal with magnitude
//     k_eff * depth,   k_eff = 1 / (1 / stiffness + compliance)
// i.e. the tool's penalty spring (stiffness, N/m) in series with the tissue's local
// compliance at that point (m/N: how far the surface yields per newton, from the physics
// model's own linearisation), so a soft organ feels soft even with a stiff penalty.
//
// The model also carries the tool proxy (the tool as physics placed it, with its velocity) for
// the virtual coupling; the loop extrapolates it from `time_ns` by the velocity (first-order
// hold, not the zero-order hold at scene rate that makes forces step). When physics rebuilds
// the model in the step a cut changes the topology, the next tick starts using it: the loop
// fades each new model in over one physics step (HapticLoopConfig::blend_ns; a model that
// interrupts a fade takes over from the blend in progress, model_fade.hpp), so no pre-cut
// contact outlasts the fade, and none ends in a jump.
//
// Fixed capacity, trivially copyable: published through TripleBuffer<ContactModel>.
#pragma once

#include <array>
#include <cstdint>

#include "haptics/device.hpp"
#include "haptics/triple_buffer.hpp"

namespace incise::haptics {

struct ContactPoint {
  Vector3 point{};        // m, on the tissue surface, world frame
  Vector3 normal{0, 0, 1};  // unit, out of the tissue
  double reach = 0;       // m, tool extent past the device reference point (probe radius)
  double stiffness = 0;   // N/m, > 0
  double compliance = 0;  // m/N, >= 0
};

// The tissue's resistance to a blade that is cutting (physics/cut/cutting_resistance.hpp:
// the toughness times the engaged edge length, plus the flanks' friction, Mahvash and
// Hayward 2004), as physics found it at the model's step: `force` is the level at which the
// tissue ahead of the edge ruptures, `direction` the blade's motion then. The loop renders it
// with a state of its own (haptics/cutting_proxy.hpp): the tissue ahead of the edge loads like
// a spring of `stiffness` along `direction` until its force reaches `force`, then the crack
// front advances with the hand at that force; the two phases of Mahvash and Hayward, so the
// force builds up with the hand's motion rather than stepping with its speed.
struct CuttingResistance {
  Vector3 direction{1, 0, 0};  // unit
  double force = 0;            // N, >= 0; 0: not cutting
  double stiffness = 500;      // N/m, > 0
};

// A needle in the tissue (seed 002 §2.3; engine/haptic_session.cpp builds it from the needle's
// zones), as the hand meets it at 1 kHz (haptics/needle_proxy.hpp): along the shaft, a friction
// spring of `stiffness` that slips at `insert_force` pushing in (the cutting zone's intensity C
// plus the nodes' kinetic friction) or at `retract_force` pulling out (friction only: no cutting
// on retraction); across it, the tissue's grip, a spring of the same stiffness pulling the
// device's reference point (the tip) back onto the line through `line` along `axis`. All zero
// (stiffness 0) while the needle is outside the tissue.
struct NeedleResistance {
  Vector3 axis{0, 0, -1};      // unit, the way the needle goes in (hub to tip)
  Vector3 line{};              // m, a point of the line the tissue holds the tip on
  double insert_force = 0;     // N, >= 0
  double retract_force = 0;    // N, >= 0
  double stiffness = 0;        // N/m, >= 0; 0: the needle is not in the tissue
};

struct ContactModel {
  static constexpr int kCapacity = 16;
  std::array<ContactPoint, kCapacity> contacts{};
  int count = 0;

  // The domain of the linearisation: the contacts hold near the tool position they were built
  // at. Beyond valid_radius / 2 from `linearised_at` their force fades linearly to zero at
  // valid_radius (continuously: no step when the hand leaves the domain), so a model that
  // physics has not refreshed while the hand moved on (physics slower than real time) renders
  // nothing rather than a surface that is no longer where the hand is. 0: no limit.
  Vector3 linearised_at{};  // m
  double valid_radius = 0;  // m, >= 0

  CuttingResistance cutting{};
  NeedleResistance needle{};

  bool has_proxy = false;  // false: no tool proxy yet, the coupling force is zero
  Vector3 proxy_position{};  // m
  Vector3 proxy_velocity{};  // m/s
  std::int64_t time_ns = 0;  // haptic clock time the proxy position refers to
  std::uint64_t step = 0;    // physics step that built it (for logs and tests)
};

// Throws std::invalid_argument naming the field (e.g. "contacts[2].normal is not unit
// (|n| = 0.5)") on a non-finite number, a count outside [0, kCapacity], a non-unit normal,
// stiffness <= 0 or compliance < 0, a needle with a negative level or stiffness or, in the
// tissue, a non-unit axis. Physics calls it before publishing.
void validate(const ContactModel& model);

// Force on the hand (N) of the model's contacts at device position x, with the velocity x_dot
// (m/s) and the loop's period T (s) for the contact damping (see haptic_loop.hpp: each active
// contact's normal force gets a damper of k_eff * T, twice Colgate's bound). The normal force
// is never negative (tissue pushes, it does not pull).
Vector3 contact_force(const ContactModel& model, const Vector3& x, const Vector3& x_dot, double period_s);

// The model's weight at x: 1 within half its domain, fading linearly to 0 at valid_radius.
double domain_weight(const ContactModel& model, const Vector3& x);

// The publication channel: physics writes, the haptic loop reads.
using ContactChannel = TripleBuffer<ContactModel>;

}  // namespace incise::haptics
