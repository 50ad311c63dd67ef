// The mechanics of a beam cut by the cutter (physics/cut/volume_cut): a cantilever cut halfway
// through at mid-length is softer than the uncut one, by about what the same cut made as
// geometry at build time (EfgSettings::cuts) gives, and no neighbourhood reaches across the
// cut above its front. Static linear solves of the assembled stiffness, so every figure is an
// equilibrium, compared with independent models only (never with timings).
#include "physics/core/implicit_euler.hpp"
#include "physics/cut/volume_cut.hpp"
#include "physics/efg/efg_static.hpp"
#include "physics/fem/static_solve.hpp"
#include "physics/fem/tet_mesh.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

using namespace incise::physics;

namespace {

constexpr double a = 0.0025;      // integration cube side; particles 5 mm apart
constexpr double length = 0.1;    // the beam is 0.1 x 0.02 x 0.02 m along +x, clamped at x = 0
constexpr double half_side = 0.01;
constexpr double cut_x = 0.05;    // mid-length: a particle layer (x = 10 x 2a)
// The blade's plane: between the particle layer x = cut_x and the integration points at
// cut_x - a/2, a/4 from both, so that no link is touched at an end (the particles on the plane
// count on the +x side, as in the build-time rule); its edge stops 1e-3 a above the particle
// row z = 0, the crack front (accuracy.cpp gives the reasoning in full).
constexpr double blade_x = cut_x - a / 4;
constexpr double front_z = 1e-3 * a;
const Material material{1e6, 0.3, 1000};
const Vec3 gravity(0, 0, -9.81);

CorotationalEfg make_beam(const std::vector<CutRectangle>& cuts = {}) {
  EfgSettings settings;
  settings.spacing = a;
  settings.threaded_elements = 0;
  settings.cuts = cuts;
  return CorotationalEfg(Vec3(0, -half_side, -half_side), Vec3(length, half_side, half_side), material, settings);
}

// The cut from the top (z = +half_side) down to z = 0, across the whole width.
VolumeCutReport cut_with_the_cutter(CorotationalEfg& model) {
  VolumeCutter cutter(model, 1e-6, 0);
  const Vector rest = model.rest_positions();
  const std::vector<Vec3> start{Vec3(blade_x, -0.02, 0.02), Vec3(blade_x, 0.02, 0.02)};
  const std::vector<Vec3> end{Vec3(blade_x, -0.02, front_z), Vec3(blade_x, 0.02, front_z)};
  const VolumeCutReport report = cutter.cut(start, end, rest, rest);
  std::vector<int> piece;
  EXPECT_EQ(cutter.pieces(piece), 1) << "a cut halfway through leaves one piece";
  return report;
}

// Mean z displacement of the tip particles (x = length) under gravity, clamped at x = 0.
double tip_deflection(CorotationalEfg& model) {
  model.update_rotations(model.rest_positions());
  const Vector& rest = model.rest_positions();
  const std::vector<uint8_t> fixed = nodes_in_box(rest, Vec3::Constant(-1), Vec3(1e-9, 1, 1));
  const Vector u = solve_static(assemble_stiffness(model), gravity_forces(model.lumped_masses(), gravity), fixed);
  double sum = 0;
  int count = 0;
  for (int i = 0; i < model.node_count(); ++i) {
    if (std::abs(rest[3 * i] - length) > 1e-9) continue;
    sum += u[3 * i + 2];
    ++count;
  }
  EXPECT_GT(count, 0);
  return sum / count;
}

// Neighbour links (integration point to particle, at rest) that cross the cut's plane above
// its front: through x = blade_x at a height z > front_z, within the section.
int links_across_the_cut(const CorotationalEfg& model) {
  int across = 0;
  for (int e = 0; e < model.element_count(); ++e) {
    const Vec3 centre = model.element_centres()[e];
    const size_t base = static_cast<size_t>(e) * model.row_stride();
    for (int k = 0; k < model.row_lengths()[e]; ++k) {
      const Vec3 p = model.rest_positions().segment<3>(3 * model.neighbours()[base + k]);
      if ((centre.x() - blade_x) * (p.x() - blade_x) >= 0) continue;  // same side
      const double s = (blade_x - centre.x()) / (p.x() - centre.x());
      const Vec3 crossing = centre + s * (p - centre);
      if (crossing.z() > front_z) ++across;
    }
  }
  return across;
}

// Elements whose integration point lies above the front (z > 0) with a neighbour on the other
// side of the plane that is not below the front: a link that can only pass through the cut.
int elements_above_the_front_reaching_across(const CorotationalEfg& model) {
  int reaching = 0;
  for (int e = 0; e < model.element_count(); ++e) {
    const Vec3 centre = model.element_centres()[e];
    if (centre.z() <= 0) continue;
    const size_t base = static_cast<size_t>(e) * model.row_stride();
    for (int k = 0; k < model.row_lengths()[e]; ++k) {
      const Vec3 p = model.rest_positions().segment<3>(3 * model.neighbours()[base + k]);
      if ((centre.x() < blade_x) != (p.x() < blade_x) && p.z() >= 0) {
        ++reaching;
        break;
      }
    }
  }
  return reaching;
}

}  // namespace

