#pragma once

// Internal to physics/gpu: GL prototypes. libglvnd's libOpenGL exports every core 4.5 entry
// point and dispatches to the context current on the calling thread, so no loader is needed
// (the same arrangement as render/gl.hpp, which physics may not include).
#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES 1
#endif
#include <GL/glcorearb.h>
