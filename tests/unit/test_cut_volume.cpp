// Volume cutting of the EFG model (physics/cut/volume_cut): what the blade severs, what the
// re-selected neighbourhoods look like, and the mechanics of the pieces it leaves.
#include "physics/core/implicit_euler.hpp"
#include "physics/cut/volume_cut.hpp"
#include "physics/fem/tet_mesh.hpp"

#include <Eigen/LU>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

using namespace incise::physics;

namespace {

constexpr double a = 0.0025;  // integration cube side; particles 5 mm apart

// A beam 0.1 x 0.02 x 0.02 m along +x.
CorotationalEfg make_beam() {
  EfgSettings settings;
  settings.spacing = a;
  settings.threaded_elements = 0;
  return CorotationalEfg(Vec3(0, -0.01, -0.01), Vec3(0.1, 0.01, 0.01), Material{1e5, 0.3, 1000}, settings);
}

// A straight blade along y, wider than the body, at height z.
std::vector<Vec3> blade_at(double x, double z) { return {Vec3(x, -0.03, z), Vec3(x, 0.03, z)}; }

// Every element's neighbours lie on its own side of the plane x = x_cut.
int elements_reaching_across(const CorotationalEfg& model, double x_cut) {
  int across = 0;
  for (int e = 0; e < model.element_count(); ++e) {
    const bool left = model.element_centres()[e].x() < x_cut;
    const size_t base = static_cast<size_t>(e) * model.row_stride();
    for (int k = 0; k < model.row_lengths()[e]; ++k) {
      const double px = model.rest_positions()[3 * model.neighbours()[base + k]];
      if ((px < x_cut) != left) {
        ++across;
        break;
      }
    }
  }
  return across;
}

}  // namespace

TEST(VolumeCut, ABladeThroughTheWholeSectionSplitsTheBodyInTwo) {
  CorotationalEfg model = make_beam();
  const Vector rest = model.rest_positions();
  const int dofs = 3 * model.node_count();
  const double mass = model.lumped_masses().sum();
  VolumeCutter cutter(model, 1e-6, 0.002);
  std::vector<int> piece;
  ASSERT_EQ(cutter.pieces(piece), 1);
  ASSERT_GT(elements_reaching_across(model, 0.051), 0);

  // One step takes the blade from above the beam to below it: a fast stroke, one sweep.
  const double x_cut = 0.051;  // between particle layers (5 mm apart) and off the cube centres
  const VolumeCutReport report = cutter.cut(blade_at(x_cut, 0.03), blade_at(x_cut, -0.03), rest, rest);
  std::printf("full cut: %d candidates, %d particle links and %d element links severed, %d elements "
              "re-selected, %d isolated, %d failures\n",
              report.candidates, report.particle_links_severed, report.element_links_severed,
              report.elements_reselected, report.elements_isolated, report.reselection_failures);
  // The particle layers either side are 5 x 5 particles: 25 links along x cross the plane.
  EXPECT_EQ(report.particle_links_severed, 25);
  EXPECT_GT(report.element_links_severed, 0);
  EXPECT_EQ(report.elements_isolated, 0);
  EXPECT_EQ(report.reselection_failures, 0);
  EXPECT_EQ(elements_reaching_across(model, x_cut), 0);
  EXPECT_EQ(cutter.pieces(piece), 2);
  // No DOF added or lost; mass moved, not created.
  EXPECT_EQ(3 * model.node_count(), dofs);
  EXPECT_NEAR(model.lumped_masses().sum(), mass, 1e-12 * mass);
  EXPECT_GT(model.lumped_masses().minCoeff(), 0.0);
  // Every hit lies on the cut plane, inside the body's section.
  for (const Vec3& hit : report.rest_hits) {
    EXPECT_NEAR(hit.x(), x_cut, 1e-9);
    EXPECT_LE(std::abs(hit.y()), 0.0125);
  }
  // A second pass of the same blade finds nothing left to cut.
  const VolumeCutReport again = cutter.cut(blade_at(x_cut, 0.03), blade_at(x_cut, -0.03), rest, rest);
  EXPECT_FALSE(again.any());
}

