// Cutting in the engine: a blade following a recorded trajectory through a cuttable EFG body.
// After every cut event the surface is a closed 2-manifold, the DOF count is unchanged, no
// vertex follows the wrong side, and a piece cut free falls as g t^2 / 2.
#include "engine/replay.hpp"
#include "engine/scene.hpp"
#include "engine/trajectory.hpp"
#include "engine/world.hpp"
#include "physics/cut/front_mapping.hpp"
#include "render/frame.hpp"
#include "tests/unit/temp_dir.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <set>
#include <string>
#include <tuple>


using namespace incise::engine;
namespace physics = incise::physics;
using Json = nlohmann::json;
using incise::testing::TempDir;

namespace {

// A beam 0.1 x 0.02 x 0.02 m clamped at x = 0, and a straight blade along y that comes down
// through the whole section at x = 0.0512 in `cut_seconds`, engaged throughout.
Scene beam_cut_scene(const TempDir& dir, double cut_seconds, double blade_x = 0.0512) {
  std::vector<ToolSample> samples;
  const int count = static_cast<int>(std::lround(0.3 * 1000));
  for (int k = 0; k <= count; ++k) {
    ToolSample s;
    s.time = k / 1000.0;
    const double f = std::clamp((s.time - 0.02) / cut_seconds, 0.0, 1.0);
    s.position = {blade_x, 0, 0.03 - 0.06 * f};
    // Engaged on the way down; released once below the beam, so that the falling piece is
    // not sliced again on the resting blade (a static engaged blade cuts what moves onto it).
    s.buttons = f < 1 ? kToolButtonEngaged : 0;
    samples.push_back(s);
  }
  write_trajectory(dir.path / "cut.traj", samples);
  const Json scene = Json::parse(R"({
    "name": "beam_cut",
    "bodies": [{
      "name": "beam", "model": "efg", "cuttable": true,
      "generator": {"type": "box", "min": [0, -0.01, -0.01], "max": [0.1, 0.01, 0.01]},
      "resolution": 0.0025,
      "efg": {"surface_resolution": 0.00125, "samples_per_axis": 4},
      "material": {"E": 1e5, "nu": 0.3, "rho": 1000},
      "fixed": [{"min": [-1, -1, -1], "max": [0.0001, 1, 1]}]
    }],
    "tool": {"shape": "blade", "edge": [[0, -0.03, 0], [0, 0.03, 0]], "trajectory": "cut.traj"},
    "solver": {"dt": 0.005, "duration": 0.3, "tolerance": 1e-9, "max_iterations": 3000}
  })");
  return parse_scene(scene.dump(), dir.path / "scene.json");
}

// The free piece of the beam (particles right of the cut at x = 0.0512): how far its centre of
// mass falls over 40 more steps, and what free fall from its state now gives. Implicit Euler
// falls g dt^2 k (k + 1) / 2 over k steps, i.e. g t^2 / 2 within 1 / k.
struct Fall {
  double fallen, expected, seconds;
};
Fall free_piece_fall(World& world, const Body& body, const std::vector<int>& piece, double dt) {
  const auto& masses = body.data.mechanics->lumped_masses();
  std::vector<std::uint8_t> free_particle(static_cast<std::size_t>(body.data.mechanics->node_count()), 0);
  int tip = 0;  // the element farthest along the beam is on the free piece
  for (int e = 0; e < body.data.efg->element_count(); ++e)
    if (body.data.efg->element_centres()[e].x() > body.data.efg->element_centres()[tip].x()) tip = e;
  for (int e = 0; e < body.data.efg->element_count(); ++e) {
    if (piece[e] != piece[tip]) continue;
    EXPECT_GT(body.data.efg->element_centres()[e].x(), 0.0512) << "element " << e << " on the wrong piece";
    const std::size_t base = static_cast<std::size_t>(e) * body.data.efg->row_stride();
    for (int k = 0; k < body.data.efg->row_lengths()[e]; ++k) free_particle[body.data.efg->neighbours()[base + k]] = 1;
  }
  const auto centre = [&](const physics::Vector& v) {
    double weighted = 0, total = 0;
    for (int i = 0; i < body.data.mechanics->node_count(); ++i)
      if (free_particle[i]) weighted += masses[i] * v[3 * i + 2], total += masses[i];
    return weighted / total;
  };
  const double z0 = centre(body.data.state.positions), v0 = centre(body.data.state.velocities);
  const int fall_steps = 40;
  for (int k = 0; k < fall_steps; ++k) world.step();
  const double t = fall_steps * dt;
  return {z0 - centre(body.data.state.positions), -v0 * t + 0.5 * 9.81 * t * t, t};
}

}  // namespace

