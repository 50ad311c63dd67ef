#include "bench/soak.hpp"
#include "bench/plot.hpp"
#include "bench/repo_files.hpp"

#include "engine/haptic_session.hpp"
#include "engine/scene.hpp"
#include "haptics/clock.hpp"
#include "haptics/virtual_device.hpp"

#include <unistd.h>

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <random>
#include <sstream>
#include <thread>
#include <vector>

namespace incise::bench {

namespace {

// Resident set size in MiB: the second field of /proc/self/statm, in pages.
double rss_mib() {
  std::ifstream statm("/proc/self/statm");
  long size = 0, resident = 0;
  if (!(statm >> size >> resident)) return 0;
  return static_cast<double>(resident) * static_cast<double>(sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0);
}

// Bytes the program holds from malloc (glibc's mallinfo2: in arenas and mmapped), MiB; 0
// elsewhere. Beside RSS it tells a leak (this grows too) from a heap whose free space is
// fragmented (RSS grows, this does not).
double heap_in_use_mib() {
#ifdef __GLIBC__
  const struct mallinfo2 info = mallinfo2();
  return static_cast<double>(info.uordblks + info.hblkhd) / (1024.0 * 1024.0);
#else
  return 0;
#endif
}

// Where the strokes go: the middle half of the bodies' box in x and y, from above its top.
struct StrokeArea {
  double x0, x1, y0, y1, top;
};

struct Stroke {
  std::array<double, 2> from{}, to{};
  double z = 0;  // the tip's height while drawing
};

// Stroke k of the run, the same for a given seed whatever the timing: a start in the area, a
// direction, a length of 2 to 5 cm (clamped to the area) and a depth of 12 to 25 mm below the
// top of the box.
Stroke stroke(const StrokeArea& area, std::uint32_t seed, long k) {
  std::mt19937_64 random(seed * 0x9E3779B97F4A7C15ull + static_cast<std::uint64_t>(k));
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const auto clamp = [](double v, double lo, double hi) { return std::min(hi, std::max(lo, v)); };
  Stroke s;
  s.from = {area.x0 + (area.x1 - area.x0) * unit(random), area.y0 + (area.y1 - area.y0) * unit(random)};
  const double angle = 2 * M_PI * unit(random), length = 0.02 + 0.03 * unit(random);
  s.to = {clamp(s.from[0] + length * std::cos(angle), area.x0, area.x1),
          clamp(s.from[1] + length * std::sin(angle), area.y0, area.y1)};
  s.z = area.top - (0.012 + 0.013 * unit(random));
  return s;
}

// The hand at `t` seconds into stroke `base + t / kPeriod`: press in at the start (engaged)
// over 0.4 s, draw to the end over 1.6 s, lift out over 0.4 s (released), move above the
// next stroke's start over 0.6 s.
constexpr double kPeriod = 3.0;
haptics::DevicePose hand_pose(const StrokeArea& area, std::uint32_t seed, long base, double t) {
  const long k = base + static_cast<long>(std::floor(t / kPeriod));
  const double s = t - kPeriod * std::floor(t / kPeriod);
  const Stroke now = stroke(area, seed, k);
  const double above = area.top + 0.01;
  const auto mix = [](double a, double b, double u) { return a + (b - a) * u; };
  haptics::DevicePose pose;
  double x = now.from[0], y = now.from[1], z = above;
  bool engaged = false;
  if (s < 0.4) {
    z = mix(above, now.z, s / 0.4), engaged = true;
  } else if (s < 2.0) {
    const double u = (s - 0.4) / 1.6;
    x = mix(now.from[0], now.to[0], u), y = mix(now.from[1], now.to[1], u), z = now.z, engaged = true;
  } else if (s < 2.4) {
    x = now.to[0], y = now.to[1], z = mix(now.z, above, (s - 2.0) / 0.4);
  } else {
    const Stroke next = stroke(area, seed, k + 1);
    const double u = (s - 2.4) / 0.6;
    x = mix(now.to[0], next.from[0], u), y = mix(now.to[1], next.from[1], u);
  }
  pose.position = {x, y, z};
  pose.buttons = engaged ? haptics::kButtonEngage : 0;
  return pose;
}

struct Row {
  double t_s = 0, rss_mib = 0, heap_mib = 0, sim_time_s = 0;
  std::uint64_t steps = 0;
  long cut_events = 0, guard_events = 0, nonfinite = 0, rebuilds = 0;
  double p50_us = 0, p99_us = 0, max_us = 0;  // the current session's haptic periods
  bool session_start = false;  // taken right after a body was built, before its first step
  bool idle = false;           // taken between bodies: the last one stopped, its pages trimmed
};

// What the bodies rebuilt so far did, added to the current one's for each row.
struct Totals {
  std::uint64_t steps = 0;
  double sim_time_s = 0;
  long cut_events = 0, guard_events = 0, nonfinite = 0, rebuilds = 0;
  double p50_us = 0, p99_us = 0, max_us = 0;  // the worst session's
};

long guard_events(const engine::World& world) {
  const auto& g = world.guard_counts();
  return g.nonfinite_retries + g.cg_not_converged + g.energy_growth;
}
long nonfinite(engine::HapticSession& session) {
  return session.world().guard_counts().nonfinite_retries + static_cast<long>(session.loop().nonfinite_forces());
}

Row row_now(double t, const Totals& done, engine::HapticSession& session) {
  const auto p = session.loop().period_statistics();
  Row r;
  r.t_s = t;
  r.rss_mib = rss_mib();
  r.heap_mib = heap_in_use_mib();
  r.steps = done.steps + session.world().steps_taken();
  r.sim_time_s = done.sim_time_s + session.world().time();
  r.cut_events = done.cut_events + session.world().cut_totals().events;
  r.guard_events = done.guard_events + guard_events(session.world());
  r.nonfinite = done.nonfinite + nonfinite(session);
  r.rebuilds = done.rebuilds;
  r.p50_us = p.p50_us, r.p99_us = p.p99_us, r.max_us = p.max_us;
  return r;
}

// A row from the finished bodies' totals alone, with no body alive: what RSS holds then is the
// program, its caches and whatever a session leaked, without the fragments a build leaves.
Row idle_row(double t, const Totals& done) {
  Row r;
  r.t_s = t, r.rss_mib = rss_mib(), r.heap_mib = heap_in_use_mib();
  r.steps = done.steps, r.sim_time_s = done.sim_time_s, r.cut_events = done.cut_events;
  r.guard_events = done.guard_events, r.nonfinite = done.nonfinite, r.rebuilds = done.rebuilds;
  r.p50_us = done.p50_us, r.p99_us = done.p99_us, r.max_us = done.max_us;
  r.idle = true;
  return r;
}

void add_session(Totals& done, engine::HapticSession& session) {
  const auto p = session.loop().period_statistics();
  done.steps += session.world().steps_taken();
  done.sim_time_s += session.world().time();
  done.cut_events += session.world().cut_totals().events;
  done.guard_events += guard_events(session.world());
  done.nonfinite += nonfinite(session);
  done.p50_us = std::max(done.p50_us, p.p50_us);
  done.p99_us = std::max(done.p99_us, p.p99_us);
  done.max_us = std::max(done.max_us, p.max_us);
}

std::size_t surface_triangles(const engine::World& world) {
  std::size_t n = 0;
  for (const auto& body : world.bodies()) n += body.data.surface.size();
  return n;
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

namespace {

struct Run {
  std::vector<Row> rows;
  Totals totals;
  std::string error;  // why the session stopped early; empty when it ran its time
};

// The hand on its own thread, as the window's mouse would be: the pose at the time since
// `t0_ns` of stroke `base` on. Each body starts its strokes from the approach.
class Hand {
 public:
  Hand(haptics::VirtualDevice& device, const StrokeArea& area, std::uint32_t seed)
      : device_(device), area_(area), seed_(seed), thread_([this] { move(); }) {}
  ~Hand() {
    stop_.store(true, std::memory_order_release);
    thread_.join();
  }
  void restart(long base, std::int64_t t0_ns) {
    base_.store(base, std::memory_order_release);
    t0_ns_.store(t0_ns, std::memory_order_release);
  }

 private:
  void move() {
    while (!stop_.load(std::memory_order_acquire)) {
      const double t = std::max(0.0, 1e-9 * static_cast<double>(haptics::monotonic_now_ns() - t0_ns_.load()));
      device_.set_pose(hand_pose(area_, seed_, base_.load(), t));
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
  }
  haptics::VirtualDevice& device_;
  StrokeArea area_;
  std::uint32_t seed_;
  std::atomic<long> base_{0};
  std::atomic<std::int64_t> t0_ns_{haptics::monotonic_now_ns()};
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

StrokeArea stroke_area(const engine::World& world) {
  const auto lo = world.bounds_min(), hi = world.bounds_max();
  const double cx = 0.5 * (lo[0] + hi[0]), cy = 0.5 * (lo[1] + hi[1]);
  const double hx = 0.25 * (hi[0] - lo[0]), hy = 0.25 * (hi[1] - lo[1]);
  return {cx - hx, cx + hx, cy - hy, cy + hy, hi[2]};
}

Run soak(const engine::Scene& scene, const SoakOptions& options, std::ostream& progress) {
  haptics::VirtualDevice device;
  engine::SessionOptions session_options;
  session_options.clock = engine::SessionOptions::Clock::realtime;
  session_options.budget = scene.solver.realtime;
  session_options.loop.spin_ns = 300'000;  // as the window and bench haptics
  session_options.loop.realtime_priority = options.realtime_priority;
  haptics::DevicePose away;
  away.position = {0, 0, 1};  // far above anything until the first body says where to cut
  device.set_pose(away);

  Run run;
  std::unique_ptr<Hand> hand;
  const auto start = std::chrono::steady_clock::now();
  const double report_every = std::max(10.0, options.seconds / 20);
  double next_row = 0, next_report = report_every;
  long strokes = 0;
  try {
    while (seconds_since(start) < options.seconds) {
      if (hand) hand->restart(strokes, haptics::monotonic_now_ns());
      // Held so that it can be destroyed before the trim: its memory is then all freed.
      auto held = std::make_unique<engine::HapticSession>(scene, device, session_options);
      engine::HapticSession& session = *held;
      if (!hand) hand = std::make_unique<Hand>(device, stroke_area(session.world()), options.seed);
      hand->restart(strokes, session.t0_ns());
      run.rows.push_back(row_now(seconds_since(start), run.totals, session));
      run.rows.back().session_start = true;
      const std::size_t triangles_at_build = surface_triangles(session.world());
      std::size_t guards_printed = 0;
      while (seconds_since(start) < options.seconds) {
        session.step();
        const double t = seconds_since(start);
        // Each guard that fired, as it fires: which one and its figures (World::guard_events).
        const auto& guards = session.world().guard_events();
        for (; guards_printed < guards.size(); ++guards_printed) {
          const engine::GuardEvent& g = guards[guards_printed];
          progress << "soak " << static_cast<long>(t) << " s: guard event " << g.kind << " at the body's step " << g.step
                   << " (" << g.body << "): " << g.detail << '\n';
        }
        if (t >= next_row) {
          run.rows.push_back(row_now(t, run.totals, session));
          next_row = options.sample_every_s * (std::floor(t / options.sample_every_s) + 1);
        }
        if (t >= next_report) {
          const Row& r = run.rows.back();
          progress << "soak " << static_cast<long>(t) << " s: RSS " << r.rss_mib << " MiB, " << r.steps << " steps, "
                   << r.cut_events << " cut events, " << r.rebuilds << " rebuilds\n";
          next_report += report_every;
        }
        const bool strokes_done = session.world().time() >= kStrokesPerBody * kPeriod;
        if (strokes_done || surface_triangles(session.world()) > kSurfaceGrowthLimit * triangles_at_build) break;
      }
      session.stop();
      add_session(run.totals, session);
      strokes += static_cast<long>(std::ceil(session.world().time() / kPeriod));
      if (seconds_since(start) < options.seconds) ++run.totals.rebuilds;
      // The body is rebuilt as a trainee restarts a scene: the finished session is destroyed and
      // what it freed goes back to the system (glibc keeps freed pages otherwise, and RSS would
      // follow the largest session so far rather than what is alive), so the row taken then
      // holds no body: the baseline a leak would raise.
      held.reset();
      malloc_trim(0);
      run.rows.push_back(idle_row(seconds_since(start), run.totals));
    }
  } catch (const std::exception& e) {
    run.error = e.what();
  }
  if (run.rows.empty() || !run.rows.back().idle) {  // a session that failed: its last figures all the same
    run.rows.push_back(idle_row(seconds_since(start), run.totals));
    run.rows.back().idle = false;
  }
  return run;
}

struct Verdict {
  double warmup_s = 0, warmup_peak_mib = 0, peak_after_mib = 0, growth = 0, slope_mib_per_min = 0;
  double working_mib = 0;  // the largest RSS of any row during the warm-up: growth's unit
  long after_samples = 0;  // rows after the warm-up (session starts, when judged by them)
  double warmup_heap_peak_mib = 0, heap_peak_after_mib = 0;
  bool by_idle = false;  // judged by the RSS between bodies, else by every row
  bool flat = false;
};

// Warm-up: the first 20 % of the run (at least 30 s in a run of a minute or more), extended to
// 10 s past the first rebuild but never past half the run: the heap reaches its working size
// once it has seen a body built, cut, freed and built again. A leak is memory a finished
// session leaves behind, so the verdict takes the RSS between bodies (the last one stopped,
// its pages trimmed, none alive): its rise after the warm-up over the largest between bodies
// during it, as a fraction of the process's working size (the largest RSS of any row during
// the warm-up). Not of the between-bodies figure itself: that is a small base (18-27 MiB
// against 90-113 while a body lives) with high-water marks of its own: anonymous memory outside
// malloc's count (thread stacks, library buffers) rose 4.8 MiB in one step during the fifth body
// of seed 35, in every run, with the bytes held flat: 26 % of that base in a 2-minute run, where
// a 30-minute one levels off at 27 MiB. RSS while a body lives
// depends on how far it was cut, and right after a build on the fragments the build left. A
// run with no body finished during the warm-up and another after it (a slow one:
// ThreadSanitizer's, whose one body ends with the run) is judged by every row instead, against
// the warm-up's peak. The slope (least squares over every row
// after the warm-up) is reported beside it.
Verdict judge(const std::vector<Row>& rows, double seconds, double limit) {
  Verdict v;
  v.warmup_s = seconds >= 60 ? std::max(0.2 * seconds, 30.0) : 0.2 * seconds;
  const auto rebuilt = std::find_if(rows.begin(), rows.end(), [](const Row& r) { return r.rebuilds > 0; });
  if (rebuilt != rows.end()) v.warmup_s = std::max(v.warmup_s, std::min(rebuilt->t_s + 10, 0.5 * seconds));
  // The first body's build is not the session: the warm-up holds at least its first row.
  if (!rows.empty()) v.warmup_s = std::max(v.warmup_s, rows.front().t_s);
  // Between bodies only where there are rows to compare on both sides of the warm-up's end.
  const auto idle_before = [&](bool before) {
    return std::any_of(rows.begin(), rows.end(), [&](const Row& r) { return r.idle && (r.t_s <= v.warmup_s) == before; });
  };
  v.by_idle = idle_before(true) && idle_before(false);
  double n = 0, st = 0, sr = 0, stt = 0, str = 0;
  long judged = 0;
  for (const Row& r : rows) {
    const bool counts = !v.by_idle || r.idle;
    if (r.t_s <= v.warmup_s) {
      if (counts) v.warmup_peak_mib = std::max(v.warmup_peak_mib, r.rss_mib);
      v.working_mib = std::max(v.working_mib, r.rss_mib);
      v.warmup_heap_peak_mib = std::max(v.warmup_heap_peak_mib, r.heap_mib);
      continue;
    }
    if (counts) v.peak_after_mib = std::max(v.peak_after_mib, r.rss_mib), ++judged;
    v.heap_peak_after_mib = std::max(v.heap_peak_after_mib, r.heap_mib);
    n += 1, st += r.t_s, sr += r.rss_mib, stt += r.t_s * r.t_s, str += r.t_s * r.rss_mib;
  }
  if (n >= 2 && n * stt - st * st > 0) v.slope_mib_per_min = 60 * (n * str - st * sr) / (n * stt - st * st);
  v.growth = v.working_mib > 0 ? (v.peak_after_mib - v.warmup_peak_mib) / v.working_mib : 0;
  v.after_samples = judged;
  v.flat = judged >= 1 && v.warmup_peak_mib > 0 && v.growth <= limit;
  return v;
}

void write_csv(const std::filesystem::path& file, const std::vector<Row>& rows) {
  std::ofstream out(file);
  out << "t_s,rss_mib,steps,sim_time_s,cut_events,guard_events,nonfinite,rebuilds,period_p50_us,period_p99_us,"
         "period_max_us,heap_in_use_mib,session_start,idle\n";
  for (const Row& r : rows)
    out << r.t_s << ',' << r.rss_mib << ',' << r.steps << ',' << r.sim_time_s << ',' << r.cut_events << ','
        << r.guard_events << ',' << r.nonfinite << ',' << r.rebuilds << ',' << r.p50_us << ',' << r.p99_us << ','
        << r.max_us << ',' << r.heap_mib << ',' << (r.session_start ? 1 : 0) << ',' << (r.idle ? 1 : 0) << '\n';
  if (!out) throw std::runtime_error(file.string() + ": cannot write");
}

std::string plot_script(const Verdict& v) {
  std::ostringstream s;
  s << "set terminal pngcairo size 900,500 font ',9'\n"
       "set output 'soak.png'\n"
       "set datafile separator ','\n"
       "set title 'incise bench soak: RSS and cut events over time (dashed: end of warm-up)'\n"
       "set xlabel 'time (s)'\nset ylabel 'RSS (MiB)'\nset y2label 'cut events'\n"
       "set ytics nomirror\nset y2tics\nset key top left\nset grid\n"
       "set arrow from "
    << v.warmup_s
    << ", graph 0 to " << v.warmup_s
    << ", graph 1 nohead dt 2\n"
       "plot 'soak.csv' skip 1 using 1:2 with lines lw 2 title 'RSS', "
       "'' skip 1 using 1:5 axes x1y2 with lines title 'cut events'\n";
  return s.str();
}

}  // namespace

int run_soak_bench(const SoakOptions& options, std::ostream& progress) {
  try {
    if (!(options.seconds > 0 && options.seconds <= 24 * 3600))
      throw std::runtime_error("--minutes/--seconds: " + std::to_string(options.seconds) + " s must be in (0, 24 h]");
    const auto scene_file = options.scene.empty() ? find_repo_file("assets/scenes/default.json", "soak") : options.scene;
    const engine::Scene scene = engine::load_scene(scene_file);
    if (!scene.tool) throw std::runtime_error(scene_file.string() + ": the scene has no tool for the hand to move");
    std::filesystem::create_directories(options.out_dir);
    progress << "bench soak: " << scene.name << " for " << options.seconds << " s, seed " << options.seed << "\n";
    const Run run = soak(scene, options, progress);
    write_csv(options.out_dir / "soak.csv", run.rows);
    const Verdict v = judge(run.rows, options.seconds, options.rss_growth_limit);
    draw_with_gnuplot(options.out_dir, "soak.gnuplot", plot_script(v), "soak.png", progress);
    const Row& end = run.rows.back();
    char line[768];
    std::snprintf(line, sizeof line,
                  "soak %.0f s: %llu steps (%.1f s simulated), %ld cut events, %ld rebuilds, %ld guard events, "
                  "%ld non-finite; haptic period p50 %.1f p99 %.1f max %.1f us (the worst session's)\n"
                  "RSS %s: warm-up (first %.0f s) peak %.1f MiB, after it peak %.1f MiB (%+.1f %% of the warm-up's "
                  "working size %.1f MiB), end %.1f MiB, slope after warm-up %+.3f MiB/min; malloc'd in use: warm-up "
                  "peak %.1f MiB, after it peak %.1f MiB\n",
                  end.t_s, static_cast<unsigned long long>(end.steps), end.sim_time_s, end.cut_events, end.rebuilds,
                  end.guard_events, end.nonfinite, end.p50_us, end.p99_us, end.max_us,
                  v.by_idle ? "between bodies" : "over every row", v.warmup_s, v.warmup_peak_mib,
                  v.peak_after_mib, 100 * v.growth, v.working_mib, end.rss_mib, v.slope_mib_per_min, v.warmup_heap_peak_mib,
                  v.heap_peak_after_mib);
    progress << line;
    progress << "report: " << (options.out_dir / "soak.csv").string() << "\n";
    if (!run.error.empty()) throw std::runtime_error("the session stopped after " + std::to_string(end.t_s) + " s: " + run.error);
    if (end.nonfinite != 0) throw std::runtime_error("verdict: FAIL, " + std::to_string(end.nonfinite) + " non-finite values");
    if (v.after_samples == 0)
      throw std::runtime_error("verdict: none, no RSS sample after the warm-up (" + std::to_string(v.warmup_s) +
                               " s): run longer");
    if (!v.flat) {
      char why[160];
      std::snprintf(why, sizeof why, "verdict: FAIL, RSS grew %.1f %% of the working size after warm-up (limit %.0f %%)", 100 * v.growth,
                    100 * options.rss_growth_limit);
      throw std::runtime_error(why);
    }
    progress << "verdict: flat (RSS " << (v.by_idle ? "between bodies " : "") << "within "
             << 100 * options.rss_growth_limit << " % of the warm-up's working size), no non-finite value\n";
    return 0;
  } catch (const std::exception& e) {
    progress << "bench soak: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace incise::bench
