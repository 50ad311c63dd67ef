// The tissue's resistance to the blade (Mahvash and Hayward 2004; engine/cutting_resistance.cpp):
// a vertical blade pressed into a block and drawn through it at constant speed. Before the
// crack's onset nothing is cut and the surface dimples more as the blade pushes harder; in
// steady cutting the force against the motion is the toughness times the engaged edge
// length, and twice the toughness gives twice the force.
#include "engine/scene.hpp"
#include "engine/trajectory.hpp"
#include "engine/world.hpp"
#include "physics/core/contact.hpp"
#include "physics/cut/cutting_resistance.hpp"
#include "tests/unit/temp_dir.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

using namespace incise::engine;
namespace physics = incise::physics;
using Json = nlohmann::json;
using incise::testing::TempDir;

namespace {

constexpr double kTop = 0.03;     // the block's top, m
constexpr double kDepth = 0.015;  // how far the blade's tip goes below it, m
constexpr double kSpeed = 0.05;   // drawing speed, m/s

// A block 80 x 40 x 30 mm (E = 5 kPa, no gravity, its base fixed) and a 30 mm vertical edge
// whose tip starts 10 mm above it at x = -25 mm, is pressed kDepth below the top over 0.3 s
// and drawn along +x at kSpeed for 0.8 s, engaged throughout.
Scene drawn_blade_scene(const TempDir& dir, double toughness) {
  std::vector<ToolSample> samples;
  for (int k = 0; k <= 1200; ++k) {
    ToolSample s;
    s.time = k / 1000.0;
    const double press = std::clamp(s.time / 0.3, 0.0, 1.0);
    const double draw = std::clamp(s.time - 0.3, 0.0, 0.8);
    s.position = {-0.025 + kSpeed * draw, 0, kTop + 0.01 - (0.01 + kDepth) * press};
    s.buttons = kToolButtonEngaged;
    samples.push_back(s);
  }
  write_trajectory(dir.path / "draw.traj", samples);
  Json scene = Json::parse(R"({
    "name": "drawn_blade",
    "bodies": [{
      "name": "block", "model": "efg", "cuttable": true,
      "generator": {"type": "box", "min": [-0.04, -0.02, 0], "max": [0.04, 0.02, 0.03]},
      "resolution": 0.005,
      "efg": {"surface_resolution": 0.0025},
      "material": {"E": 5000, "nu": 0.45, "rho": 1000},
      "fixed": [{"min": [-1, -1, -1], "max": [1, 1, 0.001]}],
      "damping": {"mass": 2.0, "stiffness": 0.001}
    }],
    "tool": {"shape": "blade", "edge": [[0, 0, 0], [0, 0, 0.03]], "radius": 0.0005, "flank_friction": 0, "onset": true,
             "trajectory": "draw.traj"},
    "solver": {"dt": 0.01, "duration": 1.1, "gravity": [0, 0, 0], "tolerance": 1e-6, "max_iterations": 500}
  })");
  scene["bodies"][0]["material"]["toughness"] = toughness;
  return parse_scene(scene.dump(), dir.path / "scene.json");
}

struct DrawnRun {
  std::vector<double> pressing_force, pressing_indent;  // per step before the onset
  long events_before_onset = 0;
  double lowest_surface_before_onset = kTop;  // the dimple's bottom
  double steady_force = 0;                    // mean force against the motion, N
  double steady_length = 0;                   // mean engaged length, m
  long cut_events = 0;
  long front_problems = 0;  // samples the surface's front could not cut
  std::string first_front_problem;
};

