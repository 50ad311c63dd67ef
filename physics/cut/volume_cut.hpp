// Volume cutting of the meshless model: the topology graph, its continuous collision with the
// blade, and the re-selection of the neighbourhoods it breaks (seed 004 §2.1, §2.3, §2.4).
//
// The graph has two kinds of links (§2.1): particle-particle links, 6-connectivity on the
// particle grid, and integration point-particle links, which are the elements'
// neighbourhoods (the model's rows). Over a step, the blade polyline moves linearly from its
// pose at t = 0 to its pose at t = 1, and so does every link endpoint, from the positions
// before the last solve to the positions after it (user input is taken to happen during the
// previous step's motion, §2.7). A link the blade touches during the step (Provot's test,
// continuous_collision.hpp; candidates from the btDbvt broad phase) is severed:
// - a particle-particle link no longer joins its particles in the graph distances below;
// - an integration point-particle link takes the particle out of the element's neighbourhood.
// Each element that lost a neighbour is re-selected in the rest configuration (§2.4): its
// still-linked neighbours are kept; each severed neighbour is replaced by its mirror through
// the kept neighbour nearest it (one step further from the cut on the element's side, when
// that particle is within the graph distance), and candidates are added in order of graph distance from
// them over the particle-particle links that remain, nearest (rest distance to the
// integration point) first within a distance, skipping any candidate whose link to the
// integration point the blade crosses this step, until the neighbourhood has its nominal size
// and spans three dimensions (more are added while it is coplanar, §2.4 "extra neighbours").
// CorotationalEfg::set_neighbourhood then recomputes its MLS values and gradients and moves
// its mass. Particles are never added or removed: the DOF count does not change.
//
// The thesis's failure cases are detected and counted, not hidden (§2.8): an element left
// with no linked neighbour (several cuts inside one element, or the blade through its
// integration point) keeps a neighbourhood found from its nearest particles on the side of
// its first surviving neighbour, or, failing that, its old one (counted as isolated); a
// re-selection that finds no neighbourhood spanning three dimensions on the element's side
// deactivates the element (CorotationalEfg::deactivate_element) and is counted as a failure.
#pragma once

#include "physics/cut/broad_phase.hpp"
#include "physics/efg/corotational_efg.hpp"

#include <array>
#include <optional>
#include <cstdint>
#include <functional>
#include <map>
#include <span>
#include <memory>
#include <vector>

namespace incise::physics {

struct VolumeCutReport {
  int candidates = 0;              // links the broad phase returned for the narrow test
  int particle_links_severed = 0;
  int element_links_severed = 0;   // integration point-particle links
  int links_severed_at_rest = 0;   // element links dropped by the rest cut (see cut())
  int elements_reselected = 0;
  int elements_isolated = 0;       // left with no linked neighbour (thesis §4.3.3 failure)
  int reselection_failures = 0;    // no valid neighbourhood: the element was deactivated
  // Re-selected past two particle spacings from the point along an axis: no neighbourhood
  // within them spanned three dimensions (a thin slice, the body's rim, a second cut).
  int elements_nonlocal = 0;
  std::vector<int> changed_elements;  // increasing: rows to re-upload, vertices to remap
  // Where the links were cut, in the rest configuration (the hit's fraction along the link,
  // applied to its rest endpoints, §2.3), in the order found.
  std::vector<Vec3> rest_hits;
  double ms_ccd = 0;       // broad phase and continuous collision (wall time)
  double ms_topology = 0;  // re-selection, MLS and masses
  bool any() const { return particle_links_severed + element_links_severed + links_severed_at_rest > 0; }
};

class VolumeCutter {
 public:
  // The graph of `model` as built (its current neighbourhoods). The model must outlive the
  // cutter; its neighbourhoods are edited only through cut(). `margin` grows the broad-phase
  // boxes (m; at least the CCD touching distance), `slack` keeps boxes fat between refits.
  VolumeCutter(CorotationalEfg& model, double margin, double slack);
  ~VolumeCutter();
  // The cutter of a copy of `other`'s model (a copy of the body it cuts; the same rows): the
  // same graph, severed links and searches, editing `model`, so that it cuts as `other` would.
  VolumeCutter(const VolumeCutter& other, CorotationalEfg& model);
  VolumeCutter(const VolumeCutter&) = delete;  // it would edit the other's model
  VolumeCutter& operator=(const VolumeCutter&) = delete;

