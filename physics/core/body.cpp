#include "physics/core/body.hpp"

#include <stdexcept>

namespace incise::physics {

// Every member is copied here: a member added to BodyData must be added to this list.
BodyData::BodyData(const BodyData& other)
    : mechanics(other.mechanics ? other.mechanics->clone() : nullptr),
      state(other.state),
      warm_start(other.warm_start),
      last_energy(other.last_energy),
      fixed(other.fixed),
      topology_revision(other.topology_revision),
      preconditioner(other.preconditioner),  // shares the immutable factors, in use and being built
      gravity(other.gravity),
      surface(other.surface),
      render_triangles(other.render_triangles),
      render_cut_face(other.render_cut_face),
      embedding(other.embedding),
      surface_positions(other.surface_positions),
      fixed_vertices(other.fixed_vertices) {
  // efg is the mechanics seen as an EFG model: the copy's own.
  if (other.efg) {
    efg = dynamic_cast<CorotationalEfg*>(mechanics.get());
    if (!efg || other.efg != other.mechanics.get())
      throw std::logic_error("BodyData: efg is not the body's mechanical model; cannot copy the body");
  }
}

BodyData& BodyData::operator=(const BodyData& other) {
  if (this != &other) *this = BodyData(other);
  return *this;
}

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
