// A scratch folder for one test, removed afterwards. Named after the process too: two test
// runs at once (two build folders, or ctest in parallel) must not share it.
#pragma once

#include <filesystem>
#include <string>

#include <unistd.h>

namespace incise::testing {

struct TempDir {
  std::filesystem::path path;
  explicit TempDir(const std::string& name)
      : path(std::filesystem::temp_directory_path() / (name + "_" + std::to_string(::getpid()))) {
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~TempDir() { std::filesystem::remove_all(path); }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
};

}  // namespace incise::testing
