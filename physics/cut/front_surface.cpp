// FrontSurface's strokes: the base it starts from, the samples it takes or leaves out, and the
// surface it leaves as the next base (front_surface.hpp). Each sample's cut is recomputed by
// the stages in front_recompute.hpp; the base is indexed in front_binning.cpp.
#include "physics/cut/front_surface.hpp"

#include "physics/cut/front_geometry.hpp"
#include "physics/cut/front_recompute.hpp"
#include "physics/cut/front_stroke.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

namespace incise::physics {

using namespace front;

std::vector<std::vector<ConstraintPlane>> VertexPlanes::lists() const {
  std::vector<std::vector<ConstraintPlane>> all = lists_;
  all.reserve(size());
  for (std::size_t v = lists_.size(); v < size(); ++v) {
    const auto planes = (*this)[v];
    all.emplace_back(planes.begin(), planes.end());
  }
  return all;
}

void VertexPlanes::set_singles(std::size_t count) {
  singles_ = count;
  if (single_.size() < count) single_.resize(count);
  has_single_.assign(count, 0);
}

void VertexPlanes::add(std::size_t v, const ConstraintPlane& plane) {
  if (v < lists_.size()) {
    lists_[v].push_back(plane);
    return;
  }
  const std::size_t k = v - lists_.size();
  if (k >= singles_) throw std::logic_error("VertexPlanes::add: vertex " + std::to_string(v) + " is past the last one");
  if (has_single_[k]) throw std::logic_error("VertexPlanes::add: vertex " + std::to_string(v) + " takes one plane and has it");
  single_[k] = plane;
  has_single_[k] = 1;
}

FrontSurface::~FrontSurface() = default;
FrontSurface::FrontSurface(FrontSurface&&) noexcept = default;
FrontSurface& FrontSurface::operator=(FrontSurface&&) noexcept = default;

// Every member is copied here: a member added to FrontSurface must be added to this list.
FrontSurface::FrontSurface(const FrontSurface& other)
    : front_width_(other.front_width_),
      base_vertices_(other.base_vertices_),
      base_triangles_(other.base_triangles_),
      base_(other.base_ ? std::make_unique<Base>(*other.base_) : nullptr),
      stroke_(other.stroke_ ? std::make_unique<Stroke>(*other.stroke_) : nullptr),
      spare_edge_cut_(other.spare_edge_cut_),
      samples_(other.samples_),
      sample_t_(other.sample_t_),
      blade_s_(other.blade_s_),
      base_planes_(other.base_planes_),
      vertices_(other.vertices_),
      triangles_(other.triangles_),
      vertex_planes_(other.vertex_planes_),
      crack_front_(other.crack_front_),
      base_crack_front_(other.base_crack_front_),
      base_cut_face_(other.base_cut_face_),
      cut_face_(other.cut_face_),
      replaced_slots_(other.replaced_slots_),
      planed_base_(other.planed_base_),
      last_report_(other.last_report_),
      end_problem_(other.end_problem_),
      reuse_face_(other.reuse_face_) {}

FrontSurface& FrontSurface::operator=(const FrontSurface& other) {
  if (this != &other) *this = FrontSurface(other);
  return *this;
}

FrontSurface::FrontSurface(std::vector<Vec3> vertices, std::vector<std::array<int, 3>> triangles, double front_width)
    : front_width_(front_width), base_vertices_(std::move(vertices)), base_triangles_(std::move(triangles)) {
  if (!(front_width_ > 0) || !std::isfinite(front_width_))
    throw std::invalid_argument("FrontSurface: front_width must be positive and finite, got " + std::to_string(front_width_));
  for (size_t v = 0; v < base_vertices_.size(); ++v)
    if (!finite(base_vertices_[v])) throw std::invalid_argument("FrontSurface: vertex " + std::to_string(v) + " is not finite");
  const int n = static_cast<int>(base_vertices_.size());
  for (size_t t = 0; t < base_triangles_.size(); ++t) {
    const auto& tri = base_triangles_[t];
    for (const int v : tri)
      if (v < 0 || v >= n)
        throw std::invalid_argument("FrontSurface: triangle " + std::to_string(t) + " names vertex " + std::to_string(v) +
                                    ", out of range [0, " + std::to_string(n) + ")");
    const Vec3 normal = (base_vertices_[static_cast<size_t>(tri[1])] - base_vertices_[static_cast<size_t>(tri[0])])
                            .cross(base_vertices_[static_cast<size_t>(tri[2])] - base_vertices_[static_cast<size_t>(tri[0])]);
    if (!(normal.norm() > 0)) throw std::invalid_argument("FrontSurface: triangle " + std::to_string(t) + " is degenerate");
  }
  if (base_triangles_.empty()) throw std::invalid_argument("FrontSurface: the mesh has no triangle");
  base_planes_.assign(base_vertices_.size(), {});
  base_cut_face_.assign(base_triangles_.size(), 0);
  base_crack_front_.assign(base_vertices_.size(), 0);
  index_base();
  show_base();
}

void FrontSurface::show_base() {
  // With room for a stroke's vertices and triangles: the first sample would otherwise move the
  // whole surface to a larger block, into fresh pages, on the stroke's first cutting step
  // (docs/physics-choices.md, "Threads and memory").
  const auto with_room = [](auto& to, const auto& from) {
    const std::size_t room = from.size() + from.size() / 4 + 256;
    if (to.capacity() < room) {
      to.clear();
      to.reserve(room);
    }
    to.assign(from.begin(), from.end());
  };
  with_room(vertices_, base_vertices_);
  with_room(triangles_, base_triangles_);
  vertex_planes_ = VertexPlanes(base_planes_);
  with_room(crack_front_, base_crack_front_);
  crack_front_.resize(vertices_.size(), 0);
  with_room(cut_face_, base_cut_face_);
  cut_face_.resize(triangles_.size(), 0);
  replaced_slots_.clear();
  planed_base_.clear();
}

void FrontSurface::restore_base() {
  // The output is the base's but for the replaced slots, the planed base vertices and what
  // follows the base's vertices and triangles (see front_surface.hpp).
  for (const int s : replaced_slots_) {
    triangles_[static_cast<size_t>(s)] = base_triangles_[static_cast<size_t>(s)];
    cut_face_[static_cast<size_t>(s)] = base_cut_face_[static_cast<size_t>(s)];
  }
  for (const int v : planed_base_) vertex_planes_.listed()[static_cast<size_t>(v)] = base_planes_[static_cast<size_t>(v)];
  replaced_slots_.clear();
  planed_base_.clear();
  triangles_.resize(base_triangles_.size());
  cut_face_.resize(base_triangles_.size());
  vertices_.resize(base_vertices_.size());
  vertex_planes_.set_singles(0);
  crack_front_.resize(base_vertices_.size());
}

namespace {

// A sample whose points moved less than this times w across the blade's segments since the
// stroke's last sample is not taken either: an edge pushed along itself (a stab) sweeps cells
// of no width, and the draw that follows a stab of such cells crossed a base triangle with
// four cut ends (the drawn-blade test, CuttingResistance).
constexpr double kMinimumWidth = 0.1;

// How far the blade's points moved across its segments from `last` to `blade` (the largest):
// the width of the sheet's cells between the two samples.
double sweep_width(const std::vector<Vec3>& last, std::span<const Vec3> blade) {
  double width = 0;
  for (size_t i = 0; i + 1 < blade.size(); ++i) {
    const Vec3 along = last[i + 1] - last[i];
    const double length = along.norm();
    if (!(length > 0)) continue;
    const Vec3 u = along / length;
    for (const size_t k : {i, i + 1}) {
      const Vec3 motion = blade[k] - last[k];
      width = std::max(width, (motion - motion.dot(u) * u).norm());
    }
  }
  return width;
}

}  // namespace

FrontCutReport FrontSurface::advance(std::span<const Vec3> blade) {
  if (blade.size() < 2) throw std::invalid_argument("FrontSurface::advance: the blade needs at least two points");
  if (!samples_.empty() && blade.size() != samples_.front().size())
    throw std::invalid_argument("FrontSurface::advance: the blade has " + std::to_string(blade.size()) +
                                " points, the stroke's first sample had " + std::to_string(samples_.front().size()));
  for (size_t i = 0; i < blade.size(); ++i)
    if (!finite(blade[i])) throw std::invalid_argument("FrontSurface::advance: blade point " + std::to_string(i) + " is not finite");
  FrontCutReport report;
  if (samples_.empty()) {
    blade_s_.assign(1, 0.0);
    for (size_t i = 1; i < blade.size(); ++i) blade_s_.push_back(blade_s_.back() + (blade[i] - blade[i - 1]).norm());
    sample_t_.assign(1, 0.0);
    samples_.emplace_back(blade.begin(), blade.end());
    last_report_ = report;
    return report;  // a sheet needs two samples
  }
  double moved = 0;
  for (size_t i = 0; i < blade.size(); ++i) moved += (blade[i] - samples_.back()[i]).norm();
  moved /= static_cast<double>(blade.size());
  // Less than a hundredth of w from the last sample: the same cut (the motion adds up until
  // it is more). A blade that pauses in the body still moves at rest by what the solver's
  // roundoff moves the body (0.1-1 um per step in single precision on the GPU); such a sample
  // would set the direction the next ones must follow, at random (see below).
  if (!(moved > minimum_motion * front_width_)) return last_report_;
  // Moved along the edge only: the motion adds up until it has width (kMinimumWidth).
  if (!(sweep_width(samples_.back(), blade) > kMinimumWidth * front_width_)) return last_report_;
  if (samples_.size() >= 2) {
    // Back over what the stroke has cut (at rest the blade retreats when the body moves
    // onto it and back, or the hand does): nothing new to cut, and the sheet would fold
    // onto itself. The sample is left out; the front waits where it is.
    const auto& last = samples_.back();
    const auto& before = samples_[samples_.size() - 2];
    double forward = 0;
    for (size_t i = 0; i < blade.size(); ++i) forward += (blade[i] - last[i]).dot(last[i] - before[i]);
    if (forward < 0) {
      FrontCutReport held = last_report_;
      held.samples_held = 1;
      return held;
    }
  }
  // What the last good sample's stroke was, kept until this one is known to cut (its surface
  // follows from it: recompute gives it again).
  const bool keep = samples_.size() >= 2 && last_report_.ok();
  std::optional<Stroke> stroke_before;
  if (keep && stroke_) stroke_before = stroke_->snapshot();
  sample_t_.push_back(sample_t_.back() + moved);
  samples_.emplace_back(blade.begin(), blade.end());
  recompute(report);
  if (!report.ok() && keep) {
    // This sample cannot be cut (the problems say why): it is left out, and the surface
    // stays as the last good sample left it rather than going back to the stroke's base.
    samples_.pop_back();
    sample_t_.pop_back();
    if (stroke_before)
      stroke_->restore(std::move(*stroke_before));
    else
      drop_stroke();
    FrontCutReport again;
    recompute(again);
    FrontCutReport held = last_report_;
    held.problems = report.problems;
    held.samples_held = 1;
    return held;
  }
  last_report_ = report;
  if (report.ok() && report.crossings == 0 && report.tips == 0) {
    // Nothing touched: the stroke starts again from this sample.
    samples_.erase(samples_.begin(), samples_.end() - 1);
    sample_t_.assign(1, 0.0);
    blade_s_.assign(1, 0.0);
    for (size_t i = 1; i < blade.size(); ++i) blade_s_.push_back(blade_s_.back() + (blade[i] - blade[i - 1]).norm());
    drop_stroke();
  }
  return report;
}

bool FrontSurface::end_stroke(double reach) {
  if (!(reach >= 0) || !std::isfinite(reach))
    throw std::invalid_argument("FrontSurface::end_stroke: reach must be finite and not negative, got " + std::to_string(reach));
  bool carried = false;
  if (reach > 0 && samples_.size() >= 2 && last_report_.ok() && last_report_.front_in_body) {
    const std::vector<Vec3> last = samples_.back(), before = samples_[samples_.size() - 2];
    double mean = 0;
    for (size_t i = 0; i < last.size(); ++i) mean += (last[i] - before[i]).norm();
    mean /= static_cast<double>(last.size());
    if (mean > 0) {
      std::vector<Vec3> on(last.size());
      for (size_t i = 0; i < last.size(); ++i) on[i] = last[i] + (reach / mean) * (last[i] - before[i]);
      const FrontCutReport through = advance(on);
      if (through.samples_held == 0 && through.ok() && !through.front_in_body && samples_.size() >= 2) {
        carried = true;
      } else if (through.samples_held == 0 && samples_.size() >= 2 && samples_.back() == on) {
        // Taken, but the front is still in the body: back to the last sample, cut again from
        // the stroke's base.
        samples_.pop_back();
        sample_t_.pop_back();
        drop_stroke();
        FrontCutReport again;
        recompute(again);
        last_report_ = again;
      }
    }
  }
  FrontCutReport report;
  if (samples_.size() >= 2) recompute(report);
  end_problem_.clear();
  if (report.ok() && samples_.size() >= 2) {
    // The edge table first: a surface that is not closed and consistently oriented would
    // make every later stroke on it fail, so it is not taken (see front_surface.hpp).
    auto fresh = std::make_unique<Base>();
    try {
      fresh->edges = edge_table(triangles_);
    } catch (const std::invalid_argument& error) {
      end_problem_ = std::string("the stroke's surface was not kept: ") + error.what();
      fresh.reset();
    }
    if (fresh) {
      base_vertices_ = vertices_;
      base_triangles_ = triangles_;
      base_planes_ = vertex_planes_.lists();
      base_cut_face_ = cut_face_;
      base_crack_front_ = crack_front_;
      index_base(std::move(fresh));
    }
  }
  drop_stroke();
  last_report_ = FrontCutReport();
  show_base();
  samples_.clear();
  sample_t_.clear();
  blade_s_.clear();
  return carried;
}

void FrontSurface::drop_stroke() {
  if (!stroke_) return;
  // Its per-edge index is kept, reset where set, for the next stroke on the same base: a
  // stroke that touches nothing starts again at every sample until the blade meets the body,
  // and the index is as long as the base's edges.
  for (const int e : stroke_->cut_edges) stroke_->edge_cut[static_cast<size_t>(e)] = -1;
  spare_edge_cut_ = std::move(stroke_->edge_cut);
  stroke_.reset();
}

}  // namespace incise::physics
