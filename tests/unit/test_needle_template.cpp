// Several needles driven by one trajectory (tool.needles: an offset and a delay each; engine/
// insert_needle.cpp) into the fast needle cube (assets/scenes/needle_cube_fast.json): a needle
// that never reaches the tissue changes nothing; a delayed needle follows the trajectory that
// much later (as one needle on the trajectory shifted by the delay); each needle keeps its own
// figures and their forces add up; bad entries are refused naming the field.
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

const std::string kScene = std::string(INCISE_SOURCE_DIR) + "/assets/scenes/needle_cube_fast.json";

using incise::testing::read_json;

std::string error_of(const Json& json) {
  try {
    const Scene scene = parse_scene(json.dump(), kScene);
    World world(scene, read_trajectory(*scene.tool->trajectory));
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

struct Replay {
  std::vector<StepStats> stats;
  std::uint64_t motion_hash = 0;
};

Replay replay(const Scene& scene, const Trajectory& trajectory, int steps) {
  World world(scene, trajectory);
  Replay out;
  for (int k = 0; k < steps; ++k) out.stats.push_back(world.step());
  out.motion_hash = world.motion_hash();
  return out;
}

int steps_of(const Scene& scene) { return static_cast<int>(std::lround(scene.solver.duration / scene.solver.dt)); }

}  // namespace

TEST(NeedleTemplate, ANeedleOutsideTheTissueChangesNothing) {
  const Scene one = load_scene(kScene);
  Json json = read_json(kScene);
  json["tool"]["needles"] = Json::parse(R"([{"offset": [0, 0, 0]}, {"offset": [0.2, 0, 0], "delay": 0.1}])");
  const Scene two = parse_scene(json.dump(), kScene);
  const Trajectory trajectory = read_trajectory(*one.tool->trajectory);
  const Replay a = replay(one, trajectory, steps_of(one));
  const Replay b = replay(two, trajectory, steps_of(two));
  // The same positions bit for bit: the far needle adds no force; the first one's figures are
  // the template's sum.
  EXPECT_EQ(a.motion_hash, b.motion_hash);
  const NeedleSummary sa = summarise_needle(a.stats), sb = summarise_needle(b.stats, 0), far = summarise_needle(b.stats, 1);
  EXPECT_EQ(sa.puncture_peak, sb.puncture_peak);
  EXPECT_EQ(sa.retract_max, sb.retract_max);
  EXPECT_EQ(sa.stick_to_slip, sb.stick_to_slip);
  EXPECT_EQ(far.max_depth, 0);
  EXPECT_EQ(far.puncture_steps + far.insert_steps, 0);
  ASSERT_EQ(b.stats.back().needles.size(), 2u);
  EXPECT_TRUE(a.stats.back().needles.empty());  // one needle: its figures are the block itself
  const NeedleSummary sum = summarise_needle(b.stats);
  EXPECT_EQ(sum.puncture_peak, sa.puncture_peak);
  EXPECT_LT(sum.balance_max, 1e-14);
}

TEST(NeedleTemplate, ADelayedNeedleFollowsTheTrajectoryThatMuchLater) {
  const double delay = 0.2;
  Json json = read_json(kScene);
  json["tool"]["needles"] = Json::parse(R"([{"delay": 0.2}])");
  json["solver"]["duration"] = json["solver"]["duration"].get<double>() + delay;
  const Scene delayed = parse_scene(json.dump(), kScene);
  // The reference: one needle on the trajectory shifted by the delay (held at its start before).
  Trajectory shifted = read_trajectory(*delayed.tool->trajectory);
  const Trajectory original = shifted;
  for (ToolSample& s : shifted.samples) s.time += delay;
  shifted.samples.insert(shifted.samples.begin(), original.samples.front());
  json["tool"].erase("needles");
  const Scene reference = parse_scene(json.dump(), kScene);
  const Replay a = replay(delayed, original, steps_of(delayed));
  const Replay b = replay(reference, shifted, steps_of(reference));
  // The same motion up to the interpolation's round-off (t - delay against shifted sample times).
  const NeedleSummary sa = summarise_needle(a.stats), sb = summarise_needle(b.stats);
  std::printf("delayed needle: puncture peak %.6f / %.6f N, retract max %.6f / %.6f N, depth %.4f / %.4f mm\n",
              sa.puncture_peak, sb.puncture_peak, sa.retract_max, sb.retract_max, 1e3 * sa.max_depth, 1e3 * sb.max_depth);
  EXPECT_NEAR(sa.puncture_peak, sb.puncture_peak, 1e-3 * sb.puncture_peak);
  EXPECT_NEAR(sa.insert_late_mean, sb.insert_late_mean, 2e-2 * sb.insert_late_mean);
  EXPECT_NEAR(sa.max_depth, sb.max_depth, 1e-9);
  EXPECT_GT(sa.max_depth, 0.007);
  // The first contact is `delay` later than the undelayed needle's.
  const Scene plain = load_scene(kScene);
  const Replay c = replay(plain, original, steps_of(plain));
  const auto first_contact = [](const Replay& r) {
    for (std::size_t k = 0; k < r.stats.size(); ++k)
      if (r.stats[k].needle.phase != "approach") return static_cast<double>(k);
    return -1.0;
  };
  EXPECT_NEAR(first_contact(a) - first_contact(c), delay / plain.solver.dt, 1.0);
}

TEST(NeedleTemplate, BadEntriesAreRefusedByName) {
  const auto refused = [](const char* needles, const std::string& expected) {
    Json json = read_json(kScene);
    json["tool"]["needles"] = Json::parse(needles);
    const std::string error = error_of(json);
    EXPECT_NE(error.find(expected), std::string::npos) << needles << " -> " << error;
  };
  refused("[]", "tool.needles: must be an array of 1 to 64 needles");
  refused(R"({"offset": [0, 0, 0]})", "tool.needles: must be an array");
  refused(R"([{"offset": [0, 0]}])", "tool.needles[0].offset: must be an array of 3 finite numbers");
  refused(R"([{}, {"offset": [0, 2, 0]}])", "tool.needles[1].offset: must be an array of 3 finite numbers within [-1, 1] m");
  refused(R"([{}, {"offset": [0, "a", 0]}])", "tool.needles[1].offset");
  refused(R"([{"delay": -1}])", "tool.needles[0].delay: -1 must be in [0, 10000]");
  refused(R"([{"delay": "soon"}])", "tool.needles[0].delay: must be a number");
  refused(R"([{"depth": 0.01}])", "tool.needles[0].depth: unknown key");
  refused(R"([3])", "tool.needles[0]: must be an object");
  Json json = read_json(kScene);
  json["tool"] = Json::parse(R"({"shape": "capsule", "radius": 0.002, "length": 0.03, "needles": [{}]})");
  json["tool"]["trajectory"] = "../trajectories/needle_cube_fast.traj";
  EXPECT_NE(error_of(json).find("tool.needles: only a needle tool has it"), std::string::npos) << error_of(json);
}
