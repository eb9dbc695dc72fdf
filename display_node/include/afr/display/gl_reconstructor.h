// The OpenGL reconstructor (sections 5.2 and 6.2, the paper's GPU reconstructor), OpenGL 4.3
// core with persistent mappings (4.4 or ARB_buffer_storage). Asynchronous: new samples go
// through a persistently mapped staging ring, fenced, and are copied on the GPU into the
// sample ring (the store's ring, slot for slot), so the CPU fills image j+1's samples while
// the GPU draws image j; at most three images are in flight. Nothing is read back unless the
// caller asks for the image (then a compute pass packs it into a mapped buffer); pixel counts
// and GPU times (GL_TIME_ELAPSED per pass, GL_TIMESTAMP per image) come back a few images
// later without waiting.
//
// The splat pass, two ways (GlSplat):
//   gather  compute shaders: each sample's splat is prepared (reprojection, tile filter,
//           coverage rule) and binned to the screen tiles (4, 8 or 16 pixels) it reaches; one
//           work group a tile then evaluates its splats at each of its pixels (sum w c, sum w,
//           coverage), a batch at a time, each batch culled to the 8 x 4 pixel cells it
//           reaches. The ring is cut into chunks (GlReconstructorOptions::chunk_bytes), each
//           binned to lists of its own and gathered by a dispatch of its own: a tile's splats
//           lie anywhere in the ring, and random reads spread over more memory than the GPU's
//           address translation covers cost ~25x the reads (docs/benchmarks.md).
//   raster  a vertex shader prepares each splat and draws it as a point; a fragment shader
//           weights it and float blending accumulates.
// Both then build the hole-filling pyramid and normalise with compute shaders. The arithmetic
// is the CPU backend's, so the backends agree within rounding and summation order.
#pragma once

#include <afr/display/gl_context.h>
#include <afr/display/reconstructor.h>

#include <memory>

#include <string_view>

namespace afr {

// kAuto: the gather on a hardware GPU, the raster path on a software rasteriser (measured:
// docs/benchmarks.md, "GPU reconstructor").
enum class GlSplat { kAuto, kGather, kRaster };
// "auto", "gather", "raster"; throws afr::Error naming the text otherwise.
GlSplat parse_gl_splat(std::string_view text);
const char* gl_splat_name(GlSplat splat);

// For benchmarks only (afr-bench-reconstruct --gl-probes): the splat pass with part of its
// work left out, to measure on a driver what the rest of it costs. Its images are wrong.
//   kCulled  raster: the vertex stage in full (the sample's fetch and its splat's
//            preparation), then every point culled: the cost before any rasterising.
//   kFlat    raster: the same points drawn and blended, each fragment a constant (no kernel,
//            no discard): the cost of rasterising them.
//   kDots    raster: kFlat with every point one pixel: the cost of a point, whatever its size.
//   kVisit   gather: every pixel loads the splats its cell tests and adds them up (no kernel,
//            no box test): the cost of visiting them.
enum class GlProbe { kNone, kCulled, kFlat, kVisit, kDots };
// "none", "culled", "flat", "visit", "dots"; throws afr::Error naming the text otherwise.
GlProbe parse_gl_probe(std::string_view text);
const char* gl_probe_name(GlProbe probe);
// True for kNone and for a probe of that splat pass (kVisit: the gather; the others: raster).
bool gl_probe_fits(GlProbe probe, GlSplat splat);

struct GlReconstructorOptions {
  GlSplat splat = GlSplat::kAuto;
  // gather: the screen tile side in pixels, one work group a tile (4..16). Smaller tiles test
  // fewer splats at each pixel but bin each splat to more tiles.
  int tile = 16;
  // gather: the most bytes of splat records (48 bytes a sample) one pass reads; 0: the whole
  // store in one pass. The store's ring is cut into chunks of this size, each binned to its own
  // lists and gathered by its own dispatch: a tile's splats lie anywhere in the ring, and
  // random reads spread over more memory than the GPU's address translation covers at once
  // cost far more than the reads (measured: docs/benchmarks.md, "GPU reconstructor").
  size_t chunk_bytes = size_t(256) << 20;
  // Where the driver's timer queries measure nothing (a software rasteriser, which runs the
  // work when it is waited for): wait for the GPU (glFinish) before and after each pass and
  // time it on the CPU, so that FrameStats::gpu has per-pass times there too. It serialises
  // the passes with the calling thread: for benchmarks, not for a display.
  bool sync_passes = false;
  // Benchmarks only: a splat pass with part of its work left out (GlProbe). kCulled, kFlat and
  // kDots need the raster path, kVisit the gather (the constructor throws otherwise).
  GlProbe probe = GlProbe::kNone;
};

class GlReconstructor final : public Reconstructor {
 public:
  // `context` is made current here and in every call below; call them all (and destroy the
  // reconstructor) on one thread. Throws afr::Error when shaders or buffers cannot be made.
  GlReconstructor(const ReconstructorConfig& config, std::shared_ptr<GlContext> context,
                  GlReconstructorOptions options = {});
  ~GlReconstructor() override;

  const char* backend_name() const override { return "gl"; }
  void read_weights(std::vector<float>* out) override;
  void read_coverage(std::vector<CoverageCell>* out) override;
  bool read_coverage(const PixelRect& rect, std::vector<CoverageCell>* out) override;
  size_t write_coverage(const PixelRect& rect, const std::vector<CoverageCell>& cells) override;
  StoredSlots stored_samples() override;
  void finish() override;
  GlSplat splat_method() const { return options_.splat; }  // never kAuto
  // gather: list entries the tiles have room for (grows when an image needs more).
  size_t gather_list_capacity() const;
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
  GlReconstructorOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace afr
