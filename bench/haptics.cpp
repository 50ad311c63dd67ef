#include "bench/haptics.hpp"
#include "bench/repo_files.hpp"
#include "bench/scripted_stroke.hpp"

#include "common/percentile.hpp"
#include "engine/haptic_session.hpp"
#include "engine/scene.hpp"
#include "haptics/clock.hpp"
#include "haptics/path_device.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <fstream>
#include <sched.h>
#include <thread>

namespace incise::bench {

namespace {

using Json = nlohmann::json;

Json period_json(const haptics::PeriodStatistics& p) {
  return {{"p50", p.p50_us}, {"p99", p.p99_us}, {"p999", p.p999_us}, {"max", p.max_us}, {"mean", p.mean_us}};
}

// The CPU the loop and the bare loops run on: --cpu, or the last one this process may run on;
// -1: not pinned.
int loop_cpu(const HapticsBenchOptions& options) {
  if (!options.pin) return -1;
  if (options.cpu >= 0) return options.cpu;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) != 0) return -1;
  for (int c = CPU_SETSIZE - 1; c >= 0; --c)
    if (CPU_ISSET(c, &set)) return c;
  return -1;
}

haptics::HapticLoopConfig bare_config(const HapticsBenchOptions& options) {
  haptics::HapticLoopConfig bare;
  bare.spin_ns = static_cast<std::int64_t>(options.spin_us * 1000);
  bare.realtime_priority = options.realtime_priority;
  bare.cpu = loop_cpu(options);
  return bare;
}

Json cpu_json(int cpu) { return cpu >= 0 ? Json(cpu) : Json(nullptr); }
std::string cpu_name(int cpu) { return cpu >= 0 ? std::to_string(cpu) : std::string("free"); }

// The long periods, each with its split (late wake-up or long tick), at seconds since t0.
Json long_periods_json(const std::vector<haptics::LongPeriod>& periods, std::int64_t t0) {
  Json list = Json::array();
  for (const auto& p : periods)
    list.push_back({{"at_s", 1e-9 * static_cast<double>(p.end_ns - t0)},
                    {"period_ms", 1e-6 * static_cast<double>(p.period_ns)},
                    {"late_ms", 1e-6 * static_cast<double>(p.late_ns)},
                    {"tick_us", 1e-3 * static_cast<double>(p.work_ns)}});
  return list;
}

// The longest tick among the long periods (what the loop's own work contributed to them).
double longest_tick_us(const std::vector<haptics::LongPeriod>& periods) {
  std::int64_t longest = 0;
  for (const auto& p : periods) longest = std::max(longest, p.work_ns);
  return 1e-3 * static_cast<double>(longest);
}

// The cutting resistance the hand felt (TickSample::cutting_force), over the ticks that cut
// (those where it was not zero): mean and peak magnitude, N.
Json cutting_force_json(const std::vector<haptics::TickSample>& ticks, double& mean, double& peak) {
  double sum = 0;
  std::uint64_t cutting = 0;
  mean = peak = 0;
  for (const auto& t : ticks) {
    const double f = std::hypot(t.cutting_force[0], t.cutting_force[1], t.cutting_force[2]);
    if (!(f > 0)) continue;
    sum += f;
    peak = std::max(peak, f);
    ++cutting;
  }
  if (cutting > 0) mean = sum / static_cast<double>(cutting);
  return {{"mean", mean}, {"peak", peak}, {"ticks", cutting}};
}

// What changed at the tick at time_ns against the tick before, N/ms: the cutting resistance,
// the needle, the passivity damper and the rest of the contact (the lips), so that a figure
// says which term jumped.
Json jump_parts_json(const std::vector<haptics::TickSample>& ticks, std::int64_t time_ns) {
  for (std::size_t i = 1; i < ticks.size(); ++i) {
    if (ticks[i].time_ns != time_ns) continue;
    const auto& a = ticks[i - 1];
    const auto& b = ticks[i];
    const double ms = 1e-6 * static_cast<double>(b.time_ns - a.time_ns);
    const auto rate = [ms](const haptics::Vector3& before, const haptics::Vector3& after) {
      return std::hypot(after[0] - before[0], after[1] - before[1], after[2] - before[2]) / ms;
    };
    const auto lips = [](const haptics::TickSample& t) {
      haptics::Vector3 l;
      for (int k = 0; k < 3; ++k) l[k] = t.contact_force[k] - t.cutting_force[k] - t.needle_force[k];
      return l;
    };
    return {{"cutting", rate(a.cutting_force, b.cutting_force)},
            {"needle", rate(a.needle_force, b.needle_force)},
            {"damper", rate(a.damper_force, b.damper_force)},
            {"lips", rate(lips(a), lips(b))}};
  }
  return nullptr;
}

