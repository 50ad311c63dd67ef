// A benchmark's report.html (issue 33: the benches link into the review pages): its figures
// embedded, its summary and its CSV as a table, on the run report's page writer.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace incise::bench {

struct BenchPage {
  std::string title;
  std::string intro;
  std::vector<std::pair<std::string, std::string>> figures;  // PNG file name in out_dir, its title
  std::string summary_file;  // a text file in out_dir shown as written (may be empty)
  std::string csv_file;      // the bench's CSV in out_dir, shown as a table
  std::size_t max_rows = 400;  // beyond them the page says how many more the CSV has
};

// Writes out_dir/report.html and returns its path; a missing figure, summary or CSV is said on
// the page. Throws std::runtime_error naming the page if it cannot be written.
std::filesystem::path write_bench_page(const std::filesystem::path& out_dir, const BenchPage& bench);

}  // namespace incise::bench
