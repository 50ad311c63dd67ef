#include "physics/cut/detect_cuts.hpp"

#include "physics/core/stopwatch.hpp"

#include <algorithm>
#include <cmath>

namespace incise::physics {

namespace {

// Whether the sweep's box meets the body's, grown by `margin`. The body's box is its
// particles': they lie at the corners of the particle cells that hold the integration points,
// around the surface (which is mapped from them), and are far fewer than a fine surface's
// vertices.
bool sweep_near_body(const BladeSweep& sweep, const Vector& particles, double margin) {
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  for (const auto& pose : sweep.poses)
    for (const auto& p : pose) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  Vec3 body_lo = Vec3::Constant(1e300), body_hi = Vec3::Constant(-1e300);
  for (Eigen::Index p = 0; p < particles.size() / 3; ++p) {
    body_lo = body_lo.cwiseMin(particles.segment<3>(3 * p));
    body_hi = body_hi.cwiseMax(particles.segment<3>(3 * p));
  }
  for (int axis = 0; axis < 3; ++axis)
    if (lo[axis] > body_hi[axis] + margin || hi[axis] < body_lo[axis] - margin) return false;
  return true;
}

}  // namespace

std::optional<RestSweep> detect_cuts(const CutModel& cut_model, CutData& cut, const BodyData& body,
                                     const BladeSweep& sweep, CutStepReport& report) {
  const auto& active = sweep.active;
  if (std::find(active.begin(), active.end(), 1) == active.end() ||
      !sweep_near_body(sweep, body.state.positions, 2 * cut_model.spacing)) {
    // The stroke, if any, ends here: the next one has no line to start from.
    cut.rest_edge.clear();
    cut.rest_edge_far.clear();
    return std::nullopt;
  }
  report.tested = true;
  const Stopwatch watch;
  // The sweep in the rest configuration (seed 004 §2.3: topology edits are done at rest).
  // The edge is resampled every a / 2 and each point mapped through the body's local
  // deformation at its moment; moments are taken so that the blade moves at most about a / 2
  // relative to the body between two of them, and consecutive moments span quads, two
  // triangles each.
  const double a = cut_model.spacing;
  RestSweep out;
  std::vector<RestTriangle>& triangles = out.triangles;
  auto& moments = out.moments;
  {
    const auto& edge0 = sweep.poses.front();
    std::vector<int> pieces;
    for (std::size_t i = 0; i + 1 < edge0.size(); ++i)
      pieces.push_back(std::max(1, static_cast<int>(std::ceil((edge0[i + 1] - edge0[i]).norm() / (0.5 * a)))));
    // A front surface's strokes need the same points at every sample: the resampling is
    // fixed the first time (the count could flip where a segment is a multiple of a / 2).
    if (cut.blade_pieces.size() != pieces.size()) cut.blade_pieces = pieces;
    pieces = cut.blade_pieces;
    const auto resample = [&](const std::vector<Vec3>& edge) {
      std::vector<Vec3> points;
      for (std::size_t i = 0; i + 1 < edge.size(); ++i)
        for (int k = 0; k < pieces[i]; ++k) points.push_back(edge[i] + (static_cast<double>(k) / pieces[i]) * (edge[i + 1] - edge[i]));
      points.push_back(edge.back());
      return points;
    };
    // Moments of the step at which the sweep is mapped: every sample's, and more wherever
    // the blade or the body moved more than a / 2 between two of them (a static blade in a
    // falling body sweeps the body all the same).
    double body_motion = 0;
    for (Eigen::Index p = 0; p < body.state.positions.size() / 3; ++p)
      body_motion = std::max(body_motion, (body.state.positions.segment<3>(3 * p) - cut.previous_positions.segment<3>(3 * p)).norm());
    Vector at_fraction;
    const auto map_edge = [&](const std::vector<Vec3>& edge, double f, std::vector<Vec3>& rest, std::vector<double>& distance) {
      at_fraction = cut.previous_positions + f * (body.state.positions - cut.previous_positions);
      cut.cutter->to_rest(at_fraction, resample(edge), rest, &distance);
    };
    const auto map_at = [&](std::size_t j, double f, std::vector<Vec3>& rest, std::vector<double>& distance) {
      // The blade between samples j and j + 1, at the step's fraction f.
      const double f0 = sweep.fractions[j], f1 = sweep.fractions[j + 1];
      const double s = f1 > f0 ? std::clamp((f - f0) / (f1 - f0), 0.0, 1.0) : 0.0;
      std::vector<Vec3> edge(sweep.poses[j].size());
      for (std::size_t i = 0; i < edge.size(); ++i) edge[i] = sweep.poses[j][i] + s * (sweep.poses[j + 1][i] - sweep.poses[j][i]);
      map_edge(edge, f, rest, distance);
    };
    const auto moved = [&](std::size_t j) {
      double most = 0;
      for (std::size_t i = 0; i < sweep.poses[j].size(); ++i)
        most = std::max(most, (sweep.poses[j + 1][i] - sweep.poses[j][i]).norm());
      return most;
    };
    const auto add_quads = [&](const std::vector<Vec3>& rest_0, const std::vector<double>& far_0,
                               const std::vector<Vec3>& rest_1, const std::vector<double>& far_1) {
      for (std::size_t i = 0; i + 1 < rest_0.size(); ++i) {
        // Outside the body (every corner beyond 2a of the integration points) the mapping
        // only extrapolates: such quads are left out.
        if (std::min({far_0[i], far_0[i + 1], far_1[i], far_1[i + 1]}) > 2 * a) continue;
        triangles.push_back({rest_0[i], rest_0[i + 1], rest_1[i + 1]});
        triangles.push_back({rest_0[i], rest_1[i + 1], rest_1[i]});
      }
    };
    std::vector<Vec3> rest_a, rest_b;
    std::vector<double> far_a, far_b;
    bool open = false;  // rest_a holds the sweep's last mapped moment
    for (std::size_t j = 0; j + 1 < sweep.poses.size(); ++j) {
      if (!active[j]) {
        open = false;
        continue;
      }
      const double f0 = sweep.fractions[j], f1 = sweep.fractions[j + 1];
      if (!open) {
        map_at(j, f0, rest_a, far_a);
        open = true;
        // A stroke going on from the last step: this pose is its last sample already (the
        // same blade in the same body, only mapped to rest again after the step's topology
        // change, which moves it a little and would make the sheet waver); not sampled again.
        if (j > 0 || !cut.engaged) {
          if (j == 0 && sweep.entry && sweep.entry->size() == sweep.poses[0].size()) {
            // The onset's step (BladeSweep::entry): the stroke starts where the edge met the
            // tissue, mapped through the dimpled body (the tissue it pressed went in with it,
            // so that point is out of the body again, and at rest above the surface), and
            // goes on to the edge at the dimple's bottom: the crack opens from the surface.
            std::vector<Vec3> rest_entry;
            std::vector<double> far_entry;
            map_edge(*sweep.entry, f0, rest_entry, far_entry);
            moments.emplace_back(rest_entry, true);
            add_quads(rest_entry, far_entry, rest_a, far_a);
            moments.emplace_back(rest_a, false);
          } else {
            moments.emplace_back(rest_a, true);
          }
        } else if (cut.rest_edge.size() == rest_a.size()) {
          // The same line mapped again after the last step's topology change has moved a
          // little: the seam between the two is closed, or a link could pass between the
          // last step's sheet and this one's (cut_torus with the onset: a hinge).
          add_quads(cut.rest_edge, cut.rest_edge_far, rest_a, far_a);
        }
      }
      const double relative = moved(j) + body_motion * (f1 - f0);
      const int pieces_in_time = std::max(1, static_cast<int>(std::ceil(relative / (0.5 * a))));
      // Consecutive samples that moved little are merged: only map where needed.
      const bool stretch_ends = j + 2 >= sweep.poses.size() || !active[j + 1];
      if (pieces_in_time == 1 && !stretch_ends && relative < 0.25 * a) {
        // Accumulate nothing now: the next interval's quad starts from rest_a, whose moment is
        // earlier; its relative motion is bounded by the same test there.
        continue;
      }
      for (int piece = 1; piece <= pieces_in_time; ++piece) {
        map_at(j, f0 + (f1 - f0) * piece / pieces_in_time, rest_b, far_b);
        moments.emplace_back(rest_b, false);
        add_quads(rest_a, far_a, rest_b, far_b);
        rest_a.swap(rest_b);
        far_a.swap(far_b);
      }
    }
    // Where the next step's sheet starts if the stroke goes on: the line the last interval
    // ended with when it was active (stretch_ends mapped it).
    if (open) {
      cut.rest_edge = rest_a;
      cut.rest_edge_far = far_a;
    } else {
      cut.rest_edge.clear();
      cut.rest_edge_far.clear();
    }
  }
  report.ms_rest_cut += watch.ms();
  report.ms_topology += watch.ms();
  return out;
}

}  // namespace incise::physics
