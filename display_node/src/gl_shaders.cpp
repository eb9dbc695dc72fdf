#include "gl_shaders.h"

namespace afr::gl_shaders {

const char* const kPixelBox = R"(
// The pixels whose centers lie strictly within (r.x, r.y) of `center` (x + 0.5 in
// (center - r, center + r)) lie in [lo, hi], unclamped to any image.
void pixel_box(vec2 center, vec2 r, out ivec2 lo, out ivec2 hi) {
  lo = ivec2(floor(center - r - 0.5));
  hi = ivec2(ceil(center + r - 0.5));
}
)";

// What the raster path's vertex shader and the gather's prepare pass share: the uniforms of a
// splat's preparation and prepare_splat(), which reprojects a sample (reprojection.h), reads
// its tile's filter and the previous image's coverage, and sizes its splat (coverage_map.h,
// filter.h): cpu_reconstructor.cpp's phases 1 and 2. Programs put it after their #version.
const char* const kSplatCommon = R"(
uniform double u_now;
uniform bool u_reproject;
// Projector (reprojection.h)
uniform vec3 u_eye;
uniform vec3 u_forward;
uniform vec3 u_axis_x;
uniform vec3 u_axis_y;
uniform float u_znear;
uniform bool u_orthographic;
uniform vec2 u_half;  // the whole image's center
uniform float u_min_direction_z;
uniform float u_max_coordinate;
uniform vec2 u_scale;   // sampling image -> output pixels
uniform vec2 u_origin;  // the grid's first pixel in the whole image, output pixels
uniform ivec2 u_size;   // grid pixels (the viewport with its margin)
uniform float u_guard;  // samples are kept while inside the image grown by this
// FilterLimits
uniform float u_max_future;
uniform float u_cutoff;
uniform float u_min_wt;
// SplatSizeRule
uniform bool u_have_coverage;
uniform float u_grow_below;
uniform float u_grow;
uniform float u_shrink_above;
uniform float u_relax;
uniform float u_shrink;
uniform float u_min_radius;
uniform float u_max_radius;

uniform usampler2D u_tile_index;       // per output pixel: index into u_tile_filters
uniform samplerBuffer u_tile_filters;  // sigma_x, sigma_y, k_t, e_t
uniform samplerBuffer u_tile_caps;     // the widest splat the tile's density calls for
uniform sampler2D u_coverage;          // previous image: count, growth sum

// quantize_position (reprojection.h): 1/256 pixel in the whole image's coordinates.
vec2 quantize_position(vec2 v) {
  return mix(v, roundEven(v * 256.0) / 256.0, lessThan(abs(v), vec2(16384.0)));
}
float quantize_position(float v) { return abs(v) < 16384.0 ? roundEven(v * 256.0) / 256.0 : v; }

float splat_radius(vec2 cell, float filter_radius) {
  float g = 1.0;
  if (u_have_coverage) {
    float c = cell.x;
    if (!(c > 0.0)) {
      g = u_grow;
    } else {
      float mean = cell.y / c;
      float base = mean + u_relax * (1.0 - mean);
      if (c < u_grow_below) g = base * min(u_grow, sqrt(u_grow_below / c));
      else if (c > u_shrink_above) g = base * max(u_shrink, sqrt(sqrt(u_shrink_above / c)));
      else g = base;
    }
  }
  float r = g * filter_radius;
  if (!(r >= u_min_radius)) return u_min_radius;
  return min(r, u_max_radius);
}

struct Splat {
  vec2 center;  // grid pixels
  vec4 kernel;  // k_x, k_y, and the Gaussians' values at the cut: off_x, off_y
  vec3 extent;  // r_x, r_y, growth r / r_filter
  float wt;     // temporal weight over the Gaussian's area
};

