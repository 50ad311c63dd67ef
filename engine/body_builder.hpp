// Scene body -> engine::Body: the shape (generator or mesh file), the model named by the
// body's `model` key, built by its entry in the registry (engine/model_registry.hpp; fem:
// tetrahedra filling the shape; efg: the meshless model with a render surface of its own, and
// for a cuttable body the cut's state), fixed regions, gravity, the settled start and the
// integrator's settings. The parts below build_body are what the models' builders share.
#pragma once

#include "engine/body.hpp"
#include "engine/mesh_import.hpp"
#include "engine/scene.hpp"
#include "physics/fem/surface_snap.hpp"
#include "physics/fem/tet_mesh.hpp"
#include "physics/mss/hex_mesh.hpp"

#include <functional>
#include <memory>

namespace incise::engine {

// Throws std::runtime_error naming the body (and the field, where one is at fault).
Body build_body(const BodySpec& spec, const SolverSpec& solver);

// What the body occupies: an inside test and its bounding box; for an imported mesh also its
// sections along lines (engine/mesh_shape.hpp), which the fairing uses; for a tetrahedral mesh
// also the tetrahedra (whose boundary is the shape), which a fem body takes as they are.
struct BodyShape {
  std::function<bool(const physics::Vec3&)> inside;
  physics::LineQuery along;
  physics::Vec3 lo, hi;
  std::shared_ptr<const physics::TetMesh> tets;
  // A mesh body's surface (the file's, or the tetrahedral mesh's boundary) as read for the
  // shape: a meshless body's render surface is taken from it, not from the file again.
  std::shared_ptr<const TriangleSoup> surface;
};

// A tetrahedral mesh's boundary faces on the nodes they use (outward, as boundary_triangles).
TriangleSoup boundary_surface(const physics::TetMesh& tets);

// Tetrahedra filling the shape with cells of about `resolution`: a box exactly, a tetrahedral
// mesh as it is, anything else by voxels whose boundary nodes are snapped onto the true surface
// (reported in `snap`).
physics::TetMesh fill_with_tets(const BodySpec& spec, const BodyShape& shape, double resolution,
                                physics::SnapReport* snap);
// The cells of a hexahedral model (mass_spring, Promayon's lattices): a box generator's box cut
// into cells of about `resolution`, anything else voxelised (the cells whose centre is inside);
// a shape no cell's centre is inside is refused, naming the cell (`brick`, `lattice cell`).
physics::HexMesh hex_cells(const BodySpec& spec, const BodyShape& shape, const std::string& cell);
// From body.surface (triangles over node indices, `node_count` nodes): the model's surface nodes
// in increasing order and the body's render triangles indexed into them.
void index_surface(physics::BodyModel& model, physics::BodyData& body, int node_count);
// The read-only part every body has: name, kind (the model's name), integrator, gravity.
std::shared_ptr<physics::BodyModel> body_model(const BodySpec& spec, const SolverSpec& solver);
// Positions at rest, velocities and the velocity change zero.
void start_at_rest(physics::BodyData& body);
// Marks the nodes of `rest` inside any of the spec's fixed boxes.
void fix_nodes(physics::BodyData& body, const BodySpec& spec, const physics::Vector& rest);
// solver.start "settled": adds the model's static displacement under gravity (`settle`, which
// needs the body held by its fixed regions) to the body's positions and times it in
// build_ms.settle, so a replay does not begin with the body dropping; a failure is rethrown
// naming the body (`where`) and what the start needs. Nothing for any other start.
void settle_if_asked(Body& result, const SolverSpec& solver, const std::string& where,
                     const std::function<physics::Vector()>& settle);

}  // namespace incise::engine
