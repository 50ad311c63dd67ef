// A coarse space for a two-level preconditioner: the trilinear functions of a regular grid of
// spacing H laid over the body's rest shape (the embedded coarse grid of geometric multigrid
// on unstructured or meshless nodes; Dick, Georgii and Westermann 2011 coarsen the hexahedral
// grid the same way). P maps coarse values to the nodes: node i takes sum_c w_ic u_c, w the
// trilinear weights of its cell's corners.
//
// For the EFG particle grid (2a apart) with H = 4a every coarse vertex that holds a particle
// is that particle, and the rest lie halfway between: standard geometric coarsening. Coarse
// vertices outside the body that would carry only a sliver of a node's weight are dropped and
// the node's weights renormalised (translations stay exact); fixed nodes take no coarse value.
// Every kept vertex has a node of weight >= 1/2 on it alone, so P has full column rank and
// P^T A P is positive definite whenever A is.
//
// A cut body (given its stiffness as `coupling`): a vertex whose support the cut divides, its
// free nodes falling into pieces that no nonzero block of the stiffness joins inside the
// support, becomes one vertex per piece (Dick, Georgii and Westermann split their coarse cells
// by the fine cells' connected pieces likewise), each kept by the rule above. Otherwise the
// vertex's function ties the two lips of the cut together, and the coarse correction can
// neither open the cut nor let a separated piece move alone: CG's iterations over the shipped
// scenes' replays (multigrid_current), unsplit -> split: cut_torus 10.13 -> 7.98 mean,
// cut_rising_blade 3.84 -> 3.33, cut_twisting_blade 6.44 -> 6.21, default 4.64 -> 4.59, the
// uncut scenes as they were. A body whose supports are all connected (an uncut ball) keeps the
// plain space bit for bit; an uncut non-convex one, whose neighbourhoods see no node across a
// fold, splits there too (efg_organ, kidney_mesh, probe_organ: iterations within 0.2 %).
//
// The coupling alone leaves a vertex whole wherever the cut's front lies inside its support
// (2H wide, as wide as a default incision is deep): the two lips stay connected around the front
// and the function still ties them together. Given the cut itself (`separation`), the support's
// nodes that the vertex does not see (the segment from the vertex to the node crosses the cut,
// EFG's own visibility criterion; a node or vertex lying on the cut hides nothing) are never
// joined to those it sees, so they become a copy of their own, or lean on their other corners
// where none of them holds more than half a weight on it (a copy that only visibility made
// needs a pivot above one half: two such copies of one node midway between two vertices would
// be the same column, and P^T A P singular, as a soak's strokes drawn along a node layer found).
// CG's iterations on the cutting steps of the default incision: 3948 elements 4.67 -> 4.52
// (mean), 20248 6.42 -> 6.04, 75458 6.89 -> 6.46; cut_twisting_blade 6.62 -> 6.34, cut_organ
// 5.37 -> 5.27, the others within 1 % (docs/status.md).
#pragma once

#include "physics/solve/block_matrix.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <cstdint>
#include <functional>
#include <vector>

namespace incise::physics {

// One of node i's trilinear weights w_ic: coarse vertex c (a column of W).
struct CoarseWeight {
  int vertex;
  double weight;
};

struct CoarseSpace {
  Eigen::SparseMatrix<double> prolongation;  // 3n x 3m, 3x3 blocks w_ic I
  int coarse_nodes = 0;
  // The same P = W (x) I3 by node (the Galerkin product from blocks, galerkin.hpp): node i's
  // weights are weights[weight_start[i] .. weight_start[i + 1]), at most 8, their vertices
  // increasing; none for a fixed node or one no kept vertex reaches. weight_start: n + 1.
  std::vector<int> weight_start;
  std::vector<CoarseWeight> weights;
};

// The body's cut as the coarse space asks it (its rest cut, physics/cut/rest_cut.hpp): whether
// any of it lies in the box [lo, hi], and whether the rest segment [a, b] crosses it.
struct CutSeparation {
  std::function<bool(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi)> near;
  std::function<bool(const Eigen::Vector3d& a, const Eigen::Vector3d& b)> crosses;
  explicit operator bool() const { return near && crosses; }
};

// `rest`: 3n rest positions; `spacing`: H; `fixed`: per node, 1 = fixed (empty: none);
// `coupling`: the stiffness whose nonzero blocks connect the nodes (a cut body's K0; nullptr:
// no vertex is split); `separation` (with a coupling): the cut, whose far side a vertex does
// not see (nullptr: the coupling alone splits).
CoarseSpace make_coarse_space(const Eigen::VectorXd& rest, double spacing, const std::vector<std::uint8_t>& fixed,
                              const BlockMatrix* coupling = nullptr, const CutSeparation* separation = nullptr);

}  // namespace incise::physics
