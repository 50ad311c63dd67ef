// A batch manifest (docs/batch.md): the jobs of a batch, each a scene with an optional
// trajectory, step count and overrides, or a grid of overrides that expands to one job per
// combination. Read and validated like a scene: every problem is listed, each naming the
// manifest file and the field (`jobs[3].overrides."bodies.0.material.E": ...`).
#pragma once

#include "batch/overrides.hpp"

#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace incise::batch {

// A part of a benchmark's sweep run as a job (batch/bench_job.hpp): `incise bench NAME
// --emit-manifest` writes one per part, `incise batch merge` joins their rows into one sweep.
struct BenchPart {
  std::string name;  // "stability"
  bool quick = false;
  int part = 0;
  int parts = 1;
  std::string cases;  // accuracy only: its --cases (comma-separated), empty for all
};

// One run: a replay of a scene into DIR/jobs/NAME/, or a part of a benchmark.
struct Job {
  std::string name;                // unique; the folder's name
  std::optional<BenchPart> bench;  // instead of a scene
  std::filesystem::path scene;     // resolved against the manifest's folder, canonical
  std::optional<std::filesystem::path> trajectory;  // likewise
  std::optional<long> steps;       // default: the scene's solver.duration / dt
  int capture_every = 0;           // frames only when asked
  Overrides overrides;             // the job's own, then its grid point's
};

struct Manifest {
  std::filesystem::path file;
  std::vector<Job> jobs;                    // expanded, in the manifest's order
  std::vector<std::string> override_keys;   // every key any job overrides, first seen first
};

class ManifestError : public std::runtime_error {
 public:
  ManifestError(const std::string& file, const std::vector<std::string>& errors);
};

// Reads, validates and expands a manifest; throws ManifestError listing every problem.
// Each job's scene is read and its override keys resolved in it; the overridden values are
// judged by the scene reader when the job runs, so that one bad value in a sweep fails that
// job only.
Manifest read_manifest(const std::filesystem::path& file);

// The expanded jobs as JSON (DIR/jobs.json): what `incise batch merge` reads.
Json jobs_json(const Manifest& manifest);

}  // namespace incise::batch