// False when the sample reaches no pixel of the grid (too far in the future, behind the
// camera, off the grid and its guard band).
bool prepare_splat(double time, vec2 xy, uint flags, vec3 position, vec3 velocity,
                   out Splat s) {
  double age_d = u_now - time;
  if (age_d < double(-u_max_future)) return false;
  float age_signed = float(age_d);
  float age = max(age_signed, 0.0);
  vec2 p;
  if (u_reproject && (flags & 1u) != 0u) {
    vec3 d;
    float z;
    if ((flags & 2u) != 0u) {
      d = position;
      z = dot(d, u_forward);
      if (!(z > u_min_direction_z) || u_orthographic) return false;
    } else {
      vec3 w = position;
      if ((flags & 4u) != 0u) w += velocity * age_signed;
      d = w - u_eye;
      z = dot(d, u_forward);
      if (!(z >= u_znear)) return false;
    }
    float w = u_orthographic ? 1.0 : z;
    p = vec2(u_half.x + dot(d, u_axis_x) / w, u_half.y - dot(d, u_axis_y) / w);
    if (!(abs(p.x) < u_max_coordinate) || !(abs(p.y) < u_max_coordinate)) return false;
    p = quantize_position(p) - u_origin;
  } else {
    p = quantize_position(xy * u_scale) - u_origin;
  }
  vec2 size = vec2(u_size);
  if (!(p.x > -u_guard && p.x < size.x + u_guard && p.y > -u_guard && p.y < size.y + u_guard)) {
    return false;
  }
  ivec2 pix = clamp(ivec2(floor(p)), ivec2(0), u_size - 1);
  int tile = int(texelFetch(u_tile_index, pix, 0).r);
  vec4 f = texelFetch(u_tile_filters, tile);
  float r_filter = u_cutoff * max(f.x, f.y);
  float cap = max(max(texelFetch(u_tile_caps, tile).r, r_filter), u_min_radius);
  float r = min(splat_radius(texelFetch(u_coverage, pix, 0).xy, r_filter), cap);
  float grown = max(1.0, r / r_filter);
  float sigma_x = f.x * grown;
  float sigma_y = f.y * grown;
  float k_x = 0.5 / (sigma_x * sigma_x);
  float k_y = 0.5 / (sigma_y * sigma_y);
  // The square of radius r cut to the Gaussian's own cutoff box.
  float r_x = quantize_position(min(r, u_cutoff * sigma_x));
  float r_y = quantize_position(min(r, u_cutoff * sigma_y));
  s.center = p;
  s.kernel = vec4(k_x, k_y, exp(-r_x * r_x * k_x), exp(-r_y * r_y * k_y));
  s.extent = vec3(r_x, r_y, r / r_filter);
  // Divided by the Gaussian's area (filter.h).
  s.wt = max(exp(-age * age * f.z), u_min_wt) / (sigma_x * sigma_y);
  return true;
}
)";

// Vertex attributes are StoredSample's fields (sample_store.h), 64 bytes a sample.
const char* const kSplatVertex = R"(
layout(location = 0) in double a_time;
layout(location = 1) in vec2 a_xy;
layout(location = 2) in vec3 a_color;
layout(location = 3) in uint a_flags;
layout(location = 4) in vec3 a_position;
layout(location = 5) in vec3 a_velocity;

flat out vec2 v_center;
flat out vec4 v_kernel;  // k_x, k_y, off_x, off_y
flat out vec3 v_color;
flat out float v_wt;
flat out vec3 v_extent;  // r_x, r_y, growth r / r_filter

void main() {
  Splat s;
  if (!prepare_splat(a_time, a_xy, a_flags, a_position, a_velocity, s)) {
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);  // outside the clip volume: culled
    gl_PointSize = 1.0;
    return;
  }
#if AFR_PROBE == 1
  // GlProbe::kCulled: culled after the whole preparation (a test of its results, which the
  // compiler cannot drop: no splat's values sum below -1e30).
  if (!(s.center.x + s.center.y + s.kernel.x + s.kernel.y + s.kernel.z + s.kernel.w +
        s.extent.x + s.extent.y + s.extent.z + s.wt < -1e30)) {
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
    gl_PointSize = 1.0;
    return;
  }
#endif
  v_center = s.center;
  v_kernel = s.kernel;
  v_color = a_color;
  v_wt = s.wt;
  v_extent = s.extent;
  // The viewport is the image grown by u_guard on every side.
  vec2 size = vec2(u_size);
  gl_Position = vec4((s.center + u_guard) / (size + 2.0 * u_guard) * 2.0 - 1.0, 0.0, 1.0);
  // Covers every pixel center within r of p, with half a pixel to spare on each side for the
  // rasteriser's snapping of point positions (1/256 pixel on llvmpipe) and size rounding.
  gl_PointSize = 2.0 * max(s.extent.x, s.extent.y) + 1.0;
