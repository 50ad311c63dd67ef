#include "physics/gpu/efg_step_impl.hpp"

#include "physics/fem/material.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <initializer_list>
#include <map>
#include <stdexcept>
#include <utility>

namespace incise::physics::gpu {

std::string precision_name(Precision precision) {
  return precision == Precision::single ? "single" : "double";
}

EfgStep::EfgStep(const CorotationalEfg& model, const GpuSettings& settings) : settings_(settings) {
  if (settings.batch_rows < 1)
    throw std::invalid_argument("gpu batch_rows must be at least 1, got " + std::to_string(settings.batch_rows));
  if (settings.cg_iterations_per_check < 1)
    throw std::invalid_argument("gpu cg_iterations_per_check must be at least 1, got " +
                                std::to_string(settings.cg_iterations_per_check));
  if (settings.row_headroom < 0)
    throw std::invalid_argument("gpu row_headroom must not be negative, got " + std::to_string(settings.row_headroom));
  if (!(settings.surface_headroom >= 1) || !std::isfinite(settings.surface_headroom))
    throw std::invalid_argument("gpu surface_headroom must be at least 1, got " + std::to_string(settings.surface_headroom));
  context_ = ComputeContext::create(settings.required);
  CurrentScope current(*context_);
  const bool want_double = settings.precision == Precision::double_precision;
  if (want_double && !context_->double_precision()) {
    throw ComputeUnavailable("GPU backend: double precision needs GL_ARB_gpu_shader_fp64, which OpenGL " +
                             context_->version() + " on '" + context_->renderer() + "' does not offer");
  }
  GLint bindings = 0, blocks = 0;
  glGetIntegerv(GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS, &bindings);
  glGetIntegerv(GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS, &blocks);
  if (bindings < 27 || blocks < 13) {
    throw ComputeUnavailable("GPU backend: the kernels need 27 storage buffer bindings and 13 blocks per compute "
                             "shader; OpenGL " + context_->version() + " on '" + context_->renderer() + "' has " +
                             std::to_string(bindings) + " and " + std::to_string(blocks));
  }
  impl_ = std::make_unique<Impl>();
  Impl& s = *impl_;
  s.double_precision = want_double;
  const char* profile = std::getenv("INCISE_GPU_PROFILE");
  s.profile = profile && std::strcmp(profile, "1") == 0;
  s.real_bytes = want_double ? 8 : 4;
  s.counters = &counters_;
  s.settings = &settings_;
  s.build_programs();
  s.elements = model.element_count();
  s.nodes = model.node_count();
  s.stride_capacity = model.row_stride() + settings.row_headroom;
  s.allocate_rows();
  const long long dofs = 3LL * s.nodes;
  s.allocate_reals(s.rotations, 9LL * s.elements);
  s.allocate_reals(s.stresses, 9LL * s.elements);
  s.allocate_reals(s.rest, dofs);
  s.allocate_reals(s.masses, s.nodes);
  s.allocate_reals(s.free, s.nodes);
  s.allocate_ints(s.spring_index, s.nodes);
  s.allocate_reals(s.spring_force, 3);
  s.allocate_reals(s.spring_stiffness, 9);
  s.allocate_reals(s.parameters, 8);
  s.allocate_reals(s.scalars, 8);
  s.allocate_reals(s.partials, 2 * kReduceGroups * kGroupSize);
  for (Buffer* b : {&s.u, &s.v, &s.u_next, &s.v_next, &s.external, &s.forces, &s.stiffness_velocity,
                    &s.rhs, &s.dv, &s.r, &s.z, &s.p, &s.product, &s.inverse_diagonal})
    s.allocate_reals(*b, dofs);
  s.allocate_reals(s.points_out, 3LL * s.elements);
  s.allocate_reals(s.orientations, 4LL * s.elements);
  s.allocate_ints(s.flags, 4);
  {
    std::vector<double> identity(4 * static_cast<size_t>(s.elements), 0.0);
    for (int e = 0; e < s.elements; ++e) identity[4 * static_cast<size_t>(e) + 3] = 1.0;
    s.state_upload(s.orientations, identity.data(), static_cast<long long>(identity.size()));
  }
  const std::vector<int> no_springs(static_cast<size_t>(s.nodes), -1);
  counters_.state_bytes += s.upload_ints(s.spring_index, 0, no_springs.data(), s.nodes);
  const std::vector<double> zeros(static_cast<size_t>(dofs), 0.0);
  s.state_upload(s.u, zeros.data(), dofs);
  counters_.row_bytes += s.upload_reals(s.rest, 0, model.rest_positions().data(), dofs);
  s.sync_rows(model);
  check_gl("uploading the model");
}

EfgStep::~EfgStep() {
  if (!context_) return;
  try {
    CurrentScope current(*context_);
    impl_.reset();
  } catch (...) {
    // The objects go with the context.
  }
}

bool EfgStep::rotations_on_gpu(const CorotationalEfg& model) const {
  return settings_.rotations_on_gpu && model.settings().rotation == EfgRotation::deformation_gradient;
}

int EfgStep::row_capacity() const { return impl_->stride_capacity; }
int EfgStep::incidence_capacity() const { return impl_->incidence_capacity; }
int EfgStep::surface_row_capacity() const { return impl_->surface_stride_capacity; }
int EfgStep::surface_capacity() const { return impl_->surface_capacity; }

long long EfgStep::full_row_bytes() const {
  const Impl& s = *impl_;
  return s.elements * s.element_row_bytes() + s.nodes * s.incidence_row_bytes() +
         static_cast<long long>(s.surface_vertices) * s.surface_row_bytes();
}

void EfgStep::check_arguments(const CorotationalEfg& model, const State& state, const std::vector<uint8_t>& fixed_nodes,
                              const Vector& external_forces, std::span<const NodalSpring> springs,
                              const ImplicitEulerSettings& settings) const {
  const Impl& s = *impl_;
  const int nodes = model.node_count();
  const Index size = 3 * static_cast<Index>(nodes);
  if (nodes != s.nodes || model.element_count() != s.elements)
    throw std::invalid_argument("EfgStep::step: the model has " + std::to_string(nodes) + " particles and " +
                                std::to_string(model.element_count()) + " elements, the GPU copy " +
                                std::to_string(s.nodes) + " and " + std::to_string(s.elements));
  if (state.positions.size() != size || state.velocities.size() != size || external_forces.size() != size)
    throw std::invalid_argument("EfgStep::step: state or external forces do not have " + std::to_string(size) + " entries");
  if (!fixed_nodes.empty() && static_cast<int>(fixed_nodes.size()) != nodes)
    throw std::invalid_argument("EfgStep::step: fixed_nodes has " + std::to_string(fixed_nodes.size()) +
                                " entries, expected " + std::to_string(nodes));
  for (const NodalSpring& spring : springs)
    if (spring.node < 0 || spring.node >= nodes)
      throw std::invalid_argument("EfgStep::step: spring node " + std::to_string(spring.node) + " outside [0, " +
                                  std::to_string(nodes) + ")");
  if (!(settings.dt > 0.0)) throw std::invalid_argument("EfgStep::step: dt must be positive");
}

StepReport EfgStep::step(CorotationalEfg& model, State& state, const std::vector<uint8_t>& fixed_nodes,
                         const Vector& external_forces, std::span<const NodalSpring> springs,
                         const ImplicitEulerSettings& settings, Vector* velocity_change_guess) {
  check_arguments(model, state, fixed_nodes, external_forces, springs, settings);
  CurrentScope current(*context_);
  StepReport report;
  std::vector<std::uint8_t> fixed = fixed_nodes;
  fixed.resize(static_cast<size_t>(model.node_count()), 0);
  upload_step(model, state, fixed, external_forces, springs, settings, velocity_change_guess);
  if (!solve_velocity_change(settings, report.cg) || !integrate(model, state, fixed, velocity_change_guess)) {
    report.nonfinite = true;
    return report;
  }
  report.elastic_energy = model.elastic_energy(state.positions);
  report.kinetic_energy = kinetic_energy(model.lumped_masses(), state.velocities);
  return report;
}

void EfgStep::upload_cpu_rotations(CorotationalEfg& model, const State& state) {
  Impl& s = *impl_;
  model.update_rotations(state.positions);
  const auto& rotations = model.rotations();
  std::vector<double> offsets(9 * static_cast<size_t>(s.elements));
  for (int e = 0; e < s.elements; ++e)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) offsets[9 * static_cast<size_t>(e) + 3 * i + j] = rotations[e](i, j) - (i == j ? 1.0 : 0.0);
  counters_.rotation_bytes += s.state_upload(s.rotations, offsets.data(), static_cast<long long>(offsets.size()));
}