TEST(VolumeCut, APartialCutLeavesOnePieceJoinedAroundTheCrackFront) {
  CorotationalEfg model = make_beam();
  const Vector rest = model.rest_positions();
  VolumeCutter cutter(model, 1e-6, 0.002);
  // From the top down to z = 0: half the section.
  const VolumeCutReport report = cutter.cut(blade_at(0.051, 0.03), blade_at(0.051, 0.0), rest, rest);
  EXPECT_GT(report.particle_links_severed, 0);
  EXPECT_LT(report.particle_links_severed, 25);
  for (const Vec3& hit : report.rest_hits) EXPECT_GE(hit.z(), -1e-9);
  std::vector<int> piece;
  EXPECT_EQ(cutter.pieces(piece), 1);
  // Above the crack front, no element reaches across; below it, the body is whole.
  for (int e = 0; e < model.element_count(); ++e) {
    const Vec3 c = model.element_centres()[e];
    if (c.z() < 0.0026) continue;  // elements whose cells straddle the front may
    const size_t base = static_cast<size_t>(e) * model.row_stride();
    for (int k = 0; k < model.row_lengths()[e]; ++k) {
      const double px = model.rest_positions()[3 * model.neighbours()[base + k]];
      EXPECT_EQ(px < 0.051, c.x() < 0.051) << "element " << e;
    }
  }
}

TEST(VolumeCut, AStaticBladeCutsABodyMovingOntoIt) {
  CorotationalEfg model = make_beam();
  const Vector rest = model.rest_positions();
  VolumeCutter cutter(model, 1e-6, 0.002);
  // The blade does not move; the body passes down through it during the step.
  Vector above = rest, below = rest;
  for (int i = 0; i < model.node_count(); ++i) above[3 * i + 2] += 0.03, below[3 * i + 2] -= 0.03;
  const auto blade = blade_at(0.051, 0.0);
  const VolumeCutReport report = cutter.cut(blade, blade, above, below);
  EXPECT_EQ(report.particle_links_severed, 25);
  std::vector<int> piece;
  EXPECT_EQ(cutter.pieces(piece), 2);
}

TEST(VolumeCut, ABladeThatMissesTheBodyCutsNothing) {
  CorotationalEfg model = make_beam();
  const Vector rest = model.rest_positions();
  VolumeCutter cutter(model, 1e-6, 0.002);
  // Beyond the end of the beam, and passing above it.
  EXPECT_FALSE(cutter.cut(blade_at(0.13, 0.03), blade_at(0.13, -0.03), rest, rest).any());
  EXPECT_FALSE(cutter.cut(blade_at(0.05, 0.03), blade_at(0.07, 0.02), rest, rest).any());
}

TEST(VolumeCut, BadInputIsRefusedBeforeAnythingChanges) {
  CorotationalEfg model = make_beam();
  Vector rest = model.rest_positions();
  VolumeCutter cutter(model, 1e-6, 0.002);
  EXPECT_THROW(cutter.cut(blade_at(0.05, 0.03), {}, rest, rest), std::invalid_argument);
  Vector broken = rest;
  broken[7] = std::nan("");
  EXPECT_THROW(cutter.cut(blade_at(0.05, 0.03), blade_at(0.05, -0.03), rest, broken), std::invalid_argument);
  EXPECT_EQ(cutter.severed_particle_links(), 0);
}

