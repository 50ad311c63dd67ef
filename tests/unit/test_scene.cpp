// Scene validation: a good scene loads; each broken one is refused with a message that
// names the file and the field.
#include "engine/scene.hpp"

#include <gtest/gtest.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <functional>

using incise::engine::parse_scene;
using incise::engine::SceneError;
using Json = nlohmann::json;

namespace {

const std::filesystem::path kSceneFile = std::filesystem::path(INCISE_SOURCE_DIR) / "assets/scenes/test_scene.json";

Json good_scene() {
  return Json::parse(R"({
    "name": "unit",
    "bodies": [{
      "name": "block", "model": "fem",
      "generator": {"type": "box", "min": [0, 0, 0], "max": [0.04, 0.02, 0.02]},
      "resolution": 0.01,
      "material": {"E": 5000, "nu": 0.45, "rho": 1000},
      "fixed": [{"min": [-1, -1, -1], "max": [0.001, 1, 1]}]
    }],
    "solver": {"dt": 0.01, "duration": 0.1, "tolerance": 1e-6, "max_iterations": 100},
    "loads": [{"body": "block", "region": {"min": [0.039, -1, -1], "max": [1, 1, 1]},
               "events": [{"t": 0, "force": [0, 0, 0]}, {"t": 1, "force": [0, 0, -1]}]}],
    "render": {"capture_every": 5, "size": [320, 240]},
    "expect": {"nonfinite_events": {"max": 0}}
  })");
}

