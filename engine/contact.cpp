// contact: the probe's penalty springs on the touched surface, passed to the nodes or
// particles (physics/core/body_contact.hpp). A blade pressing on a cuttable body before its
// cut's onset (engine/cutting_resistance.cpp) is such a probe too, each segment of its edge
// a capsule of the blade's radius, and held wherever it went inside, whatever the depth
// (physics::held_contact), so that a thin edge cannot slip through before the onset; once
// cutting, the ideal blade applies no contact force (seed 004 §2.2): its resistance is the
// toughness's.
#include "engine/world.hpp"

#include "physics/core/body_contact.hpp"

namespace incise::engine {

std::vector<physics::NodalSpring> World::contact(const Body& body, StepStats& stats) const {
  // A needle touches nothing: its forces are its zones' (engine/insert_needle.cpp).
  if (!tool_.present || needle()) return {};
  if (blade()) {
    if (!tool_.pressing || !body.cut || tool_.blade_poses.empty()) return {};
    // An edge pressed across itself (engaged wider than its rounded width across its motion) is
    // held at points a quarter particle spacing apart (the pieces the engagement is measured
    // on). One pushed along itself presses with its tip, which the capsule's end holds.
    const bool across = tool_.onset_width > 2 * tool_.radius;
    return physics::body_edge_contact(body.data, tool_.blade_poses.back(), tool_.radius, scene_.tool->stiffness,
                                      across ? 0.25 * body.cut_model->spacing : 0.0, stats.contacts);
  }
  return physics::body_contact(body.data, {tool_.tip[0], tool_.tip[1], tool_.tip[2]},
                               {tool_.tail[0], tool_.tail[1], tool_.tail[2]}, tool_.radius, scene_.tool->stiffness,
                               stats.contacts);
}

}  // namespace incise::engine
