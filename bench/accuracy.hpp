// The error-against-run-time report of the deformable models (issue 3): `incise bench
// accuracy [--quick] --out DIR`.
#pragma once

#include <Eigen/Core>

#include <filesystem>
#include <ostream>

namespace incise::bench {

// Writes DIR/accuracy.csv, DIR/references.json, DIR/accuracy.gnuplot and (with gnuplot)
// DIR/accuracy.png. Progress and the reference refinement checks go to `progress`.
// Returns 0 on success, 1 on failure (with a message on `progress`).
int run_accuracy_bench(bool quick, const std::filesystem::path& out_dir, std::ostream& progress);

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