// What the cut keeps of the front surface where the stroke changed it (physics/cut/
// remap_surface.cpp) is what it would take from the whole surface: the body's and the
// render's triangles, the vertex positions, the edge counts, and the number of vertices whose
// point lies across a cut face (the worst so far is at least the current whole count, which
// is 0 on every shipped scene).
void expect_front_kept_as_whole(const World& world, const Body& body, const std::string& when) {
  const physics::FrontSurface& front = *body.cut->surface;
  ASSERT_TRUE(body.data.surface == front.triangles()) << when;
  ASSERT_EQ(body.data.render_triangles.size(), 3 * body.data.surface.size()) << when;
  for (std::size_t t = 0; t < body.data.surface.size(); ++t)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(body.data.render_triangles[3 * t + c], static_cast<std::uint32_t>(body.data.surface[t][c])) << when;
  // The cut-face flags the frame is drawn with are the surface's.
  ASSERT_TRUE(body.data.render_cut_face == front.on_cut_face()) << when;
  physics::Vector whole;
  physics::CorotationalEfg::surface_positions(*body.data.embedding, body.data.state.positions, whole);
  ASSERT_EQ(whole.size(), body.data.surface_positions.size()) << when;
  EXPECT_LE((whole - body.data.surface_positions).cwiseAbs().maxCoeff(), 1e-15) << when;
  // The planes each vertex was mapped with (the third trigger compares against them).
  ASSERT_EQ(body.cut->mapping.plane_counts.size(), front.vertex_planes().size()) << when;
  for (std::size_t v = 0; v < front.vertex_planes().size(); ++v)
    ASSERT_EQ(body.cut->mapping.plane_counts[v], front.vertex_planes()[v].size()) << when << ", vertex " << v;
  const physics::SurfaceTopology full = physics::surface_topology(body.data.surface);
  EXPECT_EQ(body.cut->topology.boundary_edges, full.boundary_edges) << when;
  EXPECT_EQ(body.cut->topology.nonmanifold_edges, full.nonmanifold_edges) << when;
  // The linked-across count kept around each cut (the elements found by their centres) is the
  // full one.
  EXPECT_EQ(world.cut_totals().elements_linked_across, physics::elements_linked_across(*body.data.efg, *body.cut->rest_cut)) << when;
  std::set<std::array<double, 9>> seen;
  std::vector<std::array<physics::Vec3, 3>> faces;
  std::vector<std::uint8_t> on_face(front.vertices().size(), 0);
  for (std::size_t t = 0; t < body.data.surface.size(); ++t) {
    if (!front.on_cut_face()[t]) continue;
    std::array<physics::Vec3, 3> corners;
    for (int c = 0; c < 3; ++c) {
      corners[static_cast<std::size_t>(c)] = front.vertices()[static_cast<std::size_t>(body.data.surface[t][static_cast<std::size_t>(c)])];
      on_face[static_cast<std::size_t>(body.data.surface[t][static_cast<std::size_t>(c)])] = 1;
    }
    std::sort(corners.begin(), corners.end(), [](const physics::Vec3& l, const physics::Vec3& r) {
      return std::lexicographical_compare(l.data(), l.data() + 3, r.data(), r.data() + 3);
    });
    std::array<double, 9> key{};
    for (int c = 0; c < 9; ++c) key[static_cast<std::size_t>(c)] = corners[static_cast<std::size_t>(c / 3)][c % 3];
    if (seen.insert(key).second) faces.push_back(corners);
  }
  std::vector<int> across;
  const physics::CutFaceIndex index(*body.data.efg, faces);
  physics::count_wrong_side(*body.data.efg, front.vertices(), body.data.surface, *body.data.embedding, index, 0.1 * front.front_width() / 1.5, {}, &across,
                            on_face);
  std::vector<int> off_crack;
  for (const int v : across)
    if (front.crack_front()[static_cast<std::size_t>(v)] == 0) off_crack.push_back(v);
  EXPECT_GE(world.cut_totals().wrong_side, static_cast<long>(off_crack.size())) << when;
  std::vector<int> flagged;
  for (std::size_t v = 0; v < body.cut->mapping.wrong_side.size(); ++v)
    if (body.cut->mapping.wrong_side[v] != 0 && front.crack_front()[v] == 0) flagged.push_back(static_cast<int>(v));
  EXPECT_EQ(flagged, off_crack) << when;
}

