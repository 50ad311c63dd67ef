#pragma once

// Internal to render/: the colour/depth targets a frame is drawn into before it is
// read back (offscreen) or shown (window). Keeping the scene in our own framebuffer
// gives MSAA and screenshots that do not depend on what the window system offers.

#include "render/image.hpp"

namespace render {

class Framebuffer {
public:
    Framebuffer() = default;
    ~Framebuffer();  // needs the owning context current
    Framebuffer(const Framebuffer&) = delete;
    Framebuffer& operator=(const Framebuffer&) = delete;

    // (Re)creates the targets if the size or sample count changed. samples <= 1 means
    // no multisampling; larger values are clamped to what the driver supports.
    void resize(int width, int height, int samples);
    void bind_for_drawing() const;  // and sets the viewport
    void resolve() const;           // multisampled -> single-sampled; no-op without MSAA
    void bind_resolved_for_drawing() const;
    void blit_to(unsigned framebuffer, int width, int height) const;
    Image read() const;  // from the resolved target, top row first
    void release();

    int width() const { return width_; }
    int height() const { return height_; }
    int samples() const { return samples_; }

private:
    int width_ = 0;
    int height_ = 0;
    int samples_ = 0;
    unsigned multisampled_framebuffer_ = 0;
    unsigned multisampled_color_ = 0;
    unsigned multisampled_depth_ = 0;
    unsigned resolved_framebuffer_ = 0;
    unsigned resolved_color_ = 0;
    unsigned resolved_depth_ = 0;
};

}  // namespace render
