#include "physics/cut/apply_topology.hpp"

#include "physics/core/contact.hpp"
#include "physics/core/stopwatch.hpp"
#include "physics/cut/remap_surface.hpp"

#include <algorithm>
#include <functional>
#include <stdexcept>
#include <string>

namespace incise::physics {

namespace {

// The thesis's surface cut: each moment is a blade sample of the stroke; a stroke ends when
// the blade disengages or its front has left the body after cutting. It needs nothing the
// volume's cut below makes, nor the volume anything it makes (the volume's agreement pass
// reads the sweep at rest, CutData::rest_cut, filled first), so with a helper thread
// (the executor's side job) the two run side by side.
// Returns how many samples changed the surface (each stroke ended here counts one).
int cut_front(CutContext& ctx, const RestSweep& sweep) {
  CutData& cut = ctx.cut;
  CutTotals& totals = ctx.totals;
  int faces = 0;
  FrontSurface& front = *cut.surface;
  for (const auto& [blade_at_rest, starts_run] : sweep.moments) {
    if (starts_run && front.stroke_samples() > 1) {
      close_stroke(ctx, front.front_width());
      ++faces;
    }
    FrontCutReport sample;
    try {
      sample = front.advance(blade_at_rest);
    } catch (const std::invalid_argument& error) {
      // A sample the stroke cannot take (its point count changed, a point not finite): the
      // stroke ends where it was, and this sample starts the next one.
      sample.problems.push_back(error.what());
      close_stroke(ctx, 0);
      if (std::all_of(blade_at_rest.begin(), blade_at_rest.end(), [](const Vec3& p) { return p.allFinite(); }))
        front.advance(blade_at_rest);
    }
    totals.front_folded_edges += std::max(0, sample.folded_edges - cut.stroke_folds);
    cut.stroke_folds = sample.folded_edges;
    if (!sample.ok()) {
      totals.front_problems++;
      if (totals.first_front_problem.empty())
        totals.first_front_problem = "step " + std::to_string(ctx.step) + ": " + sample.problems.front();
    }
    if (sample.crossings + sample.tips > 0) ++faces;
    if (sample.ok() && sample.crossings > 0 && !sample.front_in_body) {
      close_stroke(ctx, 0);
      ctx.report.cut_through = true;
    }
  }
  return faces;
}

// Particles no element uses any more are pinned: they carry no stiffness. Returns whether
// any was pinned this step (every vertex's fixed flag is then taken again).
bool pin_orphans(CutContext& ctx) {
  BodyData& body = ctx.body;
  CutData& cut = ctx.cut;
  CutTotals& totals = ctx.totals;
  const auto& orphans = body.efg->orphaned_particles();
  for (std::size_t k = cut.orphans_pinned; k < orphans.size(); ++k) {
    body.fixed[orphans[k]] = 1;
    body.state.velocities.segment<3>(3 * orphans[k]).setZero();
    body.warm_start.zero_node(orphans[k]);
  }
  const bool pinned = orphans.size() > cut.orphans_pinned;
  cut.orphans_pinned = orphans.size();
  totals.orphaned_particles = static_cast<long>(orphans.size());
  totals.positive_mass_elements = body.efg->positive_mass_elements();
  totals.deactivated_elements = body.efg->deactivated_elements();
  totals.masses_floored = body.efg->masses_floored();
  return pinned;
}

}  // namespace

bool close_stroke(CutContext& ctx, double reach) {
  const bool carried = ctx.cut.surface->end_stroke(reach);
  ctx.cut.stroke_folds = 0;
  // A stroke the surface could not keep is counted with the samples it could not cut.
  if (const std::string& problem = ctx.cut.surface->end_problem(); !problem.empty()) {
    ctx.totals.front_problems++;
    if (ctx.totals.first_front_problem.empty())
      ctx.totals.first_front_problem = "step " + std::to_string(ctx.step) + ": " + problem;
  }
  if (carried) ctx.totals.front_strokes_carried_through++;
  return carried;
}

void end_stroke(CutContext& ctx) {
  ctx.cut.engaged = false;
  FrontSurface& front = *ctx.cut.surface;
  if (front.stroke_samples() == 0) return;
  const Stopwatch watch;
  // Not carried: the surface is the one shown (its stroke's vertices became base ones), unless
  // the stroke was dropped (FrontSurface::end_problem), which shows the last base again.
  if (!close_stroke(ctx, front.front_width()) && front.end_problem().empty()) return;
  const std::vector<std::uint8_t> unchanged(static_cast<std::size_t>(ctx.body.efg->element_count()), 0);
  remap_front_surface(ctx, {ctx.model.rest_lo, ctx.model.rest_hi, unchanged, false});
  ctx.report.ms_topology += watch.ms();
  ctx.report.event = true;
  ctx.totals.events++;
}

void apply_topology(CutContext& ctx, const BladeSweep& blade, const std::optional<RestSweep>& rest_sweep, Executor& executor) {
  if (!rest_sweep) {
    end_stroke(ctx);
    return;
  }
  const RestSweep& sweep = *rest_sweep;
  const BodyModel& model = ctx.model;
  BodyData& body = ctx.body;
  CutData& cut = ctx.cut;
  CutTotals& totals = ctx.totals;
  CutStepReport& report = ctx.report;
  const auto& active = blade.active;
  Stopwatch watch;
  const auto& triangles = sweep.triangles;
  for (const auto& t : triangles) cut.rest_cut->add(t);
  double ms_rest = watch.ms();
  // The volume: CCD of the sweep against the links, re-selection kept consistent with the
  // rest cut around this sweep.
  VolumeCutter::RestVisibility visibility;
  const RestCut& rest_cut = *cut.rest_cut;
  visibility.blocked = [&rest_cut](const Vec3& a, const Vec3& b) { return rest_cut.crosses(a, b); };
  visibility.lo = Vec3::Constant(1e300);
  visibility.hi = Vec3::Constant(-1e300);
  for (const auto& t : triangles)
    for (const auto* p : {&t.a, &t.b, &t.c}) visibility.lo = visibility.lo.cwiseMin(*p), visibility.hi = visibility.hi.cwiseMax(*p);
  visibility.lo -= Vec3::Constant(2 * body.efg->spacing());
  visibility.hi += Vec3::Constant(2 * body.efg->spacing());
  VolumeCutReport volume;
  const auto cut_volume = [&] {
    volume = cut.cutter->cut(blade.poses, blade.fractions, active, cut.previous_positions, body.state.positions,
                              triangles.empty() ? nullptr : &visibility);
  };
  int faces = 0;
  if (!sweep.moments.empty()) {
    // The volume on this thread (a GPU body's context is current here), the surface on the
    // helper (or here, after the volume, if the helper has not begun it by then). The step
    // waits for the surface only when it takes longer than the volume: that wait is the
    // surface cut's share of the step (ms_rest_cut, ms_topology), its whole time ms_front_cut.
    const Stopwatch fork;
    double ms_volume = 0, ms_front = 0;
    const std::function<void()> volume_job = [&] {
      const Stopwatch own;
      cut_volume();
      ms_volume = own.ms();
    };
    const std::function<void()> front_job = [&] {
      const Stopwatch side;
      faces = cut_front(ctx, sweep);
      ms_front = side.ms();
    };
    executor.run_beside(volume_job, front_job);
    const double wall = fork.ms();
    const double wait = std::max(0.0, wall - ms_volume);
    report.ms_front_cut += ms_front;
    report.ms_front_wait += wait;
    ms_rest += wait;
  } else {
    cut_volume();  // no surface sample to cut this step
  }
  cut.engaged = active.back() != 0;
  report.ms_rest_cut += ms_rest;
  report.ms_ccd += volume.ms_ccd;
  report.ms_reselect += volume.ms_topology;
  watch.restart();
  const bool pinned = pin_orphans(ctx);
  const bool changed = volume.any() || faces > 0;
  if (volume.any() || pinned) body.topology_revision++;  // the mechanics changed: a new factor
  if (changed) {
    // The masses moved with the neighbourhoods: so does their weight.
    body.gravity = gravity_forces(body.mechanics->lumped_masses(), model.gravity);
    // Remap what the cut's new triangles hide and wherever an element was re-selected
    // (remap_surface); the linked-across check takes the re-selected elements and
    // those with a link reaching into the box of this step's triangles (grown by 2 a).
    std::vector<std::uint8_t> element_changed(static_cast<std::size_t>(body.efg->element_count()), 0);
    for (int e : volume.changed_elements) element_changed[e] = 1;
    const RemapRegion region{visibility.lo, visibility.hi, element_changed, pinned};
    if (volume.any() && model.integrator.assembled_system && !ctx.on_gpu) {
      // The re-selected rows' plan of the step's assembled stiffness on the helper, beside the
      // surface's remap (which reads the model and leaves the plan alone): the step's solve
      // then finds it laid. The same plan wherever and whenever it is laid.
      const std::function<void()> remap = [&] { remap_front_surface(ctx, region); };
      const std::function<void()> plan = [&] { body.mechanics->plan_current_stiffness(); };
      executor.run_beside(remap, plan);
    } else {
      remap_front_surface(ctx, region);
    }
  }
  report.ms_topology += ms_rest + volume.ms_topology + watch.ms();
  report.links_severed += volume.particle_links_severed + volume.element_links_severed + volume.links_severed_at_rest;
  if (changed) {
    report.event = true;
    totals.events++;
    totals.links_severed += volume.particle_links_severed + volume.element_links_severed;
    totals.links_severed_at_rest += volume.links_severed_at_rest;
    totals.elements_reselected += volume.elements_reselected;
    totals.isolated_elements += volume.elements_isolated;
    totals.nonlocal_reselections += volume.elements_nonlocal;
    totals.reselection_failures += volume.reselection_failures;
  }
}

}  // namespace incise::physics
