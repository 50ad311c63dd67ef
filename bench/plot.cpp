#include "bench/plot.hpp"

#include "common/shell_quoted.hpp"

#include <cstdlib>
#include <fstream>
#include <stdexcept>

namespace incise::bench {

using common::shell_quoted;

void draw_with_gnuplot(const std::filesystem::path& out_dir, const std::string& script_name, const std::string& script,
                       const std::string& png_name, std::ostream& progress) {
  const std::filesystem::path script_path = out_dir / script_name;
  {
    std::ofstream out(script_path);
    out << script;
    if (!out) throw std::runtime_error("cannot write " + script_path.string());
  }
  if (std::system("command -v gnuplot > /dev/null 2>&1") != 0) {
    progress << "gnuplot is not installed: " << (out_dir / png_name).string() << " not drawn (the CSV and "
             << script_name << " are written)\n";
    return;
  }
  // The script names its PNG without a folder: gnuplot runs in out_dir.
  const std::string command =
      "cd " + shell_quoted(std::filesystem::absolute(out_dir).string()) + " && gnuplot " + shell_quoted(script_name);
  if (std::system(command.c_str()) != 0) progress << "gnuplot failed on " << script_path.string() << "\n";
}

}  // namespace incise::bench
