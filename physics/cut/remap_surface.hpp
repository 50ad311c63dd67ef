// The surface's vertices remapped after a cut (seed 004 §2.6), the last part of
// apply_topology: each vertex follows one integration point through the MLS weights of its
// neighbourhood, and a row is redone only where one of the thesis's triggers names it: the
// vertex is new or renumbered by the stroke, gained a constraint plane, lies on a re-selected
// element, or has the segment to its integration point crossed by the cut faces. What this
// costs follows the stroke, not the surface: FrontSurface keeps the base's triangles in their
// slots and says which slots and base vertices the stroke changed, so only those, then and
// now, are looked at. Then the checks the metrics report: the surface's edge counts (kept up to
// date where it changed), the vertices whose point lies across a cut face, and the elements
// linked across the rest cut.
#pragma once

#include "physics/cut/cut_body.hpp"

#include <cstdint>
#include <vector>

namespace incise::physics {

// Where the cut changed the body: the rest box around it (for the linked-across check), per
// element whether it was re-selected, and whether particles were pinned (every vertex's fixed
// flag is then taken again).
struct RemapRegion {
  Vec3 lo, hi;
  const std::vector<std::uint8_t>& changed;
  bool fixed_changed = false;
};

void remap_front_surface(CutContext& ctx, const RemapRegion& region);

}  // namespace incise::physics
