// afr-bench-binned-gather: what a splat pass that bins the samples on the CPU and gathers them
// on the GL device would cost at least. The GL backend bins on the device (gather) or
// rasterises points (raster); on a software rasteriser both cost 15-30 times the CPU backend,
// because the driver runs atomics and per-point setup lane by lane (docs/benchmarks.md, "GPU
// reconstructor"). This benchmark times the one structure that needs neither:
//
//   1. bin  (CPU, one thread): a counting sort of the samples by the pixel their center falls
//           in, into two records each (center, age, k_t; color) and a (first, count) per pixel;
//   2. upload: the records and the cell table into buffer and texture storage;
//   3. gather (GL compute): one invocation per block of B x B pixels visits every cell within
//           `reach` pixels of its block and evaluates each of their samples at its pixels with
//           the splat kernel's arithmetic (box test, the two Gaussians lowered by their value at
//           the edge, the temporal weight, the weight floor; sums and coverage), its splat shape
//           read per cell as the GL backend's prepare pass reads it per pixel.
//
// The samples lie uniformly at random, N = spp x pixels, each splat as wide as the reach lets
// it be (reach + 0.5 pixels). What the pass would need besides (the reprojection of every
// sample, each pixel's splat shape from its tile and the coverage, wider splats drawn another
// way, the hole fill) is not timed: the sum of the three phases is a floor under that design.
#include <afr/common/error.h>
#include <afr/common/log.h>
#include <afr/display/gl_context.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "gl_program.h"

namespace {

// What both gathers read and write.
const char* const kGatherInputs = R"(
uniform usampler2D u_cells;        // per pixel: first record, count
uniform sampler2D u_kernel;        // per pixel: k_x, k_y, off_x, off_y of a splat landing there
uniform sampler2D u_extent;        // per pixel: r_x, r_y, growth, 1 / (sigma_x sigma_y)
uniform samplerBuffer u_where;     // per record: center x, y, age, k_t
uniform samplerBuffer u_color;     // per record: r, g, b
uniform ivec2 u_size;
uniform float u_min_wt;
uniform float u_min_weight;
layout(rgba32f, binding = 0) uniform writeonly image2D u_sums;
layout(rg32f, binding = 1) uniform writeonly image2D u_coverage;
)";

const char* const kGatherCompute = R"(
layout(local_size_x = 8, local_size_y = 8) in;
void main() {
  ivec2 b = ivec2(gl_GlobalInvocationID.xy) * B;
  if (b.x >= u_size.x || b.y >= u_size.y) return;
  vec4 sums[B * B];
  vec2 coverage[B * B];
  for (int k = 0; k < B * B; ++k) {
    sums[k] = vec4(0.0);
    coverage[k] = vec2(0.0);
  }
  ivec2 lo = max(b - REACH, ivec2(0)), hi = min(b + B - 1 + REACH, u_size - 1);
  for (int cy = lo.y; cy <= hi.y; ++cy) {
    for (int cx = lo.x; cx <= hi.x; ++cx) {
      uvec2 cell = texelFetch(u_cells, ivec2(cx, cy), 0).xy;
      if (cell.y == 0u) continue;
      vec4 kernel = texelFetch(u_kernel, ivec2(cx, cy), 0);
      vec4 extent = texelFetch(u_extent, ivec2(cx, cy), 0);
      for (uint i = cell.x; i < cell.x + cell.y; ++i) {
        vec4 where = texelFetch(u_where, int(i));
        vec3 color = texelFetch(u_color, int(i)).rgb;
        float wt = max(exp(-where.z * where.z * where.w), u_min_wt) * extent.w;
        float wx[B], wy[B];
        for (int j = 0; j < B; ++j) {
          float dx = float(b.x + j) + 0.5 - where.x;
          float dy = float(b.y + j) + 0.5 - where.y;
          wx[j] = abs(dx) < extent.x ? exp(-dx * dx * kernel.x) - kernel.z : 0.0;
          wy[j] = abs(dy) < extent.y ? exp(-dy * dy * kernel.y) - kernel.w : 0.0;
        }
        for (int y = 0; y < B; ++y) {
          if (!(wy[y] > 0.0)) continue;
          for (int x = 0; x < B; ++x) {
            float w = wx[x] * (wy[y] * wt);
            if (wx[x] > 0.0 && w > u_min_weight) {
              sums[y * B + x] += vec4(color * w, w);
              coverage[y * B + x] += vec2(1.0, extent.z);
            }
          }
        }
      }
    }
  }
  for (int y = 0; y < B; ++y) {
    for (int x = 0; x < B; ++x) {
      ivec2 p = b + ivec2(x, y);
      if (p.x < u_size.x && p.y < u_size.y) {
        imageStore(u_sums, p, sums[y * B + x]);
        imageStore(u_coverage, p, vec4(coverage[y * B + x], 0.0, 0.0));
      }
    }
  }
}
)";