// A blade through the beam: two closed pieces, every vertex on its own side, and the free
// piece falling as free fall predicts, with its surface.
TEST(WorldCut, ABladeCutsTheBeamInTwoClosedPiecesAndTheFreeOneFallsWithItsSurface) {
  TempDir dir("incise_world_cut_front");
  Scene scene = beam_cut_scene(dir, 0.02);
  World world(scene, read_trajectory(dir.path / "cut.traj"));
  const Body& body = world.bodies()[0];
  ASSERT_TRUE(body.cut->surface);
  const int dofs = 3 * body.data.mechanics->node_count();
  const std::size_t triangles_before = body.data.surface.size();
  int events = 0;
  for (int step = 0; step < 12; ++step) {
    if (!world.step().cut_event) continue;
    ++events;
    const physics::SurfaceTopology now = physics::surface_topology(body.data.surface);
    EXPECT_TRUE(now.watertight()) << "step " << step << ": " << now.boundary_edges << " boundary, "
                                  << now.nonmanifold_edges << " non-manifold edges";
    EXPECT_EQ(3 * body.data.mechanics->node_count(), dofs);
    ASSERT_EQ(body.data.embedding->vertex_count(), static_cast<int>(body.cut->surface->vertices().size())) << "step " << step;
    expect_front_kept_as_whole(world, body, "step " + std::to_string(step));
    // The counts the world keeps where the surface changed are the whole surface's.
    EXPECT_EQ(body.cut->topology.boundary_edges, now.boundary_edges) << "step " << step;
    EXPECT_EQ(body.cut->topology.nonmanifold_edges, now.nonmanifold_edges) << "step " << step;
    // No vertex across a cut from its point, counted over the whole surface (the world keeps
    // the rows of the stroke's vertices behind the front and tests only where it changed).
    {
      const physics::FrontSurface& front = *body.cut->surface;
      std::set<std::array<double, 9>> seen;
      std::vector<std::array<physics::Vec3, 3>> faces;
      for (std::size_t t = 0; t < body.data.surface.size(); ++t) {
        if (!front.on_cut_face()[t]) continue;
        std::array<physics::Vec3, 3> corners;
        for (int c = 0; c < 3; ++c) corners[static_cast<std::size_t>(c)] = front.vertices()[static_cast<std::size_t>(body.data.surface[t][static_cast<std::size_t>(c)])];
        std::sort(corners.begin(), corners.end(), [](const physics::Vec3& l, const physics::Vec3& r) {
          return std::lexicographical_compare(l.data(), l.data() + 3, r.data(), r.data() + 3);
        });
        std::array<double, 9> key{};
        for (int c = 0; c < 9; ++c) key[static_cast<std::size_t>(c)] = corners[static_cast<std::size_t>(c / 3)][c % 3];
        if (seen.insert(key).second) faces.push_back(corners);
      }
      std::vector<std::uint8_t> on_face(front.vertices().size(), 0);
      for (std::size_t t = 0; t < body.data.surface.size(); ++t)
        if (front.on_cut_face()[t])
          for (const int v : body.data.surface[t]) on_face[static_cast<std::size_t>(v)] = 1;
      std::vector<int> across;
      const physics::CutFaceIndex index(*body.data.efg, faces);
      physics::count_wrong_side(*body.data.efg, front.vertices(), body.data.surface, *body.data.embedding, index, 0.1 * front.front_width() / 1.5, {}, &across,
                                on_face);
      const long wrong = std::count_if(across.begin(), across.end(), [&](int v) { return front.crack_front()[static_cast<std::size_t>(v)] == 0; });
      EXPECT_EQ(wrong, 0) << "step " << step;
    }
    ASSERT_TRUE(body.data.surface_positions.allFinite()) << "step " << step;
  }
  EXPECT_GT(events, 0);
  EXPECT_EQ(world.cut_totals().front_problems, 0) << world.cut_totals().first_front_problem;
  std::vector<int> piece;
  ASSERT_EQ(body.cut->cutter->pieces(piece), 2);
  EXPECT_GT(body.data.surface.size(), triangles_before);
  EXPECT_EQ(world.cut_totals().wrong_side, 0);  // the worst over the events
  EXPECT_EQ(world.cut_totals().elements_linked_across, 0);
  // The surface's vertices beyond the cut (at rest) fall with the free piece; those before it
  // stay with the clamped one.
  const auto& rest = body.cut->surface->vertices();
  const physics::Vector before = body.data.surface_positions;
  const auto [fallen, expected, t] = free_piece_fall(world, body, piece, scene.solver.dt);
  EXPECT_NEAR(fallen, expected, 0.03 * expected);
  double free_drop = 0, clamped_drop = 0;
  int free_count = 0, clamped_count = 0;
  for (std::size_t v = 0; v < rest.size(); ++v) {
    const double drop = before[3 * static_cast<Eigen::Index>(v) + 2] - body.data.surface_positions[3 * static_cast<Eigen::Index>(v) + 2];
    if (rest[v].x() > 0.06) free_drop += drop, ++free_count;
    if (rest[v].x() < 0.04) clamped_drop += drop, ++clamped_count;
  }
  free_drop /= free_count;
  clamped_drop /= clamped_count;
  std::printf("engine front cut: %d events, %zu -> %zu triangles; free surface fell %.5f m (piece %.5f), clamped one %.5f m\n",
              events, triangles_before, body.data.surface.size(), free_drop, fallen, clamped_drop);
  EXPECT_NEAR(free_drop, fallen, 0.1 * fallen);
  EXPECT_LT(std::abs(clamped_drop), 0.1 * fallen);
  EXPECT_TRUE(physics::surface_topology(body.data.surface).watertight());
}

