#include <afr/display/gl_reconstructor.h>

#include <afr/common/check.h>
#include <afr/common/error.h>
#include <afr/common/log.h>
#include <afr/display/hole_fill.h>
#include <afr/display/reprojection.h>

#include "gl_program.h"
#include "gl_shaders.h"
#include "parallel_copy.h"

#include <epoxy/gl.h>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstddef>

namespace afr {

namespace {

static_assert(sizeof(TileFilter) == 4 * sizeof(float), "TileFilter is one RGBA32F texel");
static_assert(offsetof(StoredSample, time) == 0 && offsetof(StoredSample, x) == 8 &&
              offsetof(StoredSample, color) == 16 && offsetof(StoredSample, flags) == 28 &&
              offsetof(StoredSample, position) == 32 && offsetof(StoredSample, velocity) == 44);

constexpr int kGroup = 16;  // compute work group side

void check_gl(const char* where) {
  const GLenum e = glGetError();
  if (e != GL_NO_ERROR) throw Error(fmt::format("OpenGL error 0x{:x} in {}", e, where));
}

// A buffer only the GPU reads and writes (copies, clears and shaders; never a CPU map):
// immutable storage without access flags, which drivers keep in the device's own memory.
GLuint gpu_buffer(size_t bytes) {
  GLuint b = 0;
  glGenBuffers(1, &b);
  glBindBuffer(GL_COPY_WRITE_BUFFER, b);
  glBufferStorage(GL_COPY_WRITE_BUFFER, GLsizeiptr(std::max<size_t>(bytes, 4)), nullptr, 0);
  glBindBuffer(GL_COPY_WRITE_BUFFER, 0);
  return b;
}

// Uniform setters by name (a few dozen lookups per image: negligible next to the splats).
struct Uniforms {
  GLuint program;
  GLint at(const char* name) const { return glGetUniformLocation(program, name); }
  void set(const char* name, int v) const { glUniform1i(at(name), v); }
  void set(const char* name, float v) const { glUniform1f(at(name), v); }
  void set(const char* name, double v) const { glUniform1d(at(name), v); }
  void set(const char* name, const glm::vec2& v) const { glUniform2f(at(name), v.x, v.y); }
  void set(const char* name, const glm::vec3& v) const { glUniform3f(at(name), v.x, v.y, v.z); }
  void set(const char* name, const glm::ivec2& v) const { glUniform2i(at(name), v.x, v.y); }
};

constexpr int kInFlight = 3;  // images the GPU may still be drawing when the next begins
constexpr GLsizeiptr kStatusStride = 256;  // >= GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT
// Status words of an image (kPrepareCompute, kScanCompute, kNormaliseCompute).
enum StatusWord { kHoles = 0, kEmpty = 1, kNonfinite = 2, kListWanted = 4 };
enum Pass { kUpload = 0, kBin = 1, kSplatPass = 2, kFill = 3, kReadback = 4, kPasses = 5 };

// Work groups for `n` invocations of 256, as x * y groups within every driver's 65535 a side.
std::array<GLuint, 2> groups_for(size_t n) {
  const size_t groups = std::max<size_t>(1, (n + 255) / 256);
  const size_t x = std::min<size_t>(groups, 65535);
  return {GLuint(x), GLuint((groups + x - 1) / x)};
}

// A buffer texture over a new buffer of `bytes` (filled per image with glBufferData): the
// per-tile tables the splat's preparation fetches by tile index.
void make_buffer_texture(GLenum format, size_t bytes, GLuint* buffer, GLuint* texture) {
  glGenBuffers(1, buffer);
  glBindBuffer(GL_TEXTURE_BUFFER, *buffer);
  glBufferData(GL_TEXTURE_BUFFER, GLsizeiptr(bytes), nullptr, GL_STREAM_DRAW);
  glGenTextures(1, texture);
  glBindTexture(GL_TEXTURE_BUFFER, *texture);
  glTexBuffer(GL_TEXTURE_BUFFER, format, *buffer);
}

}  // namespace

GlSplat parse_gl_splat(std::string_view text) {
  if (text == "auto") return GlSplat::kAuto;
  if (text == "gather") return GlSplat::kGather;
  if (text == "raster") return GlSplat::kRaster;
  throw Error("--gl-splat '" + std::string(text) + "': expected auto, gather or raster");
}

const char* gl_splat_name(GlSplat splat) {
  switch (splat) {
    case GlSplat::kAuto:
      return "auto";
    case GlSplat::kGather:
      return "gather";
    case GlSplat::kRaster:
      return "raster";
  }
  return "?";
}

GlProbe parse_gl_probe(std::string_view text) {
  if (text == "none") return GlProbe::kNone;
  if (text == "culled") return GlProbe::kCulled;
  if (text == "flat") return GlProbe::kFlat;
  if (text == "visit") return GlProbe::kVisit;
  if (text == "dots") return GlProbe::kDots;
  throw Error("GL probe '" + std::string(text) + "': expected none, culled, flat, visit or dots");
}

const char* gl_probe_name(GlProbe probe) {
  switch (probe) {
    case GlProbe::kNone:
      return "none";
    case GlProbe::kCulled:
      return "culled";
    case GlProbe::kFlat:
      return "flat";
    case GlProbe::kVisit:
      return "visit";
    case GlProbe::kDots:
      return "dots";
  }
  return "?";
}

bool gl_probe_fits(GlProbe probe, GlSplat splat) {
  if (probe == GlProbe::kNone) return true;
  return (probe == GlProbe::kVisit) == (splat == GlSplat::kGather);
}

struct GlReconstructor::Impl {
  // Samples: the store's ring, slot for slot.
  GLuint vao = 0;
  GLuint samples = 0;
  GLuint empty_vao = 0;
  uint64_t seen = 0;
  size_t stored = 0;
  std::vector<StoredSample> staging;
  // The staging ring: kInFlight segments of a persistently mapped buffer, each reused once
  // the GPU's copy out of it (fenced) is done.
  GLuint upload = 0;
  uint8_t* upload_map = nullptr;
  size_t segment_bytes = 0;
  std::array<GLsync, kInFlight> segment_fence{};
  int next_segment = 0;

