// The World: what a scene names, built once, stepped on simulated time.
//
// A step reads as the pipeline it runs (seed 004's loop order; cutting stages join when
// bodies become cuttable):
//   take_tool_input -> contact -> solve -> update_surface   (then the caller publishes)
// Static model data lives in each body's model; the dynamic data is the bodies' States,
// so the state hash covers exactly what determines the future of the simulation.
#pragma once

#include "engine/scene.hpp"
#include "engine/thread_pool.hpp"
#include "engine/trajectory.hpp"
#include "physics/core/model.hpp"
#include "physics/core/implicit_euler.hpp"
#include "physics/cut/linked_across.hpp"
#include "physics/cut/rest_cut.hpp"
#include "physics/cut/surface_topology.hpp"
#include "physics/cut/voxel_boundary.hpp"
#include "physics/cut/front_surface.hpp"
#include "physics/cut/front_mapping.hpp"
#include "physics/cut/volume_cut.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/fem/surface_snap.hpp"
#include "render/frame.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace incise::physics::gpu {
class EfgStep;  // physics/gpu/efg_step.hpp
}

namespace incise::engine {

// Raised when a step stays non-finite after every retry; names the body and the step.
class NonFiniteError : public std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Body {
  std::string name;
  std::unique_ptr<physics::DeformableModel> model;
  physics::State state;
  double last_energy = 0;            // elastic + kinetic after the last step (energy watchdog)
  physics::Vector velocity_change;  // last step's dv: the CG warm start (part of the state hash)
  std::string model_name;                          // "fem" or "efg"
  std::vector<std::uint8_t> fixed;                 // per node
  // The surface the user sees and the tool touches. Tetrahedral bodies: the boundary of the
  // volume mesh, in node indices, its vertices the nodes `surface_nodes`. Meshless bodies
  // (`embedding` set): a mesh of its own, in vertex indices, each vertex moved by the MLS
  // weights of one integration point (seed-004 §2.6), so its resolution is independent of
  // the particles'.
  std::vector<std::array<int, 3>> surface;
  std::vector<int> surface_nodes;                  // tetrahedral: nodes on the surface, increasing
  std::vector<std::uint32_t> render_triangles;     // surface triangles in render-vertex numbering
  // Cuttable bodies: per surface triangle, 1 on a cut face (the tissue a cut exposed), which
  // fill_frame draws in the cut's colour (FrontSurface::on_cut_face).
  std::vector<std::uint8_t> render_cut_face;
  std::optional<physics::SurfaceEmbedding> embedding;
  physics::Vector surface_positions;               // embedded: 3 x vertices, after the last step
  std::vector<std::uint8_t> fixed_vertices;        // embedded: vertices moved by fixed particles only
  // Cuttable bodies (seed 004 §2): the topology graph with its cutter, and the cut surface
  // (physics/cut/front_surface.hpp), which then is the render surface. `previous_positions` are
  // the particles before the last solve: the links move from there to state.positions over
  // the step the blade is tested against (user input happens during the last motion, §2.7).
  physics::CorotationalEfg* efg = nullptr;         // the model, when it is an EFG one
  std::unique_ptr<physics::VolumeCutter> cutter;
  // The thesis's explicit surface cut, with the sweep at rest kept apart for the volume's
  // agreement pass and the count of each vertex's constraint planes at its last mapping.
  std::unique_ptr<physics::FrontSurface> front_surface;
  std::unique_ptr<physics::RestCut> front_rest_cut;
  // EFG bodies: the threads their model's loops run on (efg.threads of them, the physics
  // thread among them; the model owns none), with a helper thread when a `front` body has
  // efg.threads >= 2: a cutting step's surface cut (FrontSurface::advance, the blade's samples
  // at rest) runs on it beside the volume's CCD and re-selection, which need nothing from it
  // (World::cut_body). The model only calls it from its methods, never as it is destroyed.
  std::unique_ptr<ThreadPoolExecutor> executor;
  std::vector<std::size_t> front_plane_counts;
  int front_stroke_folds = 0;  // folded_edges of the stroke's last report
  std::vector<std::uint8_t> front_wrong_side;  // per surface vertex: its point across a cut face when last tested
  bool front_engaged = false;  // the blade was engaged at the end of the last step tested
  int front_mapped_base = 0;   // the surface's base vertex count at the last mapping
  physics::FrontVertexIdentity front_identity;  // the stroke's vertices at the last mapping
  std::vector<physics::Vec3> front_stroke_rest;  // their rest positions (from front_identity.first on)
  // What the stroke had changed at the last mapping (FrontSurface: the replaced slots and
  // those after the base's; the base vertices given planes): the surface elsewhere is the same
  // until the stroke changes it, so each mapping looks at what changed since, not at it all.
  std::vector<int> front_changed_slots, front_planed;
  // The largest distance (per axis) from a vertex below front_reach_upto to its integration
  // point, over its rows since they were counted (a bound: for finding the segments near a box).
  double front_reach = 0;
  int front_reach_upto = 0;
  physics::ElementCubes front_cubes;  // the mapping's candidates, kept between cut events
  // The vertices below front_wrong_upto whose point is across a cut face, off the crack front.
  long front_wrong_base = 0;
  int front_wrong_upto = 0;
  // The surface's boundary and non-manifold edges, kept up to date where it changes (a full
  // count when the body is built).
  physics::SurfaceTopology front_topology;
  std::vector<int> front_blade_pieces;  // the blade's resampling, per segment, kept for the strokes
  physics::Vector previous_positions;
  std::size_t orphans_pinned = 0;       // of efg->orphaned_particles()
  physics::Vec3 surface_min = physics::Vec3::Zero(), surface_max = physics::Vec3::Zero();  // rest box
  std::vector<std::uint8_t> linked_across;          // per element, kept by update_elements_linked_across
  std::vector<std::array<physics::Vec3, 2>> link_boxes;  // its cache of the elements' link boxes
  std::vector<int> linked_seen;  // and per element the rest cut's size when its flag was taken
  physics::LinkedAcrossIndex linked_index;  // and its index of the elements by their centre
  physics::Vector gravity;                         // 3n, constant
  physics::ImplicitEulerSettings integrator;
  // solver.backend "gpu": the body's step, surface and rows on the GPU (its own context).
  std::shared_ptr<physics::gpu::EfgStep> gpu;
  std::vector<std::vector<int>> load_nodes;        // per scene load aimed at this body
  std::vector<std::size_t> load_index;             // which scene load
  std::size_t elements = 0;
  physics::SnapReport snap;  // boundary nodes moved onto the true surface (generated and mesh bodies)
};

// Where time went in one step, and what the solver said.
struct StepStats {
  double ms_tool_input = 0;
  double ms_contact = 0;
  double ms_solve = 0;
  double ms_surface = 0;
  double ms_total = 0;
  int cg_iterations = 0;  // summed over bodies and retried sub-steps
  double cg_residual = 0;  // worst relative residual over bodies
  bool cg_converged = true;
  int nonfinite_events = 0;  // steps that produced a non-finite value and were retried
  int energy_growth_events = 0;
  int contacts = 0;
  std::array<double, 3> tool_force{};  // force of the tissue on the tool, N
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

// What the cutting steps have done so far (metrics.json `cut`, `surface`, `mapping`).
struct CutTotals {
  long events = 0;
  long links_severed = 0;          // by the CCD
  long links_severed_at_rest = 0;  // by the agreement with the rest cut
  long elements_reselected = 0;
  long isolated_elements = 0;     // thesis failure: several cuts in one element
  long nonlocal_reselections = 0;  // re-selected past two particle spacings (thin slices, rims)
  long reselection_failures = 0;
  long orphaned_particles = 0;      // left by every element, pinned
  long positive_mass_elements = 0;  // share their mass by the positive part of phi
  long deactivated_elements = 0;    // no valid neighbourhood left after a cut
  long masses_floored = 0;          // particles kept at a floor mass
  long vertices_remapped = 0;
  long relaxed_fallbacks = 0;
  long wrong_side = 0;            // over every remapping
  long elements_linked_across = 0;  // after the last event: volume and surface cuts disagree
  int worst_boundary_edges = 0;   // over every cut event
  int worst_nonmanifold_edges = 0;
  // efg.cut_surface "front": the stroke samples its stage could not cut (left out: the
  // surface stays as the stroke's last good sample left it, closed), and the first such
  // problem in words.
  long front_problems = 0;
  std::string first_front_problem;
  long front_folded_edges = 0;  // edges a stroke's sheet crossed twice, left uncut (front_surface.hpp)
  long front_strokes_carried_through = 0;  // strokes whose front was carried out of the body at their end
};

struct ToolState {
  ToolSample pose;
  // Blade: the edge in the world at every sample of the step's sweep, their fractions of
  // the step, and whether the blade was engaged over each interval between them.
  std::vector<std::vector<physics::Vec3>> blade_poses;
  std::vector<double> blade_fractions;
  std::vector<std::uint8_t> blade_active;
  std::array<double, 3> tip{};
  std::array<double, 3> tail{};  // capsule end (= tip for a sphere)
  double radius = 0;
  bool present = false;
};

class World {
 public:
  // `trajectory` drives the tool when the scene has one (already read by the caller so the
  // read report can go to the metrics).
  World(const Scene& scene, std::optional<Trajectory> trajectory);

