// Each query point's nearest triangle of a moving surface, for mark_engaged and held_contact:
// the scan of every triangle (in order, a triangle replacing the nearest so far when it is
// strictly nearer, skipped when its box is no nearer), run over a TriangleGrid's candidates
// (physics/core/triangle_grid.hpp), bit for bit the scan's result.
//
// The grid holds only the triangles that can matter. A hint, the triangles nearest to the
// points at the caller's previous call, bounds each point's nearest distance from above (the
// distance to any usable triangle does); a triangle whose box lies beyond every point's bound
// (widened by margins far above rounding) is farther than that point's nearest, so it is
// neither the nearest nor can it hide it, and stays out of the grid. On the default incision
// at 20k elements that is a small part of the 44k surface triangles, and the one pass over
// all of them is only their boxes. Without a hint (the first call, or one whose triangles
// are all gone or unusable) the grid holds every usable triangle. The hint only decides what
// the work is, never the result.
#pragma once

#include "physics/core/executor.hpp"
#include "physics/core/model.hpp"

#include <array>
#include <cstdint>
#include <limits>
#include <vector>

namespace incise::physics {

struct NearestTriangle {
  int triangle = -1;  // -1: none (no usable triangle, or a point that is not finite)
  double distance = std::numeric_limits<double>::infinity();
  Vec3 closest = Vec3::Zero();  // the triangle's point nearest to the query point
};

// The usable triangles: those `skip` does not mark (1: a cut face; skip may be shorter than
// the surface, or empty) with a nonzero face normal (b - a) x (c - a).
// hint (optional, in and out): any triangle indices (those out of range or unusable are
// ignored); on return, the points' nearest triangles, each once, for the next call. The pass
// over every triangle's box runs on `executor`'s threads, in fixed chunks joined in order: the
// same result on any executor.
std::vector<NearestTriangle> nearest_triangles(const Vector& x, const std::vector<std::array<int, 3>>& surface,
                                               const std::vector<std::uint8_t>& skip, const std::vector<Vec3>& points,
                                               std::vector<int>* hint = nullptr, Executor& executor = serial_executor());

// The face normal the scans use: (b - a) x (c - a), not normalised.
Vec3 face_normal(const Vector& x, const std::array<int, 3>& triangle);

}  // namespace incise::physics
