// Scene text -> parse_scene (JSON, then every field validated): any input ends in a Scene or
// a SceneError naming the file; anything else (another exception, a sanitizer report, a hang)
// is a finding.
#include "engine/scene.hpp"

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const incise::engine::Scene scene = incise::engine::parse_scene(text, "fuzz/scene.json");
    if (scene.bodies.empty()) std::abort();  // the validator requires one
  } catch (const incise::engine::SceneError& e) {
    if (e.errors().empty()) std::abort();  // a refusal always says why
  }
  return 0;
}
