// contact: the probe's penalty springs on the touched surface, passed to the nodes or particles.
#include "engine/world.hpp"

#include "physics/core/contact.hpp"

#include <cmath>

namespace incise::engine {

namespace {

physics::Vec3 vec(const std::array<double, 3>& p) { return {p[0], p[1], p[2]}; }

}  // namespace

std::vector<physics::NodalSpring> World::contact(const Body& body, StepStats& stats) const {
  if (!tool_.present || blade()) return {};  // the ideal blade applies no force (seed 004 §2.2)
  if (!body.data.embedding) {
    auto contact = physics::probe_contact(body.data.state.positions, body.data.surface, body.data.fixed, vec(tool_.tip),
                                          vec(tool_.tail), tool_.radius, scene_.tool->stiffness);
    stats.contacts += contact.triangles_touched;
    return std::move(contact.springs);
  }
  // Embedded surface: the contact acts on surface vertices, and a vertex force f_v goes to the
  // particles with the vertex's weights, f_i = w_i f_v (seed-004 §2.6), so the total force is
  // unchanged (the weights sum to 1). The exact stiffness W^T K_v W couples the particles;
  // each particle takes |w_i| K_v instead (the row sums of W^T K_v W, made positive
  // semi-definite: the MLS weights of far corners are negative), which keeps the implicit
  // system symmetric positive definite.
  auto contact = physics::probe_contact(body.data.surface_positions, body.data.surface, body.data.fixed_vertices,
                                        vec(tool_.tip), vec(tool_.tail), tool_.radius,
                                        scene_.tool->stiffness);
  stats.contacts += contact.triangles_touched;
  const auto& embedding = *body.data.embedding;
  std::vector<int> slot(static_cast<std::size_t>(body.data.mechanics->node_count()), -1);
  std::vector<physics::NodalSpring> springs;
  for (const auto& vertex_spring : contact.springs) {
    const std::size_t row = static_cast<std::size_t>(vertex_spring.node) * embedding.stride;
    for (int k = 0; k < embedding.row_lengths[vertex_spring.node]; ++k) {
      const int particle = embedding.particles[row + k];
      if (body.data.fixed[particle]) continue;
      const double weight = embedding.weights[row + k];
      if (slot[particle] < 0) {
        slot[particle] = static_cast<int>(springs.size());
        springs.push_back({particle, physics::Vec3::Zero(), physics::Mat3::Zero()});
      }
      auto& spring = springs[slot[particle]];
      spring.force += weight * vertex_spring.force;
      spring.stiffness += std::abs(weight) * vertex_spring.stiffness;
    }
  }
  return springs;
}

}  // namespace incise::engine
