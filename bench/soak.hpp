// The soak (issue 35): `incise bench soak --minutes M --out DIR`. A training session runs for as
// long as the trainee cuts; this runs one for M minutes and says whether memory stays flat.
#pragma once

#include <cstdint>
#include <filesystem>
#include <ostream>

namespace incise::bench {

struct SoakOptions {
  double seconds = 30 * 60;
  std::filesystem::path scene;  // empty: assets/scenes/default.json (the lobe)
  std::filesystem::path out_dir = "out/bench/soak";
  std::uint32_t seed = 35;         // the strokes' positions, directions and depths
  double sample_every_s = 1;       // one row of soak.csv per this many seconds
  double rss_growth_limit = 0.10;  // of the working size (the warm-up's largest RSS)
  bool realtime_priority = true;   // for the haptic loop, where the system grants it
};

// The haptic session on its real-time clock (the 1 kHz loop on its own thread, physics
// stepping in this one) with a scripted hand on another thread making seeded random strokes:
// approach from above, press the blade in (engaged), draw it across the top, lift it out,
// move to the next stroke. A body is rebuilt (a new session from the scene) after
// kStrokesPerBody strokes, or sooner when its surface has grown to kSurfaceGrowthLimit times
// its triangles at build: by then it is cut to pieces. Every sample_every_s: RSS
// (/proc/self/statm), the bytes malloc'd and still held (glibc's mallinfo2), steps, cut events, guard events, non-finite values, rebuilds and the
// current session's haptic period percentiles go to DIR/soak.csv; DIR/soak.png plots RSS and
// cut events over time; a row is also taken right after each body's build (session_start 1)
// and between bodies (idle 1: the last session stopped and its pages trimmed by malloc_trim, no
// body alive). The verdict: after the warm-up (the first 20 % of the run, at least 30 s where
// the run is a minute or longer, extended to 10 s after the first rebuild but not past half
// the run) the RSS between bodies never exceeds the largest between bodies during the warm-up
// by more than rss_growth_limit times the working size (the largest RSS of any row during the
// warm-up; a run without bodies finished both during and after its warm-up: every row against
// the warm-up's peak), and no value was non-finite. Returns 0 when it holds, 1 when it does not
// or the session failed (the reason on `progress`).
int run_soak_bench(const SoakOptions& options, std::ostream& progress);

inline constexpr int kStrokesPerBody = 6;
inline constexpr double kSurfaceGrowthLimit = 4.0;

}  // namespace incise::bench
