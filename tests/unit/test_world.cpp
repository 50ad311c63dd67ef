// The World and the headless replay: invariants of the assembled engine.
#include "engine/replay.hpp"
#include "engine/scene.hpp"
#include "engine/trajectory.hpp"
#include "engine/trajectory_synth.hpp"
#include "engine/world.hpp"
#include "tests/unit/temp_dir.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <filesystem>
#include <string>
#include <vector>


using namespace incise::engine;
namespace physics = incise::physics;
using Json = nlohmann::json;
using incise::testing::TempDir;

namespace {

// A 4 x 2 x 2 cm block clamped at x = 0 and a sphere probe pressing its top.
Json block_scene(bool with_tool) {
  Json s = Json::parse(R"({
    "name": "block",
    "bodies": [{
      "name": "block", "model": "fem",
      "generator": {"type": "box", "min": [0, -0.01, 0], "max": [0.04, 0.01, 0.02]},
      "resolution": 0.005,
      "material": {"E": 20000, "nu": 0.4, "rho": 1000},
      "fixed": [{"min": [-1, -1, -1], "max": [0.0001, 1, 1]}],
      "damping": {"mass": 1.0}
    }],
    "solver": {"dt": 0.01, "duration": 0.3, "tolerance": 1e-8, "max_iterations": 500}
  })");
  if (with_tool)
    s["tool"] = {{"shape", "sphere"}, {"radius", 0.004}, {"stiffness", 2000}, {"trajectory", "poke.traj"}};
  return s;
}

Scene write_scene(const TempDir& dir, const Json& json) {
  PokeSpec poke;
  poke.approach_point = {0.03, 0, 0.05};
  poke.contact_point = {0.03, 0, 0.024};  // the sphere's centre when its bottom touches the top
  poke.depth = 0.004;
  poke.stroke = {-0.01, 0, 0};
  poke.approach_seconds = 0.05;
  poke.press_seconds = 0.1;
  poke.hold_seconds = 0.05;
  poke.stroke_seconds = 0.1;
  poke.release_seconds = 0.05;
  write_trajectory(dir.path / "poke.traj", synthesize_poke(poke));
  auto file = dir.path / "scene.json";
  return parse_scene(json.dump(), file);
}

}  // namespace

TEST(World, ReplayIsDeterministicAndTheHashSeesChanges) {
  TempDir dir("incise_world_determinism");
  Scene scene = write_scene(dir, block_scene(true));
  ReplayOptions options;
  options.out_dir = dir.path / "a";
  auto a = run_replay(scene, options);
  options.out_dir = dir.path / "b";
  auto b = run_replay(scene, options);
  ASSERT_TRUE(a.ok);
  ASSERT_TRUE(b.ok);
  EXPECT_EQ(a.metrics["state_hash"], b.metrics["state_hash"]);
  EXPECT_EQ(a.metrics["steps"], 30);
  EXPECT_TRUE(std::filesystem::exists(dir.path / "a" / "metrics.json"));

  Json softer = block_scene(true);
  softer["bodies"][0]["material"]["E"] = 19999;
  Scene changed = write_scene(dir, softer);
  options.out_dir = dir.path / "c";
  auto c = run_replay(changed, options);
  EXPECT_NE(a.metrics["state_hash"], c.metrics["state_hash"]);
}

TEST(World, BodiesSayWhereTheirConstructionWent) {
  TempDir dir("incise_world_build_ms");
  const World world(write_scene(dir, block_scene(false)), std::nullopt);
  const BuildTimes& t = world.bodies()[0].build_ms;
  EXPECT_GT(t.volume, 0);  // the tetrahedra were made and timed
  for (const double part : {t.shape, t.volume, t.surface, t.cut, t.settle}) EXPECT_GE(part, 0);
  // The parts are disjoint spans of the whole.
  EXPECT_LE(t.shape + t.volume + t.surface + t.cut + t.settle, t.total);
  EXPECT_EQ(World(world).bodies()[0].build_ms.total, t.total);  // a copy was built the same way
}

