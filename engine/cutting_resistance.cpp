// The tissue's resistance to the blade (Mahvash and Hayward 2004; the model is
// physics/cut/cutting_resistance.hpp), a stage of World::step between take_tool_input and the
// cut stages, and the onset's work after the solve.
//
// An engaged blade goes through two phases. Pressing: the edge acts as a probe (penalty
// contact of its segments, held wherever it went a radius inside when it presses across
// itself: engine/contact.cpp), the tissue dimples, no cut stage sees the
// blade engaged; the work its contact does on the tissue, F . (dx_blade - dx_body) with dx_body
// the body's mass centre's motion (the tissue's own frame: a body falling onto a resting
// blade is pressed just the same), adds up. The onset is an energy criterion: cutting begins
// in the step after that work reaches G_c times the area the crack's first advance would open
// (physics::onset_work: the engaged length across the edge's motion, at least its rounded
// width, times half a particle spacing). Cutting: the cut stages run as before (the ideal blade cuts where
// its edge passes) and the edge feels G_c per metre of engaged edge against its motion plus
// the flanks' friction. The blade is driven by the hand's position, so its work over a step,
// F . dx, is exactly G_c times the crack area it opened: the crack advances only as far as
// the hand moves, a slow hand cuts slowly. The cutting force is not applied to the tissue: in
// steady cutting its work goes into the new crack surfaces, not into deformation. When the
// button is released, or no piece of the edge is engaged any more (once the step it left in
// has been cut), the engagement ends and the next one starts pressing again. Everything here
// is a function of the step's state: replays are bit for bit.
#include "engine/world.hpp"

#include <algorithm>
#include <cmath>

namespace incise::engine {

namespace {

// The smallest particle spacing of the cuttable bodies (0: none).
double cut_spacing(const std::vector<Body>& bodies) {
  double spacing = 0;
  for (const auto& body : bodies)
    if (body.cut_model && body.cut_model->spacing > 0)
      spacing = spacing > 0 ? std::min(spacing, body.cut_model->spacing) : body.cut_model->spacing;
  return spacing;
}

}  // namespace

void World::resist_cutting(StepStats& stats) {
  tool_.pressing = false;
  tool_.leaving = false;
  tool_.engaged_length = 0;
  tool_.onset_width = 0;
  tool_.cutting_force.setZero();
  if (!blade()) return;
  const double spacing = cut_spacing(bodies_);
  if (!stats.blade_engaged || tool_.blade_poses.size() < 2 || !(spacing > 0)) {
    tool_.cutting = {};
    return;
  }
  // The edge in pieces of a quarter spacing at the step's end, each with its motion over the
  // step, engaged where it is in a cuttable body or touches it (within the blade's radius).
  std::vector<physics::EdgePiece> pieces =
      physics::edge_pieces(tool_.blade_poses.front(), tool_.blade_poses.back(), 0.25 * spacing);
  engaged_hints_.resize(bodies_.size());
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const auto& body = bodies_[b];
    if (!body.cut) continue;
    const physics::Vector& x = body.data.embedding ? body.data.surface_positions : body.data.state.positions;
    physics::mark_engaged(x, body.data.surface, body.data.render_cut_face, tool_.radius, pieces, &engaged_hints_[b], body.threads());
  }
  // The engaged length, and its part across the edge's mean motion: the width of the crack its
  // first advance would open (a blade pushed along its own edge opens only its rounded width).
  physics::Vec3 heading = physics::Vec3::Zero();
  for (const auto& piece : pieces) heading += piece.motion;
  const double moved = heading.norm();
  if (moved > 1e-12) heading /= moved;
  double engaged = 0, across = 0;
  for (const auto& piece : pieces) {
    if (!piece.engaged) continue;
    engaged += piece.length;
    across += piece.length * (moved > 1e-12 ? piece.tangent.cross(heading).norm() : 1.0);
  }
  tool_.engaged_length = engaged;
  tool_.onset_width = across;
  stats.engaged_length = engaged;
  // A blade that left the tissue over this step ends its cut once the cut stages have cut the
  // step's sweep (World::step): entering again starts a new onset.
  tool_.leaving = scene_.tool->onset && tool_.cutting.cutting && engaged == 0;
  // Without the onset (tool.onset false) the blade cuts from first contact, the cut stages
  // seeing it as the trajectory says; only its resistance is added.
  if (!scene_.tool->onset) tool_.cutting.cutting = engaged > 0;
  if (scene_.tool->onset && !tool_.cutting.cutting) {
    // Before the onset nothing is cut: the cut stages see the blade disengaged.
    std::fill(tool_.blade_active.begin(), tool_.blade_active.end(), std::uint8_t{0});
    tool_.pressing = engaged > 0;
    // Where the edge meets the tissue: the cut's first sample once the onset starts it.
    if (tool_.pressing && tool_.cutting.entry.empty()) tool_.cutting.entry = tool_.blade_poses.front();
    if (!tool_.pressing) tool_.cutting.work = 0, tool_.cutting.entry.clear();
    stats.blade_pressing = tool_.pressing;
    return;
  }
  if (!tool_.cutting.cutting) return;
  const physics::CuttingForce force = physics::cutting_force(
      pieces, {toughness(), scene_.tool->flank_friction});
  stats.blade_cutting = true;
  tool_.cutting_force = force.on_tool;
  for (int i = 0; i < 3; ++i) {
    stats.cutting_force[i] = force.on_tool[i];
    stats.tool_force[i] += force.on_tool[i];
  }
}

