// The deformable models a scene can name in a body's `model` key, and what each can do.
//
// A model is one entry: its name, whether the blade can cut it, whether the GPU backend runs
// it, how it reads its own settings block (the body's key named after the model, e.g. `efg`),
// and how it builds a body. The scene validator, the world builder, `incise check` and the
// benchmarks read the list from here, so adding a model is its class, its registration file
// (engine/models/NAME_model.cpp) and its line in engine/CMakeLists.txt (docs/models.md).
#pragma once

#include "engine/scene.hpp"
#include "engine/scene_reader.hpp"

#include <functional>
#include <string>
#include <vector>

namespace incise::engine {

struct Body;       // engine/body.hpp
struct BodyShape;  // engine/body_builder.hpp

struct ModelEntry {
  std::string name;     // the scene's `model` value and the key of its settings block (not a body key)
  std::string summary;  // one line for `incise check` and docs
  bool cuttable = false;  // the blade cuts it: its builder makes the cut state for `cuttable` bodies
  bool gpu = false;       // solver.backend "gpu" runs it (physics/gpu/efg_step: the builder sets data.efg)
  std::string node_name = "node";  // what its degrees of freedom sit on, in messages ("particle")
  // Reads the body's settings block (the key named `name`; an empty one when the body has
  // none), opened as `block` with its path ("bodies[0].efg"), into `body` (BodySpec::efg, or
  // BodySpec::settings for a model of its own); errors go through block.error() and keys it
  // does not read are reported as unknown. `body` has its model, shape, material and
  // `cuttable` read. Null: the model takes no block (a body giving one is refused).
  std::function<void(Reader& block, BodySpec& body)> read_settings;
  // Builds the body from its checked spec and its shape (engine/body_builder.hpp has the parts
  // every model shares); throws std::runtime_error naming the body.
  std::function<Body(const BodySpec& spec, const SolverSpec& solver, const BodyShape& shape)> build;
};

class ModelRegistry {
 public:
  // Throws std::invalid_argument for an empty or taken name, or a missing builder.
  void add(ModelEntry entry);
  // Removes a model (tests that register one of their own); false if none has the name.
  bool remove(const std::string& name);
  const ModelEntry* find(const std::string& name) const;
  const std::vector<ModelEntry>& entries() const { return entries_; }
  std::vector<std::string> names() const;
  // The names of the models whose `capability` holds, in registration order ("efg").
  std::vector<std::string> names_where(bool ModelEntry::*capability) const;

 private:
  std::vector<ModelEntry> entries_;  // registration order: the order errors and listings use
};

// The registry, with the built-in models registered on first use (explicitly, in the order of
// engine/CMakeLists.txt's INCISE_MODELS, so none depends on static initialisation). Register
// further models before scenes are read; reading is safe from several threads, registering is
// not.
const ModelRegistry& models();
void register_model(ModelEntry entry);
bool unregister_model(const std::string& name);

// Names as alternatives in a message: "'efg'", "'fem' or 'efg'", "'a', 'b' or 'c'" (quoted),
// or the same without quotes.
std::string alternatives(const std::vector<std::string>& names, bool quoted = true);

}  // namespace incise::engine
