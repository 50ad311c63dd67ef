// The needle's term of the haptic ContactModel (haptics/needle_proxy.hpp renders it at 1 kHz),
// from the needle's state after the step (physics/needle/needle.hpp): how hard the tissue resists
// the shaft along its axis, and where and how stiffly it holds it across.
#include "engine/haptic_session.hpp"

namespace incise::engine {

namespace {
physics::Vec3 vec3(const std::array<double, 3>& p) { return {p[0], p[1], p[2]}; }
}  // namespace

haptics::NeedleResistance needle_resistance(const World& world) {
  haptics::NeedleResistance out;
  if (!world.needle()) return out;
  const ToolState& tool = world.tool();
  const physics::NeedleSettings& settings = world.scene().tool->needle;
  physics::NeedlePose pose;
  pose.tip = vec3(tool.tip);
  pose.axis = (pose.tip - vec3(tool.tail)).normalized();
  pose.nodes = settings.nodes;
  pose.spacing = settings.length / (settings.nodes - 1);
  double insert = 0, friction = 0, stiffness = 0;
  physics::Vec3 offset = physics::Vec3::Zero();  // the grips' lateral pulls, stiffness-weighted
  for (std::size_t b = 0; b < world.needles().size(); ++b) {
    const physics::Needle& needle = world.needles()[b];
    const physics::NeedleTissue& tissue = needle.tissue();
    const BodySpec& spec = world.scene().bodies[b];
    // Each gripping node holds the shaft through its virtual particle (k_v) in series with the
    // tissue around it: an elastic half-space under a punch of the body's resolution, as the
    // contacts' compliance (haptic_session.hpp).
    const double nu = spec.material.poisson_ratio;
    const double compliance = (1 - nu * nu) / (2 * spec.material.youngs_modulus * spec.resolution);
    const double grip = 1 / (1 / settings.stick_stiffness + compliance);
    const auto& cutting = needle.zones().cutting;
    const auto w = physics::inverse_distance_shares(cutting);
    for (std::size_t i = 0; i < w.size(); ++i) insert += tissue.cutting[cutting[i].atom] * w[i];
    if (!cutting.empty()) stiffness += grip;  // the tip, held where it is
    const physics::Vector points = world.needle_tissue_positions(b);
    for (int j = 0; j < settings.nodes; ++j) {
      const auto& zone = needle.zones().friction[j];
      if (zone.empty() || needle.grips()[j] == physics::NodeGrip::none) continue;
      const auto share = physics::inverse_distance_shares(zone);
      for (std::size_t i = 0; i < share.size(); ++i) friction += tissue.friction[zone[i].atom] * share[i];
      const physics::Vec3 pull = needle.particles()[j].at(points) - pose.node(j);
      offset += grip * (pull - pull.dot(pose.axis) * pose.axis);
      stiffness += grip;
    }
  }
  if (!(stiffness > 0)) return out;
  const physics::Vec3 line = vec3(tool.pose.position) + offset / stiffness;
  for (int k = 0; k < 3; ++k) out.axis[k] = pose.axis[k], out.line[k] = line[k];
  out.insert_force = insert + friction;
  out.retract_force = friction;
  out.stiffness = stiffness;
  return out;
}

}  // namespace incise::engine
