#include "engine/trajectory_synth.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace incise::engine {
namespace {

using Vec3 = std::array<double, 3>;

// A synthetic path longer than this is almost certainly a unit mistake in the spec (e.g.
// milliseconds given as seconds), and would otherwise quietly fill gigabytes.
constexpr double kMaximumSamples = 10'000'000;

Vec3 add(const Vec3& a, const Vec3& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Vec3 subtract(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3 scale(const Vec3& a, double factor) { return {a[0] * factor, a[1] * factor, a[2] * factor}; }
double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

struct Phase {
  Vec3 from;
  Vec3 to;
  double seconds;
};

void require(bool condition, const std::string& message) {
  if (!condition) throw std::invalid_argument("synthesize_poke: " + message);
}

bool finite(const Vec3& v) {
  return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
}

}  // namespace

std::vector<ToolSample> synthesize_poke(const PokeSpec& spec) {
  require(finite(spec.approach_point) && finite(spec.contact_point) && finite(spec.stroke),
          "points and stroke must be finite");
  require(std::isfinite(spec.depth) && spec.depth >= 0, "depth must be finite and >= 0");
  require(std::isfinite(spec.rate_hz) && spec.rate_hz > 0, "rate_hz must be finite and > 0");

  const Vec3 approach_vector = subtract(spec.contact_point, spec.approach_point);
  const double approach_distance = std::sqrt(dot(approach_vector, approach_vector));
  require(approach_distance > 0, "approach point and contact point coincide");
  const Vec3 down = scale(approach_vector, 1 / approach_distance);
  const Vec3 lateral = subtract(spec.stroke, scale(down, dot(spec.stroke, down)));

  const auto& q = spec.orientation;
  const double quaternion_norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  require(std::isfinite(quaternion_norm) && quaternion_norm > 0,
          "orientation must be a non-zero finite quaternion");
  const std::array<double, 4> orientation{q[0] / quaternion_norm, q[1] / quaternion_norm,
                                          q[2] / quaternion_norm, q[3] / quaternion_norm};

  const Vec3 pressed = add(spec.contact_point, scale(down, spec.depth));
  const Vec3 stroked = add(pressed, lateral);
  const Vec3 lifted = add(spec.approach_point, lateral);
  const Phase phases[] = {
      {spec.approach_point, spec.contact_point, spec.approach_seconds},
      {spec.contact_point, pressed, spec.press_seconds},
      {pressed, pressed, spec.hold_seconds},
      {pressed, stroked, spec.stroke_seconds},
      {stroked, lifted, spec.release_seconds},
  };
  const char* phase_names[] = {"approach", "press", "hold", "stroke", "release"};

  double total_seconds = 0;
  for (int i = 0; i < 5; ++i) {
    const Phase& phase = phases[i];
    const std::string name = phase_names[i];
    require(std::isfinite(phase.seconds) && phase.seconds >= 0,
            name + "_seconds must be finite and >= 0");
    // A moving phase of zero duration would be a jump, breaking the continuity promised.
    const Vec3 travel = subtract(phase.to, phase.from);
    require(phase.seconds > 0 || dot(travel, travel) == 0,
            name + "_seconds must be > 0 because that phase moves the tool");
    total_seconds += phase.seconds;
  }
  const double period_count = std::floor(total_seconds * spec.rate_hz);
  require(period_count < kMaximumSamples, "the path would have more than " +
                                              std::to_string(static_cast<long>(kMaximumSamples)) +
                                              " samples");

  auto position_at = [&](double time) {
    double phase_start = 0;
    for (const Phase& phase : phases) {
      const double phase_end = phase_start + phase.seconds;
      if (time <= phase_end && phase.seconds > 0) {
        const double fraction = std::clamp((time - phase_start) / phase.seconds, 0.0, 1.0);
        const double eased = fraction * fraction * (3 - 2 * fraction);
        return add(phase.from, scale(subtract(phase.to, phase.from), eased));
      }
      phase_start = phase_end;
    }
    return lifted;
  };
  // A picometre of slack so the points that sit on the surface by construction (start of the
  // press, end of the lift through it) do not flicker with rounding.
  auto below_surface = [&](const Vec3& position) {
    return dot(subtract(position, spec.contact_point), down) > 1e-12;
  };
  auto make_sample = [&](double time) {
    ToolSample sample;
    sample.time = time;
    sample.position = position_at(time);
    sample.orientation = orientation;
    sample.buttons = below_surface(sample.position) ? kToolButtonEngaged : 0u;
    return sample;
  };

  std::vector<ToolSample> samples;
  const auto whole_periods = static_cast<std::size_t>(period_count);
  samples.reserve(whole_periods + 2);
  // Each time computed from its index, not accumulated, so no rounding drift builds up.
  for (std::size_t k = 0; k <= whole_periods; ++k) {
    samples.push_back(make_sample(static_cast<double>(k) / spec.rate_hz));
  }
  if (samples.back().time < total_seconds) samples.push_back(make_sample(total_seconds));
  return samples;
}

}  // namespace incise::engine