  // Per image in flight: a fence at its end, its timer queries and its status words (a
  // persistently mapped buffer, kStatusStride bytes an image).
  struct InFlight {
    GLsync fence = nullptr;
    uint64_t image = 0;
    std::array<GLuint, kPasses> queries{};
    std::array<bool, kPasses> timed{};
    std::array<GLuint, 2> stamps{};  // GL_TIMESTAMP at its start and end
    // GlReconstructorOptions::sync_passes: each pass's wall time, waited for on the CPU.
    std::array<double, kPasses> waited_ms{};
    bool waited = false;
  };
  std::array<InFlight, kInFlight> flight;
  GLuint status = 0;
  uint32_t* status_map = nullptr;
  uint64_t images = 0;
  GpuTimes latest_gpu;
  std::array<uint64_t, 3> latest_counts{};  // holes, empty, non-finite of the latest finished

  // The gather's buffers: prepared splats (3 vec4 each at their samples' ring slots) and
  // their first and last tiles, the per-tile counts, starts and cursors, and the tiles' lists
  // of splat indices.
  GLuint prepare = 0, scan = 0, scatter = 0, gather = 0;
  GLuint splats = 0, splat_tiles = 0, tile_count = 0, tile_start = 0, tile_cursor = 0, lists = 0;
  size_t list_capacity = 0;
  int tiles_x = 0, tiles_y = 0;
  size_t chunk_slots = 1;  // ring slots a chunk
  int chunks = 1;          // chunks of the ring: each has tiles_x * tiles_y counts and lists
  // Read back: the output packed by a compute pass into a persistently mapped buffer.
  GLuint pack = 0, readback = 0;
  void* readback_map = nullptr;
  // The tile index map, built on the GPU from the tiles' pixel spans (TileField::spans).
  GLuint index_map = 0, tile_spans = 0;
  size_t readback_bytes = 0;
  // A CPU copy of the ring, kept once stored_samples() asked for it.
  bool mirrored = false;
  std::vector<StoredSample> mirror;

  GLuint splat = 0, newest = 0, pyramid = 0, normalise = 0, blit = 0;

  // Tile field.
  GLuint tile_filters_buffer = 0, tile_filters = 0;
  GLuint tile_caps_buffer = 0, tile_caps = 0;  // FrameSetup::radius_caps, one R32F a tile
  // Per grid (the viewport with its margin: accumulation, coverage, tile index, pyramid) and
  // per output (the viewport's pixels).
  int width = 0, height = 0;          // grid
  int out_width = 0, out_height = 0;  // output
  int view_x = 0, view_y = 0;         // the output's first pixel in the grid
  PixelGrid grid;
  std::vector<PyramidLevel> levels;
  GLuint tile_index = 0, accum = 0, atlas = 0, output = 0, depth = 0;
  std::array<GLuint, 2> coverage{};
  std::array<GLuint, 2> fbo{};  // accum + coverage[i] + depth
  int current = 0;              // coverage[current] is written by the next image
  bool have_coverage = false;   // coverage[1 - current] holds the previous image's map
  GLint max_viewport[2] = {0, 0};
  GLint max_texture = 0;
  size_t max_block_bytes = 0;  // GL_MAX_SHADER_STORAGE_BLOCK_SIZE

  void release_sized() {
    glDeleteFramebuffers(2, fbo.data());
    glDeleteTextures(2, coverage.data());
    for (GLuint* t : {&tile_index, &accum, &atlas, &output}) glDeleteTextures(1, t);
    glDeleteRenderbuffers(1, &depth);
    for (GLuint* b : {&tile_count, &tile_start, &tile_cursor}) glDeleteBuffers(1, b);
    tile_count = tile_start = tile_cursor = 0;
    tiles_x = tiles_y = 0;
    fbo = {};
    coverage = {};
    tile_index = accum = atlas = output = depth = 0;
    width = height = out_width = out_height = 0;
  }

