// The lock-free channels between threads: the SPSC ring (haptic -> physics) and the triple
// buffer carrying the ContactModel (physics -> haptic), each under two real threads.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "haptics/contact_model.hpp"
#include "haptics/spsc_ring.hpp"
#include "haptics/triple_buffer.hpp"

using namespace incise::haptics;

TEST(HapticsSpscRing, RefusesWhenFullAndKeepsOrder) {
  SpscRing<int> ring(3);
  EXPECT_EQ(ring.capacity(), 4u);
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(ring.try_push(i));
  EXPECT_FALSE(ring.try_push(99));
  EXPECT_EQ(ring.size(), 4u);
  int v = -1;
  EXPECT_TRUE(ring.try_pop(v));
  EXPECT_EQ(v, 0);
  EXPECT_TRUE(ring.try_push(4));
  std::vector<int> rest;
  EXPECT_EQ(ring.drain([&](int x) { rest.push_back(x); }), 4u);
  EXPECT_EQ(rest, (std::vector<int>{1, 2, 3, 4}));
  EXPECT_FALSE(ring.try_pop(v));
  EXPECT_THROW(SpscRing<int>(0), std::invalid_argument);
}

// Every item arrives exactly once and in order, with the consumer alternating pop and drain.
TEST(HapticsSpscRing, TwoThreadsEveryItemOnceInOrder) {
  struct Item {
    std::uint64_t index = 0;
    std::uint64_t check = 0;  // a second word, so a torn item would show
  };
  constexpr std::uint64_t kItems = 300'000;
  SpscRing<Item> ring(256);
  std::uint64_t refused = 0;
  std::thread producer([&] {
    for (std::uint64_t i = 0; i < kItems;) {
      if (ring.try_push(Item{i, ~i * 0x9E3779B97F4A7C15ull}))
        ++i;
      else {
        ++refused;
        std::this_thread::yield();
      }
    }
  });
  std::uint64_t expected = 0, drains = 0;
  bool in_order = true;
  while (expected < kItems) {
    auto check = [&](const Item& item) {
      if (item.index != expected || item.check != ~item.index * 0x9E3779B97F4A7C15ull) in_order = false;
      ++expected;
    };
    if (expected % 2 == 0) {
      if (ring.drain(check) > 0) ++drains;
    } else {
      Item item;
      if (ring.try_pop(item)) check(item);
    }
    if (!in_order) break;
  }
  producer.join();
  EXPECT_TRUE(in_order) << "item " << expected << " out of order or torn";
  EXPECT_EQ(expected, kItems);
  Item extra;
  EXPECT_FALSE(ring.try_pop(extra));
  std::printf("spsc ring: %llu items in order through 256 slots (%llu pushes refused while full, %llu drains)\n",
              static_cast<unsigned long long>(kItems), static_cast<unsigned long long>(refused),
              static_cast<unsigned long long>(drains));
}

namespace {
// Every field of model k is a function of k: a read mixing two publications is caught.
ContactModel model_for(std::uint64_t k) {
  ContactModel m;
  m.step = k;
  m.count = static_cast<int>(k % ContactModel::kCapacity) + 1;
  for (int i = 0; i < m.count; ++i) {
    ContactPoint& c = m.contacts[i];
    c.point = {double(k), double(k) + i, -double(k)};
    c.normal = {0, 0, 1};
    c.reach = 1e-3 * double(i);
    c.stiffness = double(k) + 1;
    c.compliance = 1.0 / (double(k) + 1);
  }
  m.has_proxy = true;
  m.proxy_position = {double(k), 0, 0};
  m.time_ns = static_cast<std::int64_t>(k);
  return m;
}
bool consistent(const ContactModel& m) {
  const std::uint64_t k = m.step;
  if (m.count != static_cast<int>(k % ContactModel::kCapacity) + 1) return false;
  if (m.proxy_position[0] != double(k) || m.time_ns != static_cast<std::int64_t>(k)) return false;
  for (int i = 0; i < m.count; ++i) {
    const ContactPoint& c = m.contacts[i];
    if (c.point[0] != double(k) || c.point[1] != double(k) + i || c.stiffness != double(k) + 1 ||
        c.compliance != 1.0 / (double(k) + 1))
      return false;
  }
  return true;
}
}  // namespace

TEST(HapticsTripleBuffer, ContactModelReadWhileWrittenIsNeverTorn) {
  ContactChannel channel(model_for(0));
  constexpr std::uint64_t kPublications = 100'000;
  std::atomic<bool> finished{false};
  std::thread physics([&] {
    for (std::uint64_t k = 1; k <= kPublications; ++k) {
      // Fill the back slot in place, field by field, as physics would.
      ContactModel& back = channel.back();
      back = model_for(k);
      channel.publish();
    }
    finished.store(true);
  });
  std::uint64_t reads = 0, fresh_reads = 0, previous = 0;
  bool ok = true, monotonic = true;
  while (!finished.load()) {
    bool fresh = false;
    const ContactModel& m = channel.read(&fresh);
    ++reads;
    fresh_reads += fresh;
    if (!consistent(m)) ok = false;
    if (m.step < previous) monotonic = false;
    previous = m.step;
  }
  physics.join();
  const ContactModel& last = channel.read();
  EXPECT_TRUE(ok) << "a torn ContactModel was read";
  EXPECT_TRUE(monotonic) << "an older model was read after a newer one";
  EXPECT_EQ(last.step, kPublications);
  EXPECT_TRUE(consistent(last));
  std::printf("triple buffer: %llu reads (%llu fresh) during %llu publications, none torn\n",
              static_cast<unsigned long long>(reads), static_cast<unsigned long long>(fresh_reads),
              static_cast<unsigned long long>(kPublications));
}
