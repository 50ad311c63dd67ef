// The report of `incise bench accuracy` (accuracy_report.hpp): the CSV, references.json, the
// plot, the page and the printed figures, and a part's results as JSON for the batch's merge.
#include "bench/accuracy_report.hpp"

#include "bench/bench_page.hpp"
#include "bench/plot.hpp"

#include "common/csv.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <stdexcept>
#include <tuple>

namespace incise::bench::accuracy {

Row from_mass_spring(const MassSpringRow& r) {
  Row row{r.case_name, r.model, r.variant, r.resolution, r.dofs, r.elements, r.ms_per_step, r.cg_iterations,
          r.error_pct, r.converged, r.tip};
  row.measured_E = r.measured_E;
  row.measured_nu = r.measured_nu;
  return row;
}

void take_solver(Row& row, const Timing& timing) {
  row.preconditioner = timing.preconditioner;
  if (timing.preconditioner != "jacobi") row.preconditioner_build_ms = timing.build_ms;
  row.ms_per_step_jacobi = timing.jacobi_ms_per_step;
  row.cg_iterations_jacobi = timing.jacobi_cg_iterations;
}

std::string format(double value, int digits) { return common::significant(value, digits); }

std::string mm(const Vec3& v) {
  std::ostringstream stream;
  stream << std::fixed << std::setprecision(5) << "(" << 1e3 * v.x() << ", " << 1e3 * v.y() << ", " << 1e3 * v.z()
         << ") mm";
  return stream.str();
}

namespace {

std::string json_vector(const Vec3& v) {
  std::ostringstream stream;
  stream << std::setprecision(10) << "[" << v.x() << ", " << v.y() << ", " << v.z() << "]";
  return stream.str();
}

void write_csv(const std::filesystem::path& path, const std::vector<Row>& rows) {
  common::CsvWriter csv(path, {"case", "model", "variant", "resolution", "dofs", "elements", "ms_per_step",
                               "cg_iterations", "error_pct", "measured_E", "measured_nu", "volume_change_pct",
                               "preconditioner", "preconditioner_build_ms", "ms_per_step_jacobi", "cg_iterations_jacobi",
                               "speedup_vs_jacobi"});
  const auto optional = [](double value, int digits) { return std::isnan(value) ? std::string() : format(value, digits); };
  for (const Row& row : rows) {
    const double speedup = row.ms_per_step > 0 ? row.ms_per_step_jacobi / row.ms_per_step : std::nan("");
    csv.row(row.case_name, row.model, row.variant, row.resolution, row.dofs, row.elements,
            common::fixed(row.ms_per_step, 3), common::fixed(row.cg_iterations, 1), common::fixed(row.error_pct, 4),
            optional(row.measured_E, 8), optional(row.measured_nu, 8), optional(row.volume_change_pct, 6),
            row.preconditioner, optional(row.preconditioner_build_ms, 4), optional(row.ms_per_step_jacobi, 4),
            optional(row.cg_iterations_jacobi, 4), optional(speedup, 3));
  }
}

void write_references(const std::filesystem::path& path, const std::vector<Case>& cases,
                      const std::map<std::string, Reference>& references) {
  std::ofstream json(path);
  json << "{\n  \"units\": \"metres\",\n  \"tip\": \"area-weighted mean displacement over the face x = 0.2\",\n"
       << "  \"cases\": {\n";
  for (size_t i = 0; i < cases.size(); ++i) {
    const Reference& reference = references.at(cases[i].name);
    json << "    \"" << cases[i].name << "\": {\n      \"element\": \"" << reference.element
         << "\",\n      \"reference_tip_displacement\": " << json_vector(reference.tip) << ",\n";
    if (cases[i].name == "b1") {
      json << "      \"beam_theory_tip_z\": " << -b1_beam_theory_tip << ",\n";
    }
    json << "      \"meshes\": [\n";
    for (size_t l = 0; l < reference.levels.size(); ++l) {
      const auto& level = reference.levels[l];
      json << "        {\"mesh\": \"" << level.mesh << "\", \"dofs\": " << level.dofs
           << ", \"tip_displacement\": " << json_vector(level.tip)
           << ", \"change_from_previous_pct\": " << format(level.change_pct) << "}"
           << (l + 1 < reference.levels.size() ? "," : "") << "\n";
    }
    json << "      ]\n    }" << (i + 1 < cases.size() ? "," : "") << "\n";
  }
  json << "  }\n}\n";
}

// gnuplot script with the data inline: one panel per case, one series per model and variant.
std::string plot_script(const std::string& png, const std::vector<Case>& cases, const std::vector<Row>& rows) {
  std::ostringstream script;
  std::vector<std::string> series;
  for (const Row& row : rows) {
    std::string key = row.model + " " + row.variant;
    // The cut cases carry the cut in the variant; plot them under the same series names.
    const size_t suffix = key.find("_geomcut");
    if (suffix != std::string::npos) key.erase(suffix);
    if (std::find(series.begin(), series.end(), key) == series.end()) series.push_back(key);
  }
  script << "# Written by incise bench accuracy: error against time per step, log-log.\n"
         << "set terminal pngcairo size 1500,950 font ',10'\n"
         << "set termoption noenhanced\n"
         << "set output '" << png << "'\n"
         << "set logscale xy\nset grid\nset key bottom left font ',8'\n"
         << "set xlabel 'ms per implicit Euler step (dt = 1/60, CG 1e-6)'\n"
         << "set ylabel 'tip error %'\n";
  for (const Case& c : cases) {
    for (size_t s = 0; s < series.size(); ++s) {
      script << "$" << c.name << "_" << s << " << EOD\n";
      for (const Row& row : rows) {
        std::string key = row.model + " " + row.variant;
        const size_t suffix = key.find("_geomcut");
        if (suffix != std::string::npos) key.erase(suffix);
        if (row.case_name != c.name || key != series[s] || row.ms_per_step <= 0) continue;
        // Log axes: errors below 1e-3 % are drawn at 1e-3 %.
        script << row.ms_per_step << " " << std::max(row.error_pct, 1e-3) << "\n";
      }
      script << "EOD\n";
    }
  }
  script << "set multiplot layout 2,3 title 'incise accuracy: tip error against run time (Magnoux Table 4.1 cases)'\n";
  for (const Case& c : cases) {
    script << "set title '" << c.name << (c.cut ? " (geometry cut; _cutter: the cutter)" : "") << "'\n" << "plot ";
    // Only the series with rows in this case (the cutter variants exist for the cut cases only).
    std::vector<size_t> present;
    for (size_t s = 0; s < series.size(); ++s) {
      const bool any = std::any_of(rows.begin(), rows.end(), [&](const Row& row) {
        std::string key = row.model + " " + row.variant;
        const size_t suffix = key.find("_geomcut");
        if (suffix != std::string::npos) key.erase(suffix);
        return row.case_name == c.name && key == series[s] && row.ms_per_step > 0;
      });
      if (any) present.push_back(s);
    }
    for (size_t i = 0; i < present.size(); ++i) {
      const size_t s = present[i];
      script << "$" << c.name << "_" << s << " using 1:2 with linespoints lw 1.5 pt " << (s % 10) + 1
             << " title '" << series[s] << "'" << (i + 1 < present.size() ? ", \\\n     " : "\n");
    }
  }
  script << "unset multiplot\n";
  return script.str();
}

}  // namespace

namespace {

// Rows in case order, then model, variant and size (stable: a case's rows all come from one
// body, in the order its runs made them, so the parts' rows joined sort as the whole run's).
void sort_rows(const std::vector<Case>& cases, std::vector<Row>& rows) {
  const auto case_index = [&](const std::string& name) {
    // The cases outside `cases` last: traction, then compression.
    return std::find_if(cases.begin(), cases.end(), [&](const Case& c) { return c.name == name; }) - cases.begin() +
           (name == "compression" ? 1 : 0);
  };
  std::stable_sort(rows.begin(), rows.end(), [&](const Row& left, const Row& right) {
    return std::make_tuple(case_index(left.case_name), left.model, left.variant, left.dofs) <
           std::make_tuple(case_index(right.case_name), right.model, right.variant, right.dofs);
  });
}

// The figures: efg nb8 at its largest size per case (about 10k dofs in --quick).
// For the cut cases, nb8 with the geometry cut and with the cutter, side by side.
// "; multigrid_current, built in B ms; Jacobi: J ms per step, N CG iterations, xR" for a row
// timed with a factor, else nothing.
std::string solver_comparison(const Row& row) {
  if (std::isnan(row.ms_per_step_jacobi)) return "";
  std::ostringstream text;
  text << "; " << row.preconditioner << " (factor built in " << format(row.preconditioner_build_ms, 3)
       << " ms); Jacobi CG: " << format(row.ms_per_step_jacobi, 4) << " ms per step, " << format(row.cg_iterations_jacobi, 4)
       << " CG iterations, x" << format(row.ms_per_step_jacobi / row.ms_per_step, 3) << " the time";
  return text.str();
}

// The largest tet4 row of each case: its time per step against today's Jacobi CG.
void print_tet_figures(const std::vector<Case>& cases, const Results& results, std::ostream& progress) {
  for (const Case& c : cases) {
    const Row* largest = nullptr;
    for (const Row& row : results.rows)
      if (row.case_name == c.name && row.model == "fem" && row.variant.rfind("tet4", 0) == 0 &&
          (largest == nullptr || row.dofs > largest->dofs))
        largest = &row;
    if (largest == nullptr) continue;
    progress << c.name << " fem " << largest->variant << " at " << largest->dofs << " dofs: " << format(largest->ms_per_step, 4)
             << " ms per step (" << format(largest->cg_iterations, 4) << " CG iterations), error "
             << format(largest->error_pct, 3) << " %" << solver_comparison(*largest) << "\n";
  }
}

void print_figures(const std::vector<Case>& cases, const Results& results, std::ostream& progress) {
  for (const Case& c : cases) {
    for (const std::string& variant : c.cut ? std::vector<std::string>{"nb8_geomcut", "nb8_cutter"}
                                           : std::vector<std::string>{"nb8"}) {
      const Row* largest = nullptr;
      for (const Row& row : results.rows) {
        if (row.case_name == c.name && row.model == "efg" && row.variant == variant &&
            (largest == nullptr || row.dofs > largest->dofs)) {
          largest = &row;
        }
      }
      if (largest == nullptr) continue;
      progress << c.name << " efg " << variant << " at " << largest->dofs << " dofs: "
               << format(largest->ms_per_step, 4) << " ms per step (" << format(1000 / largest->ms_per_step, 3)
               << " steps/s, " << format(largest->cg_iterations, 4) << " CG iterations), error "
               << format(largest->error_pct, 3) << " %, tip " << mm(largest->tip) << " against "
               << mm(results.references.at(c.name).tip) << solver_comparison(*largest);
      const auto report = results.cut_reports.find(variant + " " + largest->resolution);
      if (report != results.cut_reports.end()) {
        const physics::VolumeCutReport& r = report->second;
        progress << "; cutter: " << r.particle_links_severed + r.element_links_severed << " links severed ("
                 << r.particle_links_severed << " particle, " << r.element_links_severed << " element), "
                 << r.elements_reselected << " elements re-selected, " << r.elements_isolated << " isolated, "
                 << r.reselection_failures << " failures";
      }
      progress << "\n";
    }
  }
  print_tet_figures(cases, results, progress);
}

}  // namespace

void Results::add(const Results& other) {
  rows.insert(rows.end(), other.rows.begin(), other.rows.end());
  references.insert(other.references.begin(), other.references.end());
  cut_reports.insert(other.cut_reports.begin(), other.cut_reports.end());
}

void write_rows_csv(const std::filesystem::path& path, const std::vector<Case>& cases, std::vector<Row>& rows) {
  sort_rows(cases, rows);
  write_csv(path, rows);
}

void write_report(const std::string& title, const std::vector<Case>& cases, Results& results, const std::filesystem::path& out_dir,
                  std::chrono::steady_clock::time_point start, std::ostream& progress) {
  std::vector<Row>& rows = results.rows;
  write_rows_csv(out_dir / "accuracy.csv", cases, rows);
  print_figures(cases, results, progress);
  write_references(out_dir / "references.json", cases, results.references);
  int unconverged = 0;
  for (const Row& row : rows) unconverged += row.converged ? 0 : 1;
  if (unconverged > 0) {
    progress << unconverged << " rows had a timed step whose CG stopped at its iteration "
             << "limit (2000): their ms_per_step is a lower bound\n";
  }
  draw_with_gnuplot(out_dir, "accuracy.gnuplot", plot_script("accuracy.png", cases, rows), "accuracy.png", progress);
  const std::chrono::duration<double> elapsed = std::chrono::steady_clock::now() - start;
  progress << "wrote " << (out_dir / "accuracy.csv").string() << " (" << rows.size()
           << " rows), references.json and accuracy.png in " << format(elapsed.count(), 3) << " s\n";
  progress << "report: "
           << write_bench_page(out_dir, {title,
                                         "Error against run time per step, per model, variant and "
                                         "resolution, against converged references (bench/accuracy.cpp).",
                                         {{"accuracy.png", "Error against time per step"}}, "", "accuracy.csv"})
                  .string()
           << "\n";
}

// ---------------------------------------------------------------------------------------------
// A part's results as JSON. NaN (measured_E, measured_nu of the rows that have none) as null.

namespace {

using Json = nlohmann::json;

Json vec(const Vec3& v) { return Json::array({v.x(), v.y(), v.z()}); }
Vec3 vec(const Json& j) { return Vec3(j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()); }
Json number(double value) { return std::isnan(value) ? Json(nullptr) : Json(value); }
double number(const Json& j) { return j.is_null() ? std::numeric_limits<double>::quiet_NaN() : j.get<double>(); }

Json row_json(const Row& r) {
  return {{"case", r.case_name},       {"model", r.model},
          {"variant", r.variant},      {"resolution", r.resolution},
          {"dofs", r.dofs},            {"elements", r.elements},
          {"ms_per_step", r.ms_per_step}, {"cg_iterations", r.cg_iterations},
          {"error_pct", r.error_pct},  {"converged", r.converged},
          {"tip", vec(r.tip)},         {"measured_E", number(r.measured_E)},
          {"measured_nu", number(r.measured_nu)}, {"volume_change_pct", number(r.volume_change_pct)},
          {"preconditioner", r.preconditioner}, {"preconditioner_build_ms", number(r.preconditioner_build_ms)},
          {"ms_per_step_jacobi", number(r.ms_per_step_jacobi)}, {"cg_iterations_jacobi", number(r.cg_iterations_jacobi)}};
}

Row row_from(const Json& j) {
  Row r;
  r.case_name = j.at("case").get<std::string>();
  r.model = j.at("model").get<std::string>();
  r.variant = j.at("variant").get<std::string>();
  r.resolution = j.at("resolution").get<std::string>();
  r.dofs = j.at("dofs").get<long long>();
  r.elements = j.at("elements").get<long long>();
  r.ms_per_step = j.at("ms_per_step").get<double>();
  r.cg_iterations = j.at("cg_iterations").get<double>();
  r.error_pct = j.at("error_pct").get<double>();
  r.converged = j.at("converged").get<bool>();
  r.tip = vec(j.at("tip"));
  r.measured_E = number(j.at("measured_E"));
  r.measured_nu = number(j.at("measured_nu"));
  if (j.contains("volume_change_pct")) r.volume_change_pct = number(j.at("volume_change_pct"));
  if (j.contains("preconditioner")) {
    r.preconditioner = j.at("preconditioner").get<std::string>();
    r.preconditioner_build_ms = number(j.at("preconditioner_build_ms"));
    r.ms_per_step_jacobi = number(j.at("ms_per_step_jacobi"));
    r.cg_iterations_jacobi = number(j.at("cg_iterations_jacobi"));
  }
  return r;
}

Json reference_json(const Reference& reference) {
  Json levels = Json::array();
  for (const Reference::Level& l : reference.levels)
    levels.push_back({{"mesh", l.mesh}, {"dofs", l.dofs}, {"tip", vec(l.tip)}, {"change_pct", l.change_pct}});
  return {{"tip", vec(reference.tip)}, {"element", reference.element}, {"levels", levels}};
}

Reference reference_from(const Json& j) {
  Reference reference;
  reference.tip = vec(j.at("tip"));
  reference.element = j.at("element").get<std::string>();
  for (const Json& l : j.at("levels"))
    reference.levels.push_back({l.at("mesh").get<std::string>(), l.at("dofs").get<long long>(), vec(l.at("tip")),
                                l.at("change_pct").get<double>()});
  return reference;
}

// The counts the printed figures use.
Json cut_report_json(const physics::VolumeCutReport& r) {
  return {{"particle_links_severed", r.particle_links_severed}, {"element_links_severed", r.element_links_severed},
          {"elements_reselected", r.elements_reselected},       {"elements_isolated", r.elements_isolated},
          {"reselection_failures", r.reselection_failures}};
}

physics::VolumeCutReport cut_report_from(const Json& j) {
  physics::VolumeCutReport r;
  r.particle_links_severed = j.at("particle_links_severed").get<int>();
  r.element_links_severed = j.at("element_links_severed").get<int>();
  r.elements_reselected = j.at("elements_reselected").get<int>();
  r.elements_isolated = j.at("elements_isolated").get<int>();
  r.reselection_failures = j.at("reselection_failures").get<int>();
  return r;
}

}  // namespace

void write_part_results(const std::filesystem::path& path, const Results& results) {
  Json rows = Json::array(), references = Json::object(), cut_reports = Json::object();
  for (const Row& row : results.rows) rows.push_back(row_json(row));
  for (const auto& [name, reference] : results.references) references[name] = reference_json(reference);
  for (const auto& [name, report] : results.cut_reports) cut_reports[name] = cut_report_json(report);
  const std::filesystem::path partial = path.string() + ".partial";
  {
    std::ofstream out(partial);
    out << Json{{"rows", rows}, {"references", references}, {"cut_reports", cut_reports}}.dump(1) << "\n";
    if (!out) throw std::runtime_error(partial.string() + ": cannot write");
  }
  std::filesystem::rename(partial, path);
}

Results read_part_results(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path.string() + ": cannot read a part's results");
  Results results;
  try {
    const Json j = Json::parse(in);
    for (const Json& row : j.at("rows")) results.rows.push_back(row_from(row));
    for (const auto& [name, reference] : j.at("references").items()) results.references[name] = reference_from(reference);
    for (const auto& [name, report] : j.at("cut_reports").items()) results.cut_reports[name] = cut_report_from(report);
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(path.string() + ": not a part's results: " + e.what());
  }
  return results;
}

}  // namespace incise::bench::accuracy
