// What cutting adds to a cuttable EFG body (seed 004 §2), split as the body is
// (physics/core/body.hpp): CutModel, built once and only read, and CutData, which every cut
// writes: the topology graph, the thesis's front surface with the sweep kept at rest, and the
// caches that let each cut look only at what it changed. The step's cut stages take them
// (detect_cuts.hpp, apply_topology.hpp, remap_surface.hpp); engine/ only wires them.
#pragma once

#include "physics/core/body.hpp"
#include "physics/cut/front_mapping.hpp"
#include "physics/cut/front_surface.hpp"
#include "physics/cut/linked_across.hpp"
#include "physics/cut/rest_cut.hpp"
#include "physics/cut/surface_topology.hpp"
#include "physics/cut/volume_cut.hpp"

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace incise::physics {

struct CutModel {
  double spacing = 0;       // a, the integration grid's (sweep resampling, margins)
  double surface_cell = 0;  // the first surface's voxel cell (efg.surface_resolution)
  // The front's width w: 1.5 surface cells (seed 004 §2.5: about the surface's triangle size).
  double front_width() const { return 1.5 * surface_cell; }
};

// What the last remapping of the front surface saw, so that the next one looks only at what
// the stroke changed since (seed 004 §2.6's three triggers, remap_surface.hpp).
struct FrontMappingCache {
  std::vector<std::size_t> plane_counts;  // per vertex: its constraint planes when last mapped
  std::vector<std::uint8_t> wrong_side;   // per vertex: its point across a cut face when last tested
  int mapped_base = 0;                    // the surface's base vertex count at the last mapping
  FrontVertexIdentity identity;           // the stroke's vertices at the last mapping
  std::vector<Vec3> stroke_rest;          // their rest positions (from identity.first on)
  // What the stroke had changed at the last mapping: the replaced slots and those after the
  // base's, and the base vertices given planes.
  std::vector<int> changed_slots, planed;
  // The largest distance (per axis) from a vertex below reach_upto to its integration point,
  // over its rows since they were counted (a bound: for finding the segments near a box).
  double reach = 0;
  int reach_upto = 0;
  ElementCubes cubes;  // the mapping's candidates, kept between cut events
  // The vertices below wrong_upto whose point is across a cut face, off the crack front.
  long wrong_base = 0;
  int wrong_upto = 0;
  int unseen_at_build = 0;  // first mapping: vertices on a point they do not see through the body
};

// The linked-across check's caches (linked_across.hpp), kept between cut events.
struct LinkedAcrossCache {
  std::vector<std::uint8_t> linked;             // per element
  std::vector<std::array<Vec3, 2>> link_boxes;  // per element, its links' box at rest
  std::vector<int> seen;                        // per element, the rest cut's size at its flag
  LinkedAcrossIndex index;
};

// Copied with the body it cuts: CutData(other, model) is a deep copy of `other` for a copy of
// its body (BodyData's copy), whose EFG model `model` its cutter edits and its caches refer
// to, so that the two bodies cut on alike, bit for bit, and share nothing.
struct CutData {
  CutData() = default;
  CutData(const CutData& other, CorotationalEfg& model);
  CutData(CutData&&) = default;
  CutData& operator=(CutData&&) = default;
  ~CutData() = default;

  std::unique_ptr<VolumeCutter> cutter;  // the topology graph; edits the body's EFG rows
  std::unique_ptr<FrontSurface> surface;
  std::unique_ptr<RestCut> rest_cut;     // every sweep so far, at rest
  FrontMappingCache mapping;
  SurfaceTopology topology;  // the surface's boundary and non-manifold edges, kept up to date
  LinkedAcrossCache linked;
  std::vector<int> blade_pieces;  // the blade's resampling, per segment, fixed for the strokes
  int stroke_folds = 0;           // folded_edges of the stroke's last report
  bool engaged = false;           // the blade was engaged at the end of the last step tested
  // The sweep's last line at rest as the last step tested mapped it, with each point's
  // distance from the integration points (empty when that step's sweep did not end engaged):
  // the next step's sheet starts from it (detect_cuts), so that the rest cut has no seam
  // where the topology change between the steps moved the mapping.
  std::vector<Vec3> rest_edge;
  std::vector<double> rest_edge_far;
  // The particles before the last solve: the links move from there to the state's positions
  // over the step the blade is tested against (user input happens during the last motion,
  // seed 004 §2.7).
  Vector previous_positions;
  std::size_t orphans_pinned = 0;  // of the model's orphaned particles
};

// What the cutting steps have done so far (metrics.json `cut`, `surface`, `mapping`).
struct CutTotals {
  long events = 0;
  long links_severed = 0;          // by the CCD
  long links_severed_at_rest = 0;  // by the agreement with the rest cut
  long elements_reselected = 0;
  long isolated_elements = 0;       // thesis failure: several cuts in one element
  long nonlocal_reselections = 0;   // re-selected past two particle spacings (thin slices, rims)
  long reselection_failures = 0;
  long orphaned_particles = 0;      // left by every element, pinned
  long positive_mass_elements = 0;  // share their mass by the positive part of phi
  long deactivated_elements = 0;    // no valid neighbourhood left after a cut
  long masses_floored = 0;          // particles kept at a floor mass
  long vertices_remapped = 0;
  long relaxed_fallbacks = 0;
  long wrong_side = 0;              // the worst over every remapping
  long elements_linked_across = 0;  // after the last event: volume and surface cuts disagree
  int worst_boundary_edges = 0;     // over every cut event
  int worst_nonmanifold_edges = 0;
  // The stroke samples the surface could not cut (left out: the surface stays as the stroke's
  // last good sample left it, closed), and the first such problem in words.
  long front_problems = 0;
  std::string first_front_problem;
  long front_folded_edges = 0;  // edges a stroke's sheet crossed twice, left uncut (front_surface.hpp)
  long front_strokes_carried_through = 0;  // strokes whose front was carried out of the body at their end
};

// One step's cut, for the step's statistics: whether it ran and changed anything, and where
// its time went (wall clock, ms).
struct CutStepReport {
  bool tested = false;  // the blade was engaged near the body: CCD ran
  bool event = false;   // the topology changed
  // A stroke's front left the body over the step (the edge cut its way out): its stroke ended
  // there (apply_topology.cpp, cut_front), and a later sample starts another.
  bool cut_through = false;
  double ms_ccd = 0;    // broad phase, continuous collision
  double ms_topology = 0;  // all of the topology's time on the step's critical path; its parts:
  // the sweep mapped to rest and the surface's cut, the volume's re-selection (MLS, masses),
  // the surface rebuild, the vertex mapping, and the checks that feed the metrics.
  double ms_rest_cut = 0, ms_reselect = 0, ms_surface_rebuild = 0, ms_mapping = 0, ms_checks = 0;
  // The surface's cut (FrontSurface::advance) runs beside the volume's CCD and re-selection:
  // ms_rest_cut and ms_topology count only what the step waited for it beyond those
  // (ms_front_wait), this its whole time.
  double ms_front_cut = 0, ms_front_wait = 0;
  int links_severed = 0;
};

// The blade over one step: its edge in the world at every sample of the step's sweep, their
// fractions of the step, and whether it was engaged over each interval between them.
struct BladeSweep {
  const std::vector<std::vector<Vec3>>& poses;
  const std::vector<double>& fractions;
  const std::vector<std::uint8_t>& active;
  // Set in the step a crack's onset starts the cut (tool.onset): the edge where it met the
  // tissue before pressing it in (CuttingState::entry). The stroke's first sample is then
  // taken there rather than at the dimple's bottom, which the pressing carried inside the body
  // at rest: the crack opens from the surface the edge went through.
  const std::vector<Vec3>* entry = nullptr;
};

// Everything a cut stage reads and writes besides the cut itself.
struct CutContext {
  const BodyModel& model;
  BodyData& body;
  const CutModel& cut_model;
  CutData& cut;
  CutTotals& totals;
  CutStepReport& report;
  bool on_gpu = false;    // the body's positions come from the GPU: every surface row is formed again
  long step = 0;          // the step being taken (1-based), for the problems' messages
};

// The cut state of a cuttable body whose data holds its EFG model and its first surface
// (voxel_boundary, put onto the shape): the topology graph, the front surface and its mapping
// (set in body.embedding), the rest box of the linked-across check; the body's surface and
// render triangles become the front's.
// With `inside` (the body's rest shape), each vertex is first mapped to an integration point it
// sees through the body (FrontVisibility::inside; the count of those that see none is kept in
// mapping.unseen_at_build).
CutData make_cut_data(const BodyModel& model, BodyData& body, const CutModel& cut_model, std::vector<Vec3> vertices,
                      std::vector<std::array<int, 3>> triangles,
                      const std::function<bool(const Vec3&)>* inside = nullptr);

}  // namespace incise::physics
