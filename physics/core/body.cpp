#include "physics/core/body.hpp"

namespace incise::physics {

std::uint8_t fixed_vertex(const BodyData& body, int v) {
  const auto& embedding = *body.embedding;
  for (int k = 0; k < embedding.row_lengths[static_cast<std::size_t>(v)]; ++k)
    if (!body.fixed[static_cast<std::size_t>(embedding.particles[static_cast<std::size_t>(v) * embedding.stride + k])]) return 0;
  return 1;
}

void set_fixed_vertices(BodyData& body) {
  const auto& embedding = *body.embedding;
  body.fixed_vertices.resize(static_cast<std::size_t>(embedding.vertex_count()));
  for (int v = 0; v < embedding.vertex_count(); ++v) body.fixed_vertices[static_cast<std::size_t>(v)] = fixed_vertex(body, v);
}

void set_surface_position(BodyData& body, int v) {
  const SurfaceEmbedding& embedding = *body.embedding;
  const std::size_t row = static_cast<std::size_t>(v) * static_cast<std::size_t>(embedding.stride);
  Vec3 position = Vec3::Zero();
  for (int k = 0; k < embedding.row_lengths[static_cast<std::size_t>(v)]; ++k)
    position += embedding.weights[row + static_cast<std::size_t>(k)] *
                body.state.positions.segment<3>(3 * static_cast<Eigen::Index>(embedding.particles[row + static_cast<std::size_t>(k)]));
  body.surface_positions.segment<3>(3 * static_cast<Eigen::Index>(v)) = position;
}

}  // namespace incise::physics
