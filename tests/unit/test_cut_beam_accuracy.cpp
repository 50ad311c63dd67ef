// The accuracy report's cut beams (issue 4's test list): efg nb8 cut by the cutter against the
// conforming 10-node-tet FEM, within the thesis's bounds (Magnoux Table 4.1: 0.8 % bend_cut,
// 3.7 % stretch_cut at about 10k dofs; the issue asks 1.5 % and 4 %).
//
// The reference is the finest mesh of `incise bench accuracy` (bench/accuracy.cpp): tet10
// with quarter points on the crack front, 16 rows either side of it (708k dofs), whose change
// from 12 rows is 0.017 % (bend_cut) and 0.098 % (stretch_cut); Richardson puts the latter
// 0.18 % short of the limit. Solving it takes minutes, so its tips are written here, and the
// first test re-solves the family's coarsest level and checks it against the value the same
// run printed: the written reference is the one this code computes.
#include "bench/accuracy.hpp"

#include <gtest/gtest.h>

#include <cstdio>

using incise::bench::CutBeamTips;
using incise::bench::cut_beam_efg;
using incise::bench::cut_beam_reference;

namespace {

// references.json, mesh hexagon_rows16_y8_x106_graded (m).
const Eigen::Vector3d reference_bend_cut(4.714029089e-05, -2.131180266e-08, -4.966382255e-03);
const Eigen::Vector3d reference_stretch_cut(2.543978912e-05, 5.802663660e-10, -9.426337356e-05);
// The same run, mesh hexagon_rows2_y8_x16_graded (15351 dofs).
const Eigen::Vector3d coarse_bend_cut(4.520428305e-05, -1.030551376e-06, -4.926453250e-03);
const Eigen::Vector3d coarse_stretch_cut(2.514166461e-05, 1.916616578e-08, -9.032516271e-05);

double error_pct(const Eigen::Vector3d& tip, const Eigen::Vector3d& reference) {
  return 100 * (tip - reference).norm() / reference.norm();
}

}  // namespace

TEST(CutBeamAccuracy, TheReferenceFamilyGivesTheWrittenCoarseLevel) {
  const CutBeamTips coarse = cut_beam_reference(2);
  EXPECT_EQ(coarse.dofs, 15351);
  EXPECT_LT(error_pct(coarse.bend_cut, coarse_bend_cut), 1e-6);
  EXPECT_LT(error_pct(coarse.stretch_cut, coarse_stretch_cut), 1e-6);
  // And the family converges towards the written reference: the coarse level is further from
  // it than the change between the two finest levels by far.
  EXPECT_GT(error_pct(coarse.stretch_cut, reference_stretch_cut), 2.0);
  EXPECT_LT(error_pct(coarse.bend_cut, reference_bend_cut), 1.5);
}

TEST(CutBeamAccuracy, EfgNb8CutByTheCutterIsWithinTheThesisBoundsOfTheConformingFem) {
  // About 10k dofs, the thesis's size: a = 1.96 mm.
  const CutBeamTips at_10k = cut_beam_efg(51, true);
  const CutBeamTips geometry = cut_beam_efg(51, false);
  // 24k dofs: a = 1.41 mm.
  const CutBeamTips at_24k = cut_beam_efg(71, true);
  const double bend = error_pct(at_10k.bend_cut, reference_bend_cut);
  const double stretch_10k = error_pct(at_10k.stretch_cut, reference_stretch_cut);
  const double stretch_24k = error_pct(at_24k.stretch_cut, reference_stretch_cut);
  std::printf("efg nb8 cutter: %lld dofs bend_cut %.3f %%, stretch_cut %.3f %%; %lld dofs bend_cut %.3f %%, "
              "stretch_cut %.3f %%; geometry cut at %lld dofs: %.3f %%, %.3f %%\n",
              at_10k.dofs, bend, stretch_10k, at_24k.dofs, error_pct(at_24k.bend_cut, reference_bend_cut),
              stretch_24k, geometry.dofs, error_pct(geometry.bend_cut, reference_bend_cut),
              error_pct(geometry.stretch_cut, reference_stretch_cut));
  EXPECT_GT(at_10k.dofs, 9000);
  EXPECT_LT(at_10k.dofs, 12000);
  EXPECT_LT(bend, 1.5);
  EXPECT_LT(error_pct(at_24k.bend_cut, reference_bend_cut), 1.5);
  // stretch_cut is 3.9 % at 10.7k dofs (4.2 % with support_factor 1.1547, one reason for 1.1:
  // docs/physics-choices.md) and converges: 2.2 % at 24k.
  EXPECT_LT(stretch_10k, 4.0);
  EXPECT_LT(stretch_24k, stretch_10k);
  // The cutter makes the neighbourhoods the geometry cut makes at build time.
  EXPECT_LT(error_pct(at_10k.stretch_cut, geometry.stretch_cut), 0.05);
  EXPECT_LT(error_pct(at_10k.bend_cut, geometry.bend_cut), 0.05);
}