  StepStats step();
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
  // The first kGuardLogLimit events; guard_counts() has them all.
  const std::vector<GuardEvent>& guard_events() const { return guard_events_; }
  static constexpr std::size_t kGuardLogLimit = 200;

  // FNV-1a over the bytes of every body's positions and velocities, in body order.
  std::uint64_t state_hash() const;
  // Fill a render frame (surfaces as floats, tool, camera) from the current state.
  void fill_frame(render::Frame& frame, int width, int height) const;
  std::array<double, 3> bounds_min() const { return bounds_min_; }
  std::array<double, 3> bounds_max() const { return bounds_max_; }

 private:
  void take_tool_input(double time);
  std::vector<physics::NodalSpring> contact(const Body& body, StepStats& stats) const;
  void update_surface(Body& body) const;
  // solver.backend "gpu": the body's GPU step (throws naming the field when it cannot be).
  void make_gpu_backend(Body& body, std::size_t index) const;
  // detect_cuts -> apply_topology for one body (seed 004 §2.7): CCD of the step's blade
  // sweep against its links, re-selection, the cut surface and its mapping.
  void cut_body(Body& body, StepStats& stats);
  void end_front_stroke(Body& body, StepStats& stats);
  // Ends the body's front stroke (FrontSurface::end_stroke with `reach`), counting a front
  // carried through; returns whether it was.
  bool close_front_stroke(Body& body, double reach);
  // dirty_lo/hi: rest box around what the cut changed (for the linked-across check);
  // changed: per element, re-selected; fixed_changed: particles were pinned this step (every
  // vertex's fixed flag is taken again). The rows are redone where the stroke renumbers vertices,
  // where a vertex gained a constraint plane, sits on a changed element, or has the segment
  // to its integration point crossed by the cut faces (seed 004 §2.6's triggers).
  void rebuild_front_surface(Body& body, const physics::Vec3& dirty_lo, const physics::Vec3& dirty_hi,
                             const std::vector<std::uint8_t>& changed, bool fixed_changed, StepStats& stats);
  void solve_body(Body& body, const std::vector<physics::NodalSpring>& springs, double end_time,
                  StepStats& stats);

  Scene scene_;
  std::vector<Body> bodies_;
  std::optional<Trajectory> trajectory_;
  ToolState tool_;
  double time_ = 0;
  std::uint64_t steps_ = 0;
  std::array<double, 3> bounds_min_{}, bounds_max_{};
  GuardCounts guard_counts_;
  CutTotals cut_totals_;
  std::vector<GuardEvent> guard_events_;
  void log_guard(const std::string& body, const std::string& kind, const std::string& detail);
};

// Build one body from its spec (generator or mesh file -> tetrahedra -> model).
Body build_body(const BodySpec& spec, const SolverSpec& solver);

// Force of a load at time t: linear between events, held before the first and after the last.
std::array<double, 3> load_force_at(const LoadSpec& load, double time);

}  // namespace incise::engine
