#include <afr/display/gl_reconstructor.h>

#include <afr/common/error.h>
#include <afr/common/random.h>
#include <afr/display/cpu_reconstructor.h>

#include "test_support.h"

#include <gtest/gtest.h>

#include <limits>
#include <thread>

namespace afr {
namespace {

using test::diff8;

// Skips the test (with the reason) where no headless OpenGL 4.3 context can be made.
#define AFR_REQUIRE_GL(context)                                             \
  std::string why_no_gl;                                                    \
  std::shared_ptr<GlContext> context = test::shared_gl_context(&why_no_gl); \
  if (context == nullptr) GTEST_SKIP() << "no EGL/OpenGL context: " << why_no_gl

ReconstructorConfig config(int w, int h, ReconstructionMode mode) {
  ReconstructorConfig c;
  c.image.width = w;
  c.image.height = h;
  c.mode = mode;
  c.threads = 2;
  return c;
}

// Both splat passes: the compute gather (a GPU's default) and the points (llvmpipe's).
constexpr GlSplat kSplatPasses[] = {GlSplat::kGather, GlSplat::kRaster};
// The gather on each tile side it takes: 16 (8 cells of 8 x 4 pixels a tile), 8 (two cells)
// and 4 (the tile is its one cell), and with the ring cut into chunks of 1000 slots (a dozen
// dispatches adding up); the points.
constexpr GlReconstructorOptions kEveryPass[] = {{GlSplat::kGather, 16},
                                                 {GlSplat::kGather, 8},
                                                 {GlSplat::kGather, 4},
                                                 {GlSplat::kGather, 16, 48 * 1000},
                                                 {GlSplat::kRaster, 16}};

TEST(GlReconstructorTest, AgreesWithTheCpuBackendOnRandomSampleSets) {
  AFR_REQUIRE_GL(context);
  test::FloorScene scene;
  scene.velocity = glm::dvec3(0.7, 0.0, 0.2);
  for (const GlReconstructorOptions& pass : kEveryPass) {
    for (ReconstructionMode mode :
         {ReconstructionMode::kAdaptive, ReconstructionMode::kAdaptiveNoReprojection,
          ReconstructionMode::kTraditionalFrameless}) {
      for (const glm::ivec2 size : {glm::ivec2(96, 64), glm::ivec2(77, 53)}) {
        const int W = size.x, H = size.y;
        SCOPED_TRACE(std::string(gl_splat_name(pass.splat)) + " " + std::to_string(pass.tile) +
                     " chunk " + std::to_string(pass.chunk_bytes) + " " + mode_name(mode) + " " +
                     std::to_string(W) + "x" + std::to_string(H));
        const ReconstructorConfig cfg = config(W, H, mode);
        CpuReconstructor cpu(cfg);
        GlReconstructor gl(cfg, context, pass);
        ASSERT_EQ(gl.splat_method(), pass.splat);
        Pcg32 rng(uint64_t(W) * 7 + uint64_t(mode));
        double t = 0.0;
        // Frames with new samples and tilings in between; the ring wraps after a few.
        for (int frame = 0; frame < 6; ++frame) {
          const double t1 = t + 0.25;
          const Camera sampled =
              Camera::look_at({0.1 * frame, 0.5, 0.0}, {0.0, 0.1, -5.0}, {0, 1, 0}, 1.0, 0.01);
          const SampleBatch b = frame % 2 == 0
                                    ? test::scene_batch(scene, sampled, rng, size_t(W * H), W, H, t,
                                                        t1, frame % 4 == 0)
                                    : test::random_batch(rng, size_t(W * H), W, H, t, t1);
          const TilingSnapshot tiling = test::random_tiling(rng, W, H, 8 + 4 * frame, t1);
          // A second sampler's tiles over the lower right, older or newer than the first's:
          // where they overlap the newest wins (the GL backend builds that map itself).
          TilingSnapshot other =
              test::random_tiling(rng, W, H, 5 + frame, t1 + (frame % 2 ? 0.1 : -0.1));
          other.sampler_id = 2;
          other.region = PixelRect{W / 3, H / 4, W, H};
          for (Reconstructor* r :
               {static_cast<Reconstructor*>(&cpu), static_cast<Reconstructor*>(&gl)}) {
            r->add_batch(b);
            r->set_tiling(tiling);
            r->set_tiling(other);
          }
          t = t1;
          const Camera view = Camera::look_at({0.1 * frame + 0.2, 0.55, -0.1}, {0.0, 0.1, -5.0},
                                              {0, 1, 0}, 1.0, 0.01);
          const Image a = cpu.reconstruct(view, t, W, H);
          const Image g = gl.reconstruct(view, t, W, H);
          const test::Diff8 d = diff8(a, g);
          EXPECT_LE(d.rms, 1.0) << "frame " << frame;
          EXPECT_LE(d.max, 4) << "frame " << frame;
          // Whether a pixel is a hole turns on thresholds (a weight above kMinSplatWeight, a splat
          // radius rounded to 1/256 px) that the shader's exp and division and the CPU's fast_exp
          // can put on either side: a few pixels in a thousand may differ.
          EXPECT_NEAR(double(gl.frame_stats().hole_pixels), double(cpu.frame_stats().hole_pixels),
                      0.002 * W * H);
          EXPECT_TRUE(test::all_finite(g));
        }
      }
    }
  }
}

TEST(GlReconstructorTest, AgreesWithTheCpuBackendInAMovingOrthographicView) {
  AFR_REQUIRE_GL(context);
  test::FloorScene scene;
  scene.velocity = glm::dvec3(0.7, 0.0, 0.2);
  const int W = 96, H = 64;
  for (const GlReconstructorOptions& pass : kEveryPass) {
    SCOPED_TRACE(std::string(gl_splat_name(pass.splat)) + " " + std::to_string(pass.tile));
    const ReconstructorConfig cfg = config(W, H, ReconstructionMode::kAdaptive);
    CpuReconstructor cpu(cfg);
    GlReconstructor gl(cfg, context, pass);
    Pcg32 rng(21);
    double t = 0.0;
    for (int frame = 0; frame < 4; ++frame) {
      const double t1 = t + 0.25;
      Camera sampled =
          Camera::look_at({0.1 * frame, 2.0, 0.0}, {0.0, -1.0, -4.0}, {0, 1, 0}, 1.0, 0.01);
      sampled.ymag = 1.5;
      const SampleBatch b =
          test::scene_batch(scene, sampled, rng, size_t(W * H), W, H, t, t1, frame % 2 == 0);
      const TilingSnapshot tiling = test::random_tiling(rng, W, H, 8 + 4 * frame, t1);
      for (Reconstructor* r :
           {static_cast<Reconstructor*>(&cpu), static_cast<Reconstructor*>(&gl)}) {
        r->add_batch(b);
        r->set_tiling(tiling);
      }
      t = t1;
      Camera view = sampled;
      view.eye += glm::dvec3(0.2, 0.05, -0.1);
      view.ymag = 1.4;
      const Image a = cpu.reconstruct(view, t, W, H);
      const Image g = gl.reconstruct(view, t, W, H);
      const test::Diff8 d = diff8(a, g);
      EXPECT_LE(d.rms, 1.0) << "frame " << frame;
      EXPECT_LE(d.max, 4) << "frame " << frame;
      EXPECT_NEAR(double(gl.frame_stats().hole_pixels), double(cpu.frame_stats().hole_pixels),
                  0.002 * W * H);
      // The samples moved: most pixels see some (the view is not all holes).
      EXPECT_LT(cpu.frame_stats().hole_pixels, size_t(W * H / 4)) << "frame " << frame;
    }
  }
}

TEST(GlReconstructorTest, WeightsAndCoverageMatchTheCpuBackend) {
  AFR_REQUIRE_GL(context);
  for (const GlSplat splat : kSplatPasses) {
    SCOPED_TRACE(gl_splat_name(splat));
    const int W = 64, H = 48;
    const ReconstructorConfig cfg = config(W, H, ReconstructionMode::kAdaptive);
    CpuReconstructor cpu(cfg);
    GlReconstructor gl(cfg, context, GlReconstructorOptions{splat});
    Pcg32 rng(21);
    const SampleBatch b = test::random_batch(rng, 2000, W, H, 0.0, 1.0);
    const TilingSnapshot tiling = test::random_tiling(rng, W, H, 16, 1.0);
    for (Reconstructor* r : {static_cast<Reconstructor*>(&cpu), static_cast<Reconstructor*>(&gl)}) {
      r->add_batch(b);
      r->set_tiling(tiling);
    }
    const Camera cam;
    for (int frame = 0; frame < 2; ++frame) {
      cpu.reconstruct(cam, 1.0, W, H);
      gl.reconstruct(cam, 1.0, W, H);
      std::vector<float> wc, wg;
      cpu.read_weights(&wc);
      gl.read_weights(&wg);
      ASSERT_EQ(wc.size(), wg.size());
      for (size_t p = 0; p < wc.size(); ++p) {
        ASSERT_NEAR(wg[p], wc[p], 1e-3 * wc[p] + 1e-12) << "frame " << frame << " pixel " << p;
      }
      std::vector<CoverageCell> cc, cg;
      cpu.read_coverage(&cc);
      gl.read_coverage(&cg);
      int same = 0;
      for (size_t p = 0; p < cc.size(); ++p) same += cc[p].count == cg[p].count;
      EXPECT_GE(same, int(cc.size()) * 99 / 100);
    }
  }
}

// The density cap (splat_density_cap) on the GPU: a sparse store's grown splats, then the store
// filled at once; the image that holds the new samples has the CPU backend's weights and
// coverage, splats the size of the new density rather than of the old map.
TEST(GlReconstructorTest, SplatsFitTheDensityOnceTheStoreFillsAsOnTheCpu) {
  AFR_REQUIRE_GL(context);
  for (const GlSplat splat : kSplatPasses) {
    SCOPED_TRACE(gl_splat_name(splat));
    const int W = 64, H = 48;
    ReconstructorConfig cfg = config(W, H, ReconstructionMode::kAdaptive);
    cfg.capacity = 4 * W * H + 200;
    cfg.filter.min_spatial_extent = cfg.filter.max_spatial_extent = 1.0f;
    CpuReconstructor cpu(cfg);
    GlReconstructor gl(cfg, context, GlReconstructorOptions{splat});
    Pcg32 rng(12);
    const SampleBatch sparse = test::random_batch(rng, 60, W, H, 0.0, 0.5);
    const SampleBatch dense = test::random_batch(rng, 4 * W * H, W, H, 0.5, 1.0);
    const TilingSnapshot tiling = test::uniform_tiling(W, H, 0.0f, 0.0f, 0.0f, 1.0f);
    for (Reconstructor* r : {static_cast<Reconstructor*>(&cpu), static_cast<Reconstructor*>(&gl)}) {
      r->set_tiling(tiling);
      r->add_batch(sparse);
      for (int i = 0; i < 5; ++i) r->reconstruct(Camera{}, 0.5, W, H);
      r->add_batch(dense);
    }
    const Image a = cpu.reconstruct(Camera{}, 1.0, W, H);
    const Image g = gl.reconstruct(Camera{}, 1.0, W, H);
    const test::Diff8 d = diff8(a, g);
    EXPECT_LE(d.rms, 1.0);
    EXPECT_LE(d.max, 4);
    std::vector<CoverageCell> cc, cg;
    cpu.read_coverage(&cc);
    gl.read_coverage(&cg);
    ASSERT_EQ(cc.size(), cg.size());
    double count = 0;
    int same = 0;
    for (size_t p = 0; p < cc.size(); ++p) {
      count += cg[p].count;
      same += cc[p].count == cg[p].count;
    }
    EXPECT_GE(same, int(cc.size()) * 99 / 100);
    EXPECT_LT(count / double(cg.size()), 200.0);  // ~144; the shrunk map alone: ~1000
  }
}

// Splats of at least 6 pixels on 4-pixel tiles reach about 18 tiles each, far beyond the
// lists' first room (4 entries a stored sample): the first image overflows them, is drawn
// again with room, and still agrees with the CPU backend.
// The former coverage rule is a CPU baseline for afr-eval; the GL backend names what it lacks
// rather than run another rule under its name.
TEST(GlReconstructorTest, RefusesTheThresholdsCoverageRule) {
  AFR_REQUIRE_GL(context);
  ReconstructorConfig cfg = config(32, 24, ReconstructionMode::kAdaptive);
  cfg.splat.thresholds = true;
  try {
    GlReconstructor gl(cfg, context);
    ADD_FAILURE() << "the thresholds rule was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("thresholds rule"), std::string::npos) << e.what();
  }
}

TEST(GlReconstructorTest, GatherListsTooShortGrowAndTheImageIsDrawnAgain) {
  AFR_REQUIRE_GL(context);
  const int W = 64, H = 48;
  ReconstructorConfig cfg = config(W, H, ReconstructionMode::kAdaptive);
  cfg.splat.min_radius = 6.0f;
  CpuReconstructor cpu(cfg);
  GlReconstructor gl(cfg, context, GlReconstructorOptions{GlSplat::kGather, 4});
  const size_t first_room = gl.gather_list_capacity();
  EXPECT_EQ(first_room, 4 * gl.capacity());
  Pcg32 rng(8);
  const SampleBatch b = test::random_batch(rng, gl.capacity(), W, H, 0.0, 1.0);
  const TilingSnapshot tiling = test::random_tiling(rng, W, H, 16, 1.0);
  for (Reconstructor* r : {static_cast<Reconstructor*>(&cpu), static_cast<Reconstructor*>(&gl)}) {
    r->add_batch(b);
    r->set_tiling(tiling);
  }
  const Camera cam;
  const Image a = cpu.reconstruct(cam, 1.0, W, H);
  const Image g = gl.reconstruct(cam, 1.0, W, H);
  EXPECT_GT(gl.gather_list_capacity(), 10 * gl.capacity());
  const test::Diff8 d = diff8(a, g);
  EXPECT_LE(d.rms, 1.0);
  EXPECT_LE(d.max, 4);
}

// Images not read back are drawn all the same: after finish() the GPU times and pixel counts
// are the last image's, and a read-back image agrees with the CPU backend's.
TEST(GlReconstructorTest, ImagesNotReadBackFinishAndReportTheirGpuTimes) {
  AFR_REQUIRE_GL(context);
  const int W = 48, H = 32;
  const ReconstructorConfig cfg = config(W, H, ReconstructionMode::kAdaptive);
  for (const GlSplat splat : kSplatPasses) {
    SCOPED_TRACE(gl_splat_name(splat));
    CpuReconstructor cpu(cfg);
    GlReconstructor gl(cfg, context, GlReconstructorOptions{splat});
    Pcg32 rng(5);
    Image a, g;
    for (int frame = 0; frame < 7; ++frame) {
      const double t = 0.1 * (frame + 1);
      const SampleBatch b = test::random_batch(rng, size_t(W * H / 2), W, H, t - 0.1, t);
      for (Reconstructor* r :
           {static_cast<Reconstructor*>(&cpu), static_cast<Reconstructor*>(&gl)}) {
        r->add_batch(b);
      }
      const bool last = frame == 6;
      cpu.reconstruct(Camera(), t, W, H, &a);
      gl.reconstruct(Camera(), t, W, H, last ? &g : nullptr);
      EXPECT_LE(gl.frame_stats().gpu.image, uint64_t(frame + 1));
    }
    // The read-back image waited for itself: its counts and times are its own.
    EXPECT_EQ(gl.frame_stats().gpu.image, 7u);
    EXPECT_NEAR(double(gl.frame_stats().hole_pixels), double(cpu.frame_stats().hole_pixels),
                0.002 * W * H + 1.0);
    // Timed where the driver's queries measure (a hardware GPU), never on a software one.
    EXPECT_EQ(gl.frame_stats().gpu.timed, !context->software());
    if (gl.frame_stats().gpu.timed) {
      EXPECT_GT(gl.frame_stats().gpu.total(), 0.0);
    }
    const test::Diff8 d = diff8(a, g);
    EXPECT_LE(d.rms, 1.0);
    EXPECT_LE(d.max, 4);
    gl.reconstruct(Camera(), 0.8, W, H, nullptr);
    gl.finish();
    EXPECT_EQ(gl.frame_stats().gpu.image, 8u);
  }
}

// sync_passes: where the timer queries measure nothing (a software rasteriser, as in CI),
// every image gets each pass's time waited for on the CPU, and the image's time is their sum;
// on a hardware GPU the queries time it as before. The image is the same either way, up to the
// order the gather's atomics list a tile's splats in (its sums' last bits).
TEST(GlReconstructorTest, PassesWaitedForAreTimedWhereTheDriverHasNoQueries) {
  AFR_REQUIRE_GL(context);
  const int W = 48, H = 32;
  const ReconstructorConfig cfg = config(W, H, ReconstructionMode::kAdaptive);
  for (const GlSplat splat : kSplatPasses) {
    SCOPED_TRACE(gl_splat_name(splat));
    GlReconstructorOptions waited_options{splat};
    waited_options.sync_passes = true;
    GlReconstructor plain(cfg, context, GlReconstructorOptions{splat});
    GlReconstructor waited(cfg, context, waited_options);
    Pcg32 rng(9);
    Image a, b;
    for (int frame = 0; frame < 3; ++frame) {
      const double t = 0.1 * (frame + 1);
      const SampleBatch batch = test::random_batch(rng, size_t(W * H), W, H, t - 0.1, t);
      plain.add_batch(batch);
      waited.add_batch(batch);
      plain.reconstruct(Camera(), t, W, H, &a);
      waited.reconstruct(Camera(), t, W, H, &b);
      const GpuTimes& g = waited.frame_stats().gpu;
      EXPECT_EQ(g.image, uint64_t(frame + 1));
      ASSERT_TRUE(g.timed);
      EXPECT_GT(g.splat, 0.0);
      EXPECT_GT(g.fill, 0.0);
      EXPECT_EQ(g.bin > 0.0, splat == GlSplat::kGather);
      if (context->software()) {
        EXPECT_NEAR(g.total(), g.upload + g.bin + g.splat + g.fill + g.readback, 1e-9);
      }
      const test::Diff8 d = diff8(a, b);
      EXPECT_LE(d.rms, 0.1);
      EXPECT_LE(d.max, 1);
    }
  }
}

TEST(GlReconstructorTest, SplatPassesParseAndAutoFollowsTheRenderer) {
  EXPECT_EQ(parse_gl_splat("gather"), GlSplat::kGather);
  EXPECT_EQ(parse_gl_splat("raster"), GlSplat::kRaster);
  EXPECT_EQ(parse_gl_splat("auto"), GlSplat::kAuto);
  EXPECT_THROW(parse_gl_splat("splat"), Error);
  AFR_REQUIRE_GL(context);
  GlReconstructor gl(config(16, 16, ReconstructionMode::kAdaptive), context);
  EXPECT_EQ(gl.splat_method(), context->software() ? GlSplat::kRaster : GlSplat::kGather);
  for (const int tile : {3, 12, 32}) {
    EXPECT_THROW(GlReconstructor(config(16, 16, ReconstructionMode::kAdaptive), context,
                                 GlReconstructorOptions{GlSplat::kGather, tile}),
                 Error);
  }
}

// The benchmarks' probes (GlProbe) leave out what they name and nothing else: a culled pass
// reaches no pixel, a flat one weights every fragment of its points at the full weight (never
// less than the kernel's), a visit counts every splat a cell tests (never fewer than reach
// the pixel); each runs only with its own splat pass.
TEST(GlReconstructorTest, ProbesLeaveOutTheirWorkAndFitOnlyTheirPass) {
  for (const GlProbe probe :
       {GlProbe::kNone, GlProbe::kCulled, GlProbe::kFlat, GlProbe::kVisit, GlProbe::kDots}) {
    EXPECT_EQ(parse_gl_probe(gl_probe_name(probe)), probe);
  }
  EXPECT_THROW(parse_gl_probe("kernel"), Error);
  EXPECT_TRUE(gl_probe_fits(GlProbe::kNone, GlSplat::kGather));
  EXPECT_TRUE(gl_probe_fits(GlProbe::kVisit, GlSplat::kGather));
  EXPECT_FALSE(gl_probe_fits(GlProbe::kVisit, GlSplat::kRaster));
  EXPECT_FALSE(gl_probe_fits(GlProbe::kFlat, GlSplat::kGather));
  AFR_REQUIRE_GL(context);
  const ReconstructorConfig cfg = config(48, 32, ReconstructionMode::kAdaptive);
  EXPECT_THROW(
      GlReconstructor(cfg, context,
                      GlReconstructorOptions{GlSplat::kRaster, 16, 0, false, GlProbe::kVisit}),
      Error);
  EXPECT_THROW(
      GlReconstructor(cfg, context,
                      GlReconstructorOptions{GlSplat::kGather, 16, 0, false, GlProbe::kCulled}),
      Error);
  struct Result {
    std::vector<float> weights;
    std::vector<CoverageCell> coverage;
    uint64_t holes = 0;
  };
  const auto reconstruct = [&](GlSplat splat, GlProbe probe) {
    GlReconstructor gl(cfg, context, GlReconstructorOptions{splat, 8, 0, false, probe});
    Pcg32 rng(31);
    gl.set_tiling(test::random_tiling(rng, 48, 32, 8, 1.0));
    gl.add_batch(test::random_batch(rng, 4 * 48 * 32, 48, 32, 0.0, 1.0));
    gl.reconstruct(Camera{}, 1.0, 48, 32);
    Result r;
    gl.read_weights(&r.weights);
    gl.read_coverage(&r.coverage);
    r.holes = gl.frame_stats().hole_pixels;
    return r;
  };
  const auto total = [](const std::vector<float>& v) {
    double sum = 0.0;
    for (const float w : v) sum += double(w);
    return sum;
  };
  const Result raster = reconstruct(GlSplat::kRaster, GlProbe::kNone);
  EXPECT_LT(raster.holes, 48u * 32u / 10u);
  EXPECT_EQ(reconstruct(GlSplat::kRaster, GlProbe::kCulled).holes, 48u * 32u);
  EXPECT_EQ(total(reconstruct(GlSplat::kRaster, GlProbe::kCulled).weights), 0.0);
  for (const GlProbe flat : {GlProbe::kFlat, GlProbe::kDots}) {
    SCOPED_TRACE(gl_probe_name(flat));
    EXPECT_GT(total(reconstruct(GlSplat::kRaster, flat).weights), 0.0);
  }
  const Result flat = reconstruct(GlSplat::kRaster, GlProbe::kFlat);
  ASSERT_EQ(flat.weights.size(), raster.weights.size());
  for (size_t p = 0; p < raster.weights.size(); ++p) {
    ASSERT_GE(flat.weights[p], raster.weights[p] * (1.0f - 1e-5f)) << "pixel " << p;
  }
  EXPECT_GT(total(flat.weights), 1.5 * total(raster.weights));
  const Result gather = reconstruct(GlSplat::kGather, GlProbe::kNone);
  const Result visit = reconstruct(GlSplat::kGather, GlProbe::kVisit);
  ASSERT_EQ(visit.coverage.size(), gather.coverage.size());
  double visited = 0.0, reached = 0.0;
  for (size_t p = 0; p < gather.coverage.size(); ++p) {
    ASSERT_GE(visit.coverage[p].count, gather.coverage[p].count) << "pixel " << p;
    visited += double(visit.coverage[p].count);
    reached += double(gather.coverage[p].count);
  }
  EXPECT_GT(visited, 2.0 * reached);
}

// Within 2 ulp of `want`, channel by channel: a GPU may divide through a reciprocal (GLSL
// allows 2.5 ulp), so sum(w c) / sum(w) can be off by one where the CPU's IEEE division is not.
void expect_within_2ulp(const Image& image, glm::vec3 want) {
  for (const glm::vec3& c : image.pixels) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_NEAR(c[k], want[k], 2.0f * std::numeric_limits<float>::epsilon() * want[k]);
    }
  }
}

