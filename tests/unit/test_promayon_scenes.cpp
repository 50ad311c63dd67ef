// Promayon's models through the engine (engine/models/shape_memory_model.cpp,
// spring_network_model.cpp): the volume-control ramp scene holds V0(t) at every step, a free
// body conserves momentum under the seed's step, and bad settings are refused naming the field.
#include "engine/scene.hpp"
#include "engine/world.hpp"
#include "physics/promayon/promayon_body.hpp"
#include "physics/promayon/shape_memory.hpp"
#include "tests/unit/read_json.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>

using namespace incise::engine;
namespace physics = incise::physics;
using Json = nlohmann::json;

namespace {

using incise::testing::read_json;

const physics::PromayonBody& promayon(const World& world) {
  return dynamic_cast<const physics::PromayonBody&>(*world.bodies()[0].data.mechanics);
}

Json free_block(const std::string& model) {
  return Json::parse(R"({
    "name": "free",
    "bodies": [{
      "name": "block", "model": ")" + model + R"(",
      "generator": {"type": "box", "min": [0, 0, 0], "max": [0.02, 0.02, 0.02]},
      "resolution": 0.005,
      "material": {"E": 5000, "nu": 0.3, "rho": 1000},
      ")" + model + R"(": {"substeps": 10}
    }],
    "solver": {"dt": 0.0005, "duration": 0.05, "gravity": [0, 0, 0]}
  })");
}

