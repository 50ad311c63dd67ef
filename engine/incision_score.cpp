#include "engine/incision_score.hpp"

#include "physics/cut/front_surface.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

namespace incise::engine {

namespace {

using physics::Vec3;
using Vec2 = Eigen::Vector2d;

constexpr double kPlanStep = 0.25e-3;   // the plan resampled, m
constexpr double kBin = 0.5e-3;         // depth and length bins along the plan, m
constexpr double kAreaStep = 0.5e-3;    // the cut faces' sub-triangles' longest edge, m
constexpr double kMouthStep = 0.25e-3;  // the wound's mouth sampled, m
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Lateral coordinates across d, and the height along it (growing into the tissue).
struct Frame {
  Vec3 d, e1, e2;
  explicit Frame(const Point& direction) {
    d = Vec3(direction[0], direction[1], direction[2]).normalized();
    const Vec3 helper = std::abs(d.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
    e1 = d.cross(helper).normalized();
    e2 = d.cross(e1);
  }
  Vec2 lateral(const Vec3& x) const { return {x.dot(e1), x.dot(e2)}; }
  double height(const Vec3& x) const { return x.dot(d); }
};

// The plan every kPlanStep of lateral length, with the height of the organ's outer surface
// under each point (NaN where the ray along d misses the organ).
struct Track {
  std::vector<Vec2> points;
  std::vector<double> arc;
  std::vector<double> surface;
  double length = 0;
};

Track resample(const PlanSpec& plan, const Frame& frame) {
  Track track;
  Vec2 previous = frame.lateral(Vec3(plan.path[0][0], plan.path[0][1], plan.path[0][2]));
  track.points.push_back(previous);
  track.arc.push_back(0);
  for (std::size_t i = 1; i < plan.path.size(); ++i) {
    const Vec2 next = frame.lateral(Vec3(plan.path[i][0], plan.path[i][1], plan.path[i][2]));
    const double length = (next - previous).norm();
    const int pieces = std::max(1, static_cast<int>(std::ceil(length / kPlanStep)));
    for (int k = 1; k <= pieces; ++k) {
      const double f = static_cast<double>(k) / pieces;
      track.points.push_back(previous + f * (next - previous));
      track.arc.push_back(track.length + f * length);
    }
    track.length += length;
    previous = next;
  }
  return track;
}

// The outer surface's height under each plan point: the first of the uncut triangles a ray
// along d meets (the smallest height).
void find_surface(const Frame& frame, const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles,
                  const std::vector<std::uint8_t>& cut_face, Track& track) {
  track.surface.assign(track.points.size(), kNaN);
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    if (cut_face[t]) continue;
    const auto& tri = triangles[t];
    const Vec2 a = frame.lateral(vertices[tri[0]]), b = frame.lateral(vertices[tri[1]]), c = frame.lateral(vertices[tri[2]]);
    const double area = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
    if (!(std::abs(area) > 1e-14)) continue;  // seen edge-on along d
    const Vec2 lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
    for (std::size_t k = 0; k < track.points.size(); ++k) {
      const Vec2& p = track.points[k];
      if (p.x() < lo.x() || p.y() < lo.y() || p.x() > hi.x() || p.y() > hi.y()) continue;
      const double wb = ((p - a).x() * (c - a).y() - (p - a).y() * (c - a).x()) / area;
      const double wc = ((b - a).x() * (p - a).y() - (b - a).y() * (p - a).x()) / area;
      const double wa = 1 - wb - wc;
      if (wa < -1e-9 || wb < -1e-9 || wc < -1e-9) continue;
      const double h = wa * frame.height(vertices[tri[0]]) + wb * frame.height(vertices[tri[1]]) +
                       wc * frame.height(vertices[tri[2]]);
      if (std::isnan(track.surface[k]) || h < track.surface[k]) track.surface[k] = h;
    }
  }
}

// Where a lateral point q is seen from the plan: its distance, the arc length of its nearest
// plan point and the surface's height there (NaN off the organ).
struct Seen {
  double distance = 0;
  double arc = 0;
  double surface = kNaN;
};

Seen see(const Track& track, const Vec2& q) {
  Seen best;
  best.distance = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k + 1 < track.points.size(); ++k) {
    const Vec2 a = track.points[k], ab = track.points[k + 1] - a;
    const double f = std::clamp((q - a).dot(ab) / std::max(ab.squaredNorm(), 1e-30), 0.0, 1.0);
    const double distance = (a + f * ab - q).norm();
    if (distance >= best.distance) continue;
    best.distance = distance;
    best.arc = track.arc[k] + f * (track.arc[k + 1] - track.arc[k]);
    const double s0 = track.surface[k], s1 = track.surface[k + 1];
    best.surface = std::isnan(s0) ? s1 : std::isnan(s1) ? s0 : s0 + f * (s1 - s0);
  }
  return best;
}

int bin_of(const Track& track, double arc) {
  const int bins = std::max(1, static_cast<int>(std::ceil(track.length / kBin)));
  return std::clamp(static_cast<int>(arc / kBin), 0, bins - 1);
}

// The cut faces' area, inside and outside the band, and the deepest cut per bin of the plan.
void score_cut_area(const PlanSpec& plan, const Frame& frame, const Track& track, const std::vector<Vec3>& vertices,
                    const std::vector<std::array<int, 3>>& triangles, const std::vector<std::uint8_t>& cut_face,
                    std::vector<double>& deepest, IncisionScore& score) {
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    if (!cut_face[t]) continue;
    const Vec3 a = vertices[triangles[t][0]], b = vertices[triangles[t][1]], c = vertices[triangles[t][2]];
    const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
    const int n = std::clamp(static_cast<int>(std::ceil(longest / kAreaStep)), 1, 200);
    // Each lip has the face: half of it is the tissue opened.
    const double area = 0.5 * 0.5 * (b - a).cross(c - a).norm() / (n * n);
    const Vec3 u = (b - a) / n, v = (c - a) / n;
    for (int i = 0; i < n; ++i) {
      for (int j = 0; i + j < n; ++j) {
        // The upright sub-triangle (i, j) and, but in the last row, the inverted one beside it.
        for (int inverted = 0; inverted < (i + j + 1 < n ? 2 : 1); ++inverted) {
          const Vec3 centre = a + (i + (inverted ? 2.0 : 1.0) / 3.0) * u + (j + (inverted ? 2.0 : 1.0) / 3.0) * v;
          const Seen seen = see(track, frame.lateral(centre));
          const double depth = frame.height(centre) - seen.surface;
          score.cut_area_mm2 += area * 1e6;
          const bool deep = !std::isnan(depth) && depth > plan.depth + plan.band;
          if (seen.distance > plan.band || deep) {
            score.outside_band_mm2 += area * 1e6;
            continue;
          }
          if (std::isnan(depth)) continue;
          double& d = deepest[static_cast<std::size_t>(bin_of(track, seen.arc))];
          if (std::isnan(d) || depth > d) d = depth;
        }
      }
    }
  }
}