// The mechanics after a full cut: the free piece falls as a rigid body, g t^2 / 2, while the
// clamped piece stays on its clamp. Internal forces of a piece sum to zero (the MLS gradients
// of a neighbourhood sum to zero), so implicit Euler moves the piece's centre of mass by
// exactly g dt^2 k (k + 1) / 2 after k steps, which is g t^2 / 2 within 1 / k.
TEST(VolumeCut, TheSeparatedPieceFallsFreely) {
  CorotationalEfg model = make_beam();
  const Vector rest = model.rest_positions();
  VolumeCutter cutter(model, 1e-6, 0.002);
  cutter.cut(blade_at(0.051, 0.03), blade_at(0.051, -0.03), rest, rest);
  std::vector<int> piece;
  ASSERT_EQ(cutter.pieces(piece), 2);

  const int n = model.node_count();
  std::vector<uint8_t> fixed = nodes_in_box(rest, Vec3::Constant(-1), Vec3(1e-9, 1, 1));
  // Particles of the free piece (x > cut): those its elements use.
  std::vector<uint8_t> free_particle(static_cast<size_t>(n), 0);
  for (int e = 0; e < model.element_count(); ++e) {
    if (model.element_centres()[e].x() < 0.051) continue;
    const size_t base = static_cast<size_t>(e) * model.row_stride();
    for (int k = 0; k < model.row_lengths()[e]; ++k) free_particle[model.neighbours()[base + k]] = 1;
  }
  const Vector& masses = model.lumped_masses();
  const auto centre_z = [&](const Vector& x) {
    double weighted = 0, total = 0;
    for (int i = 0; i < n; ++i)
      if (free_particle[i]) weighted += masses[i] * x[3 * i + 2], total += masses[i];
    return weighted / total;
  };
  State state{rest, Vector::Zero(3 * n)};
  const Vector gravity = gravity_forces(masses, Vec3(0, 0, -9.81));
  ImplicitEulerSettings settings;
  settings.dt = 0.004;
  settings.cg.tolerance = 1e-9;
  settings.cg.max_iterations = 2000;
  const double start = centre_z(state.positions);
  const int steps = 120;  // implicit Euler's fall is g dt^2 k (k + 1) / 2: 1 / k = 0.83 % above g t^2 / 2
  WarmStart warm_start;  // as the engine does
  for (int k = 0; k < steps; ++k) {
    const StepReport step = implicit_euler_step(model, state, fixed, gravity, {}, settings, &warm_start);
    ASSERT_FALSE(step.nonfinite);
  }
  const double t = steps * settings.dt;
  const double fallen = start - centre_z(state.positions);
  const double analytic = 0.5 * 9.81 * t * t;
  std::printf("free piece after %.2f s: fell %.5f m, g t^2 / 2 = %.5f m (%.3f %%)\n", t, fallen, analytic,
              100 * (fallen - analytic) / analytic);
  EXPECT_NEAR(fallen, analytic, 0.01 * analytic + 1e-9);
  // The clamped piece hangs on its clamp: it sags a little, it does not fall.
  double clamped_max = 0;
  for (int i = 0; i < n; ++i)
    if (!free_particle[i]) clamped_max = std::max(clamped_max, std::abs(state.positions[3 * i + 2] - rest[3 * i + 2]));
  EXPECT_LT(clamped_max, 0.02);
}

