// Lock-free, wait-free triple buffer for the newest value of a trivially copyable T: one
// writer publishes whole values, one reader takes the newest complete one. Three slots; the
// writer owns one ("back"), the reader owns one ("front"), and the third is exchanged through
// one atomic byte that holds its index plus a "fresh" bit. Neither side ever sees a slot the
// other is using, so a torn read is impossible by construction, and nobody waits or allocates.
//
// The physics thread publishes haptics::ContactModel through one of these each step and the
// haptic thread reads it each tick (DESIGN.md: publication is a swap of an atomic index).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <type_traits>

namespace incise::haptics {

template <typename T>
class TripleBuffer {
  static_assert(std::is_trivially_copyable_v<T>, "TripleBuffer holds trivially copyable values");

 public:
  explicit TripleBuffer(const T& initial = T{}) { slots_.fill(initial); }
  TripleBuffer(const TripleBuffer&) = delete;
  TripleBuffer& operator=(const TripleBuffer&) = delete;

  // Writer: the slot to fill, then publish(). Or write(value) for both at once.
  T& back() { return slots_[back_]; }
  void publish() {
    const std::uint8_t previous =
        middle_.exchange(static_cast<std::uint8_t>(back_ | kFresh), std::memory_order_acq_rel);
    back_ = previous & kIndex;
  }
  void write(const T& value) {
    back() = value;
    publish();
  }

  // Reader: takes the newest published value if there is one since the last read, and returns
  // the reader's slot (valid until the next read()). `fresh` tells whether it changed.
  const T& read(bool* fresh = nullptr) {
    const bool changed = (middle_.load(std::memory_order_relaxed) & kFresh) != 0;
    if (changed) {
      const std::uint8_t previous = middle_.exchange(front_, std::memory_order_acq_rel);
      front_ = previous & kIndex;
    }
    if (fresh) *fresh = changed;
    return slots_[front_];
  }

 private:
  static constexpr std::uint8_t kIndex = 0x3, kFresh = 0x4;
  std::array<T, 3> slots_{};
  std::uint8_t back_ = 0;                    // writer's slot
  std::atomic<std::uint8_t> middle_{1};      // exchanged slot | kFresh when unread
  std::uint8_t front_ = 2;                   // reader's slot
};

}  // namespace incise::haptics
