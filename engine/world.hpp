// The World: what a scene names, built once, stepped on simulated time.
//
// A step reads as the pipeline it runs, in seed 004's loop order (World::step, world.cpp):
//   take_tool_input -> resist_cutting -> detect_cuts -> apply_topology -> contact -> solve -> update_surface
// then the caller publishes (fill_frame, the haptic contact model). Each stage is a function
// in a file named after it: the cut stages in physics/cut/ (detect_cuts, apply_topology with
// remap_surface), the others in engine/ (take_tool_input.cpp, contact.cpp, solve.cpp,
// update_surface.cpp, publish.cpp). Each body is a read-only model and its data
// (physics/core/body.hpp, physics/cut/cut_body.hpp); the state hash covers every body's data
// that decides the future, the cut topology included.
#pragma once

#include "engine/body.hpp"
#include "engine/real_time_budget.hpp"
#include "engine/scene.hpp"
#include "engine/trajectory.hpp"
#include "physics/core/body.hpp"
#include "physics/cut/cut_body.hpp"
#include "physics/cut/cutting_resistance.hpp"
#include "physics/cut/detect_cuts.hpp"
#include "physics/needle/needle.hpp"
#include "render/frame.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace incise::engine {

// Raised when a step stays non-finite after every retry; names the body and the step.
class NonFiniteError : public std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The needle's step (engine/insert_needle.cpp): its phase, how deep the tip is past where it first
// met the tissue, the force on it (also in StepStats::tool_force) along and across its axis, the
// cutting and friction parts, and its nodes' grip.
struct NeedleStepStats {
  bool present = false;
  std::string phase = "approach";  // approach, puncture, insert, retract
  double depth = 0;                // m, along the axis from the first contact point
  double speed = 0;                // m/s along the axis (negative: retracting)
  double axial = 0;                // N, the tissue's force on the needle along its axis
  double lateral = 0;              // N, across it
  double cutting = 0;              // C, N (resisting the needle)
  double friction = 0;             // N along the axis, static and kinetic
  double balance = 0;              // N, |force on the needle + forces on the tissue| (round-off)
  int sticking = 0, slipping = 0;  // nodes
  long stick_to_slip = 0, slip_to_stick = 0;  // since the start
  // m, the mean displacement of the bodies' nodes from rest along the axis (the template's: the
  // first needle's), at the step's start: the deformation along the needle axis (seed 002 §5.8).
  double axial_displacement = 0;
};

