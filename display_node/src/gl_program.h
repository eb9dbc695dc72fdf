// Building GL programs from GLSL sources, for the reconstructor and the window: each throws
// afr::Error with the driver's log, naming the program, when a shader does not compile or the
// program does not link; and the textures they read. The context must be current.
#pragma once

#include <epoxy/gl.h>

namespace afr {

GLuint graphics_program(const char* vertex, const char* fragment, const char* name);
GLuint compute_program(const char* compute, const char* name);

// A 2D texture of one level, `format` (immutable storage), read texel by texel: nearest
// filtering (which integer formats need to be complete at all) and clamped to its edges.
GLuint make_texture(GLenum format, int width, int height);

}  // namespace afr
