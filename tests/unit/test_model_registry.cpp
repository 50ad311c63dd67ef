// The model registry (engine/model_registry.hpp): the built-in models and their capabilities,
// and a model registered by a test alone — the registration docs/models.md shows — that the
// scene validator, the world builder and the GPU check take from the registry like the others.
#include "engine/body_builder.hpp"
#include "engine/model_registry.hpp"
#include "engine/scene.hpp"
#include "engine/world.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <any>
#include <cmath>
#include <functional>
#include <string>

using namespace incise::engine;
namespace physics = incise::physics;
using Json = nlohmann::json;

namespace {

// Every node held to its rest position by a spring of its own: the smallest DeformableModel.
class Tethered : public physics::DeformableModel {
 public:
  Tethered(physics::Vector rest, double stiffness, double node_mass)
      : rest_(std::move(rest)), masses_(physics::Vector::Constant(rest_.size() / 3, node_mass)), k_(stiffness) {}
  int node_count() const override { return static_cast<int>(rest_.size() / 3); }
  const physics::Vector& rest_positions() const override { return rest_; }
  const physics::Vector& lumped_masses() const override { return masses_; }
  void update_rotations(const physics::Vector&) override {}
  void add_elastic_forces(const physics::Vector& x, physics::Vector& f) const override { f -= k_ * (x - rest_); }
  void add_stiffness_product(const physics::Vector& p, physics::Vector& out) const override { out += k_ * p; }
  void add_stiffness_diagonal(physics::Vector& diag) const override { diag.array() += k_; }
  double elastic_energy(const physics::Vector& x) const override { return 0.5 * k_ * (x - rest_).squaredNorm(); }

  std::unique_ptr<physics::DeformableModel> clone() const override { return std::make_unique<Tethered>(*this); }
 private:
  physics::Vector rest_, masses_;
  double k_;
};

// The registration: the nodes are the corners of the shape's box, the surface its boundary.
ModelEntry tethered_entry() {
  return {.name = "tethered",
          .summary = "nodes on springs to their rest positions (a test's model)",
          .read_settings = [](Reader& block, BodySpec& body) {
            body.settings = block.number("stiffness", true, 100, 0, 1e9, true);  // N/m
          },
          .build = [](const BodySpec& spec, const SolverSpec& solver, const BodyShape& shape) {
            Body body;
            auto model = body_model(spec, solver);
            const physics::TetMesh box = physics::make_box_tets(shape.lo, shape.hi, {1, 1, 1});
            const double mass = spec.material.density * (shape.hi - shape.lo).prod() / (box.rest.size() / 3.0);
            body.data.mechanics = std::make_unique<Tethered>(box.rest, std::any_cast<double>(spec.settings), mass);
            body.data.surface = physics::boundary_triangles(box.tets);
            for (int node = 0; node < body.data.mechanics->node_count(); ++node) model->surface_nodes.push_back(node);
            for (const auto& t : body.data.surface)
              for (int v : t) body.data.render_triangles.push_back(static_cast<std::uint32_t>(v));
            start_at_rest(body.data);
            fix_nodes(body.data, spec, box.rest);
            body.data.gravity = physics::gravity_forces(body.data.mechanics->lumped_masses(), model->gravity);
            body.model = std::move(model);
            return body;
          }};
}

// Registers the test's model for one test, so that the others see the built-in list only.
struct TetheredRegistered {
  TetheredRegistered() { register_model(tethered_entry()); }
  ~TetheredRegistered() { unregister_model("tethered"); }
};

Json tethered_scene() {
  return Json::parse(R"({
    "name": "tethered",
    "bodies": [{
      "name": "block", "model": "tethered",
      "generator": {"type": "box", "min": [0, 0, 0], "max": [0.04, 0.02, 0.02]},
      "resolution": 0.01,
      "material": {"E": 5000, "nu": 0.3, "rho": 1000},
      "fixed": [{"min": [-1, -1, -1], "max": [0.001, 1, 1]}],
      "tethered": {"stiffness": 200}
    }],
    "solver": {"dt": 0.01, "duration": 0.1}
  })");
}

Scene parse(const Json& json) { return parse_scene(json.dump(), "tethered.json"); }

