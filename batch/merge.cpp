#include "batch/merge.hpp"

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

MergeTotals merge_batch(const std::filesystem::path& out_dir, std::ostream& progress) {
  if (!std::filesystem::exists(out_dir / "jobs.json"))
    throw std::runtime_error((out_dir / "jobs.json").string() + ": no such file (is this a batch's --out folder?)");
  const Json jobs_file = read_json_file(out_dir / "jobs.json");
  std::vector<std::string> keys = jobs_file.value("override_keys", std::vector<std::string>{});
  std::ostringstream csv;
  csv << "job,outcome,state_hash";
  for (const auto& key : keys) csv << "," << field(key);
  csv << ",scene,steps,wall_s,replay_wall_s,ms_per_step_median,error\n";
  MergeTotals totals;
  std::vector<std::pair<std::string, double>> bars;
  for (const Json& job : jobs_file.at("jobs")) {
    const std::string name = job.at("name");
    const std::filesystem::path outcome_file = out_dir / "jobs" / name / "outcome.json";
    const bool finished = std::filesystem::exists(outcome_file);
    const Json outcome = finished ? read_json_file(outcome_file) : Json::object();
    const std::string result = finished ? outcome.value("outcome", "failed") : "missing";
    ++totals.jobs;
    result == "ok" ? ++totals.ok : result == "missing" ? ++totals.missing : ++totals.failed;
    csv << field(name) << "," << result << "," << outcome.value("state_hash", "");
    const Json& overrides = job.at("overrides");
    for (const auto& key : keys) csv << "," << (overrides.contains(key) ? field(value_text(overrides[key])) : "");
    csv << "," << field(job.value("scene", "")) << "," << (finished ? outcome.value("steps", Json(0)).dump() : "") << ","
        << number(outcome, "wall_s") << "," << number(outcome, "replay_wall_s") << ","
        << number(outcome, "ms_per_step_median") << "," << field(outcome.value("error", "")) << "\n";
    bars.emplace_back(name, result == "ok" ? outcome.value("ms_per_step_median", 0.0) : 0.0);
  }
  write_atomically(out_dir / "summary.csv", csv.str());
  bench::draw_with_gnuplot(out_dir, "summary.gnuplot", plot_script(bars), "summary.png", progress);
  progress << "merged " << totals.jobs << " jobs: " << totals.ok << " ok, " << totals.failed << " failed, "
           << totals.missing << " not run; wrote " << (out_dir / "summary.csv").string() << "\n";
  return totals;
}

}  // namespace incise::batch
