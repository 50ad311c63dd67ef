#pragma once

#include <memory>

#include "render/frame.hpp"

namespace render {

// Draws a Frame with OpenGL 4.5 core into whatever framebuffer is bound for drawing.
// Construct, use and destroy it only while its context is current on the calling
// thread: it owns GL objects (programs, buffers) of that context.
class GlRenderer {
public:
    GlRenderer();  // compiles the shaders; throws RenderError with the compiler log on failure
    ~GlRenderer();
    GlRenderer(const GlRenderer&) = delete;
    GlRenderer& operator=(const GlRenderer&) = delete;

    // Sets the viewport to width x height, clears depth and draws background, meshes,
    // tools, floor and overlay text. Throws std::invalid_argument for a malformed mesh
    // and RenderError if GL reports an error.
    void draw(const Frame& frame, int width, int height);

private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace render
