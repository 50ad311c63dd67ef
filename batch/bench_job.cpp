#include "batch/bench_job.hpp"

#include "batch/json_file.hpp"
#include "bench/accuracy.hpp"
#include "bench/stability.hpp"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <tuple>
#include <vector>

namespace incise::batch {

namespace {

using Json = nlohmann::json;

std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// FNV-1a of the part's rows: equal parts, equal digests, whichever machine ran them.
std::string digest(const std::string& text) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : text) h = (h ^ c) * 1099511628211ull;
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}

// The CSV's text without the columns `names` (the accuracy report's wall times, which differ
// from run to run, while every other column is a deterministic result).
std::string without_columns(const std::string& text, const std::vector<std::string>& names) {
  std::istringstream lines(text);
  std::string line, out;
  std::vector<bool> drop;
  for (bool header = true; std::getline(lines, line); header = false) {
    std::vector<std::string> fields;
    std::istringstream cells(line);
    for (std::string cell; std::getline(cells, cell, ',');) fields.push_back(cell);
    if (header)
      for (const std::string& field : fields) drop.push_back(std::find(names.begin(), names.end(), field) != names.end());
    for (int i = 0; i < static_cast<int>(fields.size()); ++i)
      if (i >= static_cast<int>(drop.size()) || !drop[static_cast<size_t>(i)]) out += fields[i] + ",";
    out += "\n";
  }
  return out;
}

// The part's rows: the bench's CSV in `dir` and the text its digest is taken of.
std::string run_part(const BenchPart& part, const std::filesystem::path& dir, std::ostream& log, int& status) {
  if (part.name == "accuracy") {
    status = bench::run_accuracy_bench({part.quick, true, part.part, part.parts, part.cases, {}}, dir, log);
    return without_columns(read_text(dir / "accuracy.csv"),
                           {"ms_per_step", "preconditioner_build_ms", "ms_per_step_jacobi", "speedup_vs_jacobi"});
  }
  status = bench::run_stability_bench({part.quick, false, part.part, part.parts}, dir, log);
  return read_text(dir / "stability.csv");
}

// Joins the parts (folders by part index) into `target` with the bench itself; returns its status.
int join_parts(const std::string& name, bool quick, const std::string& cases,
               const std::map<int, std::filesystem::path>& done, const std::filesystem::path& target, std::ostream& log) {
  if (name == "accuracy") {
    std::vector<std::filesystem::path> dirs;
    for (const auto& [index, dir] : done) dirs.push_back(dir);
    return bench::run_accuracy_bench({quick, false, 0, 1, cases, dirs}, target, log);
  }
  // The parts' rows under one header; the bench's resume keeps them all, runs nothing and
  // writes them back in the sweep's order with the summary, plot and page.
  std::string joined;
  for (const auto& [index, dir] : done) {
    std::istringstream rows(read_text(dir / "stability.csv"));
    std::string line;
    bool header = true;
    while (std::getline(rows, line)) {
      if (header && joined.empty()) joined += line + "\n";
      if (!header) joined += line + "\n";
      header = false;
    }
  }
  write_atomically(target / "stability.csv", joined);
  return bench::run_stability_bench({quick, true, 0, 1}, target, log);
}

}  // namespace

std::string bench_manifest(const std::string& bench, bool quick, int parts, const std::string& cases) {
  Json jobs = Json::array();
  for (int part = 0; part < parts; ++part) {
    Json b = {{"name", bench}, {"quick", quick}, {"part", part}, {"parts", parts}};
    if (!cases.empty()) b["cases"] = cases;
    jobs.push_back({{"name", bench + "_part_" + std::to_string(part)}, {"bench", b}});
  }
  return Json{{"description", "incise bench " + bench + (quick ? " --quick" : "") +
                                  (cases.empty() ? "" : " --cases " + cases) + " in " + std::to_string(parts) +
                                  " parts; `incise batch merge DIR` joins them into DIR/bench/" + bench + "/"},
              {"jobs", jobs}}
             .dump(2) +
         "\n";
}

void run_bench_part(const BenchPart& part, const std::filesystem::path& dir, Json& outcome) {
  std::ofstream log(dir / "bench.log");
  int status = 1;
  const std::string rows = run_part(part, dir, log, status);
  log.close();
  outcome["state_hash"] = digest(rows);
  outcome["steps"] = std::max<long>(0, static_cast<long>(std::count(rows.begin(), rows.end(), '\n')) - 1);  // runs
  if (status != 0) {
    outcome["outcome"] = "failed";
    outcome["error"] = "bench " + part.name + " part " + std::to_string(part.part) + " failed: see " +
                       (dir / "bench.log").string();
  }
}

bool merge_bench_parts(const std::filesystem::path& out_dir, const Json& jobs_file, std::ostream& progress) {
  // Per benchmark (quick or not, its cases): its parts' folders, by part index.
  using Key = std::tuple<std::string, bool, std::string>;
  std::map<Key, std::map<int, std::filesystem::path>> sweeps;
  std::map<Key, int> expected;
  bool joined_all = true;
  for (const Json& job : jobs_file.at("jobs")) {
    if (!job.contains("bench")) continue;
    const Json& b = job.at("bench");
    const Key key{b.at("name").get<std::string>(), b.at("quick").get<bool>(), b.value("cases", "")};
    expected[key] = b.at("parts").get<int>();
    const std::filesystem::path dir = out_dir / "jobs" / job.at("name").get<std::string>();
    const std::filesystem::path outcome = dir / "outcome.json";
    if (std::filesystem::exists(outcome) && read_json_file(outcome).value("outcome", "") == "ok")
      sweeps[key][b.at("part").get<int>()] = dir;
  }
  for (const auto& [key, parts] : expected) {
    const auto& [name, quick, cases] = key;
    const auto& done = sweeps[key];
    if (static_cast<int>(done.size()) != parts) {
      progress << "bench " << name << ": " << done.size() << " of " << parts
               << " parts finished ok; the sweep is joined when all are\n";
      joined_all = false;
      continue;
    }
    const std::filesystem::path target = out_dir / "bench" / name;
    std::filesystem::create_directories(target);
    std::ofstream log(target / "bench.log");
    const int status = join_parts(name, quick, cases, done, target, log);
    progress << "bench " << name << ": " << parts << " parts joined into " << (target / (name + ".csv")).string()
             << (status == 0 ? "" : " (FAILED: see " + (target / "bench.log").string() + ")") << "\n";
    joined_all = joined_all && status == 0;
  }
  return joined_all;
}

}  // namespace incise::batch