  // Returns true when the textures were made anew.
  // `tile`: the gather's tile side (GlReconstructorOptions::tile).
  bool resize(const FrameSetup& setup, int tile) {
    const int w = setup.grid.width, h = setup.grid.height;
    view_x = setup.view_x;
    view_y = setup.view_y;
    if (!(setup.grid == grid)) {
      grid = setup.grid;
      have_coverage = false;  // the previous coverage lies elsewhere
    }
    if (w == width && h == height && setup.width == out_width && setup.height == out_height) {
      return false;
    }
    release_sized();
    width = w;
    height = h;
    out_width = setup.width;
    out_height = setup.height;
    levels = pyramid_layout(w, h);
    tile_index = make_texture(GL_R32UI, w, h);
    accum = make_texture(GL_RGBA32F, w, h);
    output = make_texture(GL_RGBA32F, out_width, out_height);
    atlas = make_texture(GL_RGBA32F, std::max(1, (w + 1) / 2), pyramid_atlas_height(levels));
    for (GLuint& c : coverage) c = make_texture(GL_RG32F, w, h);
    glGenRenderbuffers(1, &depth);
    glBindRenderbuffer(GL_RENDERBUFFER, depth);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, w, h);
    glGenFramebuffers(2, fbo.data());
    for (int i = 0; i < 2; ++i) {
      glBindFramebuffer(GL_FRAMEBUFFER, fbo[size_t(i)]);
      glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, accum, 0);
      glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_TEXTURE_2D,
                             coverage[size_t(i)], 0);
      glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
      const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
      if (status != GL_FRAMEBUFFER_COMPLETE) {
        throw Error(fmt::format("OpenGL: accumulation framebuffer incomplete (0x{:x})", status));
      }
    }
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    tiles_x = (w + tile - 1) / tile;
    tiles_y = (h + tile - 1) / tile;
    const GLsizeiptr tile_bytes =
        GLsizeiptr(size_t(chunks) * size_t(tiles_x) * size_t(tiles_y) * sizeof(uint32_t));
    for (GLuint* b : {&tile_count, &tile_start, &tile_cursor}) *b = gpu_buffer(size_t(tile_bytes));
    current = 0;
    have_coverage = false;
    check_gl("resizing the reconstruction targets");
    return true;
  }

  // Waits for a fence (and deletes it); the GPU is flushed first so that it can signal.
  static void wait(GLsync* fence) {
    if (*fence == nullptr) return;
    while (glClientWaitSync(*fence, GL_SYNC_FLUSH_COMMANDS_BIT, 1000000000) == GL_TIMEOUT_EXPIRED) {
    }
    glDeleteSync(*fence);
    *fence = nullptr;
  }

  static bool signalled(GLsync fence) {
    return fence != nullptr && glClientWaitSync(fence, 0, 0) != GL_TIMEOUT_EXPIRED;
  }

  // A finished image's timer queries and counts become the latest; its slot is free again.
  void harvest(InFlight& f) {
    if (f.fence == nullptr) return;
    wait(&f.fence);
    GpuTimes t;
    t.image = f.image;
    double* pass_ms[kPasses] = {&t.upload, &t.bin, &t.splat, &t.fill, &t.readback};
    for (int p = 0; p < kPasses; ++p) {
      if (!f.timed[size_t(p)]) continue;
      t.timed = true;
      GLuint64 ns = 0;
      glGetQueryObjectui64v(f.queries[size_t(p)], GL_QUERY_RESULT, &ns);
      *pass_ms[p] = double(ns) * 1e-6;
      f.timed[size_t(p)] = false;
    }
    if (f.waited) {  // no queries: the passes were waited for one by one
      t.timed = true;
      for (int p = 0; p < kPasses; ++p) *pass_ms[p] = f.waited_ms[size_t(p)];
      t.image_ms = t.upload + t.bin + t.splat + t.fill + t.readback;
      f.waited_ms = {};
      f.waited = false;
    } else if (t.timed) {
      GLuint64 start = 0, end = 0;
      glGetQueryObjectui64v(f.stamps[0], GL_QUERY_RESULT, &start);
      glGetQueryObjectui64v(f.stamps[1], GL_QUERY_RESULT, &end);
      t.image_ms = end > start ? double(end - start) * 1e-6 : 0.0;
    }
    const uint32_t* w = status_words(f);
    if (f.image >= latest_gpu.image) {
      latest_gpu = t;
      latest_counts = {w[kHoles], w[kEmpty], w[kNonfinite]};
    }
    // An image whose tiles wanted more list entries than there were lost splats; the next
    // image gets room for this one's need and half again.
    if (w[kListWanted] > list_capacity) grow_lists(size_t(w[kListWanted]) * 3 / 2);
  }

  // The latest finished image's pixel counts and GPU times into `frame`.
  void report(FrameStats* frame) const {
    frame->hole_pixels = latest_counts[0];
    frame->empty_pixels = latest_counts[1];
    frame->nonfinite_pixels = latest_counts[2];
    frame->gpu = latest_gpu;
  }

  // Harvests every image the GPU has finished, without waiting.
  void harvest_finished() {
    for (InFlight& f : flight) {
      if (signalled(f.fence)) harvest(f);
    }
  }

  uint32_t* status_words(const InFlight& f) {
    return status_map + size_t(&f - flight.data()) * (kStatusStride / sizeof(uint32_t));
  }

  void grow_lists(size_t entries) {
    if (entries <= list_capacity) return;
    // The lists are one shader storage block: beyond the driver's largest, they are clamped
    // (and the splats that do not fit are lost, counted in the status words).
    const size_t most = std::min<size_t>(max_block_bytes / sizeof(uint32_t), UINT32_MAX);
    if (entries > most && list_capacity < most) {
      spdlog::warn(
          "GL gather: the tiles' lists want {} entries; the driver's largest storage block "
          "holds {}: splats beyond it are lost (a smaller --gl-tile bins fewer, a larger "
          "one more)",
          entries, most);
    }
    list_capacity = std::min(entries, most);
    glDeleteBuffers(1, &lists);
    lists = gpu_buffer(list_capacity * sizeof(uint32_t));
  }

  // The new samples into their ring slots: through the staging ring, a segment at a time.
  void upload_samples(const SampleStore::Delta& delta, size_t capacity) {
    RingRun runs[2];
    const int k = ring_runs(delta.first, delta.end, capacity, runs);
    const size_t per_segment = segment_bytes / sizeof(StoredSample);
    for (int r = 0; r < k; ++r) {
      for (size_t done = 0; done < runs[r].count; done += per_segment) {
        const size_t n = std::min(per_segment, runs[r].count - done);
        const int seg = next_segment;
        next_segment = (next_segment + 1) % kInFlight;
        wait(&segment_fence[size_t(seg)]);
        const size_t at = size_t(seg) * segment_bytes;
        parallel_copy(upload_map + at, staging.data() + runs[r].offset + done,
                      n * sizeof(StoredSample));
        glBindBuffer(GL_COPY_READ_BUFFER, upload);
        glBindBuffer(GL_COPY_WRITE_BUFFER, samples);
        glCopyBufferSubData(GL_COPY_READ_BUFFER, GL_COPY_WRITE_BUFFER, GLintptr(at),
                            GLintptr((runs[r].slot + done) * sizeof(StoredSample)),
                            GLsizeiptr(n * sizeof(StoredSample)));
        segment_fence[size_t(seg)] = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
      }
      if (mirrored) {
        std::copy_n(staging.begin() + ptrdiff_t(runs[r].offset), runs[r].count,
                    mirror.begin() + ptrdiff_t(runs[r].slot));
      }
    }
  }

  // The output's part of a grid-sized texture with `channels` floats per pixel.
  void read_cropped(GLuint texture, GLenum format, int channels, float* out) const {
    std::vector<float> all(size_t(width) * size_t(height) * size_t(channels));
    glBindTexture(GL_TEXTURE_2D, texture);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glGetTexImage(GL_TEXTURE_2D, 0, format, GL_FLOAT, all.data());
    const size_t row = size_t(out_width) * size_t(channels);
    for (int v = 0; v < out_height; ++v) {
      std::copy_n(all.data() + (size_t(v + view_y) * size_t(width) + size_t(view_x)) * channels,
                  row, out + size_t(v) * row);
    }
  }
};