TEST(WorldCut, AFrameDrawsTheExposedCutFacesApartInTheirOwnColour) {
  // The beam cut through by the front surface: before the cut one mesh per body; after it,
  // the body's mesh loses exactly the cut faces' triangles to a second mesh of another
  // colour. At rest the cut faces are the section on each side of the cut: 2 x 0.02 x 0.02 m^2.
  TempDir dir("incise_world_cut_frame");
  Scene scene = beam_cut_scene(dir, 0.02);
  World world(scene, read_trajectory(dir.path / "cut.traj"));
  const Body& body = world.bodies()[0];
  render::Frame frame;
  world.fill_frame(frame, 64, 48);
  ASSERT_EQ(frame.meshes.size(), 1u);
  EXPECT_EQ(frame.meshes[0].triangles, body.data.render_triangles);
  for (int step = 0; step < 12; ++step) world.step();
  ASSERT_EQ(world.cut_totals().front_problems, 0) << world.cut_totals().first_front_problem;
  world.fill_frame(frame, 64, 48);
  ASSERT_EQ(frame.meshes.size(), 2u);
  const render::SurfaceMesh& skin = frame.meshes[0];
  const render::SurfaceMesh& cut = frame.meshes[1];
  EXPECT_NE(skin.color, cut.color);
  EXPECT_EQ(cut.positions, skin.positions);
  ASSERT_EQ(skin.triangles.size() + cut.triangles.size(), body.data.render_triangles.size());
  const physics::FrontSurface& front = *body.cut->surface;
  std::vector<std::uint32_t> expect_skin, expect_cut;
  double cut_area = 0;
  for (std::size_t t = 0; t < body.data.surface.size(); ++t) {
    auto& to = front.on_cut_face()[t] ? expect_cut : expect_skin;
    for (int c = 0; c < 3; ++c) to.push_back(static_cast<std::uint32_t>(body.data.surface[t][static_cast<std::size_t>(c)]));
    if (!front.on_cut_face()[t]) continue;
    const auto& x = front.vertices();
    const auto& tri = body.data.surface[t];
    cut_area += 0.5 * (x[static_cast<std::size_t>(tri[1])] - x[static_cast<std::size_t>(tri[0])])
                          .cross(x[static_cast<std::size_t>(tri[2])] - x[static_cast<std::size_t>(tri[0])])
                          .norm();
  }
  EXPECT_EQ(skin.triangles, expect_skin);
  EXPECT_EQ(cut.triangles, expect_cut);
  std::printf("frame of the cut beam: %zu skin and %zu cut-face triangles, cut faces %.4e m^2 at rest (section x 2: 8e-4)\n",
              skin.triangles.size() / 3, cut.triangles.size() / 3, cut_area);
  EXPECT_NEAR(cut_area, 8e-4, 0.01 * 8e-4);
}