// Springs summed per node (several contact springs may share a particle), in order.
void EfgStep::upload_springs(std::span<const NodalSpring> springs) {
  Impl& s = *impl_;
  if (springs.empty() && !s.springs_uploaded) return;
  std::map<int, int> slot_of;
  for (const NodalSpring& spring : springs) slot_of.emplace(spring.node, static_cast<int>(slot_of.size()));
  const int count = static_cast<int>(slot_of.size());
  std::vector<double> force(3 * static_cast<size_t>(std::max(count, 1)), 0.0), stiffness(9 * static_cast<size_t>(std::max(count, 1)), 0.0);
  for (const NodalSpring& spring : springs) {
    const int slot = slot_of[spring.node];
    for (int i = 0; i < 3; ++i) {
      force[3 * slot + i] += spring.force[i];
      for (int j = 0; j < 3; ++j) stiffness[9 * slot + 3 * i + j] += spring.stiffness(i, j);
    }
  }
  std::vector<int> index(static_cast<size_t>(s.nodes), -1);
  for (const auto& [node, slot] : slot_of) index[node] = slot;
  if (count > s.spring_capacity) {
    s.spring_capacity = 2 * count;
    s.allocate_reals(s.spring_force, 3LL * s.spring_capacity);
    s.allocate_reals(s.spring_stiffness, 9LL * s.spring_capacity);
    s.bind(spring_force_binding, s.spring_force);
    s.bind(spring_stiffness_binding, s.spring_stiffness);
  }
  counters_.state_bytes += s.upload_ints(s.spring_index, 0, index.data(), s.nodes);
  s.state_upload(s.spring_force, force.data(), 3LL * count);
  s.state_upload(s.spring_stiffness, stiffness.data(), 9LL * count);
  s.springs_uploaded = !springs.empty();
}