TEST(GlReconstructorTest, UniformColorReconstructsToThatColor) {
  AFR_REQUIRE_GL(context);
  for (const GlSplat splat : kSplatPasses) {
    SCOPED_TRACE(gl_splat_name(splat));
    GlReconstructor gl(config(40, 30, ReconstructionMode::kAdaptive), context,
                       GlReconstructorOptions{splat});
    Pcg32 rng(22);
    gl.set_tiling(test::random_tiling(rng, 40, 30, 8, 1.0));
    SampleBatch b = test::random_batch(rng, 600, 40, 30, 0.0, 1.0);  // sparse: holes to fill
    for (Sample& s : b.samples) s.color = glm::vec3(0.25f, 0.5f, 1.0f);
    gl.add_batch(b);
    for (int frame = 0; frame < 2; ++frame) {
      const Image image = gl.reconstruct(Camera{}, 1.0, 40, 30);
      expect_within_2ulp(image, glm::vec3(0.25f, 0.5f, 1.0f));
    }
  }
}

TEST(GlReconstructorTest, BadInputsNeverReachTheImage) {
  AFR_REQUIRE_GL(context);
  const float inf = std::numeric_limits<float>::infinity();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (const GlSplat splat : kSplatPasses) {
    SCOPED_TRACE(gl_splat_name(splat));
    GlReconstructor gl(config(32, 32, ReconstructionMode::kAdaptive), context,
                       GlReconstructorOptions{splat});
    Pcg32 rng(23);
    gl.set_tiling(test::uniform_tiling(32, 32, nan, 0.0f, inf, 0.0f, 1e6));
    SampleBatch b = test::random_batch(rng, 4000, 32, 32, 1e6 - 1e4, 1e6 + 1e4);
    b.samples[0].color.r = nan;
    b.samples[1].color.g = inf;
    b.samples[2].time = nan;
    gl.add_batch(b);
    const Image image = gl.reconstruct(Camera{}, 1e6, 32, 32);
    EXPECT_TRUE(test::all_finite(image));
    EXPECT_EQ(gl.frame_stats().nonfinite_pixels, 0u);
    EXPECT_EQ(gl.ingest_stats().rejected(), 3u);
  }
}

