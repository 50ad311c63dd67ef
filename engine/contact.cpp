// contact: the probe's penalty springs on the touched surface, passed to the nodes or
// particles (physics/core/body_contact.hpp). A blade pressing on a cuttable body before its
// cut's onset (engine/cutting_resistance.cpp) is such a probe too, each segment of its edge
// a capsule of the blade's radius; once cutting, the ideal blade applies no contact force
// (seed 004 §2.2): its resistance is the toughness's.
#include "engine/world.hpp"

#include "physics/core/body_contact.hpp"

namespace incise::engine {

std::vector<physics::NodalSpring> World::contact(const Body& body, StepStats& stats) const {
  if (!tool_.present) return {};
  if (blade()) {
    if (!tool_.pressing || !body.cut || tool_.blade_poses.empty()) return {};
    const auto& edge = tool_.blade_poses.back();
    std::vector<physics::NodalSpring> springs;
    for (std::size_t i = 0; i + 1 < edge.size(); ++i) {
      auto segment = physics::body_contact(body.data, edge[i], edge[i + 1], tool_.radius, scene_.tool->stiffness,
                                           stats.contacts);
      springs.insert(springs.end(), segment.begin(), segment.end());
    }
    return springs;
  }
  return physics::body_contact(body.data, {tool_.tip[0], tool_.tip[1], tool_.tip[2]},
                               {tool_.tail[0], tool_.tail[1], tool_.tail[2]}, tool_.radius, scene_.tool->stiffness,
                               stats.contacts);
}

}  // namespace incise::engine
