// The engine's body: physics' model and data (physics/core/body.hpp, physics/cut/cut_body.hpp)
// and what the engine adds to run it.
#pragma once

#include "engine/thread_pool.hpp"
#include "physics/core/body.hpp"
#include "physics/cut/cut_body.hpp"

#include <memory>

namespace incise::physics::gpu {
class EfgStep;  // physics/gpu/efg_step.hpp
}

namespace incise::engine {

// Where a body's construction went, in ms of wall time (incise check prints it, metrics.json
// has it as build_ms). Never an input to the simulation.
struct BuildTimes {
  double shape = 0;    // the shape's inside test: a mesh read and its hierarchy (surface_queries.hpp)
  double volume = 0;   // the elements over the shape: EFG cells and their volumes, or the tetrahedra
  double surface = 0;  // the render or first cut surface put onto the shape (voxel boundary, fairing)
  double cut = 0;      // a cuttable body's cut state over it
  double settle = 0;   // solver.start "settled": the static solve
  double total = 0;
};

// A body: its read-only model and its data (physics/core/body.hpp), and for a cuttable body
// the same split of its cut (physics/cut/cut_body.hpp). The engine adds what runs it: the
// threads its model's loops use and, with solver.backend "gpu", its step on the GPU.
//
// A copy is the same body stepping on to the same future, bit for bit, sharing nothing that
// changes: it shares the read-only models, copies the data and the cut (physics' copies, the cut
// made for the copied EFG model) and starts threads of its own, as many, which its model's
// loops then run on. A body on the GPU is not copied (std::runtime_error naming it): its step
// keeps a context and buffers of its own.
struct Body {
  Body() = default;
  Body(const Body& other);
  Body& operator=(const Body& other);
  Body(Body&&) = default;
  Body& operator=(Body&&) = default;
  ~Body() = default;

  std::shared_ptr<const physics::BodyModel> model;
  physics::BodyData data;
  std::shared_ptr<const physics::CutModel> cut_model;  // cuttable bodies only
  std::unique_ptr<physics::CutData> cut;
  // EFG bodies: efg.threads threads for their model's loops (the physics thread among them),
  // with a side thread for a cuttable body with efg.threads >= 2, on which a cutting step's
  // surface cut runs beside the volume's (apply_topology). The model owns none.
  std::unique_ptr<ThreadPoolExecutor> executor;
  // The executor the body's loops run on: its threads, or the caller's alone.
  physics::Executor& threads() const {
    return executor ? static_cast<physics::Executor&>(*executor) : physics::serial_executor();
  }
  std::shared_ptr<physics::gpu::EfgStep> gpu;  // solver.backend "gpu": its step, surface and rows
  BuildTimes build_ms;
};

}  // namespace incise::engine
