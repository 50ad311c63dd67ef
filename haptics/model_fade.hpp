// The models the loop renders while a newly published one fades in (haptic_loop.hpp,
// HapticLoopConfig::blend_ns): the newest at weight w, rising over the fade, and the fade's
// origin at 1 - w. The origin is what the hand felt when the newest arrived: the model before
// it, or, when that one was itself still fading in (physics steps come unevenly in real time:
// a slow step, then a quick one), the blend it was part of at the weight it had reached, kept
// as its models with fixed shares. So no publication drops the unfinished part of a fade: the
// force at the tick a model arrives differs from the tick before by one tick of the new fade
// (and the hand's motion), where dropping the fading model was a jump of (1 - w) times the
// two models' difference. A fade that a newer model interrupts had time left; the new one
// runs over its own interval or that time, the longer, so the unfinished part is not hurried.
// Fixed capacity, no allocation after construction: beyond kCapacity models in the origin,
// the one of least share merges into the one published after it (the closest in time).
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include "haptics/contact_model.hpp"

namespace incise::haptics {

// A model and its share of the force.
struct WeightedModel {
  const ContactModel* model = nullptr;
  double weight = 0;
};

class ModelFade {
 public:
  static constexpr int kCapacity = 8;  // origin models
  using Weights = std::array<WeightedModel, kCapacity + 1>;

  bool has_model() const { return has_newest_; }
  const ContactModel& newest() const { return newest_; }
  // `latest` takes over at the tick at now_ns: the blend the last tick rendered becomes its
  // origin. It fades in over blend_ns (>= 0), or, with blend_ns -1, over the time the model
  // before it lasted or the interrupted fade had left, the longer, at most max_blend_ns.
  void publish(const ContactModel& latest, std::int64_t now_ns, std::int64_t blend_ns, std::int64_t max_blend_ns);
  // The models and their weights at the tick at now_ns (period_ns apart: the newest has a
  // tick's worth at its first tick), newest first, the origin's newest to oldest; the count.
  int weights(std::int64_t now_ns, std::int64_t period_ns, Weights& out);
  int origin_count() const { return origin_count_; }
  std::int64_t blend_over_ns() const { return blend_over_ns_; }

 private:
  void merge_least_share();

  ContactModel newest_{};
  bool has_newest_ = false;
  std::array<ContactModel, kCapacity> origin_{};  // oldest first
  std::array<double, kCapacity> share_{};          // summing to 1
  int origin_count_ = 0;                           // 0: no fade under way
  std::int64_t newest_since_ns_ = 0, blend_over_ns_ = 0;
  double last_weight_ = 1;  // the newest's weight at the last tick
};

}  // namespace incise::haptics
