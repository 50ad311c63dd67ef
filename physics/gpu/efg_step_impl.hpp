// EfgStep's state (its Impl) and the GL plumbing its files share: efg_step.cpp (the step and
// its CG), efg_step_device.cpp (buffers, kernels and their dispatch), efg_step_rows.cpp (the
// model's element, incidence and surface rows kept in sync on the GPU, only the batches that
// changed going up). Internal to physics/gpu.
#pragma once

#include "physics/gpu/efg_kernels.hpp"
#include "physics/gpu/efg_step.hpp"
#include "physics/gpu/gl.hpp"

#include <array>
#include <chrono>
#include <initializer_list>
#include <utility>
#include <vector>

namespace incise::physics::gpu {

using Index = Eigen::Index;
using Clock = std::chrono::steady_clock;

// Fixed binding points (efg_kernels.cpp).
enum Binding : GLuint {
  neighbours_binding = 0, gradients_binding, values_binding, lengths_binding, volumes_binding,
  rest_gradients_binding, rotations_binding, stresses_binding, incidence_binding,
  incidence_lengths_binding, rest_binding, masses_binding, free_binding, spring_index_binding,
  spring_force_binding, spring_stiffness_binding, parameters_binding, scalars_binding,
  partials_binding, a_binding, b_binding, c_binding, d_binding, e_binding, f_binding, orientations_binding,
  flags_binding
};

// Scalars: 0 p.Ap, 1 r.r, 2 and 3 r.z (old and new in turn), 4 b.b, 5 and 6 the guess's
// scale, 7 (tolerance |b|)^2 (efg_kernels.cpp's THRESHOLD_SLOT).
inline constexpr int curvature_slot = 0, residual_slot = 1, rz_slot = 2, rhs_slot = 4, guess_slot = 5, threshold_slot = 7;


// Incidence rows get this many slots (at least; a quarter of the longest row if more)
// beyond the longest at (re)allocation: re-selection after cuts adds particles beyond the
// cell, so interior particles gain incidences.
inline constexpr int incidence_headroom = 8;

struct Buffer {
  GLuint id = 0;
  long long bytes = 0;
};

// Throws with the GL error and `where` when the last calls left one.
void check_gl(const char* where);

// The kernel's program, compiled and linked; ComputeUnavailable with the driver's log if not.
GLuint compile(Kernel kernel, bool double_precision);

struct EfgStep::Impl {
  bool double_precision = false;
  int real_bytes = 4;
  GpuCounters* counters = nullptr;
  const GpuSettings* settings = nullptr;

  struct Program {
    GLuint id = 0;
    GLint count = -1, stride = -1, incidence_stride = -1, mode = -1, slot0 = -1, slot1 = -1, cg_gate = -1, limit = -1;
  };
  std::array<Program, static_cast<size_t>(Kernel::count)> programs{};

  int elements = 0, nodes = 0;
  int stride_capacity = 0, incidence_capacity = 0;
  int surface_capacity = 0, surface_stride_capacity = 0;

  // Rows.
  Buffer neighbours, gradients, values, lengths, volumes, rest_gradients;
  Buffer incidence, incidence_lengths;
  Buffer surface_particles, surface_weights, surface_lengths, surface_out, points_out;
  // Per step.
  Buffer rotations, stresses, rest, masses, free, spring_index, spring_force, spring_stiffness;
  Buffer parameters, scalars, partials, orientations, flags;
  Buffer u, v, u_next, v_next, external, forces, stiffness_velocity, rhs, dv, r, z, p, product,
      inverse_diagonal;

