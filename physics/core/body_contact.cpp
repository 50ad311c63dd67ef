#include "physics/core/body_contact.hpp"

#include "physics/core/contact.hpp"

#include <algorithm>
#include <cmath>

namespace incise::physics {

namespace {

// The contact's springs on the body's nodes: a tetrahedral body's surface nodes are its nodes;
// an embedded surface's vertex springs go to the particles the vertices follow.
std::vector<NodalSpring> on_nodes(const BodyData& body, ProbeContact contact) {
  if (!body.embedding) return std::move(contact.springs);
  // Embedded surface: the contact acts on surface vertices, and a vertex force f_v goes to the
  // particles with the vertex's weights, f_i = w_i f_v (seed-004 §2.6), so the total force is
  // unchanged (the weights sum to 1). The exact stiffness W^T K_v W couples the particles;
  // each particle takes |w_i| K_v instead (the row sums of W^T K_v W, made positive
  // semi-definite: the MLS weights of far corners are negative), which keeps the implicit
  // system symmetric positive definite.
  const auto& embedding = *body.embedding;
  std::vector<int> slot(static_cast<std::size_t>(body.mechanics->node_count()), -1);
  std::vector<NodalSpring> springs;
  for (const auto& vertex_spring : contact.springs) {
    const std::size_t row = static_cast<std::size_t>(vertex_spring.node) * embedding.stride;
    for (int k = 0; k < embedding.row_lengths[vertex_spring.node]; ++k) {
      const int particle = embedding.particles[row + k];
      if (body.fixed[particle]) continue;
      const double weight = embedding.weights[row + k];
      if (slot[particle] < 0) {
        slot[particle] = static_cast<int>(springs.size());
        springs.push_back({particle, Vec3::Zero(), Mat3::Zero()});
      }
      auto& spring = springs[slot[particle]];
      spring.force += weight * vertex_spring.force;
      spring.stiffness += std::abs(weight) * vertex_spring.stiffness;
    }
  }
  return springs;
}

const Vector& contact_positions(const BodyData& body) {
  return body.embedding ? body.surface_positions : body.state.positions;
}

const std::vector<std::uint8_t>& contact_fixed(const BodyData& body) {
  return body.embedding ? body.fixed_vertices : body.fixed;
}

}  // namespace

std::vector<NodalSpring> body_contact(const BodyData& body, const Vec3& tip, const Vec3& tail, double radius,
                                      double stiffness, int& triangles_touched) {
  auto contact = probe_contact(contact_positions(body), body.surface, contact_fixed(body), tip, tail, radius, stiffness);
  triangles_touched += contact.triangles_touched;
  return on_nodes(body, std::move(contact));
}

std::vector<NodalSpring> body_edge_contact(const BodyData& body, const std::vector<Vec3>& edge, double radius,
                                           double stiffness, double spacing, int& triangles_touched) {
  const Vector& x = contact_positions(body);
  const auto& fixed = contact_fixed(body);
  std::vector<NodalSpring> springs;
  std::vector<Vec3> points;
  for (std::size_t i = 0; i + 1 < edge.size(); ++i) {
    auto contact = probe_contact(x, body.surface, fixed, edge[i], edge[i + 1], radius, stiffness);
    triangles_touched += contact.triangles_touched;
    auto segment = on_nodes(body, std::move(contact));
    springs.insert(springs.end(), segment.begin(), segment.end());
    if (!(spacing > 0)) continue;
    const int count = std::max(1, static_cast<int>(std::ceil((edge[i + 1] - edge[i]).norm() / spacing)));
    for (int k = 0; k < count; ++k) points.push_back(edge[i] + (static_cast<double>(k) / count) * (edge[i + 1] - edge[i]));
  }
  if (!(spacing > 0)) return springs;
  if (!edge.empty()) points.push_back(edge.back());
  auto held = held_contact(x, body.surface, fixed, points, radius, stiffness);
  triangles_touched += held.triangles_touched;
  auto hold = on_nodes(body, std::move(held));
  springs.insert(springs.end(), hold.begin(), hold.end());
  return springs;
}

}  // namespace incise::physics