void EfgStep::upload_rotations(CorotationalEfg& model, const State& state) {
  Impl& s = *impl_;
  const int clear = 0;
  counters_.state_bytes += s.upload_ints(s.flags, 0, &clear, 1);
  s.run(Kernel::element_rotation, s.elements, {{a_binding, &s.u}});
  int unsettled = 0;
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  glGetNamedBufferSubData(s.flags.id, 0, 4, &unsettled);
  if (unsettled != 0) {
    // An element's Newton steps did not settle (a strongly inverted or degenerate one):
    // this step takes the CPU's rotations, which fall back to the SVD polar.
    counters_.rotation_fallbacks++;
    upload_cpu_rotations(model, state);
  }
}

void EfgStep::upload_step(CorotationalEfg& model, const State& state, const std::vector<uint8_t>& fixed,
                          const Vector& external_forces, std::span<const NodalSpring> springs,
                          const ImplicitEulerSettings& settings, const Vector* velocity_change_guess) {
  Impl& s = *impl_;
  const int nodes = model.node_count();
  const Index size = 3 * static_cast<Index>(nodes);
  const double dt = settings.dt, alpha = settings.rayleigh_mass, beta = settings.rayleigh_stiffness;
  // Topology (only the changed batches), then this step's state.
  s.sync_rows(model);
  s.bind_fixed();
  const bool gpu_rotations = rotations_on_gpu(model);
  if (!gpu_rotations) upload_cpu_rotations(model, state);
  const double parameters[8] = {lame_lambda(model.material()), lame_mu(model.material()), dt, alpha, beta,
                                1.0 + dt * alpha, dt * beta + dt * dt, 0};
  s.state_upload(s.parameters, parameters, 8);
  if (s.shadow_masses.size() != static_cast<size_t>(nodes) ||
      !std::equal(s.shadow_masses.begin(), s.shadow_masses.end(), model.lumped_masses().data())) {
    s.state_upload(s.masses, model.lumped_masses().data(), nodes);
    s.shadow_masses.assign(model.lumped_masses().data(), model.lumped_masses().data() + nodes);
  }
  if (fixed != s.shadow_fixed) {
    std::vector<double> free(static_cast<size_t>(nodes));
    for (int n = 0; n < nodes; ++n) free[n] = fixed[n] ? 0.0 : 1.0;
    s.state_upload(s.free, free.data(), nodes);
    s.shadow_fixed = fixed;
  }
  upload_springs(springs);
  Vector displacement = state.positions - model.rest_positions();
  s.state_upload(s.u, displacement.data(), size);
  s.state_upload(s.v, state.velocities.data(), size);
  s.state_upload(s.external, external_forces.data(), size);
  Vector guess = Vector::Zero(size);
  if (velocity_change_guess && velocity_change_guess->size() == size && velocity_change_guess->allFinite())
    guess = *velocity_change_guess;
  for (int n = 0; n < nodes; ++n)
    if (fixed[n]) guess.segment<3>(3 * n).setZero();
  s.state_upload(s.dv, guess.data(), size);
  check_gl("uploading the state");
  if (gpu_rotations) upload_rotations(model, state);
}