// The other way round (--block 0, "rows"): one work group per run of 8 pixels of a row, one
// invocation per pixel, each evaluating every sample within reach at its pixel. The records are
// sorted by pixel in row-major order, so what a run needs from one row of cells is one
// contiguous range. Each lane loads a different record of a batch of 8 and the batch is
// broadcast across the subgroup (GL_ARB_shader_ballot's readInvocationARB; Mesa 22.3 offers
// GL_KHR_shader_subgroup to no GL shader), so no lane loads what another has: the loads that
// cost llvmpipe most are shared, at the price of evaluating each sample at whole runs of
// pixels. Needs subgroups of 8 lanes or more (llvmpipe with AVX2, NVIDIA's 32); a pixel whose
// subgroup is smaller is written -1, which the row reports.
const char* const kRowsExtensions = R"(
#extension GL_ARB_shader_ballot : require
#extension GL_ARB_gpu_shader_int64 : enable
)";
// readInvocationARB's lane must be a constant: the eight evaluations of a batch are written
// out by the macro EVAL, lane j's record at this invocation's pixel.
const char* const kRowsCompute = R"(
layout(local_size_x = 8) in;
#define EVAL(j) {                                                         \
    vec4 w4 = readInvocationARB(where, j);                                \
    vec3 c3 = readInvocationARB(color, j);                                \
    vec4 k4 = readInvocationARB(kernel, j);                               \
    vec4 e4 = readInvocationARB(extent, j);                               \
    float dx = float(p.x) + 0.5 - w4.x, dy = float(p.y) + 0.5 - w4.y;     \
    float wx = abs(dx) < e4.x ? exp(-dx * dx * k4.x) - k4.z : 0.0;        \
    float wy = abs(dy) < e4.y ? exp(-dy * dy * k4.y) - k4.w : 0.0;        \
    float wt = max(exp(-w4.z * w4.z * w4.w), u_min_wt) * e4.w;            \
    float w = wx * wy * wt;                                               \
    if (wx > 0.0 && wy > 0.0 && w > u_min_weight) {                       \
      sums += vec4(c3 * w, w);                                            \
      coverage += vec2(1.0, e4.z);                                        \
    }                                                                     \
  }
void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  int x0 = int(gl_WorkGroupID.x) * 8, y = int(gl_WorkGroupID.y);
  uint lane = gl_SubGroupInvocationARB;
  if (gl_SubGroupSizeARB < 8u) {
    if (p.x < u_size.x) imageStore(u_sums, p, vec4(-1.0));
    return;
  }
  vec4 sums = vec4(0.0);
  vec2 coverage = vec2(0.0);
  int lo_x = max(x0 - REACH, 0), hi_x = min(x0 + 7 + REACH, u_size.x - 1);
  for (int cy = max(y - REACH, 0); cy <= min(y + REACH, u_size.y - 1); ++cy) {
    uint first = texelFetch(u_cells, ivec2(lo_x, cy), 0).x;
    uvec2 last = texelFetch(u_cells, ivec2(hi_x, cy), 0).xy;
    uint end = last.x + last.y;
    for (uint base = first; base < end; base += 8u) {
      uint i = base + lane;
      bool valid = i < end;
      vec4 where = valid ? texelFetch(u_where, int(i)) : vec4(-1e9, -1e9, 0.0, 0.0);
      vec3 color = texelFetch(u_color, int(i)).rgb;
      ivec2 at = clamp(ivec2(where.xy), ivec2(0), u_size - 1);
      vec4 kernel = texelFetch(u_kernel, at, 0);
      vec4 extent = texelFetch(u_extent, at, 0);
      EVAL(0u) EVAL(1u) EVAL(2u) EVAL(3u) EVAL(4u) EVAL(5u) EVAL(6u) EVAL(7u)
    }
  }
  if (p.x < u_size.x) {
    imageStore(u_sums, p, sums);
    imageStore(u_coverage, p, vec4(coverage, 0.0, 0.0));
  }
}
)";

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