GlReconstructor::GlReconstructor(const ReconstructorConfig& config,
                                 std::shared_ptr<GlContext> context, GlReconstructorOptions options)
    : Reconstructor(config),
      context_(std::move(context)),
      options_(options),
      impl_(std::make_unique<Impl>()) {
  AFR_CHECK(context_ != nullptr);
  if (config.splat.thresholds) {
    throw Error(
        "the OpenGL backend has only the continuous coverage rule (the thresholds rule "
        "is the CPU backend's baseline for afr-eval)");
  }
  context_->make_current();
  if (options_.splat == GlSplat::kAuto) {
    options_.splat = context_->software() ? GlSplat::kRaster : GlSplat::kGather;
  }
  if (epoxy_gl_version() < 44 && !epoxy_has_gl_extension("GL_ARB_buffer_storage")) {
    throw Error(
        fmt::format("OpenGL {} has no persistent buffer mappings (4.4 or "
                    "GL_ARB_buffer_storage)",
                    context_->version()));
  }
  if (epoxy_gl_version() < 44 && !epoxy_has_gl_extension("GL_ARB_clear_texture")) {
    throw Error(fmt::format("OpenGL {} cannot clear textures (4.4 or GL_ARB_clear_texture)",
                            context_->version()));
  }
  if (!gl_probe_fits(options_.probe, options_.splat)) {
    throw Error(fmt::format("GL reconstructor: probe '{}' is not a probe of the {} splat pass",
                            gl_probe_name(options_.probe), gl_splat_name(options_.splat)));
  }
  if (options_.tile != 4 && options_.tile != 8 && options_.tile != 16) {
    throw Error(fmt::format("GL reconstructor: gather tile {} is not 4, 8 or 16", options_.tile));
  }
  Impl& m = *impl_;
  GLint64 max_block = 0;
  glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &max_block);
  m.max_block_bytes = size_t(std::max<GLint64>(max_block, 0));
  // The ring and the splats are each one storage block the compute passes index.
  const size_t ring_bytes = store_.capacity() * sizeof(StoredSample);
  if (options_.splat == GlSplat::kGather && ring_bytes > m.max_block_bytes) {
    throw Error(fmt::format(
        "GL gather: a store of {} samples ({} MiB) exceeds this driver's largest shader storage "
        "block ({} MiB); store fewer samples (--capacity) or use --gl-splat raster",
        store_.capacity(), ring_bytes >> 20, m.max_block_bytes >> 20));
  }
  // AFR_PROBE: GlProbe's value, which the splat shaders test (0: the real passes).
  const std::string probe = fmt::format("#define AFR_PROBE {}\n", int(options_.probe));
  m.splat = graphics_program(
      gl_shaders::splat_program_source(gl_shaders::kSplatVertex, probe).c_str(),
      (std::string("#version 430 core\n") + probe + gl_shaders::kSplatFragment).c_str(), "splat");
  m.newest = graphics_program(gl_shaders::kNewestVertex, gl_shaders::kNewestFragment, "newest");
  m.pyramid = compute_program(gl_shaders::kPyramidCompute, "pyramid");
  m.normalise = compute_program(gl_shaders::kNormaliseCompute, "normalise");
  m.blit = graphics_program(gl_shaders::kBlitVertex, gl_shaders::kBlitFragment, "blit");
  m.pack = compute_program(gl_shaders::kPackCompute, "pack");
  m.index_map = compute_program(gl_shaders::kIndexMapCompute, "index map");
  glGenBuffers(1, &m.tile_spans);
  // The map is built here from the tiles' spans: the field need not fill one on the CPU.
  field_.set_index_map(false);
  if (options_.splat == GlSplat::kGather) {
    m.prepare = compute_program(
        gl_shaders::splat_program_source(gl_shaders::kPrepareCompute).c_str(), "prepare");
    m.scan = compute_program(gl_shaders::kScanCompute, "scan");
    m.scatter = compute_program(gl_shaders::kScatterCompute, "scatter");
    // A tile's cells are 8 x 4 pixels (a warp of invocations), or the whole 4 x 4 tile.
    const std::string gather_source = fmt::format(
        "#version 430 core\n#define TILE {}\n#define GROUP {}\n#define CELL_W {}\n#define CELL_H "
        "{}\n{}{}{}",
        options_.tile, options_.tile * options_.tile, std::min(options_.tile, 8),
        std::min(options_.tile, 4), probe, gl_shaders::kPixelBox, gl_shaders::kGatherCompute);
    m.gather = compute_program(gather_source.c_str(), "gather");
    constexpr size_t kSplatBytes = 3 * sizeof(glm::vec4);
    m.splats = gpu_buffer(store_.capacity() * kSplatBytes);
    m.chunk_slots =
        options_.chunk_bytes == 0
            ? store_.capacity()
            : std::clamp<size_t>(options_.chunk_bytes / kSplatBytes, 1, store_.capacity());
    m.chunks = int((store_.capacity() + m.chunk_slots - 1) / m.chunk_slots);
    m.splat_tiles = gpu_buffer(store_.capacity() * sizeof(glm::uvec2));
    // Splats reach about two tiles each at the filter's usual sizes; more grows the lists.
    m.grow_lists(4 * store_.capacity());
  }

  // The staging ring: room for 1/30 s of a store that turns over once a second, 1-64 MiB a
  // segment; a larger delta (the first image) goes through in several segments.
  m.segment_bytes = std::clamp<size_t>(store_.capacity() * sizeof(StoredSample) / 30,
                                       size_t(1) << 20, size_t(64) << 20);
  m.segment_bytes -= m.segment_bytes % sizeof(StoredSample);
  const GLbitfield write_flags = GL_MAP_WRITE_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
  glGenBuffers(1, &m.upload);
  glBindBuffer(GL_COPY_READ_BUFFER, m.upload);
  glBufferStorage(GL_COPY_READ_BUFFER, GLsizeiptr(kInFlight * m.segment_bytes), nullptr,
                  write_flags);
  m.upload_map = static_cast<uint8_t*>(glMapBufferRange(
      GL_COPY_READ_BUFFER, 0, GLsizeiptr(kInFlight * m.segment_bytes), write_flags));
  const GLbitfield status_flags =
      GL_MAP_READ_BIT | GL_MAP_WRITE_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
  glGenBuffers(1, &m.status);
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, m.status);
  glBufferStorage(GL_SHADER_STORAGE_BUFFER, kInFlight * kStatusStride, nullptr, status_flags);
  m.status_map = static_cast<uint32_t*>(
      glMapBufferRange(GL_SHADER_STORAGE_BUFFER, 0, kInFlight * kStatusStride, status_flags));
  if (m.upload_map == nullptr || m.status_map == nullptr) {
    throw Error("OpenGL: cannot map the staging or status buffers persistently");
  }
  for (Impl::InFlight& f : m.flight) {
    glGenQueries(kPasses, f.queries.data());
    glGenQueries(2, f.stamps.data());
  }

  glGenVertexArrays(1, &m.vao);
  glGenVertexArrays(1, &m.empty_vao);
  m.samples = gpu_buffer(ring_bytes);
  glBindVertexArray(m.vao);
  glBindBuffer(GL_ARRAY_BUFFER, m.samples);
  const GLsizei stride = sizeof(StoredSample);
  const auto at = [](size_t offset) { return reinterpret_cast<const void*>(offset); };
  glVertexAttribLPointer(0, 1, GL_DOUBLE, stride, at(offsetof(StoredSample, time)));
  glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, stride, at(offsetof(StoredSample, x)));
  glVertexAttribPointer(2, 3, GL_FLOAT, GL_FALSE, stride, at(offsetof(StoredSample, color)));
  glVertexAttribIPointer(3, 1, GL_UNSIGNED_INT, stride, at(offsetof(StoredSample, flags)));
  glVertexAttribPointer(4, 3, GL_FLOAT, GL_FALSE, stride, at(offsetof(StoredSample, position)));
  glVertexAttribPointer(5, 3, GL_FLOAT, GL_FALSE, stride, at(offsetof(StoredSample, velocity)));
  for (GLuint i = 0; i < 6; ++i) glEnableVertexAttribArray(i);
  glBindVertexArray(0);

  make_buffer_texture(GL_RGBA32F, sizeof(TileFilter), &m.tile_filters_buffer, &m.tile_filters);
  make_buffer_texture(GL_R32F, sizeof(float), &m.tile_caps_buffer, &m.tile_caps);

  glGetIntegerv(GL_MAX_VIEWPORT_DIMS, m.max_viewport);
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &m.max_texture);
  check_gl("creating the GL reconstructor");
}