// The largest force jumps at cut events, at other publications and between them (N/ms), when
// (s from the loop's start) and which term made each (jump_parts_json).
void add_force_jumps_json(Json& j, const engine::ForceJumps& jumps, const std::vector<haptics::TickSample>& ticks,
                          std::int64_t t0) {
  const auto at = [t0](std::size_t count, std::int64_t ns) {
    return count > 0 ? Json(1e-9 * static_cast<double>(ns - t0)) : Json(nullptr);
  };
  j["force_jump_at_cut_N_per_ms"] = {{"max", jumps.at_cut_max},
                                     {"ticks", jumps.cut_ticks},
                                     {"max_at_s", at(jumps.cut_ticks, jumps.at_cut_max_ns)},
                                     {"max_parts", jump_parts_json(ticks, jumps.at_cut_max_ns)}};
  j["force_jump_at_other_publications_N_per_ms"] = {
      {"max", jumps.at_publication_max},
      {"ticks", jumps.publication_ticks},
      {"max_at_s", at(jumps.publication_ticks, jumps.at_publication_max_ns)},
      {"max_parts", jump_parts_json(ticks, jumps.at_publication_max_ns)}};
  j["force_jump_between_publications_N_per_ms"] = {{"max", jumps.between_max},
                                                   {"max_at_s", at(ticks.size(), jumps.between_max_ns)},
                                                   {"max_parts", jump_parts_json(ticks, jumps.between_max_ns)}};
}

std::string scene_file_hint(const HapticsBenchOptions& options) {
  return options.scene.empty() ? std::string("assets/scenes/haptics_block.json") : options.scene.string();
}

struct RunResult {
  Json json;
  std::string line;
};

