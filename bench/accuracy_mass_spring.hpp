// The mass-spring rows of `incise bench accuracy` (issue 31): Baudet's hexahedral model with
// and without its correction forces on the report's beams, and the `traction` case that
// measures E and nu of the spring networks (digest seed-000-003.md D5, D9). A file of its own
// beside accuracy.cpp, which calls it with its cases and references.
#pragma once

#include "common/progress_bar.hpp"
#include "physics/core/model.hpp"
#include "physics/mss/hex_mesh.hpp"

#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

namespace incise::bench {

struct MassSpringRow {
  std::string case_name, model, variant, resolution;
  long long dofs = 0, elements = 0;
  double ms_per_step = 0, cg_iterations = 0, error_pct = 0;
  bool converged = true;
  physics::Vec3 tip = physics::Vec3::Zero();
  double measured_E = std::numeric_limits<double>::quiet_NaN();   // traction rows only
  double measured_nu = std::numeric_limits<double>::quiet_NaN();
};

struct StepTiming {
  double ms_per_step = 0, cg_iterations = 0;
  bool converged = true;
};
// The report's timing of a model (accuracy.cpp's time_steps): implicit Euler from rest under
// the load with the nodes `fixed`.
using TimeSteps = std::function<StepTiming(physics::DeformableModel&, const std::vector<uint8_t>&, const physics::Vector&)>;

// One of the report's beams: its shape, clamped at x = 0, tip face at x = `length`.
struct MassSpringBeam {
  std::function<bool(const physics::Vec3&)> inside;
  physics::Vec3 lo, hi;
  bool box = false;  // a box: bricks of the exact box (make_box_hexes), else voxelised
  double youngs_modulus = 0, poisson_ratio = 0, density = 0;
};
struct MassSpringCase {
  std::string name;
  physics::Vec3 acceleration, reference_tip;
};

// Area-weighted mean displacement over a brick mesh's boundary faces at x = tip_x (the bilinear
// field's mean per triangle: its corners' mean).
physics::Vec3 hex_tip_mean(const physics::HexMesh& mesh, const physics::Vector& u, double tip_x);

// The beam's bricks at each size in `cells_across` (bricks across its y extent), each with and
// without corrections, solved statically under each case's gravity (the nonlinear solve at
// these small strains, i.e. the reference's small-strain problem); error = |mean tip
// displacement - reference| / |reference| in %.
std::vector<MassSpringRow> mass_spring_beam_rows(const MassSpringBeam& beam, const std::vector<MassSpringCase>& cases,
                                                 const std::vector<int>& cells_across, const TimeSteps& time_steps,
                                                 common::ProgressBar& progress);
// How many progress steps mass_spring_beam_rows and traction_rows take.
int mass_spring_beam_runs(const std::vector<int>& cells_across);
int traction_runs();

// The `traction` case: E = 1e4 Pa, nu in {0.1, 0.3, 0.45}, on a 0.1 m cube, a 3 x 3 x 3 block of
// 0.1 m cubes and a 4 x 2 x 2 block of 0.12 x 0.1 x 0.08 m bricks (models mass_spring,
// mass_spring_uncorrected), and Van Gelder's springs on the 3 x 3 x 3 block's tets (model
// van_gelder, not timed: no dynamic model). error_pct: the larger relative deviation of the
// measured E and nu from the targets, in %. Timed: the block clamped at x = 0 under gravity.
std::vector<MassSpringRow> traction_rows(const TimeSteps& time_steps, common::ProgressBar& progress);

}  // namespace incise::bench