GlReconstructor::~GlReconstructor() {
  context_->make_current();
  Impl& m = *impl_;
  m.release_sized();
  for (Impl::InFlight& f : m.flight) {
    if (f.fence != nullptr) glDeleteSync(f.fence);
    glDeleteQueries(kPasses, f.queries.data());
    glDeleteQueries(2, f.stamps.data());
  }
  for (GLsync& f : m.segment_fence) {
    if (f != nullptr) glDeleteSync(f);
  }
  for (GLuint p : {m.splat, m.newest, m.pyramid, m.normalise, m.blit, m.pack, m.prepare, m.scan,
                   m.scatter, m.gather, m.index_map}) {
    glDeleteProgram(p);
  }
  for (GLuint* b : {&m.upload, &m.status, &m.splats, &m.splat_tiles, &m.lists, &m.readback}) {
    glDeleteBuffers(1, b);
  }
  glDeleteVertexArrays(1, &m.vao);
  glDeleteVertexArrays(1, &m.empty_vao);
  glDeleteBuffers(1, &m.samples);
  glDeleteBuffers(1, &m.tile_filters_buffer);
  glDeleteBuffers(1, &m.tile_caps_buffer);
  glDeleteBuffers(1, &m.tile_spans);
  glDeleteTextures(1, &m.tile_filters);
  glDeleteTextures(1, &m.tile_caps);
}

uint32_t GlReconstructor::output_texture() const { return impl_->output; }

size_t GlReconstructor::gather_list_capacity() const { return impl_->list_capacity; }

