#include "haptics/model_fade.hpp"

#include <algorithm>

namespace incise::haptics {

void ModelFade::publish(const ContactModel& latest, std::int64_t now_ns, std::int64_t blend_ns, std::int64_t max_blend_ns) {
  if (has_newest_) {
    const std::int64_t lasted = now_ns - newest_since_ns_;
    // The weight the newest had reached at the last tick; 1 when its fade was over.
    const double reached = origin_count_ > 0 ? last_weight_ : 1.0;
    std::int64_t left = 0;
    if (reached >= 1) {
      origin_count_ = 0;
    } else {
      for (int i = 0; i < origin_count_; ++i) share_[i] *= 1 - reached;
      left = std::max<std::int64_t>(0, blend_over_ns_ - lasted);
      if (origin_count_ == kCapacity) merge_least_share();
    }
    origin_[origin_count_] = newest_;
    share_[origin_count_] = reached;
    ++origin_count_;
    blend_over_ns_ = blend_ns >= 0 ? blend_ns : std::clamp<std::int64_t>(std::max(lasted, left), 0, max_blend_ns);
  }
  newest_ = latest;
  has_newest_ = true;
  newest_since_ns_ = now_ns;
}

void ModelFade::merge_least_share() {
  int least = 0;
  for (int i = 1; i < origin_count_; ++i)
    if (share_[i] < share_[least]) least = i;
  const int into = least + 1 < origin_count_ ? least + 1 : least - 1;
  share_[into] += share_[least];
  for (int i = least; i + 1 < origin_count_; ++i) {
    origin_[i] = origin_[i + 1];
    share_[i] = share_[i + 1];
  }
  --origin_count_;
}

int ModelFade::weights(std::int64_t now_ns, std::int64_t period_ns, Weights& out) {
  double weight = 1;
  if (origin_count_ > 0 && blend_over_ns_ > 0)
    weight = std::clamp(static_cast<double>(now_ns - newest_since_ns_ + period_ns) / static_cast<double>(blend_over_ns_), 0.0, 1.0);
  if (weight >= 1) origin_count_ = 0;
  last_weight_ = weight;
  out[0] = {&newest_, weight};
  int n = 1;
  for (int i = origin_count_ - 1; i >= 0; --i) out[n++] = {&origin_[i], (1 - weight) * share_[i]};
  return n;
}

}  // namespace incise::haptics