TEST(CutAccuracy, TheCutterCutBeamDeflectsMoreThanTheUncutOneAndLikeTheGeometryCut) {
  CorotationalEfg uncut = make_beam();
  CorotationalEfg cut = make_beam();
  // The same cut made at build time: the open rectangle x = cut_x, z in (0, 1); particles on
  // the plane count on the +x side.
  CorotationalEfg geometry_cut = make_beam({{Vec3(cut_x, -1, 0), Vec3(0, 2, 0), Vec3(0, 0, 1)}});

  ASSERT_GT(links_across_the_cut(cut), 0) << "the check must see the links the cut is to remove";
  ASSERT_GT(elements_above_the_front_reaching_across(cut), 0);
  const int dofs = 3 * cut.node_count();
  const double mass = cut.lumped_masses().sum();
  const VolumeCutReport report = cut_with_the_cutter(cut);
  std::printf("cutter: %d candidates, %d particle links and %d element links severed, %d elements re-selected, "
              "%d isolated, %d failures\n",
              report.candidates, report.particle_links_severed, report.element_links_severed,
              report.elements_reselected, report.elements_isolated, report.reselection_failures);
  EXPECT_GT(report.element_links_severed, 0);
  EXPECT_EQ(report.elements_isolated, 0);
  EXPECT_EQ(report.reselection_failures, 0);
  EXPECT_EQ(3 * cut.node_count(), dofs);
  EXPECT_NEAR(cut.lumped_masses().sum(), mass, 1e-12 * mass);
  // Every hit lies in the blade's plane, above the front.
  for (const Vec3& hit : report.rest_hits) {
    EXPECT_NEAR(hit.x(), blade_x, 1e-9);
    EXPECT_GE(hit.z(), front_z - 1e-9);
  }

  // The neighbourhoods: nothing across the cut above its front, in the cutter's model as in the
  // geometry cut's.
  EXPECT_EQ(links_across_the_cut(cut), 0);
  EXPECT_EQ(elements_above_the_front_reaching_across(cut), 0);
  EXPECT_EQ(links_across_the_cut(geometry_cut), 0);

  const double w_uncut = tip_deflection(uncut);
  const double w_cut = tip_deflection(cut);
  const double w_geometry = tip_deflection(geometry_cut);
  const double extra_cut = w_cut / w_uncut - 1, extra_geometry = w_geometry / w_uncut - 1;
  const double against_geometry = (w_cut - w_geometry) / (w_geometry - w_uncut);
  std::printf("tip deflection: uncut %.6f mm, cutter %.6f mm (%+.2f %%), geometry cut %.6f mm (%+.2f %%); "
              "cutter - geometry = %+.2f %% of the geometry cut's extra deflection, %+.3f %% of its deflection\n",
              1e3 * w_uncut, 1e3 * w_cut, 100 * extra_cut, 1e3 * w_geometry, 100 * extra_geometry,
              100 * against_geometry, 100 * (w_cut / w_geometry - 1));
  ASSERT_LT(w_uncut, 0);
  // Softer than the uncut beam: the cut takes half the section's bending stiffness over a
  // stretch of the beam near mid-length.
  EXPECT_LT(w_cut, w_uncut);
  EXPECT_GT(extra_cut, 0.01);
  // And by about what the geometry cut gives. The two models differ only in how the broken
  // neighbourhoods are refilled (the cutter by graph distance, the build-time rule by the
  // particle behind the element's side of its cell), so their extra deflections agree to a few
  // %: measured +4.7 % here, and 3 to 7 % for nb8 on the accuracy bench's bend_cut beam at 1k to
  // 10k dofs. 15 % is three times that, while a cutter that missed the cut's links (-100 %), cut
  // below the front or through the whole section (far more than +100 %) fails it.
  EXPECT_NEAR(against_geometry, 0, 0.15);
}