#if AFR_PROBE == 4
  gl_PointSize = 1.0;  // GlProbe::kDots
#endif
}
)";

const char* const kSplatFragment = R"(
flat in vec2 v_center;
flat in vec4 v_kernel;
flat in vec3 v_color;
flat in float v_wt;
flat in vec3 v_extent;
uniform float u_min_weight;
layout(location = 0) out vec4 o_accum;
layout(location = 1) out vec2 o_coverage;
void main() {
#if AFR_PROBE == 2 || AFR_PROBE == 4
  // GlProbe::kFlat, kDots: every fragment of the point, no kernel.
  o_accum = vec4(v_color * v_wt, v_wt);
  o_coverage = vec2(1.0, v_extent.z);
  return;
#endif
  vec2 d = gl_FragCoord.xy - v_center;
  if (abs(d.x) >= v_extent.x || abs(d.y) >= v_extent.y) discard;
  float wx = exp(-d.x * d.x * v_kernel.x) - v_kernel.z;
  float wy = exp(-d.y * d.y * v_kernel.y) - v_kernel.w;
  if (!(wx > 0.0) || !(wy > 0.0)) discard;
  float w = wx * (wy * v_wt);
  if (!(w > u_min_weight)) discard;
  o_accum = vec4(v_color * w, w);
  o_coverage = vec2(1.0, v_extent.z);
}
)";

const char* const kNewestVertex = R"(#version 430 core
layout(location = 0) in double a_time;
layout(location = 1) in vec2 a_xy;
layout(location = 2) in vec3 a_color;
uniform double u_now;
uniform float u_max_future;
uniform vec2 u_scale;
uniform vec2 u_origin;
uniform ivec2 u_size;
uniform float u_guard;
flat out vec3 v_color;
void main() {
  double age_d = u_now - a_time;
  vec2 p = a_xy * u_scale - u_origin;
  vec2 size = vec2(u_size);
  if (age_d < double(-u_max_future) || !(p.x >= 0.0 && p.x < size.x && p.y >= 0.0 && p.y < size.y)) {
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
    gl_PointSize = 1.0;
    return;
  }
  float age = float(max(age_d, 0.0LF));
  // Newer samples are nearer: depth age / (age + 1) is increasing in age, in [0, 1).
  float depth = age / (age + 1.0);
  vec2 center = floor(p) + 0.5;
  gl_Position = vec4((center + u_guard) / (size + 2.0 * u_guard) * 2.0 - 1.0, depth * 2.0 - 1.0, 1.0);
  gl_PointSize = 1.0;
  v_color = a_color;
}
)";

const char* const kNewestFragment = R"(#version 430 core
flat in vec3 v_color;
layout(location = 0) out vec4 o_accum;
layout(location = 1) out vec2 o_coverage;
void main() {
  o_accum = vec4(v_color, 1.0);
  o_coverage = vec2(0.0);
}
)";

const char* const kPyramidCompute = R"(#version 430 core
layout(local_size_x = 16, local_size_y = 16) in;
layout(rgba32f, binding = 0) uniform readonly image2D u_src;
layout(rgba32f, binding = 1) uniform writeonly image2D u_dst;
uniform ivec2 u_src_size;
uniform int u_src_row;
uniform ivec2 u_dst_size;
uniform int u_dst_row;
void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= u_dst_size.x || p.y >= u_dst_size.y) return;
  vec4 s = vec4(0.0);
  for (int b = 0; b < 2; ++b) {
    for (int a = 0; a < 2; ++a) {
      ivec2 q = 2 * p + ivec2(a, b);
      if (q.x < u_src_size.x && q.y < u_src_size.y) s += imageLoad(u_src, q + ivec2(0, u_src_row));
    }
  }
  imageStore(u_dst, p + ivec2(0, u_dst_row), s);
}
)";

const char* const kNormaliseCompute = R"(#version 430 core
layout(local_size_x = 16, local_size_y = 16) in;
layout(rgba32f, binding = 0) uniform readonly image2D u_accum;
layout(rgba32f, binding = 1) uniform readonly image2D u_atlas;
layout(rgba32f, binding = 2) uniform writeonly image2D u_out;
layout(std430, binding = 0) buffer Counts {
  uint holes;
  uint empty;
  uint nonfinite;
};
uniform ivec2 u_size;    // output pixels
uniform ivec2 u_offset;  // the output's first pixel in the grid (accum and pyramid)
uniform int u_levels;
uniform ivec3 u_level[32];  // width, height, first atlas row of levels 1..u_levels

