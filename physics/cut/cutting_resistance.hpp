// The tissue's resistance to the blade, by fracture mechanics (Mahvash and Hayward 2004,
// "Haptic rendering of cutting: a fracture mechanics approach", Haptics-e 2(3)): an engaged
// edge first deforms the tissue like a probe; the crack starts when the work the edge has done
// on the tissue reaches the energy the crack's first advance would take (onset); from then on
// the crack advances with the edge and each metre of edge that advances by dx opens dx metres
// squared of crack, which takes G_c dx joules: the steady force against the motion is G_c
// times the engaged edge length, plus the friction of the flanks it slides between.
#pragma once

#include "physics/core/executor.hpp"
#include "physics/core/model.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace incise::physics {

// Fracture toughness of liver-like tissue, J/m^2. Measured liver toughness is of order
// 100-300 J/m^2 (cutting tests on liver; the model is Mahvash and Hayward 2004); 200 is the
// middle of that range, the default of a scene material's `toughness`.
inline constexpr double kLiverToughness = 200;
// Coulomb-like friction of the flanks per metre of engaged edge, N/m: the flanks' contact
// (area, hence normal load) grows with the engaged length. An assumption (a tenth of the
// toughness), not a measured figure; the tool key `flank_friction` sets it.
inline constexpr double kDefaultFlankFriction = 20;

struct CuttingMaterial {
  double toughness = kLiverToughness;             // G_c, J/m^2
  double flank_friction = kDefaultFlankFriction;  // N per m of engaged edge
};

// The blade's engagement, kept from step to step (part of the simulation's state).
struct CuttingState {
  bool cutting = false;  // onset reached: the crack advances with the edge
  double work = 0;       // J, done by the edge's contact on the tissue since the onset began
  // The edge (world) at the start of the first pressing step, where it met the tissue: the
  // cut's first sample in the step the onset starts it (BladeSweep::entry); empty otherwise.
  std::vector<Vec3> entry;
};

// A piece of the edge at the step's end: its midpoint, unit tangent, length, its motion over
// the step, and whether it is engaged (inside the tissue, or within `reach` of its surface).
struct EdgePiece {
  Vec3 point = Vec3::Zero();
  Vec3 tangent = Vec3::UnitZ();
  double length = 0;
  Vec3 motion = Vec3::Zero();
  bool engaged = false;
};

// The edge (a polyline, the same points at the step's start and end) cut into pieces no
// longer than `spacing`.
std::vector<EdgePiece> edge_pieces(const std::vector<Vec3>& start, const std::vector<Vec3>& end, double spacing);

// Marks the pieces whose point is inside a body's outer surface or within `reach` of it. The
// side is the nearest outer triangle's (its face normal against the offset from its closest
// point; exact for a closed surface away from its creases), cut faces (`cut_face` 1) left out:
// a blade in its own cut is still in the tissue. hint (optional, in and out): the triangles
// nearest to the pieces at the previous call, which only spare work (nearest_triangles).
void mark_engaged(const Vector& positions, const std::vector<std::array<int, 3>>& surface,
                  const std::vector<std::uint8_t>& cut_face, double reach, std::vector<EdgePiece>& pieces,
                  std::vector<int>* hint = nullptr, Executor& executor = serial_executor());

struct CuttingForce {
  Vec3 on_tool = Vec3::Zero();  // N, against the edge's motion
  double engaged_length = 0;    // m
  double crack_area = 0;        // m^2 opened over the step
};

// Steady cutting: each engaged piece of length l moving by m (m_perp: across the edge) is
// resisted by G_c l along -m_perp (its work G_c l |m_perp| is the toughness times the crack
// area it opens) and by the flanks' friction f l along -m. A piece at rest feels neither (the
// Coulomb friction's static part is left out: a resting blade is not pushed back).
CuttingForce cutting_force(const std::vector<EdgePiece>& pieces, const CuttingMaterial& material);

// The onset's threshold, J: the toughness times the area the crack's first advance opens, the
// engaged length across the edge's motion (at least the edge's rounded width, 2 radius) times
// `advance` (the cut's resolution: its sweep is sampled every half particle spacing).
double onset_work(double engaged_width, double radius, double advance, double toughness);

}  // namespace incise::physics
