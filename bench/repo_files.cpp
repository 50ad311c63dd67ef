#include "bench/repo_files.hpp"

#include <stdexcept>
#include <system_error>

namespace incise::bench {

std::filesystem::path find_repo_file(const std::filesystem::path& relative, const std::string& bench) {
  if (std::filesystem::exists(relative)) return relative;
  std::error_code error;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", error);
  if (!error) {
    const auto candidate = exe.parent_path().parent_path().parent_path() / relative;
    if (std::filesystem::exists(candidate)) return candidate;
  }
  throw std::runtime_error("bench " + bench + ": cannot find " + relative.string() +
                           " (run it from the repository's root)");
}

}  // namespace incise::bench
