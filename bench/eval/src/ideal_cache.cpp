#include <afr/eval/ideal_cache.h>

#include <afr/common/error.h>
#include <afr/common/log.h>

#include <fmt/format.h>

#include <unistd.h>

#include <chrono>
#include <cstring>

namespace afr::eval {

namespace {

uint64_t fnv1a(const void* data, size_t n, uint64_t h = 0xcbf29ce484222325ULL) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < n; ++i) {
    h ^= p[i];
    h *= 0x100000001b3ULL;
  }
  return h;
}

template <typename T>
uint64_t mix(uint64_t h, const T& v) {
  return fnv1a(&v, sizeof(T), h);
}

}  // namespace

std::string ideal_cache_key(uint64_t fingerprint, const IdealRenderOptions& o,
                            const TracerOptions& t) {
  uint64_t h = 0xcbf29ce484222325ULL;
  h = mix(h, kIdealRendererVersion);
  h = mix(h, o.seed);
  h = mix(h, o.filter_radius);
  h = mix(h, o.filter_alpha);
  h = mix(h, t.max_mirror_depth);
  h = mix(h, t.shadows);
  h = mix(h, t.mirror_roughness);
  // packet_crosshair and threads change nothing in the picture.
  return fmt::format("{:016x}-{}x{}-spp{}-t{}-o{:08x}", fingerprint, o.width, o.height,
                     o.strata * o.strata, o.time, uint32_t(h ^ (h >> 32)));
}

IdealCache::IdealCache(std::filesystem::path folder, uint64_t fingerprint)
    : folder_(std::move(folder)), fingerprint_(fingerprint) {}

std::filesystem::path IdealCache::path_of(const IdealRenderOptions& options,
                                          const TracerOptions& tracer_options) const {
  return folder_ / (ideal_cache_key(fingerprint_, options, tracer_options) + ".exr");
}

Image IdealCache::frame(Tracer& tracer, const IdealRenderOptions& options) {
  const std::filesystem::path path = path_of(options, tracer.options());
  std::error_code ec;
  if (std::filesystem::is_regular_file(path, ec)) {
    try {
      Image image = read_image(path);
      if (image.width == options.width && image.height == options.height) {
        ++stats_.hits;
        return image;
      }
      spdlog::warn("{}: cached ideal frame is {}x{}, not {}x{}: rendering it again", path.string(),
                   image.width, image.height, options.width, options.height);
    } catch (const Error& e) {
      spdlog::warn("{}: unreadable cached ideal frame ({}): rendering it again", path.string(),
                   e.what());
    }
  }
  const auto start = std::chrono::steady_clock::now();
  Image image = render_ideal(tracer, options);
  stats_.render_seconds +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ++stats_.misses;
  std::filesystem::create_directories(folder_);
  const std::filesystem::path temporary =
      path.string() + fmt::format(".tmp{}.exr", uint64_t(::getpid()));
  write_image(image, temporary);
  std::filesystem::rename(temporary, path);
  return image;
}

}  // namespace afr::eval