  // One step: the blade polyline at t = 0 and t = 1 (same point count, >= 2) and the particle
  // positions at t = 0 and t = 1 (3n each). Severs what the blade touches and re-selects
  // the broken neighbourhoods. Throws std::invalid_argument on inconsistent sizes or
  // non-finite input (naming it), before anything changes.
  VolumeCutReport cut(std::span<const Vec3> blade_start, std::span<const Vec3> blade_end,
                      const Vector& particles_start, const Vector& particles_end);
  // The same over a sampled sweep: the blade at increasing fractions 0 <= s_0 < ... <= 1 of
  // the step (every tool sample since the last step, seed 004 §2.2), each sub-interval
  // [s_j, s_j+1] tested with the links' endpoints interpolated at its ends; `active[j]` says
  // whether the blade cuts during sub-interval j (engaged). One broad-phase refit per call.
  // `rest_cut`, when given, is the cut surface in the rest configuration (the caller's record
  // of every sweep so far, this one included): re-selection never takes a particle whose
  // link it blocks, and the elements with a link reaching into [lo, hi] (the region of
  // this step's sweep) drop the neighbours it blocks, so that the volume agrees with the
  // surface where the CCD's deformed-configuration test and the rest mapping differ by
  // rounding (counted in links_severed_at_rest).
  struct RestVisibility {
    std::function<bool(const Vec3& from, const Vec3& to)> blocked;
    Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
  };
  VolumeCutReport cut(std::span<const std::vector<Vec3>> blade_poses, std::span<const double> fractions,
                      std::span<const std::uint8_t> active, const Vector& particles_start,
                      const Vector& particles_end, const RestVisibility* rest_cut = nullptr);

  // Maps world points to the rest configuration through the local deformation of the body:
  // X = X_e + F_e^-1 (x - x_e), e the integration point nearest to x, F_e its shape-matching
  // fit (seed 004 §2.3: topology edits are done at rest). Points far outside extrapolate.
  // `distance`, if given, receives each point's distance to that integration point (far means
  // outside the body, where the extrapolation means little).
  // The nearest point is the one a scan of every element would pick (nearest up to a relative
  // 1e-9, lowest index among ties), found in bins of the integration points kept from an
  // earlier call: only the points near the query are formed. The bins stay valid while the
  // points cannot have moved more than a spacing since they were built (each point moves at
  // most sum_k |phi_k| times the farthest particle's motion); re-selected elements are tested
  // apart until the next rebuild. Not safe to call concurrently on one cutter.
  void to_rest(const Vector& particles, std::span<const Vec3> world, std::vector<Vec3>& rest,
               std::vector<double>* distance = nullptr) const;
  // How many times to_rest rebuilt its bins of integration points (over all calls).
  long rest_search_rebuilds() const;
  // cut() forms the integration points and box-tests the links of the elements near the
  // sweep only, found in bins of the links' boxes kept from an earlier call (a link moves at
  // most sum_k |phi_k| times the farthest particle's motion since); rebuilt when that bound
  // exceeds a spacing. How many times they were rebuilt (over all calls):
  long near_search_rebuilds() const;
  // For tests: with `on`, cut() looks at every element and link instead (the scan whose
  // outcome the search must reproduce exactly).
  void set_full_scan(bool on);

  // Particle-particle links (a < b) and which are severed.
  const std::vector<std::array<int, 2>>& particle_links() const { return particle_links_; }
  const std::vector<std::uint8_t>& particle_link_severed() const { return particle_link_severed_; }
  int severed_particle_links() const;
  long total_links_severed() const { return total_links_severed_; }

  // Connected pieces: elements are joined when they share a particle. piece[e] numbers the
  // pieces from 0 in order of their lowest element; returns the count.
  int pieces(std::vector<int>& piece) const;

  // Deformed integration-point positions (the MLS interpolation at each element's point).
  void integration_points(const Vector& particles, std::vector<Vec3>& out) const;

