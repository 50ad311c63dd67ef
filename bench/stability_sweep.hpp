// The numerical stability sweep's parts, shared by its files (bench/stability.cpp says what the
// sweep does): the bodies of each case (stability_bodies.cpp), a run (stability_runs.cpp), the
// thin-slice study (stability_slices.cpp), the CSV, plot and summary (stability_report.cpp).
#pragma once

#include "common/csv.hpp"
#include "physics/core/explicit_integrators.hpp"
#include "physics/core/implicit_euler.hpp"
#include "physics/cut/volume_cut.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/promayon/seed_step.hpp"

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <ostream>
#include <set>
#include <string>
#include <vector>

namespace incise::bench::sweep {

using physics::CorotationalEfg;
using physics::DeformableModel;
using physics::ExplicitScheme;
using physics::Material;
using physics::State;
using physics::Vec3;
using physics::Vector;
using Index = Eigen::Index;

constexpr double density = 1000;
const Vec3 gravity(0, 0, -9.81);
constexpr double rayleigh_mass = 1.0;  // 1/s
constexpr double cg_tolerance = 1e-6;
// The CG budget per step. Jacobi-preconditioned CG on these bodies (about 300 free dofs)
// needs 200 iterations at nu = 0.3 and 450-620 at nu = 0.49 (the system's condition number
// reaches 1e6 when dt^2 K dominates M: measured on the assembled matrix, block-Jacobi saves
// only 10-15 %), more than the dof count, as finite-precision CG loses orthogonality. A cap
// of 1000 separates that slow but steady convergence from the stagnation of locked elements
// at nu = 0.499, which is what cg_not_converged should report.
constexpr int cg_max_iterations = 1000;
constexpr int max_halvings = 3;
constexpr double energy_bound = 100;          // x E_ref
constexpr double displacement_bound = 10;     // x body size
constexpr double cg_capped_fraction = 0.1;    // of the steps
constexpr double beam_length = 0.2;
constexpr double beam_half_side = 0.01;
constexpr double cube_side = 0.04;
constexpr double squeeze = 0.1;               // compression_release starts at 10 % height
constexpr double efg_spacing = 0.005;
constexpr int flipped_nodes = 3;
// fast_blade: a straight vertical edge (x, 0.0215, z), z from fast_blade_top down to
// fast_blade_bottom, moving along +x at blade_speed from x = blade_start_x at t = 0.
constexpr double blade_speed = 5;             // m/s
constexpr double blade_start_x = -0.01;
constexpr double fast_blade_y = 0.0215;
constexpr double fast_blade_bottom = 0.0155;
constexpr double fast_blade_top = 0.06;
// thin_slice: horizontal cuts at these heights, from beyond the free face x = 0.04 back to
// x = thin_slice_front, the cube clamped on its face x = 0.
constexpr double thin_slice_front = 0.0115;
constexpr std::array<double, 2> thin_slice_cuts{0.034, 0.011};  // one element on top, two below

enum class Outcome { stable, diverged, nonfinite, cg_not_converged, refused };
constexpr std::array<Outcome, 5> all_outcomes{Outcome::stable, Outcome::diverged, Outcome::nonfinite,
                                              Outcome::cg_not_converged, Outcome::refused};
const char* outcome_name(Outcome outcome);
int outcome_colour(Outcome outcome);  // the outcome map's colours (RGB)

struct Integrator {
  std::string name;
  bool implicit = false;
  ExplicitScheme scheme = ExplicitScheme::explicit_euler;
  // Promayon's models: the seed's own explicit step (seed_step.hpp) in this scheme instead.
  std::optional<physics::SeedScheme> seed;
};

struct ModelKind {
  std::string name;
  std::vector<Integrator> integrators;
};

// One case at one material for one model: the static set-up of a run.
struct Body {
  std::unique_ptr<DeformableModel> model;
  State initial;
  std::vector<uint8_t> fixed;
  Vector external;
  double size = 0;      // largest side of the rest bounding box, m
  // Elements inverted at positions x (inverted_start only, else empty).
  std::function<int(const Vector&)> count_inverted;
  int inverted = 0;     // in the initial state
  // Cutting (fast_blade, thin_slice): the cutter of the EFG model, and for fast_blade the
  // blade polyline at time t, applied every step. single_use: the run edits the model, so each
  // run needs a fresh body.
  std::unique_ptr<physics::VolumeCutter> cutter;
  const CorotationalEfg* efg = nullptr;  // the model, when it is an EFG one
  std::function<std::vector<Vec3>(double)> blade;
  bool single_use = false;
  std::string note;  // set-up figures for the summary
  // thin_slice: the particles of each slice beyond the cut front (top, then bottom).
  std::vector<std::vector<int>> slices;
  // The model's own explicit step, when it has one (the constraint particles' Alg. 3.2: the
  // integrator, then the stretch limiter; the shape memory's seed step); empty: physics::explicit_step.
  std::function<physics::ExplicitStepReport(const Integrator&, State&, const std::vector<uint8_t>&, const Vector&,
                                            const physics::ExplicitSettings&, physics::VerletHistory&)>
      own_explicit_step;
};

struct Run {
  std::string model;
  std::string integrator;
  std::string case_name;
  double youngs_modulus = 0;
  double poisson_ratio = 0;
  double dt = 0;
  Outcome outcome = Outcome::stable;
  double max_energy_ratio = 0;
  double max_displacement = 0;
  int steps = 0;
  int guard_events = 0;
  int inverted_at_end = -1;  // elements still inverted when the run ended (-1: not counted)
};

struct Sweep {
  std::vector<double> youngs_moduli;
  std::vector<double> poisson_ratios;
  std::vector<double> time_steps;
  std::vector<std::string> cases;
  double beam_duration = 0;
  double cube_duration = 0;
};

// The sweep's grid (stability.cpp).
Sweep make_sweep(bool quick);
const std::set<std::string>& bench_models();
std::vector<ModelKind> model_kinds(std::vector<std::string>* left_out = nullptr);
// This report's figures: 6 significant digits unless a caller asks for others.
std::string format(double value, int digits = 6);

// The cases and their bodies (stability_bodies.cpp).
bool is_beam(const std::string& case_name);
bool model_runs_case(const std::string& model_name, const std::string& case_name);
void pin_orphans(Body& body, State* state = nullptr);
std::string count_pieces(const physics::VolumeCutter& cutter, const physics::VolumeCutReport& total);
Body make_efg_body(const std::string& case_name, const Material& material,
                   physics::EfgRotation rotation = physics::EfgSettings{}.rotation);
Body make_body(const std::string& model_name, const std::string& case_name, const Material& material);

// A run (stability_runs.cpp).
physics::ImplicitEulerSettings implicit_settings(double dt);
Run simulate(Body& body, const Integrator& integrator, double dt, double duration);

// The shape memory's explicit limits (stability_shape_memory.cpp): the 3-atom figure and the
// seed's symplectic step around each cube's bound 2 / omega_max, for the summary.
std::string shape_memory_limits_report(bool quick, std::ostream& progress);

// The thin-slice study (stability_slices.cpp).
std::string thin_slice_report(bool quick, std::ostream& progress);

// Output (stability_report.cpp).
void write_row(common::CsvWriter& csv, const Run& run);
std::string run_key(const std::string& model, const std::string& integrator, const std::string& case_name,
                    double youngs_modulus, double poisson_ratio, double dt);
std::map<std::string, Run> read_previous_runs(const std::filesystem::path& path, std::ostream& progress);
std::string short_modulus(double pascals);
std::string plot_script(const std::string& png, bool quick, const Sweep& sweep, const std::vector<ModelKind>& kinds,
                        const std::vector<Run>& runs);
std::string counts_table(const std::vector<ModelKind>& kinds, const std::vector<Run>& runs);
std::string inverted_table(const std::vector<ModelKind>& kinds, const std::vector<Run>& runs);
std::string bounds_text(const Sweep& sweep);

}  // namespace incise::bench::sweep