// The state hash takes in the cut topology: two worlds whose particles moved alike but whose
// cut differs must hash apart; and reset() brings a world back to its start, so a replay from
// there reaches the same state, cut and all, as a fresh world.
TEST(WorldCut, ResetReplaysToTheSameStateAndTheHashSeesTheCut) {
  TempDir dir("incise_world_cut_reset");
  Scene scene = beam_cut_scene(dir, 0.02);
  World world(scene, read_trajectory(dir.path / "cut.traj"));
  const std::uint64_t start = world.state_hash(), start_motion = world.motion_hash();
  int events = 0;
  for (int k = 0; k < 12; ++k) events += world.step().cut_event ? 1 : 0;
  ASSERT_GT(events, 0);
  const std::uint64_t cut = world.state_hash(), cut_motion = world.motion_hash();
  const auto triangles = world.bodies()[0].data.surface.size();
  EXPECT_NE(cut, start);
  world.reset();
  EXPECT_EQ(world.time(), 0.0);
  EXPECT_EQ(world.steps_taken(), 0u);
  EXPECT_EQ(world.cut_totals().events, 0);
  EXPECT_EQ(world.state_hash(), start);
  EXPECT_EQ(world.motion_hash(), start_motion);
  for (int k = 0; k < 12; ++k) world.step();
  EXPECT_EQ(world.state_hash(), cut);
  EXPECT_EQ(world.motion_hash(), cut_motion);
  EXPECT_EQ(world.bodies()[0].data.surface.size(), triangles);
  // The same motion with one particle's fixed flag flipped (what pinning a cut's orphans
  // changes): the motion hash is blind to it, the state hash is not.
  World fresh(scene, read_trajectory(dir.path / "cut.traj"));
  for (int k = 0; k < 12; ++k) fresh.step();
  ASSERT_EQ(fresh.state_hash(), cut);
  auto& fixed = const_cast<std::vector<std::uint8_t>&>(fresh.bodies()[0].data.fixed);
  fixed[0] ^= 1;
  EXPECT_EQ(fresh.motion_hash(), cut_motion);
  EXPECT_NE(fresh.state_hash(), cut);
}

