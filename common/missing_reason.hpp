// Why a path a user gave (a scene's mesh or trajectory, a command line's file) cannot be opened,
// without throwing: std::filesystem::exists throws on a path the system refuses outright (a
// name longer than NAME_MAX, found by fuzz_scene), which must be reported like any bad input,
// naming the field, not end the process.
#pragma once

#include <filesystem>
#include <string>
#include <system_error>

namespace incise::common {

// The empty string when `path` exists; else "does not exist", or "cannot be looked up: " and the
// system's reason (e.g. "File name too long").
inline std::string missing_reason(const std::filesystem::path& path) {
  std::error_code error;
  const bool exists = std::filesystem::exists(path, error);
  if (error) return "cannot be looked up: " + error.message();
  return exists ? std::string() : std::string("does not exist");
}

}  // namespace incise::common