TEST(World, FreeBodyFallsWithGravityExactly) {
  // No support, no tool: internal forces cancel, so the centroid velocity after n implicit
  // Euler steps is exactly g t, whatever the elasticity does.
  TempDir dir("incise_world_fall");
  Json json = block_scene(false);
  json["bodies"][0].erase("fixed");
  json["bodies"][0].erase("damping");
  Scene scene = write_scene(dir, json);
  World world(scene, std::nullopt);
  for (int k = 0; k < 20; ++k) world.step();
  const auto& body = world.bodies()[0];
  const auto& m = body.data.mechanics->lumped_masses();
  double momentum_z = 0, mass = 0;
  for (int i = 0; i < body.data.mechanics->node_count(); ++i) {
    momentum_z += m[i] * body.data.state.velocities[3 * i + 2];
    mass += m[i];
  }
  EXPECT_NEAR(momentum_z / mass, -9.81 * 0.2, 1e-6);
}

TEST(World, ProbePushesTheTissueAndFeelsItBack) {
  TempDir dir("incise_world_probe");
  Scene scene = write_scene(dir, block_scene(true));
  Trajectory trajectory = read_trajectory(dir.path / "poke.traj");
  World world(scene, trajectory);
  double deepest_top = 1;
  double max_up_force = 0;
  for (int k = 0; k < 20; ++k) {
    auto stats = world.step();
    max_up_force = std::max(max_up_force, stats.tool_force[2]);
    const auto& x = world.bodies()[0].data.state.positions;
    // The top node under the probe's path moves down.
    for (int i = 0; i < world.bodies()[0].data.mechanics->node_count(); ++i) {
      const auto& rest = world.bodies()[0].data.mechanics->rest_positions();
      if (std::abs(rest[3 * i] - 0.03) < 1e-9 && std::abs(rest[3 * i + 1]) < 1e-9 &&
          std::abs(rest[3 * i + 2] - 0.02) < 1e-9)
        deepest_top = std::min(deepest_top, x[3 * i + 2]);
    }
  }
  EXPECT_LT(deepest_top, 0.02 - 0.001);  // pressed at least 1 mm
  EXPECT_GT(max_up_force, 0.0);          // the tissue pushes the tool up
}

TEST(World, LoadsAreInterpolatedLinearlyAndHeld) {
  LoadSpec load;
  load.events = {{0.0, {0, 0, 0}}, {1.0, {0, 0, -2}}, {3.0, {4, 0, -2}}};
  EXPECT_DOUBLE_EQ(load_force_at(load, -1)[2], 0);
  EXPECT_DOUBLE_EQ(load_force_at(load, 0.25)[2], -0.5);
  EXPECT_DOUBLE_EQ(load_force_at(load, 2.0)[0], 2.0);
  EXPECT_DOUBLE_EQ(load_force_at(load, 10)[0], 4.0);
}

TEST(World, ExpectationsAreChecked) {
  Json metrics = {{"nonfinite_events", 0}, {"positions_digest", {{"centroid", {1.0, 2.0, 3.0}}}}};
  Scene scene;
  scene.expect = {{"nonfinite_events", std::nullopt, 0.0},
                  {"positions_digest.centroid.2", 2.5, 3.5},
                  {"positions_digest.centroid.0", 1.5, std::nullopt},
                  {"no.such.metric", 0.0, std::nullopt}};
  auto results = check_expectations(scene, metrics);
  ASSERT_EQ(results.size(), 4u);
  EXPECT_TRUE(results[0].passed);
  EXPECT_TRUE(results[1].passed);
  EXPECT_FALSE(results[2].passed);
  EXPECT_FALSE(results[3].passed);
  EXPECT_FALSE(results[3].value.has_value());
}

TEST(World, GuardsAreCountedAndLoggedWithStepAndBody) {
  TempDir dir("incise_world_guards");
  Json json = block_scene(true);
  json["solver"]["max_iterations"] = 2;  // far too few: CG cannot converge
  json["solver"]["tolerance"] = 1e-12;
  Scene scene = write_scene(dir, json);
  World world(scene, read_trajectory(dir.path / "poke.traj"));
  for (int k = 0; k < 5; ++k) world.step();
  EXPECT_EQ(world.guard_counts().cg_not_converged, 5);
  ASSERT_FALSE(world.guard_events().empty());
  const auto& first = world.guard_events().front();
  EXPECT_EQ(first.step, 1u);
  EXPECT_EQ(first.body, "block");
  EXPECT_EQ(first.kind, "cg_not_converged");
  EXPECT_NE(first.detail.find("after 2 iterations"), std::string::npos) << first.detail;
}