DrawnRun draw(double toughness) {
  TempDir dir("incise_cutting_resistance");
  const Scene scene = drawn_blade_scene(dir, toughness);
  World world(scene, read_trajectory(dir.path / "draw.traj"));
  DrawnRun run;
  int steady = 0;
  for (int step = 0; step < 110; ++step) {
    const StepStats stats = world.step();
    const double time = world.time();
    if (stats.blade_pressing) {
      run.pressing_force.push_back(std::hypot(stats.tool_force[0], stats.tool_force[1], stats.tool_force[2]));
      run.pressing_indent.push_back(kTop - world.tool().tip[2]);
      run.events_before_onset = world.cut_totals().events;
      const auto& x = world.bodies()[0].data.surface_positions;
      for (Eigen::Index i = 2; i < x.size(); i += 3) run.lowest_surface_before_onset = std::min(run.lowest_surface_before_onset, x[i]);
    }
    // The steady part: the blade at full depth, moving, from 5 mm after the draw starts.
    if (time > 0.4 && time <= 1.1) {
      EXPECT_TRUE(stats.blade_cutting) << "t = " << time;
      run.steady_force += -stats.cutting_force[0];
      run.steady_length += stats.engaged_length;
      ++steady;
    }
  }
  run.cut_events = world.cut_totals().events;
  run.front_problems = world.cut_totals().front_problems;
  run.first_front_problem = world.cut_totals().first_front_problem;
  if (steady > 0) run.steady_force /= steady, run.steady_length /= steady;
  return run;
}

}  // namespace

TEST(CuttingResistance, ADrawnBladeIsResistedByTheToughnessTimesTheEngagedLength) {
  const double toughness = 200;
  const DrawnRun run = draw(toughness);
  // Before the onset: nothing cut, a visible dimple, and the deeper the blade the harder it pushes.
  ASSERT_GE(run.pressing_force.size(), 3u) << "the blade cut as soon as it touched";
  EXPECT_EQ(run.events_before_onset, 0);
  EXPECT_LT(run.lowest_surface_before_onset, kTop - 0.001) << "no dimple before the onset";
  // The blade goes deeper at every pressing step, and the tissue pushes back harder with it: the
  // force over the pressing phase rises with the indentation (positively correlated; its first
  // step carries the contact's start-up, the tissue's inertia).
  const std::size_t n = run.pressing_force.size();
  double mean_f = 0, mean_d = 0;
  for (std::size_t i = 0; i < n; ++i) mean_f += run.pressing_force[i] / n, mean_d += run.pressing_indent[i] / n;
  double cov = 0, var_f = 0, var_d = 0;
  for (std::size_t i = 0; i < n; ++i) {
    std::printf("pressing: indentation %.2f mm, force %.4f N\n", 1e3 * run.pressing_indent[i], run.pressing_force[i]);
    if (i > 0) {
      EXPECT_GT(run.pressing_indent[i], run.pressing_indent[i - 1]) << "pressing step " << i;
    }
    cov += (run.pressing_force[i] - mean_f) * (run.pressing_indent[i] - mean_d);
    var_f += (run.pressing_force[i] - mean_f) * (run.pressing_force[i] - mean_f);
    var_d += (run.pressing_indent[i] - mean_d) * (run.pressing_indent[i] - mean_d);
  }
  EXPECT_GT(cov / std::sqrt(var_f * var_d), 0.9) << "force and indentation do not grow together";
  EXPECT_GT(run.pressing_force.back(), run.pressing_force.front());
  // Steady cutting: the blade's tip kDepth below the top, a vertical edge moving across itself.
  EXPECT_GT(run.cut_events, 0);
  // The edge, still pressed down along itself when the onset starts the cut, sweeps cells of no
  // width until the draw: the front surface takes its samples once they moved across the edge
  // (a base triangle crossed with four cut ends otherwise, from the draw's first sample on).
  std::printf("front problems %ld (%s)\n", run.front_problems, run.first_front_problem.c_str());
  EXPECT_EQ(run.front_problems, 0) << run.first_front_problem;
  const double expected = toughness * kDepth;
  std::printf("steady cutting force %.3f N, G_c x depth %.3f N, engaged length %.2f mm\n", run.steady_force, expected,
              1e3 * run.steady_length);
  EXPECT_NEAR(run.steady_force, expected, 0.2 * expected);

  const DrawnRun doubled = draw(2 * toughness);
  std::printf("twice the toughness: %.3f N (ratio %.3f)\n", doubled.steady_force, doubled.steady_force / run.steady_force);
  EXPECT_NEAR(doubled.steady_force / run.steady_force, 2.0, 0.2);
  EXPECT_EQ(doubled.events_before_onset, 0);
}