// Where time went in one step, and what the solver said.
struct StepStats {
  double ms_tool_input = 0;
  double ms_resistance = 0;  // resist_cutting: the edge pieces in the tissue (physics::mark_engaged)
  double ms_contact = 0;
  double ms_solve = 0;
  double ms_assembly = 0;  // of ms_solve: assembling the current system (solver.preconditioner "multigrid_current")
  double ms_surface = 0;
  double ms_total = 0;
  int cg_iterations = 0;  // summed over bodies and retried sub-steps
  // CG's preconditioner (solver.preconditioner; "jacobi" on the gpu backend and for models
  // without a rest stiffness), and for the warped factor: its age (steps since the first cut
  // it lacks), its build time, and the time this step waited for a late one.
  std::string preconditioner = "jacobi";
  long long preconditioner_age = 0;
  double preconditioner_build_ms = 0;
  double preconditioner_wait_ms = 0;
  double cg_residual = 0;  // worst relative residual over bodies
  bool cg_converged = true;
  int cg_budget_stops = 0;  // CGs the real-time budget stopped unconverged (engine/real_time_budget.hpp)
  int nonfinite_events = 0;  // steps that produced a non-finite value and were retried
  int energy_growth_events = 0;
  int contacts = 0;
  std::array<double, 3> tool_force{};  // force of the tissue on the tool, N
  std::array<double, 3> tool_tip{};    // the tool's position at the end of the step, m
  bool blade_engaged = false;          // the blade's button was held during the step
  // The tissue's resistance to the blade (engine/cutting_resistance.cpp): the cutting force on
  // the tool (in tool_force too), the engaged edge length, and the engagement's phase: pressing
  // (engaged, before the onset: the edge indents like a probe, nothing is cut) or cutting.
  std::array<double, 3> cutting_force{};
  double engaged_length = 0;  // m
  bool blade_pressing = false;
  bool blade_cutting = false;
  // Cutting (blade tools and cuttable bodies).
  bool cut_tested = false;   // the blade was engaged near a cuttable body: CCD ran
  bool cut_event = false;    // the topology changed this step
  double ms_ccd = 0;         // broad phase, continuous collision
  double ms_topology = 0;    // neighbourhoods, MLS, masses, surface, mapping. Its main
  // parts, each in ms: the sweep mapped to rest and the surface's cut faces, the volume's
  // re-selection (MLS, masses), the surface rebuild, the vertex mapping, and the checks
  // (surface topology, elements linked across the cut) that feed the metrics.
  double ms_rest_cut = 0, ms_reselect = 0, ms_surface_rebuild = 0, ms_mapping = 0, ms_checks = 0;
  // Front surfaces: the surface's cut (FrontSurface::advance) on its own thread, which runs
  // beside the volume's CCD and re-selection; ms_rest_cut and ms_topology count only the time
  // the step waited for it beyond those (its critical-path share, ms_front_wait), this the
  // whole of it: ms_topology - ms_front_wait + ms_front_cut is the same work done in sequence.
  double ms_front_cut = 0, ms_front_wait = 0;
  int links_severed = 0;
  double elastic_energy = 0;
  double kinetic_energy = 0;
  NeedleStepStats needle;                // the needle, or the template's sum (engine/insert_needle.cpp)
  std::vector<NeedleStepStats> needles;  // each needle of a template of several
  // GPU backend: bytes uploaded this step, and of them the rows (element, incidence, surface).
  long long gpu_bytes = 0;
  long long gpu_row_bytes = 0;
};

// A guard that fired: always counted, and logged with the step and the body.
struct GuardEvent {
  std::uint64_t step = 0;
  double time = 0;
  std::string body;
  std::string kind;    // "nonfinite_retry", "cg_not_converged", "energy_growth"
  std::string detail;  // figures: residual, energies, dt
};

struct GuardCounts {
  long nonfinite_retries = 0;
  long cg_not_converged = 0;
  long energy_growth = 0;
};

using CutTotals = physics::CutTotals;

struct ToolState {
  ToolSample pose;
  // Blade: the edge in the world at every sample of the step's sweep, their fractions of
  // the step, and whether the blade was engaged over each interval between them.
  std::vector<std::vector<physics::Vec3>> blade_poses;
  std::vector<double> blade_fractions;
  std::vector<std::uint8_t> blade_active;
  std::array<double, 3> tip{};
  std::array<double, 3> tail{};  // capsule end (= tip for a sphere)
  // Needle: each needle of the template (ToolSpec::needles) at the step's end, its tip and hub.
  std::vector<std::array<double, 3>> needle_tips, needle_tails;
  double radius = 0;
  bool present = false;
  // Blade: the crack's onset and whether it advances (physics/cut/cutting_resistance.hpp), and
  // whether this step's edge presses on the tissue before the onset (penalty contact).
  physics::CuttingState cutting;
  bool pressing = false;
  // Cutting, the edge left the tissue over this step: the cut stages still cut its sweep (the
  // edge passes out through the tissue's last part), then the engagement ends.
  bool leaving = false;
  double engaged_length = 0;  // m, at the step's end
  double onset_width = 0;     // m, the engaged length across the edge's motion
  physics::Vec3 cutting_force = physics::Vec3::Zero();  // N on the tool over the step (0 unless cutting)
};