TEST(WorldCut, AFastBladeIsNotSkippedAndReplaysAreDeterministic) {
  TempDir dir("incise_world_cut_fast");
  // 6 cm in 10 ms (6 m/s): the whole section within two steps of 5 ms.
  Scene scene = beam_cut_scene(dir, 0.01);
  ReplayOptions options;
  options.out_dir = dir.path / "a";
  options.progress = false;
  const auto a = run_replay(scene, options);
  options.out_dir = dir.path / "b";
  const auto b = run_replay(scene, options);
  ASSERT_TRUE(a.ok);
  EXPECT_EQ(a.metrics["state_hash"], b.metrics["state_hash"]);
  EXPECT_EQ(a.metrics["surface"]["triangles"], b.metrics["surface"]["triangles"]);
  EXPECT_GE(a.metrics["cut"]["events"].get<int>(), 1);
  EXPECT_TRUE(a.metrics["surface"]["watertight_after_every_event"].get<bool>());
  EXPECT_EQ(a.metrics["dofs"]["initial"], a.metrics["dofs"]["final"]);
  EXPECT_EQ(a.metrics["mapping"]["wrong_side"].get<int>(), 0);
}

TEST(WorldCut, ABladeThatMissesCutsNothing) {
  TempDir dir("incise_world_cut_miss");
  Scene scene = beam_cut_scene(dir, 0.02, 0.15);  // beyond the beam's end
  World world(scene, read_trajectory(dir.path / "cut.traj"));
  const std::size_t triangles = world.bodies()[0].data.surface.size();
  for (int k = 0; k < 12; ++k) EXPECT_FALSE(world.step().cut_event);
  EXPECT_EQ(world.bodies()[0].data.surface.size(), triangles);
  EXPECT_EQ(world.cut_totals().events, 0);
}

// A shipped scene (assets/scenes/NAME.json) replayed whole (or its first `steps`),
// `at_event(world, body, step)` after every cut event, until a fatal failure. Returns the
// number of events.
template <typename AtEvent>
int replay_shipped_scene(const std::string& name, const AtEvent& at_event, long steps = -1) {
  Scene scene = load_scene(std::filesystem::path(INCISE_SOURCE_DIR) / "assets/scenes" / (name + ".json"));
  World world(scene, read_trajectory(*scene.tool->trajectory));
  if (steps < 0) steps = std::lround(scene.solver.duration / scene.solver.dt);
  int events = 0;
  for (long k = 0; k < steps; ++k) {
    if (!world.step().cut_event) continue;
    ++events;
    at_event(world, world.bodies()[0], k);
    if (::testing::Test::HasFatalFailure()) break;
  }
  return events;
}

TEST(WorldCut, TheFrontSurfaceKeptWhereTheStrokeChangedItIsTheWholeSurfacesAtEveryEventOfAShippedScene) {
  // A curved blade turning as it advances (steps 41 to 99), its stroke carried through at its
  // end (step 100: the stroke's vertices become the base's); the retractors that follow cut
  // nothing. At every event what the world keeps is the whole surface's.
  long wrong_side = -1;
  const int events = replay_shipped_scene("cut_twisting_blade", [&](const World& world, const Body& body, long k) {
    expect_front_kept_as_whole(world, body, "step " + std::to_string(k));
    wrong_side = world.cut_totals().wrong_side;
  }, 110);
  EXPECT_GT(events, 20);
  EXPECT_EQ(wrong_side, 0);
}