RunResult run_session(const engine::Scene& scene, const HapticsBenchOptions& options, bool engage) {
  // The hand: the device computes the scripted pose from the clock when the loop reads it, as
  // a real device reports where it is when read (haptics/path_device.hpp).
  haptics::PathDevice device([engage](double t) { return scripted_stroke(t, engage); });
  engine::SessionOptions session_options;
  session_options.clock = engine::SessionOptions::Clock::realtime;
  session_options.keep_ticks = true;
  session_options.budget = scene.solver.realtime;
  session_options.loop.spin_ns = static_cast<std::int64_t>(options.spin_us * 1000);
  session_options.loop.realtime_priority = options.realtime_priority;
  session_options.loop.cpu = loop_cpu(options);
  if (engage && !options.record.empty()) session_options.record = options.record;
  engine::HapticSession session(scene, device, session_options);
  const std::int64_t t0 = session.t0_ns();
  device.start_at(t0);
  std::vector<double> step_ms;
  std::string error;
  std::atomic<bool> stop_physics{false};
  std::thread physics([&] {
    try {
      while (!stop_physics.load(std::memory_order_acquire)) step_ms.push_back(session.step().ms_total);
    } catch (const std::exception& e) {
      error = e.what();
    }
  });
  // A bare loop beside the real one, on its own thread for the same time and pinned to the same
  // CPU: a stall of that CPU or of the host shows in both, so the loop's long periods it does
  // not share are the loop's own. (Unpinned, the two may run on different vCPUs, and a stall of
  // the loop's alone would be counted as the loop's.)
  haptics::PeriodHistogram beside;
  const int beside_cpu =
      haptics::measure_bare_loop(bare_config(options), static_cast<std::int64_t>(options.seconds * 1e9), beside);
  const std::int64_t end = haptics::monotonic_now_ns();
  stop_physics.store(true, std::memory_order_release);
  physics.join();
  const haptics::PeriodStatistics periods = session.loop().period_statistics();
  const std::vector<haptics::LongPeriod> long_periods = session.loop().long_periods();
  const haptics::PeriodStatistics bare = beside.summary();
  const std::size_t own_long = haptics::long_periods_not_in(long_periods, beside.long_periods());
  const haptics::PassivityFigures energy = session.loop().passivity();
  session.stop();
  const haptics::LoopThreadUsage usage = session.loop().thread_usage();
  if (!error.empty()) {
    // The step that threw is the one after those taken.
    const std::uint64_t failed = session.world().steps_taken() + 1;
    std::string message = "physics stopped at step " + std::to_string(failed) + ": " + error;
    if (session_options.record)
      message += " (recorded; to repeat it: incise replay " + scene_file_hint(options) + " --trajectory " +
                 options.record.string() + " --steps " + std::to_string(failed) + ")";
    throw std::runtime_error(message);
  }

  const auto& ticks = session.ticks();
  const engine::ForceJumps jumps = engine::force_jumps(ticks, session.cut_steps(), 1e3 / session_options.loop.rate_hz);
  double max_force = 0;
  std::uint64_t clamped = 0;
  for (const auto& t : ticks) {
    max_force = std::max(max_force, std::hypot(t.force[0], t.force[1], t.force[2]));
    clamped += t.clamped ? 1 : 0;
  }
  const double wall = 1e-9 * static_cast<double>(end - t0);
  const double sim = session.world().time();
  // The loop's own rate: its mean period (the first tick, taken before the world was built,
  // and the build itself are not the loop's).
  const double rate = periods.mean_us > 0 ? 1e6 / periods.mean_us : 0;
  Json j = {
      {"rate_hz", rate},
      {"period_us", period_json(periods)},
      {"missed_2ms", periods.over_2ms},
      {"missed_deadlines", periods.missed_deadlines},
      {"periods", periods.periods},
      {"long_periods", long_periods_json(long_periods, t0)},
      {"long_periods_not_in_bare_loop", own_long},
      {"longest_tick_in_a_long_period_us", longest_tick_us(long_periods)},
      {"loop_thread",
       {{"minor_faults", usage.minor_faults},
        {"major_faults", usage.major_faults},
        {"involuntary_switches", usage.involuntary_switches},
        {"voluntary_switches", usage.voluntary_switches}}},
      {"bare_loop_beside",
       {{"period_us", period_json(bare)},
        {"missed_2ms", bare.over_2ms},
        {"missed_deadlines", bare.missed_deadlines},
        {"periods", bare.periods},
        {"long_periods", long_periods_json(beside.long_periods(), t0)}}},
      {"device_energy_J", energy.device_energy_J},
      {"passivity",
       {{"tissue_energy_J", energy.device_energy_J + energy.dissipated_J},
        {"dissipated_J", energy.dissipated_J},
        {"ticks_acted", energy.ticks_acted},
        {"max_damping_N_s_per_m", session.loop().passivity_parameters().max_damping}}},
      {"ticks", session.loop().ticks()},
      {"max_force_N", max_force},
      {"ticks_clamped", clamped},
      {"ring_overflows", session.loop().ring_overflows()},
      {"nonfinite_forces", session.loop().nonfinite_forces()},
      {"realtime_priority", session.loop().realtime()},
      {"cpu", {{"loop", cpu_json(session.loop().cpu())}, {"bare_loop_beside", cpu_json(beside_cpu)}}},
      {"cut_events", session.world().cut_totals().events},
      {"physics",
       {{"steps", step_ms.size()},
        {"sim_time_s", sim},
        {"wall_time_s", wall},
        {"real_time_factor", wall > 0 ? sim / wall : 0},
        {"lag_behind_hand_s_at_end", wall - sim},
        {"lag_behind_hand_steps_at_end", (wall - sim) / scene.solver.dt},
        {"real_time_budget", session.budget()},
        {"steps_over_budget", session.steps_over_budget()},
        {"residual_max_over_budget", session.residual_max_over_budget()},
        {"ms_per_step_median", common::median(step_ms)},
        {"ms_per_step_max", step_ms.empty() ? 0 : *std::max_element(step_ms.begin(), step_ms.end())}}},
  };
  char line[1024];
  std::snprintf(line, sizeof line,
                "%-16s %7.1f Hz  period p50 %6.1f p99 %6.1f p99.9 %6.1f max %7.1f us  >2ms %3llu (%zu not in the bare "
                "loop beside, longest tick in them %.1f us; the loop thread took %ld page faults, was preempted %ld times)\n"
                "  bare beside    %7.1f Hz  period p50 %6.1f p99 %6.1f p99.9 %6.1f max %7.1f us  >2ms %3llu  (CPU: loop %s, bare %s)\n"
                "  energy to the device %.3e J (tissue alone %.3e J, damper took %.3e J over %llu ticks)\n"
                "  jump N/ms: cut %.4f, publication %.4f, between %.4f  |F|max %.2f N  cuts %ld  physics x%.3f, "
                "lag %.1f steps, %llu steps over budget",
                engage ? "cutting" : "without cutting", rate, periods.p50_us, periods.p99_us, periods.p999_us,
                periods.max_us, static_cast<unsigned long long>(periods.over_2ms), own_long, longest_tick_us(long_periods),
                usage.minor_faults + usage.major_faults, usage.involuntary_switches,
                bare.mean_us > 0 ? 1e6 / bare.mean_us : 0, bare.p50_us, bare.p99_us, bare.p999_us, bare.max_us,
                static_cast<unsigned long long>(bare.over_2ms), cpu_name(session.loop().cpu()).c_str(),
                cpu_name(beside_cpu).c_str(), energy.device_energy_J,
                energy.device_energy_J + energy.dissipated_J, energy.dissipated_J,
                static_cast<unsigned long long>(energy.ticks_acted), jumps.at_cut_max, jumps.at_publication_max,
                jumps.between_max, max_force, session.world().cut_totals().events, wall > 0 ? sim / wall : 0,
                (wall - sim) / scene.solver.dt, static_cast<unsigned long long>(session.steps_over_budget()));
  add_force_jumps_json(j, jumps, ticks, t0);
  double cut_mean = 0, cut_peak = 0;
  j["cutting_force_N"] = cutting_force_json(ticks, cut_mean, cut_peak);
  const auto cutting_part = [&j](const char* key) {
    const Json& parts = j[key]["max_parts"];
    return parts.is_object() ? parts["cutting"].get<double>() : 0.0;
  };
  char cut_line[256];
  std::snprintf(cut_line, sizeof cut_line,
                "\n  cutting force mean %.2f peak %.2f N; the cutting term's part of the largest jumps N/ms: cut %.4f, "
                "publication %.4f, between %.4f",
                cut_mean, cut_peak, cutting_part("force_jump_at_cut_N_per_ms"),
                cutting_part("force_jump_at_other_publications_N_per_ms"),
                cutting_part("force_jump_between_publications_N_per_ms"));
  return {j, std::string(line) + cut_line};
}

}  // namespace

