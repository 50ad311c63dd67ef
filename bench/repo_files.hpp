// Where the benchmarks find the repository's files (scenes): relative to the working directory
// (the repository's root), else next to the binary (build/bin/incise -> the root two levels up).
#pragma once

#include <filesystem>
#include <string>

namespace incise::bench {

// `relative` from the root; throws std::runtime_error naming `bench` and the file if absent.
std::filesystem::path find_repo_file(const std::filesystem::path& relative, const std::string& bench);

}  // namespace incise::bench
