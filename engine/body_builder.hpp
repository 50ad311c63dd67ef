// Scene body -> engine::Body: the shape (generator or mesh file), the model named by the
// body's `model` key (fem: tetrahedra filling the shape; efg: the meshless model with a render
// surface of its own, and for a cuttable body the cut's state), fixed regions, gravity, the
// settled start and the integrator's settings.
#pragma once

#include "engine/body.hpp"
#include "engine/scene.hpp"

namespace incise::engine {

// Throws std::runtime_error naming the body (and the field, where one is at fault).
Body build_body(const BodySpec& spec, const SolverSpec& solver);

}  // namespace incise::engine
