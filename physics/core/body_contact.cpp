#include "physics/core/body_contact.hpp"

#include "physics/core/contact.hpp"

#include <cmath>

namespace incise::physics {

std::vector<NodalSpring> body_contact(const BodyData& body, const Vec3& tip, const Vec3& tail, double radius,
                                      double stiffness, int& triangles_touched) {
  if (!body.embedding) {
    auto contact = probe_contact(body.state.positions, body.surface, body.fixed, tip, tail, radius, stiffness);
    triangles_touched += contact.triangles_touched;
    return std::move(contact.springs);
  }
  // Embedded surface: the contact acts on surface vertices, and a vertex force f_v goes to the
  // particles with the vertex's weights, f_i = w_i f_v (seed-004 §2.6), so the total force is
  // unchanged (the weights sum to 1). The exact stiffness W^T K_v W couples the particles;
  // each particle takes |w_i| K_v instead (the row sums of W^T K_v W, made positive
  // semi-definite: the MLS weights of far corners are negative), which keeps the implicit
  // system symmetric positive definite.
  auto contact = probe_contact(body.surface_positions, body.surface, body.fixed_vertices, tip, tail, radius, stiffness);
  triangles_touched += contact.triangles_touched;
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

}  // namespace incise::physics
