// CSV text -> import_csv (`incise trajectory import`): a refusal is a TrajectoryError naming
// the line; what is accepted must be samples the trajectory writer takes (finite, unit
// quaternions, times increasing), or the import would write a file its reader calls corrupt.
#include "engine/trajectory.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <sstream>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  try {
    const auto samples = incise::engine::import_csv(in, "fuzz.csv");
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const auto& s = samples[i];
      if (!std::isfinite(s.time) || (i > 0 && !(s.time > samples[i - 1].time))) std::abort();
      for (double p : s.position)
        if (!std::isfinite(p)) std::abort();
      for (float f : s.force)
        if (!std::isfinite(f)) std::abort();
      double norm = 0;
      for (double q : s.orientation) norm += q * q;
      if (!(std::abs(std::sqrt(norm) - 1) <= 1e-4)) std::abort();
    }
  } catch (const incise::engine::TrajectoryError&) {
  }
  return 0;
}
