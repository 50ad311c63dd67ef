#include "engine/models/promayon_settings.hpp"

#include <cmath>
#include <string>

namespace incise::engine {

namespace {

// `volume_target`: [[t, V0], ...], times increasing, volumes positive.
std::vector<std::pair<double, double>> read_volume_target(Reader& block) {
  std::vector<std::pair<double, double>> events;
  const Json* v = block.get("volume_target", false);
  if (!v) return events;
  const std::string where = block.child("volume_target");
  if (!v->is_array() || v->empty()) {
    block.error(where, "must be a non-empty array of [time, volume] pairs");
    return {};
  }
  for (std::size_t i = 0; i < v->size(); ++i) {
    const Json& e = (*v)[i];
    const std::string at = where + "[" + std::to_string(i) + "]";
    if (!e.is_array() || e.size() != 2 || !e[0].is_number() || !e[1].is_number()) {
      block.error(at, "must be [time s, volume m^3]");
      return {};
    }
    const double t = e[0].get<double>(), vol = e[1].get<double>();
    if (!std::isfinite(t) || t < 0 || (!events.empty() && !(t > events.back().first))) {
      block.error(at, "time must be finite, >= 0 and after the previous event's");
      return {};
    }
    if (!std::isfinite(vol) || !(vol > 0) || vol > 1e3) {
      block.error(at, "volume must be in (0, 1000] m^3");
      return {};
    }
    events.emplace_back(t, vol);
  }
  return events;
}

PromayonSettings read_common(Reader& block) {
  PromayonSettings s;
  s.neighbourhood = block.text("neighbourhood", false, "vn1", {"vn1", "moore"});
  s.stiffness = block.number("stiffness", false, 0, 0, 1e12);
  s.damping = block.number("damping", false, 0, 0, 1e9);
  s.mass_damping = block.number("mass_damping", false, 0, 0, 1e6);
  s.integrator = block.text("integrator", false, "explicit", {"explicit", "implicit"});
  s.scheme = block.text("scheme", false, "symplectic_euler", {"explicit_euler", "symplectic_euler"});
  s.substeps = static_cast<int>(block.number("substeps", false, 1, 1, 10000));
  if (block.has("substeps") && s.substeps != block.number("substeps", false, 1, 1, 10000))
    block.error(block.child("substeps"), "must be an integer");
  s.volume = block.text("volume", false, "none", {"none", "exact", "penalty"});
  s.volume_stiffness = block.number("volume_stiffness", s.volume == "penalty", 0, 0, 1e12, true);
  s.volume_target = read_volume_target(block);
  if (s.volume == "none" && (block.has("volume_target") || block.has("volume_stiffness")))
    block.error(block.child("volume"), "volume_target and volume_stiffness need volume \"exact\" or \"penalty\"");
  if (s.volume == "exact" && block.has("volume_stiffness"))
    block.error(block.child("volume_stiffness"), "only the penalty variant has a stiffness");
  return s;
}

}  // namespace

void read_shape_memory_settings(Reader& block, BodySpec& body) { body.settings = read_common(block); }

void read_spring_network_settings(Reader& block, BodySpec& body) {
  PromayonSettings s = read_common(block);
  s.dashpot = block.number("dashpot", false, 0, 0, 1e9);
  body.settings = s;
}

}  // namespace incise::engine
