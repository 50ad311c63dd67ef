#include "batch/manifest.hpp"

#include "bench/accuracy.hpp"

#include "engine/scene_reader.hpp"

#include <algorithm>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

namespace incise::batch {

namespace {

using engine::Reader;

std::string join_errors(const std::string& file, const std::vector<std::string>& errors) {
  std::string text = file + ": " + std::to_string(errors.size()) + " problem(s) in the manifest";
  for (const auto& e : errors) text += "\n  " + file + ": " + e;
  return text;
}

std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return {};
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

// A path relative to the manifest's folder, made absolute and canonical: jobs.json must read
// the same from every shard, whatever folder each was started from and however it named the
// manifest, or the second shard would take the folder for another batch's.
std::filesystem::path resolve(const std::filesystem::path& base, const std::string& path) {
  std::error_code error;
  const std::filesystem::path absolute = std::filesystem::absolute(base / path, error);
  if (error) return (base / path).lexically_normal();
  const std::filesystem::path canonical = std::filesystem::weakly_canonical(absolute, error);
  return error ? absolute.lexically_normal() : canonical;
}

bool valid_name(const std::string& name) {
  if (name.empty() || name.size() > 100 || name[0] == '.') return false;
  for (char c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '-' && c != '.') return false;
  return true;
}

// The scenes' JSON, each read once however many jobs use it; null when it cannot be read
// (the problem is then reported once per job, naming the job's field).
class SceneCache {
 public:
  const Json& get(const std::filesystem::path& file, std::string& problem) {
    auto it = scenes_.find(file);
    if (it == scenes_.end()) {
      std::vector<std::string> errors;
      Json root;
      const std::string text = read_text(file);
      if (text.empty()) errors.push_back("cannot read the scene " + file.string());
      else root = engine::parse_scene_json(text, errors);
      it = scenes_.emplace(file, std::pair{root, errors.empty() ? "" : errors.front()}).first;
    }
    problem = it->second.second;
    return it->second.first;
  }

