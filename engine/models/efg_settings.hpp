// The EFG model's settings block, `efg` (docs/scenes.md): its own file, free of physics/, so
// that the scene fuzz target (fuzz/CMakeLists.txt) reads the block as the product does.
#pragma once

#include "engine/scene.hpp"
#include "engine/scene_reader.hpp"

namespace incise::engine {

void read_efg_settings(Reader& block, BodySpec& body);

}  // namespace incise::engine