// The wound's mouth: edges between a cut face and the outer surface, sampled.
void score_mouth(const Frame& frame, const Track& track, const std::vector<Vec3>& vertices,
                 const std::vector<std::array<int, 3>>& triangles, const std::vector<std::uint8_t>& cut_face,
                 IncisionScore& score) {
  std::unordered_map<std::uint64_t, std::array<int, 2>> sides;  // edge -> (cut faces, others)
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    for (int e = 0; e < 3; ++e) {
      const auto p = static_cast<std::uint32_t>(triangles[t][e]), q = static_cast<std::uint32_t>(triangles[t][(e + 1) % 3]);
      const std::uint64_t key = (static_cast<std::uint64_t>(std::min(p, q)) << 32) | std::max(p, q);
      sides[key][cut_face[t] ? 0 : 1]++;
    }
  }
  double weighted = 0, length = 0;
  for (const auto& [key, count] : sides) {
    if (count[0] == 0 || count[1] == 0) continue;
    const Vec3 a = vertices[key >> 32], b = vertices[key & 0xffffffffu];
    score.mouth.push_back({a.x(), a.y(), a.z(), b.x(), b.y(), b.z()});
    const int n = std::max(1, static_cast<int>(std::ceil((b - a).norm() / kMouthStep)));
    for (int k = 0; k < n; ++k) {
      const double distance = see(track, frame.lateral(a + (k + 0.5) / n * (b - a))).distance;
      const double piece = (b - a).norm() / n;
      weighted += distance * piece;
      length += piece;
      score.deviation_max_mm = std::max(score.deviation_max_mm, distance * 1e3);
    }
  }
  if (length > 0) score.deviation_mean_mm = weighted / length * 1e3;
}

}  // namespace

void score_cut_surface(const PlanSpec& plan, const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles,
                       const std::vector<std::uint8_t>& cut_face, IncisionScore& score) {
  if (plan.path.size() < 2) throw std::invalid_argument("score_cut_surface: the plan needs two points");
  const Frame frame(plan.direction);
  Track track = resample(plan, frame);
  find_surface(frame, vertices, triangles, cut_face, track);
  score.depth_target_mm = plan.depth * 1e3;
  score.band_mm = plan.band * 1e3;
  score.cut = std::find(cut_face.begin(), cut_face.end(), 1) != cut_face.end();

  const int bins = bin_of(track, track.length) + 1;
  std::vector<std::uint8_t> on_organ(static_cast<std::size_t>(bins), 0);
  for (std::size_t k = 0; k < track.points.size(); ++k)
    if (!std::isnan(track.surface[k])) on_organ[static_cast<std::size_t>(bin_of(track, track.arc[k]))] = 1;
  std::vector<double> deepest(static_cast<std::size_t>(bins), kNaN);
  score_cut_area(plan, frame, track, vertices, triangles, cut_face, deepest, score);
  score_mouth(frame, track, vertices, triangles, cut_face, score);

  double depth_sum = 0;
  int covered = 0;
  score.depth_min_mm = std::numeric_limits<double>::infinity();
  for (int b = 0; b < bins; ++b) {
    if (!on_organ[static_cast<std::size_t>(b)]) continue;
    const double width = std::min(kBin, track.length - b * kBin) * 1e3;
    score.plan_length_mm += width;
    const double depth = deepest[static_cast<std::size_t>(b)];
    if (std::isnan(depth)) continue;
    score.length_cut_mm += width;
    depth_sum += depth * 1e3;
    ++covered;
    score.depth_min_mm = std::min(score.depth_min_mm, depth * 1e3);
    score.depth_max_mm = std::max(score.depth_max_mm, depth * 1e3);
  }
  if (covered == 0) score.depth_min_mm = 0;
  score.depth_mean_mm = covered > 0 ? depth_sum / covered : 0;
  score.depth_range_mm = score.depth_max_mm - score.depth_min_mm;
}

