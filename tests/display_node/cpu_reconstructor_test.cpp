#include <afr/display/cpu_reconstructor.h>

#include <afr/common/error.h>
#include <afr/common/random.h>

#include "test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace afr {
namespace {

using test::all_finite;
using test::diff8;
using test::random_batch;
using test::uniform_tiling;

const Camera kCamera = Camera::look_at({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 1.0, 0.01);

ReconstructorConfig config(int w, int h, int threads = 2) {
  ReconstructorConfig c;
  c.image.width = w;
  c.image.height = h;
  c.threads = threads;
  return c;
}

// ---- An independent reference: a gather over every (pixel, sample) pair in double, written
// from the documentation of filter.h and coverage_map.h (filter_extents and splat_radius have
// their own tests). One snapshot; every sample valid and in the store.
struct Reference {
  Image image;
  std::vector<double> weight;
  std::vector<CoverageCell> coverage;
};

Reference gather(const SampleBatch& batch, const TilingSnapshot* tiling,
                 const ReconstructorConfig& cfg, const Camera& camera, double now, int W, int H,
                 bool reproject, const std::vector<CoverageCell>* previous) {
  const FilterLimits& lim = cfg.filter;
  const SplatSizeRule& rule = cfg.splat;
  const std::vector<Sample>& samples = batch.samples;
  const double sx = double(W) / cfg.image.width, sy = double(H) / cfg.image.height;
  const double depth = std::clamp(now - samples.front().time, double(lim.min_temporal_extent),
                                  double(lim.max_temporal_extent));
  const double rate = double(samples.size()) / (double(cfg.image.width) * cfg.image.height * depth);
  struct Splat {
    double x, y, sigma_x, sigma_y, r, growth, r_x, r_y, w_t;
    glm::dvec3 color;
    bool ok;
  };
  std::vector<Splat> splats;
  for (const Sample& s : samples) {
    Splat sp{};
    const double age = std::max(now - s.time, 0.0);
    glm::dvec2 p(s.x * sx, s.y * sy);
    sp.ok = true;
    if (reproject && (batch.fields & kFieldPosition)) {
      glm::dvec3 world =
          s.miss ? camera.eye + glm::dvec3(glm::normalize(s.position)) : glm::dvec3(s.position);
      if (!s.miss && (batch.fields & kFieldVelocity)) {
        world += glm::dvec3(s.velocity) * (now - s.time);
      }
      sp.ok = camera.project(world, W, H, &p, nullptr);
    }
    const double guard = rule.max_radius + 1.0;
    sp.ok = sp.ok && p.x > -guard && p.x < W + guard && p.y > -guard && p.y < H + guard;
    if (sp.ok) {
      // Positions are rounded to kPositionStep in the whole image (reprojection.h), before
      // the pixel whose tile and coverage the splat takes is chosen.
      p = glm::dvec2(std::round(p.x * 256.0) / 256.0, std::round(p.y * 256.0) / 256.0);
      const int px = std::clamp(int(std::floor(p.x)), 0, W - 1);
      const int py = std::clamp(int(std::floor(p.y)), 0, H - 1);
      // The tile whose rectangle holds this output pixel's center in the sampling image.
      float G_x = 0, G_y = 0, G_t = 0, R_l = 0;
      if (tiling != nullptr) {
        for (const TileInfo& t : tiling->tiles) {
          const double cx = (px + 0.5) / sx, cy = (py + 0.5) / sy;
          if (cx >= t.rect.x0 && cx < t.rect.x1 && cy >= t.rect.y0 && cy < t.rect.y1) {
            G_x = t.G_x, G_y = t.G_y, G_t = t.G_t, R_l = t.rate;
            // The rate the store shows in the tile's piece (kRateLattice: a tile larger than
            // the lattice is cut along it on the axes where it is), when it holds samples.
            PixelRect piece = t.rect;
            const int32_t L = kRateLattice;
            if (t.rect.width() > L) {
              piece.x0 = std::max(piece.x0, int32_t(std::floor(cx)) / L * L);
              piece.x1 = std::min(piece.x1, piece.x0 / L * L + L);
            }
            if (t.rect.height() > L) {
              piece.y0 = std::max(piece.y0, int32_t(std::floor(cy)) / L * L);
              piece.y1 = std::min(piece.y1, piece.y0 / L * L + L);
            }
            int inside = 0;
            for (const Sample& o : samples) inside += piece.contains(int(o.x), int(o.y));
            if (inside > 0) R_l = float(inside / (double(piece.area()) * depth));
          }
        }
      }
      const FilterExtents e =
          filter_extents(G_x, G_y, G_t, R_l > 0 ? R_l : float(rate), float(depth), lim);
      const double r_filter = lim.cutoff * std::max(e.e_x * sx, e.e_y * sy);
      sp.r = splat_radius(previous ? &(*previous)[size_t(py) * W + px] : nullptr, float(r_filter),
                          rule);
      sp.growth = sp.r / r_filter;
      const double grown = std::max(1.0, sp.r / r_filter);
      sp.sigma_x = e.e_x * sx * grown;
      sp.sigma_y = e.e_y * sy * grown;
      // Rounded to kPositionStep, as the reconstructors do (reprojection.h).
      sp.r_x = std::round(std::min(sp.r, lim.cutoff * sp.sigma_x) * 256.0) / 256.0;
      sp.r_y = std::round(std::min(sp.r, lim.cutoff * sp.sigma_y) * 256.0) / 256.0;
      sp.w_t =
          std::max(std::exp(-age * age / (2.0 * e.e_t * e.e_t)), double(lim.min_temporal_weight)) /
          (sp.sigma_x * sp.sigma_y);
      sp.x = p.x;
      sp.y = p.y;
      sp.color = glm::dvec3(s.color);
    }
    splats.push_back(sp);
  }
  Reference ref;
  ref.image = Image(W, H);
  ref.weight.assign(size_t(W) * H, 0.0);
  ref.coverage.assign(size_t(W) * H, CoverageCell{});
  for (int j = 0; j < H; ++j) {
    for (int i = 0; i < W; ++i) {
      glm::dvec3 sum(0.0);
      double wsum = 0.0;
      CoverageCell& cov = ref.coverage[size_t(j) * W + i];
      for (const Splat& sp : splats) {
        if (!sp.ok) continue;
        const double dx = i + 0.5 - sp.x, dy = j + 0.5 - sp.y;
        if (std::abs(dx) >= sp.r_x || std::abs(dy) >= sp.r_y) continue;
        const auto g = [](double d, double sigma) {
          return std::exp(-d * d / (2 * sigma * sigma));
        };
        const double w = (g(dx, sp.sigma_x) - g(sp.r_x, sp.sigma_x)) *
                         (g(dy, sp.sigma_y) - g(sp.r_y, sp.sigma_y)) * sp.w_t;
        if (!(w > kMinSplatWeight)) continue;
        sum += w * sp.color;
        wsum += w;
        cov.count += 1.0f;
        cov.growth_sum += float(sp.growth);
      }
      ref.weight[size_t(j) * W + i] = wsum;
      ref.image.at(i, j) = wsum > 0 ? glm::vec3(sum / wsum) : glm::vec3(0.0f);
    }
  }
  return ref;
}

TEST(CpuReconstructorTest, OneSampleGivesTheHandComputedGaussianFootprint) {
  // By hand (filter_test): G_x = 0.05, G_y = 0.1, G_t = 0.5, R_l = 10 give e_x = cbrt(2),
  // e_y = cbrt(0.25), e_t = cbrt(0.002); the store reaches back 0.5 s (the sample's age), more
  // than e_t, so nothing is clamped. The splat radius is 3 e_x. R_l is what the store holds:
  // 5 samples at one spot in a 1 x 1 tile over 0.5 s; each weighs the Gaussian over its area
  // e_x e_y.
  CpuReconstructor rec(config(64, 48));
  TilingSnapshot tiling = uniform_tiling(64, 48, 0.0f, 0.0f, 0.0f, 1.0f);
  TileInfo tile = tiling.tiles[0];
  tile.rect = PixelRect{30, 20, 31, 21};
  tile.G_x = 0.05f, tile.G_y = 0.1f, tile.G_t = 0.5f, tile.rate = 1.0f;
  tiling.tiles.push_back(tile);  // the later tile wins where they overlap
  rec.set_tiling(tiling);
  SampleBatch b;
  Sample s;
  s.x = 30.3f;
  s.y = 20.7f;
  s.time = 0.0;
  s.color = glm::vec3(0.2f, 0.4f, 0.8f);
  b.samples.assign(5, s);
  rec.add_batch(b);
  const Image image = rec.reconstruct(kCamera, 0.5, 64, 48);
  std::vector<float> weights;
  rec.read_weights(&weights);

  const double e_x = std::cbrt(2.0), e_y = std::cbrt(0.25), e_t = std::cbrt(0.002);
  // The splat: 3 sigma in each direction, rounded to 1/256 pixel (kPositionStep).
  const double r_x = std::round(3.0 * e_x * 256.0) / 256.0,
               r_y = std::round(3.0 * e_y * 256.0) / 256.0,
               w_t = 5.0 * std::exp(-0.25 / (2 * e_t * e_t)) / (e_x * e_y);
  const auto g = [](double d, double e) { return std::exp(-d * d / (2 * e * e)); };
  int reached = 0;
  for (int j = 0; j < 48; ++j) {
    for (int i = 0; i < 64; ++i) {
      // The sample's position rounded to 1/256 pixel (kPositionStep).
      const double dx = i + 0.5 - std::round(30.3 * 256.0) / 256.0,
                   dy = j + 0.5 - std::round(20.7 * 256.0) / 256.0;
      double want = 0.0;
      if (std::abs(dx) < r_x && std::abs(dy) < r_y) {
        want = std::max(0.0, (g(dx, e_x) - g(r_x, e_x)) * (g(dy, e_y) - g(r_y, e_y)) * w_t);
      }
      const float got = weights[size_t(j) * 64 + i];
      EXPECT_NEAR(got, want, 1e-6 * w_t + 1e-4 * want) << i << "," << j;
      if (got > 0.0f) {
        ++reached;
        EXPECT_NEAR(image.at(i, j).b, 0.8f, 1e-6f);
      }
    }
  }
  // 2 r_x = 7.56 pixels wide (7 or 8 columns), 2 r_y = 3.78 high (3 or 4 rows).
  EXPECT_GE(reached, 21);
  EXPECT_LE(reached, 32);
  EXPECT_EQ(rec.frame_stats().splatted, 5u);
  EXPECT_EQ(rec.frame_stats().hole_pixels, size_t(64 * 48 - reached));
  EXPECT_EQ(rec.frame_stats().empty_pixels, 0u);
}

TEST(CpuReconstructorTest, UniformColorReconstructsToExactlyThatColor) {
  Pcg32 rng(1);
  for (const glm::vec3 color : {glm::vec3(0.25f, 0.5f, 1.0f), glm::vec3(0.3f, 0.6f, 0.9f)}) {
    CpuReconstructor rec(config(50, 40));
    rec.set_tiling(test::random_tiling(rng, 50, 40, 8, 1.0));
    for (int frame = 0; frame < 3; ++frame) {
      // Sparse at first (holes to fill), denser later.
      SampleBatch b = random_batch(rng, frame == 0 ? 300 : 4000, 50, 40, frame, frame + 1.0);
      for (Sample& s : b.samples) s.color = color;
      rec.add_batch(b);
      const Image image = rec.reconstruct(kCamera, frame + 1.0, 50, 40);
      for (const glm::vec3& c : image.pixels) {
        if (color.r == 0.25f) {
          // Powers of two: every product and sum scales exactly.
          ASSERT_EQ(c, color);
        } else {
          // Otherwise float rounding of the weighted sums: a few ulps.
          ASSERT_NEAR(c.r, color.r, 4e-6f);
          ASSERT_NEAR(c.g, color.g, 4e-6f);
          ASSERT_NEAR(c.b, color.b, 4e-6f);
        }
      }
    }
  }
}

TEST(CpuReconstructorTest, MatchesABruteForceGatherOverTwoImages) {
  const int W = 48, H = 40;
  Pcg32 rng(2);
  const ReconstructorConfig cfg = config(W, H, 3);
  CpuReconstructor rec(cfg);
  const TilingSnapshot tiling = test::random_tiling(rng, W, H, 8, 2.0);
  rec.set_tiling(tiling);
  SampleBatch batch = random_batch(rng, 3000, W, H, 0.0, 2.0);
  rec.add_batch(batch);
  std::vector<CoverageCell> cpu_coverage;
  for (int frame = 0; frame < 2; ++frame) {
    const Image image = rec.reconstruct(kCamera, 2.0, W, H);
    std::vector<float> weights;
    rec.read_weights(&weights);
    const Reference ref = gather(batch, &tiling, cfg, kCamera, 2.0, W, H, false,
                                 frame == 0 ? nullptr : &cpu_coverage);
    int compared = 0;
    for (size_t p = 0; p < image.pixels.size(); ++p) {
      if (ref.weight[p] == 0.0) continue;
      ++compared;
      EXPECT_NEAR(weights[p], ref.weight[p], 2e-4 * ref.weight[p] + 1e-12) << p;
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(image.pixels[p][c], ref.image.pixels[p][c], 1e-4);
    }
    EXPECT_GT(compared, W * H * 9 / 10);
    rec.read_coverage(&cpu_coverage);
    int same = 0;
    for (size_t p = 0; p < cpu_coverage.size(); ++p) {
      same += cpu_coverage[p].count == ref.coverage[p].count;
      if (cpu_coverage[p].count == ref.coverage[p].count) {
        EXPECT_NEAR(cpu_coverage[p].growth_sum, ref.coverage[p].growth_sum,
                    1e-4f * ref.coverage[p].growth_sum);
      }
    }
    EXPECT_GT(same, int(cpu_coverage.size()) * 99 / 100);
  }
}

// A 64 x 64 reconstructor on 1, 2 and 5 threads given `samples` random samples (seed `seed`;
// a store of `capacity`, 0: the config's) and asked for three images: the last image and how
// many samples it splatted, per thread count.
struct ThreadedImage {
  Image image;
  uint64_t splatted = 0;
};
std::vector<ThreadedImage> images_on_1_2_and_5_threads(uint64_t seed, int samples,
                                                       size_t capacity) {
  Pcg32 rng(seed);
  const TilingSnapshot tiling = test::random_tiling(rng, 64, 64, 16, 1.0);
  const SampleBatch batch = random_batch(rng, samples, 64, 64, 0.0, 1.0);
  std::vector<ThreadedImage> out;
  for (int threads : {1, 2, 5}) {
    ReconstructorConfig cfg = config(64, 64, threads);
    if (capacity > 0) cfg.capacity = capacity;
    CpuReconstructor rec(cfg);
    EXPECT_EQ(rec.threads(), threads);
    rec.set_tiling(tiling);
    rec.add_batch(batch);
    ThreadedImage r;
    for (int frame = 0; frame < 3; ++frame) r.image = rec.reconstruct(kCamera, 1.0, 64, 64);
    r.splatted = rec.frame_stats().splatted;
    out.push_back(std::move(r));
  }
  return out;
}

TEST(CpuReconstructorTest, TheThreadCountDoesNotChangeABit) {
  const std::vector<ThreadedImage> images = images_on_1_2_and_5_threads(3, 20000, 0);
  EXPECT_EQ(images[0].image.pixels, images[1].image.pixels);
  EXPECT_EQ(images[0].image.pixels, images[2].image.pixels);
}

TEST(CpuReconstructorTest, TheRingsChunksDoNotChangeABit) {
  // Binning splits the ring into more chunks with more threads (at most 4 per thread): 60000
  // stored samples over the 33 bins of a 64 x 64 image make 4 chunks on one thread and 7 on
  // two or five, each bin's pages chained per chunk. The bins still hold their samples in
  // ring order, so the sums add in the same order.
  const std::vector<ThreadedImage> images = images_on_1_2_and_5_threads(11, 60000, 60000);
  for (const ThreadedImage& r : images) EXPECT_EQ(r.splatted, 60000u);
  EXPECT_EQ(images[0].image.pixels, images[1].image.pixels);
  EXPECT_EQ(images[0].image.pixels, images[2].image.pixels);
}

TEST(CpuReconstructorTest, PhaseTimesAreTheCallsParts) {
  // FrameStats::cpu: no phase is negative, together they take no more than the whole call,
  // the splat pass takes time when samples reach the image, and traditional frameless has no
  // splat shapes or reprojection.
  Pcg32 rng(3);
  const TilingSnapshot tiling = test::random_tiling(rng, 64, 64, 16, 1.0);
  const SampleBatch batch = random_batch(rng, 20000, 64, 64, 0.0, 1.0);
  for (const ReconstructionMode mode :
       {ReconstructionMode::kAdaptive, ReconstructionMode::kTraditionalFrameless}) {
    SCOPED_TRACE(mode_name(mode));
    ReconstructorConfig cfg = config(64, 64, 1);
    cfg.mode = mode;
    CpuReconstructor rec(cfg);
    rec.set_tiling(tiling);
    rec.add_batch(batch);
    rec.reconstruct(kCamera, 1.0, 64, 64);
    const FrameStats& f = rec.frame_stats();
    const CpuPhaseTimes& p = f.cpu;
    for (const double v : {p.prepare, p.shape, p.reproject, p.splat, p.fill}) {
      EXPECT_GE(v, 0.0);
    }
    EXPECT_LE(p.prepare + p.shape + p.reproject + p.splat + p.fill, f.milliseconds);
    EXPECT_GT(f.splatted, 0u);
    EXPECT_GT(p.splat, 0.0);
    if (mode == ReconstructionMode::kTraditionalFrameless) {
      EXPECT_EQ(p.shape + p.reproject, 0.0);
    } else {
      EXPECT_GT(p.reproject, 0.0);
    }
  }
}

TEST(CpuReconstructorTest, BadInputsAreCountedAndNeverReachTheImage) {
  const float inf = std::numeric_limits<float>::infinity();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  Pcg32 rng(4);
  CpuReconstructor rec(config(40, 30));
  // Zero gradients and zero rate in one tile, NaN and infinite values in others.
  TilingSnapshot tiling = uniform_tiling(40, 30, 0.0f, 0.0f, 0.0f, 0.0f, 1.0);
  TileInfo odd = tiling.tiles[0];
  odd.rect = PixelRect{0, 0, 20, 15};
  odd.G_x = nan;
  odd.G_t = inf;
  odd.rate = -3.0f;
  tiling.tiles.push_back(odd);
  rec.set_tiling(tiling);
  SampleBatch b = random_batch(rng, 4000, 40, 30, 0.0, 1.0);
  b.samples[0].color.r = nan;
  b.samples[1].color.g = inf;
  b.samples[2].color.b = -inf;
  b.samples[3].time = nan;
  b.samples[4].x = nan;
  b.samples[5].y = -inf;
  b.samples[6].color = glm::vec3(1e30f);  // clamped to kMaxColor
  rec.add_batch(b);
  const Image image = rec.reconstruct(kCamera, 1.0, 40, 30);
  EXPECT_TRUE(all_finite(image));
  EXPECT_EQ(rec.frame_stats().nonfinite_pixels, 0u);
  const IngestStats st = rec.ingest_stats();
  EXPECT_EQ(st.bad_color, 3u);
  EXPECT_EQ(st.bad_time, 1u);
  EXPECT_EQ(st.bad_image_position, 2u);
  EXPECT_EQ(st.clamped_color, 1u);
  EXPECT_EQ(st.accepted, 4000u - 6u);
  EXPECT_EQ(rec.tiling_stats().bad_values, 3u);
  EXPECT_EQ(rec.frame_stats().stored, 4000u - 6u);
}

TEST(CpuReconstructorTest, VeryOldSamplesStillShowAndFutureOnesAreSkipped) {
  // Samples 10^4 s old get the minimum temporal weight: the image shows them (no holes, not
  // black). Samples far in the future are skipped and counted.
  CpuReconstructor rec(config(32, 32));
  Pcg32 rng(5);
  SampleBatch old = random_batch(rng, 4096, 32, 32, 0.0, 1.0);
  for (Sample& s : old.samples) s.color = glm::vec3(0.5f);
  rec.add_batch(old);
  SampleBatch future = random_batch(rng, 100, 32, 32, 2e4, 2e4 + 1.0);
  for (Sample& s : future.samples) s.color = glm::vec3(1.0f, 0.0f, 0.0f);
  rec.add_batch(future);
  const Image image = rec.reconstruct(kCamera, 1e4, 32, 32);
  EXPECT_EQ(rec.frame_stats().future, 100u);
  EXPECT_EQ(rec.frame_stats().hole_pixels, 0u);
  for (const glm::vec3& c : image.pixels) ASSERT_NEAR(c.g, 0.5f, 1e-6f);
}

TEST(CpuReconstructorTest, ALongRunningDisplayFiltersLikeAFreshOne) {
  // The same samples relative to the display time, at t = 1 s and at t = 10^6 s.
  Pcg32 rng(6);
  Pcg32 tiles_rng(7);
  const TilingSnapshot tiling = test::random_tiling(tiles_rng, 48, 48, 12, 0.0);
  const SampleBatch batch = random_batch(rng, 9000, 48, 48, 0.0, 1.0);
  Image images[2];
  int k = 0;
  for (double base : {0.0, 1e6}) {
    CpuReconstructor rec(config(48, 48));
    rec.set_tiling(tiling);
    SampleBatch shifted = batch;
    for (Sample& s : shifted.samples) s.time += base;
    rec.add_batch(shifted);
    images[k++] = rec.reconstruct(kCamera, base + 1.0, 48, 48);
    EXPECT_TRUE(all_finite(images[k - 1]));
  }
  for (size_t p = 0; p < images[0].pixels.size(); ++p) {
    for (int c = 0; c < 3; ++c) ASSERT_NEAR(images[0].pixels[p][c], images[1].pixels[p][c], 1e-5);
  }
}

TEST(CpuReconstructorTest, AnEmptyStoreGivesBlack) {
  CpuReconstructor rec(config(16, 8));
  const Image image = rec.reconstruct(kCamera, 3.0, 16, 8);
  for (const glm::vec3& c : image.pixels) ASSERT_EQ(c, glm::vec3(0.0f));
  EXPECT_EQ(rec.frame_stats().empty_pixels, 16u * 8u);
}

TEST(CpuReconstructorTest, HolesTakeTheColorOfTheNearestSamples) {
  // Red samples in the left quarter, blue in the right quarter, dense and with a fine filter:
  // the middle half is a hole, filled from wider support: red-ish on its left, blue-ish on its
  // right, never black.
  const int W = 64, H = 16;
  CpuReconstructor rec(config(W, H));
  rec.set_tiling(uniform_tiling(W, H, 0.0f, 0.0f, 0.0f, 1000.0f));
  Pcg32 rng(8);
  SampleBatch b = random_batch(rng, 4000, W, H, 0.0, 1.0);
  for (Sample& s : b.samples) {
    const bool left = s.x < W / 2;
    s.x = left ? s.x * 0.5f : W - (W - s.x) * 0.5f;
    s.color = left ? glm::vec3(1, 0, 0) : glm::vec3(0, 0, 1);
  }
  rec.add_batch(b);
  const Image image = rec.reconstruct(kCamera, 1.0, W, H);
  EXPECT_GT(rec.frame_stats().hole_pixels, size_t(W * H / 3));
  EXPECT_EQ(rec.frame_stats().empty_pixels, 0u);
  for (int y = 0; y < H; ++y) {
    EXPECT_GT(image.at(20, y).r, image.at(20, y).b);
    EXPECT_LT(image.at(43, y).r, image.at(43, y).b);
    for (int x = 0; x < W; ++x) {
      ASSERT_NEAR(image.at(x, y).r + image.at(x, y).b, 1.0f, 1e-5f);
    }
  }
}

TEST(CpuReconstructorTest, CoverageMapGrowsSparseSplatsAndShrinksDenseOnes) {
  // Left half: 64 samples per pixel; right half: one sample per 32 pixels. One tile, its
  // extents pinned to 1 pixel: 3 pixel splats, far too big on the left (~2300 splats reach a
  // pixel), too small on the right (~1).
  const int W = 64, H = 32;
  ReconstructorConfig cfg = config(W, H);
  cfg.capacity = 100000;
  cfg.filter.min_spatial_extent = cfg.filter.max_spatial_extent = 1.0f;
  CpuReconstructor rec(cfg);
  rec.set_tiling(uniform_tiling(W, H, 1.0f, 1.0f, 0.0f, 1.0f));
  Pcg32 rng(9);
  SampleBatch b;
  for (Sample s : random_batch(rng, 32 * 32 / 32, W / 2, H, 0.0, 0.0).samples) {
    s.x += W / 2;
    b.samples.push_back(s);
  }
  for (const Sample& s : random_batch(rng, 64 * 32 * 32, W / 2, H, 0.0, 1.0).samples) {
    b.samples.push_back(s);
  }
  rec.add_batch(b);
  std::vector<CoverageCell> first, second;
  rec.reconstruct(kCamera, 1.0, W, H);
  rec.read_coverage(&first);
  rec.reconstruct(kCamera, 1.0, W, H);
  rec.read_coverage(&second);
  const auto mean = [&](const std::vector<CoverageCell>& c, int x0, int x1) {
    double count = 0, radius = 0;
    for (int y = 4; y < H - 4; ++y) {
      for (int x = x0; x < x1; ++x) {
        count += c[size_t(y) * W + x].count;
        radius += c[size_t(y) * W + x].growth_sum;
      }
    }
    return std::pair(count / ((H - 8) * (x1 - x0)), radius / std::max(count, 1.0));
  };
  const auto [dense1_n, dense1_r] = mean(first, 4, 28);
  const auto [dense2_n, dense2_r] = mean(second, 4, 28);
  const auto [sparse1_n, sparse1_r] = mean(first, 36, 60);
  const auto [sparse2_n, sparse2_r] = mean(second, 36, 60);
  EXPECT_GT(dense1_n, 32.0);
  EXPECT_NEAR(dense1_r, 1.0, 0.01);  // the filter's own radius
  // Shrunk half way (in log) to the band: (32 / c)^(1/4), at least `shrink`.
  const double half_way =
      std::max(double(cfg.splat.shrink), std::pow(double(cfg.splat.shrink_above) / dense1_n, 0.25));
  EXPECT_LT(half_way, 0.7);
  EXPECT_NEAR(dense2_r / dense1_r, half_way, 0.02);
  EXPECT_LT(sparse1_n, 4.0);
  EXPECT_GT(sparse2_r / sparse1_r, 1.5);  // grown toward the band (sqrt(4 / 1) = 2 at most
                                          // where one splat reached; some land where dense)
  EXPECT_GT(sparse2_n, 2.0 * sparse1_n);
  // Image after image the map settles: the sparse side near the band's lower end (4 splats
  // a pixel), the dense side at the smallest radius (1 px: still ~200 splats a pixel there).
  std::vector<CoverageCell> settled;
  for (int i = 0; i < 20; ++i) rec.reconstruct(kCamera, 1.0, W, H);
  rec.read_coverage(&settled);
  const auto [dense_n, dense_g] = mean(settled, 4, 28);
  const auto [sparse_n, sparse_g] = mean(settled, 36, 60);
  EXPECT_NEAR(dense_g, cfg.splat.min_radius / 3.0, 0.02);  // filter radius: 3 sigma = 3 px
  EXPECT_GT(dense_n, cfg.splat.shrink_above);
  EXPECT_GT(sparse_n, 3.0);
  EXPECT_LT(sparse_n, 8.0);
}

// A store that fills at once (a sampler's first fill landing) after images of a sparse one:
// the splats the map grew over the sparse store would cover thousands of pixels each, a
// thousand splats a pixel at the new density even after the first shrink; the tile's stored
// density caps them (splat_density_cap) from the first image that holds the new samples.
TEST(CpuReconstructorTest, SplatsGrownOverASparseStoreFitTheDensityOnceItFills) {
  const int W = 64, H = 48;
  ReconstructorConfig cfg = config(W, H);
  cfg.capacity = 4 * W * H + 200;
  cfg.filter.min_spatial_extent = cfg.filter.max_spatial_extent = 1.0f;  // r_f = 3 px
  CpuReconstructor rec(cfg);
  rec.set_tiling(uniform_tiling(W, H, 0.0f, 0.0f, 0.0f, 1.0f));
  Pcg32 rng(12);
  rec.add_batch(random_batch(rng, 60, W, H, 0.0, 0.5));
  std::vector<CoverageCell> cells;
  const auto mean = [&](bool growth) {
    double count = 0, sum = 0;
    for (const CoverageCell& c : cells) {
      count += c.count;
      sum += c.growth_sum;
    }
    return growth ? sum / std::max(count, 1.0) : count / double(cells.size());
  };
  for (int i = 0; i < 5; ++i) rec.reconstruct(kCamera, 0.5, W, H);
  rec.read_coverage(&cells);
  EXPECT_GT(mean(true), 3.0);  // grown: splats of 9 px and more
  rec.add_batch(random_batch(rng, 4 * W * H, W, H, 0.5, 1.0));
  rec.reconstruct(kCamera, 1.0, W, H);
  rec.read_coverage(&cells);
  // At 4 samples a pixel the cap is 0.5 sqrt(4 x 32 / 4) = 2.8 px, below the filter's 3 px:
  // splats of 3 px, about 4 x 6^2 = 144 a pixel (the shrunk map alone: ~1000).
  EXPECT_LT(mean(false), 200.0);
  EXPECT_NEAR(mean(true), 1.0, 0.05);
}

TEST(CpuReconstructorTest, TraditionalFramelessShowsTheNewestSampleAtEachPixel) {
  const int W = 40, H = 30;
  ReconstructorConfig cfg = config(W, H);
  cfg.mode = ReconstructionMode::kTraditionalFrameless;
  CpuReconstructor rec(cfg);
  Pcg32 rng(10);
  const SampleBatch b = random_batch(rng, 3000, W, H, 0.0, 1.0);
  rec.add_batch(b);
  const Image image = rec.reconstruct(kCamera, 1.0, W, H);
  std::vector<double> newest(size_t(W) * H, -1.0);
  std::vector<glm::vec3> want(size_t(W) * H);
  for (const Sample& s : b.samples) {
    const size_t p = size_t(int(s.y)) * W + size_t(int(s.x));
    if (s.time > newest[p]) newest[p] = s.time, want[p] = s.color;
  }
  int holes = 0;
  for (size_t p = 0; p < want.size(); ++p) {
    if (newest[p] < 0) {
      ++holes;
      continue;
    }
    ASSERT_EQ(image.pixels[p], want[p]);
  }
  EXPECT_EQ(rec.frame_stats().hole_pixels, size_t(holes));
}

TEST(CpuReconstructorTest, WithoutReprojectionTheCameraDoesNotMatter) {
  Pcg32 rng(11);
  const test::FloorScene scene;
  SampleBatch b = test::scene_batch(scene, kCamera, rng, 5000, 40, 40, 0.0, 1.0, false);
  ReconstructorConfig cfg = config(40, 40);
  cfg.mode = ReconstructionMode::kAdaptiveNoReprojection;
  CpuReconstructor rec(cfg);
  rec.add_batch(b);
  const Image a = rec.reconstruct(kCamera, 1.0, 40, 40);
  CpuReconstructor rec2(cfg);
  rec2.add_batch(b);
  const Camera moved = Camera::look_at({3, 1, 0}, {0, 0, -9}, {0, 1, 0}, 0.5, 0.01);
  EXPECT_EQ(rec2.reconstruct(moved, 1.0, 40, 40).pixels, a.pixels);
}

// Pixels of view `b` whose floor point view `a` saw well inside its image (sky pixels are
// always seen: directions do not move with the eye).
std::vector<bool> seen_from(const test::FloorScene& scene, const Camera& a, const Camera& b, int W,
                            int H, double margin) {
  std::vector<bool> mask(size_t(W) * H, false);
  for (int y = 0; y < H; ++y) {
    for (int x = 0; x < W; ++x) {
      glm::dvec3 world;
      bool miss;
      scene.trace(b.ray(x + 0.5, y + 0.5, W, H), 0.0, &world, &miss);
      glm::dvec2 p;
      mask[size_t(y) * W + x] = miss || (a.project(world, W, H, &p, nullptr) && p.x > margin &&
                                         p.x < W - margin && p.y > margin && p.y < H - margin);
    }
  }
  return mask;
}

// The RMS error against `truth` over `mask` (8-bit levels) of the image of `view` that a
// reconstructor in `mode` holding `batch` gives after three refreshes.
double error_seen_from(const SampleBatch& batch, const Camera& view, ReconstructionMode mode,
                       const Image& truth, const std::vector<bool>& mask) {
  const int W = truth.width, H = truth.height;
  ReconstructorConfig cfg = config(W, H);
  cfg.mode = mode;
  CpuReconstructor rec(cfg);
  rec.set_tiling(uniform_tiling(W, H, 0.0f, 0.0f, 0.0f, 4.0f));
  rec.add_batch(batch);
  Image image;
  for (int frame = 0; frame < 3; ++frame) rec.reconstruct(view, 1.0, W, H, &image);
  EXPECT_TRUE(all_finite(image));
  const test::Diff8 d = diff8(image, truth, &mask);
  EXPECT_GT(d.compared, size_t(W * H / 2));
  return d.rms;
}

TEST(CpuReconstructorTest, ReprojectionMatchesTheAnalyticImageOfATranslatedView) {
  const int W = 96, H = 72;
  const test::FloorScene scene;
  const Camera a = Camera::look_at({0, 0.5, 0}, {0, 0.1, -5}, {0, 1, 0}, 1.0, 0.01);
  Camera b = a;
  b.eye += glm::dvec3(0.5, 0.15, -0.3);
  Pcg32 rng(12);
  const SampleBatch batch = test::scene_batch(scene, a, rng, 4 * W * H, W, H, 0.0, 1.0, false);
  const Image truth = test::scene_image(scene, b, W, H, 1.0);
  const std::vector<bool> mask = seen_from(scene, a, b, W, H, 3.0);
  const double reprojected = error_seen_from(batch, b, ReconstructionMode::kAdaptive, truth, mask);
  EXPECT_LT(reprojected, 3.0);
  EXPECT_GT(error_seen_from(batch, b, ReconstructionMode::kAdaptiveNoReprojection, truth, mask),
            4.0 * reprojected);
}

TEST(CpuReconstructorTest, ReprojectionMatchesTheAnalyticImageOfAnOrthographicView) {
  // An orthographic camera looking down at the floor, moved across and along its view and
  // zoomed out: every sample is a hit, placed by the orthographic projection.
  const int W = 96, H = 72;
  const test::FloorScene scene;
  Camera a = Camera::look_at({0, 2, 0}, {0, -1, -4}, {0, 1, 0}, 1.0, 0.01);
  a.ymag = 1.5;
  Camera b = a;
  b.eye += glm::dvec3(0.5, 0.15, -0.3);
  b.ymag = 1.6;
  Pcg32 rng(14);
  const SampleBatch batch = test::scene_batch(scene, a, rng, 4 * W * H, W, H, 0.0, 1.0, false);
  for (const Sample& s : batch.samples) ASSERT_FALSE(s.miss);
  const Image truth = test::scene_image(scene, b, W, H, 1.0);
  const std::vector<bool> mask = seen_from(scene, a, b, W, H, 3.0);
  const double reprojected = error_seen_from(batch, b, ReconstructionMode::kAdaptive, truth, mask);
  EXPECT_LT(reprojected, 3.0);
  EXPECT_GT(error_seen_from(batch, b, ReconstructionMode::kAdaptiveNoReprojection, truth, mask),
            4.0 * reprojected);
  // The same view taken as a perspective one misplaces the samples.
  Camera perspective = b;
  perspective.ymag = 0.0;
  EXPECT_GT(error_seen_from(batch, perspective, ReconstructionMode::kAdaptive, truth, mask),
            4.0 * reprojected);
}

TEST(CpuReconstructorTest, VelocityCarriesSamplesOfMovingSurfaces) {
  const int W = 80, H = 60;
  test::FloorScene scene;
  scene.velocity = glm::dvec3(1.5, 0.0, 0.0);
  const Camera cam = Camera::look_at({0, 0.5, 0}, {0, -0.4, -5}, {0, 1, 0}, 1.0, 0.01);
  Pcg32 rng(13);
  const SampleBatch moving = test::scene_batch(scene, cam, rng, 4 * W * H, W, H, 0.0, 1.0, true);
  SampleBatch frozen = moving;
  frozen.fields = kFieldPosition;  // the same samples without their velocity
  const Image truth = test::scene_image(scene, cam, W, H, 1.0);
  double rms[2];
  int k = 0;
  for (const SampleBatch* batch : {&moving, const_cast<const SampleBatch*>(&frozen)}) {
    CpuReconstructor rec(config(W, H));
    rec.set_tiling(uniform_tiling(W, H, 0.0f, 0.0f, 0.0f, 4.0f));
    rec.add_batch(*batch);
    const Image image = rec.reconstruct(cam, 1.0, W, H);
    rms[k++] = diff8(image, truth).rms;
  }
  EXPECT_LT(rms[0], 3.0);
  EXPECT_GT(rms[1], 2.0 * rms[0]);
}

TEST(CpuReconstructorTest, OutputsOfAnotherSizeAreTheImageScaled) {
  // Left half red, right half green in a 20 x 10 sampling image; a 40 x 30 output puts the
  // boundary at x = 20.
  CpuReconstructor rec(config(20, 10));
  Pcg32 rng(14);
  SampleBatch b = random_batch(rng, 4000, 20, 10, 0.0, 1.0);
  for (Sample& s : b.samples) s.color = s.x < 10 ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
  rec.add_batch(b);
  rec.set_tiling(uniform_tiling(20, 10, 0.5f, 0.01f, 0.0f, 20.0f));
  const Image image = rec.reconstruct(kCamera, 1.0, 40, 30);
  ASSERT_EQ(image.width, 40);
  for (int y = 0; y < 30; ++y) {
    EXPECT_GT(image.at(16, y).r, 0.99f);
    EXPECT_GT(image.at(23, y).g, 0.99f);
    EXPECT_GT(image.at(18, y).r, 0.5f);
    EXPECT_GT(image.at(21, y).g, 0.5f);
  }
}

TEST(CpuReconstructorTest, RejectsBadSizesAndTimes) {
  CpuReconstructor rec(config(8, 8));
  Image image;
  EXPECT_THROW(rec.reconstruct(kCamera, 0.0, 0, 8, &image), Error);
  EXPECT_THROW(rec.reconstruct(kCamera, 0.0, 8, kMaxOutputSide + 1, &image), Error);
  EXPECT_THROW(rec.reconstruct(kCamera, std::nan(""), 8, 8, &image), Error);
  ReconstructorConfig cfg = config(8, 8);
  cfg.capacity = kMaxCapacity + 1;
  EXPECT_THROW(CpuReconstructor{cfg}, Error);
  EXPECT_EQ(CpuReconstructor(config(8, 8)).capacity(), 4u * 64u);
}

// ---- A still scene as the adaptive sampler leaves it (measured on the static test scene):
// a vertical edge at x = 24 between a dark and a bright flat region, the edge's narrow tiles
// densely sampled (16 samples per pixel per second), the flat tiles either side sparsely (one
// sample per 4 pixels per second), samples spread over the last second, in crosshairs of 5
// (the center and its neighbours one pixel away) as the sampler sends them. The ideal image
// is exact: the edge lies on a pixel border.
constexpr int kEdgeW = 64, kEdgeH = 32;
constexpr float kEdgeX = 24.0f;
const glm::vec3 kDark(0.2f, 0.15f, 0.15f), kBright(0.9f, 0.5f, 0.4f);

glm::vec3 edge_color(float x) { return x < kEdgeX ? kDark : kBright; }

Image edge_ideal() {
  Image image(kEdgeW, kEdgeH);
  for (int y = 0; y < kEdgeH; ++y) {
    for (int x = 0; x < kEdgeW; ++x) image.at(x, y) = edge_color(float(x) + 0.5f);
  }
  return image;
}

TilingSnapshot edge_tiling() {
  TilingSnapshot s;
  s.region = PixelRect{0, 0, kEdgeW, kEdgeH};
  const auto tile = [&](int x0, int x1, int y0, int y1, float G_x, float rate) {
    TileInfo t;
    t.rect = PixelRect{x0, y0, x1, y1};
    t.G_x = G_x;
    t.rate = rate;
    s.tiles.push_back(t);
  };
  for (int y = 0; y < kEdgeH; y += 2) tile(22, 26, y, y + 2, 0.2f, 16.0f);  // the edge
  tile(0, 22, 0, kEdgeH, 0.0f, 0.25f);                                      // flat, dark
  tile(26, kEdgeW, 0, kEdgeH, 0.0f, 0.25f);                                 // flat, bright
  return s;
}

// `n` samples of the still edge scene at times in [t0, t1], with the edge's density; each
// color channel off by up to +-noise (stochastic shading).
SampleBatch edge_samples(Pcg32& rng, size_t n, double t0, double t1, float noise = 0.0f) {
  SampleBatch b;
  const double edge_share = 16.0 * 4 * kEdgeH / (16.0 * 4 * kEdgeH + 0.25 * 60 * kEdgeH);
  while (b.samples.size() < n) {
    const bool edge = rng.next_double() < edge_share;
    const float x = edge ? 22.0f + 4.0f * rng.next_float() : [&] {
      const float u = 60.0f * rng.next_float();
      return u < 22.0f ? u : u + 4.0f;
    }();
    const float y = float(kEdgeH) * rng.next_float();
    const double t = t0 + (t1 - t0) * rng.next_double();
    const float arms[5][2] = {{0, 0}, {-1, 0}, {1, 0}, {0, -1}, {0, 1}};
    for (const auto& a : arms) {
      Sample s;
      s.x = x + a[0];
      s.y = y + a[1];
      if (s.x < 0.0f || s.y < 0.0f || s.x >= kEdgeW || s.y >= kEdgeH) continue;
      s.time = t;
      s.color = edge_color(s.x);
      for (int c = 0; c < 3; ++c) s.color[c] += noise * (2.0f * rng.next_float() - 1.0f);
      b.samples.push_back(s);
    }
  }
  return b;
}

TEST(CpuReconstructorTest, StillEdgeStaysWithinAPixelOfTheIdeal) {
  ReconstructorConfig cfg = config(kEdgeW, kEdgeH);
  cfg.capacity = 16 * kEdgeW * kEdgeH;
  CpuReconstructor rec(cfg);
  rec.set_tiling(edge_tiling());
  Pcg32 rng(21);
  rec.add_batch(edge_samples(rng, cfg.capacity, 0.0, 1.0));
  Image image;
  for (int k = 0; k < 10; ++k) rec.reconstruct(kCamera, 1.0, kEdgeW, kEdgeH, &image);
  const Image ideal = edge_ideal();
  const float half = 0.5f * (kDark.r + kBright.r);
  for (int y = 0; y < kEdgeH; ++y) {
    // Where the red channel crosses half-way, by linear interpolation between pixel centers.
    float crossing = -1.0f;
    for (int x = 0; x + 1 < kEdgeW && crossing < 0.0f; ++x) {
      const float a = image.at(x, y).r, b = image.at(x + 1, y).r;
      if (a < half && b >= half) crossing = float(x) + 0.5f + (half - a) / (b - a);
    }
    EXPECT_NEAR(crossing, kEdgeX, 1.0f) << "row " << y;
    // Two pixels away from the edge, each side shows its own color: nothing bleeds across.
    for (int x = 0; x < kEdgeW; ++x) {
      if (std::abs(float(x) + 0.5f - kEdgeX) < 2.0f) continue;
      for (int c = 0; c < 3; ++c) {
        ASSERT_NEAR(image.at(x, y)[c], ideal.at(x, y)[c], 0.02f) << x << "," << y;
      }
    }
  }
  EXPECT_LT(diff8(image, ideal).rms, 6.0);
}

TEST(CpuReconstructorTest, StillSceneErrorFallsAsSamplesAccumulate) {
  // The same scene, the store filling over 8 s; images at 0.25, 0.5, ..., 8 s. As samples
  // accumulate the filter at the edge narrows (e_x e_y = V_s / depth) down to
  // min_spatial_extent and the error falls (it did not: the static edge tiles' temporal
  // window was ~1/30 of the store, see FilterTest.StaticEdgeReachesBackTheWholeDepth, and
  // the image showed only the newest few samples, blurred along the edge).
  ReconstructorConfig cfg = config(kEdgeW, kEdgeH);
  cfg.capacity = 64 * kEdgeW * kEdgeH;
  CpuReconstructor rec(cfg);
  rec.set_tiling(edge_tiling());
  Pcg32 rng(22);
  const Image ideal = edge_ideal();
  // A quarter of the rates edge_tiling() states: the store's own count sets R_l.
  const size_t per_second = size_t(16.0 * 4 * kEdgeH + 0.25 * 60 * kEdgeH) / 4;
  double t = 0.0, first = 0.0, previous = 1e9;
  Image image;
  for (double until : {0.25, 0.5, 1.0, 2.0, 4.0, 8.0}) {
    rec.add_batch(edge_samples(rng, size_t(double(per_second) * (until - t)), t, until));
    t = until;
    for (int k = 0; k < 10; ++k) rec.reconstruct(kCamera, t, kEdgeW, kEdgeH, &image);
    const double rms = diff8(image, ideal).rms;
    if (first == 0.0) first = rms;
    EXPECT_LT(rms, 1.1 * previous) << "after " << t << " s";
    previous = rms;
  }
  EXPECT_LT(previous, 0.6 * first);
}

}  // namespace
}  // namespace afr
