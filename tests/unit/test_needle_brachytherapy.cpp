// Brachytherapy with 6 needles (seed 002 §5.8, §8.10; Marchal et al. 2007): the template of
// assets/scenes/needle_brachytherapy.json under the four protocols, {simultaneous, consecutive}
// x {circular, alternating} order (SC, SA, CC, CA), set through the needles' delays. The
// deformation along the needle axis (the peak of the nodes' mean displacement along it) is
// larger for simultaneous insertion than for consecutive, and the order changes it little.
#include "engine/needle_summary.hpp"
#include "engine/scene.hpp"
#include "engine/world.hpp"
#include "tests/unit/read_json.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

using namespace incise::engine;
using Json = nlohmann::json;

namespace {

const std::string kScene = std::string(INCISE_SOURCE_DIR) + "/assets/scenes/needle_brachytherapy.json";

// The template's needles: A B C along y = -5 mm, D E F back along y = +5 mm (the ring).
constexpr std::array<int, 6> kCircular{0, 1, 2, 3, 4, 5};     // A B C D E F: around the ring
constexpr std::array<int, 6> kAlternating{0, 3, 1, 4, 2, 5};  // A D B E C F: across it each time
constexpr double kInsertion = 0.7;                            // s, each needle's (the trajectory's)
constexpr double kStagger = 0.05;                             // s, between simultaneous needles' starts
constexpr double kGap = kInsertion + 0.05;                    // s, consecutive: after the one before is in
constexpr double kHold = 0.35;                                // s after the last needle is in

using incise::testing::read_json;

struct Outcome {
  double displacement_peak = 0;  // m
  double min_depth = 1e300;      // the shallowest needle's deepest, m
  double balance = 0;
  int nonfinite = 0;
};

Outcome run_protocol(const std::array<int, 6>& order, double spacing) {
  Json json = read_json(kScene);
  for (int rank = 0; rank < 6; ++rank) json["tool"]["needles"][order[rank]]["delay"] = rank * spacing;
  json["solver"]["duration"] = 5 * spacing + kInsertion + kHold;
  const Scene scene = parse_scene(json.dump(), kScene);
  World world(scene, read_trajectory(*scene.tool->trajectory));
  std::vector<StepStats> stats;
  const auto steps = static_cast<int>(std::lround(scene.solver.duration / scene.solver.dt));
  Outcome out;
  for (int k = 0; k < steps; ++k) {
    stats.push_back(world.step());
    out.nonfinite += stats.back().nonfinite_events;
  }
  out.displacement_peak = summarise_needle(stats).axial_displacement_peak;
  out.balance = summarise_needle(stats).balance_max;
  for (std::size_t n = 0; n < 6; ++n) out.min_depth = std::min(out.min_depth, summarise_needle(stats, n).max_depth);
  return out;
}

}  // namespace

TEST(NeedleBrachytherapy, SimultaneousDeformsMoreThanConsecutiveAndOrderMattersLittle) {
  const Outcome sc = run_protocol(kCircular, kStagger), sa = run_protocol(kAlternating, kStagger);
  const Outcome cc = run_protocol(kCircular, kGap), ca = run_protocol(kAlternating, kGap);
  const auto mm = [](double m) { return 1e3 * m; };
  std::printf("brachytherapy, 6 needles, peak mean displacement along the axis: SC %.5f mm, SA %.5f mm, CC %.5f mm, "
              "CA %.5f mm; shallowest needle %.2f / %.2f / %.2f / %.2f mm\n",
              mm(sc.displacement_peak), mm(sa.displacement_peak), mm(cc.displacement_peak), mm(ca.displacement_peak),
              mm(sc.min_depth), mm(sa.min_depth), mm(cc.min_depth), mm(ca.min_depth));
  for (const Outcome* o : {&sc, &sa, &cc, &ca}) {
    EXPECT_EQ(o->nonfinite, 0);
    EXPECT_GT(o->min_depth, 0.011);  // every needle in, 12 mm below the top face
    EXPECT_LT(o->balance, 1e-12);
    EXPECT_GT(o->displacement_peak, 0);  // pushed along the axis, the way the needles go in
  }
  const double simultaneous = std::min(sc.displacement_peak, sa.displacement_peak);
  const double consecutive = std::max(cc.displacement_peak, ca.displacement_peak);
  EXPECT_GT(simultaneous, 1.5 * consecutive);
  // The order: far less than the protocol's difference.
  EXPECT_LT(std::abs(sc.displacement_peak - sa.displacement_peak), 0.2 * (simultaneous - consecutive));
  EXPECT_LT(std::abs(cc.displacement_peak - ca.displacement_peak), 0.2 * (simultaneous - consecutive));
}