struct Row {
  int width = 0, height = 0, reach = 0, block = 0;
  size_t samples = 0;
  double bin = 0, upload = 0, gather = 0;
  double hit_pixels = 0;   // pixels with weight: a check that the kernel ran
  double mean_weight = 0;  // over the pixels: every variant gathers the same sums
};

// One size, reach and block: `repeats` timed passes after one untimed.
Row run(int width, int height, int reach, int block, int spp, int repeats) {
  const size_t n = size_t(spp) * size_t(width) * size_t(height);
  const size_t cells = size_t(width) * size_t(height);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> ux(0.0f, float(width)), uy(0.0f, float(height));
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  // The store as the display holds it: center, age, k_t, color; in arrival order.
  std::vector<float> store(n * 7);
  for (size_t i = 0; i < n; ++i) {
    float* s = &store[7 * i];
    s[0] = ux(rng);
    s[1] = uy(rng);
    s[2] = 0.5f * unit(rng);  // age, seconds
    s[3] = 2.0f;              // k_t
    s[4] = unit(rng);
    s[5] = unit(rng);
    s[6] = unit(rng);
  }
  // Every cell's splat shape: as wide as the reach lets it be.
  const float r = float(reach) + 0.5f, sigma = r / 3.0f, k = 0.5f / (sigma * sigma);
  const float off = std::exp(-r * r * k);
  std::vector<float> kernel(cells * 4), extent(cells * 4);
  const float cell_kernel[4] = {k, k, off, off};
  const float cell_extent[4] = {r, r, 1.0f, 1.0f / (sigma * sigma)};
  for (size_t c = 0; c < cells; ++c) {
    std::copy_n(cell_kernel, 4, &kernel[4 * c]);
    std::copy_n(cell_extent, 4, &extent[4 * c]);
  }

  const bool rows = block == 0;
  const std::string source =
      fmt::format("#version 430 core\n#define B {}\n#define REACH {}\n{}{}{}", block, reach,
                  rows ? kRowsExtensions : "", kGatherInputs, rows ? kRowsCompute : kGatherCompute);
  const GLuint program = afr::compute_program(source.c_str(), "binned gather");
  GLuint cell_tex = afr::make_texture(GL_RG32UI, width, height);
  GLuint kernel_tex = afr::make_texture(GL_RGBA32F, width, height);
  GLuint extent_tex = afr::make_texture(GL_RGBA32F, width, height);
  GLuint sums_tex = afr::make_texture(GL_RGBA32F, width, height);
  GLuint coverage_tex = afr::make_texture(GL_RG32F, width, height);
  glBindTexture(GL_TEXTURE_2D, kernel_tex);
  glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, width, height, GL_RGBA, GL_FLOAT, kernel.data());
  glBindTexture(GL_TEXTURE_2D, extent_tex);
  glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, width, height, GL_RGBA, GL_FLOAT, extent.data());
  GLuint buffers[2] = {0, 0}, buffer_tex[2] = {0, 0};
  glGenBuffers(2, buffers);
  glGenTextures(2, buffer_tex);
  for (int k2 = 0; k2 < 2; ++k2) {
    glBindBuffer(GL_TEXTURE_BUFFER, buffers[k2]);
    glBufferData(GL_TEXTURE_BUFFER, GLsizeiptr(n * 16), nullptr, GL_STREAM_DRAW);
    glBindTexture(GL_TEXTURE_BUFFER, buffer_tex[k2]);
    glTexBuffer(GL_TEXTURE_BUFFER, GL_RGBA32F, buffers[k2]);
  }

  std::vector<uint32_t> cell_of(n), cursor(cells), table(cells * 2);
  std::vector<float> where(n * 4), color(n * 4);
  Row row{width, height, reach, block, n};
  std::vector<double> bins, uploads, gathers;
  for (int rep = 0; rep <= repeats; ++rep) {
    glFinish();
    const auto t0 = Clock::now();
    std::fill(cursor.begin(), cursor.end(), 0u);
    for (size_t i = 0; i < n; ++i) {
      const int x = std::min(int(store[7 * i]), width - 1);
      const int y = std::min(int(store[7 * i + 1]), height - 1);
      cell_of[i] = uint32_t(y) * uint32_t(width) + uint32_t(x);
      ++cursor[cell_of[i]];
    }
    uint32_t at = 0;
    for (size_t c = 0; c < cells; ++c) {
      table[2 * c] = at;
      table[2 * c + 1] = cursor[c];
      at += cursor[c];
      cursor[c] = table[2 * c];
    }
    for (size_t i = 0; i < n; ++i) {
      const uint32_t slot = cursor[cell_of[i]]++;
      std::copy_n(&store[7 * i], 4, &where[4 * slot]);
      std::copy_n(&store[7 * i + 4], 3, &color[4 * slot]);
    }
    const double bin_ms = ms_since(t0);

    const auto t1 = Clock::now();
    glBindTexture(GL_TEXTURE_2D, cell_tex);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, width, height, GL_RG_INTEGER, GL_UNSIGNED_INT,
                    table.data());
    glBindBuffer(GL_TEXTURE_BUFFER, buffers[0]);
    glBufferSubData(GL_TEXTURE_BUFFER, 0, GLsizeiptr(n * 16), where.data());
    glBindBuffer(GL_TEXTURE_BUFFER, buffers[1]);
    glBufferSubData(GL_TEXTURE_BUFFER, 0, GLsizeiptr(n * 16), color.data());
    glFinish();
    const double upload_ms = ms_since(t1);

    const auto t2 = Clock::now();
    glUseProgram(program);
    const GLuint units[5] = {cell_tex, kernel_tex, extent_tex, buffer_tex[0], buffer_tex[1]};
    const char* names[5] = {"u_cells", "u_kernel", "u_extent", "u_where", "u_color"};
    for (int u = 0; u < 5; ++u) {
      glActiveTexture(GL_TEXTURE0 + GLenum(u));
      glBindTexture(u < 3 ? GL_TEXTURE_2D : GL_TEXTURE_BUFFER, units[u]);
      glUniform1i(glGetUniformLocation(program, names[u]), u);
    }
    glUniform2i(glGetUniformLocation(program, "u_size"), width, height);
    glUniform1f(glGetUniformLocation(program, "u_min_wt"), 1e-12f);
    glUniform1f(glGetUniformLocation(program, "u_min_weight"), 1e-30f);
    glBindImageTexture(0, sums_tex, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
    glBindImageTexture(1, coverage_tex, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RG32F);
    if (rows) {
      glDispatchCompute(GLuint((width + 7) / 8), GLuint(height), 1);
    } else {
      const int group = 8 * block;
      glDispatchCompute(GLuint((width + group - 1) / group), GLuint((height + group - 1) / group),
                        1);
    }
    glMemoryBarrier(GL_ALL_BARRIER_BITS);
    glFinish();
    const double gather_ms = ms_since(t2);
    if (rep > 0) {  // the first pass compiles and allocates
      bins.push_back(bin_ms);
      uploads.push_back(upload_ms);
      gathers.push_back(gather_ms);
    }
  }
  std::vector<float> sums(cells * 4);
  glBindTexture(GL_TEXTURE_2D, sums_tex);
  glGetTexImage(GL_TEXTURE_2D, 0, GL_RGBA, GL_FLOAT, sums.data());
  size_t hit = 0, small_subgroups = 0;
  for (size_t c = 0; c < cells; ++c) {
    hit += sums[4 * c + 3] > 0.0f ? 1 : 0;
    row.mean_weight += double(sums[4 * c + 3]) / double(cells);
    small_subgroups += sums[4 * c + 3] < 0.0f ? 1 : 0;
  }
  if (small_subgroups > 0) {
    throw afr::Error("the rows gather needs subgroups of 8 lanes or more; this device's are fewer");
  }
  row.hit_pixels = double(hit) / double(cells);
  row.bin = median(bins);
  row.upload = median(uploads);
  row.gather = median(gathers);

  GLuint textures[5] = {cell_tex, kernel_tex, extent_tex, sums_tex, coverage_tex};
  glDeleteTextures(5, textures);
  glDeleteTextures(2, buffer_tex);
  glDeleteBuffers(2, buffers);
  glDeleteProgram(program);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "afr-bench-binned-gather: a floor under a splat pass binned on the CPU and "
      "gathered on the GL device"};
  std::vector<int> sizes{256, 512};
  std::vector<int> reaches{2, 3};
  std::vector<int> blocks{1, 2, 4};
  int repeats = 7, gpu = -1, spp = 4;
  std::string log_level = "warn";
  app.add_option("--sizes", sizes, "square outputs, comma separated")
      ->delimiter(',')
      ->check(CLI::Range(16, 4096));
  app.add_option("--reach", reaches,
                 "cells visited on each side of a block (the widest splat: reach + 0.5 px), "
                 "comma separated")
      ->delimiter(',')
      ->check(CLI::Range(1, 8));
  app.add_option("--block", blocks,
                 "pixels a side of one invocation's block, comma separated (0: rows, one "
                 "invocation per pixel sharing the records across the subgroup)")
      ->delimiter(',')
      ->check(CLI::Range(0, 8));
  app.add_option("--repeats", repeats, "timed passes per row")->check(CLI::Range(1, 1000));
  app.add_option("--spp", spp, "samples per pixel: N = spp x pixels")->check(CLI::Range(1, 64));
  app.add_option("--gpu", gpu, "EGL device (-1: hardware first)")->check(CLI::Range(-1, 63));
  app.add_option("--log", log_level, "log level");
  CLI11_PARSE(app, argc, argv);
  try {
    afr::init_logging(log_level);
    std::string error;
    auto context = afr::EglContext::create_headless(afr::HeadlessGlOptions{gpu, false}, &error);
    if (!context) throw afr::Error("no OpenGL context: " + error);
    fmt::print(
        "Binned gather (a floor: CPU counting sort by pixel on one thread, upload, GL gather "
        "over the cells within reach), N = {} x pixels, median of {} passes\n",
        spp, repeats);
    fmt::print("OpenGL: {} on {}, {}\n\n", context->renderer(), context->device(),
               context->version());
    fmt::print(
        "| resolution | N | reach | block | bin ms | upload ms | gather ms | sum ms | "
        "pixels reached | mean weight |\n");
    fmt::print("|---|---|---|---|---|---|---|---|---|---|\n");
    for (const int size : sizes) {
      for (const int reach : reaches) {
        for (const int block : blocks) {
          const Row r = run(size, size, reach, block, spp, repeats);
          fmt::print(
              "| {}x{} | {} | {} | {} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {:.3f} | {:.5f} |\n",
              r.width, r.height, r.samples, r.reach,
              r.block == 0 ? std::string("rows") : std::to_string(r.block), r.bin, r.upload,
              r.gather, r.bin + r.upload + r.gather, r.hit_pixels, r.mean_weight);
          std::fflush(stdout);
        }
      }
    }
  } catch (const std::exception& e) {
    fmt::print(stderr, "afr-bench-binned-gather: error: {}\n", e.what());
    return 1;
  }
  return 0;
}
