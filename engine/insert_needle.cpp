// insert_needle: the needle's stage (seed 002 §2.3), after the tool's input and before the
// solve. The needle is rigid and follows the trajectory (the tool's pose: tip at the position,
// its shaft along the tool's local +z for `length`, so it goes in along local -z); each body's
// Needle (physics/needle/needle.hpp) gives the forces on its nodes from the positions the last
// step left, applied as explicit point forces in the solve, and the opposite force on the
// needle, which is the tool's force. A template of several needles (ToolSpec::needles, each at its
// offset and delay along the trajectory: take_tool_input) gives each its own Needle per body
// (zones, virtual particles, stick-slip), all from the same positions; their forces add up on
// the tissue and on the tool. A meshless body's tissue is its integration points, their forces
// passed to the particles by the MLS shape functions (physics/needle/needle_efg.hpp).
#include "engine/world.hpp"

#include "physics/needle/needle_efg.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace incise::engine {

namespace {

physics::Vec3 vec(const std::array<double, 3>& p) { return {p[0], p[1], p[2]}; }

}  // namespace

void World::build_needle() {
  needle_.clear();
  needles_phase_ = "approach";
  if (!needle()) return;
  const physics::NeedleSettings& settings = scene_.tool->needle;
  NeedleTrack track;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const Body& body = bodies_[b];
    try {
      if (body.data.efg) {
        track.bodies.emplace_back(settings, physics::make_efg_needle_tissue(*body.data.efg, settings));
      } else {
        track.bodies.emplace_back(settings, physics::make_needle_tissue(body.data.mechanics->rest_positions(),
                                                                        body.data.mechanics->node_spacing(),
                                                                        body.data.surface, settings));
      }
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(scene_.file.string() + ": tool: bodies[" + std::to_string(b) + "]: " + e.what());
    }
  }
  // Each needle of the template its own zones, virtual particles and stick-slip state.
  needle_.assign(scene_.tool->needles.size(), track);
  for (std::size_t k = 0; k < needle_.size(); ++k) needle_[k].last_tip = vec(tool_.needle_tips[k]);
  needle_points_.assign(bodies_.size(), {});
}

physics::Vector World::needle_tissue_positions(std::size_t b) const {
  const Body& body = bodies_[b];
  if (!body.data.efg) return body.data.state.positions;
  physics::Vector points;
  physics::efg_point_positions(*body.data.efg, body.data.state.positions, points);
  return points;
}

physics::Vec3 World::step_needle(NeedleTrack& track, const physics::NeedlePose& pose,
                                 std::vector<std::vector<physics::NodalSpring>>& springs, NeedleStepStats& out) {
  const physics::NeedleSettings& settings = scene_.tool->needle;
  const double speed = (pose.tip - track.last_tip).dot(pose.axis) / scene_.solver.dt;
  track.last_tip = pose.tip;
  out.present = true;
  out.speed = speed;
  bool in_tissue = false, puncturing = false;
  physics::Vec3 on_needle = physics::Vec3::Zero(), on_tissue = physics::Vec3::Zero();
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    physics::Needle& n = track.bodies[b];
    const physics::BodyData& data = bodies_[b].data;
    const physics::Vector& tissue = data.efg ? needle_points_[b] : data.state.positions;
    const physics::NeedleForces f = n.step(pose, speed, tissue);
    if (f.in_tissue && !track.touched) {
      // The first contact: depth is measured from the nearest zone node's level on the axis.
      track.touched = true;
      double nearest = 1e300;
      track.entry = pose.tip;
      for (const auto& m : n.zones().cutting)
        if (m.distance < nearest) {
          nearest = m.distance;
          const physics::Vec3 x = tissue.segment<3>(3 * m.atom);
          track.entry = pose.tip + (x - pose.tip).dot(pose.axis) * pose.axis;
        }
    }
    // The balance is the needle's: its force against those on the tissue points (an EFG
    // point's force reaches a fixed particle too, where the support takes it).
    for (const auto& [node, force] : f.tissue) on_tissue += force;
    if (data.efg) {
      const std::vector<physics::NodalSpring> on_particles =
          physics::efg_point_forces_on_particles(*data.efg, f.tissue, data.fixed);
      springs[b].insert(springs[b].end(), on_particles.begin(), on_particles.end());
    } else {
      for (const auto& [node, force] : f.tissue) springs[b].push_back({node, force, physics::Mat3::Zero()});
    }
    on_needle += f.on_needle;
    in_tissue = in_tissue || f.in_tissue;
    puncturing = puncturing || f.puncturing;
    out.cutting += f.cutting;
    out.friction += f.friction;
    out.sticking += f.sticking;
    out.slipping += f.slipping;
    out.stick_to_slip += n.stick_to_slip();
    out.slip_to_stick += n.slip_to_stick();
  }
  out.axial = on_needle.dot(pose.axis);
  out.lateral = (on_needle - out.axial * pose.axis).norm();
  out.balance = (on_needle + on_tissue).norm();
  if (track.touched) out.depth = (pose.tip - track.entry).dot(pose.axis);
  // The phase: before any contact the approach; then by the axial motion (a needle at rest keeps
  // the phase it had), puncture while a boundary node takes cutting force.
  if (!track.touched) track.phase = "approach";
  else if (speed > settings.rest_speed) track.phase = puncturing ? "puncture" : (in_tissue ? "insert" : "approach");
  else if (speed < -settings.rest_speed) track.phase = "retract";
  out.phase = track.phase;
  return on_needle;
}

