#include "physics/cut/volume_cut.hpp"

#include "physics/cut/continuous_collision.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>
#include <tuple>

namespace incise::physics {

namespace {

// Rows hold at most this many particles (CorotationalEfg's own limit).
constexpr int slots_per_element = 64;
// Candidates further than this many particle-particle links from a kept neighbour are not
// considered: the neighbourhood must stay local for the MLS fit to mean anything.
constexpr int graph_radius = 3;

[[noreturn]] void fail(const std::string& what) { throw std::invalid_argument("VolumeCutter: " + what); }

// The same rank test as the model's: the smallest singular value of the centred positions
// above 1e-6 of the largest.
bool spans_three_dimensions(const std::vector<Vec3>& points) {
  if (points.size() < 4) return false;
  Vec3 centroid = Vec3::Zero();
  for (const Vec3& p : points) centroid += p;
  centroid /= static_cast<double>(points.size());
  Eigen::MatrixXd centred(3, static_cast<Eigen::Index>(points.size()));
  for (size_t i = 0; i < points.size(); ++i) centred.col(static_cast<Eigen::Index>(i)) = points[i] - centroid;
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(centred);
  const Vec3 singular = svd.singularValues();
  return singular[0] > 0 && singular[2] > 1e-6 * singular[0];
}

void check_finite(const Vector& v, const char* name) {
  if (!v.allFinite()) fail(std::string(name) + " holds a non-finite value");
}

}  // namespace

VolumeCutter::VolumeCutter(CorotationalEfg& model, double margin, double slack)
    : model_(model), broad_phase_(margin, slack) {
  // 6-connectivity on the particle grid: each particle to its next neighbour along +x, +y, +z
  // when that particle exists (particles outside the body's influence were dropped at build).
  const auto& cells = model_.particle_grid_coordinates();
  std::map<std::array<int, 3>, int> particle_at;
  for (int p = 0; p < static_cast<int>(cells.size()); ++p) particle_at[cells[p]] = p;
  links_of_particle_.assign(cells.size(), {});
  for (int p = 0; p < static_cast<int>(cells.size()); ++p) {
    for (int axis = 0; axis < 3; ++axis) {
      std::array<int, 3> next = cells[p];
      ++next[axis];
      const auto it = particle_at.find(next);
      if (it == particle_at.end()) continue;
      const int link = static_cast<int>(particle_links_.size());
      particle_links_.push_back({std::min(p, it->second), std::max(p, it->second)});
      links_of_particle_[p].push_back(link);
      links_of_particle_[it->second].push_back(link);
    }
  }
  particle_link_severed_.assign(particle_links_.size(), 0);
  element_link_particles_.resize(static_cast<size_t>(model_.element_count()));
}

int VolumeCutter::element_link_id(int element, int slot) const {
  return static_cast<int>(particle_links_.size()) + element * slots_per_element + slot;
}

int VolumeCutter::severed_particle_links() const {
  return static_cast<int>(std::count(particle_link_severed_.begin(), particle_link_severed_.end(), 1));
}

void VolumeCutter::integration_points(const Vector& particles, std::vector<Vec3>& out) const {
  const int elements = model_.element_count();
  const int stride = model_.row_stride();
  out.resize(static_cast<size_t>(elements));
  for (int e = 0; e < elements; ++e) {
    Vec3 point = Vec3::Zero();
    const size_t base = static_cast<size_t>(e) * stride;
    for (int k = 0; k < model_.row_lengths()[e]; ++k) {
      point += model_.shape_values()[base + k] * particles.segment<3>(3 * static_cast<Eigen::Index>(model_.neighbours()[base + k]));
    }
    out[e] = point;
  }
}

void VolumeCutter::refit(const std::vector<Vec3>& points_start, const std::vector<Vec3>& points_end,
                         const Vector& particles_start, const Vector& particles_end) {
  const auto particle = [](const Vector& x, int p) { return Vec3(x.segment<3>(3 * static_cast<Eigen::Index>(p))); };
  for (size_t link = 0; link < particle_links_.size(); ++link) {
    if (particle_link_severed_[link]) continue;
    const auto [a, b] = particle_links_[link];
    broad_phase_.set_edge(static_cast<int>(link),
                          {{particle(particles_start, a), particle(particles_start, b)},
                           {particle(particles_end, a), particle(particles_end, b)}});
  }
  const int stride = model_.row_stride();
  for (int e = 0; e < model_.element_count(); ++e) {
    const size_t base = static_cast<size_t>(e) * stride;
    auto& boxed = element_link_particles_[e];
    const int length = model_.row_lengths()[e];
    // Slots that no longer hold a link (a shorter row after a re-selection) leave the tree.
    for (int k = length; k < static_cast<int>(boxed.size()); ++k) {
      if (boxed[k] >= 0) broad_phase_.remove_edge(element_link_id(e, k));
    }
    boxed.resize(static_cast<size_t>(length), -1);
    for (int k = 0; k < length; ++k) {
      const int p = model_.neighbours()[base + k];
      boxed[k] = p;
      broad_phase_.set_edge(element_link_id(e, k), {{points_start[e], particle(particles_start, p)},
                                                    {points_end[e], particle(particles_end, p)}});
    }
  }
}

VolumeCutReport VolumeCutter::cut(std::span<const Vec3> blade_start, std::span<const Vec3> blade_end,
                                  const Vector& particles_start, const Vector& particles_end) {
  const Eigen::Index size = 3 * static_cast<Eigen::Index>(model_.node_count());
  if (blade_start.size() < 2 || blade_start.size() != blade_end.size()) {
    fail("the blade needs the same number (>= 2) of points at the start and the end of the step, got " +
         std::to_string(blade_start.size()) + " and " + std::to_string(blade_end.size()));
  }
  if (particles_start.size() != size || particles_end.size() != size) {
    fail("particle positions have " + std::to_string(particles_start.size()) + " and " +
         std::to_string(particles_end.size()) + " entries, the model " + std::to_string(size));
  }
  for (size_t i = 0; i < blade_start.size(); ++i) {
    if (!blade_start[i].allFinite() || !blade_end[i].allFinite()) fail("blade point " + std::to_string(i) + " is not finite");
  }
  check_finite(particles_start, "particles at the start of the step");
  check_finite(particles_end, "particles at the end of the step");

  VolumeCutReport report;
  std::vector<Vec3> points_start, points_end;
  integration_points(particles_start, points_start);
  integration_points(particles_end, points_end);
  refit(points_start, points_end, particles_start, particles_end);
  broad_phase_.query(blade_start, blade_end, candidates_);
  report.candidates = static_cast<int>(candidates_.size());

  const auto particle = [](const Vector& x, int p) { return Vec3(x.segment<3>(3 * static_cast<Eigen::Index>(p))); };
  const int link_count = static_cast<int>(particle_links_.size());
  // Element -> particles whose link to it was cut this step.
  std::map<int, std::vector<int>> cut_from;
  for (int id : candidates_) {
    MovingSegment edge;
    Vec3 rest_first, rest_second;
    int element = -1, slot_particle = -1;
    if (id < link_count) {
      const auto [a, b] = particle_links_[id];
      edge = {{particle(particles_start, a), particle(particles_start, b)},
              {particle(particles_end, a), particle(particles_end, b)}};
      rest_first = particle(model_.rest_positions(), a);
      rest_second = particle(model_.rest_positions(), b);
    } else {
      element = (id - link_count) / slots_per_element;
      const int slot = (id - link_count) % slots_per_element;
      slot_particle = element_link_particles_[element][slot];
      edge = {{points_start[element], particle(particles_start, slot_particle)},
              {points_end[element], particle(particles_end, slot_particle)}};
      rest_first = model_.element_centres()[element];
      rest_second = particle(model_.rest_positions(), slot_particle);
    }
    const auto hit = first_polyline_hit(blade_start, blade_end, edge);
    if (!hit) continue;
    report.rest_hits.push_back(rest_first + hit->hit.edge_parameter * (rest_second - rest_first));
    if (id < link_count) {
      particle_link_severed_[id] = 1;
      broad_phase_.remove_edge(id);
      ++report.particle_links_severed;
    } else {
      cut_from[element].push_back(slot_particle);
      ++report.element_links_severed;
    }
  }
  total_links_severed_ += report.particle_links_severed + report.element_links_severed;

  // Re-selection of the broken neighbourhoods, in element order (deterministic).
  for (const auto& [element, severed] : cut_from) {
    // The stride grows when a row does (set_neighbourhood), so it is read for each element.
    const size_t base = static_cast<size_t>(element) * model_.row_stride();
    std::vector<int> kept;
    for (int k = 0; k < model_.row_lengths()[element]; ++k) {
      const int p = model_.neighbours()[base + k];
      if (std::find(severed.begin(), severed.end(), p) == severed.end()) kept.push_back(p);
    }
    bool isolated = false;
    const std::vector<int> row = reselect(element, kept, blade_start, blade_end, points_start,
                                          points_end, particles_start, particles_end, isolated);
    report.elements_isolated += isolated ? 1 : 0;
    if (row.empty()) {
      ++report.reselection_failures;
      continue;
    }
    try {
      model_.set_neighbourhood(element, row);
      ++report.elements_reselected;
      report.changed_elements.push_back(element);
    } catch (const std::invalid_argument&) {
      ++report.reselection_failures;
    }
  }
  return report;
}

std::vector<int> VolumeCutter::reselect(int element, const std::vector<int>& kept,
                                        std::span<const Vec3> blade_start, std::span<const Vec3> blade_end,
                                        const std::vector<Vec3>& points_start,
                                        const std::vector<Vec3>& points_end,
                                        const Vector& particles_start, const Vector& particles_end,
                                        bool& isolated) {
  const Vec3 centre = model_.element_centres()[element];
  const auto rest = [&](int p) { return Vec3(model_.rest_positions().segment<3>(3 * static_cast<Eigen::Index>(p))); };
  const auto particle = [](const Vector& x, int p) { return Vec3(x.segment<3>(3 * static_cast<Eigen::Index>(p))); };
  std::vector<int> seeds = kept;
  if (seeds.empty()) {
    // Every link of the element was cut (several cuts in one element, or the blade through
    // its integration point): nothing tells which side it is on. Its nearest former
    // neighbour decides, which is at least deterministic; counted as isolated.
    isolated = true;
    const int stride = model_.row_stride();
    const size_t base = static_cast<size_t>(element) * stride;
    int nearest = -1;
    double best = 0;
    for (int k = 0; k < model_.row_lengths()[element]; ++k) {
      const int p = model_.neighbours()[base + k];
      const double d = (rest(p) - centre).squaredNorm();
      if (nearest < 0 || d < best || (d == best && p < nearest)) nearest = p, best = d;
    }
    if (nearest < 0) return {};
    seeds.push_back(nearest);
  }
  // Breadth-first over the particle-particle links that remain.
  std::map<int, int> distance;
  std::vector<int> frontier = seeds;
  for (int p : seeds) distance[p] = 0;
  for (int level = 1; level <= graph_radius; ++level) {
    std::vector<int> next;
    for (int p : frontier) {
      for (int link : links_of_particle_[p]) {
        if (particle_link_severed_[link]) continue;
        const int q = particle_links_[link][0] == p ? particle_links_[link][1] : particle_links_[link][0];
        if (distance.emplace(q, level).second) next.push_back(q);
      }
    }
    frontier.swap(next);
  }
  std::vector<std::tuple<int, double, int>> candidates;  // graph distance, rest distance^2, particle
  for (const auto& [p, level] : distance) {
    if (std::find(seeds.begin(), seeds.end(), p) != seeds.end()) continue;
    candidates.emplace_back(level, (rest(p) - centre).squaredNorm(), p);
  }
  std::sort(candidates.begin(), candidates.end());

  const int nominal = model_.settings().neighbours;
  std::vector<int> row = seeds;
  std::vector<Vec3> positions;
  for (int p : row) positions.push_back(rest(p));
  for (const auto& [level, squared, p] : candidates) {
    if (static_cast<int>(row.size()) >= nominal && spans_three_dimensions(positions)) break;
    if (static_cast<int>(row.size()) >= slots_per_element) break;
    // A new link the blade crosses in this very step would be cut at once.
    const MovingSegment link{{points_start[element], particle(particles_start, p)},
                             {points_end[element], particle(particles_end, p)}};
    if (first_polyline_hit(blade_start, blade_end, link)) continue;
    row.push_back(p);
    positions.push_back(rest(p));
  }
  if (!spans_three_dimensions(positions)) return {};
  std::sort(row.begin(), row.end());
  return row;
}

int VolumeCutter::pieces(std::vector<int>& piece) const {
  // Union-find over elements through shared particles.
  const int elements = model_.element_count();
  std::vector<int> parent(static_cast<size_t>(elements));
  for (int e = 0; e < elements; ++e) parent[e] = e;
  const auto root = [&](int e) {
    while (parent[e] != e) e = parent[e] = parent[parent[e]];
    return e;
  };
  std::vector<int> owner(static_cast<size_t>(model_.node_count()), -1);
  const int stride = model_.row_stride();
  for (int e = 0; e < elements; ++e) {
    const size_t base = static_cast<size_t>(e) * stride;
    for (int k = 0; k < model_.row_lengths()[e]; ++k) {
      const int p = model_.neighbours()[base + k];
      if (owner[p] < 0) {
        owner[p] = e;
      } else {
        const int a = root(owner[p]), b = root(e);
        if (a != b) parent[std::max(a, b)] = std::min(a, b);
      }
    }
  }
  piece.assign(static_cast<size_t>(elements), -1);
  std::map<int, int> number;
  for (int e = 0; e < elements; ++e) {
    const int r = root(e);
    const auto it = number.emplace(r, static_cast<int>(number.size())).first;
    piece[e] = it->second;
  }
  return static_cast<int>(number.size());
}

}  // namespace incise::physics
