// The constraint-particle rows of `incise bench accuracy` (issue 31): Dionne's particles
// (physics/cp, digest seed-000-003.md A) on the report's uncut beams, beside the FEM, EFG and
// mass-spring rows. A file of its own beside accuracy_runs.cpp, which calls it per body.
//
// The body: the beam's voxels (the mass-spring's bricks: exact on B1, a staircase on the
// hexagon) each split into 5 tets, the split alternating with the voxel's parity (the thesis's
// cube, make_box_tets5). Constraints: distance on every edge and signed volume on every tet; no
// area constraints (on the surface triangles they are a membrane on the skin, which the
// reference's continuum has not). The thesis tunes one k per constraint by hand; here the
// stiffness is per tet volume (physics::StiffnessScaling::per_volume: each tet gives k_D V_t to
// its six edges and k_V V_t to its volume), so that the skin is no stiffer than the bulk, and
// k_D and k_V (Pa) are calibrated per voxel shape on the lattice's bulk: the homogenised
// stiffness of the periodic lattice (2 x 2 x 2 voxels, each constraint linearised at rest),
// k_V / k_D by bisection until its nu along x is the beam's, then both scaled until its E is (the
// stiffness is linear in them; on cubes this is k_D = 2 mu, k_V = lambda - 2 mu / 3, and nu <= 0.2
// is out of reach). Finite blocks of the lattice in traction then have its E within 6 % (3 to 5
// voxels across, a beam one voxel thick alike), slightly soft (test_constraint_particles_accuracy).
//
// Equilibrium, as every other row: the linear static solution with the network's stiffness at
// rest (sum k grad C grad C^T, exact there as C = 0), the small-strain problem the reference
// solves. The thesis's route to a quasi-static target, Alg. 3.2's relaxation (physics::relax:
// velocity Verlet at half the explicit bound, the stretch limiter, Rayleigh mass damping of
// 2.5 sqrt(g / tip) so that the first mode is about critically damped, until the constraints'
// energy moves by less than 1e-10 of the load's work per step over 100 steps), runs on the
// coarsest body of each case, and the progress notes its steps, its ms per explicit step and
// how far its tip is from the static solve's. ms_per_step: the shared implicit Euler timing
// (time_steps, dt 1/60), like every other row; the explicit step's cost is the note's.
#pragma once

#include "bench/accuracy_report.hpp"

#include "common/progress_bar.hpp"

#include <map>
#include <string>
#include <vector>

namespace incise::bench::accuracy {

struct ParticleCalibration {
  double distance_stiffness = 0, volume_stiffness = 0;  // k_D, k_V (Pa, per tet volume)
  double measured_E = 0, measured_nu = 0;               // the lattice's, with them
};
// k_D and k_V for voxels of size `cell` (m) so that the lattice of them has the material's E
// and nu in traction along x (measured_E, measured_nu: the lattice's, with them). Throws std::runtime_error when no k_V / k_D in
// [1e-4, 1e4] reaches nu.
ParticleCalibration calibrate_constraint_particles(const Vec3& cell, const Material& material);

// How many progress steps constraint_particles_rows takes.
int constraint_particles_runs(const std::vector<int>& cells_across);

// The rows `constraint_particles` (variant tets5) of an uncut body's cases at each size in
// `cells_across` (voxels across the beam's y extent), error against `references` (per case).
std::vector<Row> constraint_particles_rows(Shape shape, const std::vector<Case>& cases,
                                           const std::map<std::string, Reference>& references,
                                           const std::vector<int>& cells_across, int timed_steps,
                                           common::ProgressBar& progress);

}  // namespace incise::bench::accuracy
