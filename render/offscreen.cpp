#include "render/offscreen.hpp"

#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "render/error.hpp"
#include "render/framebuffer.hpp"
#include "render/gl.hpp"
#include "render/gl_renderer.hpp"

namespace render {
namespace {

std::string hex(unsigned value) {
    char text[16];
    std::snprintf(text, sizeof text, "0x%04X", value);
    return text;
}

std::string egl_error() {
    EGLint code = eglGetError();
    static const char* const names[] = {"EGL_NOT_INITIALIZED", "EGL_BAD_ACCESS",        "EGL_BAD_ALLOC",
                                        "EGL_BAD_ATTRIBUTE",   "EGL_BAD_CONFIG",        "EGL_BAD_CONTEXT",
                                        "EGL_BAD_CURRENT_SURFACE", "EGL_BAD_DISPLAY",  "EGL_BAD_MATCH",
                                        "EGL_BAD_NATIVE_PIXMAP", "EGL_BAD_NATIVE_WINDOW", "EGL_BAD_PARAMETER",
                                        "EGL_BAD_SURFACE",     "EGL_CONTEXT_LOST"};
    if (code >= EGL_NOT_INITIALIZED && code <= EGL_CONTEXT_LOST) return names[code - EGL_NOT_INITIALIZED];
    return "EGL error " + hex(unsigned(code));
}

bool has_extension(const char* list, const char* name) {
    if (!list) return false;
    size_t length = std::strlen(name);
    for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += length) {
        bool starts = p == list || p[-1] == ' ';
        bool ends = p[length] == ' ' || p[length] == '\0';
        if (starts && ends) return true;
    }
    return false;
}

// EGL displays are process-wide singletons (the same handle for the same platform
// and device), so one is initialised on first use and deliberately never terminated:
// eglTerminate would pull the display from under every other context on it, and Mesa
// then unloads its driver, whose static allocations become unreachable (reported as
// leaks by LeakSanitizer) and whose LLVM start-up is paid again by the next target.
// Everything a target creates itself is released when it is destroyed.
struct Context {
    EGLDisplay display = EGL_NO_DISPLAY;
    EGLContext context = EGL_NO_CONTEXT;
    EGLSurface surface = EGL_NO_SURFACE;
    std::string description;
};

void destroy(Context& c) {
    if (c.display == EGL_NO_DISPLAY) return;
    eglMakeCurrent(c.display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (c.surface != EGL_NO_SURFACE) eglDestroySurface(c.display, c.surface);
    if (c.context != EGL_NO_CONTEXT) eglDestroyContext(c.display, c.context);
    c = {};
}

std::optional<EGLConfig> choose_config(EGLDisplay display) {
    const EGLint attributes[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, EGL_PBUFFER_BIT,
                                 EGL_RED_SIZE,        8,              EGL_GREEN_SIZE,   8,
                                 EGL_BLUE_SIZE,       8,              EGL_NONE};
    EGLConfig config = nullptr;
    EGLint count = 0;
    if (!eglChooseConfig(display, attributes, &config, 1, &count) || count < 1) return std::nullopt;
    return config;
}

// Asks for a 4.5 core context on one display. On failure appends to `notes` why, and
// what the display did offer, so the final error tells the user what to fix.
std::optional<Context> try_display(EGLDisplay display, const std::string& label, std::string& notes) {
    notes += "\n  " + label + ": ";
    if (display == EGL_NO_DISPLAY) {
        notes += "no display (" + egl_error() + ")";
        return std::nullopt;
    }
    EGLint major = 0, minor = 0;
    if (!eglInitialize(display, &major, &minor)) {
        notes += "eglInitialize failed (" + egl_error() + ")";
        return std::nullopt;
    }
    Context c;
    c.display = display;
    const char* vendor = eglQueryString(display, EGL_VENDOR);
    const char* extensions = eglQueryString(display, EGL_EXTENSIONS);
    notes += "EGL " + std::to_string(major) + "." + std::to_string(minor) + " (" + (vendor ? vendor : "?") + ")";
    auto fail = [&](const std::string& why) {
        notes += ", " + why;
        destroy(c);
        return std::nullopt;
    };

    if (!eglBindAPI(EGL_OPENGL_API)) return fail("desktop OpenGL API not offered (" + egl_error() + ")");

    bool configless =
        has_extension(extensions, "EGL_KHR_no_config_context") || has_extension(extensions, "EGL_MESA_configless_context");
    bool surfaceless = has_extension(extensions, "EGL_KHR_surfaceless_context");
    std::optional<EGLConfig> config;
    if (!configless || !surfaceless) {
        config = choose_config(display);
        if (!config) return fail("no EGL_OPENGL_BIT pbuffer config and EGL_KHR_no_config_context missing");
    }

    const EGLint core_45[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                              EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    EGLConfig chosen = config ? *config : EGL_NO_CONFIG_KHR;
    c.context = eglCreateContext(display, chosen, EGL_NO_CONTEXT, core_45);
    if (c.context == EGL_NO_CONTEXT) {
        std::string why = "OpenGL 4.5 core context refused (" + egl_error() + ")";
        // Say which GL version the driver does give, so the message is actionable.
        EGLContext fallback = eglCreateContext(display, chosen, EGL_NO_CONTEXT, nullptr);
        if (fallback != EGL_NO_CONTEXT) {
            if (surfaceless && eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, fallback))
                why += "; default context is " + gl::version_string();
            eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
            eglDestroyContext(display, fallback);
        }
        return fail(why);
    }

    if (!surfaceless) {
        const EGLint size[] = {EGL_WIDTH, 1, EGL_HEIGHT, 1, EGL_NONE};
        c.surface = eglCreatePbufferSurface(display, *config, size);
        if (c.surface == EGL_NO_SURFACE)
            return fail("EGL_KHR_surfaceless_context missing and no pbuffer surface (" + egl_error() + ")");
    }
    if (!eglMakeCurrent(display, c.surface, c.surface, c.context))
        return fail("eglMakeCurrent failed (" + egl_error() + ")");
    if (!gl::has_core_45()) return fail("context is " + gl::version_string() + ", not 4.5 core");
    c.description = label;
    return c;
}

template <typename Function>
Function egl_function(const char* name) {
    return reinterpret_cast<Function>(eglGetProcAddress(name));
}

Context create_context() {
    // INCISE_EGL_PLATFORM=surfaceless|device restricts the search, to test one path or
    // to steer around a broken driver.
    const char* forced = std::getenv("INCISE_EGL_PLATFORM");
    std::string only = forced ? forced : "";
    const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    std::string notes = "no OpenGL 4.5 core context could be created with EGL.";
    notes += "\n  EGL client extensions: ";
    notes += client ? client : "(none: EGL_EXT_client_extensions missing)";

    auto get_platform_display = egl_function<PFNEGLGETPLATFORMDISPLAYEXTPROC>("eglGetPlatformDisplayEXT");
    bool have_platforms = has_extension(client, "EGL_EXT_platform_base") && get_platform_display;
    if (!have_platforms) notes += "\n  EGL_EXT_platform_base missing: cannot choose a headless platform";

    if (have_platforms && (only.empty() || only == "surfaceless")) {
        if (has_extension(client, "EGL_MESA_platform_surfaceless")) {
            EGLDisplay display = get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
            if (auto c = try_display(display, "surfaceless platform", notes)) return *c;
        } else {
            notes += "\n  surfaceless platform: EGL_MESA_platform_surfaceless missing";
        }
    }

    if (have_platforms && (only.empty() || only == "device")) {
        auto query_devices = egl_function<PFNEGLQUERYDEVICESEXTPROC>("eglQueryDevicesEXT");
        auto query_device_string = egl_function<PFNEGLQUERYDEVICESTRINGEXTPROC>("eglQueryDeviceStringEXT");
        if (has_extension(client, "EGL_EXT_platform_device") && query_devices) {
            EGLint count = 0;
            EGLDeviceEXT devices[16];
            if (!query_devices(16, devices, &count)) count = 0;
            if (count == 0) notes += "\n  device platform: no EGL devices";
            for (EGLint i = 0; i < count; ++i) {
                std::string label = "device " + std::to_string(i);
                const char* device_extensions =
                    query_device_string ? query_device_string(devices[i], EGL_EXTENSIONS) : nullptr;
                if (has_extension(device_extensions, "EGL_EXT_device_drm")) {
                    const char* file = query_device_string(devices[i], EGL_DRM_DEVICE_FILE_EXT);
                    if (file) label += std::string(" (") + file + ")";
                } else if (has_extension(device_extensions, "EGL_MESA_device_software")) {
                    label += " (software)";
                }
                EGLDisplay display = get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
                if (auto c = try_display(display, label, notes)) return *c;
            }
        } else {
            notes += "\n  device platform: EGL_EXT_platform_device or eglQueryDevicesEXT missing";
        }
    }
    if (!only.empty() && only != "surfaceless" && only != "device")
        notes += "\n  INCISE_EGL_PLATFORM='" + only + "' is neither 'surfaceless' nor 'device'";
    throw RenderError(notes);
}

}  // namespace

struct OffscreenTarget::State {
    Context context;
    std::thread::id owner = std::this_thread::get_id();
    std::unique_ptr<GlRenderer> renderer;
    Framebuffer framebuffer;
    std::string renderer_string;

