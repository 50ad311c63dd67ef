// A single-writer sequence lock for small trivially copyable values that a UI thread writes
// and the haptic thread reads (or the reverse): the writer never waits, the reader retries
// while a write is in progress and never sees a torn value.
//
// The payload is stored as relaxed-ordered atomic words, written with release and read with
// acquire (Boehm, "Can seqlocks get along with programming language memory models?", 2012,
// §5): that needs no stand-alone fences, is data-race-free in the C++ model, and
// ThreadSanitizer checks it as it is.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <type_traits>

namespace incise::haptics {

template <typename T>
class Seqlock {
  static_assert(std::is_trivially_copyable_v<T>, "Seqlock holds trivially copyable values");
  static constexpr std::size_t kWords = (sizeof(T) + 7) / 8;

 public:
  explicit Seqlock(const T& initial = T{}) { store(initial); }
  Seqlock(const Seqlock&) = delete;
  Seqlock& operator=(const Seqlock&) = delete;

  // One writer thread at a time (callers with several writers serialise them themselves).
  void store(const T& value) {
    std::array<std::uint64_t, kWords> words{};
    std::memcpy(words.data(), &value, sizeof(T));
    const std::uint64_t s = sequence_.load(std::memory_order_relaxed);
    sequence_.store(s + 1, std::memory_order_relaxed);  // odd: write in progress
    for (std::size_t i = 0; i < kWords; ++i) words_[i].store(words[i], std::memory_order_release);
    sequence_.store(s + 2, std::memory_order_release);
  }

  // Any number of readers. False when `attempts` reads all overlapped a write (out untouched).
  bool try_load(T& out, int attempts = 64) const {
    for (int a = 0; a < attempts; ++a) {
      const std::uint64_t before = sequence_.load(std::memory_order_acquire);
      if (before & 1) continue;
      std::array<std::uint64_t, kWords> words;
      for (std::size_t i = 0; i < kWords; ++i) words[i] = words_[i].load(std::memory_order_acquire);
      if (sequence_.load(std::memory_order_relaxed) == before) {
        std::memcpy(static_cast<void*>(&out), words.data(), sizeof(T));
        return true;
      }
    }
    return false;
  }

  T load() const {
    T out{};
    while (!try_load(out)) {
    }
    return out;
  }

  // Completed writes so far.
  std::uint64_t version() const { return sequence_.load(std::memory_order_acquire) / 2; }

 private:
  std::atomic<std::uint64_t> sequence_{0};
  std::array<std::atomic<std::uint64_t>, kWords> words_{};
};

}  // namespace incise::haptics
