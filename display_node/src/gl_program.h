// Building GL programs from GLSL sources, for the reconstructor and the window: each throws
// afr::Error with the driver's log, naming the program, when a shader does not compile or the
// program does not link. The context must be current.
#pragma once

#include <epoxy/gl.h>

namespace afr {

GLuint graphics_program(const char* vertex, const char* fragment, const char* name);
GLuint compute_program(const char* compute, const char* name);

}  // namespace afr
