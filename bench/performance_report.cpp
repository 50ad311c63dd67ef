#include "bench/performance_report.hpp"

#include "bench/plot.hpp"
#include "report/csv_table.hpp"
#include "report/html_page.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace incise::bench {

namespace {

std::string field(const report::CsvTable& table, std::size_t row, const std::string& column) {
  const auto i = table.index(column);
  return i && *i < table.text[row].size() ? table.text[row][*i] : std::string();
}

// One bar per row: "7302 el / 99k tri / jacobi", the cut's phases and the solve stacked.
std::string phases_script(const report::CsvTable& table) {
  static const std::vector<std::string> phases = {"ms_ccd", "ms_topology", "ms_solve", "ms_surface"};
  std::ostringstream data;
  data << "$data << EOD\n";
  for (std::size_t r = 0; r < table.rows.size(); ++r) {
    std::string label = field(table, r, "elements") + " el / " +
                        std::to_string(std::lround(std::atof(field(table, r, "triangles").c_str()) / 1000)) + "k tri / " +
                        field(table, r, "preconditioner") + (field(table, r, "backend") == "gpu" ? " (gpu)" : "");
    data << '"' << label << '"';
    double sum = 0;
    for (const auto& p : phases) {
      const double v = std::atof(field(table, r, p).c_str());
      sum += v;
      data << ' ' << v;
    }
    data << ' ' << std::max(0.0, std::atof(field(table, r, "ms_total").c_str()) - sum) << "\n";
  }
  data << "EOD\n";
  return "set terminal pngcairo size 960,460 font ',10' background rgb '#ffffff'\nset output 'performance.png'\n"
         "set title 'Cutting step: median time per phase, per resolution and preconditioner'\n"
         "set ylabel 'ms per step (median over the cutting steps)'\nset xlabel 'elements / surface triangles / preconditioner'\n"
         "set grid ytics lc rgb '#dddddd'\nset key outside right top\nset style data histograms\n"
         "set style histogram rowstacked\nset style fill solid 0.85 border -1\nset boxwidth 0.7\n"
         "set xtics rotate by -25 font ',8' noenhanced\nset bmargin 7\n" +
         data.str() +
         "plot $data using 2:xtic(1) title 'ccd', '' using 3 title 'topology', '' using 4 title 'solve', "
         "'' using 5 title 'surface', '' using 6 title 'other'\n";
}

}  // namespace

std::filesystem::path write_performance_report(const std::filesystem::path& out_dir, std::ostream& progress) {
  const report::CsvTable table = report::read_csv_table(out_dir / "performance.csv");
  report::HtmlPage page("incise bench performance");
  page.paragraph("Where a cutting step's time goes as the integration grid and the cut surface get finer: the default "
                 "scene's incision replayed per resolution and preconditioner, medians over the steps the blade was "
                 "engaged (bench/performance.cpp says what each column is). Timings are this machine's.");
  if (table.rows.empty()) {
    page.note("performance.csv holds no row (the bench was interrupted before its first)");
  } else {
    draw_with_gnuplot(out_dir, "performance.gp", phases_script(table), "performance.png", progress);
    page.embedded_png(out_dir / "performance.png", "Cutting step: median time per phase", "performance");
  }
  static const std::vector<std::string> shown = {"elements", "triangles", "backend", "preconditioner", "ms_ccd",
                                                 "ms_topology", "ms_solve", "ms_surface", "ms_total", "ms_total_p95",
                                                 "cut_share_pct", "cut_events", "cg_iterations"};
  std::vector<std::string> header;
  for (const auto& c : shown)
    if (table.has(c)) header.push_back(c);
  std::vector<report::TableRow> rows;
  for (std::size_t r = 0; r < table.rows.size(); ++r) {
    report::TableRow row;
    for (const auto& c : header) row.cells.push_back(field(table, r, c));
    rows.push_back(row);
  }
  page.heading("Rows (performance.csv, main columns)");
  page.table(header, rows);
  const auto file = out_dir / "report.html";
  page.write(file);
  return file;
}

}  // namespace incise::bench
