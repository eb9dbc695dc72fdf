// Viewports (a display wall): reconstructors that each draw one rectangle of the sampling image,
// fed only the samples and tiles of their received region, stitch into the image a
// reconstruction of the whole image gives, seams included, on both backends; their memory is
// bounded by the viewport and its margin, not by the sampling image; and the stored-sample
// count per tile (R_l) is exact against a brute-force count, over the received region.
#include <afr/display/cpu_reconstructor.h>

#include <afr/common/error.h>
#include <afr/common/random.h>
#include <afr/display/gl_reconstructor.h>

#include "test_support.h"

#include <gtest/gtest.h>

#include <unistd.h>
#include <algorithm>
#include <cstdio>
#include <deque>
#include <functional>
#include <memory>

namespace afr {
namespace {

#define AFR_REQUIRE_GL(context)                                             \
  std::string why_no_gl;                                                    \
  std::shared_ptr<GlContext> context = test::shared_gl_context(&why_no_gl); \
  if (context == nullptr) GTEST_SKIP() << "no EGL/OpenGL context: " << why_no_gl

using MakeReconstructor = std::function<std::unique_ptr<Reconstructor>(const ReconstructorConfig&)>;

ReconstructorConfig viewport_config(int w, int h, PixelRect viewport = {}) {
  ReconstructorConfig c;
  c.image.width = w;
  c.image.height = h;
  c.viewport = viewport;
  c.threads = 2;
  return c;
}

// Tiles whose edges do not fall on the viewports' or margins' edges (so some are cut by the
// received regions), with different gradients: a still flat area, edges in x and in y,
// a moving area, and the sampler's rates.
TilingSnapshot irregular_tiling(int side, double time, Pcg32& rng) {
  const int xs[] = {0, 40 * side / 256, 100 * side / 256, 150 * side / 256, 240 * side / 256, side};
  const int ys[] = {0, 60 * side / 256, 120 * side / 256, 170 * side / 256, 240 * side / 256, side};
  TilingSnapshot s;
  s.time = time;
  s.region = PixelRect{0, 0, side, side};
  for (int j = 0; j < 5; ++j) {
    for (int i = 0; i < 5; ++i) {
      TileInfo t;
      t.rect = PixelRect{xs[i], ys[j], xs[i + 1], ys[j + 1]};
      switch ((i + 2 * j) % 4) {
        case 0:  // still and flat
          t.G_x = t.G_y = 0.002f * rng.next_float();
          t.G_t = 0.0f;
          break;
        case 1:  // an edge along y
          t.G_x = 0.2f + 0.1f * rng.next_float();
          t.G_y = 0.01f;
          t.G_t = 0.05f;
          break;
        case 2:  // an edge along x
          t.G_x = 0.02f;
          t.G_y = 0.15f;
          t.G_t = 0.2f * rng.next_float();
          break;
        default:  // moving
          t.G_x = t.G_y = 0.05f * rng.next_float();
          t.G_t = 2.0f + rng.next_float();
      }
      t.rate = 10.0f + 30.0f * rng.next_float();
      s.tiles.push_back(t);
    }
  }
  return s;
}

// What a wall node is sent: the samples inside `region`, the tiles overlapping it.
SampleBatch samples_inside(const SampleBatch& b, const PixelRect& region) {
  SampleBatch out;
  out.sampler_id = b.sampler_id;
  out.fields = b.fields;
  for (const Sample& s : b.samples) {
    if (s.x >= float(region.x0) && s.x < float(region.x1) && s.y >= float(region.y0) &&
        s.y < float(region.y1)) {
      out.samples.push_back(s);
    }
  }
  return out;
}
TilingSnapshot tiles_overlapping(const TilingSnapshot& t, const PixelRect& region) {
  TilingSnapshot out = t;
  out.tiles.clear();
  for (const TileInfo& info : t.tiles) {
    const PixelRect& r = info.rect;
    if (r.x0 < region.x1 && region.x0 < r.x1 && r.y0 < region.y1 && region.y0 < r.y1) {
      out.tiles.push_back(info);
    }
  }
  return out;
}

struct SeamCase {
  ReconstructionMode mode = ReconstructionMode::kAdaptive;
  int frames = 5;
  size_t first = 0;  // samples before the first image (over 1 s)
  size_t next = 0;   // new samples before each further one (1/30 s)
  int margin = -1;   // the viewports' margin (-1: the automatic one)
  int max_diff = 4;  // 8-bit steps allowed
  double max_rms = 1.0;
};

// The floor scene (moving) sampled from a moving camera: `first` samples, then `next` new
// samples and a new tiling per image, in time order as a sampler sends them; reconstructed as
// a whole 256 x 256 image and as 2 x 2 viewports of 128 x 128, each fed only the samples and
// tiles of its received region. Compares every image from the second on (the first has no
// coverage map yet), over all pixels and over the seams (9 pixels wide).
void expect_seamless(const MakeReconstructor& make, const SeamCase& c) {
  constexpr int kSide = 256, kHalf = kSide / 2;
  const ReconstructionMode mode = c.mode;
  const int margin = c.margin, frames = c.frames;
  const size_t first = c.first, next = c.next;
  test::FloorScene scene;
  scene.velocity = glm::dvec3(0.6, 0.0, 0.3);
  ReconstructorConfig whole_cfg = viewport_config(kSide, kSide);
  whole_cfg.mode = mode;
  std::unique_ptr<Reconstructor> whole = make(whole_cfg);
  std::vector<std::unique_ptr<Reconstructor>> parts;
  for (int k = 0; k < 4; ++k) {
    const int x0 = (k % 2) * kHalf, y0 = (k / 2) * kHalf;
    ReconstructorConfig cfg =
        viewport_config(kSide, kSide, PixelRect{x0, y0, x0 + kHalf, y0 + kHalf});
    cfg.mode = mode;
    if (margin >= 0) cfg.viewport_margin = margin;
    parts.push_back(make(cfg));
    // The capacity follows the received region: 4 samples per pixel of it.
    EXPECT_EQ(parts.back()->capacity(), 4 * size_t(parts.back()->received_region().area()));
  }
  Pcg32 rng(77);
  double t = 0.0;
  for (int frame = 0; frame < frames; ++frame) {
    const double t1 = t + (frame == 0 ? 1.0 : 1.0 / 30.0);
    const Camera sampled =
        Camera::look_at({0.05 * frame, 0.6, -0.03 * frame}, {0.2, 0.0, -5.0}, {0, 1, 0}, 1.0, 0.01);
    const size_t n = frame == 0 ? first : next;
    SampleBatch batch =
        test::scene_batch(scene, sampled, rng, n, kSide, kSide, t, t1, /*with_velocity=*/true);
    // In time order, as a sampler sends them.
    std::sort(batch.samples.begin(), batch.samples.end(),
              [](const Sample& a, const Sample& b) { return a.time < b.time; });
    const TilingSnapshot tiling = irregular_tiling(kSide, t1, rng);
    t = t1;
    whole->add_batch(batch);
    whole->set_tiling(tiling);
    for (auto& p : parts) {
      p->add_batch(samples_inside(batch, p->received_region()));
      p->set_tiling(tiles_overlapping(tiling, p->received_region()));
    }
    const Camera view = Camera::look_at({0.05 * frame + 0.03, 0.62, -0.03 * frame - 0.02},
                                        {0.2, 0.0, -5.0}, {0, 1, 0}, 1.0, 0.01);
    const Image expected = whole->reconstruct(view, t, kSide, kSide);
    Image stitched(kSide, kSide);
    uint64_t holes = 0;
    for (int k = 0; k < 4; ++k) {
      const Image part = parts[size_t(k)]->reconstruct(view, t, kHalf, kHalf);
      holes += parts[size_t(k)]->frame_stats().hole_pixels;
      const int x0 = (k % 2) * kHalf, y0 = (k / 2) * kHalf;
      for (int y = 0; y < kHalf; ++y) {
        for (int x = 0; x < kHalf; ++x) stitched.at(x0 + x, y0 + y) = part.at(x, y);
      }
    }
    if (frame == 0) continue;  // no coverage map yet: nothing to carry across the seam
    std::vector<bool> seam(size_t(kSide) * size_t(kSide), false);
    for (int y = 0; y < kSide; ++y) {
      for (int x = 0; x < kSide; ++x) {
        seam[size_t(y) * kSide + x] = std::abs(x - kHalf) <= 4 || std::abs(y - kHalf) <= 4;
      }
    }
    const test::Diff8 all = test::diff8(stitched, expected);
    const test::Diff8 at_seams = test::diff8(stitched, expected, &seam);
    SCOPED_TRACE(std::string(mode_name(mode)) + ", " + std::to_string(first) + " + " +
                 std::to_string(next) + " samples, margin " + std::to_string(margin) + ", frame " +
                 std::to_string(frame));
    EXPECT_LE(all.rms, c.max_rms);
    EXPECT_LE(all.max, c.max_diff);
    EXPECT_LE(at_seams.rms, c.max_rms);
    EXPECT_LE(at_seams.max, c.max_diff);
    if (c.max_diff == 0) {
      EXPECT_EQ(holes, whole->frame_stats().hole_pixels);
    }
    EXPECT_TRUE(test::all_finite(stitched));
    std::printf(
        "  [%s, %zu + %zu samples, frame %d] stitched vs whole: rms %.4f max %d; seams "
        "rms %.4f max %d\n",
        mode_name(mode), first, next, frame, all.rms, all.max, at_seams.rms, at_seams.max);
  }
}

// A running display (3 samples per pixel stored, 8000 new per image) and a sparse start (5000
// samples, then 3000 per image: 0.1 per pixel, splats at their largest and the coverage map
// growing them), with the automatic margin.
constexpr size_t kDense = 3 * 256 * 256;

TEST(ViewportTest, CpuViewportsStitchIntoTheWholeImage) {
  const MakeReconstructor make = [](const ReconstructorConfig& c) {
    return std::unique_ptr<Reconstructor>(std::make_unique<CpuReconstructor>(c));
  };
  expect_seamless(make, SeamCase{ReconstructionMode::kAdaptive, 5, kDense, 8000});
  expect_seamless(make, SeamCase{ReconstructionMode::kAdaptive, 4, 5000, 3000});
  expect_seamless(make, SeamCase{ReconstructionMode::kAdaptiveNoReprojection, 3, kDense, 8000});
  expect_seamless(make, SeamCase{ReconstructionMode::kTraditionalFrameless, 2, kDense, 8000});
}

TEST(ViewportTest, CpuViewportsReceivingEverythingGiveTheWholeImageExactly) {
  // A margin reaching past the image's edges: every part gets all samples and tiles, counts
  // the same tiles and sees the same coverage; what differs is only where its grid starts
  // (the projection's offset, the pyramid's alignment), and that changes no 8-bit value.
  const MakeReconstructor make = [](const ReconstructorConfig& c) {
    return std::unique_ptr<Reconstructor>(std::make_unique<CpuReconstructor>(c));
  };
  SeamCase c{ReconstructionMode::kAdaptive, 5, 5000, 3000, /*margin=*/128, /*max_diff=*/0, 0.0};
  expect_seamless(make, c);
  c.first = kDense;
  c.next = 8000;
  expect_seamless(make, c);
}

TEST(ViewportTest, GlViewportsStitchIntoTheWholeImage) {
  AFR_REQUIRE_GL(context);
  const MakeReconstructor make = [context](const ReconstructorConfig& c) {
    return std::unique_ptr<Reconstructor>(std::make_unique<GlReconstructor>(c, context));
  };
  expect_seamless(make, SeamCase{ReconstructionMode::kAdaptive, 3, kDense, 8000});
  expect_seamless(make, SeamCase{ReconstructionMode::kAdaptive, 3, 5000, 3000});
}

TEST(ViewportTest, AViewportIsTheSameImageScaledAndItsTileRatesCountTheReceivedPart) {
  // A viewport shown at twice its size is the whole image's upscaled reconstruction cropped
  // (same grid, same pixels); tiles larger than kRateLattice enter the field as their pieces
  // in the lattice's cells, and a piece cut by the received region gets the rate of its part
  // inside: the samples there over that part's area and the store's depth.
  constexpr int kSide = 96;
  Pcg32 rng(5);
  SampleBatch batch = test::random_batch(rng, 4 * kSide * kSide, kSide, kSide, 0.0, 1.0);
  // A smooth image: the two rates differ by the noise of counting over different areas
  // (about 1 %), which random colors per sample would show as noise.
  for (Sample& s : batch.samples) {
    s.color =
        glm::vec3(0.5f + 0.4f * std::sin(s.x / 7.0f), 0.5f + 0.4f * std::cos(s.y / 9.0f), 0.5f);
  }
  TilingSnapshot tiling = test::uniform_tiling(kSide, kSide, 0.05f, 0.05f, 0.5f, 20.0f, 1.0);
  tiling.tiles[0].rect = PixelRect{0, 0, kSide, 50};
  TileInfo lower = tiling.tiles[0];
  lower.rect = PixelRect{0, 50, kSide, kSide};
  lower.G_x = 0.3f;
  tiling.tiles.push_back(lower);
  ReconstructorConfig cfg = viewport_config(kSide, kSide, PixelRect{48, 0, 96, 48});
  cfg.viewport_margin = 10;
  cfg.capacity = batch.samples.size();  // the ring does not wrap: both stores reach as far back
  CpuReconstructor part(cfg);
  ReconstructorConfig whole_cfg = viewport_config(kSide, kSide);
  whole_cfg.capacity = batch.samples.size();
  CpuReconstructor whole(whole_cfg);
  EXPECT_EQ(part.received_region(), (PixelRect{38, 0, 96, 58}));
  // The part is fed everything: samples outside its received region are stored but not
  // counted.
  for (Reconstructor* r :
       {static_cast<Reconstructor*>(&part), static_cast<Reconstructor*>(&whole)}) {
    r->add_batch(batch);
    r->set_tiling(tiling);
  }
  const Camera cam = Camera::look_at({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 1.0, 0.01);
  part.reconstruct(cam, 1.0, 96, 96);
  whole.reconstruct(cam, 1.0, 2 * kSide, 2 * kSide);
  // The tiles as the part measured them: the pieces of the lattice's cells x in [32, 64) and
  // [64, 96) (its grid starts at x = 32) of the upper tile (y [0, 32) and [32, 50)) and of the
  // lower one (y [50, 64): the grid ends at y = 58), those at x < 38 and y >= 58 cut off.
  const std::vector<TileState>& tiles = part.tile_states();
  const std::vector<PixelRect> pieces = {{32, 0, 64, 32},  {64, 0, 96, 32},  {32, 32, 64, 50},
                                         {64, 32, 96, 50}, {32, 50, 64, 64}, {64, 50, 96, 64}};
  ASSERT_EQ(tiles.size(), 1 + pieces.size());
  const double depth = part.frame_stats().depth;
  for (size_t i = 1; i < tiles.size(); ++i) {
    EXPECT_EQ(tiles[i].rect, pieces[i - 1]);
    const PixelRect& r = pieces[i - 1];
    const PixelRect want{std::max(38, r.x0), r.y0, r.x1, std::min(58, r.y1)};
    EXPECT_EQ(tiles[i].counted, want);
    uint64_t inside = 0;
    for (const Sample& s : batch.samples) inside += want.contains(int(s.x), int(s.y)) ? 1 : 0;
    EXPECT_EQ(tiles[i].stored, inside);
    EXPECT_NEAR(tiles[i].rate, double(inside) / (double(want.area()) * depth), 1e-4);
  }
  // The whole image counts every piece whole.
  for (size_t i = 1; i < whole.tile_states().size(); ++i) {
    EXPECT_EQ(whole.tile_states()[i].counted, whole.tile_states()[i].rect);
  }
  EXPECT_EQ(whole.tile_states().size(), 1u + 3u * 2u + 3u * 2u);
  // The second images (each sizing its splats from its first's coverage): the same splats over
  // the same pixels (the part's rates differ by the counting region only, a fraction of a
  // percent here).
  const Image p = part.reconstruct(cam, 1.0, 96, 96);
  Image whole_image = whole.reconstruct(cam, 1.0, 2 * kSide, 2 * kSide);
  Image cropped(96, 96);
  for (int y = 0; y < 96; ++y) {
    for (int x = 0; x < 96; ++x) cropped.at(x, y) = whole_image.at(96 + x, y);
  }
  const test::Diff8 d = test::diff8(p, cropped);
  EXPECT_LE(d.rms, 1.0);
  EXPECT_LE(d.max, 4);
}

TEST(ViewportTest, BadViewportsAndMarginsThrow) {
  for (const PixelRect& v : {PixelRect{-1, 0, 10, 10}, PixelRect{0, 0, 65, 10},
                             PixelRect{5, 5, 5, 9}, PixelRect{0, 60, 10, 70}}) {
    EXPECT_THROW(CpuReconstructor{viewport_config(64, 64, v)}, Error);
  }
  ReconstructorConfig c = viewport_config(64, 64, PixelRect{0, 0, 32, 32});
  c.viewport_margin = -2;
  EXPECT_THROW(CpuReconstructor{c}, Error);
  c.viewport_margin = 0;
  CpuReconstructor ok(c);
  EXPECT_EQ(ok.received_region(), (PixelRect{0, 0, 32, 32}));
  EXPECT_EQ(ok.capacity(), 4u * 32 * 32);
  // The default: the whole image, the margin resolved.
  CpuReconstructor whole(viewport_config(64, 48));
  EXPECT_EQ(whole.viewport(), (PixelRect{0, 0, 64, 48}));
  EXPECT_EQ(whole.received_region(), (PixelRect{0, 0, 64, 48}));
  EXPECT_EQ(whole.config().viewport_margin, auto_viewport_margin(whole.config().splat));
}

// ---- A wall's coverage exchange (write_coverage, docs/wall.md "Seams")

// write_coverage replaces the previous image's coverage where the rectangle meets the grid,
// which read_coverage then shows and the next image's splats are sized from.
void expect_coverage_written(const MakeReconstructor& make) {
  constexpr int kSide = 64;
  std::unique_ptr<Reconstructor> r = make(viewport_config(kSide, kSide));
  const std::vector<CoverageCell> cells(6 * 4, CoverageCell{7.0f, 3.5f});
  const PixelRect rect{10, 20, 16, 24};
  EXPECT_EQ(r->write_coverage(rect, cells), 0u);  // no image yet: nothing to replace
  EXPECT_THROW(r->write_coverage(rect, std::vector<CoverageCell>(5)), Error);
  test::FloorScene scene;
  Pcg32 rng(5);
  const Camera cam = Camera::look_at({0.0, 0.6, 0.0}, {0.2, 0.0, -5.0}, {0, 1, 0}, 1.0, 0.01);
  r->add_batch(
      test::scene_batch(scene, cam, rng, 3 * kSide * kSide, kSide, kSide, 0.0, 1.0, false));
  r->reconstruct(cam, 1.0, kSide, kSide);
  // The ring as stored (the GL backend reads it back from the GPU at the first call).
  const Reconstructor::StoredSlots ring = r->stored_samples();
  ASSERT_EQ(ring.stored, size_t(3 * kSide * kSide));
  ASSERT_EQ(ring.end, uint64_t(3 * kSide * kSide));
  ASSERT_GE(ring.size, ring.stored);
  for (uint64_t q = 0; q < ring.end; q += 997) {
    const StoredSample& st = ring.slots[q % ring.size];
    ASSERT_TRUE(st.x >= 0.0f && st.x < float(kSide) && (st.flags & kStoredHasPosition)) << q;
  }
  std::vector<CoverageCell> before, after;
  r->read_coverage(&before);
  EXPECT_EQ(r->write_coverage(rect, cells), 24u);
  // Partly outside the image: its part inside, x 60..63 and y 62..63.
  EXPECT_EQ(r->write_coverage(PixelRect{60, 62, 66, 66}, cells), 8u);
  r->read_coverage(&after);
  ASSERT_EQ(after.size(), before.size());
  // A rectangle of it reads the same cells; one reaching outside the grid reads nothing.
  std::vector<CoverageCell> part;
  ASSERT_TRUE(r->read_coverage(PixelRect{8, 18, 17, 25}, &part));
  ASSERT_EQ(part.size(), 9u * 7u);
  for (int y = 18; y < 25; ++y) {
    for (int x = 8; x < 17; ++x) {
      const CoverageCell& got = part[size_t(y - 18) * 9 + size_t(x - 8)];
      ASSERT_EQ(got.count, after[size_t(y) * kSide + size_t(x)].count) << x << "," << y;
      ASSERT_EQ(got.growth_sum, after[size_t(y) * kSide + size_t(x)].growth_sum) << x << "," << y;
    }
  }
  EXPECT_FALSE(r->read_coverage(PixelRect{60, 60, 66, 64}, &part));
  EXPECT_TRUE(part.empty());
  for (int y = 0; y < kSide; ++y) {
    for (int x = 0; x < kSide; ++x) {
      const size_t i = size_t(y) * kSide + size_t(x);
      const bool written = rect.contains(x, y) || (x >= 60 && y >= 62);
      const CoverageCell want = written ? CoverageCell{7.0f, 3.5f} : before[i];
      ASSERT_EQ(after[i].count, want.count) << x << "," << y;
      ASSERT_EQ(after[i].growth_sum, want.growth_sum) << x << "," << y;
    }
  }

  // A viewport: a rectangle in its margin changes what it shows next, one beyond its grid
  // replaces nothing.
  ReconstructorConfig vc = viewport_config(kSide, kSide, PixelRect{0, 0, 32, 32});
  vc.viewport_margin = 16;
  std::unique_ptr<Reconstructor> a = make(vc), b = make(vc);
  rng = Pcg32(9);
  const SampleBatch sparse =
      test::scene_batch(scene, cam, rng, kSide * kSide / 8, kSide, kSide, 0.0, 1.0, false);
  for (auto* v : {a.get(), b.get()}) {
    v->add_batch(sparse);
    v->reconstruct(cam, 1.0, 32, 32);
  }
  // The margin right of the viewport, x 32..47: every pixel a hole, so splats landing there
  // grow 4x.
  const std::vector<CoverageCell> holes(16 * 32, CoverageCell{});
  EXPECT_EQ(a->write_coverage(PixelRect{32, 0, 48, 32}, holes), 16u * 32u);
  EXPECT_EQ(a->write_coverage(PixelRect{48, 40, 64, 72}, std::vector<CoverageCell>(16 * 32)), 0u);
  const test::Diff8 d =
      test::diff8(a->reconstruct(cam, 1.0, 32, 32), b->reconstruct(cam, 1.0, 32, 32));
  EXPECT_GT(d.max, 0);
}

TEST(ViewportTest, CpuCoverageWrittenByAPeerIsWhatTheNextImageReads) {
  expect_coverage_written([](const ReconstructorConfig& c) {
    return std::unique_ptr<Reconstructor>(std::make_unique<CpuReconstructor>(c));
  });
}

TEST(ViewportTest, GlCoverageWrittenByAPeerIsWhatTheNextImageReads) {
  AFR_REQUIRE_GL(context);
  expect_coverage_written([context](const ReconstructorConfig& c) {
    return std::unique_ptr<Reconstructor>(std::make_unique<GlReconstructor>(c, context));
  });
}

// ---- Memory

// Resident memory of the process now (not its peak), KiB.
long resident_kib() {
  long pages = 0, resident = 0;
  FILE* f = std::fopen("/proc/self/statm", "r");
  if (f == nullptr) return 0;
  if (std::fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = 0;
  std::fclose(f);
  return resident * (sysconf(_SC_PAGESIZE) / 1024);
}

void expect_bounded_by_the_viewport(const MakeReconstructor& make) {
  // A 32768 x 32768 sampling image (a display wall) of which this node draws the 512 x 512 at
  // the far corner. The received region is 611 x 611 pixels; one byte per sampling-image
  // pixel would be 1 GiB.
  constexpr int kSide = 32768, kView = 512;
  const PixelRect viewport{kSide - kView, kSide - kView, kSide, kSide};
  const int margin = auto_viewport_margin(SplatSizeRule{});
  const PixelRect received{kSide - kView - margin, kSide - kView - margin, kSide, kSide};
  // Samples over the received region, tiles over the whole image (the node ignores the others).
  Pcg32 rng(3);
  SampleBatch batch;
  for (int i = 0; i < 400000; ++i) {
    Sample s;
    s.x = std::min(float(received.x0) + float(received.width()) * rng.next_float(),
                   std::nextafter(float(kSide), 0.0f));
    s.y = std::min(float(received.y0) + float(received.height()) * rng.next_float(),
                   std::nextafter(float(kSide), 0.0f));
    s.time = rng.next_double();
    s.color = glm::vec3(0.25f, 0.5f, 0.75f);
    batch.samples.push_back(s);
  }
  const long before = resident_kib();
  std::unique_ptr<Reconstructor> rec = make(viewport_config(kSide, kSide, viewport));
  EXPECT_EQ(rec->received_region(), received);
  EXPECT_EQ(rec->capacity(), 4 * size_t(received.area()));
  rec->add_batch(batch);
  TilingSnapshot tiling;
  tiling.region = PixelRect{0, 0, kSide, kSide};
  tiling.time = 1.0;
  for (int y = 0; y < kSide; y += 1024) {
    for (int x = 0; x < kSide; x += 1024) {
      TileInfo t;
      t.rect = PixelRect{x, y, x + 1024, y + 1024};
      t.G_x = t.G_y = 0.01f;
      t.G_t = 0.1f;
      t.rate = 4.0f;
      tiling.tiles.push_back(t);
    }
  }
  // The corner tile cut into small ones, one of them of a single pixel at the very corner.
  tiling.tiles.back().rect = PixelRect{kSide - 1024, kSide - 1024, kSide - 1, kSide};
  TileInfo corner = tiling.tiles.back();
  corner.rect = PixelRect{kSide - 1, kSide - 1024, kSide, kSide - 1};
  tiling.tiles.push_back(corner);
  corner.rect = PixelRect{kSide - 1, kSide - 1, kSide, kSide};
  corner.G_x = corner.G_y = 1.0f;
  tiling.tiles.push_back(corner);
  rec->set_tiling(tiling);
  const Camera cam = Camera::look_at({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 1.0, 0.01);
  const auto draw = [&](int out) {
    const Image image = rec->reconstruct(cam, 1.0, out, out);
    EXPECT_EQ(rec->frame_stats().nonfinite_pixels, 0u);
    EXPECT_EQ(rec->frame_stats().empty_pixels, 0u);
    for (const glm::vec3& c : image.pixels) ASSERT_NEAR(c.g, 0.5f, 1e-5f);
    // The grid is the output and a margin of at most what the margin and alignment add.
    const PixelGrid& grid = rec->frame_grid();
    EXPECT_LE(grid.width, out + margin * out / kView + 32 + 1) << out;
    EXPECT_LE(grid.height, out + margin * out / kView + 32 + 1) << out;
    std::vector<float> weights;
    rec->read_weights(&weights);
    EXPECT_EQ(weights.size(), size_t(out) * size_t(out));
    EXPECT_GT(weights.back(), 0.0f);
  };
  draw(kView);
  draw(kView / 4);
  // Only the tiles that overlap the grid are kept (of 1026): the big one at the corner and the
  // 2 small ones cut from it, the first two as their pieces in the rate lattice's cells that
  // reach the grid (drawn at a quarter of the size, 128 px cells: at most 640 / 128 + 1 = 6 a
  // side; 21 at full size).
  const int32_t lattice = rate_lattice(rec->frame_grid().scale_x, rec->frame_grid().scale_y);
  EXPECT_EQ(lattice, 4 * kRateLattice);
  const size_t kept = rec->tile_states().size();
  EXPECT_GE(kept, 1u + 3u);
  EXPECT_LE(kept, 1u + 6u * 6u + 6u + 1u);
  for (size_t i = 1; i < kept; ++i) {
    const PixelRect& r = rec->tile_states()[i].rect;
    EXPECT_GE(r.x0, kSide - 1024);
    EXPECT_LE(r.width(), lattice);
    EXPECT_LE(r.height(), lattice);
  }
  // The single-pixel tile holds what was sent there.
  uint64_t at_corner = 0;
  for (const Sample& s : batch.samples) {
    at_corner += (int(s.x) == kSide - 1 && int(s.y) == kSide - 1) ? 1 : 0;
  }
  EXPECT_EQ(rec->tile_states().back().stored, at_corner);
  const long grown_mib = (resident_kib() - before) / 1024;
  // The ring (and the CPU backend's copy of it, or the GL vertex buffer) is 4 x 611^2 x 64
  // bytes = 91 MiB each; one byte per sampling-image pixel would be 1024 MiB.
  EXPECT_LT(grown_mib, 512) << "resident memory grew by " << grown_mib << " MiB";
  std::printf("  resident memory grew by %ld MiB\n", grown_mib);
  // Upscaled 2x the grid (and its margin) is 4x larger: that memory follows the output, which
  // is checked by the grid's size, not counted above.
  draw(2 * kView);
}

TEST(ViewportTest, CpuMemoryIsBoundedByTheViewportNotTheSamplingImage) {
  expect_bounded_by_the_viewport([](const ReconstructorConfig& c) {
    return std::unique_ptr<Reconstructor>(std::make_unique<CpuReconstructor>(c));
  });
}

TEST(ViewportTest, GlMemoryIsBoundedByTheViewportNotTheSamplingImage) {
  AFR_REQUIRE_GL(context);
  expect_bounded_by_the_viewport([context](const ReconstructorConfig& c) {
    return std::unique_ptr<Reconstructor>(std::make_unique<GlReconstructor>(c, context));
  });
}

// ---- The stored-sample count per tile

// The counts against a brute-force count over a list of what the ring holds, through ring
// wraps, retilings, overlapping tiles, tiles cut by the region and more than N samples
// arriving between two updates; with one block per pixel and with 2 x 2 pixel blocks (the
// blocks tile edges cut are walked sample by sample); and with updates of up to N samples
// and tiles spread over 4 threads (one block per pixel: parts of 65536 pairs, of 2^20 pixels).
TEST(TileSampleCountsTest, CountsEqualABruteForceCountThroughRingWrapsAndRetilings) {
  struct Case {
    size_t capacity;
    int threads;
  };
  for (const Case c : {Case{size_t(1) << 17, 1}, Case{5000, 1}, Case{size_t(1) << 18, 4}}) {
    const size_t capacity = c.capacity;
    SCOPED_TRACE(std::to_string(capacity) + " slots, " + std::to_string(c.threads) + " threads");
    const PixelRect region{100, 50, 100 + 300, 50 + 400};  // 120000 pixels
    TileSampleCounts counts(region, capacity);
    EXPECT_EQ(counts.block_side(), capacity > 120000 ? 1 : 2);
    EXPECT_LE(counts.blocks(), std::max<size_t>(capacity, 65536));
    SampleStore store(capacity);
    Pcg32 rng{uint64_t(capacity)};
    std::deque<StoredSample> held;  // what the ring holds, oldest first
    uint64_t seen = 0;
    std::vector<FieldTile> tiles;
    std::vector<StoredSample> fresh;
    for (int round = 0; round < 12; ++round) {
      // Samples over the region and around it (some outside: not counted).
      SampleBatch b;
      const size_t n =
          round == 7 ? capacity + 123
                     : size_t(rng.next_float() * double(capacity) / (c.threads > 1 ? 1.0 : 3.0));
      for (size_t i = 0; i < n; ++i) {
        Sample s;
        s.x = 60.0f + 400.0f * rng.next_float();
        s.y = 20.0f + 460.0f * rng.next_float();
        s.time = double(round);
        b.samples.push_back(s);
      }
      store.append(b);
      if (round % 3 == 0) {
        // A new tiling: random rectangles, overlapping, some reaching outside the region.
        tiles.assign(1, FieldTile{});
        // (With threads, 100 tiles of up to 300 x 300: over 2^21 pixels to sum, two parts.)
        const int count = c.threads > 1 ? 100 : 40;
        const float most = c.threads > 1 ? 300.0f : 90.0f;
        for (int k = 0; k < count; ++k) {
          FieldTile t;
          const int x0 = 60 + int(rng.next_float() * 400), y0 = 20 + int(rng.next_float() * 460);
          t.rect = PixelRect{x0, y0, x0 + 1 + int(rng.next_float() * most),
                             y0 + 1 + int(rng.next_float() * most)};
          tiles.push_back(t);
        }
        tiles.push_back(FieldTile{0, 0, 0, 0, 0, PixelRect{101, 51, 102, 52}});  // one pixel
      }
      const SampleStore::Delta d = store.copy_since(seen, &fresh);
      counts.update(d, fresh, c.threads);
      counts.count_tiles(tiles, c.threads);
      seen = d.end;
      for (const StoredSample& s : fresh) held.push_back(s);
      while (held.size() > d.stored) held.pop_front();
      // Brute force.
      uint64_t total = 0;
      for (const StoredSample& s : held) {
        total += region.contains(int(std::floor(s.x)), int(std::floor(s.y))) ? 1 : 0;
      }
      EXPECT_EQ(counts.total(), total) << round;
      for (size_t i = 1; i < tiles.size(); ++i) {
        const PixelRect& t = tiles[i].rect;
        const PixelRect in{std::max(t.x0, region.x0), std::max(t.y0, region.y0),
                           std::min(t.x1, region.x1), std::min(t.y1, region.y1)};
        uint64_t c = 0;
        for (const StoredSample& s : held) {
          c += in.contains(int(std::floor(s.x)), int(std::floor(s.y))) ? 1 : 0;
        }
        ASSERT_EQ(counts.count(i), c) << "round " << round << " tile " << i;
        ASSERT_EQ(counts.area(i), in.empty() ? 0 : in.area());
      }
    }
  }
}

}  // namespace
}  // namespace afr