std::string error_of(const std::function<void(Json&)>& mutate) {
  Json json = free_block("shape_memory");
  mutate(json);
  try {
    parse_scene(json.dump(), "promayon.json");
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(PromayonScenes, TheBladderRampHoldsTheVolumeAtEveryStep) {
  const std::string path = std::string(INCISE_SOURCE_DIR) + "/assets/scenes/shape_memory_bladder.json";
  const Scene scene = parse_scene(read_json(path).dump(), path);
  World world(scene, std::nullopt);
  const auto& body = promayon(world);
  ASSERT_TRUE(body.volume());
  EXPECT_NEAR(body.volume()->rest_volume, 9e-5, 1e-12);  // 50 x 45 x 40 mm
  double worst = 0;
  const auto steps = static_cast<int>(std::lround(scene.solver.duration / scene.solver.dt));
  for (int k = 1; k <= steps; ++k) {
    world.step();
    const double target = body.volume()->at(world.time());
    ASSERT_NEAR(body.last_volume_target(), target, 1e-15) << k;
    const double v = physics::closed_volume(world.bodies()[0].data.state.positions, body.volume()->triangles);
    worst = std::max(worst, std::abs(v - target) / target);
  }
  std::printf("bladder 90 -> 250 ml: worst relative volume error over %d steps %.2e (body's own count %.2e)\n", steps,
              worst, body.worst_volume_error());
  EXPECT_LE(worst, 1e-9);
  EXPECT_LE(body.worst_volume_error(), 1e-9);
  EXPECT_NEAR(body.last_volume(), 2.5e-4, 1e-13);
  EXPECT_TRUE(world.bodies()[0].data.state.positions.allFinite());
}

// A free body (no gravity, no support) pushed on one side: the internal forces sum to zero, so
// its momentum is what the push gave it (the per-atom damping -alpha m v takes it off
// uniformly; none here).
TEST(PromayonScenes, AFreeBodyKeepsItsMomentum) {
  for (const char* model : {"shape_memory", "spring_network"}) {
    SCOPED_TRACE(model);
    const Scene scene = parse_scene(free_block(model).dump(), "free.json");
    World world(scene, std::nullopt);
    Body& body = const_cast<Body&>(world.bodies()[0]);
    auto& state = body.data.state;
    const physics::Vector& m = body.data.mechanics->lumped_masses();
    state.velocities.setZero();
    for (int i = 0; i < 5; ++i) state.velocities[3 * i] = 0.05;  // a few atoms kicked along x
    const auto momentum = [&] {
      physics::Vec3 p = physics::Vec3::Zero();
      for (Eigen::Index i = 0; i < m.size(); ++i) p += m[i] * state.velocities.segment<3>(3 * i);
      return p;
    };
    const physics::Vec3 before = momentum();
    for (int k = 0; k < 60; ++k) world.step();
    EXPECT_LT((momentum() - before).norm(), 1e-12 * before.norm());
    EXPECT_TRUE(state.positions.allFinite());
  }
}

// The implicit option: implicit Euler, then the fixed atoms, the projection and the velocity
// correction; the volume follows its ramp all the same.
TEST(PromayonScenes, TheImplicitOptionProjectsTheVolumeToo) {
  Json json = free_block("shape_memory");
  json["bodies"][0]["shape_memory"] = {{"integrator", "implicit"}, {"volume", "exact"},
                                       {"volume_target", {{0, 8e-6}, {0.01, 1.2e-5}}}};
  json["bodies"][0]["fixed"] = {{{"min", {-1, -1, -1}}, {"max", {1, 1, 0.001}}}};
  const Scene scene = parse_scene(json.dump(), "implicit.json");
  World world(scene, std::nullopt);
  const auto& body = promayon(world);
  for (int k = 0; k < 40; ++k) world.step();
  EXPECT_LE(body.worst_volume_error(), 1e-9);
  EXPECT_NEAR(body.last_volume(), 1.2e-5, 1e-15);
  EXPECT_TRUE(world.bodies()[0].data.state.positions.allFinite());
  // The bottom face stayed where it was.
  const auto& x = world.bodies()[0].data.state.positions;
  const auto& rest = body.rest_positions();
  for (Eigen::Index i = 0; i < x.size() / 3; ++i) {
    if (rest[3 * i + 2] < 1e-9) {
      EXPECT_EQ(x.segment<3>(3 * i), rest.segment<3>(3 * i));
    }
  }
}

// A sub-step beyond the explicit limit (seed_step_limit) is refused when the world is built,
// naming the field and the substeps that would do.
TEST(PromayonScenes, ASubStepBeyondTheExplicitLimitIsRefused) {
  Json json = free_block("shape_memory");
  json["bodies"][0]["shape_memory"] = {{"substeps", 1}};
  const Scene scene = parse_scene(json.dump(), "fast.json");
  try {
    World world(scene, std::nullopt);
    FAIL() << "a 0.5 ms explicit step on 5 mm atoms was accepted";
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("body 'block': shape_memory.substeps: solver.dt / substeps = 0.0005 s is beyond the explicit step's limit"),
              std::string::npos)
        << message;
    EXPECT_NE(message.find("or more would do"), std::string::npos) << message;
  }
}

TEST(PromayonScenes, BadSettingsAreRefusedNamingTheField) {
  const std::vector<std::pair<std::function<void(Json&)>, std::string>> cases = {
      {[](Json& s) { s["bodies"][0]["shape_memory"] = {{"neighbourhood", "hex"}}; },
       "bodies[0].shape_memory.neighbourhood: 'hex' is not one of: vn1, moore"},
      {[](Json& s) { s["bodies"][0]["shape_memory"] = {{"volume", "penalty"}}; },
       "bodies[0].shape_memory.volume_stiffness: is required"},
      {[](Json& s) { s["bodies"][0]["shape_memory"] = {{"dashpot", 1}}; }, "bodies[0].shape_memory.dashpot: unknown key"},
      {[](Json& s) { s["bodies"][0]["shape_memory"] = {{"volume", "exact"}, {"volume_target", {{0, 1e-5}, {0, 2e-5}}}}; },
       "bodies[0].shape_memory.volume_target[1]: time must be finite, >= 0 and after the previous event's"},
      {[](Json& s) { s["bodies"][0]["shape_memory"] = {{"volume", "exact"}, {"volume_target", {{0, -1}}}}; },
       "bodies[0].shape_memory.volume_target[0]: volume must be in (0, 1000] m^3"},
      {[](Json& s) { s["bodies"][0]["shape_memory"] = {{"volume_target", {{0, 1e-5}}}}; },
       "bodies[0].shape_memory.volume: volume_target and volume_stiffness need volume"},
      {[](Json& s) { s["bodies"][0]["shape_memory"] = {{"substeps", 0}}; }, "bodies[0].shape_memory.substeps:"},
      {[](Json& s) { s["bodies"][0]["shape_memory"] = {{"stiffness", -5}}; }, "bodies[0].shape_memory.stiffness:"},
      {[](Json& s) { s["bodies"][0]["shape_memory"] = {{"integrator", "rk4"}}; },
       "bodies[0].shape_memory.integrator: 'rk4' is not one of: explicit, implicit"},
      {[](Json& s) { s["bodies"][0]["model"] = "fem"; s["bodies"][0]["shape_memory"] = Json::object(); },
       "bodies[0].shape_memory: only bodies with model 'shape_memory' take shape_memory settings"},
  };
  for (const auto& [mutate, expected] : cases) {
    SCOPED_TRACE(expected);
    const std::string message = error_of(mutate);
    EXPECT_NE(message.find(expected), std::string::npos) << message;
  }
}