    void make_current() {
        if (eglGetCurrentContext() != context.context &&
            !eglMakeCurrent(context.display, context.surface, context.surface, context.context))
            throw RenderError("OffscreenTarget: eglMakeCurrent failed (" + egl_error() + ")");
    }

    ~State() {
        if (context.display == EGL_NO_DISPLAY) return;
        // GL objects can only be deleted with their context current; after a failed
        // make-current they go with the context instead.
        if (eglMakeCurrent(context.display, context.surface, context.surface, context.context)) {
            renderer.reset();
            framebuffer.release();
        }
        destroy(context);
        eglReleaseThread();
    }
};

OffscreenTarget::OffscreenTarget(std::unique_ptr<State> state) : state_(std::move(state)) {}
OffscreenTarget::OffscreenTarget(OffscreenTarget&&) noexcept = default;
OffscreenTarget& OffscreenTarget::operator=(OffscreenTarget&&) noexcept = default;
OffscreenTarget::~OffscreenTarget() = default;

OffscreenTarget OffscreenTarget::create(int width, int height, int samples) {
    if (width <= 0 || height <= 0)
        throw RenderError("OffscreenTarget size must be positive, got " + std::to_string(width) + "x" +
                          std::to_string(height));
    auto state = std::make_unique<State>();
    state->context = create_context();
    // From here the State destructor cleans up if anything below throws.
    state->renderer_string = gl::version_string();
    state->framebuffer.resize(width, height, samples);
    state->renderer = std::make_unique<GlRenderer>();
    return OffscreenTarget(std::move(state));
}

std::string OffscreenTarget::renderer_string() const { return state_->renderer_string; }

Image OffscreenTarget::render(const Frame& frame) {
    State& s = *state_;
    if (std::this_thread::get_id() != s.owner)
        throw RenderError("OffscreenTarget::render called from a thread other than the one that created it");
    s.make_current();
    s.framebuffer.bind_for_drawing();
    s.renderer->draw(frame, s.framebuffer.width(), s.framebuffer.height());
    s.framebuffer.resolve();
    return s.framebuffer.read();
}

int OffscreenTarget::width() const { return state_->framebuffer.width(); }
int OffscreenTarget::height() const { return state_->framebuffer.height(); }
int OffscreenTarget::samples() const { return state_->framebuffer.samples(); }

}  // namespace render
