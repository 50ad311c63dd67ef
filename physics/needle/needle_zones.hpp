// The needle's zones of influence (seed 002 §2.3, Fig. 18): one cutting / puncture zone, the
// hemisphere of radius r_c ahead of the tip, and one friction zone per node, the cylinder of
// radius r_f around the shaft over the node's share of it (half a node spacing each side; the
// tip node's only behind the tip, its front is the cutting zone's). There is no collision
// detection: the zones decide which tissue nodes the needle acts on.
//
// The zones are built at the first contact (a scan of every tissue node, repeated each step
// while no zone holds any) and then updated by testing only the nodes already inside a zone
// and their neighbours (NeedleTissue::neighbours), as the seed does.
#pragma once

#include "physics/core/model.hpp"
#include "physics/needle/needle_settings.hpp"
#include "physics/needle/needle_tissue.hpp"

#include <vector>

namespace incise::physics {

// The needle at one instant: the tip, the unit axis pointing the way it goes in (hub to tip),
// and its nodes `spacing` apart from the tip back along the shaft.
struct NeedlePose {
  Vec3 tip = Vec3::Zero();
  Vec3 axis = Vec3(0, 0, -1);
  double spacing = 0;
  int nodes = 0;
  Vec3 node(int j) const { return tip - (j * spacing) * axis; }
};

struct ZoneMember {
  int atom = 0;
  double distance = 0;  // to the tip (cutting zone) or to its needle node (friction zone), m
};

struct NeedleZones {
  std::vector<ZoneMember> cutting;                // increasing atom
  std::vector<std::vector<ZoneMember>> friction;  // per needle node, increasing atom
  bool empty() const;
  int members() const;
};

// The zones at `pose` over the tissue at `x` (3n), from the last ones (`zones`, which it
// replaces): a full scan when they are empty, else the last members and their neighbours.
// Returns whether it scanned every node.
bool update_zones(NeedleZones& zones, const NeedlePose& pose, const Vector& x, const NeedleTissue& tissue,
                  const NeedleSettings& settings);

}  // namespace incise::physics