vec4 texel(int k, int x, int y) {
  ivec3 L = u_level[k - 1];
  return imageLoad(u_atlas, ivec2(clamp(x, 0, L.x - 1), L.z + clamp(y, 0, L.y - 1)));
}

// The counts are summed per work group in shared memory and added to the buffer once per
// group. The buffer is the persistently mapped status buffer, which the driver may keep in
// the host's memory: with an atomic add per hole pixel the pass took 1-13 ms at 3840x2160 on
// an H200, live, with thousands of holes, and the display fell from 30 to 21 images/s; with
// one per group 1-3 ms (docs/benchmarks.md, "GPU reconstructor").
shared uint group_holes;
shared uint group_empty;
shared uint group_nonfinite;

void main() {
  if (gl_LocalInvocationIndex == 0u) {
    group_holes = 0u;
    group_empty = 0u;
    group_nonfinite = 0u;
  }
  barrier();
  ivec2 o = ivec2(gl_GlobalInvocationID.xy);
  if (o.x < u_size.x && o.y < u_size.y) {
    ivec2 p = o + u_offset;
    vec4 a = imageLoad(u_accum, p);
    vec3 c = vec3(0.0);
    if (a.w > 0.0) {
      c = a.rgb / a.w;
    } else {
      atomicAdd(group_holes, 1u);
      bool found = false;
      for (int k = 1; k <= u_levels; ++k) {
        float inv = 1.0 / float(1 << k);
        float px = (float(p.x) + 0.5) * inv - 0.5;
        float py = (float(p.y) + 0.5) * inv - 0.5;
        float fx0 = floor(px), fy0 = floor(py);
        float fx = px - fx0, fy = py - fy0;
        int ix = int(fx0), iy = int(fy0);
        vec4 s = texel(k, ix, iy) * ((1.0 - fx) * (1.0 - fy)) + texel(k, ix + 1, iy) * (fx * (1.0 - fy)) +
                 texel(k, ix, iy + 1) * ((1.0 - fx) * fy) + texel(k, ix + 1, iy + 1) * (fx * fy);
        if (s.w > 0.0) {
          c = s.rgb / s.w;
          found = true;
          break;
        }
      }
      if (!found) atomicAdd(group_empty, 1u);
    }
    if (any(isnan(c)) || any(isinf(c))) {
      atomicAdd(group_nonfinite, 1u);
      c = vec3(0.0);
    }
    imageStore(u_out, o, vec4(c, 1.0));
  }
  barrier();
  if (gl_LocalInvocationIndex == 0u) {
    if (group_holes > 0u) atomicAdd(holes, group_holes);
    if (group_empty > 0u) atomicAdd(empty, group_empty);
    if (group_nonfinite > 0u) atomicAdd(nonfinite, group_nonfinite);
  }
}
)";

const char* const kBlitVertex = R"(#version 430 core
out vec2 v_uv;
void main() {
  // One triangle covering the viewport.
  vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  v_uv = vec2(p.x, 1.0 - p.y);
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
)";

const char* const kBlitFragment = R"(#version 430 core
in vec2 v_uv;
uniform sampler2D u_image;
out vec4 o_color;
// linear_to_srgb of image.h: the window shows what write_image() would store.
vec3 to_srgb(vec3 c) {
  c = clamp(c, 0.0, 1.0);
  return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, greaterThan(c, vec3(0.0031308)));
}
void main() {
  // Texture row 0 is the image's top row; the window's top is v_uv.y = 0 after the flip.
  o_color = vec4(to_srgb(texture(u_image, v_uv).rgb), 1.0);
}
)";

// ---- The tiled gather: the splat pass as compute (prepare, scan, scatter, gather). The ring
// holds StoredSample (sample_store.h) as 16 words: time (2, a double), x, y, r, g, b, flags,
// position (3), velocity (3), sampler id, reserved.