class World {
 public:
  // `trajectory` drives the tool when the scene has one (already read by the caller so the
  // read report can go to the metrics).
  World(const Scene& scene, std::optional<Trajectory> trajectory);
  // Copying the world copies the simulation: the copy steps on to the same states as this
  // one, bit for bit (the same state_hash() after every step), and shares nothing that
  // either changes (engine/body.hpp: each body's data, cut and threads its own). Throws
  // std::runtime_error for a world with a body on the GPU.
  World(const World& other) = default;
  World& operator=(const World& other) = default;
  World(World&&) = default;
  World& operator=(World&&) = default;

  // One step. `deadline_ns` (steady_now_ns clock; 0: none) is when a live session needs the
  // step done (real time, engine/real_time_budget.hpp): its CGs stop in time for the surface
  // update after them. A trajectory's recorded CG stops are repeated whatever the deadline.
  StepStats step(std::int64_t deadline_ns = 0);
  // The CG stops the deadlines made since the last call, for the recording (in order).
  std::vector<CgStop> take_cg_stops() { return budget_.take_stops(); }
  const RealTimeBudget& real_time_budget() const { return budget_; }
  // Live tool input (issue 5): the tool's samples arrive while the world runs, from the haptic
  // loop, instead of all being known up front. Each step uses the samples as a recorded
  // trajectory would (the pose at the step's end and every sample inside it as the blade's
  // sweep), so a live session and a replay of its recording step identically, provided the
  // samples bracketing the step's end are there before step() (engine/haptic_session.hpp
  // waits for them). Samples a step no longer needs are dropped. Throws std::invalid_argument
  // naming the sample for a time earlier than the last one, a non-finite number or a
  // quaternion away from unit; std::logic_error without a tool.
  void append_tool_samples(std::span<const ToolSample> samples);
  // The newest tool sample the world holds (live input), or the trajectory's last.
  double last_tool_sample_time() const;
  double time() const { return time_; }
  std::uint64_t steps_taken() const { return steps_; }
  double dt() const { return scene_.solver.dt; }
  const Scene& scene() const { return scene_; }
  const std::vector<Body>& bodies() const { return bodies_; }
  const ToolState& tool() const { return tool_; }
  const GuardCounts& guard_counts() const { return guard_counts_; }
  const CutTotals& cut_totals() const { return cut_totals_; }
  bool blade() const { return tool_.present && scene_.tool->shape == "blade"; }
  bool needle() const { return tool_.present && scene_.tool->shape == "needle"; }
  // Needle: per body, the (first) needle in it (physics/needle/needle.hpp).
  const std::vector<physics::Needle>& needles() const { return needle_.front().bodies; }
  // The template's needles (ToolSpec::needles), and per body the k-th one in it.
  std::size_t needle_count() const { return needle_.size(); }
  const std::vector<physics::Needle>& needle_bodies(std::size_t k) const { return needle_.at(k).bodies; }
  // The positions of body b's tissue points, those its needles' zones name: its nodes, or a
  // meshless body's integration points (physics/needle/needle_efg.hpp), 3 x points.
  physics::Vector needle_tissue_positions(std::size_t b) const;
  // The first kGuardLogLimit events; guard_counts() has them all.
  const std::vector<GuardEvent>& guard_events() const { return guard_events_; }
  static constexpr std::size_t kGuardLogLimit = 200;

  // FNV-1a over everything that decides the future, in body order: each body's positions,
  // velocities and last dv (motion_hash), then its cut topology (the EFG rows, masses, fixed
  // particles, the surface and its mapping: physics/cut/cut_state_hash.hpp).
  std::uint64_t state_hash() const;
  // The positions, velocities and dv alone.
  std::uint64_t motion_hash() const;
  // Back to the state the world was built in (t = 0, the bodies as the scene makes them, the
  // trajectory as given: live samples appended since are dropped), keeping the scene.
  void reset();
  // Fill a render frame (surfaces as floats, tool, camera) from the current state.
  void fill_frame(render::Frame& frame, int width, int height) const;
  std::array<double, 3> bounds_min() const { return bounds_min_; }
  std::array<double, 3> bounds_max() const { return bounds_max_; }
  double toughness() const;  // G_c of the body the blade cuts, J/m^2

