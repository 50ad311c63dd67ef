#include "batch/merge.hpp"

#include "batch/bench_job.hpp"
#include "batch/json_file.hpp"
#include "bench/plot.hpp"

#include <nlohmann/json.hpp>

#include <fstream>
#include <sstream>

namespace incise::batch {

namespace {

using Json = nlohmann::json;

// A CSV field: quoted (RFC 4180) when it holds a comma, a quote or a line break.
std::string field(const std::string& text) {
  if (text.find_first_of(",\"\n\r") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

// An override's value as a cell: a string as it is, anything else as its JSON.
std::string value_text(const Json& value) { return value.is_string() ? value.get<std::string>() : value.dump(); }

std::string number(const Json& outcome, const char* key) {
  if (!outcome.contains(key) || !outcome[key].is_number()) return "";
  std::ostringstream out;
  out.precision(6);
  out << outcome[key].get<double>();
  return out.str();
}

// summary.png: the median step time of each finished job, failed jobs left at zero.
std::string plot_script(const std::vector<std::pair<std::string, double>>& bars) {
  std::ostringstream s;
  s << "set terminal pngcairo size " << std::max<std::size_t>(640, 40 * bars.size() + 200) << ",480 font ',9'\n"
    << "set output 'summary.png'\n"
    << "set title 'incise batch: median step time per job'\n"
    << "set ylabel 'ms per step (median)'\nset style fill solid 0.6\nset boxwidth 0.7\n"
    << "set xtics rotate by -45 noenhanced\nset grid ytics\nunset key\nset yrange [0:*]\n"
    << "$data << EOD\n";
  for (const auto& [job, ms] : bars) s << '"' << job << "\" " << ms << "\n";
  s << "EOD\nplot $data using 0:2:xtic(1) with boxes\n";
  return s.str();
}

}  // namespace

// The incision score's figures, columns of the summary when a job has a score.
constexpr const char* kScoreKeys[] = {"length_cut_mm",  "deviation_mean_mm", "deviation_max_mm", "depth_mean_mm",
                                      "depth_range_mm", "outside_band_mm2",  "duration_s",       "force_peak_N",
                                      "force_mean_N",   "strokes"};

MergeTotals merge_batch(const std::filesystem::path& out_dir, std::ostream& progress) {
  if (!std::filesystem::exists(out_dir / "jobs.json"))
    throw std::runtime_error((out_dir / "jobs.json").string() + ": no such file (is this a batch's --out folder?)");
  const Json jobs_file = read_json_file(out_dir / "jobs.json");
  std::vector<std::string> keys = jobs_file.value("override_keys", std::vector<std::string>{});
  std::vector<Json> outcomes;
  bool scored = false;
  for (const Json& job : jobs_file.at("jobs")) {
    const std::filesystem::path outcome_file = out_dir / "jobs" / job.at("name").get<std::string>() / "outcome.json";
    outcomes.push_back(std::filesystem::exists(outcome_file) ? read_json_file(outcome_file) : Json());
    scored = scored || outcomes.back().contains("score");
  }
  std::ostringstream csv;
  csv << "job,outcome,state_hash";
  for (const auto& key : keys) csv << "," << field(key);
  csv << ",scene,steps,wall_s,replay_wall_s,ms_per_step_median";
  if (scored)
    for (const char* key : kScoreKeys) csv << ",score." << key;
  csv << ",error\n";
  MergeTotals totals;
  std::vector<std::pair<std::string, double>> bars;
  for (std::size_t j = 0; j < outcomes.size(); ++j) {
    const Json& job = jobs_file.at("jobs")[j];
    const std::string name = job.at("name");
    const bool finished = !outcomes[j].is_null();
    const Json outcome = finished ? outcomes[j] : Json::object();
    const std::string result = finished ? outcome.value("outcome", "failed") : "missing";
    ++totals.jobs;
    result == "ok" ? ++totals.ok : result == "missing" ? ++totals.missing : ++totals.failed;
    csv << field(name) << "," << result << "," << outcome.value("state_hash", "");
    const Json& overrides = job.at("overrides");
    for (const auto& key : keys) csv << "," << (overrides.contains(key) ? field(value_text(overrides[key])) : "");
    csv << "," << field(job.value("scene", "")) << "," << (finished ? outcome.value("steps", Json(0)).dump() : "") << ","
        << number(outcome, "wall_s") << "," << number(outcome, "replay_wall_s") << ","
        << number(outcome, "ms_per_step_median");
    if (scored) {
      const Json score = outcome.value("score", Json::object());
      for (const char* key : kScoreKeys) csv << "," << number(score, key);
    }
    csv << "," << field(outcome.value("error", "")) << "\n";
    bars.emplace_back(name, result == "ok" ? outcome.value("ms_per_step_median", 0.0) : 0.0);
  }
  write_atomically(out_dir / "summary.csv", csv.str());
  bench::draw_with_gnuplot(out_dir, "summary.gnuplot", plot_script(bars), "summary.png", progress);
  progress << "merged " << totals.jobs << " jobs: " << totals.ok << " ok, " << totals.failed << " failed, "
           << totals.missing << " not run; wrote " << (out_dir / "summary.csv").string() << "\n";
  totals.benches_joined = merge_bench_parts(out_dir, jobs_file, progress);
  return totals;
}

}  // namespace incise::batch
