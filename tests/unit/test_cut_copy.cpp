// Copying a cuttable body's data copies its cut (physics/cut/cut_body.hpp): a body and its copy,
// made in the middle of a stroke, cut alike through the rest of it and through a second one,
// bit for bit (the EFG rows and masses, the surface, its mapping, the severed links), and
// cutting the copy leaves the original as it was. And the rest cut of a stroke over several
// steps is joined at the steps' seams.
#include "physics/core/executor.hpp"
#include "physics/cut/apply_topology.hpp"
#include "physics/cut/cut_body.hpp"
#include "physics/cut/detect_cuts.hpp"
#include "physics/cut/voxel_boundary.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

using namespace incise::physics;

namespace {

constexpr double a = 0.0025;  // integration cube side
const Vec3 lo(0, -0.01, -0.01), hi(0.04, 0.01, 0.01);

// A cuttable body as the engine holds one (engine/models/efg_model.cpp), without the engine:
// a block 40 x 20 x 20 mm at rest, its cut made for its EFG model. Copying it is what the
// engine's body does: the data, then the cut for the copied model.
struct CutBody {
  BodyModel model;
  CutModel cut_model;
  BodyData data;
  CutData cut;
  CutTotals totals;
  long steps = 0;

  CutBody() {
    model.rest_lo = lo;
    model.rest_hi = hi;
    EfgSettings settings;
    settings.spacing = a;
    settings.samples_per_axis = 4;
    settings.threaded_elements = 0;
    auto efg = std::make_unique<CorotationalEfg>(lo, hi, Material{1e5, 0.3, 1000}, settings);
    data.efg = efg.get();
    data.mechanics = std::move(efg);
    cut_model.spacing = a;
    cut_model.surface_cell = a / 2;
    const auto in_box = [](const Vec3& p) { return (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all(); };
    TriangleSurface initial = voxel_boundary(in_box, lo, hi, cut_model.surface_cell);
    cut = make_cut_data(model, data, cut_model, std::move(initial.vertices), std::move(initial.triangles));
    const int n = data.mechanics->node_count();
    data.state.positions = data.mechanics->rest_positions();
    data.state.velocities = Vector::Zero(3 * n);
    data.warm_start.clear();
    data.fixed.assign(static_cast<std::size_t>(n), 0);
    data.gravity = Vector::Zero(3 * n);
    set_fixed_vertices(data);
    CorotationalEfg::surface_positions(*data.embedding, data.state.positions, data.surface_positions);
    cut.previous_positions = data.state.positions;
  }
  CutBody(const CutBody& other)
      : model(other.model),
        cut_model(other.cut_model),
        data(other.data),
        cut(other.cut, *data.efg),
        totals(other.totals),
        steps(other.steps) {}

  // One step: the blade from `from` to `to` (engaged or not) through the cut stages, then the
  // particles moved as a solve would move them (a sag growing with the steps), so that the
  // next sweep maps through a deformed body.
  void step(const std::vector<Vec3>& from, const std::vector<Vec3>& to, bool engaged) {
    ++steps;
    const std::vector<std::vector<Vec3>> poses{from, to};
    const std::vector<double> fractions{0, 1};
    const std::vector<std::uint8_t> active{static_cast<std::uint8_t>(engaged)};
    const BladeSweep blade{poses, fractions, active};
    CutStepReport report;
    const auto sweep = detect_cuts(cut_model, cut, data, blade, report);
    CutContext context{model, data, cut_model, cut, totals, report, false, steps};
    apply_topology(context, blade, sweep, serial_executor());
    cut.previous_positions = data.state.positions;
    const Vector& rest = data.mechanics->rest_positions();
    for (Eigen::Index p = 0; p < rest.size() / 3; ++p) {
      const double x = rest[3 * p] / hi.x();
      data.state.positions[3 * p + 2] = rest[3 * p + 2] - 2e-5 * static_cast<double>(steps) * x * x;
    }
    CorotationalEfg::surface_positions(*data.embedding, data.state.positions, data.surface_positions);
  }
};

// A straight blade along y, wider than the block, at (x, z).
std::vector<Vec3> blade_at(double x, double z) { return {Vec3(x, -0.03, z), Vec3(x, 0.03, z)}; }

// The two strokes: the first comes down through the whole block at x about 21 mm, drifting in
// x as it goes, then lifts out disengaged; the second comes down halfway at x = 31 mm (its
// crack ends inside the block). Step k moves the blade from pose k - 1 to pose k.
struct Pose {
  std::vector<Vec3> blade;
  bool engaged;
};
std::vector<Pose> strokes() {
  std::vector<Pose> poses;
  for (int k = 0; k <= 10; ++k) poses.push_back({blade_at(0.0205 + 0.0002 * k, 0.015 - 0.003 * k), true});
  for (int k = 0; k < 2; ++k) poses.push_back({blade_at(0.0225, 0.02), false});
  for (int k = 0; k <= 6; ++k) poses.push_back({blade_at(0.0307, 0.015 - 0.003 * k), k > 0});
  return poses;
}

// Whatever a later cut reads or the user sees, compared bit for bit.
void expect_same(const CutBody& x, const CutBody& y, const std::string& where) {
  const CorotationalEfg &ex = *x.data.efg, &ey = *y.data.efg;
  EXPECT_EQ(ex.row_lengths(), ey.row_lengths()) << where;
  EXPECT_EQ(ex.neighbours(), ey.neighbours()) << where;
  EXPECT_EQ(ex.shape_values(), ey.shape_values()) << where;
  EXPECT_TRUE(ex.shape_gradients() == ey.shape_gradients()) << where;
  EXPECT_EQ(ex.element_volumes(), ey.element_volumes()) << where;
  EXPECT_TRUE(ex.lumped_masses() == ey.lumped_masses()) << where;
  EXPECT_EQ(ex.orphaned_particles(), ey.orphaned_particles()) << where;
  EXPECT_TRUE(x.data.state.positions == y.data.state.positions) << where;
  EXPECT_EQ(x.data.fixed, y.data.fixed) << where;
  EXPECT_TRUE(x.data.gravity == y.data.gravity) << where;
  EXPECT_EQ(x.data.surface, y.data.surface) << where;
  EXPECT_EQ(x.data.render_cut_face, y.data.render_cut_face) << where;
  EXPECT_TRUE(x.data.surface_positions == y.data.surface_positions) << where;
  EXPECT_EQ(x.data.embedding->elements, y.data.embedding->elements) << where;
  EXPECT_EQ(x.data.embedding->particles, y.data.embedding->particles) << where;
  EXPECT_EQ(x.data.embedding->weights, y.data.embedding->weights) << where;
  EXPECT_TRUE(x.cut.surface->vertices() == y.cut.surface->vertices()) << where;
  EXPECT_EQ(x.cut.surface->triangles(), y.cut.surface->triangles()) << where;
  EXPECT_EQ(x.cut.surface->crack_front(), y.cut.surface->crack_front()) << where;
  EXPECT_EQ(x.cut.surface->stroke_samples(), y.cut.surface->stroke_samples()) << where;
  EXPECT_EQ(x.cut.cutter->particle_link_severed(), y.cut.cutter->particle_link_severed()) << where;
  EXPECT_EQ(x.cut.cutter->total_links_severed(), y.cut.cutter->total_links_severed()) << where;
  EXPECT_EQ(x.cut.rest_cut->size(), y.cut.rest_cut->size()) << where;
  EXPECT_TRUE(x.cut.rest_edge == y.cut.rest_edge) << where;
  EXPECT_EQ(x.cut.rest_edge_far, y.cut.rest_edge_far) << where;
  EXPECT_EQ(x.cut.linked.linked, y.cut.linked.linked) << where;
  EXPECT_EQ(x.totals.events, y.totals.events) << where;
  EXPECT_EQ(x.totals.links_severed, y.totals.links_severed) << where;
  EXPECT_EQ(x.totals.elements_reselected, y.totals.elements_reselected) << where;
  EXPECT_EQ(x.totals.vertices_remapped, y.totals.vertices_remapped) << where;
  EXPECT_EQ(x.totals.wrong_side, y.totals.wrong_side) << where;
}

}  // namespace

TEST(CutCopy, ACopyMadeInTheMiddleOfAStrokeCutsAsTheOriginalThroughItAndTheNext) {
  const std::vector<Pose> poses = strokes();
  constexpr std::size_t copy_after = 6;  // the blade halfway down the block: the front inside it
  CutBody original;
  for (std::size_t k = 1; k <= copy_after; ++k) original.step(poses[k - 1].blade, poses[k].blade, poses[k].engaged);
  ASSERT_GT(original.totals.events, 0);
  ASSERT_GT(original.cut.surface->stroke_samples(), 0) << "the copy is made with a stroke in progress";

  CutBody copy(original);
  // The copy's model is its own, and what refers to the model refers to it.
  EXPECT_NE(copy.data.efg, original.data.efg);
  EXPECT_EQ(copy.data.efg, copy.data.mechanics.get());
  EXPECT_EQ(copy.cut.mapping.cubes.model, original.cut.mapping.cubes.model ? copy.data.efg : nullptr);
  expect_same(original, copy, "at the copy");

  // Cutting only the copy leaves the original as it was (a second copy keeps it to compare).
  const CutBody kept(original);
  const long events_at_copy = original.totals.events;
  for (std::size_t k = copy_after + 1; k < poses.size(); ++k) copy.step(poses[k - 1].blade, poses[k].blade, poses[k].engaged);
  EXPECT_GT(copy.totals.events, events_at_copy + 3) << "the copy cut on, through both strokes";
  expect_same(original, kept, "after cutting the copy");

  // And the original, cut the same way, ends where the copy did, step by step as the kept one.
  CutBody again(kept);
  for (std::size_t k = copy_after + 1; k < poses.size(); ++k) {
    original.step(poses[k - 1].blade, poses[k].blade, poses[k].engaged);
    again.step(poses[k - 1].blade, poses[k].blade, poses[k].engaged);
    expect_same(original, again, "step " + std::to_string(k));
    if (::testing::Test::HasFailure()) return;
  }
  expect_same(original, copy, "at the end");
  EXPECT_EQ(original.totals.front_problems, 0) << original.totals.first_front_problem;
}

// BodyData alone (no cut): a copy has its own model, which steps on as the original's.
TEST(CutCopy, BodyDataCopiesItsModelAndKeepsEfgOnIt) {
  CutBody body;
  const BodyData copy(body.data);
  ASSERT_NE(copy.mechanics.get(), body.data.mechanics.get());
  EXPECT_EQ(copy.efg, copy.mechanics.get());
  EXPECT_EQ(&copy.efg->executor(), &body.data.efg->executor()) << "the executor is borrowed, as is";
  Vector x = body.data.state.positions;
  for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += 1e-4 * std::sin(static_cast<double>(i));
  copy.mechanics->update_rotations(x);
  body.data.mechanics->update_rotations(x);
  Vector f_copy = Vector::Zero(x.size()), f_original = Vector::Zero(x.size());
  copy.mechanics->add_elastic_forces(x, f_copy);
  body.data.mechanics->add_elastic_forces(x, f_original);
  EXPECT_TRUE(f_copy == f_original);
  BodyData assigned;
  assigned = copy;
  EXPECT_EQ(assigned.efg, assigned.mechanics.get());
  EXPECT_TRUE(assigned.mechanics->lumped_masses() == body.data.mechanics->lumped_masses());
}

// A stroke over several steps: each step's sheet at rest starts from the line the step before
// ended with (CutData::rest_edge), though that line, mapped again after the step's topology
// change, has moved: seam quads join the two, so that no link passes between two steps'
// sheets (cut_torus with the onset hung its sector by such a link). Where the line lies outside
// the body (beyond 2a of the integration points), no quad is kept, as anywhere in the sweep.
TEST(CutRestSeams, EachStepsSheetStartsFromTheLineTheStepBeforeEndedWith) {
  const std::vector<Pose> poses = strokes();
  CutBody body;
  double widest = 0;
  int joined = 0;
  for (std::size_t k = 1; k <= 10; ++k) {  // the first stroke, engaged throughout
    const std::vector<Vec3> edge = body.cut.rest_edge;
    const std::vector<double> far = body.cut.rest_edge_far;
    const bool going_on = body.cut.engaged && !edge.empty();
    const int before = body.cut.rest_cut->size();
    body.step(poses[k - 1].blade, poses[k].blade, poses[k].engaged);
    ASSERT_EQ(body.cut.rest_edge.size(), body.cut.rest_edge_far.size());
    ASSERT_FALSE(body.cut.rest_edge.empty()) << "step " << k << " ended engaged";
    if (!going_on) continue;
    ++joined;
    const auto& triangles = body.cut.rest_cut->triangles();
    for (std::size_t i = 0; i + 1 < edge.size(); ++i) {
      if (std::min(far[i], far[i + 1]) > 2 * a) continue;
      bool found = false;
      for (std::size_t t = static_cast<std::size_t>(before); t < triangles.size() && !found; ++t)
        if (triangles[t].a == edge[i] && triangles[t].b == edge[i + 1]) {
          found = true;
          widest = std::max(widest, (triangles[t].c - edge[i + 1]).norm());
        }
      EXPECT_TRUE(found) << "step " << k << ": no triangle of the new sheet on the last line's piece " << i;
    }
  }
  EXPECT_EQ(joined, 9);
  EXPECT_GT(widest, 0) << "the line mapped again after a topology change moved: a seam to close";
  std::printf("widest seam closed: %.3g m\n", widest);
  // Lifted out disengaged, the stroke ends: no line to start from.
  body.step(poses[10].blade, poses[11].blade, poses[11].engaged);
  EXPECT_TRUE(body.cut.rest_edge.empty());
}