std::string error_of(const std::function<void(Json&)>& mutate) {
  Json json = tethered_scene();
  mutate(json);
  try {
    parse(json);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(ModelRegistry, ListsTheBuiltInModelsWithTheirCapabilities) {
  EXPECT_EQ(models().names(), (std::vector<std::string>{"fem", "efg", "mass_spring", "constraint_particles", "shape_memory", "spring_network"}));
  const ModelEntry* fem = models().find("fem");
  const ModelEntry* efg = models().find("efg");
  ASSERT_TRUE(fem && efg);
  EXPECT_FALSE(fem->cuttable);
  EXPECT_FALSE(fem->gpu);
  EXPECT_FALSE(fem->read_settings);
  EXPECT_TRUE(efg->cuttable);
  EXPECT_TRUE(efg->gpu);
  EXPECT_TRUE(efg->read_settings);
  EXPECT_EQ(efg->node_name, "particle");
  const ModelEntry* mass_spring = models().find("mass_spring");
  ASSERT_TRUE(mass_spring);
  EXPECT_FALSE(mass_spring->cuttable);
  EXPECT_FALSE(mass_spring->gpu);
  EXPECT_TRUE(mass_spring->read_settings);
  const ModelEntry* particles = models().find("constraint_particles");
  ASSERT_TRUE(particles);
  EXPECT_FALSE(particles->cuttable);
  EXPECT_FALSE(particles->gpu);
  EXPECT_TRUE(particles->read_settings);
  EXPECT_EQ(particles->node_name, "particle");
  EXPECT_EQ(models().names_where(&ModelEntry::cuttable), std::vector<std::string>{"efg"});
  EXPECT_EQ(models().find("tethered"), nullptr);
}

namespace incise::engine {
void register_fuzz_models(ModelRegistry& registry);  // fuzz/fuzz_models.cpp
}

// The scene fuzz target validates scenes through a registry of its own (the builders need
// physics/, which its build leaves out): it must list the product's models as the product does.
TEST(ModelRegistry, TheSceneFuzzTargetRegistersTheProductsModels) {
  ModelRegistry fuzz;
  register_fuzz_models(fuzz);
  ASSERT_EQ(fuzz.names(), models().names());
  for (const ModelEntry& entry : models().entries()) {
    const ModelEntry& mirror = *fuzz.find(entry.name);
    EXPECT_EQ(mirror.cuttable, entry.cuttable) << entry.name;
    EXPECT_EQ(mirror.gpu, entry.gpu) << entry.name;
    EXPECT_EQ(mirror.node_name, entry.node_name) << entry.name;
    EXPECT_EQ(static_cast<bool>(mirror.read_settings), static_cast<bool>(entry.read_settings)) << entry.name;
  }
}

TEST(ModelRegistry, RefusesATakenNameAndAModelWithoutBuilder) {
  ModelEntry again = tethered_entry();
  again.name = "fem";
  EXPECT_THROW(register_model(again), std::invalid_argument);
  ModelEntry no_builder = tethered_entry();
  no_builder.build = nullptr;
  EXPECT_THROW(register_model(no_builder), std::invalid_argument);
  EXPECT_EQ(models().names().size(), 6u);
}

TEST(ModelRegistry, ARegisteredModelValidatesBuildsAndSteps) {
  TetheredRegistered registered;
  const Scene scene = parse(tethered_scene());
  ASSERT_EQ(scene.bodies.size(), 1u);
  EXPECT_EQ(std::any_cast<double>(scene.bodies[0].settings), 200.0);

  World world(scene, std::nullopt);
  const Body& body = world.bodies()[0];
  EXPECT_EQ(body.model->kind, "tethered");
  EXPECT_EQ(body.data.mechanics->node_count(), 8);
  int fixed = 0;
  for (auto f : body.data.fixed) fixed += f;
  EXPECT_EQ(fixed, 4);
  for (int step = 0; step < 5; ++step) world.step();
  const auto& x = world.bodies()[0].data.state.positions;
  EXPECT_TRUE(x.allFinite());
  // Gravity pulls the free corners down; the springs hold them near their rest positions.
  const double sag = body.data.mechanics->rest_positions()[3 * 7 + 2] - x[3 * 7 + 2];
  EXPECT_GT(sag, 0);
  EXPECT_LT(sag, 0.01);
}

TEST(ModelRegistry, ARegisteredModelsScenesAreCheckedThroughItsEntry) {
  TetheredRegistered registered;
  const std::vector<std::pair<std::function<void(Json&)>, std::string>> cases = {
      {[](Json& s) { s["bodies"][0]["cuttable"] = true; }, "bodies[0].cuttable: only 'efg' bodies can be cut"},
      {[](Json& s) { s["bodies"][0]["model"] = "sph"; }, "bodies[0].model: 'sph' is not one of: fem, efg, mass_spring, constraint_particles, shape_memory, spring_network, tethered"},
      {[](Json& s) { s["bodies"][0]["tethered"]["stiffness"] = -1; }, "bodies[0].tethered.stiffness: -1 must be in (0"},
      {[](Json& s) { s["bodies"][0]["tethered"]["damping"] = 1; }, "bodies[0].tethered.damping: unknown key"},
      {[](Json& s) { s["bodies"][0].erase("tethered"); }, "bodies[0].tethered.stiffness: is required"},
      {[](Json& s) { s["bodies"][0]["model"] = "fem"; },
       "bodies[0].tethered: only bodies with model 'tethered' take tethered settings"},
      {[](Json& s) { s["bodies"][0]["model"] = "efg"; s["bodies"][0]["efg"] = {{"neighbours", 4}}; },
       "bodies[0].tethered: only bodies with model 'tethered' take tethered settings"},
  };
  for (const auto& [mutate, expected] : cases) {
    SCOPED_TRACE(expected);
    const std::string message = error_of(mutate);
    EXPECT_NE(message.find(expected), std::string::npos) << message;
  }
}

TEST(ModelRegistry, TheGpuBackendRefusesAModelThatCannotRunOnIt) {
  TetheredRegistered registered;
  Json json = tethered_scene();
  json["solver"]["backend"] = "gpu";
  const Scene scene = parse(json);
  try {
    World world(scene, std::nullopt);
    FAIL() << "a model without `gpu` was given to the GPU backend";
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("bodies[0] ('block') has model 'tethered'; the GPU backend runs efg bodies only"),
              std::string::npos) << message;
  }
}
