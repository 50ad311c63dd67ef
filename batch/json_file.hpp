// The batch's small JSON files (jobs.json, outcome.json) read and written whole. Shards and
// ranks write into one folder at once and a job counts as finished once its outcome.json
// exists, so a file is never seen half written: it goes through a temporary and a rename.
#pragma once

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>

namespace incise::batch {

// Throws std::runtime_error naming the file when it cannot be opened or is not JSON.
nlohmann::json read_json_file(const std::filesystem::path& file);

// Writes `text` to `file` through a temporary beside it (named after the process, so two
// shards writing the same file do not share it) and a rename.
void write_atomically(const std::filesystem::path& file, const std::string& text);

}  // namespace incise::batch
