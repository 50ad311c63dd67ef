// The lock-free hand-over between threads: run under ThreadSanitizer in CI.
#include "engine/publication.hpp"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <thread>

using incise::engine::LatestValue;
using incise::engine::SnapshotRing;

namespace {
// A value whose parts must agree: a torn read shows as a mismatch.
struct Payload {
  long sequence = 0;
  std::array<long, 64> copies{};
};
}  // namespace

TEST(Publication, LatestValueNeverTearsAndOnlyMovesForward) {
  LatestValue<Payload> latest;
  constexpr long kCount = 200000;
  std::thread writer([&] {
    for (long i = 1; i <= kCount; ++i) {
      Payload& p = latest.back();
      p.sequence = i;
      p.copies.fill(i);
      latest.publish();
    }
  });
  long last = 0, taken = 0;
  while (last < kCount) {
    if (!latest.take()) continue;
    const Payload& p = latest.front();
    for (long c : p.copies) ASSERT_EQ(c, p.sequence);
    ASSERT_GT(p.sequence, last);
    last = p.sequence;
    ++taken;
  }
  writer.join();
  EXPECT_EQ(last, kCount);
  EXPECT_GE(taken, 1);
  EXPECT_FALSE(latest.take());
}

TEST(Publication, RingIsLosslessAndOrdered) {
  SnapshotRing<Payload, 4> ring;
  constexpr long kCount = 100000;
  std::thread producer([&] {
    for (long i = 1; i <= kCount; ++i) {
      Payload& p = ring.begin_push();
      p.sequence = i;
      p.copies.fill(i);
      ring.end_push();
    }
  });
  long expected = 1;
  while (expected <= kCount) {
    Payload* p = ring.front();
    if (!p) {
      std::this_thread::yield();
      continue;
    }
    ASSERT_EQ(p->sequence, expected);
    for (long c : p->copies) ASSERT_EQ(c, expected);
    ring.pop();
    ++expected;
  }
  producer.join();
  EXPECT_EQ(ring.front(), nullptr);
}

TEST(Publication, RingReportsFull) {
  SnapshotRing<int, 2> ring;
  ASSERT_NE(ring.try_begin_push(), nullptr);
  ring.end_push();
  ASSERT_NE(ring.try_begin_push(), nullptr);
  ring.end_push();
  EXPECT_EQ(ring.try_begin_push(), nullptr);
  ring.pop();
  EXPECT_NE(ring.try_begin_push(), nullptr);
}