void GlReconstructor::do_reconstruct(const Camera& camera, double time, int width, int height,
                                     Image* out) {
  context_->make_current();
  Impl& m = *impl_;
  // The call's phases (FrameStats::call): each lap() returns the milliseconds since the last.
  CallTimes call;
  auto lap_start = std::chrono::steady_clock::now();
  const auto lap = [&lap_start] {
    const auto now = std::chrono::steady_clock::now();
    const double ms = std::chrono::duration<double, std::milli>(now - lap_start).count();
    lap_start = now;
    return ms;
  };

  // ---- This image's slot: the one kInFlight images back must be done (at most kInFlight in
  // flight); whatever else the GPU has finished reports its times and counts.
  Impl::InFlight& f = m.flight[size_t(m.images % kInFlight)];
  m.harvest(f);
  m.harvest_finished();
  f.image = ++m.images;
  uint32_t* status = m.status_words(f);
  std::fill_n(status, kStatusStride / sizeof(uint32_t), 0u);
  const GLintptr status_at = GLintptr(size_t(&f - m.flight.data()) * kStatusStride);
  // llvmpipe runs the work when it is waited for, so its GL_TIME_ELAPSED measures nothing.
  const bool queries = !context_->software();
  const bool wait_passes = !queries && options_.sync_passes;
  const auto timed = [&](Pass pass, auto&& body) {
    if (queries) glBeginQuery(GL_TIME_ELAPSED, f.queries[size_t(pass)]);
    std::chrono::steady_clock::time_point start;
    if (wait_passes) {
      glFinish();
      start = std::chrono::steady_clock::now();
    }
    body();
    if (queries) glEndQuery(GL_TIME_ELAPSED);
    if (wait_passes) {
      glFinish();
      f.waited_ms[size_t(pass)] +=
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
              .count();
      f.waited = true;
    }
    f.timed[size_t(pass)] = queries;
  };
  // Recorded once everything before it is done: the image's start (its end, in draw()).
  if (queries) glQueryCounter(f.stamps[0], GL_TIMESTAMP);

  call.wait = lap();
  // ---- Only the new samples go to the GPU, into their ring slots.
  const SampleStore::Delta delta = store_.copy_since(m.seen, &m.staging);
  call.copy = lap();
  FrameSetup setup;
  // (The upload runs while the base class counts the new samples on another thread.)
  prepare_frame(time, width, height, delta, m.staging, &setup, [&] {
    const auto upload_start = std::chrono::steady_clock::now();
    timed(kUpload, [&] { m.upload_samples(delta, store_.capacity()); });
    call.upload =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - upload_start)
            .count();
  });
  call.prepare = lap() - call.upload;
  m.seen = delta.end;
  m.stored = delta.stored;
  // From here on the image is the grid: the viewport with its margin. The output is its
  // viewport part (the whole grid when the viewport is the whole image).
  const int out_width = width, out_height = height;
  width = setup.grid.width;
  height = setup.grid.height;
  // The splat pass draws into the grid grown by a guard band on every side.
  const int g = splat_guard_band(config_.splat);
  if (width + 2 * g > m.max_viewport[0] || height + 2 * g > m.max_viewport[1] ||
      width > m.max_texture || height > m.max_texture) {
    throw Error(
        fmt::format("GL reconstructor: output {}x{} with its margin ({}x{}) plus the {} pixel "
                    "guard band exceeds this driver's largest viewport {}x{} or texture {}",
                    out_width, out_height, width, height, g, m.max_viewport[0], m.max_viewport[1],
                    m.max_texture));
  }
  const bool resized = m.resize(setup, options_.tile);
  if (setup.field_changed || resized) {
    // The tile index map from the tiles' spans: cleared to "no tile", then each span's pixels
    // take the highest index that covers them (TileField::index_map's rule).
    const std::vector<PixelRect>& spans = field_.spans();
    static_assert(sizeof(PixelRect) == 4 * sizeof(int32_t));
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, m.tile_spans);
    glBufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(spans.size() * sizeof(PixelRect)),
                 spans.data(), GL_STREAM_DRAW);
    const GLuint none = 0;
    glClearTexImage(m.tile_index, 0, GL_RED_INTEGER, GL_UNSIGNED_INT, &none);
    glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
    if (spans.size() > 1) {
      glUseProgram(m.index_map);
      glUniform1ui(glGetUniformLocation(m.index_map, "u_tiles"), GLuint(spans.size()));
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, m.tile_spans);
      glBindImageTexture(0, m.tile_index, 0, GL_FALSE, 0, GL_READ_WRITE, GL_R32UI);
      // Tiles across work groups; rows of a tile across 16 of them (a tile of the fewest,
      // largest tiles is still spread over many invocations).
      glDispatchCompute(GLuint(std::min<size_t>(spans.size() - 1, 65535)), 16, 1);
      glUseProgram(0);
    }
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
  }
  glBindBuffer(GL_TEXTURE_BUFFER, m.tile_filters_buffer);
  glBufferData(GL_TEXTURE_BUFFER, GLsizeiptr(setup.filters.size() * sizeof(TileFilter)),
               setup.filters.data(), GL_STREAM_DRAW);
  glBindBuffer(GL_TEXTURE_BUFFER, m.tile_caps_buffer);
  glBufferData(GL_TEXTURE_BUFFER, GLsizeiptr(setup.radius_caps.size() * sizeof(float)),
               setup.radius_caps.data(), GL_STREAM_DRAW);

  const ReconstructionMode current_mode = mode();
  const FilterLimits& limits = config_.filter;
  const SplatSizeRule& rule = config_.splat;
  const glm::vec2 scale(setup.scale_x, setup.scale_y);
  const glm::vec2 origin(float(setup.grid.origin_x), float(setup.grid.origin_y));
  const glm::ivec2 size(width, height);
  const bool gather = options_.splat == GlSplat::kGather &&
                      current_mode != ReconstructionMode::kTraditionalFrameless;

  // The uniforms the splat's preparation reads: the vertex stage of the raster path, the
  // prepare pass of the gather.
  const auto set_splat_uniforms = [&](const Uniforms& u) {
    const Projector proj(camera, setup.scaled_width, setup.scaled_height, setup.grid.origin_x,
                         setup.grid.origin_y);
    u.set("u_now", time);
    u.set("u_reproject", current_mode == ReconstructionMode::kAdaptive ? 1 : 0);
    u.set("u_eye", proj.eye);
    u.set("u_forward", proj.forward);
    u.set("u_axis_x", proj.axis_x);
    u.set("u_axis_y", proj.axis_y);
    u.set("u_znear", proj.znear);
    u.set("u_orthographic", proj.orthographic ? 1 : 0);
    u.set("u_half", glm::vec2(proj.half_width, proj.half_height));
    u.set("u_min_direction_z", Projector::kMinDirectionZ);
    u.set("u_max_coordinate", Projector::kMaxCoordinate);
    u.set("u_scale", scale);
    u.set("u_origin", origin);
    u.set("u_size", size);
    u.set("u_guard", float(g));
    u.set("u_max_future", limits.max_future);
    u.set("u_cutoff", limits.cutoff);
    u.set("u_min_wt", limits.min_temporal_weight);
    u.set("u_have_coverage", m.have_coverage ? 1 : 0);
    u.set("u_grow_below", rule.grow_below);
    u.set("u_grow", rule.grow);
    u.set("u_shrink_above", rule.shrink_above);
    u.set("u_shrink", rule.shrink);
    u.set("u_relax", rule.relax);
    u.set("u_min_radius", rule.min_radius);
    u.set("u_max_radius", rule.max_radius);
    u.set("u_tile_index", 0);
    u.set("u_tile_filters", 1);
    u.set("u_coverage", 2);
    u.set("u_tile_caps", 3);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, m.tile_index);
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_BUFFER, m.tile_filters);
    glActiveTexture(GL_TEXTURE2);
    glBindTexture(GL_TEXTURE_2D, m.coverage[size_t(1 - m.current)]);
    glActiveTexture(GL_TEXTURE3);
    glBindTexture(GL_TEXTURE_BUFFER, m.tile_caps);
    glActiveTexture(GL_TEXTURE0);
  };

  // ---- Splats (or newest samples) into (sum w c, sum w) and coverage.
  const auto bin_for_gather = [&] {
    const GLuint tiles = GLuint(m.chunks * m.tiles_x * m.tiles_y);
    const std::array<GLuint, 2> per_sample = groups_for(m.stored);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, m.samples);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, m.splats);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, m.tile_count);
    glBindBufferRange(GL_SHADER_STORAGE_BUFFER, 3, m.status, status_at, kStatusStride);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, m.tile_start);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, m.tile_cursor);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 6, m.lists);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 7, m.splat_tiles);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, m.tile_count);
    glClearBufferData(GL_SHADER_STORAGE_BUFFER, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, nullptr);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);

    glUseProgram(m.prepare);
    const Uniforms prep{m.prepare};
    set_splat_uniforms(prep);
    glUniform1ui(prep.at("u_stored"), GLuint(m.stored));
    prep.set("u_tile", options_.tile);
    prep.set("u_tiles", glm::ivec2(m.tiles_x, m.tiles_y));
    glUniform1ui(prep.at("u_chunk_slots"), GLuint(m.chunk_slots));
    glDispatchCompute(per_sample[0], per_sample[1], 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);

    glUseProgram(m.scan);
    glUniform1ui(glGetUniformLocation(m.scan, "u_tiles"), tiles);
    glDispatchCompute(1, 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);

    glUseProgram(m.scatter);
    const Uniforms sc{m.scatter};
    sc.set("u_tiles", glm::ivec2(m.tiles_x, m.tiles_y));
    glUniform1ui(sc.at("u_stored"), GLuint(m.stored));
    glUniform1ui(sc.at("u_list_capacity"), GLuint(m.list_capacity));
    glUniform1ui(sc.at("u_chunk_slots"), GLuint(m.chunk_slots));
    glDispatchCompute(per_sample[0], per_sample[1], 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  };
  const auto splat_by_gather = [&] {
    glUseProgram(m.gather);
    const Uniforms ga{m.gather};
    ga.set("u_size", size);
    ga.set("u_tiles", glm::ivec2(m.tiles_x, m.tiles_y));
    glUniform1ui(ga.at("u_list_capacity"), GLuint(m.list_capacity));
    ga.set("u_min_weight", kMinSplatWeight);
    glBindImageTexture(0, m.accum, 0, GL_FALSE, 0, GL_READ_WRITE, GL_RGBA32F);
    glBindImageTexture(1, m.coverage[size_t(m.current)], 0, GL_FALSE, 0, GL_READ_WRITE, GL_RG32F);
    // Chunk by chunk; a chunk past the stored samples has nothing (the first always runs: it
    // writes every pixel).
    for (int k = 0; k == 0 || size_t(k) * m.chunk_slots < m.stored; ++k) {
      glUniform1ui(ga.at("u_chunk"), GLuint(k));
      glDispatchCompute(GLuint(m.tiles_x), GLuint(m.tiles_y), 1);
      glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT);
    }
  };
  const auto splat_by_raster = [&] {
    glBindFramebuffer(GL_FRAMEBUFFER, m.fbo[size_t(m.current)]);
    const GLenum draw_buffers[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    glDrawBuffers(2, draw_buffers);
    const float zero[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    glClearBufferfv(GL_COLOR, 0, zero);
    glClearBufferfv(GL_COLOR, 1, zero);
    const float far_depth = 1.0f;
    glClearBufferfv(GL_DEPTH, 0, &far_depth);
    // The viewport is the image grown by the guard band: samples just off the image still
    // reach its edge pixels (GL culls points whose center is outside the viewport).
    glViewport(-g, -g, width + 2 * g, height + 2 * g);
    glEnable(GL_PROGRAM_POINT_SIZE);
    glBindVertexArray(m.vao);
    if (current_mode == ReconstructionMode::kTraditionalFrameless) {
      glUseProgram(m.newest);
      const Uniforms u{m.newest};
      u.set("u_now", time);
      u.set("u_max_future", limits.max_future);
      u.set("u_scale", scale);
      u.set("u_origin", origin);
      u.set("u_size", size);
      u.set("u_guard", float(g));
      glDisable(GL_BLEND);
      glEnable(GL_DEPTH_TEST);
      glDepthFunc(GL_LESS);
      glDrawArrays(GL_POINTS, 0, GLsizei(m.stored));
      glDisable(GL_DEPTH_TEST);
    } else {
      glUseProgram(m.splat);
      const Uniforms u{m.splat};
      set_splat_uniforms(u);
      u.set("u_min_weight", kMinSplatWeight);
      glEnable(GL_BLEND);
      glBlendEquation(GL_FUNC_ADD);
      glBlendFunc(GL_ONE, GL_ONE);
      glDrawArrays(GL_POINTS, 0, GLsizei(m.stored));
      glDisable(GL_BLEND);
    }
    glBindVertexArray(0);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT);
  };
  // The image: splats, fill, read-back; a fence at its end.
  const auto draw = [&] {
    if (gather) timed(kBin, bin_for_gather);
    timed(kSplatPass, [&] { gather ? splat_by_gather() : splat_by_raster(); });

    timed(kFill, [&] {
      // ---- Hole pyramid (hole_fill.h), level by level.
      glUseProgram(m.pyramid);
      {
        const Uniforms u{m.pyramid};
        glm::ivec2 src_size(width, height);
        int src_row = 0;
        for (size_t level = 0; level < m.levels.size(); ++level) {
          const PyramidLevel& L = m.levels[level];
          glBindImageTexture(0, level == 0 ? m.accum : m.atlas, 0, GL_FALSE, 0, GL_READ_ONLY,
                             GL_RGBA32F);
          glBindImageTexture(1, m.atlas, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
          u.set("u_src_size", src_size);
          u.set("u_src_row", src_row);
          u.set("u_dst_size", glm::ivec2(L.width, L.height));
          u.set("u_dst_row", L.row_offset);
          glDispatchCompute(GLuint((L.width + kGroup - 1) / kGroup),
                            GLuint((L.height + kGroup - 1) / kGroup), 1);
          glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
          src_size = glm::ivec2(L.width, L.height);
          src_row = L.row_offset;
        }
      }

      // ---- Normalise, fill holes; the pixel counts into this image's status words.
      glUseProgram(m.normalise);
      const Uniforms u{m.normalise};
      glBindBufferRange(GL_SHADER_STORAGE_BUFFER, 0, m.status, status_at, kStatusStride);
      glBindImageTexture(0, m.accum, 0, GL_FALSE, 0, GL_READ_ONLY, GL_RGBA32F);
      glBindImageTexture(1, m.atlas, 0, GL_FALSE, 0, GL_READ_ONLY, GL_RGBA32F);
      glBindImageTexture(2, m.output, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
      std::vector<glm::ivec3> level_data;
      for (const PyramidLevel& L : m.levels)
        level_data.emplace_back(L.width, L.height, L.row_offset);
      AFR_CHECK(level_data.size() <= 32);
      u.set("u_size", glm::ivec2(out_width, out_height));
      u.set("u_offset", glm::ivec2(setup.view_x, setup.view_y));
      u.set("u_levels", int(level_data.size()));
      if (!level_data.empty()) {
        glUniform3iv(u.at("u_level"), GLsizei(level_data.size()), &level_data[0].x);
      }
      glDispatchCompute(GLuint((out_width + kGroup - 1) / kGroup),
                        GLuint((out_height + kGroup - 1) / kGroup), 1);
      glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_TEXTURE_UPDATE_BARRIER_BIT |
                      GL_TEXTURE_FETCH_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT |
                      GL_CLIENT_MAPPED_BUFFER_BARRIER_BIT);
    });
    glUseProgram(0);

    // ---- The image leaves the GPU only when asked for: into a mapped buffer.
    if (out != nullptr) {
      timed(kReadback, [&] {
        const size_t bytes = out->pixels.size() * sizeof(glm::vec3);
        if (m.readback_bytes < bytes) {
          // A buffer the CPU keeps mapped: written by a compute pass, read once the image's
          // fence has signalled, with no driver read-back path in between.
          glDeleteBuffers(1, &m.readback);
          glGenBuffers(1, &m.readback);
          glBindBuffer(GL_SHADER_STORAGE_BUFFER, m.readback);
          const GLbitfield flags = GL_MAP_READ_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
          glBufferStorage(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(bytes), nullptr, flags);
          m.readback_map = glMapBufferRange(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(bytes), flags);
          if (m.readback_map == nullptr) throw Error("OpenGL: cannot map the read-back buffer");
          m.readback_bytes = bytes;
        }
        glUseProgram(m.pack);
        glBindImageTexture(0, m.output, 0, GL_FALSE, 0, GL_READ_ONLY, GL_RGBA32F);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 7, m.readback);
        Uniforms{m.pack}.set("u_size", glm::ivec2(out_width, out_height));
        glDispatchCompute(GLuint((out_width + kGroup - 1) / kGroup),
                          GLuint((out_height + kGroup - 1) / kGroup), 1);
        glMemoryBarrier(GL_CLIENT_MAPPED_BUFFER_BARRIER_BIT);
        glUseProgram(0);
      });
    }
    if (queries) glQueryCounter(f.stamps[1], GL_TIMESTAMP);
    f.fence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
    glFlush();
  };
  draw();
  call.passes = lap();

  if (out != nullptr) {
    // The caller wants the pixels now: wait for this image, then copy them out. Were the
    // tiles' lists too short for it (splats lost), it is drawn again with the room it needs.
    const size_t lists_before = m.list_capacity;
    m.harvest(f);
    if (gather && m.list_capacity > lists_before) {
      std::fill_n(status, kStatusStride / sizeof(uint32_t), 0u);
      draw();
      m.harvest(f);
    }

    std::copy_n(static_cast<const glm::vec3*>(m.readback_map), out->pixels.size(),
                out->pixels.data());
    call.wait += lap();
  }
  m.report(&frame_);
  frame_.call = call;
  if (current_mode == ReconstructionMode::kTraditionalFrameless) {
    m.have_coverage = false;
  } else {
    m.have_coverage = true;
    m.current = 1 - m.current;
  }
  check_gl("reconstruct");
}

