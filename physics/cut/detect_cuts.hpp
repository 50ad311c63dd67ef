// detect_cuts, the first cut stage of a step (seed 004 §2.2-2.3): the blade's sweep over
// the step, tested against the body's box, and mapped to the rest configuration, where every
// topology edit is made. The continuous collision of the sweep with the topology graph's links
// runs in the next stage (apply_topology.hpp), inside the volume's cut.
#pragma once

#include "physics/cut/cut_body.hpp"

#include <optional>
#include <utility>
#include <vector>

namespace incise::physics {

// The step's sweep at rest: two triangles per quad between consecutive mapped moments (the
// rest cut's new part), and the blade at rest at each moment with whether it starts a run of
// engaged samples (a new stroke of the front surface).
struct RestSweep {
  std::vector<RestTriangle> triangles;
  std::vector<std::pair<std::vector<Vec3>, bool>> moments;
};

// Nothing when the blade is not engaged during the step or its sweep's box misses the body's
// particles' box grown by two particle spacings: the stroke, if any, then ends
// (apply_topology). Otherwise the sweep at rest: the edge resampled every a / 2 (fixed the
// first time, CutData::blade_pieces, so that a stroke's samples keep their points) and mapped
// through the body's local deformation (VolumeCutter::to_rest) at moments no more than about
// a / 2 of relative motion apart; quads whose corners all lie beyond 2a of the integration
// points (outside the body, where the mapping only extrapolates) are left out. Its time goes
// to report.ms_rest_cut.
std::optional<RestSweep> detect_cuts(const CutModel& cut_model, CutData& cut, const BodyData& body,
                                     const BladeSweep& sweep, CutStepReport& report);

}  // namespace incise::physics