namespace {

// The template's step from its needles': the forces summed (the axis the first needle's), the
// deepest tip, the fastest advance, and the phase by precedence: puncture while any needle
// punctures, else retract while any retracts, else insert while any advances in the tissue; all
// at rest, the last phase kept.
void sum_needles(const std::vector<NeedleStepStats>& each, const physics::Vec3& axis,
                 const std::vector<physics::Vec3>& forces, double rest_speed, std::string& phase, NeedleStepStats& out) {
  out.present = true;
  out.depth = -1e300;
  out.speed = -1e300;
  physics::Vec3 on_needles = physics::Vec3::Zero();
  bool puncture = false, retract = false, insert = false;
  for (std::size_t k = 0; k < each.size(); ++k) {
    const NeedleStepStats& n = each[k];
    on_needles += forces[k];
    out.depth = std::max(out.depth, n.depth);
    out.speed = std::max(out.speed, n.speed);
    out.cutting += n.cutting;
    out.friction += n.friction;
    out.balance += n.balance;
    out.sticking += n.sticking;
    out.slipping += n.slipping;
    out.stick_to_slip += n.stick_to_slip;
    out.slip_to_stick += n.slip_to_stick;
    puncture = puncture || n.phase == "puncture";
    retract = retract || (n.phase == "retract" && n.speed < -rest_speed);
    insert = insert || (n.phase == "insert" && n.speed > rest_speed);
  }
  out.axial = on_needles.dot(axis);
  out.lateral = (on_needles - out.axial * axis).norm();
  if (puncture) phase = "puncture";
  else if (retract) phase = "retract";
  else if (insert) phase = "insert";
  out.phase = phase;
}

// The mean displacement of the bodies' nodes from rest along `axis` (m).
double axial_displacement(const std::vector<Body>& bodies, const physics::Vec3& axis) {
  double sum = 0;
  long nodes = 0;
  for (const Body& body : bodies) {
    const physics::Vector& x = body.data.state.positions;
    const physics::Vector& rest = body.data.mechanics->rest_positions();
    for (Eigen::Index i = 0; i + 2 < x.size() && i + 2 < rest.size(); i += 3, ++nodes)
      sum += (x.segment<3>(i) - rest.segment<3>(i)).dot(axis);
  }
  return nodes ? sum / static_cast<double>(nodes) : 0.0;
}

}  // namespace

std::vector<std::vector<physics::NodalSpring>> World::insert_needle(StepStats& stats) {
  std::vector<std::vector<physics::NodalSpring>> springs(bodies_.size());
  if (!needle()) return springs;
  // A meshless body's tissue points where the last step left them, once for every needle.
  for (std::size_t b = 0; b < bodies_.size(); ++b)
    if (bodies_[b].data.efg) physics::efg_point_positions(*bodies_[b].data.efg, bodies_[b].data.state.positions, needle_points_[b]);
  const physics::NeedleSettings& settings = scene_.tool->needle;
  std::vector<physics::NeedlePose> poses(needle_.size());
  for (std::size_t k = 0; k < needle_.size(); ++k) {
    physics::NeedlePose& pose = poses[k];
    pose.tip = vec(tool_.needle_tips[k]);
    pose.axis = (pose.tip - vec(tool_.needle_tails[k])).normalized();
    pose.nodes = settings.nodes;
    pose.spacing = settings.length / (settings.nodes - 1);
  }
  const double displacement = axial_displacement(bodies_, poses.front().axis);
  if (needle_.size() == 1) {
    step_needle(needle_.front(), poses.front(), springs, stats.needle);
    stats.needle.axial_displacement = displacement;
    return springs;
  }
  // Several needles: each its own forces on the same tissue (from the same positions), summed.
  stats.needles.resize(needle_.size());
  std::vector<physics::Vec3> forces(needle_.size());
  for (std::size_t k = 0; k < needle_.size(); ++k)
    forces[k] = step_needle(needle_[k], poses[k], springs, stats.needles[k]);
  sum_needles(stats.needles, poses.front().axis, forces, settings.rest_speed, needles_phase_, stats.needle);
  stats.needle.axial_displacement = displacement;
  return springs;
}

}  // namespace incise::engine
