// Copying the world copies the simulation (issue 28, STYLE.md's mjData): a World copied in the
// middle of the default scene's incision, after several cut events, steps on through further
// cuts to the same state hash as the original at every step; and the two share nothing, so
// stepping the copy leaves the original where it was. A tetrahedral body copies as well.
#include "engine/scene.hpp"
#include "engine/trajectory.hpp"
#include "engine/world.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

using namespace incise::engine;

namespace {

World shipped_world(const std::string& name) {
  const Scene scene = load_scene(std::filesystem::path(INCISE_SOURCE_DIR) / "assets/scenes" / (name + ".json"));
  return World(scene, read_trajectory(*scene.tool->trajectory));
}

// Steps `world` until its cut has made `events` events (the default scene's first come near
// step 90 of 300); fails the test when the scene ends first.
void step_until_cut_events(World& world, long events) {
  const auto steps = static_cast<std::uint64_t>(std::lround(world.scene().solver.duration / world.dt()));
  while (world.cut_totals().events < events && world.steps_taken() < steps) world.step();
  ASSERT_GE(world.cut_totals().events, events) << "the scene ended after " << world.steps_taken() << " steps";
}

}  // namespace

TEST(WorldCopy, ACopyMadeBetweenCutsStepsOnThroughFurtherCutsToTheOriginalsStates) {
  World world = shipped_world("default");
  step_until_cut_events(world, 5);
  if (::testing::Test::HasFatalFailure()) return;
  const auto start = std::chrono::steady_clock::now();
  const World copy_source = world;  // copied from a const world: copying reads only
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  World copy = copy_source;
  std::printf("copy of the default scene's world at step %llu (%ld cut events): %.1f ms\n",
              static_cast<unsigned long long>(world.steps_taken()), world.cut_totals().events, ms);
  EXPECT_EQ(copy.state_hash(), world.state_hash());
  EXPECT_EQ(copy.steps_taken(), world.steps_taken());
  EXPECT_EQ(copy.time(), world.time());
  // The copy's body is its own: its model, cut and threads, its model's loops on its threads.
  const Body &original_body = world.bodies()[0], &copied = copy.bodies()[0];
  EXPECT_NE(copied.data.efg, original_body.data.efg);
  EXPECT_EQ(copied.data.efg, copied.data.mechanics.get());
  EXPECT_NE(copied.cut->cutter.get(), original_body.cut->cutter.get());
  ASSERT_TRUE(copied.executor);
  EXPECT_NE(copied.executor.get(), original_body.executor.get());
  EXPECT_EQ(&copied.data.efg->executor(), copied.executor.get());
  EXPECT_EQ(copied.executor->thread_count(), original_body.executor->thread_count());
  EXPECT_EQ(copied.executor->has_side_helper(), original_body.executor->has_side_helper());
  EXPECT_EQ(copied.model, original_body.model) << "the read-only model is shared";

  const long events_at_copy = world.cut_totals().events;
  for (int k = 0; k < 60; ++k) {
    const StepStats a = world.step();
    const StepStats b = copy.step();
    ASSERT_EQ(a.cut_event, b.cut_event) << "step " << world.steps_taken();
    ASSERT_EQ(world.state_hash(), copy.state_hash()) << "step " << world.steps_taken();
  }
  EXPECT_GT(world.cut_totals().events, events_at_copy + 10) << "the copy was tested through further cuts";
  EXPECT_EQ(world.cut_totals().events, copy.cut_totals().events);
  EXPECT_EQ(world.cut_totals().links_severed, copy.cut_totals().links_severed);
  EXPECT_EQ(world.cut_totals().vertices_remapped, copy.cut_totals().vertices_remapped);
  EXPECT_EQ(world.bodies()[0].data.surface, copy.bodies()[0].data.surface);
}

TEST(WorldCopy, SteppingTheCopyLeavesTheOriginalWhereItWas) {
  World world = shipped_world("default");
  step_until_cut_events(world, 5);
  if (::testing::Test::HasFatalFailure()) return;
  // A copy assigned over a world of another scene takes everything from the one copied.
  World copy = shipped_world("cut_falling_cylinder");
  copy = world;
  const std::uint64_t at_copy = world.state_hash();
  const auto steps_at_copy = world.steps_taken();
  const long events_at_copy = world.cut_totals().events;
  ASSERT_EQ(copy.state_hash(), at_copy);
  std::vector<std::uint64_t> copy_hashes;
  for (int k = 0; k < 30; ++k) {
    copy.step();
    copy_hashes.push_back(copy.state_hash());
  }
  EXPECT_GT(copy.cut_totals().events, events_at_copy) << "the copy cut on";
  EXPECT_EQ(world.state_hash(), at_copy);
  EXPECT_EQ(world.steps_taken(), steps_at_copy);
  EXPECT_EQ(world.cut_totals().events, events_at_copy);
  // Nor did it disturb the original's future: stepped now, it goes where the copy went.
  for (int k = 0; k < 30; ++k) {
    world.step();
    ASSERT_EQ(world.state_hash(), copy_hashes[static_cast<std::size_t>(k)]) << "step " << world.steps_taken();
  }
}

TEST(WorldCopy, ATetrahedralBodyPushedByAProbeCopiesToo) {
  // The FEM model's copy (its rotations and all) and no threads of its own to start; copied
  // before the probe meets the organ (step 45), both stepped on through the contact.
  World world = shipped_world("probe_organ");
  for (int k = 0; k < 40; ++k) world.step();
  World copy = world;
  EXPECT_FALSE(copy.bodies()[0].executor);
  EXPECT_NE(copy.bodies()[0].data.mechanics.get(), world.bodies()[0].data.mechanics.get());
  int contacts = 0;
  for (int k = 0; k < 15; ++k) {
    contacts += world.step().contacts;
    copy.step();
    ASSERT_EQ(world.state_hash(), copy.state_hash()) << "step " << world.steps_taken();
  }
  EXPECT_GT(contacts, 0);
}