void GlReconstructor::finish() {
  context_->make_current();
  Impl& m = *impl_;
  for (Impl::InFlight& f : m.flight) m.harvest(f);
  m.report(&frame_);
}

void GlReconstructor::read_weights(std::vector<float>* out) {
  context_->make_current();
  Impl& m = *impl_;
  std::vector<glm::vec4> rgba(size_t(m.out_width) * size_t(m.out_height));
  out->resize(rgba.size());
  if (rgba.empty()) return;
  m.read_cropped(m.accum, GL_RGBA, 4, &rgba[0].x);
  for (size_t i = 0; i < rgba.size(); ++i) (*out)[i] = rgba[i].w;
  check_gl("read_weights");
}

void GlReconstructor::read_coverage(std::vector<CoverageCell>* out) {
  context_->make_current();
  Impl& m = *impl_;
  out->assign(size_t(m.out_width) * size_t(m.out_height), CoverageCell{});
  if (out->empty() || !m.have_coverage) return;
  static_assert(sizeof(CoverageCell) == 2 * sizeof(float));
  m.read_cropped(m.coverage[size_t(1 - m.current)], GL_RG, 2, &(*out)[0].count);
  check_gl("read_coverage");
}

bool GlReconstructor::read_coverage(const PixelRect& rect, std::vector<CoverageCell>* out) {
  out->clear();
  context_->make_current();
  Impl& m = *impl_;
  if (!m.have_coverage || rect.empty()) return false;
  const PixelRect part = grid_part(m.grid, rect);
  if (part.empty() || part.area() != rect.area()) return false;
  out->resize(size_t(rect.area()));
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glGetTextureSubImage(m.coverage[size_t(1 - m.current)], 0, part.x0, part.y0, 0, part.width(),
                       part.height(), 1, GL_RG, GL_FLOAT,
                       GLsizei(out->size() * sizeof(CoverageCell)), &(*out)[0].count);
  check_gl("read_coverage");
  return true;
}

