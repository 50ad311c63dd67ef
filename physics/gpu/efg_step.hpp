// The corotated EFG implicit Euler step on the GPU (OpenGL 4.5 compute; seed 004 ch. 6),
// computing what physics::implicit_euler_step computes for a CorotationalEfg.
//
// On the GPU: the element loop of the elastic forces and of K p, the diagonal of the system
// matrix, the right-hand side, the Jacobi-preconditioned CG with its vector kernels and
// reductions, the velocity and position update, and the surface-vertex and integration-point
// positions from their mapping weights. Per CG iteration two scalars are read back (p.Ap and
// r.r, all the stop test needs); step lengths and beta stay on the GPU.
// The per-element rotations: by default on the GPU (kernel element_rotation: the polar
// rotation of the MLS deformation gradient by the same warm-started Newton steps as
// corotational_efg.cpp, quaternions kept on the GPU), read back only as one flag per step
// saying whether every element settled; if one did not, or for a shape-matching model, or
// with GpuSettings::rotations_on_gpu false, model.update_rotations(x) runs on the CPU and
// the rotations go up as W = R - I (9 reals per element per step, GpuCounters::
// rotation_bytes). The rotations are kept as W = R - I in both cases: that keeps full float
// precision for the small rotations of most elements, where R itself would lose it to the 1
// on its diagonal. The model's own rotations() are then not updated by the GPU step. The
// elastic energy of the watchdog is computed on the CPU (model.elastic_energy, which extracts
// its rotations itself).
//
// Scatter without races: not by atomics (llvmpipe offers no GL_NV_shader_atomic_float, and
// no GL driver has double atomics) and not by colouring, but by a gather in two passes: each
// element writes its 3x3 stress term S_e = +-V_e R_e sigma_e, then each node sums S_e grad
// phi over its incidence row (the (element, slot) pairs that name it, fixed-stride like the
// element rows). Two dispatches per product whatever the topology, and a fixed summation
// order, so the result does not depend on scheduling. Colouring the beam's elements greedily
// needs 64 colours (8 per particle cell times 8 cell parities; more after cuts), i.e. 64
// dispatches per product, each a pipeline flush on a GPU and a thread-pool round trip on
// llvmpipe.
//
// Precision: the state lives on the GPU as displacements u = x - X, and an element's
// gradient is taken as grad u = H + W^T (G0 + H), H = sum_n (u_n - u_n0) (x) grad phi_n,
// G0 = sum_n (X_n - X_n0) (x) grad phi_n (n0 the row's first particle), which equals the CPU's
// R^T sum_n x_n (x) grad phi_n - G0 (the gradients sum to zero) without subtracting numbers
// near 1, so that float keeps the strain's digits.
//
// Uploads (seed 004 §3.3): the element rows (neighbours, phi, grad phi, row length, volume,
// G0), the nodes' incidence rows and the surface mapping rows are fixed-stride arrays
// allocated once with headroom (row stride + GpuSettings::row_headroom; surface vertices
// x surface_headroom). Each step the host compares every batch of batch_rows rows with what
// it last uploaded and sends only the batches that differ (so after a cut, the batches holding
// the re-selected elements, the nodes whose incidences changed and the remapped vertices).
// A row longer than the stride capacity, or more surface vertices than allocated, reallocates
// that array with fresh headroom and uploads it whole (counted in reallocations).
// Per step the state goes up (u, v, the CG warm start, external forces, rotations; masses and
// fixed flags when they changed, springs when there are any) and u, v, dv come back: the cut
// detection, contact and rendering on the CPU need them.
#pragma once

#include "physics/core/implicit_euler.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/gpu/compute_context.hpp"

#include <memory>
#include <string>