TEST(VolumeCut, ToRestPicksTheSameIntegrationPointAsAScanOfEveryElement) {
  // to_rest looks the nearest integration point up in bins it keeps between calls; the rule it
  // must keep is the scan in element order that takes a point only when it is nearer by a
  // relative 1e-9 (the lowest index among ties). Checked against that scan, written out here,
  // for points inside, on ties between points, just outside and far outside a deformed beam:
  // on the bins' first build, after a small motion (the kept bins, grown by the drift), after
  // a cut re-selected elements (tested apart), and after a motion beyond a spacing (rebuilt).
  CorotationalEfg model = make_beam();
  VolumeCutter cutter(model, 1e-6, 0.002);
  Vector x = model.rest_positions();
  for (int i = 0; i < model.node_count(); ++i) {
    const double s = x[3 * i];
    x[3 * i + 2] += 0.02 * s * s;                 // a bend
    x[3 * i + 1] += 0.05 * s * x[3 * i + 2];      // and a shear
  }
  unsigned state = 12345;
  const auto uniform = [&]() {
    state = state * 1664525u + 1013904223u;
    return static_cast<double>(state >> 8) / static_cast<double>(1u << 24);
  };
  const auto check = [&](const Vector& positions, const char* phase, const std::vector<int>& focus = {}) {
    std::vector<Vec3> points;
    cutter.integration_points(positions, points);
    std::vector<Vec3> world;
    for (int k = 0; k < 400; ++k)
      world.emplace_back(-0.02 + 0.14 * uniform(), -0.03 + 0.06 * uniform(), -0.03 + 0.06 * uniform());
    // Midway between two neighbouring points, and nearly so (ties and near-ties).
    for (int e = 0; e + 1 < model.element_count(); e += 37) {
      const Vec3 middle = 0.5 * (points[e] + points[e + 1]);
      world.push_back(middle);
      world.push_back(middle + 1e-12 * (points[e + 1] - points[e]));
      world.push_back(points[e]);
    }
    world.emplace_back(1.0, 2.0, -3.0);  // far away
    // At and between the points of the elements in focus and their neighbours in index.
    for (int e : focus) {
      world.push_back(points[e]);
      for (int other : {e - 1, e + 1})
        if (other >= 0 && other < model.element_count()) world.push_back(0.5 * (points[e] + points[other]));
    }
    std::vector<Vec3> rest;
    std::vector<double> distance;
    cutter.to_rest(positions, world, rest, &distance);
    ASSERT_EQ(rest.size(), world.size());
    int ties = 0;
    for (size_t w = 0; w < world.size(); ++w) {
      int nearest = 0;
      double best = std::numeric_limits<double>::infinity();
      for (int e = 0; e < model.element_count(); ++e) {
        const double d = (points[e] - world[w]).squaredNorm();
        if (d < best * (1 - 1e-9)) best = d, nearest = e;
      }
      int close = 0;
      for (int e = 0; e < model.element_count(); ++e) close += (points[e] - world[w]).squaredNorm() <= best * (1 + 1e-9) ? 1 : 0;
      ties += close > 1 ? 1 : 0;
      ASSERT_EQ(distance[w], std::sqrt(best)) << phase << ", point " << w;
      // The mapped point is the chosen element's: X_e + F_e^-1 (x - x_e).
      Mat3 fit = Mat3::Zero();
      const size_t base = static_cast<size_t>(nearest) * model.row_stride();
      for (int k = 0; k < model.row_lengths()[nearest]; ++k)
        fit += positions.segment<3>(3 * model.neighbours()[base + k]) * model.matching_coefficients()[base + k].transpose();
      const Eigen::FullPivLU<Mat3> lu(fit);
      const Vec3 offset = world[w] - points[nearest];
      const Vec3 expected = model.element_centres()[nearest] + (lu.isInvertible() ? Vec3(lu.solve(offset)) : offset);
      ASSERT_EQ(rest[w], expected) << phase << ", point " << w << ": expected element " << nearest;
    }
    EXPECT_GT(ties, 10) << phase << ": the case exercises ties";
  };
  check(x, "first build");
  EXPECT_EQ(cutter.rest_search_rebuilds(), 1);
  // A motion well under a spacing (a = 2.5 mm): the bins are kept.
  Vector moved = x;
  for (int i = 0; i < model.node_count(); ++i) moved[3 * i + 2] += 2e-4 * std::sin(60 * x[3 * i]), moved[3 * i] += 1e-4;
  check(moved, "small motion");
  EXPECT_EQ(cutter.rest_search_rebuilds(), 1);
  // A motion beyond a spacing: rebuilt. The part beyond x = 0.051 is lifted by 4 a, so that
  // the elements the cut below re-selects there move far: their old fits spanned both parts.
  for (int i = 0; i < model.node_count(); ++i) {
    moved[3 * i + 1] += 0.004;
    if (model.rest_positions()[3 * i] > 0.051) moved[3 * i + 2] += 0.01;
  }
  check(moved, "large motion");
  EXPECT_EQ(cutter.rest_search_rebuilds(), 2);
  // A cut re-selects elements: their points move by more than the drift (none: the bins were
  // built at these positions), so they are tested apart.
  const VolumeCutReport report = cutter.cut(blade_at(0.051, 0.04), blade_at(0.051, 0.0), moved, moved);
  ASSERT_GT(report.elements_reselected, 0);
  check(moved, "after a cut", report.changed_elements);
  EXPECT_EQ(cutter.rest_search_rebuilds(), 2);
}

