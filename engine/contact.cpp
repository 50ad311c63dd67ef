// contact: the probe's penalty springs on the touched surface, passed to the nodes or
// particles (physics/core/body_contact.hpp). The ideal blade applies no force (seed 004 §2.2).
#include "engine/world.hpp"

#include "physics/core/body_contact.hpp"

namespace incise::engine {

std::vector<physics::NodalSpring> World::contact(const Body& body, StepStats& stats) const {
  if (!tool_.present || blade()) return {};
  return physics::body_contact(body.data, {tool_.tip[0], tool_.tip[1], tool_.tip[2]},
                               {tool_.tail[0], tool_.tail[1], tool_.tail[2]}, tool_.radius, scene_.tool->stiffness,
                               stats.contacts);
}

}  // namespace incise::engine
