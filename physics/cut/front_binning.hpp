// FrontSurface's box queries (front_surface.hpp): its base's edges and triangles binned in a
// uniform grid (the base is indexed in front_binning.cpp, FrontSurface::index_base).
#pragma once

#include "physics/core/model.hpp"
#include "physics/cut/uniform_grid.hpp"

#include <array>
#include <vector>

namespace incise::physics::front {

// Items with boxes binned in a uniform grid, for box queries; each item is visited once per
// query, at the first of its cells the grid's order meets (the crossings are numbered in that
// order: the frame build() sets is part of the result).
class BoxBins {
 public:
  void build(const std::vector<std::array<Vec3, 2>>& boxes, double cell);
  // The diagonal of the box around every item.
  double extent() const { return (hi_ - lo_).norm(); }
  template <typename Visit>
  void near(const Vec3& lo, const Vec3& hi, const Visit& visit) const {
    if (boxes_.empty()) return;
    grid_.visit_box_once(lo, hi, [&](int b) {
      const auto& box = boxes_[static_cast<size_t>(b)];
      if ((lo.array() > box[1].array()).any() || (hi.array() < box[0].array()).any()) return;
      visit(b);
    });
  }

 private:
  std::vector<std::array<Vec3, 2>> boxes_;
  Vec3 lo_ = Vec3::Zero(), hi_ = Vec3::Zero();
  UniformGrid grid_;
};

}  // namespace incise::physics::front
