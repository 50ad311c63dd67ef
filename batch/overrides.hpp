// Scene overrides: a dotted key ("bodies.0.material.E") and a value set in a scene's JSON
// before the scene reader sees it, so that an overridden value is validated, and refused
// naming its field, exactly as if it had been written in the file.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <utility>
#include <vector>

namespace incise::batch {

using Json = nlohmann::json;

// A dotted key and its value, in the order they are applied.
using Overrides = std::vector<std::pair<std::string, Json>>;

// Sets `key` in `scene`. Every part but the last must exist: an object's key, or an array's
// index ("bodies.0"); the last may name a key the file leaves out (it then takes the scene
// reader's judgement like any other). Returns what is wrong with the key, or "" when set.
std::string apply_override(Json& scene, const std::string& key, const Json& value);

}  // namespace incise::batch
