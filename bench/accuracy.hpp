// The error-against-run-time report of the deformable models (issue 3): `incise bench
// accuracy [--quick] --out DIR`.
#pragma once

#include <Eigen/Core>

#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

namespace incise::bench {

// The whole report, a part of it (a batch job) or the join of the parts (the batch's merge).
// The units of work are the bodies (a shape, cut or not, with the cases that load it), then the
// `traction` and `compression` cases: a part runs the units whose index modulo `parts` is `part`, each body with
// its own references (they serve only its cases), so no part needs another's (docs/batch.md).
struct AccuracyOptions {
  bool quick = false;
  bool as_part = false;  // run the part-th of `parts` parts: DIR/accuracy_part.json and its accuracy.csv
  int part = 0;
  int parts = 1;
  // Comma-separated case names (accuracy_case_names()), a subset of the report; empty: all.
  std::string cases;
  // Folders of the parts' accuracy_part.json: run nothing, write the whole report from them.
  std::vector<std::filesystem::path> join;
};

// Writes DIR/accuracy.csv, DIR/references.json, DIR/accuracy.gnuplot, (with gnuplot)
// DIR/accuracy.png and DIR/report.html; a part writes DIR/accuracy_part.json (its rows,
// references and cutter reports, exactly) and its rows as DIR/accuracy.csv. Progress and the
// reference refinement checks go to `progress`. Returns 0 on success, 1 on failure (with a
// message on `progress`).
// The report's cases, for --cases: bend, stretch, bend_cut, stretch_cut, b1, traction, compression;
// and the same as a comma-separated list for messages.
std::vector<std::string> accuracy_case_names();
std::string accuracy_case_list();

int run_accuracy_bench(const AccuracyOptions& options, const std::filesystem::path& out_dir, std::ostream& progress);

// The report's cut beams (bend_cut, stretch_cut: the hexagonal beam cut at x = 0.1 m from the
// top down to z = 0, under 9.81 m/s^2 along -z and +x), for the tests: their mean tip
// displacements (m), and the model's dofs.
struct CutBeamTips {
  Eigen::Vector3d bend_cut = Eigen::Vector3d::Zero();
  Eigen::Vector3d stretch_cut = Eigen::Vector3d::Zero();
  long long dofs = 0;
};
// The reference family (10-node tets, quarter points on the crack front, the cut conforming)
// with `rows` element rows either side of the front; the report converges it at 12.
CutBeamTips cut_beam_reference(int rows);
// efg nb8 (the model's defaults) with `cells` particle cells along the beam (odd: the cut lies
// between two particle layers), cut by the cutter or, `cutter` false, by the geometry.
CutBeamTips cut_beam_efg(int cells, bool cutter);

}  // namespace incise::bench