TEST(CuttingResistance, APointOfAPressedEdgeDeepInsideIsHeldOutOfItsNearestFaceWhateverItsDepth) {
  // A closed 20 mm cube, its faces turned outwards. The capsule contact lets go of an axis a
  // radius past a face; held_contact pushes such a point back out of the face nearest to it
  // with k (radius + depth), the force the capsule gave a face its axis went through.
  const double side = 0.02, radius = 0.0006, k = 500;
  physics::Vector x(24);
  for (int v = 0; v < 8; ++v) x.segment<3>(3 * v) = side * physics::Vec3(v & 1, (v >> 1) & 1, (v >> 2) & 1);
  const std::vector<std::array<int, 4>> quads = {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}};
  std::vector<std::array<int, 3>> surface;
  const physics::Vec3 centre = physics::Vec3::Constant(side / 2);
  for (const auto& q : quads)
    for (const std::array<int, 3> t : {std::array<int, 3>{q[0], q[1], q[2]}, std::array<int, 3>{q[0], q[2], q[3]}}) {
      const physics::Vec3 a = x.segment<3>(3 * t[0]), b = x.segment<3>(3 * t[1]), c = x.segment<3>(3 * t[2]);
      const bool outward = (b - a).cross(c - a).dot((a + b + c) / 3 - centre) > 0;
      surface.push_back(outward ? t : std::array<int, 3>{t[0], t[2], t[1]});
    }
  const auto held = [&](const physics::Vec3& p) { return physics::held_contact(x, surface, {}, {p}, radius, k); };
  for (const double depth : {0.001, 0.004, 0.009}) {
    // Below the top face's middle, nearer to it than to any other face.
    const physics::ProbeContact c = held({0.011, 0.009, side - depth});
    EXPECT_NEAR(c.force_on_tool.z(), k * (radius + depth), 1e-9) << depth;
    EXPECT_NEAR(c.force_on_tool.head<2>().norm(), 0.0, 1e-12);
    physics::Vec3 on_tissue = physics::Vec3::Zero();
    for (const auto& spring : c.springs) on_tissue += spring.force;
    EXPECT_NEAR((on_tissue + c.force_on_tool).norm(), 0.0, 1e-12) << "the tissue takes the opposite force";
  }
  // Near a side face the way out is through it.
  EXPECT_NEAR(held({0.003, 0.01, 0.01}).force_on_tool.x(), -k * (radius + 0.003), 1e-9);
  // Within a radius of the surface, or outside, it is the capsule's: no hold.
  EXPECT_TRUE(held({0.01, 0.01, side - 0.5 * radius}).springs.empty());
  EXPECT_TRUE(held({0.01, 0.01, side + 0.002}).springs.empty());
}

