// Bytes -> read_trajectory (header, then checksummed chunks): a file that cannot be used at all
// is a TrajectoryError; anything else is read up to its first bad chunk, and what is returned
// must satisfy the format's rules (the same ones the writer enforces).
#include "engine/trajectory.hpp"
#include "fuzz/temp_file.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

namespace {

void check(const incise::engine::Trajectory& trajectory) {
  const auto& samples = trajectory.samples;
  if (trajectory.report.samples_read != samples.size()) std::abort();
  if (trajectory.report.complete != trajectory.report.problem.empty()) std::abort();
  for (std::size_t i = 0; i < samples.size(); ++i) {
    if (!std::isfinite(samples[i].time) || (i > 0 && samples[i].time < samples[i - 1].time)) std::abort();
    double norm = 0;
    for (double q : samples[i].orientation) norm += q * q;
    if (!(std::abs(std::sqrt(norm) - 1) <= 1e-3)) std::abort();
  }
  const auto& stops = trajectory.cg_stops;
  if (trajectory.report.cg_stops_read != stops.size()) std::abort();
  for (std::size_t i = 0; i < stops.size(); ++i) {
    if (stops[i].step == 0 || stops[i].iterations == 0) std::abort();
    if (i > 0 && (stops[i].step < stops[i - 1].step ||
                  (stops[i].step == stops[i - 1].step && stops[i].solve <= stops[i - 1].solve)))
      std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const auto file = incise::fuzz::temp_file("trajectory.traj");
  incise::fuzz::write_file(file, data, size);
  try {
    check(incise::engine::read_trajectory(file));
  } catch (const incise::engine::TrajectoryError&) {
  }
  return 0;
}
