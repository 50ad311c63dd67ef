// EfgStep's device side: its buffers (allocation, conversion to the kernels' precision on the
// way up and down), its programs, and their dispatch (efg_step_impl.hpp).
#include "physics/gpu/efg_step_impl.hpp"

#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace incise::physics::gpu {

void check_gl(const char* where) {
  const GLenum error = glGetError();
  if (error == GL_NO_ERROR) return;
  while (glGetError() != GL_NO_ERROR) {
  }
  char code[16];
  std::snprintf(code, sizeof code, "0x%04X", error);
  throw std::runtime_error(std::string("GPU backend: OpenGL error ") + code + " in " + where);
}

GLuint compile(Kernel kernel, bool double_precision) {
  const std::string source = kernel_source(kernel, double_precision);
  const char* text = source.c_str();
  const GLuint shader = glCreateShader(GL_COMPUTE_SHADER);
  glShaderSource(shader, 1, &text, nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  std::string log(4096, '\0');
  if (!ok) {
    GLsizei length = 0;
    glGetShaderInfoLog(shader, static_cast<GLsizei>(log.size()), &length, log.data());
    glDeleteShader(shader);
    throw ComputeUnavailable(std::string("GPU backend: kernel ") + kernel_name(kernel) +
                             " does not compile: " + log.substr(0, static_cast<size_t>(length)));
  }
  const GLuint program = glCreateProgram();
  glAttachShader(program, shader);
  glLinkProgram(program);
  glDeleteShader(shader);
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    GLsizei length = 0;
    glGetProgramInfoLog(program, static_cast<GLsizei>(log.size()), &length, log.data());
    glDeleteProgram(program);
    throw ComputeUnavailable(std::string("GPU backend: kernel ") + kernel_name(kernel) +
                             " does not link: " + log.substr(0, static_cast<size_t>(length)));
  }
  return program;
}

EfgStep::Impl::~Impl() {
  print_profile();
  for (auto& program : programs)
    if (program.id) glDeleteProgram(program.id);
  for (Buffer* b : all_buffers())
    if (b->id) glDeleteBuffers(1, &b->id);
}

std::vector<Buffer*> EfgStep::Impl::all_buffers() {
  return {&neighbours, &gradients, &values, &lengths, &volumes, &rest_gradients, &incidence,
          &incidence_lengths, &surface_particles, &surface_weights, &surface_lengths,
          &surface_out, &points_out, &rotations, &stresses, &rest, &masses, &free,
          &spring_index, &spring_force, &spring_stiffness, &parameters, &scalars, &partials, &orientations, &flags,
          &u, &v, &u_next, &v_next, &external, &forces, &stiffness_velocity, &rhs, &dv, &r,
          &z, &p, &product, &inverse_diagonal};
}

void EfgStep::Impl::allocate(Buffer& buffer, long long bytes) {
  bytes = std::max<long long>(bytes, 16);
  if (!buffer.id) glCreateBuffers(1, &buffer.id);
  glNamedBufferData(buffer.id, bytes, nullptr, GL_DYNAMIC_DRAW);
  buffer.bytes = bytes;
  check_gl("allocating a buffer");
}

long long EfgStep::Impl::upload_reals(Buffer& buffer, long long first, const double* data, long long count) {
  if (count <= 0) return 0;
  const long long bytes = count * real_bytes;
  const auto start = Clock::now();
  if (double_precision) {
    glNamedBufferSubData(buffer.id, first * 8, bytes, data);
  } else {
    staging.resize(static_cast<size_t>(bytes));
    float* out = reinterpret_cast<float*>(staging.data());
    for (long long i = 0; i < count; ++i) out[i] = static_cast<float>(data[i]);
    glNamedBufferSubData(buffer.id, first * 4, bytes, staging.data());
  }
  counters->ms_upload += std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  return bytes;
}

long long EfgStep::Impl::upload_ints(Buffer& buffer, long long first, const int* data, long long count) {
  if (count <= 0) return 0;
  const auto start = Clock::now();
  glNamedBufferSubData(buffer.id, first * 4, count * 4, data);
  counters->ms_upload += std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  return count * 4;
}

void EfgStep::Impl::download_reals(const Buffer& buffer, long long count, double* out) {
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  if (double_precision) {
    glGetNamedBufferSubData(buffer.id, 0, count * 8, out);
    return;
  }
  staging.resize(static_cast<size_t>(count * 4));
  glGetNamedBufferSubData(buffer.id, 0, count * 4, staging.data());
  const float* in = reinterpret_cast<const float*>(staging.data());
  for (long long i = 0; i < count; ++i) out[i] = in[i];
}

