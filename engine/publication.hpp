// Lock-free hand-over of state between the physics thread and its readers.
//
// LatestValue: the physics thread publishes the newest snapshot; a reader (window) takes the
// newest one there is. Three slots and one atomic word: the writer fills its back slot and
// swaps it with the middle one; the reader swaps the middle with its front slot when a new
// value is there. Neither side ever waits or allocates once the slots have grown to size.
//
// SnapshotRing: a lossless single-producer single-consumer ring for headless capture, where
// every K-th step must reach the render thread. The producer only waits when the consumer
// is a whole ring behind (replay runs on simulated time, so waiting changes no result).
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <thread>

namespace incise::engine {

template <typename T>
class LatestValue {
 public:
  // Writer side: fill back(), then publish().
  T& back() { return slots_[back_]; }
  void publish() {
    // The middle index travels in the low bits, "fresh" in bit 2.
    std::uint32_t previous = middle_.exchange(back_ | kFresh, std::memory_order_acq_rel);
    back_ = previous & kIndex;
  }
  // Reader side: returns true and moves the newest value to front() if one was published
  // since the last call.
  bool take() {
    if (!(middle_.load(std::memory_order_acquire) & kFresh)) return false;
    std::uint32_t previous = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = previous & kIndex;
    return true;
  }
  const T& front() const { return slots_[front_]; }

 private:
  static constexpr std::uint32_t kIndex = 3;
  static constexpr std::uint32_t kFresh = 4;
  std::array<T, 3> slots_{};
  std::uint32_t back_ = 0;                 // writer only
  std::atomic<std::uint32_t> middle_{1};   // shared
  std::uint32_t front_ = 2;                // reader only
};

template <typename T, std::size_t Capacity>
class SnapshotRing {
  static_assert(Capacity >= 2);

 public:
  // Producer: slot to fill, or nullptr when the ring is full.
  T* try_begin_push() {
    auto head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) == Capacity) return nullptr;
    return &slots_[head % Capacity];
  }
  T& begin_push() {
    for (;;) {
      if (T* slot = try_begin_push()) return *slot;
      std::this_thread::yield();
    }
  }
  void end_push() { head_.fetch_add(1, std::memory_order_release); }

  // Consumer: oldest unread slot, or nullptr when empty.
  T* front() {
    auto tail = tail_.load(std::memory_order_relaxed);
    if (head_.load(std::memory_order_acquire) == tail) return nullptr;
    return &slots_[tail % Capacity];
  }
  void pop() { tail_.fetch_add(1, std::memory_order_release); }

 private:
  std::array<T, Capacity> slots_{};
  alignas(64) std::atomic<std::uint64_t> head_{0};
  alignas(64) std::atomic<std::uint64_t> tail_{0};
};

}  // namespace incise::engine
