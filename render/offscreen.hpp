#pragma once

#include <memory>
#include <string>

#include "render/frame.hpp"
#include "render/image.hpp"

namespace render {

// Headless rendering: an EGL OpenGL 4.5 core context with no window (Mesa's
// surfaceless platform first, then EGL devices as on NVIDIA drivers) and a
// framebuffer of fixed size.
//
// Threading: an OpenGL context is current on one thread at a time. Create, use and
// destroy a target on ONE thread (the engine's render thread); render() throws
// RenderError when called from another. Several targets may live on the same thread.
//
// INCISE_EGL_PLATFORM=surfaceless or =device in the environment restricts the search
// to one platform, to test that path or to steer around a broken driver.
class OffscreenTarget {
public:
    // samples: MSAA sample count; 0 or 1 disables it, larger values are clamped to the
    // driver's maximum. Throws RenderError describing what EGL/GL offered (EGL
    // version, missing extensions, GL version) when no 4.5 core context can be made.
    static OffscreenTarget create(int width, int height, int samples = 4);

    OffscreenTarget(OffscreenTarget&&) noexcept;
    OffscreenTarget& operator=(OffscreenTarget&&) noexcept;
    // Releases the GL objects, surface and context. The EGL display itself stays
    // initialised for the process: it is shared by all targets (see offscreen.cpp).
    ~OffscreenTarget();

    std::string renderer_string() const;  // "GL_VERSION | GL_RENDERER"
    Image render(const Frame& frame);     // draws and reads back, top row first

    int width() const;
    int height() const;
    int samples() const;  // effective MSAA samples, 0 when off

private:
    struct State;
    explicit OffscreenTarget(std::unique_ptr<State> state);
    std::unique_ptr<State> state_;
};

}  // namespace render