void score_tool(const std::vector<StepStats>& steps, double dt, IncisionScore& score) {
  long first = -1, last = -1, touching = 0;
  double force_sum = 0;
  bool engaged = false, stroke_cut = false;
  for (std::size_t k = 0; k < steps.size(); ++k) {
    const StepStats& s = steps[k];
    if (s.cut_event) {
      if (first < 0) first = static_cast<long>(k);
      last = static_cast<long>(k);
    }
    const double force = std::sqrt(s.tool_force[0] * s.tool_force[0] + s.tool_force[1] * s.tool_force[1] +
                                   s.tool_force[2] * s.tool_force[2]);
    score.force_peak_N = std::max(score.force_peak_N, force);
    if (force > 0) {
      force_sum += force;
      ++touching;
    }
    // A stroke: one engagement of the blade (its button held) that cut.
    if (s.blade_engaged && !engaged) stroke_cut = false;
    if (s.blade_engaged && s.cut_event && !stroke_cut) {
      stroke_cut = true;
      score.strokes++;
    }
    engaged = s.blade_engaged;
  }
  score.duration_s = first >= 0 ? static_cast<double>(last - first + 1) * dt : 0;
  score.force_mean_N = touching > 0 ? force_sum / static_cast<double>(touching) : 0;
}

IncisionScore score_incision(const PlanSpec& plan, const World& world, const std::vector<StepStats>& steps, double dt) {
  const auto& bodies = world.bodies();
  const auto body = std::find_if(bodies.begin(), bodies.end(), [&](const Body& b) { return b.model->name == plan.body; });
  if (body == bodies.end()) throw std::runtime_error("plan.body: no body is named '" + plan.body + "'");
  if (!body->cut || !body->cut->surface)
    throw std::runtime_error("plan.body: '" + plan.body + "' has no cut surface to score (is it a cuttable efg body?)");
  const physics::FrontSurface& surface = *body->cut->surface;
  IncisionScore score;
  score_cut_surface(plan, surface.vertices(), surface.triangles(), surface.on_cut_face(), score);
  score_tool(steps, dt, score);
  return score;
}

nlohmann::json score_json(const IncisionScore& s) {
  return {{"length_cut_mm", s.length_cut_mm},       {"deviation_mean_mm", s.deviation_mean_mm},
          {"deviation_max_mm", s.deviation_max_mm}, {"depth_mean_mm", s.depth_mean_mm},
          {"depth_range_mm", s.depth_range_mm},     {"outside_band_mm2", s.outside_band_mm2},
          {"duration_s", s.duration_s},             {"force_peak_N", s.force_peak_N},
          {"force_mean_N", s.force_mean_N},         {"strokes", s.strokes},
          {"cut", s.cut},                           {"plan_length_mm", s.plan_length_mm},
          {"depth_target_mm", s.depth_target_mm},   {"depth_min_mm", s.depth_min_mm},
          {"depth_max_mm", s.depth_max_mm},         {"band_mm", s.band_mm},
          {"cut_area_mm2", s.cut_area_mm2}};
}

void write_score_files(const std::filesystem::path& dir, const PlanSpec& plan, const IncisionScore& score) {
  const auto write = [&dir](const char* name, const std::string& text) {
    std::ofstream out(dir / name);
    out << text;
    if (!out) throw std::runtime_error((dir / name).string() + ": cannot write");
  };
  write("score.json", score_json(score).dump(2) + "\n");
  std::ostringstream plan_csv, mouth_csv;
  plan_csv.precision(9);
  mouth_csv.precision(9);
  plan_csv << "x,y,z\n";
  for (const Point& p : plan.path) plan_csv << p[0] << ',' << p[1] << ',' << p[2] << '\n';
  mouth_csv << "x0,y0,z0,x1,y1,z1\n";
  // In the order of the vertex pairs, so that the file is the same on every run.
  std::vector<std::array<double, 6>> mouth = score.mouth;
  std::sort(mouth.begin(), mouth.end());
  for (const auto& m : mouth) mouth_csv << m[0] << ',' << m[1] << ',' << m[2] << ',' << m[3] << ',' << m[4] << ',' << m[5] << '\n';
  write("plan.csv", plan_csv.str());
  write("cut_path.csv", mouth_csv.str());
}

}  // namespace incise::engine
