// GLSL sources of the OpenGL reconstructor. Each mirrors a piece of the CPU backend and names
// it; keep the two in step (the backend agreement tests check they are).
#pragma once

#include <string>

namespace afr::gl_shaders {

// pixel_box(): the pixels a splat's box reaches, as the prepare pass bins it to tiles and the
// gather culls it to cells (the two must agree).
extern const char* const kPixelBox;
// The shaders below without a #version line are completed by splat_program_source(): the
// version, kPixelBox, then kSplatCommon (the uniforms and prepare_splat(): reprojection, tile
// filter, coverage rule, Gaussian constants, cpu_reconstructor.cpp's phases 1 and 2), then the
// body.
extern const char* const kSplatCommon;
// Adaptive splats as points: the vertex shader prepares (with kSplatCommon), the fragment
// shader weights; accumulates (sum w c, sum w) and (count, radius sum). Both, and the gather,
// test AFR_PROBE (GlProbe's value; the fragment shader has no #version line, so that the
// program can define it first).
extern const char* const kSplatVertex;
extern const char* const kSplatFragment;
// Traditional frameless: one point per sample at its pixel, the newest wins the depth test.
extern const char* const kNewestVertex;
extern const char* const kNewestFragment;
// hole_fill.cpp: one pyramid level from the one below, and normalise-with-fill.
extern const char* const kPyramidCompute;
extern const char* const kNormaliseCompute;
// The tiled gather, the splat pass as compute: prepare each sample's splat (the vertex stage
// of kSplatVertex) and count the screen tiles it reaches; scan the counts into list starts;
// scatter splat indices into the tiles' lists; gather, one work group a tile and one
// invocation a pixel, each splat evaluated as kSplatFragment does.
extern const char* const kPrepareCompute;  // with kSplatCommon
extern const char* const kScanCompute;
extern const char* const kScatterCompute;
extern const char* const kGatherCompute;  // with kPixelBox
// The tile field's per-pixel tile index (TileField::index_map) from its tiles' pixel spans.
extern const char* const kIndexMapCompute;
// Read-back: the output image as RGB floats into a persistently mapped buffer.
extern const char* const kPackCompute;
// Shows the output texture in a window, image row 0 at the top.
extern const char* const kBlitVertex;
extern const char* const kBlitFragment;

// "#version 430 core", `defines`, kPixelBox, kSplatCommon, then `body`.
inline std::string splat_program_source(const char* body, const std::string& defines = "") {
  return std::string("#version 430 core\n") + defines + kPixelBox + kSplatCommon + body;
}

}  // namespace afr::gl_shaders
