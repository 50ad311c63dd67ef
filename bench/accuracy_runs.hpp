// The runs of `incise bench accuracy` (accuracy_runs.cpp): the sweep's resolutions and EFG
// variants, and the runs of one unit of work: a body (a shape, cut or not, with the cases that
// load it: its reference levels, then its tet10, tet4, EFG, mass-spring, constraint-particle and
// shape-memory rows) or the `traction` or `compression` case. A body's references serve only its own cases, so the units are independent:
// the batch's parts (docs/batch.md) each run whole units.
#pragma once

#include "bench/accuracy_report.hpp"

#include "common/progress_bar.hpp"

#include <string>
#include <utility>
#include <vector>

namespace incise::bench::accuracy {

using Levels = std::vector<std::pair<int, int>>;

struct EfgVariant {
  std::string name;
  int neighbours;
  bool estimate_volumes;
  double support_factor;
  bool centroid_points;
  int samples_per_axis;
};

// The resolutions of the full or the quick report.
struct Sweep {
  bool quick = false;
  int timed_steps = 1;
  Levels hexagon_levels, square_levels, crack_levels;  // tet10 references (finest last)
  Levels hexagon_linear, square_linear;                // tet4, uniform
  std::vector<int> efg_cells, efg_cells_cut;           // particle cells along the beam
  std::vector<EfgVariant> efg_variants;
  std::vector<std::string> cutter_variants;  // run with the cutter too on the cut cases
  std::vector<int> mass_spring_across;       // bricks across the beam (uncut bodies)
  std::vector<int> constraint_particles_across;  // voxels across the beam (uncut bodies)
};
Sweep make_sweep(bool quick);

// Cases sharing a body share meshes, models and factorisations.
struct Body {
  Shape shape;
  bool cut;
  std::vector<Case> cases;
};
std::vector<Body> group_bodies(const std::vector<Case>& cases);

// The units of work, in the order the whole report runs them: the bodies, then traction, then
// compression.
struct Unit {
  const Body* body = nullptr;  // null: the traction or (compression true) the compression case
  bool compression = false;
};
std::vector<Unit> make_units(const std::vector<Body>& bodies, bool traction, bool compression);
// How many progress steps a unit takes.
int unit_runs(const Sweep& sweep, const Unit& unit);
// Runs the unit, appending its rows (and for a body its cases' references) to `results`.
void run_unit(const Sweep& sweep, const Unit& unit, Results& results, common::ProgressBar& progress);

}  // namespace incise::bench::accuracy