// The broad phase only narrows the search: over a progressive cut (a blade lowered in small
// steps, then a second stroke across the first, then strokes while the body moves and bends),
// the links severed in each call are exactly those the narrow test finds when it is run on
// every link of the graph as it stands, with this call's endpoints. Re-selection makes links
// several spacings long (a severed corner's mirror), and re-selected elements must never be
// tested with the particles of their old rows.
TEST(VolumeCut, EachCallSeversExactlyTheLinksABruteForceTestOfEveryLinkHits) {
  CorotationalEfg model = make_beam();
  const Vector rest = model.rest_positions();
  const int n = model.node_count();
  VolumeCutter cutter(model, 1e-6, 0.002);
  // The body's motion: a translation and a bend growing with the step number.
  const auto posed = [&](int step) {
    Vector x = rest;
    const double s = std::max(0, step - 12) * 0.002;
    for (int i = 0; i < n; ++i) {
      const double px = rest[3 * i];
      x[3 * i + 1] += 0.5 * s;
      x[3 * i + 2] += s * (1 + 40 * px * px);
    }
    return x;
  };
  struct Stroke {
    std::vector<Vec3> from, to;
  };
  std::vector<Stroke> strokes;
  for (int k = 0; k < 10; ++k) strokes.push_back({blade_at(0.051, 0.03 - 0.004 * k), blade_at(0.051, 0.026 - 0.004 * k)});
  // Along the beam, across the first cut, from x = 0.03 to 0.07 at mid-height.
  for (int k = 0; k < 4; ++k) {
    const double x0 = 0.03 + 0.01 * k, x1 = x0 + 0.01;
    strokes.push_back({{Vec3(x0, 0.0013, 0.03), Vec3(x0, 0.0013, -0.002)}, {Vec3(x1, 0.0013, 0.03), Vec3(x1, 0.0013, -0.002)}});
  }
  // While the body moves up through a blade lowered along x = 0.0763.
  for (int k = 0; k < 6; ++k) strokes.push_back({blade_at(0.0763, 0.02 - 0.005 * k), blade_at(0.0763, 0.015 - 0.005 * k)});

  int total_particle = 0, total_element = 0;
  std::vector<Vec3> points_start, points_end;
  for (size_t step = 0; step < strokes.size(); ++step) {
    const Vector x0 = posed(static_cast<int>(step)), x1 = posed(static_cast<int>(step) + 1);
    const auto& blade0 = strokes[step].from;
    const auto& blade1 = strokes[step].to;
    // The cutter's narrow test for one interval [0, 1], endpoints formed as it forms them.
    const auto hits = [&](const Vec3& a0, const Vec3& b0, const Vec3& a1, const Vec3& b1) {
      const MovingSegment edge{{a0, b0}, {a0 + 1.0 * (a1 - a0), b0 + 1.0 * (b1 - b0)}};
      return first_polyline_hit(blade0, blade1, edge).has_value();
    };
    const auto at = [](const Vector& x, int p) { return Vec3(x.segment<3>(3 * p)); };
    std::vector<std::uint8_t> expected_particle(cutter.particle_links().size(), 0);
    for (size_t l = 0; l < cutter.particle_links().size(); ++l) {
      if (cutter.particle_link_severed()[l]) continue;
      const auto [p, q] = cutter.particle_links()[l];
      expected_particle[l] = hits(at(x0, p), at(x0, q), at(x1, p), at(x1, q)) ? 1 : 0;
    }
    cutter.integration_points(x0, points_start);
    cutter.integration_points(x1, points_end);
    std::vector<std::pair<int, int>> expected_element;  // (element, particle)
    for (int e = 0; e < model.element_count(); ++e) {
      if (!model.element_active(e)) continue;
      const size_t base = static_cast<size_t>(e) * model.row_stride();
      for (int k = 0; k < model.row_lengths()[e]; ++k) {
        const int p = model.neighbours()[base + k];
        if (hits(points_start[e], at(x0, p), points_end[e], at(x1, p))) expected_element.emplace_back(e, p);
      }
    }
    const std::vector<std::uint8_t> severed_before = cutter.particle_link_severed();
    const VolumeCutReport report = cutter.cut(blade0, blade1, x0, x1);
    int particle_hits = 0;
    for (size_t l = 0; l < expected_particle.size(); ++l) {
      const bool severed_now = cutter.particle_link_severed()[l] && !severed_before[l];
      EXPECT_EQ(severed_now, expected_particle[l] != 0) << "step " << step << ", particle link " << l;
      particle_hits += expected_particle[l];
    }
    EXPECT_EQ(report.particle_links_severed, particle_hits) << "step " << step;
    EXPECT_EQ(report.element_links_severed, static_cast<int>(expected_element.size())) << "step " << step;
    std::vector<int> elements;
    for (const auto& [e, p] : expected_element) {
      if (elements.empty() || elements.back() != e) elements.push_back(e);
      const size_t base = static_cast<size_t>(e) * model.row_stride();
      for (int k = 0; k < model.row_lengths()[e]; ++k)
        EXPECT_NE(model.neighbours()[base + k], p) << "step " << step << ": element " << e << " kept a severed particle";
    }
    EXPECT_EQ(report.changed_elements, elements) << "step " << step;
    total_particle += particle_hits;
    total_element += static_cast<int>(expected_element.size());
  }
  std::printf("%zu calls: brute force finds %d particle links and %d element links to sever\n",
              strokes.size(), total_particle, total_element);
  // The strokes did cut, in every phase.
  EXPECT_GT(total_particle, 40);
  EXPECT_GT(total_element, 200);
}

