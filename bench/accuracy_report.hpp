// What `incise bench accuracy` writes (accuracy_report.cpp): its rows and references, the CSV,
// references.json, the plot, the page and the figures it prints; and a part's results as JSON
// (accuracy_part.json), which the batch's merge joins into the same report (docs/batch.md).
#pragma once

#include "bench/accuracy_beams.hpp"
#include "bench/accuracy_mass_spring.hpp"

#include <chrono>
#include <filesystem>
#include <limits>
#include <map>
#include <ostream>
#include <string>
#include <vector>

namespace incise::bench::accuracy {

struct Row {
  std::string case_name, model, variant;
  std::string resolution;
  long long dofs = 0, elements = 0;
  double ms_per_step = 0, cg_iterations = 0, error_pct = 0;
  bool converged = true;
  Vec3 tip = Vec3::Zero();  // the mean tip displacement (printed, not in the CSV)
  double measured_E = std::numeric_limits<double>::quiet_NaN();  // the traction case only
  double measured_nu = std::numeric_limits<double>::quiet_NaN();
  double volume_change_pct = std::numeric_limits<double>::quiet_NaN();  // the compression case only
  // The CG's preconditioner of ms_per_step (accuracy_beams.hpp's Timing), its factor's build
  // and, for the rows with a factor, today's Jacobi CG on the same steps (NaN: not run).
  std::string preconditioner = "jacobi";
  double preconditioner_build_ms = std::numeric_limits<double>::quiet_NaN();
  double ms_per_step_jacobi = std::numeric_limits<double>::quiet_NaN();
  double cg_iterations_jacobi = std::numeric_limits<double>::quiet_NaN();
};
// Copies a timing's preconditioner, build and Jacobi figures into its row.
void take_solver(Row& row, const Timing& timing);
Row from_mass_spring(const MassSpringRow& r);

struct Reference {
  Vec3 tip = Vec3::Zero();
  std::string element;
  struct Level {
    std::string mesh;
    long long dofs = 0;
    Vec3 tip = Vec3::Zero();
    double change_pct = 0;  // against the previous level
  };
  std::vector<Level> levels;
};

// What the runs found: rows in the order run, references per case, and what the cutter did
// per variant and resolution ("nb8_cutter a2mm").
struct Results {
  std::vector<Row> rows;
  std::map<std::string, Reference> references;
  std::map<std::string, physics::VolumeCutReport> cut_reports;
  // Appends another part's results (the parts run disjoint cases).
  void add(const Results& other);
};

// This report's figures: 4 significant digits unless a caller asks for others.
std::string format(double value, int digits = 4);
// A tip displacement in mm, 5 decimals, for the progress notes.
std::string mm(const Vec3& v);

// Sorts the rows (case order, then model, variant and dofs) and writes accuracy.csv only.
void write_rows_csv(const std::filesystem::path& path, const std::vector<Case>& cases, std::vector<Row>& rows);

// The whole report of every case: accuracy.csv (sorted as above), references.json,
// accuracy.gnuplot and accuracy.png, report.html, and the figures on `progress`.
void write_report(const std::string& title, const std::vector<Case>& cases, Results& results, const std::filesystem::path& out_dir,
                  std::chrono::steady_clock::time_point start, std::ostream& progress);

// A part's results, exactly (doubles as JSON keeps them: shortest round trip), and back.
void write_part_results(const std::filesystem::path& path, const Results& results);
Results read_part_results(const std::filesystem::path& path);

}  // namespace incise::bench::accuracy
