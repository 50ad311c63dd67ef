// Scene files: JSON in, a validated Scene out (docs/scenes.md is the reference).
//
// Every field is checked where it is read; an error names the file and the field
// (`bodies[0].material.nu: 0.7 must be in [0, 0.5)`), unknown keys are errors, and all
// the errors of a file are reported together so a user fixes them in one pass.
#pragma once

#include "physics/needle/needle_settings.hpp"

#include <any>
#include <array>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace incise::physics {
struct TetMesh;
}

namespace incise::engine {

using Point = std::array<double, 3>;

class SceneError : public std::runtime_error {
 public:
  SceneError(const std::string& file, std::vector<std::string> errors);
  const std::vector<std::string>& errors() const { return errors_; }

 private:
  std::vector<std::string> errors_;
};

struct Box {
  Point min{};
  Point max{};
  bool contains(const Point& p, double tolerance = 0) const;
};

struct MaterialSpec {
  double youngs_modulus = 0;  // Pa
  double poisson_ratio = 0;
  double density = 0;  // kg/m^3
  // Fracture toughness G_c, J/m^2: the energy a unit area of cut takes (the blade's
  // resistance, physics/cut/cutting_resistance.hpp; default physics::kLiverToughness).
  double toughness = 200;
};

// Either a mesh file (closed surface, read with assimp and filled with elements) or a
// generated shape.
struct GeneratorSpec {
  std::string type;  // "box", "ellipsoid", "organ", "cylinder", "torus"
  Box box;           // box
  Point center{};    // ellipsoid, organ, cylinder, torus
  Point radii{};     // ellipsoid, organ
  int axis = 2;      // cylinder, torus: 0, 1, 2 for x, y, z
  double radius = 0;        // cylinder; torus: the tube's radius
  double length = 0;        // cylinder, along its axis
  double major_radius = 0;  // torus: centre to the tube's centre line
};

// Settings of the meshless model (bodies with model "efg"); see physics/efg/corotational_efg.hpp.
struct EfgSpec {
  int neighbours = 8;            // 8 (the particle cell's corners) or 4 (the nearest corners)
  std::optional<double> support_factor;  // h = factor x farthest neighbour; default: the model's
  int samples_per_axis = 4;      // volume estimation: samples^3 points per integration cube
  bool estimate_volumes = true;  // false: every touched cube counts a full a^3
  int threads = 2;               // element loop threads (results do not depend on it)
  std::optional<double> surface_resolution;  // render surface cell size (generated bodies), m
  // A cuttable mesh body's first surface: the voxel boundary put onto the shape (false), or the
  // mesh's own triangles (true: `"base_surface": "mesh"`).
  bool base_surface_mesh = false;
};

struct BodySpec {
  std::string name;
  std::string model;  // a registered model (engine/model_registry.hpp): "fem" (corotational linear tetrahedra), "efg"
  // Resolved against the scene's folder: a closed surface (anything assimp reads), filled at
  // `resolution`, or a tetrahedral mesh (engine/tet_mesh_import.hpp: .msh, .vtk), which is the
  // fem body's discretisation (and an efg body's shape).
  std::optional<std::filesystem::path> mesh;
  double mesh_scale = 1;
  std::string mesh_up = "z";  // the file's axis that is the scene's +z (engine::turn_up)
  // The tetrahedral mesh as the scene reader read it (for its mean edge length, when no
  // `resolution` is given): the build takes it rather than reading and checking the file again.
  // From `mesh`, `mesh_scale` and `mesh_up` as read; whoever changes those afterwards resets it.
  std::shared_ptr<const physics::TetMesh> tets;
  std::optional<GeneratorSpec> generator;
  // fem: tetrahedra cell size; efg: integration cube side a (particles 2a apart), m. With a
  // tetrahedral mesh it may be left out: the mesh's mean edge length.
  double resolution = 0;
  EfgSpec efg;            // model "efg" only
  std::any settings;      // another registered model's own settings block, as its read_settings left it
  bool cuttable = false;  // models that can be cut only (efg): the blade cuts it (topology graph, CCD, cut surface)
  MaterialSpec material;
  std::vector<Box> fixed;  // nodes inside any box are fixed
  double damping_mass = 0;       // Rayleigh alpha, 1/s
  double damping_stiffness = 0;  // Rayleigh beta, s
};

// A needle tool's needle (seed 002 §2.3: "any number of needles"): where it sits in the tool's
// frame and how far behind the shared trajectory it follows it.
struct NeedleEntry {
  Point offset{0, 0, 0};  // m, its tip in the tool's frame (the trajectory's position the origin)
  double delay = 0;       // s: at time t it is where the tool was at t - delay (the first sample before it)
};

struct ToolSpec {
  // "sphere", "capsule" (probes, penalty contact), "blade" (cuts, no force) or "needle" (seed 002
  // §2.3: zones of influence, no contact; physics/needle/needle.hpp)
  std::string shape;
  double radius = 0;
  double length = 0;  // capsule: along the tool's local -z from the tip... see docs
  double stiffness = 0;  // penalty contact stiffness per surface node, N/m
  // Blade: the flanks' Coulomb-like friction per metre of engaged edge, N/m
  // (physics/cut/cutting_resistance.hpp).
  double flank_friction = 20;
  // Blade: whether it presses like a probe until the crack's onset (engine/cutting_resistance.cpp),
  // the default; off, it cuts from first contact (an ideal blade), resisted all the same.
  bool onset = true;
  std::optional<std::filesystem::path> trajectory;
  // Blade: the cutting edge, a polyline in the tool's frame (m; the trajectory's position is
  // the frame's origin). An ideal blade (seed 004 §2.2): no volume, no force, it cuts the
  // cuttable bodies wherever its edge passes while engaged (trajectory buttons bit 0).
  std::vector<Point> edge;
  // Needle: its nodes, zones and the tissue's intensities (`length` above is the needle's too).
  physics::NeedleSettings needle;
  // Needle: the template the trajectory drives (`needles`; one at the origin without it).
  std::vector<NeedleEntry> needles;
};

struct SolverSpec {
  double dt = 0;
  double tolerance = 1e-6;
  int max_iterations = 200;
  std::string backend = "cpu";
  std::string precision = "single";  // gpu backend: "single" or "double" (the cpu one is double)
  int batch_rows = 256;              // gpu backend: rows per upload batch
  Point gravity{0, 0, -9.81};
  double duration = 0;  // s of simulated time for a replay
  int max_retries = 3;  // halvings of dt after a non-finite step
  // CG's preconditioner on the cpu backend (physics/solve/rest_preconditioner.hpp): "jacobi",
  // "two_level", "multigrid", "multigrid_current" or "warped_cholesky" (rest-shape factors
  // warped by the rotations, rebuilt beside the steps after a cut and taking over
  // `preconditioner_latency` steps later). multigrid_current is the default: its V-cycle smooths
  // with the current system the step assembles, 8 CG iterations at 20k elements while cutting
  // against multigrid's 20 and Jacobi's 76 (docs/status.md, "EFG model"). Bodies it cannot
  // assemble (tet FEM, damped or extra-stiffness models) take "multigrid"; models without a rest
  // stiffness (mass_spring, constraint_particles, promayon) and the gpu backend use Jacobi.
  std::string preconditioner = "multigrid_current";
  // -1 (the key absent): the body's own, preconditioner_latency().
  int preconditioner_latency = -1;
  // "multigrid", "multigrid_current": the Chebyshev smoother's degree; 0 (the key absent): the
  // kind's own, multigrid_smoothing_degree().
  int multigrid_smoothing = 0;
  // "multigrid": the smoother's copy of the rest system, "double" or "float" (rounded once per
  // factor build; changes the iterates' round-off, so not the default).
  std::string multigrid_precision = "double";
  std::string start = "rest";  // "rest", or "settled": start from static equilibrium under gravity
  // Real time (engine/real_time_budget.hpp): live sessions (`run`, `session`, `bench haptics`)
  // stop each step's CG when its time is up, after at least realtime_min_iterations; replay
  // ignores it and repeats the stops a recording holds.
  bool realtime = true;
  int realtime_min_iterations = 3;
};

// The smoother's degree a solver uses: multigrid_smoothing if given, else 4 for
// "multigrid_current" (its smoother multiplies by the current system: degree 4 takes CG from
// 14 to 8 iterations at 20k elements while cutting for about the same work a solve) and 2 for
// "multigrid" (its rest-system smoother lags the cuts: degree 4 only takes 19 to 16 there;
// docs/status.md, "EFG model").
int multigrid_smoothing_degree(const SolverSpec& solver);

// The steps between a cut and its new factor taking over for a body of `model` (BodySpec::model):
// preconditioner_latency if given, else 12 for an EFG body under "multigrid_current" and 4 for
// the rest. Only that cycle's coarse correction lags a cut (its smoother multiplies by the
// current system), and a factor up to 22 steps old costs it 0.2-1.4 % more CG iterations than
// one 6 steps old on default, cut_organ, cut_liver_mesh and cut_torus (0.4-12 % for one never
// rebuilt), where builds every 5 steps took about half a core beside the step's two threads at
// 20k elements; a rest smoother lags with its factor, so "multigrid" rebuilds sooner
// (docs/status.md, "EFG model").
int preconditioner_latency(const SolverSpec& solver, const std::string& model);

struct LoadEvent {
  double time = 0;
  Point force{};  // total force, N, spread over the region's nodes by mass
};

struct LoadSpec {
  std::string body;
  Box region;
  std::vector<LoadEvent> events;  // increasing times; linear in between, held outside
};

struct CameraSpec {
  Point eye{};
  Point target{};
  double fov_deg = 40;
};

struct RenderSpec {
  int capture_every = 0;  // steps; 0: no frames
  int width = 640;
  int height = 480;
  std::optional<CameraSpec> camera;  // fitted to the bodies when absent
  bool floor = true;
  double floor_z = 0;
};

struct Expectation {
  std::string metric;  // dotted path into metrics.json, e.g. "positions_digest.max_displacement"
  std::optional<double> min;
  std::optional<double> max;
};

// A planned incision (`plan`): the line the trainee should cut along on the organ's surface at
// rest, how deep, and the tolerance band; engine/incision_score.hpp scores the cut against it.
struct PlanSpec {
  std::string body;          // the cuttable body it is drawn on (default: the first cuttable one)
  std::vector<Point> path;   // >= 2 points at rest, m; projected onto the surface along `direction`
  double depth = 0;          // target depth below the surface along `direction`, m
  double band = 0;           // half-width of the tolerance band, m (also the depth tolerance)
  Point direction{0, 0, -1}; // the blade's way into the tissue (unit)
};

struct Scene {
  std::filesystem::path file;
  std::string name;
  std::string description;
  std::vector<BodySpec> bodies;
  std::optional<ToolSpec> tool;
  SolverSpec solver;
  std::vector<LoadSpec> loads;
  RenderSpec render;
  std::vector<Expectation> expect;
  std::optional<PlanSpec> plan;
};

// The axis-aligned box a generated shape fills.
Box generator_bounds(const GeneratorSpec& generator);
// What building `body` over the box [lo, hi] takes, estimated from its cell count at its
// resolution (engine/scene.cpp has the measured bytes per cell), and the refusal when that is
// more than the machine's physical memory (or `memory_bytes`, tests): the cells and the
// estimate, named so the user can see which resolution to coarsen. Checked before anything of
// the body is allocated: by parse_scene for generated bodies, by build_body for meshes.
double estimated_bytes(const BodySpec& body, const Point& lo, const Point& hi);
std::optional<std::string> size_problem(const BodySpec& body, const Point& lo, const Point& hi,
                                        std::optional<double> memory_bytes = std::nullopt);

// Reads and validates; throws SceneError listing every problem.
Scene load_scene(const std::filesystem::path& file);
// The same from text (tests); `file` only names the source in messages and resolves paths.
Scene parse_scene(const std::string& text, const std::filesystem::path& file);

}  // namespace incise::engine
