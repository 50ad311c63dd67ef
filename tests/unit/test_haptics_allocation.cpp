// The haptic tick allocates nothing (DESIGN.md: no allocation per tick): an allocation on the
// haptic thread can take the allocator's lock or fault in fresh pages, and the loop's period
// would then wait on physics. The global operator new of this test program counts the calls
// made on the thread that asked it to, while asked.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <new>

#include "haptics/haptic_loop.hpp"
#include "haptics/virtual_device.hpp"

namespace {
thread_local bool counting = false;
thread_local long allocations = 0;
}  // namespace

void* operator new(std::size_t size) {
  if (counting) ++allocations;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

using namespace incise::haptics;

// Ticks through everything a tick can do: a moving device, new models published between
// ticks (fades, contacts on and off, the proxy), the passivity controller acting, the ring.
TEST(HapticsAllocation, ATickAllocatesNothing) {
  VirtualDevice device;
  device.open();
  ContactModel model;
  model.count = 1;
  model.contacts[0].stiffness = 400;
  model.contacts[0].compliance = 0.001;
  model.has_proxy = true;
  ContactChannel channel(model);
  HapticLoopConfig config;
  config.ring_capacity = 1 << 12;
  HapticLoop loop(device, channel, config);
  loop.tick(0);
  TickSample popped;
  long ticks_with_damper = 0;
  std::array<Vector3, 8> past{};
  for (int k = 1; k < 3000; ++k) {
    DevicePose pose;
    pose.position = {0.01 * std::sin(k * 0.01), 0, -0.002 * (1 - std::cos(k * 0.02))};
    device.set_pose(pose);
    past[k % 8] = pose.position;
    if (k % 10 == 0) {  // physics' side, as each step: a model whose surface moves up
      model.step = static_cast<std::uint64_t>(k / 10);
      model.count = (k / 10) % 7 == 0 ? 0 : 1;
      model.contacts[0].point = {0, 0, 0.0005 * ((k / 10) % 5)};
      // A proxy 7 ticks ahead of the hand: the coupling pulls along the motion, an active
      // spring (the passivity damper acts).
      for (int i = 0; i < 3; ++i) model.proxy_position[i] = 2 * pose.position[i] - past[(k + 1) % 8][i];
      model.time_ns = k * 1'000'000LL;
      channel.write(model);
    }
    counting = true;
    const TickSample s = loop.tick(k * 1'000'000LL);
    counting = false;
    ticks_with_damper += s.damper_force != Vector3{} ? 1 : 0;
    if (k % 10 == 0)
      while (loop.samples().try_pop(popped)) {
      }
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(ticks_with_damper, 0);
  std::printf("3000 ticks: %ld allocations, the passivity damper acted at %ld of them\n", allocations, ticks_with_damper);
}
