// An imported closed surface as a body's shape: the questions the fill, the EFG cells'
// volumes and the fairing ask of it, answered as the exact generalised winding number
// (engine::winding_number) would answer them, fast.
// - inside(p): a grid of cells over the mesh's box; the cells no triangle touches are
//   classified once, one winding number per connected group of them (the surface does not
//   separate cells of a group), and a point in one of them is answered from its cell; a point
//   in a cell the surface passes through asks the hierarchy (surface_queries.hpp).
// - along(p, n, reach): the classification along a line as the winding number at p and the
//   signed crossings within reach, so that a march and bisection along the line (the fairing's)
//   asks the mesh once per line rather than once per point.
#pragma once

#include "engine/surface_queries.hpp"
#include "physics/fem/surface_snap.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <vector>

namespace incise::engine {

class MeshShape {
 public:
  explicit MeshShape(const TriangleSoup& mesh);

  bool inside(const Eigen::Vector3d& p) const;
  // nullopt where the line grazes an edge or p is on the surface (ask inside() point by point).
  std::optional<physics::LineSection> along(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double reach) const;

  const SurfaceQueries& queries() const { return queries_; }
  // Cells whose classification is stored (no triangle touches them), of all cells.
  std::size_t classified_cells() const;
  std::size_t cells() const { return state_.size(); }

 private:
  enum State : std::uint8_t { surface, outside, in };
  void classify_cells();
  std::size_t cell_of(const Eigen::Vector3d& p) const;  // cells() when outside the grid

  SurfaceQueries queries_;
  Eigen::Vector3d origin_;
  double cell_ = 0;
  Eigen::Vector3i counts_;
  std::vector<std::uint8_t> state_;
};

}  // namespace incise::engine