const char* const kPrepareCompute = R"(
layout(local_size_x = 256) in;
layout(std430, binding = 0) readonly buffer Ring { uint ring[]; };
// A splat is 3 vec4 at its sample's ring slot: (center, k_x, k_y), (color, weight),
// (r_x, r_y, growth, unused); a skipped sample's r_x is -1. (Slots, not a compacted list: one
// counter that every sample increments serialises the whole pass.) Its tiles, first and last
// (x | y << 16 each), go to a buffer of their own that only the scatter reads.
layout(std430, binding = 1) writeonly buffer Splats { vec4 splats[]; };
layout(std430, binding = 2) buffer TileCounts { uint tile_count[]; };
layout(std430, binding = 7) writeonly buffer SplatTiles { uvec2 splat_tiles[]; };

uniform uint u_stored;
uniform int u_tile;     // tile side, pixels
uniform ivec2 u_tiles;  // tiles across, down
// The ring's slots come in chunks of this many, each with its own tile counts and lists (the
// gather reads one chunk's splats at a time).
uniform uint u_chunk_slots;

vec3 word3(uint i) { return uintBitsToFloat(uvec3(ring[i], ring[i + 1u], ring[i + 2u])); }

void main() {
  // groups_for(): x * y work groups of 256.
  uint slot = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * 256u +
              gl_LocalInvocationID.x;
  if (slot >= u_stored) return;
  splats[3u * slot + 2u] = vec4(-1.0, -1.0, 0.0, 0.0);  // skipped
  uint b = slot * 16u;
  Splat s;
  if (!prepare_splat(packDouble2x32(uvec2(ring[b], ring[b + 1u])),
                     uintBitsToFloat(uvec2(ring[b + 2u], ring[b + 3u])), ring[b + 7u],
                     word3(b + 8u), word3(b + 11u), s)) {
    return;
  }
  ivec2 lo, hi;
  pixel_box(s.center, s.extent.xy, lo, hi);
  lo = max(lo, ivec2(0));
  hi = min(hi, u_size - 1);
  if (any(greaterThan(lo, hi))) return;
  ivec2 t0 = lo / u_tile, t1 = hi / u_tile;
  splats[3u * slot] = vec4(s.center, s.kernel.xy);
  splats[3u * slot + 1u] = vec4(word3(b + 4u), s.wt);
  splats[3u * slot + 2u] = vec4(s.extent, 0.0);
  splat_tiles[slot] = uvec2(uint(t0.x) | (uint(t0.y) << 16), uint(t1.x) | (uint(t1.y) << 16));
  uint chunk = slot / u_chunk_slots * uint(u_tiles.x * u_tiles.y);
  for (int ty = t0.y; ty <= t1.y; ++ty) {
    for (int tx = t0.x; tx <= t1.x; ++tx) {
      atomicAdd(tile_count[chunk + uint(ty * u_tiles.x + tx)], 1u);
    }
  }
}
)";

const char* const kScanCompute = R"(#version 430 core
layout(local_size_x = 1024) in;
layout(std430, binding = 2) buffer TileCounts { uint tile_count[]; };
layout(std430, binding = 4) writeonly buffer TileStart { uint tile_start[]; };
layout(std430, binding = 5) writeonly buffer TileCursor { uint tile_cursor[]; };
layout(std430, binding = 3) buffer Status { uint status[]; };  // [4]: list entries wanted
uniform uint u_tiles;
shared uint partial[1024];
void main() {
  // Each thread sums a run of tiles; an exclusive scan over the runs; each thread writes its
  // run's starts.
  uint t = gl_LocalInvocationID.x;
  uint per = (u_tiles + 1023u) / 1024u;
  uint first = t * per, last = min(first + per, u_tiles);
  uint sum = 0u;
  for (uint i = first; i < last; ++i) sum += tile_count[i];
  partial[t] = sum;
  barrier();
  for (uint step = 1u; step < 1024u; step <<= 1) {
    uint add = t >= step ? partial[t - step] : 0u;
    barrier();
    partial[t] += add;
    barrier();
  }
  uint at = partial[t] - sum;  // exclusive
  for (uint i = first; i < last; ++i) {
    tile_start[i] = at;
    tile_cursor[i] = at;
    at += tile_count[i];
  }
  if (t == 1023u) status[4] = partial[1023];
}
)";