bool EfgStep::solve_velocity_change(const ImplicitEulerSettings& settings, CgResult& cg) {
  Impl& s = *impl_;
  const int nodes = s.nodes;
  const Index size = 3 * static_cast<Index>(nodes);
  // Right-hand side dt [f(x) - (dt + beta) K v - alpha M v], free entries only.
  s.run(Kernel::element_stress, s.elements, {{a_binding, &s.u}}, 0);
  s.run(Kernel::node_gather, nodes, {{a_binding, &s.u}, {b_binding, &s.external}, {c_binding, &s.forces}}, 0);
  s.product_of(s.v, s.stiffness_velocity, 1);
  s.run(Kernel::right_hand_side, static_cast<int>(size),
        {{a_binding, &s.forces}, {b_binding, &s.stiffness_velocity}, {c_binding, &s.v}, {d_binding, &s.rhs}});
  s.run(Kernel::diagonal, nodes, {{c_binding, &s.inverse_diagonal}});

  // CG (cg.cpp's algorithm; the same stops).
  const int dofs = static_cast<int>(size);
  s.dot(dofs, s.rhs, s.rhs, rhs_slot);
  const double b_norm = std::sqrt(s.read_scalars(rhs_slot)[0]);
  bool solved = false;
  if (!std::isfinite(b_norm)) {
    return false;
  }
  if (b_norm == 0.0) {
    const std::vector<double> zeros(static_cast<size_t>(size), 0.0);
    s.state_upload(s.dv, zeros.data(), size);
    cg.converged = true;
    solved = true;
  }
  if (!solved) {
    s.product_of(s.dv, s.product, 2);
    s.dot(dofs, s.dv, s.rhs, guess_slot, &s.dv, &s.product, guess_slot + 1);
    s.run(Kernel::scale_guess, dofs, {{a_binding, &s.dv}, {b_binding, &s.product}}, 0, guess_slot, guess_slot + 1);
    s.run(Kernel::residual_init, dofs,
          {{a_binding, &s.product}, {b_binding, &s.rhs}, {c_binding, &s.r}, {d_binding, &s.z}, {e_binding, &s.p},
           {f_binding, &s.inverse_diagonal}});
    // CG's checks run on the GPU (kernel cg_check); the host reads the status back every
    // cg_iterations_per_check iterations, and sees the deadline there.
    const double threshold = settings.cg.tolerance * b_norm * settings.cg.tolerance * b_norm;
    s.upload_reals(s.scalars, threshold_slot, &threshold, 1);
    const int cleared[2] = {0, 0};
    s.upload_ints(s.flags, 1, cleared, 2);
    const CgBudget& budget = settings.cg.budget;
    s.cg_limit = budget.stop_at > 0 ? std::min(budget.stop_at, settings.cg.max_iterations) : settings.cg.max_iterations;
    int rz_current = rz_slot, rz_next = rz_slot + 1;
    s.dot(dofs, s.r, s.r, residual_slot, &s.r, &s.z, rz_current);
    s.run(Kernel::cg_check, 1, {}, 1, curvature_slot, residual_slot);
    s.cg_gate = 1;
    int status = 0;
    for (int queued = 0;;) {
      int flags[2] = {0, 0};
      glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
      glGetNamedBufferSubData(s.flags.id, 4, 8, flags);
      status = flags[0];
      cg.iterations = flags[1];
      if (status != 0 || queued >= s.cg_limit) break;
      if (budget.stop_at == 0 && budget_spent(budget, cg.iterations)) {
        cg.stopped_by_budget = true;
        break;
      }
      // Iterations queued past the stop cost a dispatch of kernels that return at once.
      const int batch = std::min(settings_.cg_iterations_per_check, s.cg_limit - queued);
      for (int k = 0; k < batch; ++k, ++queued) {
        s.product_of(s.p, s.product, 2);
        s.dot(dofs, s.p, s.product, curvature_slot);
        s.run(Kernel::cg_update, dofs,
              {{a_binding, &s.dv}, {b_binding, &s.p}, {c_binding, &s.r}, {d_binding, &s.product}, {e_binding, &s.z},
               {f_binding, &s.inverse_diagonal}},
              0, curvature_slot, rz_current);
        s.dot(dofs, s.r, s.r, residual_slot, &s.r, &s.z, rz_next);
        s.run(Kernel::cg_check, 1, {}, 0, curvature_slot, residual_slot);
        s.run(Kernel::cg_direction, dofs, {{a_binding, &s.z}, {b_binding, &s.p}}, 0, rz_current, rz_next);
        std::swap(rz_current, rz_next);
      }
    }
    s.cg_gate = 0;
    const double residual_norm = std::sqrt(s.read_scalars(curvature_slot)[1]);
    cg.relative_residual = residual_norm / b_norm;
    cg.converged = status == 1;
    cg.nonfinite = status == 2 || (status == 1 && !std::isfinite(residual_norm));
    cg.non_positive_curvature = status == 3;
    if (status == 4 && budget.stop_at > 0 && cg.iterations >= budget.stop_at) cg.stopped_by_budget = true;
    if (cg.nonfinite) return false;
  }

  return true;
}

