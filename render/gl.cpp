#include "render/gl.hpp"

#include <cstdio>

#include "render/error.hpp"

namespace render::gl {

void check_error(const char* where) {
    GLenum first = glGetError();
    if (first == GL_NO_ERROR) return;
    // Drain the flags so the next check reports only new errors.
    for (int i = 0; i < 16 && glGetError() != GL_NO_ERROR; ++i) {
    }
    char code[16];
    std::snprintf(code, sizeof code, "0x%04X", first);
    throw RenderError(std::string("OpenGL error ") + code + " in " + where);
}

std::string version_string() {
    auto text = [](GLenum name) {
        const GLubyte* value = glGetString(name);
        return value ? std::string(reinterpret_cast<const char*>(value)) : std::string("(unknown)");
    };
    return text(GL_VERSION) + " | " + text(GL_RENDERER);
}

bool has_core_45() {
    GLint major = 0, minor = 0, profile = 0;
    glGetIntegerv(GL_MAJOR_VERSION, &major);
    glGetIntegerv(GL_MINOR_VERSION, &minor);
    glGetIntegerv(GL_CONTEXT_PROFILE_MASK, &profile);
    bool version_ok = major > 4 || (major == 4 && minor >= 5);
    return version_ok && (profile & GL_CONTEXT_CORE_PROFILE_BIT) != 0;
}

}  // namespace render::gl
