// apply_topology, the second cut stage of a step (seed 004 §2.4-2.6, §2.7's loop order):
// the sweep at rest from detect_cuts applied to the volume (CCD of the sweep against the
// topology graph's links and re-selection of the neighbourhoods it breaks, VolumeCutter) and to
// the surface (the thesis's front, FrontSurface::advance per blade sample), then the surface's
// vertices remapped where seed 004 §2.6's triggers name them (remap_surface.hpp). The surface's
// cut needs nothing the volume's makes nor the volume anything it makes, so the executor may
// run them side by side.
#pragma once

#include "physics/core/executor.hpp"
#include "physics/cut/cut_body.hpp"
#include "physics/cut/detect_cuts.hpp"

#include <optional>

namespace incise::physics {

// With a sweep: the cut as above; particles no element uses any more are pinned, gravity is
// lumped again when the masses moved, and the step's counts go to ctx.report and ctx.totals.
// Without one (the blade disengaged or away): the stroke in progress ends (end_stroke).
void apply_topology(CutContext& ctx, const BladeSweep& blade, const std::optional<RestSweep>& sweep, Executor& executor);

// The blade disengaged or left the body's box: the stroke ends now rather than when the next
// one begins, its front carried through if it only stopped short at rest
// (FrontSurface::end_stroke), the surface then remapped over the body's rest box.
void end_stroke(CutContext& ctx);

// Ends the stroke with `reach` (FrontSurface::end_stroke), counting a front carried through;
// returns whether it was.
bool close_stroke(CutContext& ctx, double reach);

}  // namespace incise::physics
