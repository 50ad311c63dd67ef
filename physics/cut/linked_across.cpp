#include "physics/cut/linked_across.hpp"

#include <algorithm>
#include <cmath>

namespace incise::physics {

namespace {

// Whether a link of element e crosses the cut (its triangles from index `from` on).
bool element_linked_across(const CorotationalEfg& model, const RestCut& cut, int e, int from = 0) {
  if (!model.element_active(e)) return false;
  const Vec3 centre = model.element_centres()[e];
  const size_t base = static_cast<size_t>(e) * model.row_stride();
  for (int k = 0; k < model.row_lengths()[e]; ++k) {
    const Vec3 particle = model.rest_positions().segment<3>(3 * static_cast<Eigen::Index>(model.neighbours()[base + k]));
    if (cut.crosses(centre, particle, from)) return true;
  }
  return false;
}

}  // namespace

int elements_linked_across(const CorotationalEfg& model, const RestCut& cut) {
  if (cut.size() == 0) return 0;
  int across = 0;
  for (int e = 0; e < model.element_count(); ++e) across += element_linked_across(model, cut, e) ? 1 : 0;
  return across;
}

int update_elements_linked_across(const CorotationalEfg& model, const RestCut& cut, std::vector<std::uint8_t>& linked,
                                  const Vec3& lo, const Vec3& hi, const std::vector<std::uint8_t>* changed,
                                  std::vector<std::array<Vec3, 2>>* boxes, std::vector<int>* seen, LinkedAcrossIndex* index) {
  const int elements = model.element_count();
  const bool all = static_cast<int>(linked.size()) != elements;
  if (all) linked.assign(static_cast<size_t>(elements), 0);
  if (seen && (all || static_cast<int>(seen->size()) != elements)) seen->assign(static_cast<size_t>(elements), -1);
  const int stride = model.row_stride();
  // The box of an element's links: its centre and its neighbours, at rest.
  const auto link_box = [&](int e) {
    Vec3 box_lo = model.element_centres()[e], box_hi = box_lo;
    const size_t base = static_cast<size_t>(e) * stride;
    for (int k = 0; k < model.row_lengths()[e]; ++k) {
      const Vec3 particle = model.rest_positions().segment<3>(3 * static_cast<Eigen::Index>(model.neighbours()[base + k]));
      box_lo = box_lo.cwiseMin(particle), box_hi = box_hi.cwiseMax(particle);
    }
    return std::array<Vec3, 2>{box_lo, box_hi};
  };
  // Cached boxes stand for the elements whose neighbourhood did not change.
  const bool cached = boxes && changed && static_cast<int>(boxes->size()) == elements;
  if (boxes && !cached) {
    boxes->resize(static_cast<size_t>(elements));
    for (int e = 0; e < elements; ++e) (*boxes)[e] = link_box(e);
  }
  // The index stands for the cached boxes: built again after they were all taken again.
  if (index && (!cached || cut.size() == 0)) index->centres.clear();
  if (cut.size() == 0) {  // nothing to be linked across (the boxes are kept up to date all the same)
    if (cached)
      for (int e = 0; e < elements; ++e)
        if ((*changed)[e]) (*boxes)[e] = link_box(e);
    if (seen) std::fill(seen->begin(), seen->end(), 0);
    return 0;
  }
  const auto in_box = [&](const std::array<Vec3, 2>& box) {
    return (box[0].array() <= hi.array()).all() && (box[1].array() >= lo.array()).all();
  };
  // The cut only grows and an unchanged element keeps its links: one linked across stays so,
  // and one that was not becomes so only through a triangle added since its flag was taken
  // (`seen`, per element): those unchanged elements are tested against the cut's triangles
  // from their `seen` on only (RestCut::crosses(p, q, from): the cut's own index, nothing
  // built per call), the same answer as the full cut's.
  // Elements are never re-activated (CorotationalEfg::deactivate_element is final).
  // One pass over the elements: those to test (changed, or whose links reach into the box).
  std::vector<int> to_test;
  // How far an element's cached link box reaches from its centre (per axis).
  const auto extent = [&](int e) {
    const Vec3 centre = model.element_centres()[e];
    const auto& box = (*boxes)[e];
    return std::max((centre - box[0]).maxCoeff(), (box[1] - centre).maxCoeff());
  };
  bool indexed = index && cached && !all;
  if (indexed && index->centres.empty()) {
    index->reach = 0;
    for (int e = 0; e < elements; ++e) index->reach = std::max(index->reach, extent(e));
    index->deactivated = -1;
    indexed = bin_points(index->centres, model.element_centres(), model.spacing());  // else the plain pass below
  }
  if (indexed) {
    // The same elements from the index: those changed (their boxes taken again, the reach
    // grown to hold them), and those whose centre lies within the reach of the box, tested.
    // Elements are never re-activated: their flags are cleared once, when the count moves.
    if (index->deactivated != model.deactivated_elements()) {
      for (int e = 0; e < elements; ++e)
        if (!model.element_active(e)) linked[e] = 0;
      index->deactivated = model.deactivated_elements();
    }
    for (int e = 0; e < elements; ++e)
      if ((*changed)[e] && model.element_active(e)) {
        (*boxes)[e] = link_box(e);
        index->reach = std::max(index->reach, extent(e));
        to_test.push_back(e);
      }
    const size_t changed_count = to_test.size();
    // The bins holding every centre within the reach of [lo, hi] (with room for rounding).
    const double margin = index->reach * (1 + 1e-9) + 1e-12 * index->centres.cells.cell;
    index->centres.visit_box(lo - Vec3::Constant(margin), hi + Vec3::Constant(margin), [&](int e) {
      if (!(*changed)[e] && model.element_active(e) && in_box((*boxes)[e])) to_test.push_back(e);
    });
    std::sort(to_test.begin() + static_cast<std::ptrdiff_t>(changed_count), to_test.end());
    std::inplace_merge(to_test.begin(), to_test.begin() + static_cast<std::ptrdiff_t>(changed_count), to_test.end());
  } else {
    if (index) index->centres.clear();  // the boxes may change without it
    for (int e = 0; e < elements; ++e) {
      if (!model.element_active(e)) {
        linked[e] = 0;
        continue;
      }
      const bool element_changed = changed && (*changed)[e];
      if (cached && element_changed) (*boxes)[e] = link_box(e);
      if (all || element_changed || in_box(boxes ? (*boxes)[e] : link_box(e))) to_test.push_back(e);
    }
  }
  const bool since_flag = seen && cached && !all;  // unchanged elements: the triangles since their flag
  // The box of the triangles any of them is tested against: one whose links' box misses it
  // is not linked across them.
  int added_from = cut.size();
  if (since_flag)
    for (const int e : to_test)
      if (!(*changed)[e] && !linked[e]) added_from = std::min(added_from, std::max(0, (*seen)[e]));
  Vec3 added_lo = Vec3::Constant(std::numeric_limits<double>::infinity()), added_hi = -added_lo;
  for (int t = added_from; t < cut.size(); ++t) {
    const RestTriangle& triangle = cut.triangles()[static_cast<size_t>(t)];
    for (const Vec3* p : {&triangle.a, &triangle.b, &triangle.c}) added_lo = added_lo.cwiseMin(*p), added_hi = added_hi.cwiseMax(*p);
  }
  const auto meets_added = [&](int e) {
    const auto& box = (*boxes)[e];
    return (box[0].array() <= added_hi.array()).all() && (box[1].array() >= added_lo.array()).all();
  };
  for (const int e : to_test) {
    if (since_flag && !(*changed)[e]) {
      // Linked before, linked still; else only the triangles since its flag can link it.
      if (!linked[e] && meets_added(e)) linked[e] = element_linked_across(model, cut, e, std::max(0, (*seen)[e])) ? 1 : 0;
    } else {
      linked[e] = element_linked_across(model, cut, e) ? 1 : 0;
    }
    if (seen) (*seen)[e] = cut.size();
  }
  int across = 0;
  for (const std::uint8_t flag : linked) across += flag;
  return across;
}

}  // namespace incise::physics