int run_haptics_bench(const HapticsBenchOptions& options, std::ostream& progress) {
  try {
    if (!(options.seconds > 0 && options.seconds <= 3600))
      throw std::runtime_error("--seconds " + std::to_string(options.seconds) + " must be in (0, 3600]");
    if (!(options.spin_us >= 0 && options.spin_us < 1000))
      throw std::runtime_error("--spin-us " + std::to_string(options.spin_us) + " must be in [0, 1000)");
    const auto scene_file = options.scene.empty() ? find_repo_file("assets/scenes/haptics_block.json", "haptics") : options.scene;
    const engine::Scene scene = engine::load_scene(scene_file);
    std::filesystem::create_directories(options.out_dir);
    progress << "bench haptics: " << scene.name << ", " << options.seconds << " s per run, spin " << options.spin_us
             << " us\n";
    RunResult cutting = run_session(scene, options, true);
    progress << cutting.line << "\n";
    RunResult pressing = run_session(scene, options, false);
    progress << pressing.line << "\n";
    haptics::PeriodHistogram alone;
    const int base_cpu =
        haptics::measure_bare_loop(bare_config(options), static_cast<std::int64_t>(options.seconds * 1e9), alone);
    const haptics::PeriodStatistics base = alone.summary();
    char line[256];
    std::snprintf(line, sizeof line, "%-16s %7.1f Hz  period p50 %6.1f p99 %6.1f p99.9 %6.1f max %7.1f us  >2ms %3llu",
                  "bare loop alone", base.mean_us > 0 ? 1e6 / base.mean_us : 0, base.p50_us, base.p99_us, base.p999_us,
                  base.max_us, static_cast<unsigned long long>(base.over_2ms));
    progress << line << "\n";

    Json report = cutting.json;
    report["scene"] = scene.name;
    report["scene_file"] = scene_file.string();
    report["seconds"] = options.seconds;
    report["spin_us"] = options.spin_us;
    report["without_cutting"] = pressing.json;
    report["baseline"] = {{"rate_hz", base.mean_us > 0 ? 1e6 / base.mean_us : 0},
                          {"period_us", period_json(base)},
                          {"missed_2ms", base.over_2ms},
                          {"missed_deadlines", base.missed_deadlines},
                          {"periods", base.periods},
                          {"cpu", cpu_json(base_cpu)}};
    const auto file = options.out_dir / "haptics.json";
    std::ofstream out(file);
    out << report.dump(2) << "\n";
    if (!out) throw std::runtime_error(file.string() + ": cannot write");
    progress << "report: " << file.string() << "\n";
    return 0;
  } catch (const std::exception& e) {
    progress << "bench haptics: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace incise::bench
