#include "physics/gpu/compute_context.hpp"

#include "physics/gpu/gl.hpp"

#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <vector>

namespace incise::physics::gpu {

namespace {

std::string egl_error() {
  char text[32];
  std::snprintf(text, sizeof text, "EGL error 0x%04X", static_cast<unsigned>(eglGetError()));
  return text;
}

bool has_extension(const char* list, const char* name) {
  if (!list) return false;
  const size_t length = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += length) {
    if ((p == list || p[-1] == ' ') && (p[length] == ' ' || p[length] == '\0')) return true;
  }
  return false;
}

std::string gl_string(GLenum name) {
  const GLubyte* value = glGetString(name);
  return value ? reinterpret_cast<const char*>(value) : "(unknown)";
}

bool gl_extension(const char* name) {
  GLint count = 0;
  glGetIntegerv(GL_NUM_EXTENSIONS, &count);
  for (GLint i = 0; i < count; ++i) {
    const GLubyte* extension = glGetStringi(GL_EXTENSIONS, static_cast<GLuint>(i));
    if (extension && std::strcmp(reinterpret_cast<const char*>(extension), name) == 0) return true;
  }
  return false;
}

// The override of the required version (see the header).
GlVersion required_version(GlVersion required, std::string& notes) {
  const char* text = std::getenv("INCISE_GPU_REQUIRE_GL");
  if (!text || !*text) return required;
  int major = 0, minor = 0;
  if (std::sscanf(text, "%d.%d", &major, &minor) != 2 || major < 1) {
    throw ComputeUnavailable("INCISE_GPU_REQUIRE_GL: '" + std::string(text) +
                             "' is not a version MAJOR.MINOR");
  }
  notes += " (INCISE_GPU_REQUIRE_GL=" + std::string(text) + ")";
  return {major, minor};
}


// A core context of the version required or, when the driver refuses it, of the newest
// version it gives, so that the message can say what was found. Asking for less and reading
// the version back is not enough: Mesa answers a 3.2 request with its newest version, but
// NVIDIA's driver gives exactly the version asked for (an H100 said "OpenGL 3.2.0").
EGLContext create_core_context(EGLDisplay display, GlVersion required) {
  std::vector<GlVersion> tries{required};
  for (const GlVersion known : {GlVersion{4, 6}, {4, 5}, {4, 3}, {4, 0}, {3, 3}, {3, 2}})
    if (known.major < required.major || (known.major == required.major && known.minor < required.minor))
      tries.push_back(known);
  for (const GlVersion version : tries) {
    const EGLint attributes[] = {EGL_CONTEXT_MAJOR_VERSION, version.major, EGL_CONTEXT_MINOR_VERSION, version.minor,
                                 EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    const EGLContext context = eglCreateContext(display, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attributes);
    if (context != EGL_NO_CONTEXT) return context;
  }
  return EGL_NO_CONTEXT;
}

}  // namespace

struct ComputeContext::Egl {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  ~Egl() {
    if (display == EGL_NO_DISPLAY || context == EGL_NO_CONTEXT) return;
    if (eglGetCurrentContext() == context) eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(display, context);
    // The display is process-wide and stays initialised (render/offscreen.cpp explains why).
    eglReleaseThread();
  }
};

std::unique_ptr<ComputeContext> ComputeContext::create(GlVersion required) {
  std::string override_note;
  required = required_version(required, override_note);
  const std::string wanted = "OpenGL " + std::to_string(required.major) + "." +
                             std::to_string(required.minor) + " core with compute shaders" + override_note;
  std::string notes;
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  auto get_platform_display =
      reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if (!has_extension(client, "EGL_EXT_platform_base") || !get_platform_display) {
    throw ComputeUnavailable("GPU backend: " + wanted +
                             " is unavailable: EGL_EXT_platform_base missing, no headless display can be chosen");
  }

  std::vector<EGLDisplay> displays;
  std::vector<std::string> labels;
  if (has_extension(client, "EGL_MESA_platform_surfaceless")) {
    displays.push_back(get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr));
    labels.push_back("surfaceless platform");
  }
  auto query_devices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
  if (has_extension(client, "EGL_EXT_platform_device") && query_devices) {
    EGLDeviceEXT devices[8];
    EGLint count = 0;
    if (!query_devices(8, devices, &count)) count = 0;
    for (EGLint i = 0; i < count; ++i) {
      displays.push_back(get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr));
      labels.push_back("device " + std::to_string(i));
    }
  }
  if (displays.empty()) notes += "\n  no surfaceless platform and no EGL device";

  for (size_t d = 0; d < displays.size(); ++d) {
    notes += "\n  " + labels[d] + ": ";
    EGLDisplay display = displays[d];
    EGLint egl_major = 0, egl_minor = 0;
    if (display == EGL_NO_DISPLAY || !eglInitialize(display, &egl_major, &egl_minor)) {
      notes += "cannot initialise (" + egl_error() + ")";
      continue;
    }
    const char* extensions = eglQueryString(display, EGL_EXTENSIONS);
    if (!eglBindAPI(EGL_OPENGL_API)) {
      notes += "desktop OpenGL not offered";
      continue;
    }
    if (!has_extension(extensions, "EGL_KHR_surfaceless_context") ||
        !(has_extension(extensions, "EGL_KHR_no_config_context") ||
          has_extension(extensions, "EGL_MESA_configless_context"))) {
      notes += "no surfaceless, configless contexts";
      continue;
    }
    auto egl = std::make_unique<Egl>();
    egl->display = display;
    egl->context = create_core_context(display, required);
    if (egl->context == EGL_NO_CONTEXT) {
      notes += "no core context (" + egl_error() + ")";
      continue;
    }
    if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, egl->context)) {
      notes += "eglMakeCurrent failed (" + egl_error() + ")";
      continue;
    }
    GLint major = 0, minor = 0, profile = 0;
    glGetIntegerv(GL_MAJOR_VERSION, &major);
    glGetIntegerv(GL_MINOR_VERSION, &minor);
    glGetIntegerv(GL_CONTEXT_PROFILE_MASK, &profile);
    std::unique_ptr<ComputeContext> context(new ComputeContext());
    context->version_ = gl_string(GL_VERSION);
    context->renderer_ = gl_string(GL_RENDERER);
    const bool new_enough = major > required.major || (major == required.major && minor >= required.minor);
    if (!new_enough || (profile & GL_CONTEXT_CORE_PROFILE_BIT) == 0 || major < 4 || (major == 4 && minor < 3)) {
      notes += "found OpenGL " + context->version_ + " on '" + context->renderer_ + "'";
      continue;  // egl's destructor releases the context
    }
    const char* hide = std::getenv("INCISE_GPU_DISABLE_FP64");
    context->double_precision_ = gl_extension("GL_ARB_gpu_shader_fp64") && !(hide && std::strcmp(hide, "1") == 0);
    context->float_atomics_ = gl_extension("GL_NV_shader_atomic_float");
    context->egl_ = std::move(egl);
    context->release();
    return context;
  }
  throw ComputeUnavailable("GPU backend: " + wanted + " is unavailable:" + notes);
}

ComputeContext::~ComputeContext() = default;

void ComputeContext::make_current() {
  if (eglGetCurrentContext() == egl_->context) return;
  if (!eglMakeCurrent(egl_->display, EGL_NO_SURFACE, EGL_NO_SURFACE, egl_->context))
    throw ComputeUnavailable("GPU backend: eglMakeCurrent failed (" + egl_error() + ")");
}

void ComputeContext::release() {
  if (eglGetCurrentContext() == egl_->context) eglMakeCurrent(egl_->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
}

CurrentScope::CurrentScope(ComputeContext& context) : context_(context) { context_.make_current(); }
CurrentScope::~CurrentScope() { context_.release(); }

}  // namespace incise::physics::gpu
