#include "physics/cut/volume_cut.hpp"

#include "physics/core/stopwatch.hpp"
#include "physics/cut/continuous_collision.hpp"
#include "physics/cut/uniform_grid.hpp"
#include "physics/efg/mls.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <tuple>

namespace incise::physics {

namespace {

// Rows hold at most this many particles (CorotationalEfg's own limit).
constexpr int slots_per_element = 64;
// Candidates further than this many particle-particle links from a kept neighbour are not
// considered: the neighbourhood must stay local for the MLS fit to mean anything.
constexpr int graph_radius = 3;

[[noreturn]] void fail(const std::string& what) { throw std::invalid_argument("VolumeCutter: " + what); }

void check_finite(const Vector& v, const char* name) {
  if (!v.allFinite()) fail(std::string(name) + " holds a non-finite value");
}

// Whether the boxes [lo_a, hi_a] and [lo_b, hi_b] overlap (touching counts; a NaN bound
// meets nothing).
bool boxes_meet(const Vec3& lo_a, const Vec3& hi_a, const Vec3& lo_b, const Vec3& hi_b) {
  for (int axis = 0; axis < 3; ++axis)
    if (!(hi_a[axis] >= lo_b[axis] && lo_a[axis] <= hi_b[axis])) return false;
  return true;
}

// The box of a link's two endpoints at the start (a0, b0) and at the end (a1, b1) of a step.
std::array<Vec3, 2> swept_box(const Vec3& a0, const Vec3& b0, const Vec3& a1, const Vec3& b1) {
  std::array<Vec3, 2> box;
  for (int axis = 0; axis < 3; ++axis) {
    box[0][axis] = std::min({a0[axis], b0[axis], a1[axis], b1[axis]});
    box[1][axis] = std::max({a0[axis], b0[axis], a1[axis], b1[axis]});
  }
  return box;
}

// Boxes binned by their centres, with the largest half-extent of a box about its centre (the
// reach): a box that meets a region has its centre in the region grown by the reach, so the
// bins over that grown region hold every box that can meet it (and some that cannot).
struct BoxIndex {
  UniformGrid bins;
  double reach = 0;
  double slack = 0;  // room for the rounding of the centres and of the grown region

  bool build(const std::vector<std::array<Vec3, 2>>& boxes, double spacing) {
    std::vector<Vec3> centres(boxes.size());
    reach = 0;
    double scale = 0;
    for (size_t i = 0; i < boxes.size(); ++i) {
      const Vec3 centre = 0.5 * (boxes[i][0] + boxes[i][1]);
      centres[i] = centre;
      reach = std::max({reach, (boxes[i][1] - centre).maxCoeff(), (centre - boxes[i][0]).maxCoeff()});
      scale = std::max({scale, boxes[i][0].cwiseAbs().maxCoeff(), boxes[i][1].cwiseAbs().maxCoeff()});
    }
    slack = 1e-9 * (reach + spacing + scale);
    return std::isfinite(reach) && bin_points(bins, centres, spacing);
  }
  // Calls visit(i) once for every box i that can meet [lo - grow, hi + grow] (a superset;
  // every box when a bound is NaN).
  template <class Visit>
  void query(const Vec3& lo, const Vec3& hi, double grow, Visit&& visit) const {
    const double r = reach + grow + slack;
    bins.visit_box(lo - Vec3::Constant(r), hi + Vec3::Constant(r), visit);
  }
};

// Elements re-selected (or re-boxed) since a search's bins were built: tested apart.
struct LooseSet {
  std::vector<std::uint8_t> loose;
  std::vector<int> list;
  void reset(int elements) {
    loose.assign(static_cast<size_t>(elements), 0);
    list.clear();
  }
  void mark(int element) {
    if (element < 0 || element >= static_cast<int>(loose.size()) || loose[element]) return;
    loose[element] = 1;
    list.push_back(element);
  }
};

// Integration points formed at most once per call: point[e] is this call's when stamp[e] == call.
struct PointMemo {
  std::vector<Vec3> point;
  std::vector<unsigned> stamp;
  unsigned call = 0;

  void begin(int elements) {
    if (++call == 0) {  // the stamps wrapped: forget them all
      std::fill(stamp.begin(), stamp.end(), 0u);
      call = 1;
    }
    point.resize(static_cast<size_t>(elements));
    stamp.resize(static_cast<size_t>(elements), 0u);
  }
  template <class Form>
  const Vec3& get(int element, const Form& form) {
    if (stamp[element] != call) point[element] = form(element), stamp[element] = call;
    return point[element];
  }
};

}  // namespace

// refit's search (see near_search_rebuilds()): the swept box of a link over a step lies in
// its box at the reference positions grown by how far its endpoints can have moved since: a
// particle by at most `moved`, the farthest any particle moved (at the start or at the end of
// the step), an integration point by at most sum_k |phi_k| times that, while its row is the
// one it had at the reference (loose elements are tested apart).
struct VolumeCutter::NearSearch {
  bool valid = false;
  bool full_scan = false;
  Vector particles;  // the reference positions
  double scale = 0;  // their largest coordinate magnitude
  std::vector<std::array<Vec3, 2>> element_boxes;  // the box of each element's links, at the reference
  std::vector<std::array<Vec3, 2>> link_boxes;     // the box of each particle link, at the reference
  std::vector<double> shape_sums;                  // sum_k |phi_k| of each element
  double shape_sum = 0;                            // their maximum
  BoxIndex elements, links;
  LooseSet loose;
  long rebuilds = 0;
  std::vector<int> selected;  // reused
};

// The agreement pass's search: the elements' rest link boxes, binned; rebuilt when too many
// were re-boxed since (those are tested apart).
struct VolumeCutter::RestLinkIndex {
  bool valid = false;
  BoxIndex boxes;
  LooseSet loose;
  std::vector<int> selected;  // reused
};

struct VolumeCutter::StepPoints {
  const Vector* particles_start = nullptr;
  const Vector* particles_end = nullptr;
  PointMemo start, end;