// cut() forms the integration points and box-tests the links near the sweep only, found in
// bins kept between calls with a bound on how far anything moved since (near_search_rebuilds).
// Its outcome must be exactly that of a scan of every element and link (set_full_scan): the
// same candidates from the broad phase (so the same tree updates), the same links severed,
// at the same places, the same rows. The calls: strokes with a rest cut (the agreement pass);
// the body moved away while the blade is elsewhere (a rebuild right after a re-selection: the
// re-selected elements are refit where they are, far from the blade, and their old boxes
// must leave the blade's way); the body creeping around a blade left in the cut (elements
// re-selected earlier, not stale, moved beyond their slack); strokes where the body was; a body thrown far away and back
// through a blade in one call; a body creeping onto a static blade (no rebuild, only the
// drift bound finds the links that reach it).
TEST(VolumeCut, TheNearSearchGivesExactlyWhatAScanOfEveryElementAndLinkGives) {
  CorotationalEfg searched_model = make_beam();
  CorotationalEfg scanned_model = make_beam();
  const Vector rest = searched_model.rest_positions();
  const int n = searched_model.node_count();
  // Little slack: the boxes of links that moved a fraction of a spacing are updated.
  VolumeCutter searched(searched_model, 1e-6, 0.0002);
  VolumeCutter scanned(scanned_model, 1e-6, 0.0002);
  scanned.set_full_scan(true);
  const auto shifted = [&](const Vec3& by) {
    Vector x = rest;
    for (int i = 0; i < n; ++i) x.segment<3>(3 * i) += by;
    return x;
  };
  struct Call {
    std::vector<Vec3> from, to;
    Vec3 body_from, body_to;
    double rest_x = -1;  // > 0: a rest cut, the plane x = rest_x above z = depth
    double depth = 0;
  };
  std::vector<Call> calls;
  const Vec3 none = Vec3::Zero(), along(0.02, 0, 0), far(0, 0.5, 0);
  for (int k = 0; k < 4; ++k) {
    const double z0 = 0.012 - 0.004 * k, z1 = z0 - 0.004;
    calls.push_back({blade_at(0.051, z0), blade_at(0.051, z1), none, none, 0.051 + 0.4 * a, z1});
  }
  // The body creeping up around a blade left in the cut: the elements re-selected by the
  // strokes move beyond their boxes' slack (the tree needs their update).
  const Vec3 step_up(0, 0, 0.15 * a);
  for (int k = 0; k < 3; ++k)
    calls.push_back({blade_at(0.0505, -0.003), blade_at(0.0505, -0.003), k * step_up, (k + 1) * step_up});
  // One more stroke (its re-selected elements are stale), then the body moves away.
  calls.push_back({blade_at(0.051, -0.004), blade_at(0.051, -0.008), 3 * step_up, 3 * step_up, 0.051 + 0.4 * a,
                   -0.008 - 3 * step_up.z()});
  calls.push_back({blade_at(0.051, 0.05), blade_at(0.051, 0.05), 3 * step_up, along});
  for (int k = 0; k < 4; ++k) {
    const double z0 = 0.012 - 0.004 * k, z1 = z0 - 0.004;
    calls.push_back({blade_at(0.051, z0), blade_at(0.051, z1), along, along, 0.031 + 0.4 * a, z1});
  }
  calls.push_back({blade_at(0.0763, 0.0), blade_at(0.0763, 0.0), along, along + far});
  calls.push_back({blade_at(0.0763, 0.0), blade_at(0.0763, 0.0), along + far, along});
  for (int k = 0; k < 8; ++k) {
    const Vec3 up0(0, 0, 0.15 * a * k), up1(0, 0, 0.15 * a * (k + 1));
    calls.push_back({blade_at(0.09, 0.0104), blade_at(0.09, 0.0104), along + up0, along + up1});
  }

  int severed = 0, at_rest = 0, candidates_far = 0;
  for (size_t c = 0; c < calls.size(); ++c) {
    const Call& call = calls[c];
    const Vector x0 = shifted(call.body_from), x1 = shifted(call.body_to);
    VolumeCutter::RestVisibility visibility;
    if (call.rest_x > 0) {
      const double xc = call.rest_x, depth = call.depth;
      visibility.blocked = [xc, depth](const Vec3& p, const Vec3& q) {
        if ((p.x() - xc) * (q.x() - xc) >= 0) return false;
        const double t = (xc - p.x()) / (q.x() - p.x());
        return p.z() + t * (q.z() - p.z()) >= depth;
      };
      visibility.lo = Vec3(xc - 2 * a, -0.03, depth - 2 * a);
      visibility.hi = Vec3(xc + 2 * a, 0.03, 0.03);
    }
    const std::vector<std::vector<Vec3>> poses{call.from, call.to};
    const std::vector<double> fractions{0.0, 1.0};
    const std::vector<std::uint8_t> active{1};
    const VolumeCutter::RestVisibility* rest_cut = call.rest_x > 0 ? &visibility : nullptr;
    const VolumeCutReport s = searched.cut(poses, fractions, active, x0, x1, rest_cut);
    const VolumeCutReport f = scanned.cut(poses, fractions, active, x0, x1, rest_cut);
    EXPECT_EQ(s.candidates, f.candidates) << "call " << c;
    EXPECT_EQ(s.particle_links_severed, f.particle_links_severed) << "call " << c;
    EXPECT_EQ(s.element_links_severed, f.element_links_severed) << "call " << c;
    EXPECT_EQ(s.links_severed_at_rest, f.links_severed_at_rest) << "call " << c;
    EXPECT_EQ(s.elements_reselected, f.elements_reselected) << "call " << c;
    EXPECT_EQ(s.elements_isolated, f.elements_isolated) << "call " << c;
    EXPECT_EQ(s.reselection_failures, f.reselection_failures) << "call " << c;
    EXPECT_EQ(s.changed_elements, f.changed_elements) << "call " << c;
    ASSERT_EQ(s.rest_hits.size(), f.rest_hits.size()) << "call " << c;
    for (size_t h = 0; h < s.rest_hits.size(); ++h) EXPECT_EQ(s.rest_hits[h], f.rest_hits[h]) << "call " << c << ", hit " << h;
    EXPECT_EQ(searched.particle_link_severed(), scanned.particle_link_severed()) << "call " << c;
    EXPECT_EQ(searched_model.row_lengths(), scanned_model.row_lengths()) << "call " << c;
    EXPECT_EQ(searched_model.neighbours(), scanned_model.neighbours()) << "call " << c;
    severed += s.particle_links_severed + s.element_links_severed;
    at_rest += s.links_severed_at_rest;
    if (c >= 9 && c < 13) candidates_far += s.candidates;
  }
  std::printf("%zu calls: %d links severed, %d at rest, %ld rebuilds of the near search\n", calls.size(), severed,
              at_rest, searched.near_search_rebuilds());
  // Every phase did something: cuts, the rest cut's agreement, several rebuilds.
  EXPECT_GT(severed, 200);
  EXPECT_GT(candidates_far, 0);
  EXPECT_GE(searched.near_search_rebuilds(), 3);
}