// v += dv, x += dt v on the GPU, read back; the fixed nodes keep their positions.
bool EfgStep::integrate(const CorotationalEfg& model, State& state, const std::vector<uint8_t>& fixed,
                        Vector* velocity_change_guess) {
  Impl& s = *impl_;
  const int nodes = s.nodes;
  const Index size = 3 * static_cast<Index>(nodes);
  const int dofs = static_cast<int>(size);
  s.run(Kernel::integrate, dofs,
        {{a_binding, &s.u}, {b_binding, &s.v}, {c_binding, &s.v_next}, {d_binding, &s.dv}, {e_binding, &s.u_next}});
  Vector velocities(size), next_displacement(size), velocity_change(size);
  s.download_reals(s.v_next, size, velocities.data());
  s.download_reals(s.u_next, size, next_displacement.data());
  s.download_reals(s.dv, size, velocity_change.data());
  check_gl("the step's kernels");
  Vector positions = model.rest_positions() + next_displacement;
  for (int n = 0; n < nodes; ++n) {
    if (!fixed[n]) continue;
    velocities.segment<3>(3 * n).setZero();
    positions.segment<3>(3 * n) = state.positions.segment<3>(3 * n);
  }
  if (!velocities.allFinite() || !positions.allFinite() || !velocity_change.allFinite()) return false;
  std::swap(s.u, s.u_next);
  std::swap(s.v, s.v_next);
  if (velocity_change_guess) *velocity_change_guess = velocity_change;
  state.positions.swap(positions);
  state.velocities.swap(velocities);
  return true;
}

void EfgStep::upload_surface(const SurfaceEmbedding& embedding) {
  CurrentScope current(*context_);
  impl_->sync_surface(embedding);
  check_gl("uploading the surface mapping");
}

void EfgStep::surface_positions(const SurfaceEmbedding& embedding, Vector& out) {
  Impl& s = *impl_;
  CurrentScope current(*context_);
  s.sync_surface(embedding);
  const int vertices = embedding.vertex_count();
  for (int v = 0; v < vertices; ++v)
    for (int k = 0; k < embedding.row_lengths[v]; ++k)
      if (embedding.particles[static_cast<size_t>(v) * embedding.stride + k] >= s.nodes)
        throw std::invalid_argument("EfgStep::surface_positions: vertex " + std::to_string(v) + " names particle " +
                                    std::to_string(embedding.particles[static_cast<size_t>(v) * embedding.stride + k]) +
                                    " of " + std::to_string(s.nodes));
  s.bind_fixed();
  s.bind(neighbours_binding, s.surface_particles);
  s.bind(values_binding, s.surface_weights);
  s.bind(lengths_binding, s.surface_lengths);
  s.run(Kernel::surface, vertices, {{a_binding, &s.u}, {c_binding, &s.surface_out}}, 0, 0, 0, s.surface_stride_capacity);
  out.resize(3 * static_cast<Index>(vertices));
  s.download_reals(s.surface_out, 3LL * vertices, out.data());
  s.bind_fixed();
  check_gl("surface positions");
}

void EfgStep::integration_points(const CorotationalEfg& model, Vector& out) {
  Impl& s = *impl_;
  CurrentScope current(*context_);
  s.sync_rows(model);
  s.bind_fixed();
  s.run(Kernel::integration_points, s.elements, {{a_binding, &s.u}, {c_binding, &s.points_out}});
  out.resize(3 * static_cast<Index>(s.elements));
  s.download_reals(s.points_out, 3LL * s.elements, out.data());
  check_gl("integration points");
}

}  // namespace incise::physics::gpu
