// update_surface: an embedded surface's vertices from the particles (seed 004 §2.6).
#include "engine/world.hpp"

#include "physics/gpu/efg_step.hpp"

namespace incise::engine {

void World::update_surface(Body& body) const {
  if (!body.data.embedding) return;  // the surface vertices are nodes
  if (body.gpu)
    body.gpu->surface_positions(*body.data.embedding, body.data.surface_positions);
  else
    physics::CorotationalEfg::surface_positions(*body.data.embedding, body.data.state.positions,
                                                body.data.surface_positions, body.threads());
}

}  // namespace incise::engine
