// The OpenGL reconstructor (sections 5.2 and 6.2, the paper's GPU reconstructor), OpenGL 4.3
// core. Samples live in a vertex buffer laid out as the store's ring, updated each image with
// only the samples that arrived; the tile field is a texture of tile indices plus a buffer
// texture of per-tile filters; a vertex shader reprojects each sample and sizes its splat
// from the previous image's coverage texture, and points with a fragment shader accumulate
// (sum w c, sum w) and the new coverage by float blending into two render targets. Compute
// shaders then build the hole-filling pyramid and normalise. The arithmetic is the CPU
// backend's, so the two agree within the rasteriser's and exp's rounding.
#pragma once

#include <afr/display/gl_context.h>
#include <afr/display/reconstructor.h>

#include <memory>

namespace afr {

class GlReconstructor final : public Reconstructor {
 public:
  // `context` is made current here and in every call below; call them all (and destroy the
  // reconstructor) on one thread. Throws afr::Error when shaders or buffers cannot be made.
  GlReconstructor(const ReconstructorConfig& config, std::shared_ptr<GlContext> context);
  ~GlReconstructor() override;

  const char* backend_name() const override { return "gl"; }
  void read_weights(std::vector<float>* out) override;
  void read_coverage(std::vector<CoverageCell>* out) override;
  bool read_coverage(const PixelRect& rect, std::vector<CoverageCell>* out) override;
  size_t write_coverage(const PixelRect& rect, const std::vector<CoverageCell>& cells) override;
  StoredSlots stored_samples() override;
  const std::string& renderer() const { return context_->renderer(); }

  // The last image as an RGBA32F texture (linear RGB, row 0 = image top), for display.
  uint32_t output_texture() const;
  // Draws the last image over the currently bound framebuffer's viewport of fb_width x
  // fb_height (a window: row 0 of the image at the top), scaled to fit.
  void draw_output(int fb_width, int fb_height);

 protected:
  void do_reconstruct(const Camera& camera, double time, int width, int height,
                      Image* out) override;

 private:
  struct Impl;
  std::shared_ptr<GlContext> context_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace afr