 private:
  void build();  // the bodies and the tool from the scene (the constructor, reset)
  void take_tool_input(double time);
  std::vector<physics::NodalSpring> contact(const Body& body, StepStats& stats) const;
  // The blade's phase and cutting force for the step (after take_tool_input: before the onset
  // the blade's sweep is not engaged for the cut stages), and the onset's work after the solve
  // from the bodies' mass centres before it (engine/cutting_resistance.cpp).
  void resist_cutting(StepStats& stats);
  std::vector<physics::Vec3> mass_centres() const;
  void advance_onset(const std::vector<physics::Vec3>& centres_before, StepStats& stats);
  void update_surface(Body& body) const;
  // The needle's forces on every body this step (engine/insert_needle.cpp), as explicit springs.
  void build_needle();
  std::vector<std::vector<physics::NodalSpring>> insert_needle(StepStats& stats);
  // solver.backend "gpu": the body's GPU step (throws naming the field when it cannot be).
  void make_gpu_backend(Body& body, std::size_t index) const;
  // The cut stages of one cuttable body (physics/cut/detect_cuts.hpp, apply_topology.hpp).
  physics::BladeSweep blade_sweep() const;
  std::optional<physics::RestSweep> detect_cuts(Body& body, physics::CutStepReport& report);
  void apply_topology(Body& body, const std::optional<physics::RestSweep>& sweep, physics::CutStepReport& report);
  const physics::RestFactor* prepare_preconditioner(Body& body, StepStats& stats);
  void solve(Body& body, const std::vector<physics::NodalSpring>& springs, double end_time,
                  StepStats& stats);

  Scene scene_;
  std::vector<Body> bodies_;
  std::optional<Trajectory> trajectory_;
  std::optional<Trajectory> initial_trajectory_;  // for reset()
  ToolState tool_;
  // Needle: per needle of the template, one per body, the tip at the last step, where it first
  // met the tissue, the phase.
  struct NeedleTrack {
    std::vector<physics::Needle> bodies;
    physics::Vec3 last_tip = physics::Vec3::Zero();
    bool touched = false;
    physics::Vec3 entry = physics::Vec3::Zero();
    std::string phase = "approach";
  };
  std::vector<NeedleTrack> needle_;
  std::vector<physics::Vector> needle_points_;  // per body: a meshless body's integration points this step (else empty)
  std::string needles_phase_ = "approach";  // the template's, from its needles' (insert_needle.cpp)
  // One needle's step on every body: its forces added to `springs`, its figures in `out`; returns
  // the tissue's force on it.
  physics::Vec3 step_needle(NeedleTrack& track, const physics::NeedlePose& pose,
                            std::vector<std::vector<physics::NodalSpring>>& springs, NeedleStepStats& out);
  double time_ = 0;
  std::uint64_t steps_ = 0;
  std::array<double, 3> bounds_min_{}, bounds_max_{};
  GuardCounts guard_counts_;
  CutTotals cut_totals_;
  std::vector<GuardEvent> guard_events_;
  RealTimeBudget budget_;
  double ms_after_solve_ = 0;  // the last step's surface update: what a CG deadline leaves room for
  // Per body, the triangles nearest to the blade's pieces at the last resist_cutting: a hint
  // that spares mark_engaged work (physics/core/nearest_triangles.hpp), never a result's bit.
  std::vector<std::vector<int>> engaged_hints_;
  void log_guard(const std::string& body, const std::string& kind, const std::string& detail);
};

// Force of a load at time t: linear between events, held before the first and after the last.
std::array<double, 3> load_force_at(const LoadSpec& load, double time);

}  // namespace incise::engine