const char* const kScatterCompute = R"(#version 430 core
layout(local_size_x = 256) in;
layout(std430, binding = 1) readonly buffer Splats { vec4 splats[]; };
layout(std430, binding = 5) buffer TileCursor { uint tile_cursor[]; };
layout(std430, binding = 6) writeonly buffer Lists { uint lists[]; };
layout(std430, binding = 7) readonly buffer SplatTiles { uvec2 splat_tiles[]; };
uniform uint u_stored;
uniform ivec2 u_tiles;
uniform uint u_list_capacity;
uniform uint u_chunk_slots;
void main() {
  uint i = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * 256u +
           gl_LocalInvocationID.x;
  if (i >= u_stored || splats[3u * i + 2u].x < 0.0) return;
  uvec2 range = splat_tiles[i];
  ivec2 t0 = ivec2(range.x & 0xffffu, range.x >> 16), t1 = ivec2(range.y & 0xffffu, range.y >> 16);
  uint chunk = i / u_chunk_slots * uint(u_tiles.x * u_tiles.y);
  for (int ty = t0.y; ty <= t1.y; ++ty) {
    for (int tx = t0.x; tx <= t1.x; ++tx) {
      uint at = atomicAdd(tile_cursor[chunk + uint(ty * u_tiles.x + tx)], 1u);
      if (at < u_list_capacity) lists[at] = i;
    }
  }
}
)";

// One work group a tile, one invocation a pixel, one dispatch a chunk of the ring (its sums are
// added to the chunks' before). The tile's splats come a batch at a time through shared
// memory; each batch is culled to the tile's cells (8 x 4 pixels, a warp of invocations each:
// CELL_W x CELL_H) so that a pixel tests only the splats whose box reaches its cell, and each
// is evaluated at the pixel exactly as kSplatFragment does.
const char* const kGatherCompute = R"(
// TILE (4, 8 or 16), GROUP (TILE * TILE), CELL_W, CELL_H: defined by the program (after
// #version).
const uint kCellSize = uint(CELL_W * CELL_H);
const int kCellsX = TILE / CELL_W;
const uint kCells = uint(kCellsX * (TILE / CELL_H));
const uint kBatch = uint(TILE * TILE);
layout(local_size_x = GROUP) in;
layout(std430, binding = 1) readonly buffer Splats { vec4 splats[]; };
layout(std430, binding = 2) readonly buffer TileCounts { uint tile_count[]; };
layout(std430, binding = 4) readonly buffer TileStart { uint tile_start[]; };
layout(std430, binding = 6) readonly buffer Lists { uint lists[]; };
layout(rgba32f, binding = 0) uniform image2D u_accum;
layout(rg32f, binding = 1) uniform image2D u_cover;
uniform ivec2 u_size;
uniform ivec2 u_tiles;
uniform uint u_list_capacity;
uniform float u_min_weight;
uniform uint u_chunk;  // this dispatch's chunk: 0 writes the sums, later ones add to them
// The batch: center and kernel, color and weight, extent and growth, and the Gaussians'
// values at the cut (off_x, off_y); per cell, the batch entries that reach it.
shared vec4 batch[kBatch * 4u];
shared uint cell_count[kCells];
shared uint cell_list[kCells * kBatch];
void main() {
  uint tile = u_chunk * uint(u_tiles.x * u_tiles.y) + gl_WorkGroupID.y * uint(u_tiles.x) +
              gl_WorkGroupID.x;
  uint local = gl_LocalInvocationIndex;
  // Invocations numbered cell by cell: one cell's pixels are consecutive invocations.
  uint cell = local / kCellSize, in_cell = local % kCellSize;
  ivec2 cell_at = ivec2(int(cell) % kCellsX * CELL_W, int(cell) / kCellsX * CELL_H);
  ivec2 tile_at = ivec2(gl_WorkGroupID.xy) * TILE;
  ivec2 pix = tile_at + cell_at + ivec2(int(in_cell) % CELL_W, int(in_cell) / CELL_W);
  vec2 at = vec2(pix) + 0.5;
  uint start = tile_start[tile];
  uint count = start < u_list_capacity ? min(tile_count[tile], u_list_capacity - start) : 0u;
  vec4 sum = vec4(0.0);
  vec2 cover = vec2(0.0);
  for (uint base = 0u; base < count; base += kBatch) {
    uint n = min(kBatch, count - base);
    barrier();
    if (local < kCells) cell_count[local] = 0u;
    barrier();
    if (local < n) {
      uint s = lists[start + base + local];
      vec4 a = splats[3u * s], c = splats[3u * s + 1u], e = splats[3u * s + 2u];
      batch[4u * local] = a;
      batch[4u * local + 1u] = c;
      batch[4u * local + 2u] = e;
      batch[4u * local + 3u] = vec4(exp(-e.x * e.x * a.z), exp(-e.y * e.y * a.w), 0.0, 0.0);
      // The tile's cells that the splat's pixel box (as the prepare pass bins it) reaches.
      ivec2 lo, hi;
      pixel_box(a.xy, e.xy, lo, hi);
      lo = max(lo - tile_at, ivec2(0));
      hi = min(hi - tile_at, ivec2(TILE - 1));
      for (int cy = lo.y / CELL_H; cy <= hi.y / CELL_H; ++cy) {
        for (int cx = lo.x / CELL_W; cx <= hi.x / CELL_W; ++cx) {
          uint c_at = uint(cy * kCellsX + cx);
          cell_list[c_at * kBatch + atomicAdd(cell_count[c_at], 1u)] = local;
        }
      }
    }
    barrier();
    uint m = cell_count[cell];
    for (uint j = 0u; j < m; ++j) {
      uint k = cell_list[cell * kBatch + j];
      vec4 a = batch[4u * k], c = batch[4u * k + 1u], e = batch[4u * k + 2u];
#if AFR_PROBE == 3
      // GlProbe::kVisit: the splat loaded and added, no box test, no kernel.
      sum += a + c + e + batch[4u * k + 3u];
      cover += vec2(1.0, e.z);
      continue;
#endif
      vec2 d = at - a.xy;
      if (abs(d.x) >= e.x || abs(d.y) >= e.y) continue;
      vec2 off = batch[4u * k + 3u].xy;
      float wx = exp(-d.x * d.x * a.z) - off.x;
      float wy = exp(-d.y * d.y * a.w) - off.y;
      if (!(wx > 0.0) || !(wy > 0.0)) continue;
      float w = wx * (wy * c.w);
      if (!(w > u_min_weight)) continue;
      sum += vec4(c.rgb * w, w);
      cover += vec2(1.0, e.z);
    }
  }
  if (pix.x < u_size.x && pix.y < u_size.y) {
    if (u_chunk > 0u) {
      sum += imageLoad(u_accum, pix);
      cover += imageLoad(u_cover, pix).xy;
    }
    imageStore(u_accum, pix, sum);
    imageStore(u_cover, pix, vec4(cover, 0.0, 0.0));
  }
}
)";

