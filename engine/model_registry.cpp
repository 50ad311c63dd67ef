#include "engine/model_registry.hpp"

#include <algorithm>
#include <stdexcept>

namespace incise::engine {

// Generated from INCISE_MODELS in engine/CMakeLists.txt: one register_NAME_model(registry)
// declaration and call per built-in model, so that a model's CMake line is its registration.
#include "engine/builtin_models.inc"

void ModelRegistry::add(ModelEntry entry) {
  if (entry.name.empty()) throw std::invalid_argument("model registry: a model needs a name");
  if (find(entry.name)) throw std::invalid_argument("model registry: '" + entry.name + "' is registered already");
  if (!entry.build) throw std::invalid_argument("model registry: '" + entry.name + "' has no builder");
  entries_.push_back(std::move(entry));
}

bool ModelRegistry::remove(const std::string& name) {
  auto it = std::find_if(entries_.begin(), entries_.end(), [&](const ModelEntry& e) { return e.name == name; });
  if (it == entries_.end()) return false;
  entries_.erase(it);
  return true;
}

const ModelEntry* ModelRegistry::find(const std::string& name) const {
  for (const auto& e : entries_)
    if (e.name == name) return &e;
  return nullptr;
}

std::vector<std::string> ModelRegistry::names() const {
  std::vector<std::string> result;
  for (const auto& e : entries_) result.push_back(e.name);
  return result;
}

std::vector<std::string> ModelRegistry::names_where(bool ModelEntry::*capability) const {
  std::vector<std::string> result;
  for (const auto& e : entries_)
    if (e.*capability) result.push_back(e.name);
  return result;
}

namespace {

ModelRegistry& registry() {
  // A function-local static: built on first use, once, whatever the order in which the
  // translation units were initialised or linked.
  static ModelRegistry instance = [] {
    ModelRegistry r;
    register_builtin_models(r);
    return r;
  }();
  return instance;
}

}  // namespace

const ModelRegistry& models() { return registry(); }

void register_model(ModelEntry entry) { registry().add(std::move(entry)); }

bool unregister_model(const std::string& name) { return registry().remove(name); }

std::string alternatives(const std::vector<std::string>& names, bool quoted) {
  std::string text;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) text += i + 1 == names.size() ? " or " : ", ";
    text += quoted ? "'" + names[i] + "'" : names[i];
  }
  return text;
}

}  // namespace incise::engine
