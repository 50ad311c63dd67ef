// The base's index: its edges and triangles binned for box queries, and its triangles around
// each vertex (FrontSurface::Base).
#include "physics/cut/front_binning.hpp"
#include "physics/cut/front_stroke.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace incise::physics::front {

void BoxBins::build(const std::vector<std::array<Vec3, 2>>& boxes, double cell) {
  boxes_ = boxes;
  lo_ = boxes.front()[0];
  hi_ = boxes.front()[1];
  for (const auto& box : boxes) lo_ = lo_.cwiseMin(box[0]), hi_ = hi_.cwiseMax(box[1]);
  // At most about 2^22 cells: the cell grows for large extents.
  GridCells frame;
  frame.origin = lo_;
  frame.cell = cell;
  for (;;) {
    for (int d = 0; d < 3; ++d) frame.count[static_cast<size_t>(d)] = std::max(1LL, static_cast<long long>(std::ceil((hi_[d] - lo_[d]) / frame.cell)) + 1);
    if (static_cast<double>(frame.total()) <= 4.2e6) break;
    frame.cell *= 1.5;
  }
  grid_.build_boxes(frame, boxes);
}

}  // namespace incise::physics::front

namespace incise::physics {

using namespace front;

void FrontSurface::index_base(std::unique_ptr<Base> with_edges) {
  if (with_edges) {
    base_ = std::move(with_edges);
  } else {
    base_ = std::make_unique<Base>();
    base_->edges = edge_table(base_triangles_);
  }
  double length = 0;
  std::vector<std::array<Vec3, 2>> boxes;
  boxes.reserve(base_->edges.ends.size());
  for (const auto& e : base_->edges.ends) {
    const Vec3& a = base_vertices_[static_cast<size_t>(e[0])];
    const Vec3& b = base_vertices_[static_cast<size_t>(e[1])];
    boxes.push_back({a.cwiseMin(b), a.cwiseMax(b)});
    length += (b - a).norm();
  }
  const double cell = 2 * length / static_cast<double>(std::max<size_t>(1, boxes.size()));
  base_->edge_bins.build(boxes, cell);
  boxes.clear();
  for (const auto& t : base_triangles_) {
    Vec3 lo = base_vertices_[static_cast<size_t>(t[0])], hi = lo;
    for (const int v : t) {
      lo = lo.cwiseMin(base_vertices_[static_cast<size_t>(v)]);
      hi = hi.cwiseMax(base_vertices_[static_cast<size_t>(v)]);
    }
    boxes.push_back({lo, hi});
  }
  base_->triangle_bins.build(boxes, cell);
  const size_t n = base_vertices_.size();
  base_->around_start.assign(n + 1, 0);
  for (const auto& tri : base_triangles_)
    for (const int v : tri) ++base_->around_start[static_cast<size_t>(v) + 1];
  for (size_t v = 0; v < n; ++v) base_->around_start[v + 1] += base_->around_start[v];
  base_->around.assign(static_cast<size_t>(base_->around_start[n]), 0);
  std::vector<int> fill(base_->around_start.begin(), base_->around_start.end() - 1);
  for (size_t s = 0; s < base_triangles_.size(); ++s)
    for (const int v : base_triangles_[s]) base_->around[static_cast<size_t>(fill[static_cast<size_t>(v)]++)] = static_cast<int>(s);
  base_->cut_face_slots.clear();
  for (size_t s = 0; s < base_cut_face_.size(); ++s)
    if (base_cut_face_[s]) base_->cut_face_slots.push_back(static_cast<int>(s));
}

std::span<const int> FrontSurface::base_triangles_around(int v) const {
  if (v < 0 || static_cast<size_t>(v) >= base_vertices_.size())
    throw std::invalid_argument("FrontSurface::base_triangles_around: vertex " + std::to_string(v) + " is not a base vertex");
  const auto first = static_cast<size_t>(base_->around_start[static_cast<size_t>(v)]);
  const auto last = static_cast<size_t>(base_->around_start[static_cast<size_t>(v) + 1]);
  return {base_->around.data() + first, last - first};
}

const std::vector<int>& FrontSurface::base_cut_face_slots() const { return base_->cut_face_slots; }

void FrontSurface::base_vertices_in(const Vec3& lo, const Vec3& hi, std::vector<int>& out) const {
  // Every vertex is a corner of a triangle whose box holds it.
  out.clear();
  base_->triangle_bins.near(lo, hi, [&](int t) {
    for (const int v : base_triangles_[static_cast<size_t>(t)]) {
      const Vec3& x = base_vertices_[static_cast<size_t>(v)];
      if ((x.array() >= lo.array()).all() && (x.array() <= hi.array()).all()) out.push_back(v);
    }
  });
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
}

}  // namespace incise::physics