TEST(World, EnergyWatchdogStaysQuietOnAHealthyRun) {
  TempDir dir("incise_world_quiet");
  Scene scene = write_scene(dir, block_scene(true));
  World world(scene, read_trajectory(dir.path / "poke.traj"));
  for (int k = 0; k < 30; ++k) world.step();
  EXPECT_EQ(world.guard_counts().energy_growth, 0);
  EXPECT_EQ(world.guard_counts().nonfinite_retries, 0);
  EXPECT_EQ(world.guard_counts().cg_not_converged, 0);
}

// The meshless body in the engine: the B1 cantilever settled by the static solve, its
// embedded render surface, the probe pushing it through that surface.
namespace {

Json efg_beam_scene() {
  return Json::parse(R"({
    "name": "efg_b1",
    "bodies": [{
      "name": "beam", "model": "efg",
      "generator": {"type": "box", "min": [0, -0.01, -0.01], "max": [0.2, 0.01, 0.01]},
      "resolution": 0.005,
      "efg": {"neighbours": 8, "surface_resolution": 0.005},
      "material": {"E": 1e7, "nu": 0.3, "rho": 1000},
      "fixed": [{"min": [-1, -1, -1], "max": [0.0001, 1, 1]}]
    }],
    "solver": {"dt": 0.01, "duration": 0.1, "start": "settled", "tolerance": 1e-8, "max_iterations": 2000}
  })");
}

}  // namespace

TEST(World, EfgBeamSettlesAtTheCantileverDeflectionAndStaysThere) {
  TempDir dir("incise_world_efg_beam");
  Scene scene = parse_scene(efg_beam_scene().dump(), dir.path / "scene.json");
  World world(scene, std::nullopt);
  const Body& body = world.bodies()[0];
  ASSERT_TRUE(body.data.embedding.has_value());
  // Mean z displacement of the tip face's surface vertices (x = L), against the converged
  // 10-node tetrahedra of B1 (5.888 mm, tests/unit/test_fem_cantilever.cpp; beam theory 5.947).
  const auto tip_deflection = [&] {
    physics::Vector rest;
    physics::CorotationalEfg::surface_positions(*body.data.embedding, body.data.mechanics->rest_positions(), rest);
    double sum = 0;
    int count = 0;
    for (int v = 0; v < body.data.embedding->vertex_count(); ++v) {
      if (std::abs(rest[3 * v] - 0.2) > 1e-9) continue;
      sum += body.data.surface_positions[3 * v + 2] - rest[3 * v + 2];
      ++count;
    }
    EXPECT_GT(count, 8);
    return -sum / count;
  };
  const double settled = tip_deflection();
  std::printf("EFG B1 in the engine: settled tip %.4f mm\n", 1e3 * settled);
  EXPECT_NEAR(settled, 5.888e-3, 0.03 * 5.888e-3);
  // Starting at equilibrium, the dynamic steps keep it there (gravity balances elasticity).
  for (int k = 0; k < 10; ++k) world.step();
  EXPECT_NEAR(tip_deflection(), settled, 0.002 * settled);
  // The clamped face does not move.
  for (int i = 0; i < body.data.mechanics->node_count(); ++i)
    if (body.data.fixed[i]) {
      EXPECT_EQ(body.data.state.positions.segment<3>(3 * i), body.data.mechanics->rest_positions().segment<3>(3 * i));
    }
}

TEST(World, ProbePushesAnEfgBodyThroughItsEmbeddedSurface) {
  TempDir dir("incise_world_efg_probe");
  Json json = block_scene(true);
  json["bodies"][0]["model"] = "efg";
  json["bodies"][0]["resolution"] = 0.0025;
  json["bodies"][0]["efg"] = {{"support_factor", 1.2}};
  Scene scene = write_scene(dir, json);
  Trajectory trajectory = read_trajectory(dir.path / "poke.traj");
  World world(scene, trajectory);
  const Body& body = world.bodies()[0];
  // The surface vertex at the top of the probe's path (rest (0.03, 0, 0.02)).
  int under = -1;
  {
    physics::Vector rest;
    physics::CorotationalEfg::surface_positions(*body.data.embedding, body.data.mechanics->rest_positions(), rest);
    double best = 1;
    for (int v = 0; v < body.data.embedding->vertex_count(); ++v) {
      const double d = (rest.segment<3>(3 * v) - physics::Vec3(0.03, 0, 0.02)).norm();
      if (d < best) best = d, under = v;
    }
    ASSERT_LT(best, 1e-6);
  }
  double deepest = 1, max_up_force = 0;
  for (int k = 0; k < 20; ++k) {
    auto stats = world.step();
    max_up_force = std::max(max_up_force, stats.tool_force[2]);
    deepest = std::min(deepest, body.data.surface_positions[3 * under + 2]);
  }
  EXPECT_LT(deepest, 0.02 - 0.001);  // the seen surface is pressed at least 1 mm
  EXPECT_GT(max_up_force, 0.0);      // and pushes the tool back
}

