// CorotationalEfg's surface embedding (seed 004 §2.6): each render-surface vertex follows the
// MLS weights of one integration point's neighbourhood, evaluated at the vertex
// (corotational_efg.hpp, "Surface embedding").
#include "physics/efg/corotational_efg.hpp"

#include "physics/efg/efg_detail.hpp"
#include "physics/efg/mls.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace incise::physics {

namespace {
using Index = Eigen::Index;
using efg_detail::fail;
using efg_detail::format_point;
}  // namespace

bool CorotationalEfg::sees_through_body(const std::function<bool(const Vec3&)>& inside, const Vec3& vertex,
                                        const Vec3& point, double a) {
  const double length = (point - vertex).norm();
  const int steps = std::max(1, static_cast<int>(std::ceil(length / (a / 8))));
  for (int k = 1; k <= steps; ++k) {
    const double along = length * k / steps;
    if (along < a / 20) continue;
    if (!inside(vertex + (along / length) * (point - vertex))) return false;
  }
  return true;
}

SurfaceEmbedding CorotationalEfg::embed_surface(const Vector& rest_vertices, const std::function<bool(const Vec3&)>* inside,
                                                int* unseen) const {
  if (unseen != nullptr) *unseen = 0;
  if (rest_vertices.size() % 3 != 0) {
    fail("embed_surface: " + std::to_string(rest_vertices.size()) +
         " coordinates, not a multiple of 3");
  }
  const Index vertices = rest_vertices.size() / 3;
  const double a = shape_->settings.spacing;
  SurfaceEmbedding embedding;
  embedding.stride = stride_;
  embedding.elements.resize(vertices);
  embedding.row_lengths.resize(vertices);
  embedding.particles.assign(static_cast<size_t>(vertices) * stride_, 0);
  embedding.weights.assign(static_cast<size_t>(vertices) * stride_, 0.0);
  std::vector<Vec3> positions;
  for (Index v = 0; v < vertices; ++v) {
    const Vec3 vertex = rest_vertices.segment<3>(3 * v);
    if (!vertex.allFinite()) fail("embed_surface: vertex " + std::to_string(v) + " is not finite");
    // The nearest integration point, searched in shells of cubes around the vertex's cube:
    // every point lies in its cube, so one in shell r lies at least (r - 1) a away and the
    // search stops once the best found is nearer than the next shell can be.
    std::array<long long, 3> cube;
    long long nearest_shell = 0, farthest_shell = 0;  // Chebyshev distances to the grid's cubes
    for (int axis = 0; axis < 3; ++axis) {
      const double coordinate = std::clamp((vertex[axis] - shape_->origin[axis]) / a, -1e9, 1e9);
      cube[axis] = static_cast<long long>(std::floor(coordinate));
      const long long last_cube = shape_->cube_counts[axis] - 1;
      nearest_shell = std::max({nearest_shell, -cube[axis], cube[axis] - last_cube});
      farthest_shell = std::max({farthest_shell, std::abs(cube[axis]), std::abs(cube[axis] - last_cube)});
    }
    double best_distance = std::numeric_limits<double>::infinity();
    int best = -1;
    // With `inside`: the nearest seen point (`seen`), searched up to embed_visible_reach_rings
    // shells beyond the one where the first point was found.
    double seen_distance = std::numeric_limits<double>::infinity();
    int seen = -1;
    long long first_shell = -1;
    for (long long r = nearest_shell; r <= farthest_shell; ++r) {
      const auto low = [&](int axis) { return std::max(-r, -cube[axis]); };
      const auto high = [&](int axis) { return std::min(r, shape_->cube_counts[axis] - 1 - cube[axis]); };
      for (long long dz = low(2); dz <= high(2); ++dz) {
        for (long long dy = low(1); dy <= high(1); ++dy) {
          for (long long dx = low(0); dx <= high(0); ++dx) {
            if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != r) continue;
            const long long i = cube[0] + dx, j = cube[1] + dy, k = cube[2] + dz;
            const int e = shape_->element_of_cube[i + shape_->cube_counts[0] * (j + shape_->cube_counts[1] * k)];
            if (e < 0) continue;
            const double distance = (shape_->centres[e] - vertex).squaredNorm();
            if (distance < best_distance || (distance == best_distance && e < best)) {
              best_distance = distance;
              best = e;
            }
            if (inside != nullptr && (distance < seen_distance || (distance == seen_distance && e < seen)) &&
                sees_through_body(*inside, vertex, shape_->centres[e], a)) {
              seen_distance = distance;
              seen = e;
            }
          }
        }
      }
      if (best >= 0 && first_shell < 0) first_shell = r;
      const double next_shell = static_cast<double>(r) * a;
      if (inside == nullptr) {
        if (best >= 0 && std::sqrt(best_distance) < next_shell) break;
      } else if ((seen >= 0 && std::sqrt(seen_distance) < next_shell) ||
                 (first_shell >= 0 && r >= first_shell + embed_visible_reach_rings)) {
        break;
      }
    }
    if (best < 0) fail("embed_surface: no integration point found for vertex " + std::to_string(v));
    if (inside != nullptr) {
      if (seen >= 0) {
        best = seen;
      } else if (unseen != nullptr) {
        ++*unseen;
      }
    }

    const size_t base = static_cast<size_t>(best) * stride_;
    const int length = row_lengths_[best];
    positions.clear();
    double farthest = 0;
    for (int k = 0; k < length; ++k) {
      positions.push_back(shape_->positions.segment<3>(3 * static_cast<Index>(neighbours_[base + k])));
      farthest = std::max(farthest, (positions.back() - vertex).norm());
    }
    // The element's support, widened if the vertex sits off-centre so that every neighbour
    // keeps a positive weight (the same rule as for the integration point).
    const double support = std::max(supports_[best], shape_->settings.support_factor * farthest);
    const size_t row = static_cast<size_t>(v) * stride_;
    if (!mls_shape_functions(vertex, positions, support, a,
                             std::span<double>(&embedding.weights[row], length), {})) {
      fail("embed_surface: vertex " + std::to_string(v) + " at " + format_point(vertex) +
           " is too far from its integration point " + std::to_string(best) +
           " for the MLS weights");
    }
    embedding.elements[v] = best;
    embedding.row_lengths[v] = length;
    std::copy(neighbours_.begin() + base, neighbours_.begin() + base + length,
              embedding.particles.begin() + row);
  }
  return embedding;
}

void CorotationalEfg::surface_positions(const SurfaceEmbedding& embedding, const Vector& particle_positions, Vector& out,
                                        Executor& executor) {
  const int vertices = embedding.vertex_count();
  out.resize(3 * static_cast<Index>(vertices));
  // A vertex is a few multiply-adds: ranges of a few thousand pay for the hand-off.
  constexpr int vertices_per_thread = 4096;
  executor.parallel_for(vertices, [&](int begin, int end) {
    for (int v = begin; v < end; ++v) {
      const size_t row = static_cast<size_t>(v) * embedding.stride;
      Vec3 position = Vec3::Zero();
      for (int k = 0; k < embedding.row_lengths[v]; ++k) {
        position += embedding.weights[row + k] *
                    particle_positions.segment<3>(3 * static_cast<Index>(embedding.particles[row + k]));
      }
      out.segment<3>(3 * static_cast<Index>(v)) = position;
    }
  }, vertices_per_thread);
}

}  // namespace incise::physics
