// The builder the two Promayon models share (engine/models/shape_memory_model.cpp,
// spring_network_model.cpp): atoms on a lattice of about `resolution` filling the body's shape
// (the mass-spring's voxelisation: a box generator exactly, anything else by whole bricks),
// the force model with its stiffness given or from E by the calibration, the lattice's
// boundary as the closed surface whose volume the body may control, and the seed's step.
#pragma once

#include "engine/body.hpp"
#include "engine/body_builder.hpp"
#include "physics/promayon/calibration.hpp"

namespace incise::engine {

Body build_promayon_body(physics::PromayonKind kind, const BodySpec& spec, const SolverSpec& solver,
                         const BodyShape& shape);

}  // namespace incise::engine