// A tetrahedral mesh from a file is the fem body's discretisation as it is (issue 32).
TEST(World, TetrahedralMeshFileIsTheFemBody) {
  TempDir dir("incise_world_tet_mesh");
  Json json = block_scene(false);
  json["bodies"][0].erase("generator");
  json["bodies"][0].erase("resolution");
  json["bodies"][0]["mesh"] = (std::filesystem::path(INCISE_SOURCE_DIR) / "assets/meshes/lobe_tets_v2.msh").string();
  json["bodies"][0]["mesh_scale"] = 0.001;
  json["bodies"][0]["mesh_up"] = "y";
  json["bodies"][0]["fixed"] = Json::parse(R"([{"min": [-1, -1, -1], "max": [1, 1, 0.002]}])");
  const World world(write_scene(dir, json), std::nullopt);
  const auto& body = world.bodies()[0];
  EXPECT_EQ(body.data.mechanics->node_count(), 646);
  EXPECT_EQ(body.model->elements, 2454u);
  EXPECT_EQ(body.data.surface.size(), 828u);  // the boundary the file's triangles were
}

// A surface thinner than the resolution everywhere (a 1 mm slab and a speck, at 5 mm) fills
// nothing: refused with its size and the resolution, for either model.
TEST(World, ASurfaceWithNoInteriorAtTheResolutionIsRefused) {
  TempDir dir("incise_world_thin_mesh");
  std::ofstream(dir.path / "slab.obj") << "v 0 0 0\nv 0.02 0 0\nv 0.02 0.02 0\nv 0 0.02 0\n"
                                          "v 0 0 0.001\nv 0.02 0 0.001\nv 0.02 0.02 0.001\nv 0 0.02 0.001\n"
                                          "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\n"
                                          "f 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n"
                                          // A speck 10 mm above, so that the box is deeper than one cell.
                                          "v 0.01 0.01 0.01\nv 0.0105 0.01 0.01\nv 0.01 0.0105 0.01\nv 0.01 0.01 0.0105\n"
                                          "f 9 11 10\nf 9 10 12\nf 9 12 11\nf 10 11 12\n";
  for (const char* model : {"fem", "efg", "mass_spring"}) {
    Json json = block_scene(false);
    json["bodies"][0].erase("generator");
    json["bodies"][0]["model"] = model;
    json["bodies"][0]["mesh"] = "slab.obj";
    json["bodies"][0]["resolution"] = 0.005;
    try {
      const World world(write_scene(dir, json), std::nullopt);
      ADD_FAILURE() << model << ": a 1 mm slab was filled at 5 mm";
    } catch (const std::exception& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("body 'block': mesh 'slab.obj' (0.02 x 0.02 x 0.0105 m) has no interior at resolution 0.005 m"),
                std::string::npos)
          << model << ": " << message;
    }
  }
}

