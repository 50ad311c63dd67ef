// An OpenGL 4.5 core context for compute, created through EGL without any display (Mesa's
// surfaceless platform, else the device platform for NVIDIA and other vendors), owned by the
// thread that steps the physics. It is separate from the render context: the two are made
// current in turn on their own thread, never shared.
//
// Unavailability is an error that says what was found: which EGL platforms were tried, and
// for a context that was made, its GL version and renderer and why it does not do.
// Simulating it (tests, docs/scenes.md): INCISE_GPU_REQUIRE_GL=MAJOR.MINOR raises the GL
// version the backend requires (e.g. 9.9: no driver has it), and INCISE_GPU_DISABLE_FP64=1
// hides double precision as if GL_ARB_gpu_shader_fp64 were missing.
#pragma once

#include <memory>
#include <stdexcept>
#include <string>

namespace incise::physics::gpu {

class ComputeUnavailable : public std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct GlVersion {
  int major = 4;
  int minor = 5;
};

// Makes the context current for a scope and releases it at the end: the backend's calls may
// come from whichever thread steps the physics, and a context current on a finished thread
// could not be made current anywhere else.
class ComputeContext;
class CurrentScope {
 public:
  explicit CurrentScope(ComputeContext& context);
  ~CurrentScope();
  CurrentScope(const CurrentScope&) = delete;
  CurrentScope& operator=(const CurrentScope&) = delete;

 private:
  ComputeContext& context_;
};

class ComputeContext {
 public:
  // Throws ComputeUnavailable when no context of at least `required` (core profile, with
  // compute shaders) can be made; the environment override above raises `required`.
  static std::unique_ptr<ComputeContext> create(GlVersion required = {});
  ~ComputeContext();
  ComputeContext(const ComputeContext&) = delete;
  ComputeContext& operator=(const ComputeContext&) = delete;

  // Makes the context current on the calling thread if it is not (a render context may have
  // been made current there in between).
  void make_current();
  // Leaves the calling thread with no current context, so that another thread (the physics
  // thread of a replay) may make it current next.
  void release();
  // GL_VERSION and GL_RENDERER, e.g. "4.5 (Core Profile) Mesa 22.3.6", "llvmpipe (LLVM 15.0.6, 256 bits)".
  const std::string& version() const { return version_; }
  const std::string& renderer() const { return renderer_; }
  // GL_ARB_gpu_shader_fp64 (core since 4.0) offered and not hidden by the override.
  bool double_precision() const { return double_precision_; }
  // Whether GL_NV_shader_atomic_float is offered (a scatter by float atomics would need it).
  bool float_atomics() const { return float_atomics_; }

 private:
  ComputeContext() = default;
  struct Egl;
  std::unique_ptr<Egl> egl_;
  std::string version_;
  std::string renderer_;
  bool double_precision_ = false;
  bool float_atomics_ = false;
};

}  // namespace incise::physics::gpu
