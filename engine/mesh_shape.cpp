#include "engine/mesh_shape.hpp"

#include <algorithm>
#include <cmath>

namespace incise::engine {

namespace {

// Cells of half a mean edge length keep the band of cells the surface touches a few cells
// thick; the cap keeps the grid's memory bounded for very fine meshes.
constexpr double kEdgesPerCell = 0.5;
constexpr int kMaxCellsPerAxis = 256;

double mean_edge(const TriangleSoup& mesh) {
  double sum = 0;
  for (const auto& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) {
      const auto& a = mesh.vertices[static_cast<std::size_t>(t[static_cast<std::size_t>(k)])];
      const auto& b = mesh.vertices[static_cast<std::size_t>(t[static_cast<std::size_t>((k + 1) % 3)])];
      sum += std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
    }
  return mesh.triangles.empty() ? 0 : sum / (3.0 * static_cast<double>(mesh.triangles.size()));
}

}  // namespace

MeshShape::MeshShape(const TriangleSoup& mesh) : queries_(mesh) {
  const Eigen::Vector3d lo(mesh.min[0], mesh.min[1], mesh.min[2]), hi(mesh.max[0], mesh.max[1], mesh.max[2]);
  const double extent = (hi - lo).maxCoeff();
  cell_ = std::max(kEdgesPerCell * mean_edge(mesh), extent / kMaxCellsPerAxis);
  if (!(cell_ > 0)) cell_ = 1;
  // One cell of margin all round: the outermost cells are outside and connect the outside.
  origin_ = lo - Eigen::Vector3d::Constant(cell_);
  for (int i = 0; i < 3; ++i) counts_[i] = static_cast<int>(std::ceil((hi[i] - lo[i]) / cell_)) + 3;
  state_.assign(static_cast<std::size_t>(counts_[0]) * counts_[1] * counts_[2], outside);
  // Every cell a triangle's box touches (closed, slightly enlarged: a triangle on a cell's
  // face belongs to both) is a surface cell.
  const double margin = 1e-9 * cell_;
  for (const auto& t : mesh.triangles) {
    Eigen::Vector3i first, last;
    for (int i = 0; i < 3; ++i) {
      double a = mesh.vertices[static_cast<std::size_t>(t[0])][static_cast<std::size_t>(i)], b = a;
      for (int k = 1; k < 3; ++k) {
        const double x = mesh.vertices[static_cast<std::size_t>(t[static_cast<std::size_t>(k)])][static_cast<std::size_t>(i)];
        a = std::min(a, x);
        b = std::max(b, x);
      }
      first[i] = std::clamp(static_cast<int>(std::floor((a - margin - origin_[i]) / cell_)), 0, counts_[i] - 1);
      last[i] = std::clamp(static_cast<int>(std::floor((b + margin - origin_[i]) / cell_)), 0, counts_[i] - 1);
    }
    for (int k = first[2]; k <= last[2]; ++k)
      for (int j = first[1]; j <= last[1]; ++j)
        for (int i = first[0]; i <= last[0]; ++i)
          state_[static_cast<std::size_t>(i) + static_cast<std::size_t>(counts_[0]) * (j + static_cast<std::size_t>(counts_[1]) * k)] = surface;
  }
  classify_cells();
}

// Groups the cells no triangle touches through shared faces (no surface lies between two such
// cells, so a group is all inside or all outside) and classifies each group by the winding
// number at the centre of its first cell, at least half a cell from the surface.
void MeshShape::classify_cells() {
  const std::size_t n = state_.size();
  std::vector<std::uint8_t> seen(n, 0);
  std::vector<std::size_t> group, queue;
  const std::size_t nx = static_cast<std::size_t>(counts_[0]), nxy = nx * static_cast<std::size_t>(counts_[1]);
  for (std::size_t start = 0; start < n; ++start) {
    if (state_[start] == surface || seen[start]) continue;
    group.clear();
    queue.assign(1, start);
    seen[start] = 1;
    while (!queue.empty()) {
      const std::size_t c = queue.back();
      queue.pop_back();
      group.push_back(c);
      const std::size_t i = c % nx, j = (c / nx) % static_cast<std::size_t>(counts_[1]), k = c / nxy;
      const auto visit = [&](bool valid, std::size_t next) {
        if (valid && state_[next] != surface && !seen[next]) {
          seen[next] = 1;
          queue.push_back(next);
        }
      };
      visit(i > 0, c - 1);
      visit(i + 1 < nx, c + 1);
      visit(j > 0, c - nx);
      visit(j + 1 < static_cast<std::size_t>(counts_[1]), c + nx);
      visit(k > 0, c - nxy);
      visit(k + 1 < static_cast<std::size_t>(counts_[2]), c + nxy);
    }
    const Eigen::Vector3d centre =
        origin_ + cell_ * Eigen::Vector3d(static_cast<double>(start % nx) + 0.5,
                                          static_cast<double>((start / nx) % static_cast<std::size_t>(counts_[1])) + 0.5,
                                          static_cast<double>(start / nxy) + 0.5);
    const State state = queries_.inside(centre) ? in : outside;
    for (const std::size_t c : group) state_[c] = state;
  }
}

std::size_t MeshShape::cell_of(const Eigen::Vector3d& p) const {
  std::size_t index = 0, stride = 1;
  for (int i = 0; i < 3; ++i) {
    const double x = std::floor((p[i] - origin_[i]) / cell_);
    if (!(x >= 0 && x < counts_[i])) return state_.size();
    index += static_cast<std::size_t>(x) * stride;
    stride *= static_cast<std::size_t>(counts_[i]);
  }
  return index;
}

bool MeshShape::inside(const Eigen::Vector3d& p) const {
  const std::size_t c = cell_of(p);
  if (c == state_.size()) return false;  // beyond the margin round the mesh's box
  if (state_[c] != surface) return state_[c] == in;
  return queries_.inside(p);
}

std::optional<physics::LineSection> MeshShape::along(const Eigen::Vector3d& p, const Eigen::Vector3d& n,
                                                     double reach) const {
  const double w = queries_.winding_number(p);
  // On the surface (within the expansion's error of one half) the point test decides alone.
  if (std::abs(w - std::round(w)) > 0.25) return std::nullopt;
  std::vector<SurfaceQueries::Crossing> hits;
  if (!queries_.crossings(p, n, -reach, reach, hits)) return std::nullopt;
  physics::LineSection section;
  section.winding = static_cast<int>(std::lround(w));
  section.crossings.reserve(hits.size());
  for (const auto& hit : hits) section.crossings.emplace_back(hit.t, hit.change);
  return section;
}

std::size_t MeshShape::classified_cells() const {
  return static_cast<std::size_t>(std::count_if(state_.begin(), state_.end(), [](std::uint8_t s) { return s != surface; }));
}

}  // namespace incise::engine
