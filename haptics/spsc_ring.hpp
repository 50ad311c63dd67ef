// A bounded lock-free single-producer single-consumer ring (Lamport's queue with cached
// indices). The haptic thread pushes one TickSample per tick; the physics thread drains them
// all at the start of its step, so the blade's swept path contains every pose since the last
// step. Storage is allocated once, in the constructor: no allocation after that, no lock, and
// a push never waits (a full ring refuses the item and the producer counts the loss).
//
// Exactly one thread may call the producer side (try_push) and exactly one the consumer side
// (try_pop, drain); size() and capacity() are safe anywhere.
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>
#include <new>
#include <stdexcept>
#include <type_traits>
#include <utility>

namespace incise::haptics {

template <typename T>
class SpscRing {
  static_assert(std::is_nothrow_copy_assignable_v<T> && std::is_default_constructible_v<T>,
                "SpscRing holds default-constructible, nothrow-copyable items");

 public:
  // capacity is rounded up to a power of two (at least 2).
  explicit SpscRing(std::size_t capacity) {
    if (capacity == 0 || capacity > (std::size_t{1} << 30))
      throw std::invalid_argument("SpscRing: capacity must be in [1, 2^30]");
    std::size_t size = 2;
    while (size < capacity) size <<= 1;
    mask_ = size - 1;
    items_ = std::make_unique<T[]>(size);
  }
  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;

  std::size_t capacity() const { return mask_ + 1; }

  // Items in the ring at some instant between the call and its return.
  std::size_t size() const {
    const std::size_t tail = tail_.load(std::memory_order_acquire);
    const std::size_t head = head_.load(std::memory_order_acquire);
    return head - tail;
  }

  // Producer. False (and nothing written) when the ring is full.
  bool try_push(const T& item) noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_cache_ > mask_) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      if (head - tail_cache_ > mask_) return false;
    }
    items_[head & mask_] = item;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }

  // Consumer. False when the ring is empty.
  bool try_pop(T& out) noexcept {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_cache_) {
      head_cache_ = head_.load(std::memory_order_acquire);
      if (tail == head_cache_) return false;
    }
    out = items_[tail & mask_];
    tail_.store(tail + 1, std::memory_order_release);
    return true;
  }

  // Consumer: pops everything present now, in order, calling visit(const T&) on each; returns
  // the count. Items pushed during the drain may or may not be included.
  template <typename Visit>
  std::size_t drain(Visit&& visit) {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    const std::size_t head = head_.load(std::memory_order_acquire);
    head_cache_ = head;
    for (std::size_t i = tail; i != head; ++i) visit(std::as_const(items_[i & mask_]));
    tail_.store(head, std::memory_order_release);
    return head - tail;
  }

 private:
  static constexpr std::size_t kLine = 64;  // keep the two indices off one cache line
  std::size_t mask_ = 0;
  std::unique_ptr<T[]> items_;
  alignas(kLine) std::atomic<std::size_t> head_{0};  // written by the producer
  std::size_t tail_cache_ = 0;                       // producer's view of tail_
  alignas(kLine) std::atomic<std::size_t> tail_{0};  // written by the consumer
  std::size_t head_cache_ = 0;                       // consumer's view of head_
};

}  // namespace incise::haptics