TEST(WorldCut, TheFrontSurfacesCutBesideTheVolumesGivesWhatItGivesInSequence) {
  // With efg.threads >= 2 a cutting step runs the surface's cut (FrontSurface::advance) on a
  // second thread beside the volume's CCD and re-selection (and the element loops on two
  // threads); with 1 it runs after them, on the physics thread (the engine's executor with one
  // thread, as physics::serial_executor). Likewise the plan of the assembled stiffness for the
  // re-selected rows (multigrid_current, the scene's) beside the surface's remap. Neither job
  // reads what the other writes, so the steps must agree bit for bit: the particles, the
  // surface, the counts (and ThreadSanitizer, in CI, sees the overlap).
  const auto run = [](int threads, double& front_ms) {
    Scene scene = load_scene(std::filesystem::path(INCISE_SOURCE_DIR) / "assets/scenes/cut_twisting_blade.json");
    scene.bodies[0].efg.threads = threads;
    World world(scene, read_trajectory(*scene.tool->trajectory));
    EXPECT_EQ(world.bodies()[0].executor->has_side_helper(), threads >= 2);
    EXPECT_EQ(world.bodies()[0].executor->thread_count(), threads);
    EXPECT_EQ(&world.bodies()[0].data.efg->executor(), world.bodies()[0].executor.get());
    front_ms = 0;
    int events = 0;
    for (int k = 0; k < 100; ++k) {
      const StepStats stats = world.step();
      events += stats.cut_event ? 1 : 0;
      front_ms += stats.ms_front_cut;
    }
    const Body& body = world.bodies()[0];
    // Whether the helper or the caller ran each step's surface cut depends on the scheduler;
    // the results must not.
    if (body.executor->has_side_helper()) std::printf("surface cut on the helper thread in %llu steps\n", static_cast<unsigned long long>(body.executor->side_taken_by_helper()));
    return std::make_tuple(world.state_hash(), body.cut->surface->vertices(), body.data.surface, events,
                           world.cut_totals().links_severed, world.cut_totals().front_problems, world.cut_totals().wrong_side);
  };
  double beside_ms = 0, sequence_ms = 0;
  const auto beside = run(2, beside_ms);
  const auto sequence = run(1, sequence_ms);
  EXPECT_GT(std::get<3>(beside), 20);
  EXPECT_GT(beside_ms, 0);  // the surface's cut ran, and was timed, beside the volume's
  EXPECT_GT(sequence_ms, 0);
  EXPECT_EQ(std::get<0>(beside), std::get<0>(sequence));
  EXPECT_TRUE(std::get<1>(beside) == std::get<1>(sequence));
  EXPECT_TRUE(std::get<2>(beside) == std::get<2>(sequence));
  EXPECT_EQ(std::get<3>(beside), std::get<3>(sequence));
  EXPECT_EQ(std::get<4>(beside), std::get<4>(sequence));
  EXPECT_EQ(std::get<5>(beside), 0);
  EXPECT_EQ(std::get<5>(sequence), 0);
  EXPECT_EQ(std::get<6>(beside), std::get<6>(sequence));
}

TEST(WorldCut, TheFrontSurfaceKeptAcrossOtherShippedCutScenesIsTheWholeSurfacesAtEveryEvent) {
  // A falling body cut by a static blade, and a blade cutting upwards: what the world keeps
  // where each stroke changed the surface is the whole surface's after every event.
  for (const char* name : {"cut_falling_cylinder", "cut_rising_blade"}) {
    const int events = replay_shipped_scene(name, [&](const World& world, const Body& body, long k) {
      expect_front_kept_as_whole(world, body, std::string(name) + ", step " + std::to_string(k));
    });
    EXPECT_GT(events, 5) << name;
  }
}

