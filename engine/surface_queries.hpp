// Inside and nearest-point queries on an imported closed surface in about log(n) per query:
// a bounding volume hierarchy over its triangles with, per cluster, the first two terms of
// the Taylor expansion of the winding number's kernel about the cluster's centre (the fast
// winding numbers of Barill, Dickson, Schmidt, Levin and Jacobson, "Fast Winding Numbers for
// Soups and Clouds", SIGGRAPH 2018). A cluster seen from farther than `accuracy` times its
// radius contributes its expansion; nearer ones are opened down to their triangles, whose
// solid angles are exact. The winding number of a closed surface is 0 or 1 away from it and
// the expansion's error is a smooth part of a few hundredths, so the classification
// (winding number > 0.5) is that of the exact sum, engine::winding_number, everywhere but
// within rounding of the surface.
#pragma once

#include "engine/mesh_import.hpp"

#include <Eigen/Core>

#include <vector>

namespace incise::engine {

class SurfaceQueries {
 public:
  // Builds the hierarchy (leaves of a few triangles, split at the median along the longest
  // axis) and each cluster's expansion. `accuracy` is Barill's beta (2 in the paper).
  explicit SurfaceQueries(const TriangleSoup& mesh, double accuracy = 2.0);

  // Generalised winding number at p: 1 inside, 0 outside a closed surface.
  double winding_number(const Eigen::Vector3d& p) const;
  bool inside(const Eigen::Vector3d& p) const { return winding_number(p) > 0.5; }

  struct Nearest {
    Eigen::Vector3d point;  // on the surface
    double distance = 0;
    int triangle = -1;  // index into the mesh's triangles
  };
  // The point of the surface nearest to p (ties: the first triangle in hierarchy order).
  Nearest nearest(const Eigen::Vector3d& p) const;

  // Where the segment p + t d, t in [t_lo, t_hi], crosses the surface: t and the change of
  // the winding number across it going towards +t (+1 entering through a face's back, -1
  // leaving), sorted by t, ties by triangle. False, with `out` unspecified, where the segment
  // grazes an edge or a vertex or runs in a triangle's plane: there a crossing could be
  // counted twice or not at all, and the caller asks point by point.
  struct Crossing {
    double t;
    int change;
    int triangle;
  };
  bool crossings(const Eigen::Vector3d& p, const Eigen::Vector3d& d, double t_lo, double t_hi,
                 std::vector<Crossing>& out) const;

  std::size_t triangle_count() const { return triangles_.size(); }

 private:
  struct Node {
    Eigen::Vector3d lo, hi;      // bounding box of the cluster's triangles
    Eigen::Vector3d centre;      // area-weighted centroid: the expansion's point
    double radius = 0;           // farthest vertex from the centre
    Eigen::Vector3d dipole;      // sum of area * unit normal (order 1)
    Eigen::Matrix3d moment;      // sum of area * (centroid - centre) normal^T (order 2)
    int first = 0, count = 0;    // triangles [first, first + count) in hierarchy order
    int left = -1, right = -1;   // children; -1 for a leaf
  };
  struct Triangle {
    Eigen::Vector3d a, b, c;
    int index = 0;  // in the mesh
  };
  int build(int first, int count);
  double far_field(const Node& node, const Eigen::Vector3d& p) const;

  std::vector<Triangle> triangles_;  // reordered so that each node's triangles are contiguous
  std::vector<Node> nodes_;          // nodes_[0] is the root
  double accuracy_;
};

}  // namespace incise::engine