 private:
  std::map<std::filesystem::path, std::pair<Json, std::string>> scenes_;
};

// `overrides` or `grid` of a job: an object whose keys are dotted scene keys that resolve in
// the scene. For a grid each value is a non-empty array of the values to sweep.
void read_keys(const Json& block, const std::string& path, bool grid, const Json* scene, Reader& job,
               Overrides& out) {
  if (!block.is_object()) {
    job.error(path, "must be an object of dotted scene keys, not " + engine::kind_of(block));
    return;
  }
  for (const auto& [key, value] : block.items()) {
    const std::string where = path + ".\"" + key + "\"";
    if (grid && (!value.is_array() || value.empty())) {
      job.error(where, "must be a non-empty array of values, not " + engine::kind_of(value));
      continue;
    }
    if (scene) {
      Json copy = *scene;
      if (const std::string problem = apply_override(copy, key, grid ? value[0] : value); !problem.empty()) {
        job.error(where, problem);
        continue;
      }
    }
    out.emplace_back(key, value);
  }
}

// A job's `bench` block: which benchmark, its quick form or not, and which part of how many.
BenchPart read_bench(const Json& node, const std::string& path, std::vector<std::string>& errors) {
  Reader b(node, path, errors);
  BenchPart bench;
  bench.name = b.text("name", true, "stability", {"stability", "accuracy"});
  bench.quick = b.boolean("quick", false);
  bench.parts = b.integer("parts", false, 1, 1, 10000);
  bench.part = b.integer("part", true, 0, 0, 9999);
  bench.cases = b.text("cases", false, "");
  if (!bench.cases.empty() && bench.name != "accuracy")
    b.error(b.child("cases"), "only the accuracy report takes cases");
  std::stringstream names(bench.cases);
  const std::vector<std::string> known = bench::accuracy_case_names();
  for (std::string name; !bench.cases.empty() && std::getline(names, name, ',');) {
    if (std::find(known.begin(), known.end(), name) == known.end())
      b.error(b.child("cases"), "'" + name + "' is not a case (" + bench::accuracy_case_list() + ")");
  }
  if (bench.part >= bench.parts)
    b.error(b.child("part"), std::to_string(bench.part) + " is not below parts (" + std::to_string(bench.parts) + ")");
  return bench;
}

// One entry of `jobs`: one job, or one per point of its grid (the last key varies fastest;
// keys in the order nlohmann keeps them, sorted). Names: NAME, or NAME-000, NAME-001, ...
void read_job(const Json& node, const std::string& path, const std::filesystem::path& base, SceneCache& scenes,
              std::vector<std::string>& errors, std::vector<Job>& jobs) {
  Reader r(node, path, errors);
  Job job;
  job.name = r.text("name", true, "");
  if (r.has("name") && !job.name.empty() && !valid_name(job.name))
    r.error(r.child("name"), "'" + job.name + "' must be letters, digits, '_', '-' or '.' (a folder's name)");
  if (const Json* bench = r.get("bench", false)) {
    job.bench = read_bench(*bench, r.child("bench"), errors);
    if (r.has("scene")) r.error(r.child("scene"), "a job is a scene or a bench part, not both");
    jobs.push_back(job);
    return;
  }
  const std::string scene = r.text("scene", true, "");
  const Json* scene_json = nullptr;
  if (!scene.empty()) {
    job.scene = resolve(base, scene);
    std::string problem;
    const Json& root = scenes.get(job.scene, problem);
    if (!problem.empty()) r.error(r.child("scene"), problem);
    else scene_json = &root;
  }
  if (r.has("trajectory")) {
    job.trajectory = resolve(base, r.text("trajectory", true, ""));
    if (!std::filesystem::is_regular_file(*job.trajectory))
      r.error(r.child("trajectory"), "no such file " + job.trajectory->string());
  }
  if (r.has("steps")) job.steps = r.integer("steps", false, 0, 0, 100000000);
  job.capture_every = r.integer("capture_every", false, 0, 0, 1000000);
  if (const Json* overrides = r.get("overrides", false))
    read_keys(*overrides, r.child("overrides"), false, scene_json, r, job.overrides);
  Overrides grid;
  if (const Json* g = r.get("grid", false)) read_keys(*g, r.child("grid"), true, scene_json, r, grid);
  if (grid.empty()) {
    jobs.push_back(job);
    return;
  }
  std::size_t points = 1;
  for (const auto& [key, values] : grid) points *= values.size();
  if (points > 100000) {
    r.error(r.child("grid"), std::to_string(points) + " combinations: at most 100000");
    return;
  }
  const int width = std::max<int>(3, static_cast<int>(std::to_string(points - 1).size()));
  for (std::size_t p = 0; p < points; ++p) {
    Job point = job;
    std::size_t rest = p;
    Overrides chosen(grid.size());
    for (std::size_t k = grid.size(); k-- > 0;) {
      const Json& values = grid[k].second;
      chosen[k] = {grid[k].first, values[rest % values.size()]};
      rest /= values.size();
    }
    point.overrides.insert(point.overrides.end(), chosen.begin(), chosen.end());
    std::string index = std::to_string(p);
    index.insert(0, static_cast<std::size_t>(width) - std::min<std::size_t>(width, index.size()), '0');
    point.name += '-';
    point.name += index;
    jobs.push_back(std::move(point));
  }
}

}  // namespace

ManifestError::ManifestError(const std::string& file, const std::vector<std::string>& errors)
    : std::runtime_error(join_errors(file, errors)) {}

Manifest read_manifest(const std::filesystem::path& file) {
  const std::string text = read_text(file);
  if (text.empty()) throw ManifestError(file.string(), {"cannot read the file, or it is empty"});
  std::vector<std::string> errors;
  const Json root = engine::parse_scene_json(text, errors);
  if (!errors.empty()) throw ManifestError(file.string(), errors);
  Manifest manifest;
  manifest.file = file;
  SceneCache scenes;
  {
    Reader r(root, "", errors);
    r.text("description", false, "");
    const Json* jobs = r.get("jobs", true);
    if (jobs && (!jobs->is_array() || jobs->empty())) r.error("jobs", "must be a non-empty array, not " + engine::kind_of(*jobs));
    else if (jobs)
      for (std::size_t i = 0; i < jobs->size(); ++i)
        read_job((*jobs)[i], "jobs[" + std::to_string(i) + "]", file.parent_path(), scenes, errors, manifest.jobs);
  }
  std::set<std::string> names;
  for (const Job& job : manifest.jobs) {
    if (!job.name.empty() && !names.insert(job.name).second) errors.push_back("jobs: two jobs are named '" + job.name + "'");
    for (const auto& [key, value] : job.overrides)
      if (std::find(manifest.override_keys.begin(), manifest.override_keys.end(), key) == manifest.override_keys.end())
        manifest.override_keys.push_back(key);
  }
  if (!errors.empty()) throw ManifestError(file.string(), errors);
  return manifest;
}

Json jobs_json(const Manifest& manifest) {
  Json jobs = Json::array();
  for (const Job& job : manifest.jobs) {
    Json overrides = Json::object();
    for (const auto& [key, value] : job.overrides) overrides[key] = value;
    Json entry = {{"name", job.name},
                  {"scene", job.scene.string()},
                  {"trajectory", job.trajectory ? job.trajectory->string() : ""},
                  {"overrides", overrides}};
    if (job.bench)
      entry["bench"] = {{"name", job.bench->name}, {"quick", job.bench->quick}, {"part", job.bench->part},
                        {"parts", job.bench->parts}, {"cases", job.bench->cases}};
    jobs.push_back(std::move(entry));
  }
  return {{"manifest", manifest.file.string()}, {"override_keys", manifest.override_keys}, {"jobs", jobs}};
}

}  // namespace incise::batch