// The output image into a buffer the CPU maps (read-back): RGB floats, row 0 first, as
// afr::Image holds them.
const char* const kIndexMapCompute = R"(#version 430 core
// Work group (x, y): tiles x, x + X, ...; rows y, y + Y, ... of each. The map was cleared to 0
// ("no tile"); where spans overlap the highest index wins, as the newest snapshot's tiles
// come last in TileField::tiles().
layout(local_size_x = 256) in;
layout(r32ui, binding = 0) uniform coherent uimage2D u_map;
layout(std430, binding = 0) readonly buffer Spans { ivec4 spans[]; };  // x0, y0, x1, y1
uniform uint u_tiles;  // entries of spans, 0 included
void main() {
  for (uint t = gl_WorkGroupID.x + 1u; t < u_tiles; t += gl_NumWorkGroups.x) {
    ivec4 s = spans[t];
    for (int y = s.y + int(gl_WorkGroupID.y); y < s.w; y += int(gl_NumWorkGroups.y)) {
      for (int x = s.x + int(gl_LocalInvocationID.x); x < s.z; x += 256) {
        imageAtomicMax(u_map, ivec2(x, y), t);
      }
    }
  }
}
)";

const char* const kPackCompute = R"(#version 430 core
layout(local_size_x = 16, local_size_y = 16) in;
layout(rgba32f, binding = 0) uniform readonly image2D u_image;
layout(std430, binding = 7) writeonly buffer Pixels { float pixels[]; };
uniform ivec2 u_size;
void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= u_size.x || p.y >= u_size.y) return;
  vec4 c = imageLoad(u_image, p);
  uint i = 3u * (uint(p.y) * uint(u_size.x) + uint(p.x));
  pixels[i] = c.r;
  pixels[i + 1u] = c.g;
  pixels[i + 2u] = c.b;
}
)";

}  // namespace afr::gl_shaders
