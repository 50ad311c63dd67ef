// Promayon's models in `incise bench accuracy` (issue 30): the `compression` case, the seed's
// Truth-Cube set-up (physics/promayon/truth_cube.hpp), and the shape memory's rows of B1. A file
// of its own beside accuracy_runs.cpp, which calls it.
//
// compression: the 9^3-atom block compressed 18.25 % between two plates, each model relaxed by
// the seed's step (unit masses and stiffness: the set-up is scale-free); error_pct the seed's
// epsilon_REN over the 343 interior atoms against the quadratic-tet FEM (nu 0.49) on 8^3 cells,
// volume_change_pct the block's. Models: mass_spring_vn1, mass_spring_moore (variant moore, and
// moore_volume with the exact projection), shape_memory (VN1: every non-collinear triplet),
// shape_memory_volume (the same with the projection), in the full report both again with the
// unmirrored triplet selection (variant vn1_unmirrored, shape_memory.hpp), fem tet10 (the reference, error 0; 4^3
// cells against it, and in the full report 12^3 cells, which shows it converged). ms_per_step:
// the seed's explicit step's wall time in the relaxation (fem: 0, a static solve only).
//
// b1, model shape_memory (variant vn1): the square beam's lattice (2, 4, 6 cells across, as the
// mass-spring's bricks), k_e from E by the calibration (calibration.hpp: the 4^3-cell block's
// apparent modulus), lumped masses rho V / 8 per brick corner. Its equilibrium, as every row's,
// is the linear static solution: the tangent at rest by central differences of the forces (the
// normals' rotation included, which the model's own frozen-normal K leaves out; colours of
// atoms 5 apart so that no atom's force sees two perturbed atoms), solved by sparse LU (the
// redistributed forces derive from no energy: the tangent is not symmetric; at 10 mm the tip is
// the seed's step relaxed with k_a to 1e-5 relative, docs/status.md). ms_per_step: the
// report's implicit Euler timing with the model's frozen-normal K.
#pragma once

#include "bench/accuracy_report.hpp"

#include "common/progress_bar.hpp"

#include <map>
#include <string>
#include <vector>

namespace incise::bench::accuracy {

int compression_runs(bool quick);
std::vector<Row> compression_rows(bool quick, common::ProgressBar& progress);

int shape_memory_beam_runs(const std::vector<int>& cells_across);
// The rows of the square beam's cases (b1) at each size in `cells_across`.
std::vector<Row> shape_memory_beam_rows(const std::vector<Case>& cases, const std::map<std::string, Reference>& references,
                                        const std::vector<int>& cells_across, int timed_steps,
                                        common::ProgressBar& progress);

}  // namespace incise::bench::accuracy