  void begin(int elements, const Vector& at_start, const Vector& at_end) {
    particles_start = &at_start;
    particles_end = &at_end;
    start.begin(elements);
    end.begin(elements);
  }
};

struct VolumeCutter::RestSearch {
  bool valid = false;
  UniformGrid bins;             // of the integration points at the last rebuild
  std::vector<Vec3> binned;     // per element, its point at the last rebuild
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();  // their box
  Vector particles;             // the particle positions they were formed from
  double shape_sum = 0;         // max over elements of sum_k |phi_k|, at the last rebuild
  LooseSet loose;               // re-selected since the rebuild: tested apart
  long rebuilds = 0;
  PointMemo points;             // per call: the points formed so far
  std::vector<std::pair<int, double>> candidates;  // reused: element, squared distance
};

VolumeCutter::VolumeCutter(CorotationalEfg& model, double margin, double slack)
    : model_(model),
      broad_phase_(margin, slack),
      margin_(margin),
      step_points_(std::make_unique<StepPoints>()),
      near_search_(std::make_unique<NearSearch>()),
      rest_link_index_(std::make_unique<RestLinkIndex>()),
      rest_search_(std::make_unique<RestSearch>()) {
  // 6-connectivity on the particle grid: each particle to its next neighbour along +x, +y, +z
  // when that particle exists (particles outside the body's influence were dropped at build).
  const auto& cells = model_.particle_grid_coordinates();
  std::map<std::array<int, 3>, int> particle_at;
  for (int p = 0; p < static_cast<int>(cells.size()); ++p) particle_at[cells[p]] = p;
  links_of_particle_.assign(cells.size(), {});
  for (int p = 0; p < static_cast<int>(cells.size()); ++p) {
    for (int axis = 0; axis < 3; ++axis) {
      std::array<int, 3> next = cells[p];
      ++next[axis];
      const auto it = particle_at.find(next);
      if (it == particle_at.end()) continue;
      const int link = static_cast<int>(particle_links_.size());
      particle_links_.push_back({std::min(p, it->second), std::max(p, it->second)});
      links_of_particle_[p].push_back(link);
      links_of_particle_[it->second].push_back(link);
    }
  }
  particle_link_severed_.assign(particle_links_.size(), 0);
  element_link_particles_.resize(static_cast<size_t>(model_.element_count()));
  element_stale_.assign(static_cast<size_t>(model_.element_count()), 0);
}

int VolumeCutter::element_link_id(int element, int slot) const {
  return static_cast<int>(particle_links_.size()) + element * slots_per_element + slot;
}

int VolumeCutter::severed_particle_links() const {
  return static_cast<int>(std::count(particle_link_severed_.begin(), particle_link_severed_.end(), 1));
}

Vec3 VolumeCutter::integration_point(int element, const Vector& particles) const {
  Vec3 point = Vec3::Zero();
  const size_t base = static_cast<size_t>(element) * model_.row_stride();
  for (int k = 0; k < model_.row_lengths()[element]; ++k) {
    point += model_.shape_values()[base + k] * particles.segment<3>(3 * static_cast<Eigen::Index>(model_.neighbours()[base + k]));
  }
  return point;
}

void VolumeCutter::integration_points(const Vector& particles, std::vector<Vec3>& out) const {
  const int elements = model_.element_count();
  out.resize(static_cast<size_t>(elements));
  for (int e = 0; e < elements; ++e) out[e] = integration_point(e, particles);
}

const Vec3& VolumeCutter::point_at_start(int element) {
  StepPoints& points = *step_points_;
  return points.start.get(element, [&](int e) { return integration_point(e, *points.particles_start); });
}

const Vec3& VolumeCutter::point_at_end(int element) {
  StepPoints& points = *step_points_;
  return points.end.get(element, [&](int e) { return integration_point(e, *points.particles_end); });
}

long VolumeCutter::near_search_rebuilds() const { return near_search_->rebuilds; }

void VolumeCutter::set_full_scan(bool on) { near_search_->full_scan = on; }

void VolumeCutter::refit(const Vector& particles_start, const Vector& particles_end, const Vec3& near_lo,
                         const Vec3& near_hi) {
  const auto particle = [](const Vector& x, int p) { return Vec3(x.segment<3>(3 * static_cast<Eigen::Index>(p))); };
  // Only links whose own swept box (both endpoints at the start and at the end of the step)
  // meets the sweep's region are (re)boxed: any other link cannot touch the blade, and a
  // stale box elsewhere only adds candidates, which the narrow test, on this step's
  // endpoints, rejects. Links enter the tree the first time they come near a sweep, so the
  // first contact does not box the whole body.
  const auto near = [&](const Vec3& a0, const Vec3& b0, const Vec3& a1, const Vec3& b1) {
    const auto box = swept_box(a0, b0, a1, b1);
    return boxes_meet(box[0], box[1], near_lo, near_hi);
  };
  // Which links that test can pass is found in NearSearch's bins, so that only the
  // integration points of the elements near the sweep are formed: every link whose swept box
  // can meet the region is selected (a superset), then tested as above, in increasing order,
  // so that the tree sees exactly the updates a test of every link would make.
  NearSearch& search = *near_search_;
  const int elements = model_.element_count();
  const int link_count = static_cast<int>(particle_links_.size());
  const double spacing = model_.spacing();
  const double scale = std::max(particles_start.cwiseAbs().maxCoeff(), particles_end.cwiseAbs().maxCoeff());
  const auto farthest = [&](const Vector& from) {
    double moved = 0;
    for (Eigen::Index i = 0; i < particles_start.size(); i += 3) {
      moved = std::max({moved, (particles_start.segment<3>(i) - from.segment<3>(i)).squaredNorm(),
                        (particles_end.segment<3>(i) - from.segment<3>(i)).squaredNorm()});
    }
    return std::sqrt(moved);
  };
  double moved = std::numeric_limits<double>::infinity();
  if (search.valid && search.particles.size() == particles_start.size() &&
      search.loose.loose.size() == static_cast<size_t>(elements)) {
    moved = farthest(search.particles);
  }
  // How far a link's endpoints can be out of its reference box, with room for rounding (of
  // the points formed, at most ~64 ulps of the coordinates).
  const auto reach = [&](double shape_sum) {
    return std::max(1.0, shape_sum) * moved * (1 + 1e-6) + 1e-9 * (spacing + std::max(scale, search.scale));
  };
  if (!search.full_scan && (!(reach(search.shape_sum) <= spacing) ||
                            8 * search.loose.list.size() > static_cast<size_t>(elements))) {
    // Rebuilt at the end of this step (its points are this step's, and the next step starts
    // there: its drift is one step's motion).
    search.particles = particles_end;
    search.scale = particles_end.cwiseAbs().maxCoeff();
    search.element_boxes.resize(static_cast<size_t>(elements));
    search.shape_sums.resize(static_cast<size_t>(elements));
    search.shape_sum = 0;
    const int stride = model_.row_stride();
    for (int e = 0; e < elements; ++e) {
      const Vec3& point = point_at_end(e);
      Vec3 lo = point, hi = point;
      double sum = 0;
      const size_t base = static_cast<size_t>(e) * stride;
      for (int k = 0; k < model_.row_lengths()[e]; ++k) {
        const Vec3 to = particle(particles_end, model_.neighbours()[base + k]);
        lo = lo.cwiseMin(to), hi = hi.cwiseMax(to);
        sum += std::abs(model_.shape_values()[base + k]);
      }
      search.element_boxes[e] = {lo, hi};
      search.shape_sums[e] = sum;
      search.shape_sum = std::max(search.shape_sum, sum);
    }
    search.link_boxes.resize(particle_links_.size());
    for (int link = 0; link < link_count; ++link) {
      const auto [a, b] = particle_links_[link];
      const Vec3 pa = particle(particles_end, a), pb = particle(particles_end, b);
      search.link_boxes[link] = {pa.cwiseMin(pb), pa.cwiseMax(pb)};
    }
    search.valid = search.elements.build(search.element_boxes, spacing) && search.links.build(search.link_boxes, spacing);
    search.loose.reset(elements);
    ++search.rebuilds;
    moved = farthest(search.particles);
  }
  const bool searched = search.valid && !search.full_scan && std::isfinite(reach(search.shape_sum));
  std::vector<int>& selected = search.selected;
  selected.clear();
  if (searched) {
    const double grow = reach(1.0);
    search.links.query(near_lo, near_hi, grow, [&](int link) {
      const auto& box = search.link_boxes[link];
      if (boxes_meet(box[0] - Vec3::Constant(grow), box[1] + Vec3::Constant(grow), near_lo, near_hi)) selected.push_back(link);
    });
    std::sort(selected.begin(), selected.end());
  } else {
    for (int link = 0; link < link_count; ++link) selected.push_back(link);
  }
  for (const int link : selected) {
    if (particle_link_severed_[link]) continue;
    const auto [a, b] = particle_links_[link];
    const Vec3 a0 = particle(particles_start, a), b0 = particle(particles_start, b);
    const Vec3 a1 = particle(particles_end, a), b1 = particle(particles_end, b);
    if (!near(a0, b0, a1, b1)) continue;
    broad_phase_.set_edge(link, {{a0, b0}, {a1, b1}});
  }
  // The elements: those whose links can meet the region, those re-selected since the bins
  // were built (their boxes are not the rows'), and the stale ones (below).
  selected.clear();
  if (searched) {
    search.elements.query(near_lo, near_hi, reach(search.shape_sum), [&](int e) {
      if (search.loose.loose[e]) return;
      const auto& box = search.element_boxes[e];
      const Vec3 grow = Vec3::Constant(reach(search.shape_sums[e]));
      if (boxes_meet(box[0] - grow, box[1] + grow, near_lo, near_hi)) selected.push_back(e);
    });
    selected.insert(selected.end(), search.loose.list.begin(), search.loose.list.end());
    selected.insert(selected.end(), stale_list_.begin(), stale_list_.end());
    std::sort(selected.begin(), selected.end());
    selected.erase(std::unique(selected.begin(), selected.end()), selected.end());
  } else {
    for (int e = 0; e < elements; ++e) selected.push_back(e);
  }
  const int stride = model_.row_stride();
  for (const int e : selected) {
    const size_t base = static_cast<size_t>(e) * stride;
    auto& boxed = element_link_particles_[e];
    const int length = model_.row_lengths()[e];
    // An element whose row changed since it was boxed is refit wherever it is: its slots
    // name the particles a candidate is narrow-tested with, so none may be stale.
    bool touching = element_stale_[e] != 0;
    for (int k = 0; k < length && !touching; ++k) {
      const int p = model_.neighbours()[base + k];
      touching = near(point_at_start(e), particle(particles_start, p), point_at_end(e), particle(particles_end, p));
    }
    if (!touching) continue;
    element_stale_[e] = 0;
    // Slots that no longer hold a link (a shorter row after a re-selection) leave the tree.
    for (int k = length; k < static_cast<int>(boxed.size()); ++k) {
      if (boxed[k] >= 0) broad_phase_.remove_edge(element_link_id(e, k));
    }
    boxed.resize(static_cast<size_t>(length), -1);
    for (int k = 0; k < length; ++k) {
      const int p = model_.neighbours()[base + k];
      boxed[k] = p;
      broad_phase_.set_edge(element_link_id(e, k), {{point_at_start(e), particle(particles_start, p)},
                                                    {point_at_end(e), particle(particles_end, p)}});
    }
  }
  stale_list_.clear();  // every stale element was refit above
}

struct VolumeCutter::Sweep {
  std::span<const std::vector<Vec3>> poses;
  std::span<const double> fractions;
  std::span<const std::uint8_t> active;
};

std::optional<PolylineHit> VolumeCutter::sweep_hit(const Sweep& sweep, const Vec3& a0, const Vec3& b0,
                                                   const Vec3& a1, const Vec3& b1) const {
  for (size_t j = 0; j + 1 < sweep.poses.size(); ++j) {
    if (!sweep.active[j]) continue;
    const double s0 = sweep.fractions[j], s1 = sweep.fractions[j + 1];
    const MovingSegment edge{{a0 + s0 * (a1 - a0), b0 + s0 * (b1 - b0)},
                             {a0 + s1 * (a1 - a0), b0 + s1 * (b1 - b0)}};
    if (auto hit = first_polyline_hit(sweep.poses[j], sweep.poses[j + 1], edge)) return hit;
  }
  return std::nullopt;
}

VolumeCutReport VolumeCutter::cut(std::span<const Vec3> blade_start, std::span<const Vec3> blade_end,
                                  const Vector& particles_start, const Vector& particles_end) {
  const std::vector<std::vector<Vec3>> poses{std::vector<Vec3>(blade_start.begin(), blade_start.end()),
                                             std::vector<Vec3>(blade_end.begin(), blade_end.end())};
  const std::vector<double> fractions{0.0, 1.0};
  const std::vector<std::uint8_t> active{1};
  return cut(poses, fractions, active, particles_start, particles_end);
}

namespace {

// Throws std::invalid_argument, naming it, on a sweep or positions cut() cannot take (`size`:
// the model's 3n), before anything changes.
void check_sweep(std::span<const std::vector<Vec3>> blade_poses, std::span<const double> fractions,
                 std::span<const std::uint8_t> active, const Vector& particles_start, const Vector& particles_end,
                 Eigen::Index size) {
  if (blade_poses.size() < 2 || fractions.size() != blade_poses.size() || active.size() + 1 != blade_poses.size()) {
    fail("a sweep needs at least 2 blade poses, one fraction per pose and one active flag per interval, got " +
         std::to_string(blade_poses.size()) + ", " + std::to_string(fractions.size()) + " and " +
         std::to_string(active.size()));
  }
  for (size_t j = 0; j < blade_poses.size(); ++j) {
    if (blade_poses[j].size() < 2 || blade_poses[j].size() != blade_poses[0].size()) {
      fail("blade pose " + std::to_string(j) + " has " + std::to_string(blade_poses[j].size()) +
           " points; every pose needs the same number, at least 2");
    }
    for (size_t i = 0; i < blade_poses[j].size(); ++i) {
      if (!blade_poses[j][i].allFinite()) fail("blade point " + std::to_string(i) + " of pose " + std::to_string(j) + " is not finite");
    }
    if (!std::isfinite(fractions[j]) || fractions[j] < 0 || fractions[j] > 1 || (j > 0 && fractions[j] < fractions[j - 1])) {
      fail("blade pose fractions must increase within [0, 1]; pose " + std::to_string(j) + " has " + std::to_string(fractions[j]));
    }
  }
  if (particles_start.size() != size || particles_end.size() != size) {
    fail("particle positions have " + std::to_string(particles_start.size()) + " and " +
         std::to_string(particles_end.size()) + " entries, the model " + std::to_string(size));
  }
  check_finite(particles_start, "particles at the start of the step");
  check_finite(particles_end, "particles at the end of the step");
}

// The box of the blade's poses at the ends of the active sub-intervals (lo > hi when none is
// active).
std::array<Vec3, 2> swept_region(std::span<const std::vector<Vec3>> blade_poses, std::span<const std::uint8_t> active) {
  Vec3 near_lo = Vec3::Constant(std::numeric_limits<double>::infinity()), near_hi = -near_lo;
  for (size_t j = 0; j + 1 < blade_poses.size(); ++j) {
    if (!active[j]) continue;
    for (size_t end = j; end <= j + 1; ++end)
      for (const Vec3& point : blade_poses[end]) near_lo = near_lo.cwiseMin(point), near_hi = near_hi.cwiseMax(point);
  }
  return {near_lo, near_hi};
}

}  // namespace

VolumeCutReport VolumeCutter::cut(std::span<const std::vector<Vec3>> blade_poses, std::span<const double> fractions,
                                  std::span<const std::uint8_t> active, const Vector& particles_start,
                                  const Vector& particles_end, const RestVisibility* rest_cut) {
  check_sweep(blade_poses, fractions, active, particles_start, particles_end,
              3 * static_cast<Eigen::Index>(model_.node_count()));

  VolumeCutReport report;
  Stopwatch watch;
  const Sweep sweep{blade_poses, fractions, active};
  // The integration points are formed only where they are looked at (near the sweep, the
  // candidates, the re-selected elements).
  step_points_->begin(model_.element_count(), particles_start, particles_end);
  // The region the blade sweeps this step, grown by the broad phase's margin (what the narrow
  // test can touch beyond the blade): a link whose swept box misses it cannot reach the blade.
  const auto [near_lo, near_hi] = swept_region(blade_poses, active);
  const Vec3 grow = Vec3::Constant(2 * margin_ + 1e-9);
  refit(particles_start, particles_end, near_lo - grow, near_hi + grow);

  SeveredLinks cut_from;
  sever_swept_links(sweep, particles_start, particles_end, cut_from, report);
  if (rest_cut && rest_cut->blocked) sever_at_rest(*rest_cut, cut_from, report);
  total_links_severed_ += report.particle_links_severed + report.element_links_severed + report.links_severed_at_rest;
  report.ms_ccd = watch.ms();
  watch.restart();

  reselect_severed(sweep, cut_from, rest_cut, particles_start, particles_end, report);
  report.ms_topology = watch.ms();
  return report;
}

void VolumeCutter::sever_swept_links(const Sweep& everything, const Vector& particles_start,
                                     const Vector& particles_end, SeveredLinks& cut_from, VolumeCutReport& report) {
  const auto particle = [](const Vector& x, int p) { return Vec3(x.segment<3>(3 * static_cast<Eigen::Index>(p))); };
  const int link_count = static_cast<int>(particle_links_.size());
  const auto& blade_poses = everything.poses;
  // Candidates over every active sub-interval (the boxes cover the whole step).
  // (edge, sub-interval) pairs: an edge can only touch the blade in a sub-interval whose
  // blade box overlaps its (whole-step) box, so it is tested in those alone.
  std::vector<std::pair<int, int>> pairs;
  for (size_t j = 0; j + 1 < blade_poses.size(); ++j) {
    if (!everything.active[j]) continue;
    broad_phase_.query(blade_poses[j], blade_poses[j + 1], candidates_);
    for (int id : candidates_) pairs.emplace_back(id, static_cast<int>(j));
  }
  std::sort(pairs.begin(), pairs.end());
  std::vector<std::uint8_t> intervals(everything.active.size(), 0);

  for (size_t first = 0; first < pairs.size();) {
    const int id = pairs[first].first;
    std::fill(intervals.begin(), intervals.end(), 0);
    size_t last = first;
    for (; last < pairs.size() && pairs[last].first == id; ++last) intervals[pairs[last].second] = 1;
    first = last;
    ++report.candidates;
    const Sweep sweep{everything.poses, everything.fractions, intervals};
    Vec3 a0, b0, a1, b1, rest_first, rest_second;
    int element = -1, slot_particle = -1;
    if (id < link_count) {
      const auto [a, b] = particle_links_[id];
      a0 = particle(particles_start, a), b0 = particle(particles_start, b);
      a1 = particle(particles_end, a), b1 = particle(particles_end, b);
      rest_first = particle(model_.rest_positions(), a);
      rest_second = particle(model_.rest_positions(), b);
    } else {
      element = (id - link_count) / slots_per_element;
      if (!model_.element_active(element)) continue;  // out of the mechanics already
      const int slot = (id - link_count) % slots_per_element;
      slot_particle = element_link_particles_[element][slot];
      a0 = point_at_start(element), b0 = particle(particles_start, slot_particle);
      a1 = point_at_end(element), b1 = particle(particles_end, slot_particle);
      rest_first = model_.element_centres()[element];
      rest_second = particle(model_.rest_positions(), slot_particle);
    }
    const auto hit = sweep_hit(sweep, a0, b0, a1, b1);
    if (!hit) continue;
    report.rest_hits.push_back(rest_first + hit->hit.edge_parameter * (rest_second - rest_first));
    if (id < link_count) {
      particle_link_severed_[id] = 1;
      broad_phase_.remove_edge(id);
      ++report.particle_links_severed;
    } else {
      cut_from[element].push_back(slot_particle);
      ++report.element_links_severed;
    }
  }
}

void VolumeCutter::sever_at_rest(const RestVisibility& rest_cut, SeveredLinks& cut_from, VolumeCutReport& report) {
  const auto particle = [](const Vector& x, int p) { return Vec3(x.segment<3>(3 * static_cast<Eigen::Index>(p))); };
  const int stride = model_.row_stride();
  // Each element's links at rest, boxed (rest positions do not move; a row changes only
  // in re-selection, and its box is taken again there): most elements are far from the region.
  const int elements = model_.element_count();
  RestLinkIndex& index = *rest_link_index_;
  if (rest_link_boxes_.size() != static_cast<size_t>(elements)) {
    rest_link_boxes_.resize(static_cast<size_t>(elements));
    index.valid = false;
    for (int e = 0; e < elements; ++e) box_rest_links(e);
  }
  // The elements whose box can meet the region, from bins of the boxes (those re-boxed
  // since the bins were built are tested apart), in increasing order.
  if (!near_search_->full_scan && (!index.valid || 8 * index.loose.list.size() > static_cast<size_t>(elements))) {
    index.valid = index.boxes.build(rest_link_boxes_, model_.spacing());
    index.loose.reset(elements);
  }
  std::vector<int>& selected = index.selected;
  selected.clear();
  if (index.valid && !near_search_->full_scan) {
    index.boxes.query(rest_cut.lo, rest_cut.hi, 0.0, [&](int e) {
      if (!index.loose.loose[e]) selected.push_back(e);
    });
    selected.insert(selected.end(), index.loose.list.begin(), index.loose.list.end());
    std::sort(selected.begin(), selected.end());
  } else {
    for (int e = 0; e < elements; ++e) selected.push_back(e);
  }
  for (const int e : selected) {
    if (!model_.element_active(e)) continue;
    const auto& box = rest_link_boxes_[e];
    if (!boxes_meet(box[0], box[1], rest_cut.lo, rest_cut.hi)) continue;
    const Vec3& centre = model_.element_centres()[e];
    // Each link whose box meets the region (not only the links of the integration points
    // inside it: a link to a particle a few spacings away, as re-selection makes, can
    // cross this sweep's cut from an integration point outside it). The box test first:
    // the exact test (RestCut::crosses) is the costly part.
    const size_t base = static_cast<size_t>(e) * stride;
    std::vector<int>* severed = nullptr;
    bool looked_up = false;
    for (int k = 0; k < model_.row_lengths()[e]; ++k) {
      const int p = model_.neighbours()[base + k];
      const Vec3 to = particle(model_.rest_positions(), p);
      if (!boxes_meet(centre.cwiseMin(to), centre.cwiseMax(to), rest_cut.lo, rest_cut.hi)) continue;
      if (!looked_up) {
        const auto it = cut_from.find(e);
        severed = it == cut_from.end() ? nullptr : &it->second;
        looked_up = true;
      }
      if (severed != nullptr && std::find(severed->begin(), severed->end(), p) != severed->end()) continue;
      if (rest_cut.blocked(centre, to)) {
        if (severed == nullptr) severed = &cut_from[e];
        severed->push_back(p);
        ++report.links_severed_at_rest;
      }
    }
  }
}

void VolumeCutter::reselect_severed(const Sweep& sweep, const SeveredLinks& cut_from, const RestVisibility* rest_cut,
                                    const Vector& particles_start, const Vector& particles_end,
                                    VolumeCutReport& report) {
  // Re-selection of the broken neighbourhoods, in element order (deterministic). Each
  // element's points are formed before any row changes (the test of a candidate's link).
  for (const auto& cut_element : cut_from) {
    point_at_start(cut_element.first);
    point_at_end(cut_element.first);
  }
  rest_cut_ = rest_cut;
  particles_start_ = &particles_start;
  particles_end_ = &particles_end;
  for (const auto& [element, severed] : cut_from) {
    // The stride grows when a row does (set_neighbourhood), so it is read for each element.
    const size_t base = static_cast<size_t>(element) * model_.row_stride();
    std::vector<int> kept;
    for (int k = 0; k < model_.row_lengths()[element]; ++k) {
      const int p = model_.neighbours()[base + k];
      if (std::find(severed.begin(), severed.end(), p) == severed.end()) kept.push_back(p);
    }
    bool isolated = false, nonlocal = false;
    const std::vector<int> row = reselect(element, kept, severed, sweep, isolated, nonlocal);
    report.elements_isolated += isolated ? 1 : 0;
    report.elements_nonlocal += nonlocal ? 1 : 0;
    // No valid neighbourhood left on its side (a sliver, several cuts in one element): the
    // element leaves the mechanics rather than keep links across the cut (counted).
    bool placed = !row.empty();
    if (placed) {
      try {
        model_.set_neighbourhood(element, row);
        ++report.elements_reselected;
      } catch (const std::invalid_argument&) {
        placed = false;
      }
    }
    if (!placed) {
      ++report.reselection_failures;
      model_.deactivate_element(element);
    }
    report.changed_elements.push_back(element);
    if (rest_link_boxes_.size() == static_cast<size_t>(model_.element_count())) box_rest_links(element);
    if (!element_stale_[element]) stale_list_.push_back(element);
    element_stale_[element] = 1;  // its boxed slots are stale until the next refit
    if (rest_search_->valid) rest_search_->loose.mark(element);
    near_search_->loose.mark(element);
  }
  particles_start_ = particles_end_ = nullptr;
  rest_cut_ = nullptr;
}

std::vector<int> VolumeCutter::reselect(int element, const std::vector<int>& kept, const std::vector<int>& severed,
                                        const Sweep& sweep, bool& isolated, bool& nonlocal) {
  const Vec3 centre = model_.element_centres()[element];
  const auto rest = [&](int p) { return Vec3(model_.rest_positions().segment<3>(3 * static_cast<Eigen::Index>(p))); };
  const auto particle = [](const Vector& x, int p) { return Vec3(x.segment<3>(3 * static_cast<Eigen::Index>(p))); };
  std::vector<int> seeds = kept;
  if (seeds.empty()) {
    // Every link of the element was cut (several cuts in one element, or the blade through
    // its integration point): nothing tells which side it is on. Its nearest former
    // neighbour decides, which is at least deterministic; counted as isolated.
    isolated = true;
    const size_t base = static_cast<size_t>(element) * model_.row_stride();
    int nearest = -1;
    double best = 0;
    for (int k = 0; k < model_.row_lengths()[element]; ++k) {
      const int p = model_.neighbours()[base + k];
      const double d = (rest(p) - centre).squaredNorm();
      if (nearest < 0 || d < best || (d == best && p < nearest)) nearest = p, best = d;
    }
    if (nearest < 0) return {};
    seeds.push_back(nearest);
  }
  // Breadth-first over the particle-particle links that remain; each particle reached is
  // stamped with this search (the seeds at level 0 are not candidates).
  if (reached_.size() != links_of_particle_.size()) reached_.assign(links_of_particle_.size(), 0), search_ = 0;
  if (++search_ == 0) {
    std::fill(reached_.begin(), reached_.end(), 0);
    search_ = 1;
  }
  // Scratch kept per thread between calls (a few elements per step, each growing these
  // from empty otherwise).
  thread_local std::vector<std::tuple<int, double, int>> candidates;  // graph distance, rest distance^2, particle
  thread_local std::vector<int> frontier, next;
  candidates.clear();
  frontier.assign(seeds.begin(), seeds.end());
  std::vector<size_t> level_end;  // per level from 1: where its candidates end
  for (int p : seeds) reached_[p] = search_;
  for (int level = 1; level <= graph_radius; ++level) {
    next.clear();
    for (int p : frontier) {
      for (int link : links_of_particle_[p]) {
        if (particle_link_severed_[link]) continue;
        const int q = particle_links_[link][0] == p ? particle_links_[link][1] : particle_links_[link][0];
        if (reached_[q] == search_) continue;
        reached_[q] = search_;
        next.push_back(q);
        candidates.emplace_back(level, (rest(q) - centre).squaredNorm(), q);
      }
    }
    frontier.swap(next);
    level_end.push_back(candidates.size());
  }
  // A total order (each particle once): the same whatever order they were reached in. The
  // candidates come level by level, so each level is sorted on its own, when the fill below
  // first reaches it (it mostly stops within the first two).
  size_t sorted_end = 0;
  const auto sorted_upto = [&](size_t i) {
    for (const size_t end : level_end)
      if (sorted_end <= i && sorted_end < end) {
        std::sort(candidates.begin() + static_cast<std::ptrdiff_t>(sorted_end), candidates.begin() + static_cast<std::ptrdiff_t>(end));
        sorted_end = end;
      }
  };

  const int nominal = model_.settings().neighbours;
  // Local: within two particle spacings of the point along every axis (offsets a / 2, 3a / 2,
  // 5a / 2 or 7a / 2: the corners of its particle cell and the layer past them). Without the
  // bound a blade drawn along a layer of particles (which lie in its sweep) carried the
  // neighbourhoods ahead of it: each mirror below was taken about a kept particle of that
  // layer, one step further along it, then severed when the blade got there, 25 a away after
  // 30 steps (test VolumeCut.ABladeDrawnAlongAParticleLayerKeepsEveryNeighbourhoodLocal).
  const double reach = 3.5 * model_.spacing() * (1 + 1e-9);
  const auto local = [&](int p) { return ((rest(p) - centre).cwiseAbs().array() <= reach).all(); };
  std::vector<int> row;
  row.reserve(static_cast<size_t>(slots_per_element) + seeds.size());
  for (int p : seeds)
    if (local(p)) row.push_back(p);
  std::vector<Vec3> positions;
  positions.reserve(row.capacity());
  for (int p : row) positions.push_back(rest(p));
  // Not across the cut so far (at rest), nor across this very step's sweep.
  const auto eligible = [&](int p) {
    if (rest_cut_ && rest_cut_->blocked && rest_cut_->blocked(centre, rest(p))) return false;
    return !sweep_hit(sweep, point_at_start(element), particle(*particles_start_, p), point_at_end(element),
                      particle(*particles_end_, p));
  };
  const auto add = [&](int p) {
    row.push_back(p);
    positions.push_back(rest(p));
  };
  // First, each severed neighbour's mirror: the kept neighbour nearest to it, k, and the
  // particle at k + (k - severed), i.e. one step further from the cut on the element's side.
  // A cell cut through its middle thus becomes the cell pair on the element's side, the
  // box-shaped neighbourhood the MLS fit is best conditioned on (the geometry cut's rule,
  // EfgSettings::cuts). Without it the nearest candidates by graph distance tie between the
  // particle behind the kept face and those beside or below it, and the irregular
  // neighbourhoods they make cost accuracy (the stretch_cut benchmark's error grows markedly).
  // Only a candidate within the graph distance and eligible is taken; the rest is filled below.
  for (int p : severed) {
    if (static_cast<int>(row.size()) >= slots_per_element) break;
    int nearest_kept = -1;
    double nearest = std::numeric_limits<double>::infinity();
    for (int k : kept) {
      const double d = (rest(k) - rest(p)).squaredNorm();
      if (d < nearest || (d == nearest && k < nearest_kept)) nearest = d, nearest_kept = k;
    }
    if (nearest_kept < 0) break;
    const Vec3 target = 2 * rest(nearest_kept) - rest(p);
    const double tolerance = 0.25 * nearest;  // (half the step)^2
    int best = -1;
    double best_distance = tolerance;
    // (The nearest to the target, the lowest particle among ties: in any order.)
    for (const auto& [level, squared, q] : candidates) {
      const double d = (rest(q) - target).squaredNorm();
      if (d < best_distance || (d == best_distance && best >= 0 && q < best)) best_distance = d, best = q;
    }
    if (best < 0 || !local(best) || std::find(row.begin(), row.end(), best) != row.end() || !eligible(best)) continue;
    add(best);
  }
  const auto fill = [&](bool only_local) {
    for (size_t i = 0; i < candidates.size(); ++i) {
      sorted_upto(i);
      const int p = std::get<2>(candidates[i]);
      if (static_cast<int>(row.size()) >= nominal && spans_three_dimensions(positions)) break;
      if (static_cast<int>(row.size()) >= slots_per_element) break;
      if ((only_local && !local(p)) || std::find(row.begin(), row.end(), p) != row.end() || !eligible(p)) continue;
      add(p);
    }
  };
  fill(true);
  // Where no local neighbourhood spans three dimensions (a thin part, the body's rim, a second
  // cut in the element), the kept neighbours and the candidates farther out, as without the
  // bound, rather than losing the element.
  if (!spans_three_dimensions(positions)) {
    nonlocal = true;
    for (int p : seeds)
      if (!local(p) && static_cast<int>(row.size()) < slots_per_element) add(p);
    fill(false);
  }
  if (!spans_three_dimensions(positions)) return {};
  std::sort(row.begin(), row.end());
  return row;
}

VolumeCutter::~VolumeCutter() = default;

// Every member is copied here but the call-scoped pointers (valid only inside cut()): a member
// added to VolumeCutter must be added to this list.
VolumeCutter::VolumeCutter(const VolumeCutter& other, CorotationalEfg& model)
    : model_(model),
      broad_phase_(other.broad_phase_),
      margin_(other.margin_),
      particle_links_(other.particle_links_),
      particle_link_severed_(other.particle_link_severed_),
      links_of_particle_(other.links_of_particle_),
      element_link_particles_(other.element_link_particles_),
      element_stale_(other.element_stale_),
      stale_list_(other.stale_list_),
      total_links_severed_(other.total_links_severed_),
      candidates_(other.candidates_),
      reached_(other.reached_),
      search_(other.search_),
      step_points_(std::make_unique<StepPoints>(*other.step_points_)),
      rest_link_boxes_(other.rest_link_boxes_),
      near_search_(std::make_unique<NearSearch>(*other.near_search_)),
      rest_link_index_(std::make_unique<RestLinkIndex>(*other.rest_link_index_)),
      rest_search_(std::make_unique<RestSearch>(*other.rest_search_)) {
  if (model.node_count() != other.model_.node_count() || model.element_count() != other.model_.element_count() ||
      model.neighbours() != other.model_.neighbours())
    fail("a copy must cut a copy of the model the original cuts (the same particles, elements and rows)");
  // The step's points name the step's particles only while cut() runs.
  step_points_->particles_start = step_points_->particles_end = nullptr;
}

void VolumeCutter::box_rest_links(int element) {
  const Vec3& centre = model_.element_centres()[element];
  Vec3 lo = centre, hi = centre;
  const size_t base = static_cast<size_t>(element) * model_.row_stride();
  for (int k = 0; k < model_.row_lengths()[element]; ++k) {
    const Vec3 to = model_.rest_positions().segment<3>(3 * static_cast<Eigen::Index>(model_.neighbours()[base + k]));
    lo = lo.cwiseMin(to), hi = hi.cwiseMax(to);
  }
  rest_link_boxes_[element] = {lo, hi};
  if (rest_link_index_->valid) rest_link_index_->loose.mark(element);
}

long VolumeCutter::rest_search_rebuilds() const { return rest_search_ ? rest_search_->rebuilds : 0; }

const Vec3& VolumeCutter::rest_point(int element, const Vector& particles) const {
  return rest_search_->points.get(element, [&](int e) { return integration_point(e, particles); });
}

double VolumeCutter::update_rest_bins(const Vector& particles, bool finite) const {
  const int stride = model_.row_stride();
  const int elements = model_.element_count();
  RestSearch& search = *rest_search_;
  // How far a point can have moved since the bins were built: |sum_k phi_k (x_k - x_k^bin)|
  // <= sum_k |phi_k| max_k |x_k - x_k^bin|, with room for rounding.
  double drift = std::numeric_limits<double>::infinity();
  if (search.valid && finite && search.particles.size() == particles.size()) {
    double moved = 0;
    for (Eigen::Index i = 0; i < particles.size(); i += 3)
      moved = std::max(moved, (particles.segment<3>(i) - search.particles.segment<3>(i)).squaredNorm());
    drift = search.shape_sum * std::sqrt(moved) * (1 + 1e-6) + 1e-9 * model_.spacing();
  }
  const bool stale = !(drift <= model_.spacing()) || 8 * search.loose.list.size() > static_cast<size_t>(elements);
  if (stale && finite) {
    std::vector<Vec3> points(static_cast<size_t>(elements));
    search.shape_sum = 0;
    for (int e = 0; e < elements; ++e) {
      points[e] = rest_point(e, particles);
      double sum = 0;
      const size_t base = static_cast<size_t>(e) * stride;
      for (int k = 0; k < model_.row_lengths()[e]; ++k) sum += std::abs(model_.shape_values()[base + k]);
      search.shape_sum = std::max(search.shape_sum, sum);
    }
    search.valid = bin_points(search.bins, points, model_.spacing());
    if (search.valid) {
      search.lo = search.hi = points[0];
      for (const Vec3& p : points) search.lo = search.lo.cwiseMin(p), search.hi = search.hi.cwiseMax(p);
    }
    search.binned = std::move(points);
    search.particles = particles;
    search.loose.reset(elements);
    ++search.rebuilds;
    drift = 1e-9 * model_.spacing();
  }
  return drift;
}

namespace {

// The bound D of to_rest's search: just above the least squared distance, moved up until no
// candidate is within a relative 1e-8 of it; none when that takes more than 64 moves.
std::optional<double> clear_bound(const std::vector<std::pair<int, double>>& candidates, double least) {
  double bound = least * (1 + 1e-7) + 1e-300;
  bool clear = false;
  for (int tries = 0; tries < 64 && !clear; ++tries) {
    clear = std::none_of(candidates.begin(), candidates.end(), [&](const auto& c) {
      return c.second >= bound * (1 - 1e-8) && c.second <= bound * (1 + 1e-8);
    });
    if (!clear) bound *= 1 + 1e-7;
  }
  if (!clear) return std::nullopt;
  return bound;
}

}  // namespace

bool VolumeCutter::nearest_in_bins(const Vector& particles, const Vec3& q, double drift, int hint, int& nearest,
                                   double& best) const {
  RestSearch& search = *rest_search_;
  const UniformGrid& bins = search.bins;
  const GridCells& cells = bins.cells;
  std::vector<std::pair<int, double>>& candidates = search.candidates;  // element, squared distance
  // The nearest up to a relative 1e-9, the lowest index among ties: where two points are
  // equally near (a blade midway between two layers of them), roundoff in the positions
  // (another thread count, the GPU backend) must not pick the other one, whose fit differs.
  // The rule is a scan in element order keeping a point only when it is nearer than the
  // kept one by that margin; scanning only the set S of points nearer than a bound D, with
  // no point at all within a relative 1e-8 of D, gives the same choice: the scan over every
  // point keeps the first of S it meets (all points before it are beyond D by more than the
  // margin), and no point outside S can then replace one of S.
  const auto scan = [&](const auto& order) {
    for (const auto& [e, d] : order)
      if (d < best * (1 - 1e-9)) best = d, nearest = e;
  };
  // Boxes [q - R, q + R] of growing R: every point within R of q is in the bins of the
  // box grown by the drift (points are binned where they were at the rebuild), or among
  // the loose ones. The first R: just beyond the previous choice's distance (the points
  // of a polyline come in order), else beyond q's distance to the points' box.
  // The previous choice is a point within its distance of q: no box larger than that is
  // needed (a box of a cell or more would look at up to 64 bins).
  double reach = cells.cell;
  if (hint >= 0) {
    reach = 1.001 * (rest_point(hint, particles) - q).norm() + 1e-12;
  } else {
    const Vec3 outside = (search.lo - q).cwiseMax(q - search.hi).cwiseMax(Vec3::Zero());
    reach = std::max(reach, std::max(0.0, outside.norm() - drift) + cells.cell);
  }
  for (int attempt = 0; attempt < 64; ++attempt) {
    GridCell first{}, last{};
    cells.range(q - Vec3::Constant(reach + drift), q + Vec3::Constant(reach + drift), first, last);
    const bool everything = first[0] == 0 && first[1] == 0 && first[2] == 0 && last[0] == cells.count[0] - 1 &&
                            last[1] == cells.count[1] - 1 && last[2] == cells.count[2] - 1;
    candidates.clear();
    double least = std::numeric_limits<double>::infinity();
    const auto consider = [&](int e) {
      const double d = (rest_point(e, particles) - q).squaredNorm();
      candidates.emplace_back(e, d);
      least = std::min(least, d);
    };
    // A binned point farther than reach + drift from q where it was binned is farther than
    // reach now: it can be neither within the bound nor near it (both below reach, checked
    // below), and is passed over without being formed; all are taken when the box holds
    // every bin. (The box is a cube around that ball.)
    const double ball = (reach + drift) * (reach + drift) * (1 + 1e-9);
    bins.visit_cells(first, last, [&](int e) {
      if (search.loose.loose[e]) return;
      if (!everything && (search.binned[static_cast<size_t>(e)] - q).squaredNorm() > ball) return;
      consider(e);
    });
    // The loose ones are where they are now: only those within reach of q (per axis) can be
    // nearer than the bound, which must stay below reach (else the box grows, below), unless
    // the box holds every bin (then the bound is not checked: all of them).
    for (int e : search.loose.list)
      if (everything || ((rest_point(e, particles) - q).cwiseAbs().array() <= reach).all()) consider(e);
    if (!std::isfinite(least)) {
      if (everything) return false;  // no finite distance: the caller's scan decides
      reach *= 2;
      continue;
    }
    const std::optional<double> bound = clear_bound(candidates, least);
    if (!bound) return false;
    // Every point within the bound (and its margin) must have been seen.
    if (!everything && !(*bound * (1 + 1e-8) < reach * reach * (1 - 1e-12))) {
      reach = std::max(2 * reach, 1.01 * std::sqrt(*bound * (1 + 1e-8)));
      continue;
    }
    std::erase_if(candidates, [&](const auto& c) { return !(c.second < *bound); });
    std::sort(candidates.begin(), candidates.end());
    scan(candidates);
    return true;
  }
  return false;
}

void VolumeCutter::to_rest(const Vector& particles, std::span<const Vec3> world, std::vector<Vec3>& rest,
                           std::vector<double>* distance) const {
  rest.resize(world.size());
  if (distance) distance->resize(world.size());
  const int stride = model_.row_stride();
  const int elements = model_.element_count();
  rest_search_->points.begin(elements);
  const bool finite = particles.allFinite();
  const double drift = update_rest_bins(particles, finite);
  const bool binned = rest_search_->valid && finite;
  int hint = -1;  // the previous point's choice: its distance bounds this point's nearest
  for (size_t w = 0; w < world.size(); ++w) {
    int nearest = 0;
    double best = std::numeric_limits<double>::infinity();
    const Vec3 q = world[w];
    const bool found = binned && q.allFinite() && nearest_in_bins(particles, q, drift, hint, nearest, best);
    if (found) hint = nearest;
    if (!found) {
      nearest = 0;
      best = std::numeric_limits<double>::infinity();
      for (int e = 0; e < elements; ++e) {
        const double d = (rest_point(e, particles) - q).squaredNorm();
        if (d < best * (1 - 1e-9)) best = d, nearest = e;
      }
    }
    // X = X_e + F_e^-1 (x - x_e) through the nearest point's shape-matching fit F_e.
    Mat3 fit = Mat3::Zero();
    const size_t base = static_cast<size_t>(nearest) * stride;
    for (int k = 0; k < model_.row_lengths()[nearest]; ++k) {
      fit += particles.segment<3>(3 * static_cast<Eigen::Index>(model_.neighbours()[base + k])) *
             model_.matching_coefficients()[base + k].transpose();
    }
    if (distance) (*distance)[w] = std::sqrt(best);
    const Eigen::FullPivLU<Mat3> lu(fit);
    const Vec3 offset = world[w] - rest_point(nearest, particles);
    rest[w] = model_.element_centres()[nearest] + (lu.isInvertible() ? Vec3(lu.solve(offset)) : offset);
  }
}

int VolumeCutter::pieces(std::vector<int>& piece) const {
  // Union-find over elements through shared particles.
  const int elements = model_.element_count();
  std::vector<int> parent(static_cast<size_t>(elements));
  for (int e = 0; e < elements; ++e) parent[e] = e;
  const auto root = [&](int e) {
    while (parent[e] != e) e = parent[e] = parent[parent[e]];
    return e;
  };
  std::vector<int> owner(static_cast<size_t>(model_.node_count()), -1);
  const int stride = model_.row_stride();
  for (int e = 0; e < elements; ++e) {
    const size_t base = static_cast<size_t>(e) * stride;
    for (int k = 0; k < model_.row_lengths()[e]; ++k) {
      const int p = model_.neighbours()[base + k];
      if (owner[p] < 0) {
        owner[p] = e;
      } else {
        const int a = root(owner[p]), b = root(e);
        if (a != b) parent[std::max(a, b)] = std::min(a, b);
      }
    }
  }
  piece.assign(static_cast<size_t>(elements), -1);
  std::map<int, int> number;
  for (int e = 0; e < elements; ++e) {
    const int r = root(e);
    const auto it = number.emplace(r, static_cast<int>(number.size())).first;
    piece[e] = it->second;
  }
  return static_cast<int>(number.size());
}

}  // namespace incise::physics