// A cuttable EFG body with `base_surface: mesh` cuts the file's own triangles (a thin edge keeps
// the mesh's shape rather than a voxel boundary faired onto it): the body's first surface is
// the file's, its vertices embedded where the file has them. Without the key, the voxel
// boundary at resolution / 2: more triangles than the file's 12.
TEST(World, ACuttableBodysBaseSurfaceCanBeTheMeshItself) {
  TempDir dir("incise_world_base_surface");
  const std::vector<std::array<int, 3>> outward = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                                                   {1, 2, 6}, {1, 6, 5}, {2, 3, 7}, {2, 7, 6}, {3, 0, 4}, {3, 4, 7}};
  {
    std::ofstream obj(dir.path / "cube.obj");
    obj << "v 0 0 0\nv 0.02 0 0\nv 0.02 0.02 0\nv 0 0.02 0\n"
           "v 0 0 0.02\nv 0.02 0 0.02\nv 0.02 0.02 0.02\nv 0 0.02 0.02\n";
    for (const auto& t : outward) obj << "f " << t[0] + 1 << " " << t[1] + 1 << " " << t[2] + 1 << "\n";
  }
  for (const bool from_mesh : {true, false}) {
    Json json = block_scene(false);
    json["bodies"][0].erase("generator");
    json["bodies"][0]["model"] = "efg";
    json["bodies"][0]["cuttable"] = true;
    json["bodies"][0]["mesh"] = "cube.obj";
    if (from_mesh) json["bodies"][0]["efg"] = {{"base_surface", "mesh"}};
    const World world(write_scene(dir, json), std::nullopt);
    const auto& body = world.bodies()[0];
    if (!from_mesh) {
      EXPECT_GT(body.data.surface.size(), 12u) << "the voxel boundary";
      continue;
    }
    // The reader numbers an OBJ's vertices in the order the faces first use them: the
    // triangles are compared corner by corner, where they sit.
    ASSERT_EQ(body.data.surface.size(), outward.size());
    ASSERT_EQ(body.data.surface_positions.size(), 24);
    for (std::size_t t = 0; t < outward.size(); ++t)
      for (int k = 0; k < 3; ++k) {
        const int v = outward[t][k];
        const physics::Vec3 file((v == 1 || v == 2 || v == 5 || v == 6) ? 0.02 : 0, (v % 4 >= 2) ? 0.02 : 0, v >= 4 ? 0.02 : 0);
        // The embedding's weights reproduce a rest point to rounding (sums over its particles).
        EXPECT_LT((body.data.surface_positions.segment<3>(3 * body.data.surface[t][k]) - file).norm(), 1e-8)
            << "triangle " << t << ", corner " << k;
      }
  }
}

// Baudet's mass-spring model through the world: a free block falls at exactly g (its springs
// and dashpots are internal), the probe presses it and feels it, and a voxelised ellipsoid
// starts settled under gravity.
TEST(World, MassSpringBodiesFallArePressedAndSettle) {
  TempDir dir("incise_world_mass_spring");
  Json json = block_scene(false);
  json["bodies"][0]["model"] = "mass_spring";
  json["bodies"][0].erase("fixed");
  json["bodies"][0].erase("damping");
  {
    World world(write_scene(dir, json), std::nullopt);
    for (int k = 0; k < 20; ++k) world.step();
    const auto& body = world.bodies()[0];
    EXPECT_EQ(body.model->elements, 8u * 4u * 4u);
    const auto& m = body.data.mechanics->lumped_masses();
    double momentum_z = 0, mass = 0;
    for (int i = 0; i < body.data.mechanics->node_count(); ++i) momentum_z += m[i] * body.data.state.velocities[3 * i + 2], mass += m[i];
    EXPECT_NEAR(mass, 1000 * 0.04 * 0.02 * 0.02, 1e-12);
    EXPECT_NEAR(momentum_z / mass, -9.81 * 0.2, 1e-6);
  }
  json = block_scene(true);
  json["bodies"][0]["model"] = "mass_spring";
  {
    World world(write_scene(dir, json), read_trajectory(dir.path / "poke.traj"));
    double max_up_force = 0;
    for (int k = 0; k < 20; ++k) max_up_force = std::max(max_up_force, world.step().tool_force[2]);
    EXPECT_GT(max_up_force, 0.01);
  }
  json = block_scene(false);
  json["bodies"][0]["model"] = "mass_spring";
  json["bodies"][0]["generator"] = Json::parse(R"({"type": "ellipsoid", "center": [0.02, 0, 0.01], "radii": [0.02, 0.01, 0.01]})");
  json["bodies"][0]["fixed"] = Json::parse(R"([{"min": [-1, -1, -1], "max": [0.006, 1, 1]}])");
  json["bodies"][0]["material"]["E"] = 2e6;  // small strain, where the linear settle holds
  json["solver"]["start"] = "settled";
  World world(write_scene(dir, json), std::nullopt);
  const auto& body = world.bodies()[0];
  EXPECT_GT(body.model->elements, 20u);
  // Settled: the first step barely moves it (the static solve is linear, the step nonlinear).
  const physics::Vector start = body.data.state.positions;
  EXPECT_GT((start - body.data.mechanics->rest_positions()).cwiseAbs().maxCoeff(), 0);
  world.step();
  EXPECT_LT((world.bodies()[0].data.state.positions - start).cwiseAbs().maxCoeff(),
            0.01 * (start - body.data.mechanics->rest_positions()).cwiseAbs().maxCoeff());
}