 private:
  struct Sweep;  // the sampled sweep of one call
  int element_link_id(int element, int slot) const;
  // The integration point of `element` (the MLS interpolation of `particles` at it); every
  // point this class forms is formed here, so that the same inputs give the same bits.
  Vec3 integration_point(int element, const Vector& particles) const;
  // The integration point of `element` at the start and at the end of the call in progress,
  // each formed once per call, when first asked for.
  const Vec3& point_at_start(int element);
  const Vec3& point_at_end(int element);
  void refit(const Vector& particles_start, const Vector& particles_end, const Vec3& near_lo, const Vec3& near_hi);
  // Whether the blade, over the active sub-intervals, touches the moving segment whose
  // endpoints go linearly from (a0, b0) at fraction 0 to (a1, b1) at fraction 1.
  std::optional<PolylineHit> sweep_hit(const Sweep& sweep, const Vec3& a0, const Vec3& b0,
                                       const Vec3& a1, const Vec3& b1) const;
  std::vector<int> reselect(int element, const std::vector<int>& kept, const std::vector<int>& severed,
                            const Sweep& sweep, bool& isolated, bool& nonlocal);
  // cut()'s stages, in order: sever the links the blade touches over the sweep, then those the
  // rest cut blocks near it, then re-select the neighbourhood of every element that lost a
  // neighbour. SeveredLinks: element -> the particles whose link to it was cut.
  using SeveredLinks = std::map<int, std::vector<int>>;
  void sever_swept_links(const Sweep& sweep, const Vector& particles_start, const Vector& particles_end,
                         SeveredLinks& cut_from, VolumeCutReport& report);
  void sever_at_rest(const RestVisibility& rest_cut, SeveredLinks& cut_from, VolumeCutReport& report);
  void reselect_severed(const Sweep& sweep, const SeveredLinks& cut_from, const RestVisibility* rest_cut,
                        const Vector& particles_start, const Vector& particles_end, VolumeCutReport& report);
  // to_rest()'s stages: the integration point of `element` (formed once per call), the bins
  // brought up to date (returns how far a point can have moved since they were built), and
  // the nearest point to `q` found from them (false: the bins could not settle it).
  const Vec3& rest_point(int element, const Vector& particles) const;
  double update_rest_bins(const Vector& particles, bool finite) const;
  bool nearest_in_bins(const Vector& particles, const Vec3& q, double drift, int hint, int& nearest,
                       double& best) const;

  CorotationalEfg& model_;
  EdgeBroadPhase broad_phase_;
  double margin_;
  std::vector<std::array<int, 2>> particle_links_;
  std::vector<std::uint8_t> particle_link_severed_;
  std::vector<std::vector<int>> links_of_particle_;  // link indices per particle
  // Element links in the broad phase: which (element, particle) each slot holds, to remove
  // exactly what is there when a neighbourhood changes.
  std::vector<std::vector<int>> element_link_particles_;
  std::vector<std::uint8_t> element_stale_;  // 1: the row changed since its links were boxed
  std::vector<int> stale_list_;               // the elements with element_stale_ set
  long total_links_severed_ = 0;
  std::vector<int> candidates_;  // reused
  // reselect's breadth-first search: per particle, the search that last reached it (stamp).
  std::vector<unsigned> reached_;
  unsigned search_ = 0;
  // The endpoints of the call in progress (valid only inside cut()).
  struct StepPoints;  // the integration points formed in the call in progress
  std::unique_ptr<StepPoints> step_points_;
  const Vector* particles_start_ = nullptr;
  const Vector* particles_end_ = nullptr;
  const RestVisibility* rest_cut_ = nullptr;
  // Per element, the box of its links at rest (the rest-cut agreement pass of cut()).
  std::vector<std::array<Vec3, 2>> rest_link_boxes_;
  void box_rest_links(int element);
  // Which elements and particle links can come near a sweep, kept between calls (refit), and
  // which elements' rest link boxes can meet a region (the agreement pass).
  struct NearSearch;
  std::unique_ptr<NearSearch> near_search_;
  struct RestLinkIndex;
  std::unique_ptr<RestLinkIndex> rest_link_index_;
  struct RestSearch;  // to_rest's bins, kept between calls
  std::unique_ptr<RestSearch> rest_search_;
};

}  // namespace incise::physics