double World::toughness() const {
  // The blade cuts the cuttable bodies: the first one's toughness (scenes cut one body).
  for (std::size_t b = 0; b < bodies_.size(); ++b)
    if (bodies_[b].cut) return scene_.bodies[b].material.toughness;
  return physics::kLiverToughness;
}

std::vector<physics::Vec3> World::mass_centres() const {
  std::vector<physics::Vec3> centres;
  for (const auto& body : bodies_) {
    const auto& m = body.data.mechanics->lumped_masses();
    const auto& x = body.data.state.positions;
    physics::Vec3 sum = physics::Vec3::Zero();
    double mass = 0;
    for (Eigen::Index i = 0; i < m.size(); ++i) sum += m[i] * x.segment<3>(3 * i), mass += m[i];
    centres.push_back(mass > 0 ? physics::Vec3(sum / mass) : physics::Vec3::Zero());
  }
  return centres;
}

void World::advance_onset(const std::vector<physics::Vec3>& centres_before, StepStats& stats) {
  // The contact's force on the tissue is -tool_force; the edge moved by the mean of its points'
  // motion, the tissue by its mass centre's (the first cuttable body's: the one pressed on).
  const auto& start = tool_.blade_poses.front();
  const auto& end = tool_.blade_poses.back();
  physics::Vec3 blade_motion = physics::Vec3::Zero();
  for (std::size_t i = 0; i < end.size(); ++i) blade_motion += (end[i] - start[i]) / static_cast<double>(end.size());
  const std::vector<physics::Vec3> centres = mass_centres();
  physics::Vec3 body_motion = physics::Vec3::Zero();
  for (std::size_t b = 0; b < bodies_.size(); ++b)
    if (bodies_[b].cut) {
      body_motion = centres[b] - centres_before[b];
      break;
    }
  const physics::Vec3 on_tissue(-stats.tool_force[0], -stats.tool_force[1], -stats.tool_force[2]);
  tool_.cutting.work += on_tissue.dot(blade_motion - body_motion);
  const double threshold =
      physics::onset_work(tool_.onset_width, tool_.radius, 0.5 * cut_spacing(bodies_), toughness());
  if (tool_.cutting.work >= threshold) tool_.cutting.cutting = true;
}

}  // namespace incise::engine
