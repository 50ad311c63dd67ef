#include "physics/needle/needle_zones.hpp"

#include <algorithm>
#include <cmath>

namespace incise::physics {

bool NeedleZones::empty() const { return members() == 0; }

int NeedleZones::members() const {
  std::size_t n = cutting.size();
  for (const auto& zone : friction) n += zone.size();
  return static_cast<int>(n);
}

namespace {

// Puts tissue node `atom` into the zones it lies in at `pose`: the cutting zone if it is ahead
// of the tip within r_c, the friction zone of the node whose share of the shaft it faces if it
// is within r_f of the axis (each node in one friction zone at most).
void classify(int atom, const Vec3& p, const NeedlePose& pose, const NeedleSettings& settings, NeedleZones& zones) {
  const Vec3 from_tip = p - pose.tip;
  const double ahead = from_tip.dot(pose.axis);
  if (ahead >= 0) {
    const double d = from_tip.norm();
    if (d <= settings.cutting_radius) zones.cutting.push_back({atom, d});
    return;
  }
  const double radial = (from_tip - ahead * pose.axis).norm();
  if (radial > settings.friction_radius) return;
  const int j = static_cast<int>(std::floor(-ahead / pose.spacing + 0.5));
  if (j >= pose.nodes) return;
  zones.friction[j].push_back({atom, (p - pose.node(j)).norm()});
}

}  // namespace

bool update_zones(NeedleZones& zones, const NeedlePose& pose, const Vector& x, const NeedleTissue& tissue,
                  const NeedleSettings& settings) {
  const bool scan = zones.empty();
  std::vector<int> candidates;
  if (scan) {
    candidates.resize(tissue.size());
    for (int i = 0; i < tissue.size(); ++i) candidates[i] = i;
  } else {
    const auto add = [&](const ZoneMember& m) {
      candidates.push_back(m.atom);
      candidates.insert(candidates.end(), tissue.neighbours[m.atom].begin(), tissue.neighbours[m.atom].end());
    };
    for (const auto& m : zones.cutting) add(m);
    for (const auto& zone : zones.friction)
      for (const auto& m : zone) add(m);
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
  }
  zones.cutting.clear();
  zones.friction.assign(pose.nodes, {});
  for (int atom : candidates) classify(atom, x.segment<3>(3 * atom), pose, settings, zones);
  return scan;
}

}  // namespace incise::physics