namespace {

// One replay of the beam's cut with a preconditioner rebuilt after each cut on a thread of its
// own, taking over two steps later: the state's hash and positions, the iterations, the oldest
// factor a step ran on.
struct FactorRun {
  std::uint64_t hash = 0;
  physics::Vector positions;
  long long iterations = 0;
  long long max_age = 0;
};

FactorRun run_beam_cut(const Scene& scene, const TempDir& dir, const std::string& preconditioner) {
  Scene s = scene;
  s.solver.preconditioner = preconditioner;
  s.solver.preconditioner_latency = 2;
  World world(s, read_trajectory(dir.path / "cut.traj"));
  FactorRun run;
  int events = 0;
  for (int k = 0; k < 30; ++k) {
    const StepStats stats = world.step();
    events += stats.cut_event ? 1 : 0;
    run.iterations += stats.cg_iterations;
    run.max_age = std::max(run.max_age, stats.preconditioner_age);
    EXPECT_EQ(stats.preconditioner, preconditioner);
  }
  EXPECT_GT(events, 0);
  run.hash = world.state_hash();
  run.positions = world.bodies()[0].data.state.positions;
  return run;
}

}  // namespace

// The rest factors (solver.preconditioner "multigrid", as "warped_cholesky" and "two_level":
// RestPreconditioner) rebuilt beside the steps after each cut replay bit-for-bit: a step takes
// a new factor at a fixed step, whenever its build ends. ThreadSanitizer runs this one.
TEST(WorldCut, TheRestFactorsReplayBitForBitThroughCuts) {
  TempDir dir("incise_world_cut_replay");
  const Scene scene = beam_cut_scene(dir, 0.02);
  const FactorRun multigrid = run_beam_cut(scene, dir, "multigrid");
  const FactorRun again = run_beam_cut(scene, dir, "multigrid");
  EXPECT_EQ(multigrid.hash, again.hash);
  EXPECT_EQ(multigrid.iterations, again.iterations);
  EXPECT_GE(multigrid.max_age, 1);  // steps ran on a factor older than the cut
}

// Each rest factor reaches the Jacobi CG's solution (same tolerance) in fewer iterations through
// the cut, the multigrid in fewer than the two-level one; the warped Cholesky replays too.
TEST(WorldCut, TheRestFactorsAgreeWithJacobiThroughCuts) {
  TempDir dir("incise_world_cut_warped");
  const Scene scene = beam_cut_scene(dir, 0.02);
  const FactorRun two_level = run_beam_cut(scene, dir, "two_level");
  const FactorRun multigrid = run_beam_cut(scene, dir, "multigrid");
  const FactorRun warped = run_beam_cut(scene, dir, "warped_cholesky");
  const FactorRun again = run_beam_cut(scene, dir, "warped_cholesky");
  const FactorRun jacobi = run_beam_cut(scene, dir, "jacobi");
  EXPECT_EQ(warped.hash, again.hash);
  EXPECT_EQ(warped.iterations, again.iterations);
  EXPECT_GE(warped.max_age, 1);
  EXPECT_LT(warped.iterations, jacobi.iterations / 2);
  const physics::Vector rest = World(scene, read_trajectory(dir.path / "cut.traj")).bodies()[0].data.state.positions;
  const double moved = (jacobi.positions - rest).cwiseAbs().maxCoeff();
  ASSERT_GT(moved, 0);
  EXPECT_LE((warped.positions - jacobi.positions).cwiseAbs().maxCoeff(), 1e-4 * moved);
  EXPECT_LT(two_level.iterations, jacobi.iterations);
  EXPECT_GE(two_level.max_age, 1);
  EXPECT_LE((two_level.positions - jacobi.positions).cwiseAbs().maxCoeff(), 1e-4 * moved);
  EXPECT_LT(multigrid.iterations, two_level.iterations);
  EXPECT_LE((multigrid.positions - jacobi.positions).cwiseAbs().maxCoeff(), 1e-4 * moved);
  std::printf("CG iterations over 30 cut steps: jacobi %lld, two_level %lld, multigrid %lld, warped %lld\n",
              jacobi.iterations, two_level.iterations, multigrid.iterations, warped.iterations);
}