std::array<double, 2> EfgStep::Impl::read_scalars(int first) {
  std::array<double, 2> values{};
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  if (double_precision) {
    glGetNamedBufferSubData(scalars.id, first * 8, 16, values.data());
  } else {
    float v[2];
    glGetNamedBufferSubData(scalars.id, first * 4, 8, v);
    values = {v[0], v[1]};
  }
  return values;
}

void EfgStep::Impl::build_programs() {
  for (int k = 0; k < static_cast<int>(Kernel::count); ++k) {
    Program& program = programs[static_cast<size_t>(k)];
    program.id = compile(static_cast<Kernel>(k), double_precision);
    program.count = glGetUniformLocation(program.id, "count");
    program.stride = glGetUniformLocation(program.id, "stride");
    program.incidence_stride = glGetUniformLocation(program.id, "incidence_stride");
    program.mode = glGetUniformLocation(program.id, "mode");
    program.slot0 = glGetUniformLocation(program.id, "slot0");
    program.slot1 = glGetUniformLocation(program.id, "slot1");
    program.cg_gate = glGetUniformLocation(program.id, "cg_gate");
    program.limit = glGetUniformLocation(program.id, "limit");
  }
}

void EfgStep::Impl::bind_fixed() {
  bind(neighbours_binding, neighbours);
  bind(gradients_binding, gradients);
  bind(values_binding, values);
  bind(lengths_binding, lengths);
  bind(volumes_binding, volumes);
  bind(rest_gradients_binding, rest_gradients);
  bind(rotations_binding, rotations);
  bind(stresses_binding, stresses);
  bind(incidence_binding, incidence);
  bind(incidence_lengths_binding, incidence_lengths);
  bind(rest_binding, rest);
  bind(masses_binding, masses);
  bind(free_binding, free);
  bind(spring_index_binding, spring_index);
  bind(spring_force_binding, spring_force);
  bind(spring_stiffness_binding, spring_stiffness);
  bind(parameters_binding, parameters);
  bind(scalars_binding, scalars);
  bind(partials_binding, partials);
  bind(orientations_binding, orientations);
  bind(flags_binding, flags);
}

void EfgStep::Impl::run(Kernel kernel, int count, std::initializer_list<std::pair<GLuint, const Buffer*>> vectors,
                         int mode, int slot0, int slot1, int stride) {
  const Program& program = programs[static_cast<size_t>(kernel)];
  glUseProgram(program.id);
  if (program.count >= 0) glUniform1i(program.count, count);
  if (program.stride >= 0) glUniform1i(program.stride, stride >= 0 ? stride : stride_capacity);
  if (program.incidence_stride >= 0) glUniform1i(program.incidence_stride, incidence_capacity);
  if (program.mode >= 0) glUniform1i(program.mode, mode);
  if (program.slot0 >= 0) glUniform1i(program.slot0, slot0);
  if (program.slot1 >= 0) glUniform1i(program.slot1, slot1);
  if (program.cg_gate >= 0) glUniform1i(program.cg_gate, cg_gate);
  if (program.limit >= 0) glUniform1i(program.limit, cg_limit);
  for (const auto& [binding, buffer] : vectors) bind(binding, *buffer);
  GLuint groups = 0;
  if (kernel == Kernel::dot_partial) groups = kReduceGroups;
  else if (kernel == Kernel::dot_final) groups = 1;
  else groups = static_cast<GLuint>((count + kGroupSize - 1) / kGroupSize);
  const auto start = profile ? Clock::now() : Clock::time_point{};
  if (groups > 0) glDispatchCompute(groups, 1, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  if (profile) {
    glFinish();
    kernel_ms[static_cast<size_t>(kernel)] += std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    kernel_runs[static_cast<size_t>(kernel)]++;
  }
}

void EfgStep::Impl::print_profile() const {
  if (!profile) return;
  for (int k = 0; k < static_cast<int>(Kernel::count); ++k)
    if (kernel_runs[static_cast<size_t>(k)] > 0)
      std::fprintf(stderr, "gpu kernel %-20s %8ld runs %10.2f ms %8.4f ms/run\n", kernel_name(static_cast<Kernel>(k)),
                   kernel_runs[static_cast<size_t>(k)], kernel_ms[static_cast<size_t>(k)],
                   kernel_ms[static_cast<size_t>(k)] / kernel_runs[static_cast<size_t>(k)]);
}

void EfgStep::Impl::dot(int count, const Buffer& a, const Buffer& b, int slot0, const Buffer* c,
                         const Buffer* d, int slot1) {
  const int mode = c ? 2 : 1;
  if (c) {
    run(Kernel::dot_partial, count, {{a_binding, &a}, {b_binding, &b}, {c_binding, c}, {d_binding, d}}, mode);
  } else {
    run(Kernel::dot_partial, count, {{a_binding, &a}, {b_binding, &b}}, mode);
  }
  run(Kernel::dot_final, count, {}, mode, slot0, slot1);
}

}  // namespace incise::physics::gpu
