#include "bench/bench_page.hpp"

#include "report/csv_table.hpp"
#include "report/html_page.hpp"

#include <fstream>
#include <sstream>

namespace incise::bench {

std::filesystem::path write_bench_page(const std::filesystem::path& out_dir, const BenchPage& bench) {
  report::HtmlPage page(bench.title);
  page.paragraph(bench.intro);
  for (std::size_t i = 0; i < bench.figures.size(); ++i)
    page.embedded_png(out_dir / bench.figures[i].first, bench.figures[i].second, "figure" + std::to_string(i));
  if (!bench.summary_file.empty()) {
    page.heading("Summary (" + bench.summary_file + ")");
    std::ifstream in(out_dir / bench.summary_file);
    std::ostringstream text;
    text << in.rdbuf();
    if (in) page.preformatted(text.str());
    else page.note(bench.summary_file + " is missing");
  }
  page.heading("Rows (" + bench.csv_file + ")");
  try {
    const report::CsvTable table = report::read_csv_table(out_dir / bench.csv_file);
    std::vector<report::TableRow> rows;
    for (std::size_t r = 0; r < table.text.size() && r < bench.max_rows; ++r) rows.push_back({table.text[r], ""});
    page.table(table.columns, rows);
    if (table.text.size() > bench.max_rows)
      page.note(std::to_string(table.text.size() - bench.max_rows) + " more rows in " + bench.csv_file);
  } catch (const std::exception& e) {
    page.note(e.what());
  }
  const auto file = out_dir / "report.html";
  page.write(file);
  return file;
}

}  // namespace incise::bench
