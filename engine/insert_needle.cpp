// insert_needle: the needle's stage (seed 002 §2.3), after the tool's input and before the
// solve. The needle is rigid and follows the trajectory (the tool's pose: tip at the position,
// its shaft along the tool's local +z for `length`, so it goes in along local -z); each body's
// Needle (physics/needle/needle.hpp) gives the forces on its nodes from the positions the last
// step left, applied as explicit point forces in the solve, and the opposite force on the
// needle, which is the tool's force. A meshless body's tissue is its integration points, their
// forces passed to the particles by the MLS shape functions (physics/needle/needle_efg.hpp).
#include "engine/world.hpp"

#include "physics/needle/needle_efg.hpp"

#include <cmath>
#include <stdexcept>

namespace incise::engine {

namespace {

physics::Vec3 vec(const std::array<double, 3>& p) { return {p[0], p[1], p[2]}; }

}  // namespace

void World::build_needle() {
  needle_ = NeedleTrack{};
  if (!needle()) return;
  const physics::NeedleSettings& settings = scene_.tool->needle;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const Body& body = bodies_[b];
    try {
      if (body.data.efg) {
        needle_.bodies.emplace_back(settings, physics::make_efg_needle_tissue(*body.data.efg, settings));
      } else {
        needle_.bodies.emplace_back(settings, physics::make_needle_tissue(body.data.mechanics->rest_positions(),
                                                                          body.data.mechanics->node_spacing(),
                                                                          body.data.surface, settings));
      }
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(scene_.file.string() + ": tool: bodies[" + std::to_string(b) + "]: " + e.what());
    }
  }
  needle_.points.assign(bodies_.size(), {});
  needle_.last_tip = vec(tool_.tip);
}

physics::Vector World::needle_tissue_positions(std::size_t b) const {
  const Body& body = bodies_[b];
  if (!body.data.efg) return body.data.state.positions;
  physics::Vector points;
  physics::efg_point_positions(*body.data.efg, body.data.state.positions, points);
  return points;
}

std::vector<std::vector<physics::NodalSpring>> World::insert_needle(StepStats& stats) {
  std::vector<std::vector<physics::NodalSpring>> springs(bodies_.size());
  if (!needle()) return springs;
  const physics::NeedleSettings& settings = scene_.tool->needle;
  physics::NeedlePose pose;
  pose.tip = vec(tool_.tip);
  pose.axis = (pose.tip - vec(tool_.tail)).normalized();
  pose.nodes = settings.nodes;
  pose.spacing = settings.length / (settings.nodes - 1);
  const double speed = (pose.tip - needle_.last_tip).dot(pose.axis) / scene_.solver.dt;
  needle_.last_tip = pose.tip;
  NeedleStepStats& out = stats.needle;
  out.present = true;
  out.speed = speed;
  bool in_tissue = false, puncturing = false;
  physics::Vec3 on_needle = physics::Vec3::Zero(), on_tissue = physics::Vec3::Zero();
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    physics::Needle& n = needle_.bodies[b];
    const physics::BodyData& data = bodies_[b].data;
    if (data.efg) physics::efg_point_positions(*data.efg, data.state.positions, needle_.points[b]);
    const physics::Vector& tissue = data.efg ? needle_.points[b] : data.state.positions;
    const physics::NeedleForces f = n.step(pose, speed, tissue);
    if (f.in_tissue && !needle_.touched) {
      // The first contact: depth is measured from the nearest zone node's level on the axis.
      needle_.touched = true;
      double nearest = 1e300;
      needle_.entry = pose.tip;
      for (const auto& m : n.zones().cutting)
        if (m.distance < nearest) {
          nearest = m.distance;
          const physics::Vec3 x = tissue.segment<3>(3 * m.atom);
          needle_.entry = pose.tip + (x - pose.tip).dot(pose.axis) * pose.axis;
        }
    }
    // The balance is the needle's: its force against those on the tissue points (an EFG
    // point's force reaches a fixed particle too, where the support takes it).
    for (const auto& [node, force] : f.tissue) on_tissue += force;
    if (data.efg) {
      springs[b] = physics::efg_point_forces_on_particles(*data.efg, f.tissue, data.fixed);
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
  if (needle_.touched) out.depth = (pose.tip - needle_.entry).dot(pose.axis);
  // The phase: before any contact the approach; then by the axial motion (a needle at rest keeps
  // the phase it had), puncture while a boundary node takes cutting force.
  if (!needle_.touched) needle_.phase = "approach";
  else if (speed > settings.rest_speed) needle_.phase = puncturing ? "puncture" : (in_tissue ? "insert" : "approach");
  else if (speed < -settings.rest_speed) needle_.phase = "retract";
  out.phase = needle_.phase;
  return springs;
}

}  // namespace incise::engine
