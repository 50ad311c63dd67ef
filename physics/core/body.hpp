// A simulated body split as MuJoCo splits a simulation (mjModel / mjData): what is built once
// from the scene and only read while stepping (BodyModel), and what the steps write
// (BodyData). The engine builds both (engine/body_builder.hpp) and wires the step's stages
// over them; a cuttable body's cut bookkeeping is physics/cut/cut_body.hpp's.
//
// The mechanical model (DeformableModel) belongs to the data: its per-element rotations
// change every step, and a cut re-selects an EFG body's neighbourhoods, which recomputes their
// shape functions and moves their masses (seed 004 §2.4).
#pragma once

#include "physics/core/implicit_euler.hpp"
#include "physics/core/model.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/fem/surface_snap.hpp"
#include "physics/solve/rest_preconditioner.hpp"

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace incise::physics {

// A model that steps itself instead of by implicit Euler (constraint particles: an explicit
// scheme, then position projections, physics/cp/cp_step.hpp; Promayon's bodies: the seed's
// step order, physics/promayon/seed_step.hpp): advances `state` over settings.dt from
// `start_time` (s; V0(t) curves read it) with the forces `external` and the springs' forces
// (applied explicitly), and reports like implicit_euler_step (cg converged, no iterations).
// The guarded step halves its dt on a non-finite step as it does implicit Euler's; the start
// time then follows the halved steps.
using OwnStep = std::function<StepReport(DeformableModel& mechanics, State& state, const std::vector<std::uint8_t>& fixed,
                                         const Vector& external, const std::vector<NodalSpring>& springs,
                                         const ImplicitEulerSettings& settings, double start_time)>;

struct BodyModel {
  std::string name;
  std::string kind;  // the model's name in the registry: "fem", "efg"
  ImplicitEulerSettings integrator;
  OwnStep own_step;  // empty: implicit Euler (the engine's solve stage)
  PreconditionerSettings preconditioner;
  Vec3 gravity = Vec3::Zero();  // acceleration, m/s^2 (lumped into BodyData::gravity)
  // The body's box at rest (its shape's), the region a whole-surface remapping covers.
  Vec3 rest_lo = Vec3::Zero(), rest_hi = Vec3::Zero();
  std::size_t elements = 0;
  std::vector<int> surface_nodes;  // tetrahedral bodies: the nodes on the surface, increasing
  SnapReport snap;  // boundary nodes moved onto the true surface (generated and mesh bodies)
  // Per scene load aimed at this body: which load, and the nodes it pulls.
  std::vector<std::size_t> load_index;
  std::vector<std::vector<int>> load_nodes;
};

// Copying the data copies the simulation (STYLE.md, MuJoCo's mjData): a copy is deep (its own
// mechanical model, efg pointing at it) and steps on to the same future, bit for bit.
struct BodyData {
  BodyData() = default;
  BodyData(const BodyData& other);
  BodyData& operator=(const BodyData& other);
  BodyData(BodyData&&) noexcept = default;
  BodyData& operator=(BodyData&&) noexcept = default;
  ~BodyData() = default;

  std::unique_ptr<DeformableModel> mechanics;
  CorotationalEfg* efg = nullptr;  // mechanics, when it is an EFG model
  State state;
  WarmStart warm_start;  // the last steps' dv: CG's start (warm_start.hpp)
  double last_energy = 0;  // elastic + kinetic after the last step (the energy watchdog)
  std::vector<std::uint8_t> fixed;  // per node
  // Counts the changes of the mechanics' topology (a cut's re-selections, pinned particles):
  // the preconditioner rebuilds its factor when it moves.
  std::uint64_t topology_revision = 0;
  RestPreconditioner preconditioner;  // the factor the solves use, and the one being built
  Vector gravity;  // 3n; lumped again when a cut moves the masses
  // The surface the user sees and the tool touches. Tetrahedral bodies: the boundary of the
  // volume mesh, in node indices (BodyModel::surface_nodes). Meshless bodies (`embedding`
  // set): a mesh of its own, each vertex moved by the MLS weights of one integration point
  // (seed 004 §2.6), so its resolution is independent of the particles'.
  std::vector<std::array<int, 3>> surface;
  std::vector<std::uint32_t> render_triangles;  // surface triangles in render-vertex numbering
  // Per surface triangle, 1 on a cut face (the tissue a cut exposed), drawn in the cut's colour.
  std::vector<std::uint8_t> render_cut_face;
  std::optional<SurfaceEmbedding> embedding;
  Vector surface_positions;  // embedded: 3 x vertices, after the last step
  std::vector<std::uint8_t> fixed_vertices;  // embedded: vertices moved by fixed particles only
};

// A vertex moved only by fixed particles is fixed: the tool cannot push it. 1 when every
// particle of vertex v's row is fixed.
std::uint8_t fixed_vertex(const BodyData& body, int v);
// fixed_vertex for every vertex of the embedding.
void set_fixed_vertices(BodyData& body);
// Surface vertex v's position from its embedding row and the particles' positions (one row of
// CorotationalEfg::surface_positions).
void set_surface_position(BodyData& body, int v);

}  // namespace incise::physics
