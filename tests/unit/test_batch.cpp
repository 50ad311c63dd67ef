// incise batch's manifest reader, overrides and shards (tests/batch/ runs the command end to end).
#include "batch/manifest.hpp"
#include "batch/overrides.hpp"
#include "batch/runner.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <fstream>

namespace incise::batch {
namespace {

const Json kScene = Json::parse(R"({"name": "s", "bodies": [{"material": {"E": 1, "nu": 0.3}}], "solver": {"dt": 0.01}})");

TEST(Overrides, SetsNestedKeysThroughArrayIndices) {
  Json scene = kScene;
  EXPECT_EQ(apply_override(scene, "bodies.0.material.E", 2e6), "");
  EXPECT_EQ(scene["bodies"][0]["material"]["E"], 2e6);
  EXPECT_EQ(scene["bodies"][0]["material"]["nu"], 0.3);
  // The last part may be a key the file leaves out: the scene reader judges it.
  EXPECT_EQ(apply_override(scene, "solver.realtime", false), "");
  EXPECT_EQ(scene["solver"]["realtime"], false);
  EXPECT_EQ(apply_override(scene, "bodies.0", Json::object()), "");
  EXPECT_TRUE(scene["bodies"][0].empty());
}

TEST(Overrides, RefusesKeysThatDoNotResolve) {
  Json scene = kScene;
  EXPECT_EQ(apply_override(scene, "bodies.1.material.E", 1), "'bodies' has 1 element(s): no index 1");
  EXPECT_EQ(apply_override(scene, "bodies.first.material", 1), "'bodies' is an array: 'first' is not an index");
  EXPECT_EQ(apply_override(scene, "bodies.0.damping.mass", 1), "'bodies.0' has no key 'damping'");
  EXPECT_EQ(apply_override(scene, "solver.dt.x", 1), "'solver.dt' is number, not an object or array");
  EXPECT_EQ(apply_override(scene, "solver..dt", 1), "an empty part in the key");
  EXPECT_EQ(scene, kScene) << "a refused override changed the scene";
}

class ManifestTest : public ::testing::Test {
 protected:
  testing::TempDir dir{"incise_test_batch"};
  std::filesystem::path write(const std::string& name, const std::string& text) {
    std::ofstream(dir.path / name) << text;
    return dir.path / name;
  }
  void SetUp() override { write("scene.json", kScene.dump()); }
};

TEST_F(ManifestTest, GridExpandsToTheProductWithStableNames) {
  const auto file = write("m.json", R"({"jobs": [
    {"name": "one", "scene": "scene.json", "steps": 5},
    {"name": "sweep", "scene": "scene.json", "overrides": {"solver.dt": 0.02},
     "grid": {"bodies.0.material.nu": [0.2, 0.4], "bodies.0.material.E": [1, 2, 3]}}]})");
  const Manifest m = read_manifest(file);
  ASSERT_EQ(m.jobs.size(), 7u);
  EXPECT_EQ(m.jobs[0].name, "one");
  EXPECT_EQ(m.jobs[0].steps, 5);
  EXPECT_EQ(m.jobs[0].scene, std::filesystem::weakly_canonical(dir.path / "scene.json"));
  // Grid keys in sorted order (E before nu), the last varying fastest.
  EXPECT_EQ(m.jobs[1].name, "sweep-000");
  EXPECT_EQ(m.jobs[6].name, "sweep-005");
  const Overrides expected_4 = {{"solver.dt", 0.02}, {"bodies.0.material.E", 2}, {"bodies.0.material.nu", 0.4}};
  EXPECT_EQ(m.jobs[4].overrides, expected_4);
  EXPECT_EQ(m.override_keys, (std::vector<std::string>{"solver.dt", "bodies.0.material.E", "bodies.0.material.nu"}));
  EXPECT_EQ(jobs_json(m)["jobs"][4]["overrides"]["bodies.0.material.nu"], 0.4);
}

TEST_F(ManifestTest, ListsEveryProblemNamingFileAndField) {
  const auto file = write("bad.json", R"({"jobs": [
    {"name": "a b", "scene": "scene.json", "stepz": 3},
    {"name": "b", "scene": "missing.json"},
    {"name": "c", "scene": "scene.json", "overrides": {"bodies.2.material.E": 1}, "grid": {"solver.dt": []}}]})");
  try {
    read_manifest(file);
    FAIL() << "a manifest with problems was accepted";
  } catch (const ManifestError& e) {
    const std::string text = e.what();
    const std::string at = file.string() + ": ";
    for (const std::string& expected :
         {at + "jobs[0].name: 'a b' must be letters", at + "jobs[0].stepz: unknown key", at + "jobs[1].scene: cannot read the scene",
          at + "jobs[2].overrides.\"bodies.2.material.E\": 'bodies' has 1 element(s): no index 2",
          at + "jobs[2].grid.\"solver.dt\": must be a non-empty array"})
      EXPECT_NE(text.find(expected), std::string::npos) << "missing '" << expected << "' in:\n" << text;
  }
}

TEST(Shards, ParsesIOfNAndRefusesTheRest) {
  const Shard shard = parse_shard("3/4");
  EXPECT_EQ(shard.index, 3);
  EXPECT_EQ(shard.count, 4);
  for (const char* bad : {"4/4", "-1/2", "1/0", "1", "1/2x", "a/b"}) EXPECT_THROW(parse_shard(bad), std::runtime_error) << bad;
}

}  // namespace
}  // namespace incise::batch
