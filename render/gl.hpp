#pragma once

// Internal to render/: the single place that pulls in GL prototypes. libglvnd's
// libOpenGL exports every core 4.5 entry point, so no loader is needed; the calls
// dispatch to whichever context (EGL or GLX) is current on the calling thread.

#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES 1
#endif
#include <GL/glcorearb.h>

#include <string>

namespace render::gl {

// Throws RenderError naming `where` if the GL error flag is set.
void check_error(const char* where);

// "4.5 (Core Profile) Mesa ... | llvmpipe (...)" for the current context.
std::string version_string();

// True if the current context is at least 4.5 with the core profile.
bool has_core_45();

}  // namespace render::gl