// Returns the error text of parsing the mutated scene (empty if it parsed).
std::string error_of(const std::function<void(Json&)>& mutate) {
  Json scene = good_scene();
  mutate(scene);
  try {
    parse_scene(scene.dump(), kSceneFile);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Scene, GoodSceneLoads) {
  auto scene = parse_scene(good_scene().dump(), kSceneFile);
  ASSERT_EQ(scene.bodies.size(), 1u);
  EXPECT_EQ(scene.bodies[0].material.poisson_ratio, 0.45);
  EXPECT_EQ(scene.render.width, 320);
  EXPECT_EQ(scene.loads[0].events.size(), 2u);
  ASSERT_EQ(scene.expect.size(), 1u);
  EXPECT_EQ(*scene.expect[0].max, 0.0);
}

// The smoother's degree is the key's when given, else the kind's: the current system's cycle
// takes a higher one than the rest system's (engine/scene.hpp).
TEST(Scene, TheMultigridDegreeIsTheKeysOrTheKinds) {
  auto degree_of = [](const char* preconditioner, int smoothing) {
    Json scene = good_scene();
    scene["solver"]["preconditioner"] = preconditioner;
    if (smoothing > 0) scene["solver"]["multigrid_smoothing"] = smoothing;
    return incise::engine::multigrid_smoothing_degree(parse_scene(scene.dump(), kSceneFile).solver);
  };
  EXPECT_EQ(degree_of("multigrid", 0), 2);
  EXPECT_EQ(degree_of("multigrid_current", 0), 4);
  EXPECT_EQ(degree_of("multigrid", 3), 3);
  EXPECT_EQ(degree_of("multigrid_current", 1), 1);
}

// The factor's latency is the key's when given, else the body's: an EFG body under the current
// system's cycle, whose smoother sees a cut at once, rebuilds its coarse factor less often
// (engine/scene.hpp).
TEST(Scene, TheFactorLatencyIsTheKeysOrTheBodys) {
  auto latency_of = [](const char* preconditioner, int latency, const char* model) {
    Json scene = good_scene();
    scene["solver"]["preconditioner"] = preconditioner;
    if (latency >= 0) scene["solver"]["preconditioner_latency"] = latency;
    return incise::engine::preconditioner_latency(parse_scene(scene.dump(), kSceneFile).solver, model);
  };
  EXPECT_EQ(latency_of("multigrid_current", -1, "efg"), 12);
  EXPECT_EQ(latency_of("multigrid_current", -1, "fem"), 4);  // falls back to the rest system's cycle
  EXPECT_EQ(latency_of("multigrid", -1, "efg"), 4);
  EXPECT_EQ(latency_of("warped_cholesky", -1, "efg"), 4);
  EXPECT_EQ(latency_of("multigrid_current", 0, "efg"), 0);
  EXPECT_EQ(latency_of("multigrid", 7, "fem"), 7);
}

// A path the system refuses outright (a name longer than NAME_MAX: fuzz_scene's finding) is
// refused like a missing file, naming the key, instead of std::filesystem's exception.
TEST(Scene, APathTooLongForTheSystemIsRefusedByName) {
  const std::string long_name(5000, 'x');
  const std::string trajectory = error_of([&](Json& s) { s["tool"]["trajectory"] = long_name + ".traj"; });
  EXPECT_NE(trajectory.find("tool.trajectory: file '"), std::string::npos) << trajectory;
  EXPECT_NE(trajectory.find("cannot be looked up"), std::string::npos) << trajectory;
  const std::string mesh = error_of([&](Json& s) { s["bodies"][0]["mesh"] = long_name + ".obj"; });
  EXPECT_NE(mesh.find("bodies[0].mesh: file '"), std::string::npos) << mesh;
  EXPECT_NE(mesh.find("cannot be looked up"), std::string::npos) << mesh;
}

struct BrokenCase {
  const char* name;
  std::function<void(Json&)> mutate;
  const char* expected;  // substring of the message
};

TEST(Scene, BrokenScenesAreRefusedWithTheFieldNamed) {
  const std::vector<BrokenCase> cases = {
      {"nu too large", [](Json& s) { s["bodies"][0]["material"]["nu"] = 0.7; },
       "bodies[0].material.nu: 0.7 must be in [0, 0.5)"},
      {"nu exactly 0.5", [](Json& s) { s["bodies"][0]["material"]["nu"] = 0.5; },
       "bodies[0].material.nu: 0.5 must be in [0, 0.5)"},
      {"negative E", [](Json& s) { s["bodies"][0]["material"]["E"] = -3; },
       "bodies[0].material.E: -3 must be in (0"},
      {"unknown key", [](Json& s) { s["bodies"][0]["colour"] = "red"; }, "bodies[0].colour: unknown key"},
      {"unknown top-level key", [](Json& s) { s["solvr"] = Json::object(); }, "solvr: unknown key"},
      {"missing solver", [](Json& s) { s.erase("solver"); }, "solver: is required"},
      {"dt as string", [](Json& s) { s["solver"]["dt"] = "fast"; }, "solver.dt: must be a number, not a string"},
      {"unknown model", [](Json& s) { s["bodies"][0]["model"] = "sph"; }, "bodies[0].model: 'sph' is not one of: fem, efg, mass_spring, constraint_particles, shape_memory, spring_network"},
      {"efg settings on a fem body", [](Json& s) { s["bodies"][0]["efg"] = {{"neighbours", 8}}; },
       "bodies[0].efg: only bodies with model 'efg' take efg settings"},
      {"efg with 6 neighbours", [](Json& s) {
         s["bodies"][0]["model"] = "efg";
         s["bodies"][0]["efg"] = {{"neighbours", 6}};
       }, "bodies[0].efg.neighbours: must be 4 or 8"},
      {"efg support factor 1", [](Json& s) {
         s["bodies"][0]["model"] = "efg";
         s["bodies"][0]["efg"] = {{"support_factor", 1.0}};
       }, "bodies[0].efg.support_factor: 1 must be in (1, 10]"},
      {"cuttable fem body", [](Json& s) { s["bodies"][0]["cuttable"] = true; },
       "bodies[0].cuttable: only 'efg' bodies can be cut"},
      {"blade without edge", [](Json& s) {
         s["tool"] = {{"shape", "blade"}, {"trajectory", "../trajectories/probe_organ.traj"}};
       }, "tool.edge: is required"},
      {"blade edge of one point", [](Json& s) {
         s["tool"] = {{"shape", "blade"}, {"edge", {{0, 0, 0}}}, {"trajectory", "../trajectories/probe_organ.traj"}};
       }, "tool.edge: must be an array of 2 to 64 points"},
      {"blade edge repeats a point", [](Json& s) {
         s["tool"] = {{"shape", "blade"}, {"edge", {{0, 0, 0}, {0, 0, 0}}}, {"trajectory", "../trajectories/probe_organ.traj"}};
       }, "tool.edge[1]: repeats the point before it"},
      {"efg unknown setting", [](Json& s) {
         s["bodies"][0]["model"] = "efg";
         s["bodies"][0]["efg"] = {{"kernel", "gauss"}};
       }, "bodies[0].efg.kernel: unknown key"},
      {"unknown backend", [](Json& s) { s["solver"]["backend"] = "cuda"; }, "solver.backend: 'cuda' is not one of: cpu, gpu"},
      {"unknown multigrid precision", [](Json& s) { s["solver"]["multigrid_precision"] = "half"; },
       "solver.multigrid_precision: 'half' is not one of: double, float"},
      {"no bodies", [](Json& s) { s["bodies"] = Json::array(); }, "bodies: must be a non-empty array"},
      {"mesh and generator", [](Json& s) { s["bodies"][0]["mesh"] = "../meshes/cube.obj"; },
       "bodies[0]: give either 'mesh' or 'generator', not both"},
      {"missing mesh file", [](Json& s) {
         s["bodies"][0].erase("generator");
         s["bodies"][0]["mesh"] = "no/such/organ.obj";
       }, "bodies[0].mesh: file '"},
      {"inverted fixed box", [](Json& s) { s["bodies"][0]["fixed"][0]["min"] = {2, 0, 0}; },
       "bodies[0].fixed[0]: min[0] 2 is greater than max[0] 0.001"},
      {"point with two numbers", [](Json& s) { s["solver"]["gravity"] = {0, -9.81}; },
       "solver.gravity: must be an array of 3 numbers"},
      {"load on unknown body", [](Json& s) { s["loads"][0]["body"] = "liver"; },
       "loads[0].body: no body is named 'liver'"},
      {"load times decrease", [](Json& s) { s["loads"][0]["events"][1]["t"] = 0; },
       "loads[0].events[1].t: times must increase"},
      {"render size", [](Json& s) { s["render"]["size"] = {10, 240}; }, "render.size: must be [width, height]"},
      {"negative capture", [](Json& s) { s["render"]["capture_every"] = -1; }, "render.capture_every: -1 must be in [0"},
      {"missing trajectory file", [](Json& s) {
         s["tool"] = {{"shape", "sphere"}, {"radius", 0.005}, {"trajectory", "nowhere.traj"}};
       }, "tool.trajectory: file '"},
      {"capsule without length", [](Json& s) {
         s["tool"] = {{"shape", "capsule"}, {"radius", 0.005}, {"trajectory", "../trajectories/probe_organ.traj"}};
       }, "tool.length: is required"},
      {"expect without bounds", [](Json& s) { s["expect"]["steps"] = Json::object(); }, "expect.steps: needs 'min' or 'max'"},
      {"duplicate body names", [](Json& s) { s["bodies"].push_back(s["bodies"][0]); },
       "bodies[1].name: 'block' is used twice"},
      {"non-integer iterations", [](Json& s) { s["solver"]["max_iterations"] = 2.5; },
       "solver.max_iterations: must be an integer, not 2.5"},
      // Beyond long long, the value once wrapped to -1 and the message quoted that.
      {"iterations beyond 64 bits", [](Json& s) { s["solver"]["max_iterations"] = 18446744073709551615ull; },
       "solver.max_iterations: 18446744073709551615 must be in [1, 100000]"},
      {"flag as a number", [](Json& s) { s["render"]["floor"] = 1; }, "render.floor: must be true or false, not 1"},
      {"name as an array", [](Json& s) { s["name"] = {1, 2}; }, "name: must be a string, not an array of 2"},
      {"body as null", [](Json& s) { s["bodies"][0] = nullptr; }, "bodies[0]: must be an object, not null"},
      {"point with two numbers, named", [](Json& s) { s["solver"]["gravity"] = {0, -9.81}; },
       "solver.gravity: must be an array of 3 numbers, not an array of 2"},
      {"resolution needing petabytes", [](Json& s) {
         s["bodies"][0]["generator"]["max"] = {1, 1, 1};
         s["bodies"][0]["resolution"] = 1e-4;
       }, "bodies[0].resolution: 0.0001 m over the body's 1 x 1 x 1 m bounding box is 1e+12 cells, about 4.1 PB"},
      {"mesh_up not an axis", [](Json& s) {
         s["bodies"][0].erase("generator");
         s["bodies"][0]["mesh"] = "../meshes/lobe_tets.msh";
         s["bodies"][0]["mesh_up"] = "up";
       }, "bodies[0].mesh_up: 'up' is not one of: x, y, z, -x, -y, -z"},
      {"mesh_up without a mesh", [](Json& s) { s["bodies"][0]["mesh_up"] = "y"; },
       "bodies[0].mesh_up: only a body with a 'mesh' takes mesh_up"},
      {"surface mesh without resolution", [](Json& s) {
         s["bodies"][0].erase("generator");
         s["bodies"][0].erase("resolution");
         s["bodies"][0]["mesh"] = "../meshes/kidney.obj";
       }, "bodies[0].resolution: is required"},
  };
  ASSERT_GE(cases.size(), 10u);
  for (const auto& c : cases) {
    std::string message = error_of(c.mutate);
    SCOPED_TRACE(c.name);
    ASSERT_FALSE(message.empty()) << "accepted a broken scene";
    EXPECT_NE(message.find(c.expected), std::string::npos) << "message was:\n" << message;
    EXPECT_NE(message.find("test_scene.json"), std::string::npos) << "the file is not named:\n" << message;
  }
}

TEST(Scene, AllErrorsOfAFileAreListedTogether) {
  std::string message = error_of([](Json& s) {
    s["bodies"][0]["material"]["nu"] = 0.7;
    s["solver"]["dt"] = -1;
    s["typo"] = 1;
  });
  EXPECT_NE(message.find("3 errors"), std::string::npos) << message;
  EXPECT_NE(message.find("bodies[0].material.nu"), std::string::npos);
  EXPECT_NE(message.find("solver.dt"), std::string::npos);
  EXPECT_NE(message.find("typo: unknown key"), std::string::npos);
}

TEST(Scene, InvalidJsonNamesTheLine) {
  try {
    parse_scene("{\n  \"name\": \"x\",\n  \"bodies\": [\n}", kSceneFile);
    FAIL() << "accepted invalid JSON";
  } catch (const SceneError& e) {
    std::string m = e.what();
    EXPECT_NE(m.find("not valid JSON"), std::string::npos) << m;
    EXPECT_NE(m.find("line 4"), std::string::npos) << m;
  }
}

// nlohmann throws out_of_range for a number beyond a double with neither line nor key; the
// scene reader places it.
TEST(Scene, NumberOutOfRangeNamesTheFieldAndTheLine) {
  const std::string text = "{\n  \"name\": \"x\",\n  \"solver\": {\"dt\": 1e400}\n}";
  try {
    parse_scene(text, kSceneFile);
    FAIL() << "accepted 1e400";
  } catch (const SceneError& e) {
    ASSERT_EQ(e.errors().size(), 1u);
    EXPECT_EQ(e.errors()[0], "solver.dt: number 1e400 is out of range (line 3, column 20)");
    EXPECT_NE(std::string(e.what()).find("test_scene.json"), std::string::npos) << e.what();
  }
}

TEST(Scene, SyntaxErrorNamesTheElementBeingRead) {
  try {
    parse_scene("{\"name\": \"x\", \"bodies\": [{}, {\"name\": tru}]}", kSceneFile);
    FAIL();
  } catch (const SceneError& e) {
    ASSERT_EQ(e.errors().size(), 1u);
    const std::string& m = e.errors()[0];
    EXPECT_EQ(m.rfind("line 1, column ", 0), 0u) << m;
    EXPECT_NE(m.find("not valid JSON"), std::string::npos) << m;
    EXPECT_NE(m.find("(near bodies[1].name)"), std::string::npos) << m;
  }
}

TEST(Scene, NestingBeyondTheLimitIsRefusedWhereItStarts) {
  const std::string deep = std::string(40, '[') + std::string(40, ']');
  try {
    parse_scene("{\"name\": \"x\",\n \"bodies\": " + deep + "}", kSceneFile);
    FAIL();
  } catch (const SceneError& e) {
    ASSERT_EQ(e.errors().size(), 1u);
    // The root object is level 1, so the 32nd bracket (column 12 + 31) is level 33.
    EXPECT_EQ(e.errors()[0], "line 2, column 43: nested deeper than 32 levels (a scene needs a handful)");
  }
  // Brackets inside strings are text, not nesting.
  EXPECT_THROW(
      try { parse_scene("{\"name\": \"" + deep + "\"}", kSceneFile); } catch (const SceneError& e) {
        EXPECT_EQ(std::string(e.what()).find("nested"), std::string::npos) << e.what();
        throw;
      },
      SceneError);
}

TEST(Scene, SizeEstimateRefusesWhatTheMachineLacks) {
  incise::engine::BodySpec body;
  body.resolution = 0.01;
  const incise::engine::Point lo{0, 0, 0}, hi{0.1, 0.2, 0.3};  // 10 x 20 x 30 cells
  EXPECT_DOUBLE_EQ(incise::engine::estimated_bytes(body, lo, hi), 6000 * 4096.0);
  EXPECT_FALSE(incise::engine::size_problem(body, lo, hi, 6000 * 4096.0 + 1));
  const auto problem = incise::engine::size_problem(body, lo, hi, 1e6);
  ASSERT_TRUE(problem);
  EXPECT_EQ(*problem, "0.01 m over the body's 0.1 x 0.2 x 0.3 m bounding box is 6e+03 cells, about 24.6 MB to "
                      "build; this machine has 1 MB (coarsen the resolution)");
  body.efg.surface_resolution = 0.005;  // 8 times the cells, at a smaller cost each
  EXPECT_DOUBLE_EQ(incise::engine::estimated_bytes(body, lo, hi), 6000 * 4096.0 + 48000 * 512.0);
}

TEST(Scene, MissingAndEmptyFilesAreErrors) {
  EXPECT_THROW(incise::engine::load_scene("no/such/scene.json"), SceneError);
  auto empty = std::filesystem::temp_directory_path() / ("incise_empty_scene_" + std::to_string(::getpid()) + ".json");
  { std::ofstream(empty).flush(); }
  try {
    incise::engine::load_scene(empty);
    FAIL();
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("empty"), std::string::npos);
  }
  std::filesystem::remove(empty);
}

