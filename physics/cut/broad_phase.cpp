#include "physics/cut/broad_phase.hpp"

#include <BulletCollision/BroadphaseCollision/btDbvt.h>

#include <algorithm>
#include <array>
#include <limits>
#include <optional>
#include <sstream>
#include <cfloat>
#include <cmath>
#include <stdexcept>
#include <string>

namespace incise::physics {

namespace {

// btDbvt keeps btScalar boxes (float in the default Bullet build). Beyond half the float
// range a box could not be grown without overflowing.
constexpr double largest_coordinate = 0.5 * static_cast<double>(FLT_MAX);

struct Box {
  Vec3 lower;
  Vec3 upper;
};

// `kind` and `index` name the segment in the error; the message is built only on error, so
// that queries do not allocate.
Box swept_box(const MovingSegment& segment, const char* kind, std::optional<long> index) {
  const std::array<const Vec3*, 4> points = {&segment.at_start.first, &segment.at_start.second,
                                             &segment.at_end.first, &segment.at_end.second};
  Box box{*points[0], *points[0]};
  for (const Vec3* p : points) {
    if (!p->allFinite() || p->cwiseAbs().maxCoeff() > largest_coordinate) {
      // A stream rather than string concatenation: GCC 12 warns falsely (-Wrestrict) on the latter.
      std::ostringstream message;
      message << "broad phase: " << kind;
      if (index) message << " " << *index;
      message << " has a position that is not finite or beyond single precision (" << p->x() << ", " << p->y()
              << ", " << p->z() << ")";
      throw std::invalid_argument(message.str());
    }
    box.lower = box.lower.cwiseMin(*p);
    box.upper = box.upper.cwiseMax(*p);
  }
  return box;
}

// Rounding towards -inf and +inf, so that the stored box holds the double-precision one.
btScalar round_down(double x) {
  btScalar f = static_cast<btScalar>(x);
  if (static_cast<double>(f) > x) f = std::nextafter(f, -std::numeric_limits<btScalar>::infinity());
  return f;
}
btScalar round_up(double x) {
  btScalar f = static_cast<btScalar>(x);
  if (static_cast<double>(f) < x) f = std::nextafter(f, std::numeric_limits<btScalar>::infinity());
  return f;
}

btDbvtVolume to_volume(const Box& box, double grow) {
  const btVector3 lower(round_down(box.lower.x() - grow), round_down(box.lower.y() - grow),
                        round_down(box.lower.z() - grow));
  const btVector3 upper(round_up(box.upper.x() + grow), round_up(box.upper.y() + grow),
                        round_up(box.upper.z() + grow));
  return btDbvtVolume::FromMM(lower, upper);
}

void require_length(double value, const char* name) {
  if (!std::isfinite(value) || value < 0) {
    throw std::invalid_argument(std::string("broad phase: ") + name + " must be finite and >= 0, not " +
                                std::to_string(value));
  }
}

}  // namespace

// Bullet's traversal callback, and the stack it reuses between queries.
struct EdgeBroadPhase::Traversal : btDbvt::ICollide {
  using btDbvt::ICollide::Process;
  void Process(const btDbvtNode* leaf) override { output->push_back(leaf->dataAsInt); }
  btNodeStack stack;
  std::vector<int>* output = nullptr;
};

EdgeBroadPhase::EdgeBroadPhase(double margin, double slack)
    : margin_(margin), slack_(slack), tree_(std::make_unique<btDbvt>()), traversal_(std::make_unique<Traversal>()) {
  require_length(margin, "margin");
  require_length(slack, "slack");
}

EdgeBroadPhase::~EdgeBroadPhase() = default;
EdgeBroadPhase::EdgeBroadPhase(EdgeBroadPhase&&) noexcept = default;
EdgeBroadPhase& EdgeBroadPhase::operator=(EdgeBroadPhase&&) noexcept = default;

EdgeBroadPhase::EdgeBroadPhase(const EdgeBroadPhase& other)
    : margin_(other.margin_),
      slack_(other.slack_),
      tree_(std::make_unique<btDbvt>()),
      traversal_(std::make_unique<Traversal>()),
      leaves_(other.leaves_.size(), nullptr),
      edge_count_(other.edge_count_) {
  // The stored boxes by increasing id (the header says why the tree's shape does not matter).
  for (std::size_t id = 0; id < other.leaves_.size(); ++id) {
    const btDbvtNode* leaf = other.leaves_[id];
    if (leaf == nullptr) continue;
    leaves_[id] = tree_->insert(leaf->volume, nullptr);
    leaves_[id]->dataAsInt = static_cast<int>(id);
  }
}

EdgeBroadPhase& EdgeBroadPhase::operator=(const EdgeBroadPhase& other) {
  if (this != &other) *this = EdgeBroadPhase(other);
  return *this;
}

bool EdgeBroadPhase::set_edge(int id, const MovingSegment& edge) {
  if (id < 0) throw std::invalid_argument("broad phase: edge id " + std::to_string(id) + " is negative");
  const Box box = swept_box(edge, "edge", id);
  const btDbvtVolume needed = to_volume(box, margin_);
  if (static_cast<size_t>(id) >= leaves_.size()) leaves_.resize(static_cast<size_t>(id) + 1, nullptr);
  btDbvtNode*& leaf = leaves_[static_cast<size_t>(id)];
  if (leaf == nullptr) {
    leaf = tree_->insert(to_volume(box, margin_ + slack_), nullptr);
    leaf->dataAsInt = id;  // leaves keep the caller's id in the node's data word
    ++edge_count_;
    return true;
  }
  if (leaf->volume.Contain(needed)) return false;
  btDbvtVolume grown = to_volume(box, margin_ + slack_);
  tree_->update(leaf, grown);
  return true;
}

void EdgeBroadPhase::remove_edge(int id) {
  if (!contains(id)) throw std::out_of_range("broad phase: no edge " + std::to_string(id) + " to remove");
  btDbvtNode*& leaf = leaves_[static_cast<size_t>(id)];
  tree_->remove(leaf);
  leaf = nullptr;
  --edge_count_;
}

bool EdgeBroadPhase::contains(int id) const {
  return id >= 0 && static_cast<size_t>(id) < leaves_.size() && leaves_[static_cast<size_t>(id)] != nullptr;
}

int EdgeBroadPhase::edge_count() const { return edge_count_; }

void EdgeBroadPhase::rebalance(int passes) {
  if (passes > 0) tree_->optimizeIncremental(passes);
}

void EdgeBroadPhase::collect(const MovingSegment& blade_segment, std::optional<long> index, std::vector<int>& candidates) const {
  // The blade's box is not grown: the edges' margin already covers the touching distance.
  const btDbvtVolume volume = to_volume(swept_box(blade_segment, "blade segment", index), 0);
  traversal_->output = &candidates;
  tree_->collideTVNoStackAlloc(tree_->m_root, volume, traversal_->stack, *traversal_);
  traversal_->output = nullptr;
}

void EdgeBroadPhase::query(const MovingSegment& blade_segment, std::vector<int>& candidates) const {
  candidates.clear();
  collect(blade_segment, std::nullopt, candidates);
  std::sort(candidates.begin(), candidates.end());
}

void EdgeBroadPhase::query(std::span<const Vec3> blade_at_start, std::span<const Vec3> blade_at_end,
                           std::vector<int>& candidates) const {
  if (blade_at_start.size() != blade_at_end.size() || blade_at_start.size() < 2) {
    throw std::invalid_argument("broad phase: a blade polyline needs the same number (>= 2) of points at the start "
                                "and at the end of the step, not " + std::to_string(blade_at_start.size()) +
                                " and " + std::to_string(blade_at_end.size()));
  }
  candidates.clear();
  for (std::size_t i = 0; i + 1 < blade_at_start.size(); ++i) {
    collect({{blade_at_start[i], blade_at_start[i + 1]}, {blade_at_end[i], blade_at_end[i + 1]}}, static_cast<long>(i),
            candidates);
  }
  std::sort(candidates.begin(), candidates.end());
  candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
}

}  // namespace incise::physics