TEST(CuttingResistance, AThinEdgePressedAcrossItselfFasterThanItsWidthIsHeldUntilTheOnset) {
  // A horizontal edge 0.6 mm in radius pressed down into the block at 2 mm a step, further than
  // its width: the capsules alone let go of it once its axis is a radius inside, after which it
  // sank without force, its work never reached the onset's threshold and nothing was cut.
  TempDir dir("incise_cutting_resistance_hold");
  std::vector<ToolSample> samples;
  for (int k = 0; k <= 300; ++k) {
    ToolSample s;
    s.time = k / 1000.0;
    s.position = {0, 0, kTop + 0.004 - 0.2 * std::min(s.time, 0.12)};
    s.buttons = kToolButtonEngaged;
    samples.push_back(s);
  }
  write_trajectory(dir.path / "press.traj", samples);
  Json json = Json::parse(R"({
    "name": "pressed_edge",
    "bodies": [{
      "name": "block", "model": "efg", "cuttable": true,
      "generator": {"type": "box", "min": [-0.02, -0.02, 0], "max": [0.02, 0.02, 0.03]},
      "resolution": 0.005,
      "efg": {"surface_resolution": 0.0025},
      "material": {"E": 5000, "nu": 0.45, "rho": 1000},
      "fixed": [{"min": [-1, -1, -1], "max": [1, 1, 0.001]}],
      "damping": {"mass": 2.0, "stiffness": 0.001}
    }],
    "tool": {"shape": "blade", "edge": [[0, -0.03, 0], [0, 0.03, 0]], "radius": 0.0006, "onset": true,
             "trajectory": "press.traj"},
    "solver": {"dt": 0.01, "duration": 0.3, "gravity": [0, 0, 0], "tolerance": 1e-6, "max_iterations": 500}
  })");
  World world(parse_scene(json.dump(), dir.path / "scene.json"), read_trajectory(dir.path / "press.traj"));
  int pressing = 0, cutting = 0, pressing_after_cutting = 0;
  double deepest_pressing_force = 0;
  for (int step = 0; step < 30; ++step) {
    const StepStats stats = world.step();
    if (stats.blade_pressing) {
      ++pressing;
      if (cutting > 0) ++pressing_after_cutting;
      deepest_pressing_force = std::hypot(stats.tool_force[0], stats.tool_force[1], stats.tool_force[2]);
      EXPECT_GT(deepest_pressing_force, 0) << "step " << step + 1 << ": an engaged edge pressing without force";
    }
    if (stats.blade_cutting) ++cutting;
  }
  std::printf("pressing steps %d (last force %.3f N), cutting steps %d, cut events %ld\n", pressing,
              deepest_pressing_force, cutting, world.cut_totals().events);
  EXPECT_GE(pressing, 2) << "the edge cut at first contact";
  EXPECT_GT(cutting, 0) << "the onset never came";
  EXPECT_EQ(pressing_after_cutting, 0) << "the engagement started over";
  EXPECT_GT(world.cut_totals().events, 0);
}

TEST(CuttingResistance, TheForceOfAPieceIsTheToughnessTimesItsLengthAcrossItsMotion) {
  // Independent of the engine: two pieces 1 cm long, one moving across the edge, one along it.
  std::vector<physics::EdgePiece> pieces(2);
  pieces[0] = {physics::Vec3::Zero(), physics::Vec3::UnitZ(), 0.01, physics::Vec3(0.001, 0, 0), true};
  pieces[1] = {physics::Vec3::Zero(), physics::Vec3::UnitZ(), 0.01, physics::Vec3(0, 0, -0.001), true};
  const physics::CuttingForce f = physics::cutting_force(pieces, {300, 0});
  EXPECT_NEAR(f.on_tool.x(), -3.0, 1e-12);  // G_c l against the crossing motion
  EXPECT_NEAR(f.on_tool.z(), 0.0, 1e-12);   // a stab along the edge opens no area
  EXPECT_NEAR(f.crack_area, 1e-5, 1e-18);
  EXPECT_NEAR(f.engaged_length, 0.02, 1e-15);
  // The work over the step is the toughness times the area opened (Mahvash and Hayward's balance).
  EXPECT_NEAR(-f.on_tool.dot(pieces[0].motion), 300 * f.crack_area, 1e-15);
  const physics::CuttingForce with_friction = physics::cutting_force(pieces, {300, 20});
  EXPECT_NEAR(with_friction.on_tool.x(), -3.0 - 0.2, 1e-12);
  EXPECT_NEAR(with_friction.on_tool.z(), 0.2, 1e-12);
}

TEST(CuttingResistance, AToughnessThatIsNotPositiveIsRefusedNamingTheField) {
  TempDir dir("incise_cutting_resistance_refusal");
  for (const std::string bad : {"0", "-5"}) {
    Json scene = Json::parse(R"({"name": "s", "bodies": [{"name": "b", "model": "efg",
      "generator": {"type": "box", "min": [0, 0, 0], "max": [0.01, 0.01, 0.01]}, "resolution": 0.005,
      "material": {"E": 1000, "nu": 0.3, "rho": 1000, "toughness": )" + bad + R"(}}],
      "solver": {"dt": 0.01, "duration": 0.1}})");
    try {
      parse_scene(scene.dump(), dir.path / "bad.json");
      ADD_FAILURE() << "toughness " << bad << " accepted";
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find("material.toughness"), std::string::npos) << e.what();
    }
  }
}