namespace incise::physics::gpu {

enum class Precision { single, double_precision };

struct GpuSettings {
  Precision precision = Precision::single;
  int batch_rows = 256;             // rows per upload batch (>= 1)
  int row_headroom = 4;             // extra slots per row beyond the model's stride
  double surface_headroom = 1.25;   // surface vertex capacity / vertices (>= 1)
  GlVersion required{4, 5};
  // Rotations from the deformation gradient computed on the GPU (EfgRotation::
  // deformation_gradient, the model's default); false, or a shape-matching model: computed on
  // the CPU by model.update_rotations and uploaded each step.
  bool rotations_on_gpu = true;
  // CG's iterations queued between two read-backs of its status (>= 1). Each read-back drains
  // the pipeline (on an H100 at 20k elements an iteration cost 0.37 ms, mostly waiting, with
  // one each); the checks themselves run on the GPU, so the iterate does not depend on it.
  int cg_iterations_per_check = 8;
};

// What went up, cumulative.
struct GpuCounters {
  long long row_bytes = 0;         // rows (element, incidence, surface), batches included
  long long row_batches = 0;
  long long element_batches = 0;
  long long incidence_batches = 0;
  long long surface_batches = 0;
  long long state_bytes = 0;       // per-step state, rotations included
  long long rotation_bytes = 0;
  long long reallocations = 0;     // arrays reallocated and uploaded whole
  long long rotation_fallbacks = 0;  // steps whose GPU rotations did not settle (CPU ones used)
  double ms_upload = 0;            // wall time of the uploads
  long long bytes_uploaded() const { return row_bytes + state_bytes; }
};

class EfgStep {
 public:
  // Makes its own context (ComputeContext::create(settings.required)) and uploads the
  // model's rows. Throws ComputeUnavailable (no compute, or double asked where the driver
  // has no fp64) or std::invalid_argument (bad settings, naming the field).
  EfgStep(const CorotationalEfg& model, const GpuSettings& settings);
  ~EfgStep();
  EfgStep(const EfgStep&) = delete;
  EfgStep& operator=(const EfgStep&) = delete;

  // The same contract as physics::implicit_euler_step (implicit_euler.hpp).
  StepReport step(CorotationalEfg& model, State& state, const std::vector<uint8_t>& fixed_nodes,
                  const Vector& external_forces, std::span<const NodalSpring> springs,
                  const ImplicitEulerSettings& settings, Vector* velocity_change = nullptr);

  // Uploads the embedding's rows that differ from the GPU's copy (surface_positions does it
  // too; the engine calls this once at build so that the first step uploads no rows).
  void upload_surface(const SurfaceEmbedding& embedding);
  // out = the embedded surface vertex positions for the displacements of the last step
  // accepted on the GPU (uploads the embedding's changed batches first).
  void surface_positions(const SurfaceEmbedding& embedding, Vector& out);
  // out (3 x elements) = the integration points' positions sum_n phi_n x_n, same state.
  void integration_points(const CorotationalEfg& model, Vector& out);

  const GpuCounters& counters() const { return counters_; }
  // Bytes of one full upload of the rows at the current capacities (the cost of rebuilding
  // everything after a topology change, as SOFA's CUDA path does).
  long long full_row_bytes() const;
  // Current strides of the GPU's element rows, incidence rows and surface rows, and its
  // surface vertex capacity (the layouts are in the file comment).
  int row_capacity() const;
  bool rotations_on_gpu(const CorotationalEfg& model) const;
  int incidence_capacity() const;
  int surface_row_capacity() const;
  int surface_capacity() const;
  const std::string& device() const { return context_->renderer(); }
  const std::string& gl_version() const { return context_->version(); }
  Precision precision() const { return settings_.precision; }
  int real_bytes() const { return settings_.precision == Precision::single ? 4 : 8; }

 private:
  // step()'s stages, in order: its arguments checked (std::invalid_argument), this step's
  // state uploaded (changed rows, parameters, masses, fixed nodes, springs, u, v, the loads,
  // the warm start, the rotations), the right-hand side and CG on the GPU (false: a non-finite
  // value), and the integration read back into `state` (false: a non-finite value).
  void check_arguments(const CorotationalEfg& model, const State& state, const std::vector<uint8_t>& fixed_nodes,
                       const Vector& external_forces, std::span<const NodalSpring> springs,
                       const ImplicitEulerSettings& settings) const;
  void upload_step(CorotationalEfg& model, const State& state, const std::vector<uint8_t>& fixed,
                   const Vector& external_forces, std::span<const NodalSpring> springs,
                   const ImplicitEulerSettings& settings, const Vector* velocity_change_guess);
  void upload_springs(std::span<const NodalSpring> springs);
  void upload_cpu_rotations(CorotationalEfg& model, const State& state);
  void upload_rotations(CorotationalEfg& model, const State& state);
  bool solve_velocity_change(const ImplicitEulerSettings& settings, CgResult& cg);
  bool integrate(const CorotationalEfg& model, State& state, const std::vector<uint8_t>& fixed,
                 Vector* velocity_change_guess);

  struct Impl;
  std::unique_ptr<ComputeContext> context_;
  GpuSettings settings_;
  GpuCounters counters_;
  std::unique_ptr<Impl> impl_;
};

std::string precision_name(Precision precision);  // "single" or "double"

}  // namespace incise::physics::gpu
