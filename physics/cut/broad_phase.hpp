// Broad phase of the cutting CCD: which object edges can the blade touch this step?
//
// Seed 004 §2.3 tests every blade segment against every object edge (brute force, ch. 4) and
// notes that full scenes need an acceleration structure (§7.1.3). This is that structure: a
// dynamic AABB tree (Bullet's btDbvt, STYLE.md) over the edges' swept boxes, the box of an
// edge's two endpoints at t = 0 and at t = 1. Each box contains the whole segment at every
// t in [0, 1], because a point moving linearly between two endpoints moving linearly stays
// in their convex hull; so does a blade segment's swept box for its skew quadrilateral
// (seed 004 §2.2). Two segments that touch at some t therefore have overlapping boxes, and
// the candidates are a superset of the edges first_edge_hit reports, provided `margin` is at
// least the touching distance of continuous_collision.hpp.
//
// Edges are named by a non-negative integer id of the caller's choosing (an index into its
// edge list; the ids index a table, so keep them dense).
// btDbvt stores single-precision boxes; conversion rounds outwards, so no box shrinks.
// Queries reuse a traversal stack and the caller's vector: no allocation once warm. A query
// is not safe to run concurrently with another query on the same object.
#pragma once

#include "physics/cut/continuous_collision.hpp"

#include <memory>
#include <optional>
#include <span>
#include <vector>

struct btDbvt;
struct btDbvtNode;

namespace incise::physics {

class EdgeBroadPhase {
 public:
  // margin: every edge box is grown by it on all sides (>= 0, finite). slack: extra growth
  // kept when an edge is (re)boxed, so that an edge moving less than `slack` in a later step
  // needs no tree update (a "fat" box; still a superset, only looser). Both in the
  // coordinates of the positions.
  explicit EdgeBroadPhase(double margin, double slack = 0);
  ~EdgeBroadPhase();
  EdgeBroadPhase(EdgeBroadPhase&&) noexcept;
  EdgeBroadPhase& operator=(EdgeBroadPhase&&) noexcept;
  // A copy holds the same edges in the same boxes, in a tree of its own built from them: its
  // shape may differ from this one's, but a query answers the ids whose stored box meets the
  // blade's, sorted, which the boxes alone decide; and set_edge compares with the stored box.
  // So the copy answers every later call as this one would.
  EdgeBroadPhase(const EdgeBroadPhase& other);
  EdgeBroadPhase& operator=(const EdgeBroadPhase& other);

  // Inserts the edge `id`, or, when it is already there, refits it to its swept box this
  // step. Returns whether the tree changed (false: the new box fits in the stored one).
  bool set_edge(int id, const MovingSegment& edge);
  // Removes the edge `id` (a cut edge, replaced by its two halves). Throws std::out_of_range
  // when there is no such edge.
  void remove_edge(int id);
  bool contains(int id) const;
  int edge_count() const;
  // Rebalances the tree by `passes` incremental passes (Bullet's optimizeIncremental); worth
  // calling once a step after many edges moved.
  void rebalance(int passes = 1);

  // Ids of the edges whose stored box overlaps the swept box of one blade segment, sorted
  // ascending. `candidates` is cleared first and its capacity reused.
  void query(const MovingSegment& blade_segment, std::vector<int>& candidates) const;
  // The same for a whole polyline blade (its points at t = 0 and at t = 1): the union over
  // its segments, sorted ascending, without repeats.
  void query(std::span<const Vec3> blade_at_start, std::span<const Vec3> blade_at_end,
             std::vector<int>& candidates) const;

 private:
  struct Traversal;
  void collect(const MovingSegment& blade_segment, std::optional<long> index, std::vector<int>& candidates) const;

  double margin_;
  double slack_;
  std::unique_ptr<btDbvt> tree_;
  std::unique_ptr<Traversal> traversal_;  // reused stack and collector of queries
  std::vector<btDbvtNode*> leaves_;  // by id (ids are dense indices); nullptr: absent
  int edge_count_ = 0;
};

}  // namespace incise::physics
