// The incision score (engine/incision_score.hpp, issue 33): on a surface built by hand whose
// answers are known exactly, and on real cuts of a block by a synthesised stroke along the
// plan and the same stroke shifted 5 mm across it.
#include "engine/incision_score.hpp"
#include "engine/scene.hpp"
#include "engine/trajectory_synth.hpp"
#include "engine/world.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>

using namespace incise::engine;
namespace physics = incise::physics;
using physics::Vec3;

namespace {

// A slab's top (z = 0, 1 mm grid over [-30, 30] x [-20, 20] mm, uncut) with a vertical cut at
// y = 0 from x = -20 to 20 mm and `depth` mm deep, its face there twice (the two lips, at rest
// on one another), hanging from the top grid's vertices so the wound's mouth is the line y = 0.
struct Slab {
  std::vector<Vec3> vertices;
  std::vector<std::array<int, 3>> triangles;
  std::vector<std::uint8_t> cut_face;

  explicit Slab(double depth_mm) {
    const auto top = [](int i, int j) { return (j + 20) * 61 + (i + 30); };
    for (int j = -20; j <= 20; ++j)
      for (int i = -30; i <= 30; ++i) vertices.emplace_back(i * 1e-3, j * 1e-3, 0);
    for (int j = -20; j < 20; ++j) {
      for (int i = -30; i < 30; ++i) {
        add({top(i, j), top(i + 1, j), top(i + 1, j + 1)}, 0);
        add({top(i, j), top(i + 1, j + 1), top(i, j + 1)}, 0);
      }
    }
    const int bottom = static_cast<int>(vertices.size());
    for (int i = -20; i <= 20; ++i) vertices.emplace_back(i * 1e-3, 0, -depth_mm * 1e-3);
    for (int i = -20; i < 20; ++i) {
      const int a = top(i, 0), b = top(i + 1, 0), c = bottom + i + 21, d = bottom + i + 20;
      for (int lip = 0; lip < 2; ++lip) {
        add(lip ? std::array<int, 3>{a, b, c} : std::array<int, 3>{a, c, b}, 1);
        add(lip ? std::array<int, 3>{a, c, d} : std::array<int, 3>{a, d, c}, 1);
      }
    }
  }
  void add(std::array<int, 3> t, std::uint8_t cut) {
    triangles.push_back(t);
    cut_face.push_back(cut);
  }
};

PlanSpec straight_plan(double y, double depth, double band) {
  PlanSpec plan;
  plan.path = {{-0.03, y, 0.01}, {0.03, y, 0.01}};
  plan.depth = depth;
  plan.band = band;
  return plan;
}

TEST(IncisionScore, ACutAlongThePlanScoresNoDeviationAndItsLengthAndDepth) {
  const Slab slab(10);
  IncisionScore score;
  score_cut_surface(straight_plan(0, 0.010, 0.002), slab.vertices, slab.triangles, slab.cut_face, score);
  EXPECT_TRUE(score.cut);
  EXPECT_NEAR(score.plan_length_mm, 60, 1e-9);
  EXPECT_NEAR(score.length_cut_mm, 40, 0.5);  // within a depth bin of the cut's ends
  EXPECT_LT(score.deviation_max_mm, 1e-9);
  EXPECT_NEAR(score.cut_area_mm2, 400, 1e-6);  // 40 x 10 mm, one lip
  EXPECT_NEAR(score.outside_band_mm2, 0, 1e-9);
  EXPECT_NEAR(score.depth_mean_mm, 10, 0.2);  // the deepest sub-triangle centre of each bin
  EXPECT_LT(score.depth_range_mm, 0.2);
}

TEST(IncisionScore, ThePlanFiveMillimetresAsideScoresFiveAndEveryCutOutsideTheBand) {
  const Slab slab(10);
  IncisionScore score;
  score_cut_surface(straight_plan(0.005, 0.010, 0.002), slab.vertices, slab.triangles, slab.cut_face, score);
  EXPECT_NEAR(score.deviation_mean_mm, 5, 1e-9);
  EXPECT_NEAR(score.deviation_max_mm, 5, 1e-9);
  EXPECT_NEAR(score.outside_band_mm2, 400, 1e-6);
  EXPECT_NEAR(score.length_cut_mm, 0, 1e-9);
}

TEST(IncisionScore, CutDeeperThanTheTargetAndItsBandCountsOutside) {
  const Slab slab(10);
  IncisionScore score;
  score_cut_surface(straight_plan(0, 0.005, 0.002), slab.vertices, slab.triangles, slab.cut_face, score);
  EXPECT_NEAR(score.outside_band_mm2, 40 * 3, 0.5 * 40);  // below 7 mm, to a sub-triangle row
  EXPECT_NEAR(score.depth_max_mm, 7, 0.5);
}

TEST(IncisionScore, ThePlanOffTheOrganHasNoLengthThere) {
  const Slab slab(10);
  IncisionScore score;
  PlanSpec plan = straight_plan(0, 0.010, 0.002);
  plan.path = {{0.0, 0, 0.01}, {0.05, 0, 0.01}};  // the slab ends at x = 30 mm
  score_cut_surface(plan, slab.vertices, slab.triangles, slab.cut_face, score);
  EXPECT_NEAR(score.plan_length_mm, 30, 0.5);
  EXPECT_NEAR(score.length_cut_mm, 20, 0.5);
}

// A block (80 x 40 x 20 mm, EFG at 6 mm, surface cells 3 mm) cut by a blade pressed 8 mm and
// drawn 50 mm along x at y = y_mm; returns its score against the plan along y = 0.
IncisionScore cut_block(double y_mm) {
  const nlohmann::json json = nlohmann::json::parse(R"({
    "name": "score_block",
    "bodies": [{
      "name": "block", "model": "efg", "cuttable": true,
      "generator": {"type": "box", "min": [-0.04, -0.02, 0], "max": [0.04, 0.02, 0.02]},
      "resolution": 0.006,
      "efg": {"surface_resolution": 0.003},
      "material": {"E": 5000, "nu": 0.45, "rho": 1060},
      "fixed": [{"min": [-1, -1, -1], "max": [1, 1, 0.001]}]
    }],
    "tool": {"shape": "blade", "edge": [[0, 0, 0], [0, 0, 0.03]]},
    "solver": {"dt": 0.01, "duration": 2.5, "tolerance": 1e-6, "max_iterations": 500},
    "plan": {"path": [[-0.03, 0, 0.03], [0.03, 0, 0.03]], "depth": 0.008, "band": 0.002}
  })");
  const Scene scene = parse_scene(json.dump(), std::filesystem::path("score_block.json"));
  PokeSpec poke;
  poke.approach_point = {-0.025, y_mm * 1e-3, 0.04};
  poke.contact_point = {-0.025, y_mm * 1e-3, 0.02};
  poke.depth = 0.008;
  poke.stroke = {0.05, 0, 0};
  Trajectory trajectory;
  trajectory.samples = synthesize_poke(poke);
  World world(scene, trajectory);
  std::vector<StepStats> steps;
  while (world.time() < 2.5 - 1e-9) steps.push_back(world.step());
  IncisionScore score = score_incision(*scene.plan, world, steps, scene.solver.dt);
  std::printf("[stroke at y = %g mm] deviation mean %.3f max %.3f mm, length cut %.1f of %.1f mm, depth %.2f (%.2f..%.2f) mm, "
              "area %.1f mm2, outside %.1f mm2, %d strokes, %.2f s\n",
              y_mm, score.deviation_mean_mm, score.deviation_max_mm, score.length_cut_mm, score.plan_length_mm,
              score.depth_mean_mm, score.depth_min_mm, score.depth_max_mm, score.cut_area_mm2, score.outside_band_mm2,
              score.strokes, score.duration_s);
  return score;
}