TEST(GlReconstructorTest, AnEmptyStoreGivesBlackAndResizingWorks) {
  AFR_REQUIRE_GL(context);
  GlReconstructor gl(config(16, 16, ReconstructionMode::kAdaptive), context);
  Image image = gl.reconstruct(Camera{}, 0.0, 16, 16);
  for (const glm::vec3& c : image.pixels) ASSERT_EQ(c, glm::vec3(0.0f));
  EXPECT_EQ(gl.frame_stats().empty_pixels, 256u);
  Pcg32 rng(24);
  SampleBatch b = test::random_batch(rng, 2000, 16, 16, 0.0, 1.0);
  for (Sample& s : b.samples) s.color = glm::vec3(0.5f);
  gl.add_batch(b);
  image = gl.reconstruct(Camera{}, 1.0, 33, 20);
  ASSERT_EQ(image.width, 33);
  expect_within_2ulp(image, glm::vec3(0.5f));
}

TEST(GlReconstructorTest, IngestOnAnotherThreadWhileReconstructing) {
  AFR_REQUIRE_GL(context);
  const int W = 48, H = 32;
  ReconstructorConfig cfg = config(W, H, ReconstructionMode::kAdaptive);
  cfg.capacity = 6000;
  // One splat size whatever the coverage map says: the image depends on the store only.
  cfg.splat.min_radius = 3.0f;
  cfg.splat.max_radius = 3.0f;
  GlReconstructor gl(cfg, context);
  CpuReconstructor cpu(cfg);
  std::vector<SampleBatch> batches;
  Pcg32 rng(25);
  for (int i = 0; i < 40; ++i)
    batches.push_back(test::random_batch(rng, 400, W, H, 0.02 * i, 0.02 * (i + 1)));
  const TilingSnapshot tiling = test::uniform_tiling(W, H, 0.05f, 0.05f, 0.2f, 100.0f, 0.8);
  gl.set_tiling(tiling);
  cpu.set_tiling(tiling);
  std::thread ingest([&] {
    for (const SampleBatch& b : batches) {
      gl.add_batch(b);
      std::this_thread::yield();
    }
  });
  for (int i = 0; i < 5; ++i) EXPECT_TRUE(test::all_finite(gl.reconstruct(Camera{}, 0.8, W, H)));
  ingest.join();
  for (const SampleBatch& b : batches) cpu.add_batch(b);
  // Once everything is in, both hold the same ring.
  const Image g = gl.reconstruct(Camera{}, 0.8, W, H);
  const Image c = cpu.reconstruct(Camera{}, 0.8, W, H);
  EXPECT_EQ(gl.frame_stats().stored, 6000u);
  const test::Diff8 d = diff8(g, c);
  EXPECT_LE(d.rms, 1.0);
  EXPECT_LE(d.max, 4);
}

}  // namespace
}  // namespace afr