// A blade drawn along a layer of particles (the degenerate case: the particles of the plane
// y = 0 lie in the sweep) re-selects the same elements again and again as it advances. Each
// re-selection must stay local: an element's neighbours within two particle spacings of its
// point along every axis (the corners of its particle cell and, past a cut, the next layer:
// offsets of a / 2, 3a / 2, 5a / 2 or 7a / 2), never carried along with the blade.
TEST(VolumeCut, ABladeDrawnAlongAParticleLayerKeepsEveryNeighbourhoodLocal) {
  CorotationalEfg model = make_beam();
  const Vector rest = model.rest_positions();
  const int dofs = 3 * model.node_count();
  VolumeCutter cutter(model, 1e-6, 0.002);
  // A vertical edge from above the beam down to z = -0.002 (past mid-depth), drawn along x in
  // steps of a / 5 at y = 0.
  const auto edge = [](double x) { return std::vector<Vec3>{Vec3(x, 0, 0.03), Vec3(x, 0, -0.002)}; };
  long reselected = 0;
  int failures = 0;
  for (int k = 0; k < 160; ++k) {
    const double x0 = 0.01 + k * a / 5, x1 = x0 + a / 5;
    const VolumeCutReport report = cutter.cut(edge(x0), edge(x1), rest, rest);
    reselected += report.elements_reselected;
    failures += report.reselection_failures;
  }
  double farthest = 0;
  int worst = -1;
  for (int e = 0; e < model.element_count(); ++e) {
    if (!model.element_active(e)) continue;
    const size_t base = static_cast<size_t>(e) * model.row_stride();
    for (int k = 0; k < model.row_lengths()[e]; ++k) {
      const Vec3 p = model.rest_positions().segment<3>(3 * static_cast<Eigen::Index>(model.neighbours()[base + k]));
      const double offset = (p - model.element_centres()[e]).cwiseAbs().maxCoeff();
      if (offset > farthest) farthest = offset, worst = e;
    }
  }
  std::printf("blade along a particle layer: %ld re-selections, %d failures; farthest neighbour %.2f a from its "
              "point (element %d)\n", reselected, failures, farthest / a, worst);
  EXPECT_GT(reselected, 0);
  EXPECT_LE(farthest, 3.5 * a * (1 + 1e-9));
  EXPECT_EQ(3 * model.node_count(), dofs);
  EXPECT_GT(model.lumped_masses().minCoeff(), 0.0);
}
