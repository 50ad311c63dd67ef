#include "batch/bench_job.hpp"

#include "batch/json_file.hpp"
#include "bench/stability.hpp"

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
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

}  // namespace

std::string bench_manifest(const std::string& bench, bool quick, int parts) {
  Json jobs = Json::array();
  for (int part = 0; part < parts; ++part)
    jobs.push_back({{"name", bench + "_part_" + std::to_string(part)},
                    {"bench", {{"name", bench}, {"quick", quick}, {"part", part}, {"parts", parts}}}});
  return Json{{"description", "incise bench " + bench + (quick ? " --quick" : "") + " in " + std::to_string(parts) +
                                  " parts; `incise batch merge DIR` joins them into DIR/bench/" + bench + "/"},
              {"jobs", jobs}}
             .dump(2) +
         "\n";
}

void run_bench_part(const BenchPart& part, const std::filesystem::path& dir, Json& outcome) {
  std::ofstream log(dir / "bench.log");
  const int status = bench::run_stability_bench({part.quick, false, part.part, part.parts}, dir, log);
  log.close();
  const std::string rows = read_text(dir / "stability.csv");
  outcome["state_hash"] = digest(rows);
  outcome["steps"] = std::max<long>(0, static_cast<long>(std::count(rows.begin(), rows.end(), '\n')) - 1);  // runs
  if (status != 0) {
    outcome["outcome"] = "failed";
    outcome["error"] = "bench " + part.name + " part " + std::to_string(part.part) + " failed: see " +
                       (dir / "bench.log").string();
  }
}

bool merge_bench_parts(const std::filesystem::path& out_dir, const Json& jobs_file, std::ostream& progress) {
  // Per benchmark (and quick or not): its parts' folders, by part index.
  std::map<std::pair<std::string, bool>, std::map<int, std::filesystem::path>> sweeps;
  std::map<std::pair<std::string, bool>, int> expected;
  bool joined_all = true;
  for (const Json& job : jobs_file.at("jobs")) {
    if (!job.contains("bench")) continue;
    const Json& b = job.at("bench");
    const auto key = std::pair{b.at("name").get<std::string>(), b.at("quick").get<bool>()};
    expected[key] = b.at("parts").get<int>();
    const std::filesystem::path dir = out_dir / "jobs" / job.at("name").get<std::string>();
    const std::filesystem::path outcome = dir / "outcome.json";
    if (std::filesystem::exists(outcome) && read_json_file(outcome).value("outcome", "") == "ok")
      sweeps[key][b.at("part").get<int>()] = dir;
  }
  for (const auto& [key, parts] : expected) {
    const auto& [name, quick] = key;
    const auto& done = sweeps[key];
    if (static_cast<int>(done.size()) != parts) {
      progress << "bench " << name << ": " << done.size() << " of " << parts
               << " parts finished ok; the sweep is joined when all are\n";
      joined_all = false;
      continue;
    }
    // The parts' rows under one header; the bench's resume keeps them all, runs nothing and
    // writes them back in the sweep's order with the summary, plot and page.
    const std::filesystem::path target = out_dir / "bench" / name;
    std::filesystem::create_directories(target);
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
    std::ofstream log(target / "bench.log");
    const int status = bench::run_stability_bench({quick, true, 0, 1}, target, log);
    progress << "bench " << name << ": " << parts << " parts joined into " << (target / "stability.csv").string()
             << (status == 0 ? "" : " (FAILED: see " + (target / "bench.log").string() + ")") << "\n";
    joined_all = joined_all && status == 0;
  }
  return joined_all;
}

}  // namespace incise::batch
