// The incision score (issue 33): how the cut a run made compares with the scene's planned
// incision (`plan`, engine/scene.hpp), in the figures training simulators report: length cut
// along the plan, deviation of the cut path from it, depth against the target, tissue cut
// outside the tolerance band, duration, tool force and strokes.
//
// The cut is read from the cut body's surface at rest (physics/cut/front_surface.hpp): its cut
// faces are the tissue the blade opened, meshed at rest where the two lips coincide, so each
// opened area is there twice and is counted once. Measuring at rest makes the score independent
// of how the organ deformed under the blade and the retractors. Across the blade's way into the
// tissue (`plan.direction`, d) a point x has a lateral position (x projected on the plane normal
// to d) and a height x.d; the plan is followed in lateral positions, and its surface is where a
// ray along d through the plan first meets the organ's outer (uncut) surface.
//   - deviation: the lateral distance from the plan to the cut path, the cut faces' edges on the
//     outer surface (the wound's mouth), sampled every 0.25 mm;
//   - depth: per 0.5 mm of plan, the deepest cut within the band below the plan's surface point;
//     length cut: the plan's length over the organ with a cut within the band;
//   - outside the band: cut-face area laterally farther than `band` from the plan or deeper than
//     depth + band (sampled on sub-triangles of at most 0.5 mm).
#pragma once

#include "engine/scene.hpp"
#include "engine/world.hpp"

#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <filesystem>
#include <vector>

namespace incise::engine {

struct IncisionScore {
  bool cut = false;             // any cut face at all
  double plan_length_mm = 0;    // the plan's length over the organ (its rays meet the surface)
  double length_cut_mm = 0;
  double deviation_mean_mm = 0;  // along the wound's mouth, weighted by its length
  double deviation_max_mm = 0;
  double depth_target_mm = 0;
  double depth_mean_mm = 0;     // over the plan's cut length
  double depth_min_mm = 0;
  double depth_max_mm = 0;
  double depth_range_mm = 0;    // max - min
  double band_mm = 0;
  double cut_area_mm2 = 0;      // tissue opened (one lip)
  double outside_band_mm2 = 0;
  double duration_s = 0;        // from the first step that cut to the end of the last
  double force_peak_N = 0;      // over the run
  double force_mean_N = 0;      // over the steps the tool touched tissue
  int strokes = 0;              // engagements of the blade that cut
  // The cut path at rest: the wound's mouth as segments (x0, y0, z0, x1, y1, z1), m.
  std::vector<std::array<double, 6>> mouth;
};

// The geometric part, from a cut body's surface at rest: `vertices`, `triangles` and per
// triangle 1 on a cut face. Fills every figure but the tool's.
void score_cut_surface(const PlanSpec& plan, const std::vector<physics::Vec3>& vertices,
                       const std::vector<std::array<int, 3>>& triangles, const std::vector<std::uint8_t>& cut_face,
                       IncisionScore& score);
// The tool's part, from the steps of the run (StepStats::cut_event, blade_engaged, tool_force).
void score_tool(const std::vector<StepStats>& steps, double dt, IncisionScore& score);

// Both, for the plan's body of `world` after the run. Throws std::runtime_error when the
// plan's body is missing or has no cut surface.
IncisionScore score_incision(const PlanSpec& plan, const World& world, const std::vector<StepStats>& steps,
                             double dt);

// score.json's object: the keys first, then the context (target, band, areas).
nlohmann::json score_json(const IncisionScore& score);

// Writes dir/score.json, and for the report's view from above dir/plan.csv (x,y,z of the
// plan's points) and dir/cut_path.csv (x0,y0,z0,x1,y1,z1 of the mouth's segments), m at rest.
// Throws std::runtime_error naming a file it cannot write.
void write_score_files(const std::filesystem::path& dir, const PlanSpec& plan, const IncisionScore& score);

}  // namespace incise::engine
