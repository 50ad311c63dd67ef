// take_tool_input, the step's first stage: the tool's pose at the step's end and, for a blade, its sweep
// over the step (every sample inside it, seed 004 §2.2), from the trajectory or live samples.
#include "engine/world.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace incise::engine {

namespace {

std::array<double, 3> rotate(const std::array<double, 4>& q, const std::array<double, 3>& v) {
  // v' = v + 2 w (u x v) + 2 u x (u x v), q = (w, u)
  double w = q[0];
  double ux = q[1], uy = q[2], uz = q[3];
  double cx = uy * v[2] - uz * v[1];
  double cy = uz * v[0] - ux * v[2];
  double cz = ux * v[1] - uy * v[0];
  double ccx = uy * cz - uz * cy;
  double ccy = uz * cx - ux * cz;
  double ccz = ux * cy - uy * cx;
  return {v[0] + 2 * (w * cx + ccx), v[1] + 2 * (w * cy + ccy), v[2] + 2 * (w * cz + ccz)};
}


}  // namespace

void World::take_tool_input(double time) {
  if (!tool_.present) return;
  // Every sample since the last step belongs to the tool's swept path; the probe's contact
  // needs only the pose at the end of the step (the blade's CCD will use the whole sweep).
  tool_.pose = sample_at(trajectory_->samples, time);
  tool_.tip = tool_.pose.position;
  tool_.tail = tool_.tip;
  if (scene_.tool->shape == "blade") {
    // The swept path: the pose at the start of the step, every recorded sample inside it,
    // the pose at its end (seed 004 §2.2: a fast stroke is never skipped).
    const double dt = scene_.solver.dt;
    const double start = std::max(0.0, time - dt);
    std::vector<ToolSample> poses{sample_at(trajectory_->samples, start)};
    for (const ToolSample& sample : samples_between(trajectory_->samples, start, time))
      if (sample.time > start && sample.time < time) poses.push_back(sample);
    poses.push_back(tool_.pose);
    tool_.blade_poses.clear();
    tool_.blade_fractions.clear();
    tool_.blade_active.clear();
    for (std::size_t j = 0; j < poses.size(); ++j) {
      std::vector<physics::Vec3> edge;
      for (const Point& local : scene_.tool->edge) {
        const auto world = rotate(poses[j].orientation, local);
        edge.emplace_back(poses[j].position[0] + world[0], poses[j].position[1] + world[1],
                          poses[j].position[2] + world[2]);
      }
      tool_.blade_poses.push_back(std::move(edge));
      tool_.blade_fractions.push_back(time > start ? std::clamp((poses[j].time - start) / (time - start), 0.0, 1.0) : 0.0);
      if (j > 0) tool_.blade_active.push_back((poses[j].buttons & kToolButtonEngaged) != 0 && time > start ? 1 : 0);
    }
    // sample_at may return the recorded time of the nearest sample: keep the ends exact.
    tool_.blade_fractions.front() = 0;
    tool_.blade_fractions.back() = 1;
    for (std::size_t j = 1; j < tool_.blade_fractions.size(); ++j)
      tool_.blade_fractions[j] = std::max(tool_.blade_fractions[j], tool_.blade_fractions[j - 1]);
  }
  if (scene_.tool->shape == "capsule" || scene_.tool->shape == "needle") {
    auto axis = rotate(tool_.pose.orientation, {0, 0, scene_.tool->length});
    for (int i = 0; i < 3; ++i) tool_.tail[i] = tool_.tip[i] + axis[i];
  }
  if (scene_.tool->shape == "needle") {
    // The template: each needle where the tool was `delay` earlier, its tip at its offset.
    const auto& needles = scene_.tool->needles;
    tool_.needle_tips.resize(needles.size());
    tool_.needle_tails.resize(needles.size());
    for (std::size_t k = 0; k < needles.size(); ++k) {
      const ToolSample at = needles[k].delay > 0 ? sample_at(trajectory_->samples, time - needles[k].delay) : tool_.pose;
      const auto offset = rotate(at.orientation, needles[k].offset);
      const auto shaft = rotate(at.orientation, {0, 0, scene_.tool->length});
      for (int i = 0; i < 3; ++i) {
        tool_.needle_tips[k][i] = at.position[i] + offset[i];
        tool_.needle_tails[k][i] = tool_.needle_tips[k][i] + shaft[i];
      }
    }
  }
}

void World::append_tool_samples(std::span<const ToolSample> samples) {
  if (!tool_.present || !trajectory_) throw std::logic_error("World::append_tool_samples: the scene has no tool");
  auto& held = trajectory_->samples;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const ToolSample& s = samples[k];
    const auto at = [&] { return "live tool sample " + std::to_string(k) + " (t = " + std::to_string(s.time) + " s)"; };
    bool finite = std::isfinite(s.time);
    for (double v : s.position) finite = finite && std::isfinite(v);
    for (double v : s.orientation) finite = finite && std::isfinite(v);
    if (!finite) throw std::invalid_argument(at() + ": a time, position or orientation is not finite");
    const double norm = std::sqrt(s.orientation[0] * s.orientation[0] + s.orientation[1] * s.orientation[1] +
                                  s.orientation[2] * s.orientation[2] + s.orientation[3] * s.orientation[3]);
    if (std::abs(norm - 1) > 1e-3) throw std::invalid_argument(at() + ": orientation |q| = " + std::to_string(norm) + " is not 1");
    if (!held.empty() && s.time < held.back().time)
      throw std::invalid_argument(at() + ": earlier than the previous sample (t = " + std::to_string(held.back().time) + " s)");
    held.push_back(s);
  }
  // The next step starts at time_ (computed there as end - dt, which may round below time_):
  // it needs the last sample at or before its start (sample_at's left neighbour) and
  // everything after it. Keeping from one step further back is safe; what is older can go.
  // A needle template's delayed needles look further back.
  double behind = 0;
  if (scene_.tool->shape == "needle")
    for (const NeedleEntry& e : scene_.tool->needles) behind = std::max(behind, e.delay);
  const auto keep = std::upper_bound(held.begin(), held.end(), time_ - scene_.solver.dt - behind,
                                     [](double t, const ToolSample& s) { return t < s.time; });
  if (keep - held.begin() > 1) held.erase(held.begin(), keep - 1);
}

double World::last_tool_sample_time() const {
  return trajectory_ && !trajectory_->samples.empty() ? trajectory_->samples.back().time : 0.0;
}

}  // namespace incise::engine
