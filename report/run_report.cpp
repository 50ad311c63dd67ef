#include "report/run_report.hpp"

#include "report/frames_player.hpp"
#include "report/html_page.hpp"
#include "report/run_plots.hpp"
#include "report/csv_table.hpp"
#include "report/video.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>

namespace incise::report {

namespace {

using Json = nlohmann::json;

Json read_json(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot read");
  try {
    return Json::parse(in);
  } catch (const Json::exception& e) {
    throw std::runtime_error(file.string() + ": not JSON: " + e.what());
  }
}

std::string scalar_text(const Json& value) {
  if (value.is_string()) return value.get<std::string>();
  if (value.is_number_float()) {
    std::ostringstream text;
    text.precision(6);
    text << value.get<double>();
    return text.str();
  }
  return value.dump();
}

// metrics.json flattened to dotted names ("ms_per_step.median", "bodies.0.triangles"); a
// short array of numbers stays one row ("[0.01, 0, 0.05]").
void flatten(const Json& value, const std::string& name, std::vector<TableRow>& rows) {
  const bool short_numbers = value.is_array() && value.size() <= 4 &&
                             std::all_of(value.begin(), value.end(), [](const Json& v) { return v.is_number(); });
  if (value.is_object()) {
    for (const auto& [key, item] : value.items()) flatten(item, name.empty() ? key : name + "." + key, rows);
  } else if (value.is_array() && !short_numbers) {
    for (std::size_t i = 0; i < value.size(); ++i) flatten(value[i], name + "." + std::to_string(i), rows);
  } else if (short_numbers) {
    std::string text = "[";
    for (std::size_t i = 0; i < value.size(); ++i) text += (i ? ", " : "") + scalar_text(value[i]);
    rows.push_back({{name, text + "]"}, ""});
  } else {
    rows.push_back({{name, scalar_text(value)}, ""});
  }
}

// The scene's own words. scene_file is as the run was given it (relative to where it ran):
// `incise report` run from elsewhere may not find it, and the page then says so.
void scene_section(HtmlPage& page, const Json& metrics) {
  const std::string name = metrics.value("scene", std::string("(unnamed)"));
  const std::string file = metrics.value("scene_file", std::string());
  page.heading("Scene: " + name);
  if (file.empty()) {
    page.note("the metrics name no scene file");
    return;
  }
  try {
    const Json scene = read_json(file);
    page.paragraph(scene.value("description", std::string("(the scene has no description)")));
    page.paragraph("Scene file: " + file);
  } catch (const std::exception& e) {
    page.note(std::string("scene description unavailable: ") + e.what());
  }
}

void score_section(HtmlPage& page, const std::filesystem::path& run_dir) {
  page.heading("Incision score");
  const auto file = run_dir / "score.json";
  if (!std::filesystem::exists(file)) {
    page.paragraph("No planned incision: the scene names no `plan`, so the run has no score.json.");
    return;
  }
  std::vector<TableRow> rows;
  flatten(read_json(file), "", rows);
  page.table({"measure", "value"}, rows);
}

void expect_section(HtmlPage& page, const Json& metrics) {
  page.heading("Expectations");
  if (!metrics.contains("expect") || !metrics["expect"].is_array()) {
    page.paragraph("The scene has no `expect` block.");
    return;
  }
  std::vector<TableRow> rows;
  int failed = 0;
  for (const auto& e : metrics["expect"]) {
    const bool passed = e.value("passed", false);
    failed += passed ? 0 : 1;
    rows.push_back({{e.value("metric", std::string("?")), e.contains("value") ? scalar_text(e["value"]) : "missing",
                     e.contains("min") ? scalar_text(e["min"]) : "", e.contains("max") ? scalar_text(e["max"]) : "",
                     passed ? "pass" : "FAIL"},
                    passed ? "pass" : "fail"});
  }
  page.paragraph(std::to_string(rows.size() - failed) + " of " + std::to_string(rows.size()) + " passed.");
  page.table({"metric", "value", "min", "max", "result"}, rows);
}

void plots_section(HtmlPage& page, const std::filesystem::path& run_dir, std::ostream& progress) {
  page.heading("Over time");
  const auto file = run_dir / "steps.csv";
  if (!std::filesystem::exists(file)) {
    page.note("no steps.csv in the run folder: nothing to plot");
    return;
  }
  if (!gnuplot_installed()) page.note("gnuplot is not installed: the plots are not drawn (their scripts are in report/)");
  std::optional<CsvTable> rest_top, plan, cut_path;
  const auto read_if_there = [&run_dir](const char* name, std::optional<CsvTable>& table) {
    if (std::filesystem::exists(run_dir / name)) table = read_csv_table(run_dir / name);
    return table ? &*table : nullptr;
  };
  const TopView top{read_if_there("rest_top.csv", rest_top), read_if_there("plan.csv", plan),
                    read_if_there("cut_path.csv", cut_path)};
  const RunPlots plots = draw_run_plots(read_csv_table(file), top, run_dir / "report", progress);
  for (const auto& p : plots.plots) page.embedded_png(p.png, p.title, p.id);
  for (const auto& n : plots.notes) page.note(n);
}

}  // namespace

std::filesystem::path write_run_report(const std::filesystem::path& run_dir, std::ostream& progress) {
  const auto metrics_file = run_dir / "metrics.json", session_file = run_dir / "session.json";
  const bool replay = std::filesystem::exists(metrics_file);
  if (!replay && !std::filesystem::exists(session_file))
    throw std::runtime_error(metrics_file.string() + ": no such file (nor " + session_file.filename().string() +
                             "): not a run folder");
  const Json metrics = read_json(replay ? metrics_file : session_file);

  HtmlPage page("incise run: " + metrics.value("scene", std::string("(unnamed scene)")));
  page.paragraph(std::string(replay ? "Headless replay" : "Haptic session") + ", " +
                 (metrics.contains("steps") ? metrics["steps"].dump() : std::string("?")) + " steps, " +
                 (metrics.contains("sim_time_s") ? scalar_text(metrics["sim_time_s"]) : std::string("?")) +
                 " s simulated. Run folder: " + run_dir.filename().string());
  if (metrics.contains("error")) page.note("the run stopped on an error: " + scalar_text(metrics["error"]));
  scene_section(page, metrics);
  score_section(page, run_dir);
  frames_section(page, run_dir, metrics);
  plots_section(page, run_dir, progress);
  expect_section(page, metrics);
  page.heading("Metrics");
  std::vector<TableRow> rows;
  flatten(metrics, "", rows);
  page.table({"metric", "value"}, rows);

  const auto file = run_dir / "report.html";
  page.write(file);
  return file;
}

}  // namespace incise::report