  // What the GPU holds, in the model's layout (to find the changed rows).
  int shadow_stride = -1;
  std::vector<int> shadow_neighbours, shadow_lengths;
  std::vector<double> shadow_values, shadow_gradients, shadow_volumes;
  std::vector<int> host_incidence, host_incidence_lengths;  // in the GPU layout
  bool incidence_uploaded = false;
  std::vector<double> shadow_masses;
  std::vector<std::uint8_t> shadow_fixed;
  bool springs_uploaded = false;
  int spring_capacity = 0;
  int surface_shadow_stride = -1;
  std::vector<int> surface_shadow_particles, surface_shadow_lengths;
  std::vector<double> surface_shadow_weights;
  int surface_vertices = 0;

  // Staging for conversions.
  std::vector<unsigned char> staging;
  std::vector<double> reals;
  std::vector<int> ints;

  ~Impl();

  std::vector<Buffer*> all_buffers();

  void allocate(Buffer& buffer, long long bytes);
  void allocate_reals(Buffer& buffer, long long count) { allocate(buffer, count * real_bytes); }
  void allocate_ints(Buffer& buffer, long long count) { allocate(buffer, count * 4); }

  // Uploads count reals from data at entry `first`; returns the bytes sent.
  long long upload_reals(Buffer& buffer, long long first, const double* data, long long count);
  long long upload_ints(Buffer& buffer, long long first, const int* data, long long count);
  void download_reals(const Buffer& buffer, long long count, double* out);
  std::array<double, 2> read_scalars(int first);

  void build_programs();

  void bind(GLuint binding, const Buffer& buffer) { glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding, buffer.id); }

  void bind_fixed();

  void run(Kernel kernel, int count, std::initializer_list<std::pair<GLuint, const Buffer*>> vectors,
           int mode = 0, int slot0 = 0, int slot1 = 0, int stride = -1);

  // Inside CG's loop: the loop's kernels stop once flags[1] is set (efg_kernels.cpp, CG_DONE).
  int cg_gate = 0;
  int cg_limit = 0;

  // INCISE_GPU_PROFILE=1: glFinish after every dispatch and the time per kernel on stderr
  // when the step is destroyed (a measurement aid; it serialises the pipeline).
  bool profile = false;
  std::array<double, static_cast<size_t>(Kernel::count)> kernel_ms{};
  std::array<long, static_cast<size_t>(Kernel::count)> kernel_runs{};
  void print_profile() const;

  // Two dot products a.b -> scalars[slot0] and (c.d -> scalars[slot1] when c is given).
  void dot(int count, const Buffer& a, const Buffer& b, int slot0, const Buffer* c = nullptr,
           const Buffer* d = nullptr, int slot1 = 0);

  // out = A p (mode 2), K p (mode 1) for p in `in`.
  void product_of(const Buffer& in, const Buffer& out, int mode) {
    run(Kernel::element_stress, elements, {{a_binding, &in}}, 1);
    run(Kernel::node_gather, nodes, {{a_binding, &in}, {c_binding, &out}}, mode);
  }

  long long element_row_bytes() const {
    return static_cast<long long>(stride_capacity) * (4 + 4LL * real_bytes) + 4 + 10LL * real_bytes;
  }
  long long incidence_row_bytes() const { return static_cast<long long>(incidence_capacity) * 4 + 4; }
  long long surface_row_bytes() const {
    return static_cast<long long>(surface_stride_capacity) * (4 + real_bytes) + 4;
  }

  void allocate_rows();

  // Uploads rows [first, last) of the element arrays in the GPU layout.
  void upload_element_rows(const CorotationalEfg& model, int first, int last);

  // Element rows and incidences: the batches that differ from the GPU's copy go up.
  void sync_rows(const CorotationalEfg& model);

  // Each node's (element, slot) pairs in element order, as slots of the GPU layout.
  void sync_incidence(const CorotationalEfg& model, bool everything);

  void sync_surface(const SurfaceEmbedding& embedding);

  long long state_upload(Buffer& buffer, const double* data, long long count) {
    const long long bytes = upload_reals(buffer, 0, data, count);
    counters->state_bytes += bytes;
    return bytes;
  }
};

}  // namespace incise::physics::gpu
