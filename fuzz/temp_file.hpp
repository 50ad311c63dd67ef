// The readers under test take a path, so each input is written to a file of this process's own
// (TMPDIR, which scripts/fuzz points at memory where it can) and read back through the same
// call the product makes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include <unistd.h>

namespace incise::fuzz {

inline std::filesystem::path temp_file(const std::string& name) {
  // Removed when the process exits normally, as libFuzzer's timed runs and ctest's replays do.
  struct Remover {
    std::vector<std::filesystem::path> files;
    ~Remover() {
      for (const auto& file : files) {
        std::error_code ignored;
        std::filesystem::remove(file, ignored);
      }
    }
  };
  static Remover remover;
  remover.files.push_back(std::filesystem::temp_directory_path() /
                          ("incise_fuzz_" + std::to_string(::getpid()) + "_" + name));
  return remover.files.back();
}

inline void write_file(const std::filesystem::path& file, const std::uint8_t* data, std::size_t size) {
  std::FILE* stream = std::fopen(file.c_str(), "wb");
  if (!stream) std::abort();  // the harness, not the product: nothing to fuzz without the file
  if (size > 0 && std::fwrite(data, 1, size, stream) != size) std::abort();
  std::fclose(stream);
}

}  // namespace incise::fuzz