TEST(Scene, ShippedScenesAreValid) {
  const auto dir = std::filesystem::path(INCISE_SOURCE_DIR) / "assets/scenes";
  int count = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() != ".json") continue;
    SCOPED_TRACE(entry.path().string());
    EXPECT_NO_THROW(incise::engine::load_scene(entry.path()));
    ++count;
  }
  EXPECT_GE(count, 1);
}

// A tetrahedral mesh is the discretisation: no resolution needed (its mean edge length stands
// in), and a bad one is refused while the scene is read, naming the field, the file and the element.
TEST(Scene, TetrahedralMeshNeedsNoResolutionAndIsCheckedOnReading) {
  Json scene = good_scene();
  scene["bodies"][0].erase("generator");
  scene["bodies"][0].erase("resolution");
  scene["bodies"][0]["mesh"] = "../meshes/lobe_tets.vtk";
  scene["bodies"][0]["mesh_scale"] = 0.001;
  scene["bodies"][0]["mesh_up"] = "y";
  const auto parsed = parse_scene(scene.dump(), kSceneFile);
  EXPECT_EQ(parsed.bodies[0].mesh_up, "y");
  // 10 mm cells: Kuhn edges of 10 to 17 mm.
  EXPECT_GT(parsed.bodies[0].resolution, 0.008);
  EXPECT_LT(parsed.bodies[0].resolution, 0.03);

  const auto bad = std::filesystem::temp_directory_path() / (std::to_string(::getpid()) + "_hex.vtk");
  std::ofstream(bad) << "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 8 float\n"
                        "0 0 0 1 0 0 1 1 0 0 1 0 0 0 1 1 0 1 1 1 1 0 1 1\nCELLS 1 9\n8 0 1 2 3 4 5 6 7\n"
                        "CELL_TYPES 1\n12\n";
  scene["bodies"][0]["mesh"] = bad.string();
  try {
    parse_scene(scene.dump(), kSceneFile);
    ADD_FAILURE() << "a hexahedral mesh was accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("bodies[0].mesh: " + bad.string() + ": cell 0 is a hexahedron (type 12)"),
              std::string::npos)
        << e.what();
  }
  std::filesystem::remove(bad);
}