Reconstructor::StoredSlots GlReconstructor::stored_samples() {
  Impl& m = *impl_;
  if (!m.mirrored) {
    // The first call reads the ring back from the GPU once; every reconstruct() after it
    // copies its new samples to the copy too.
    context_->make_current();
    m.mirrored = true;
    m.mirror.resize(store_.capacity());
    glBindBuffer(GL_ARRAY_BUFFER, m.samples);
    glGetBufferSubData(GL_ARRAY_BUFFER, 0, GLsizeiptr(m.mirror.size() * sizeof(StoredSample)),
                       m.mirror.data());
    check_gl("stored_samples");
  }
  return StoredSlots{m.mirror.data(), m.mirror.size(), m.seen, m.stored};
}

size_t GlReconstructor::write_coverage(const PixelRect& rect,
                                       const std::vector<CoverageCell>& cells) {
  check_coverage_size(rect, cells);
  context_->make_current();
  Impl& m = *impl_;
  if (!m.have_coverage) return 0;
  const PixelRect part = grid_part(m.grid, rect);
  if (part.empty()) return 0;
  const int32_t gx = int32_t(m.grid.origin_x), gy = int32_t(m.grid.origin_y);
  glBindTexture(GL_TEXTURE_2D, m.coverage[size_t(1 - m.current)]);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  glPixelStorei(GL_UNPACK_ROW_LENGTH, rect.width());
  const CoverageCell* first = cells.data() + size_t(part.y0 + gy - rect.y0) * size_t(rect.width()) +
                              size_t(part.x0 + gx - rect.x0);
  glTexSubImage2D(GL_TEXTURE_2D, 0, part.x0, part.y0, part.width(), part.height(), GL_RG, GL_FLOAT,
                  &first->count);
  glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
  check_gl("write_coverage");
  return size_t(part.area());
}

void GlReconstructor::draw_output(int fb_width, int fb_height) {
  context_->make_current();
  Impl& m = *impl_;
  if (m.output == 0 || fb_width <= 0 || fb_height <= 0) return;
  // Fit the image into the framebuffer, keeping its aspect.
  const double s = std::min(double(fb_width) / m.out_width, double(fb_height) / m.out_height);
  const int w = std::max(1, int(m.out_width * s)), h = std::max(1, int(m.out_height * s));
  glViewport((fb_width - w) / 2, (fb_height - h) / 2, w, h);
  glUseProgram(m.blit);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, m.output);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glUniform1i(glGetUniformLocation(m.blit, "u_image"), 0);
  glBindVertexArray(m.empty_vao);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glBindVertexArray(0);
  glUseProgram(0);
  check_gl("draw_output");
}

}  // namespace afr
