// The needle through the engine (engine/insert_needle.cpp) into the shape-memory cube of the
// seed's test (seed 002 §8.9; assets/scenes/needle_cube.json): the force against depth shows the
// puncture's peak, then cutting plus friction growing with depth; the retraction has friction
// only; stick and slip transitions happen and are counted; the forces on the tissue and on the
// needle are equal and opposite, the tool's force the needle's. Bad set-ups are refused by name.
#include "engine/needle_summary.hpp"
#include "engine/scene.hpp"
#include "engine/world.hpp"
#include "tests/unit/read_json.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

using namespace incise::engine;
using Json = nlohmann::json;

namespace {

const std::string kScene = std::string(INCISE_SOURCE_DIR) + "/assets/scenes/needle_cube.json";

using incise::testing::read_json;

World cube_world(const Scene& scene) { return World(scene, read_trajectory(*scene.tool->trajectory)); }

std::string error_of(Json json) {
  try {
    const Scene scene = parse_scene(json.dump(), kScene);
    World world(scene, read_trajectory(*scene.tool->trajectory));
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(NeedleScene, PunctureThenGrowthThenFrictionOnlyOnRetraction) {
  const Scene scene = load_scene(kScene);
  World world = cube_world(scene);
  std::vector<StepStats> stats;
  const auto steps = static_cast<int>(std::lround(scene.solver.duration / scene.solver.dt));
  double tool_vs_needle = 0;
  for (int k = 0; k < steps; ++k) {
    stats.push_back(world.step());
    const StepStats& s = stats.back();
    ASSERT_TRUE(s.needle.present);
    // The tool's force (the solve's, from the springs it applied) is the needle's, along -z.
    tool_vs_needle = std::max(tool_vs_needle, std::abs(-s.tool_force[2] - s.needle.axial));
    ASSERT_EQ(s.nonfinite_events, 0) << "step " << k;
  }
  const NeedleSummary n = summarise_needle(stats);
  std::printf("needle_cube: puncture peak %.4f N, insert early %.4f N, late %.4f N, retract max %.4f N, depth %.2f mm, "
              "stick->slip %ld, slip->stick %ld, balance %.1e N, tool vs needle %.1e N\n",
              n.puncture_peak, n.insert_early_mean, n.insert_late_mean, n.retract_max, 1e3 * n.max_depth, n.stick_to_slip,
              n.slip_to_stick, n.balance_max, tool_vs_needle);
  EXPECT_GT(n.puncture_steps, 0);
  EXPECT_GT(n.puncture_peak, 1.5 * n.insert_early_mean);  // the puncture's peak above the cutting past it
  EXPECT_GT(n.insert_late_mean, 1.2 * n.insert_early_mean);  // friction grows with depth
  EXPECT_GT(n.max_depth, 0.010);
  EXPECT_EQ(n.retract_cutting_max, 0);  // no cutting force on retraction
  EXPECT_GT(n.retract_max, 0.04 - 1e-12);  // but friction, at least one node's
  // Friction only: at most every node's k_f (7 x 0.04 N; the stuck nodes unload through zero
  // as the motion reverses, so the force's sign is not asserted).
  EXPECT_LE(n.retract_max, 7 * 0.04 + 1e-12);
  EXPECT_GT(n.stick_to_slip, 0);
  EXPECT_GT(n.slip_to_stick, 0);
  EXPECT_LT(n.balance_max, 1e-14);
  EXPECT_LT(tool_vs_needle, 1e-14);
}

TEST(NeedleScene, ACopyStepsOnToTheSameState) {
  const Scene scene = load_scene(kScene);
  World world = cube_world(scene);
  for (int k = 0; k < 900; ++k) world.step();  // in the tissue, nodes gripping
  World copy = world;
  for (int k = 0; k < 300; ++k) {
    world.step();
    copy.step();
  }
  EXPECT_EQ(world.state_hash(), copy.state_hash());
}

TEST(NeedleScene, BadSetUpsAreRefusedByName) {
  Json json = read_json(kScene);
  json["tool"]["stiffness"] = 100;
  EXPECT_NE(error_of(json).find("tool.stiffness: a needle has no penalty contact"), std::string::npos);
  json = read_json(kScene);
  json["tool"]["nodes"] = 1;
  EXPECT_NE(error_of(json).find("tool.nodes"), std::string::npos);
  json = read_json(kScene);
  json["tool"].erase("length");
  EXPECT_NE(error_of(json).find("tool.length: is required"), std::string::npos);
  json = read_json(kScene);
  json["tool"]["shape"] = "sphere";
  json["tool"]["radius"] = 0.005;
  json["tool"].erase("length");
  EXPECT_NE(error_of(json).find("tool.friction_force: only a needle has it"), std::string::npos);
  json = read_json(kScene);
  // An EFG body is accepted: its integration points are the needle's tissue (needle_efg.hpp).
  json["bodies"][0]["model"] = "efg";
  json["bodies"][0].erase("shape_memory");
  EXPECT_EQ(error_of(json), "");
}
