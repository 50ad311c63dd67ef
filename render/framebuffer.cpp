#include "render/framebuffer.hpp"

#include <algorithm>
#include <cstring>
#include <string>

#include "render/error.hpp"
#include "render/gl.hpp"

namespace render {

namespace {

void require_complete(GLuint framebuffer, const char* which) {
    GLenum status = glCheckNamedFramebufferStatus(framebuffer, GL_DRAW_FRAMEBUFFER);
    if (status != GL_FRAMEBUFFER_COMPLETE)
        throw RenderError(std::string("the ") + which + " framebuffer is incomplete (status " +
                          std::to_string(status) + ")");
}

}  // namespace

Framebuffer::~Framebuffer() { release(); }

void Framebuffer::release() {
    GLuint framebuffers[2] = {multisampled_framebuffer_, resolved_framebuffer_};
    GLuint renderbuffers[4] = {multisampled_color_, multisampled_depth_, resolved_color_, resolved_depth_};
    if (framebuffers[0] || framebuffers[1]) glDeleteFramebuffers(2, framebuffers);
    if (renderbuffers[0] || renderbuffers[1] || renderbuffers[2] || renderbuffers[3])
        glDeleteRenderbuffers(4, renderbuffers);
    multisampled_framebuffer_ = multisampled_color_ = multisampled_depth_ = 0;
    resolved_framebuffer_ = resolved_color_ = resolved_depth_ = 0;
    width_ = height_ = samples_ = 0;
}

void Framebuffer::resize(int width, int height, int samples) {
    if (width <= 0 || height <= 0)
        throw RenderError("framebuffer size must be positive, got " + std::to_string(width) + "x" +
                          std::to_string(height));
    GLint max_samples = 1;
    glGetIntegerv(GL_MAX_SAMPLES, &max_samples);
    int effective = samples > 1 ? std::min(samples, int(max_samples)) : 0;
    if (effective <= 1) effective = 0;
    if (width == width_ && height == height_ && effective == samples_ && resolved_framebuffer_) return;
    release();

    glCreateFramebuffers(1, &resolved_framebuffer_);
    glCreateRenderbuffers(1, &resolved_color_);
    glNamedRenderbufferStorage(resolved_color_, GL_RGBA8, width, height);
    glNamedFramebufferRenderbuffer(resolved_framebuffer_, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, resolved_color_);
    // The resolved target gets depth only when it is drawn into directly.
    if (effective == 0) {
        glCreateRenderbuffers(1, &resolved_depth_);
        glNamedRenderbufferStorage(resolved_depth_, GL_DEPTH24_STENCIL8, width, height);
        glNamedFramebufferRenderbuffer(resolved_framebuffer_, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER,
                                       resolved_depth_);
    }
    require_complete(resolved_framebuffer_, "resolved");

    if (effective > 0) {
        glCreateFramebuffers(1, &multisampled_framebuffer_);
        glCreateRenderbuffers(1, &multisampled_color_);
        glNamedRenderbufferStorageMultisample(multisampled_color_, effective, GL_RGBA8, width, height);
        glCreateRenderbuffers(1, &multisampled_depth_);
        glNamedRenderbufferStorageMultisample(multisampled_depth_, effective, GL_DEPTH24_STENCIL8, width, height);
        glNamedFramebufferRenderbuffer(multisampled_framebuffer_, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER,
                                       multisampled_color_);
        glNamedFramebufferRenderbuffer(multisampled_framebuffer_, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER,
                                       multisampled_depth_);
        require_complete(multisampled_framebuffer_, "multisampled");
    }
    width_ = width;
    height_ = height;
    samples_ = effective;
    gl::check_error("Framebuffer::resize");
}

void Framebuffer::bind_for_drawing() const {
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, samples_ > 0 ? multisampled_framebuffer_ : resolved_framebuffer_);
    glViewport(0, 0, width_, height_);
}

void Framebuffer::bind_resolved_for_drawing() const {
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, resolved_framebuffer_);
    glViewport(0, 0, width_, height_);
}

void Framebuffer::resolve() const {
    if (samples_ == 0) return;
    glBlitNamedFramebuffer(multisampled_framebuffer_, resolved_framebuffer_, 0, 0, width_, height_, 0, 0, width_,
                           height_, GL_COLOR_BUFFER_BIT, GL_NEAREST);
}

void Framebuffer::blit_to(unsigned framebuffer, int width, int height) const {
    glBlitNamedFramebuffer(resolved_framebuffer_, framebuffer, 0, 0, width_, height_, 0, 0, width, height,
                           GL_COLOR_BUFFER_BIT, GL_NEAREST);
}

Image Framebuffer::read() const {
    Image image;
    image.width = width_;
    image.height = height_;
    image.rgba.resize(size_t(width_) * size_t(height_) * 4);
    std::vector<uint8_t> bottom_up(image.rgba.size());
    glBindFramebuffer(GL_READ_FRAMEBUFFER, resolved_framebuffer_);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, width_, height_, GL_RGBA, GL_UNSIGNED_BYTE, bottom_up.data());
    glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    gl::check_error("Framebuffer::read");
    // GL rows start at the bottom; images and PNGs start at the top.
    size_t row = size_t(width_) * 4;
    for (int y = 0; y < height_; ++y)
        std::memcpy(image.rgba.data() + size_t(y) * row, bottom_up.data() + size_t(height_ - 1 - y) * row, row);
    return image;
}

}  // namespace render
