// The agreement of the volume cut with the surface's: an element whose link to a neighbour
// crosses the rest cut is "linked across" it (the two cuts disagree there). Counted after every
// cut event for the metrics (cut.elements_linked_across), kept up to date where the cut grew.
#pragma once

#include "physics/cut/uniform_grid.hpp"
#include "physics/cut/rest_cut.hpp"
#include "physics/efg/corotational_efg.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace incise::physics {

// Elements with a neighbour across the rest cut (its link to the integration point crosses a
// cut triangle): zero when the volume cut agrees with the surface's.
int elements_linked_across(const CorotationalEfg& model, const RestCut& cut);
// The same kept up to date after a cut grew by triangles inside the rest box [lo, hi]:
// `linked` (per element, 1 = linked across) is recomputed for the elements whose links reach
// into the box or that `changed` marks (may be null), all of them when its size is not the
// element count; returns the count. Equal to the full count as long as every triangle added
// since the last call lies in [lo, hi]. `boxes` (may be null) caches each element's link box
// at rest between calls: taken again for the elements `changed` marks, for all when its size
// is not the element count or `changed` is null (also while the cut is empty, so a first call
// can take them before any cut). `seen` (may be null; used with `boxes` and
// `changed`) keeps per element the cut's size when its flag was last taken: an unchanged
// element is then tested against the triangles added since only (it keeps its links and the
// cut only grows: linked before, linked still), with the same outcome as the whole cut's.
// `index` (may be null; used with `boxes` and `changed`) finds the elements whose links can
// reach into [lo, hi] from their centres (at rest, which never move) binned, within the
// largest reach of a cached link box from its centre, instead of looking at every element's
// box: the same elements, the same flags.
struct LinkedAcrossIndex {
  UniformGrid centres;   // the elements' centres; empty: to be built
  double reach = 0;      // per axis, over the cached boxes (kept as they change: only grows)
  int deactivated = -1;  // the model's deactivated elements when their flags were last cleared
};
int update_elements_linked_across(const CorotationalEfg& model, const RestCut& cut, std::vector<std::uint8_t>& linked,
                                  const Vec3& lo, const Vec3& hi, const std::vector<std::uint8_t>* changed,
                                  std::vector<std::array<Vec3, 2>>* boxes = nullptr, std::vector<int>* seen = nullptr,
                                  LinkedAcrossIndex* index = nullptr);

}  // namespace incise::physics