TEST(IncisionScore, AStrokeAlongThePlanScoresNoDeviationAndTheSameStrokeFiveMillimetresAsideScoresFive) {
  const IncisionScore along = cut_block(0);
  EXPECT_TRUE(along.cut);
  EXPECT_EQ(along.strokes, 1);
  EXPECT_GT(along.duration_s, 0.5);
  EXPECT_LT(along.deviation_mean_mm, 0.5);
  EXPECT_LT(along.deviation_max_mm, 1.5);  // half a surface cell
  EXPECT_NEAR(along.outside_band_mm2, 0, 1e-9);
  EXPECT_GT(along.length_cut_mm, 40);
  EXPECT_GT(along.depth_mean_mm, 3);

  const IncisionScore aside = cut_block(5);
  EXPECT_NEAR(aside.deviation_mean_mm, 5, 1.5);
  EXPECT_GT(aside.outside_band_mm2, 0.9 * aside.cut_area_mm2);
  EXPECT_GT(aside.cut_area_mm2, 0.5 * along.cut_area_mm2);
  EXPECT_NEAR(aside.length_cut_mm, 0, 1e-9);
}

TEST(IncisionScore, ABadPlanIsRefusedNamingTheField) {
  const std::string bodies = R"("bodies": [{"name": "block", "model": "efg", "cuttable": CUTTABLE,
      "generator": {"type": "box", "min": [0, 0, 0], "max": [0.02, 0.02, 0.02]}, "resolution": 0.005,
      "material": {"E": 5000, "nu": 0.45, "rho": 1000}}],
    "solver": {"dt": 0.01, "duration": 0.1})";
  const struct {
    const char* plan;
    bool cuttable;
    const char* expected;
  } cases[] = {
      {R"({"path": [[0, 0, 0]], "depth": 0.01, "band": 0.002})", true, "plan.path: must be an array of 2 to 1000 points"},
      {R"({"path": [[0, 0, 0], [0, 0, 0.01]], "depth": 0.01, "band": 0.002})", true,
       "plan.path[1]: repeats the point before it, seen along plan.direction"},
      {R"({"path": [[0, 0, 0], [0.01, 0, 0]], "depth": 0, "band": 0.002})", true, "plan.depth: 0 must be in (0, 1]"},
      {R"({"path": [[0, 0, 0], [0.01, 0, 0]], "depth": 0.01, "band": 0.002, "direction": [0, 0, 0]})", true,
       "plan.direction: must not be the zero vector"},
      {R"({"path": [[0, 0, 0], [0.01, 0, 0]], "depth": 0.01, "band": 0.002, "body": "liver"})", true,
       "plan.body: no body is named 'liver'"},
      {R"({"path": [[0, 0, 0], [0.01, 0, 0]], "depth": 0.01, "band": 0.002})", false,
       "plan.body: no body is cuttable: a plan needs one"},
      {R"({"path": [[0, 0, "x"], [0.01, 0, 0]], "depth": 0.01, "band": 0.002, "width": 1})", true, "plan.path[0]: must be"},
      {R"({"path": [[0, 0, 0], [0.01, 0, 0]], "depth": 0.01, "band": 0.002, "width": 1})", true, "plan.width: unknown key"},
  };
  for (const auto& c : cases) {
    std::string text = "{\"name\": \"plan\", " + bodies + ", \"plan\": " + c.plan + "}";
    text.replace(text.find("CUTTABLE"), 8, c.cuttable ? "true" : "false");
    try {
      parse_scene(text, "plan.json");
      ADD_FAILURE() << "accepted: " << c.plan;
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find(c.expected), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("plan.json"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
