#include <afr/sampler/service/scene_cache.h>

#include <afr/common/builtin_scene.h>
#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>
#include <afr/protocol/scene_hash.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>

namespace afr::service {

// ---------------------------------------------------------------------------------------------
// Assembly

void SceneAssembler::reset(const protocol::SceneHash& hash, uint64_t size) {
  hash_ = hash;
  size_ = size;
  received_ = 0;
  next_chunk_ = 0;
  bytes_.assign(size_t(size), 0);
  have_.clear();
}

std::string SceneAssembler::add(const protocol::SceneChunk& chunk) {
  if (chunk.scene_hash != hash_ || chunk.scene_size != size_) {
    return fmt::format("scene chunk {} of {}: belongs to another scene ({} bytes, hash {})",
                       chunk.index, chunk.count, chunk.scene_size,
                       protocol::to_hex(chunk.scene_hash).substr(0, 16));
  }
  // The decoder has checked offset + size <= scene_size and index < count.
  if (have_.size() != chunk.count) have_.assign(chunk.count, 0);
  if (have_[chunk.index]) return {};
  std::memcpy(bytes_.data() + chunk.offset, chunk.bytes.data(), chunk.bytes.size());
  have_[chunk.index] = 1;
  received_ += chunk.bytes.size();
  while (next_chunk_ < have_.size() && have_[next_chunk_]) ++next_chunk_;
  return {};
}

std::vector<uint8_t> SceneAssembler::take_bytes() {
  std::vector<uint8_t> out = std::move(bytes_);
  reset(protocol::SceneHash{}, 0);
  return out;
}

// ---------------------------------------------------------------------------------------------
// Cache

namespace {

std::vector<uint8_t> read_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw Error(fmt::format("{}: cannot open", file.string()));
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

bool is_payload_file(const std::filesystem::path& p, const std::string& hex) {
  return p.stem().string() == hex;
}

// A cached scene of any hash: <hex hash>.glb, .gltf or .builtin.
bool is_cached_scene(const std::filesystem::path& p) {
  const std::string ext = p.extension().string(), stem = p.stem().string();
  return (ext == ".glb" || ext == ".gltf" || ext == ".builtin") &&
         stem.size() == protocol::to_hex(protocol::SceneHash{}).size() &&
         std::all_of(stem.begin(), stem.end(),
                     [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); });
}

// A write that never finished (its sampler died): <file>.<pid>.part, left for an hour.
constexpr auto kStalePart = std::chrono::hours(1);

}  // namespace

std::optional<std::filesystem::path> SceneCache::find(const protocol::SceneHash& hash) const {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir_, ec)) return std::nullopt;
  const std::string hex = protocol::to_hex(hash);
  for (const auto& entry : std::filesystem::directory_iterator(dir_, ec)) {
    if (!entry.is_regular_file() || !is_payload_file(entry.path(), hex)) continue;
    try {
      if (protocol::scene_hash(read_file(entry.path())) == hash) {
        // Used now: the last to go (evict).
        std::filesystem::last_write_time(entry.path(),
                                         std::filesystem::file_time_type::clock::now(), ec);
        return entry.path();
      }
    } catch (const Error&) {
    }
  }
  return std::nullopt;
}

std::filesystem::path SceneCache::store(const protocol::SceneHash& hash,
                                        std::string_view scene_name,
                                        const std::vector<uint8_t>& bytes) const {
  std::string ext = std::filesystem::path(std::string(scene_name)).extension().string();
  const bool glb = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
  if (is_builtin_scene_payload(bytes)) {
    ext = ".builtin";
  } else if (ext != ".glb" && ext != ".gltf") {
    ext = glb ? ".glb" : ".gltf";
  }
  std::error_code ec;
  std::filesystem::create_directories(dir_, ec);
  const std::filesystem::path file = dir_ / (protocol::to_hex(hash) + ext);
  const std::filesystem::path tmp = file.string() + fmt::format(".{}.part", ::getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    if (!out) throw Error(fmt::format("{}: cannot write the scene cache file", tmp.string()));
  }
  std::filesystem::rename(tmp, file, ec);  // atomic: another sampler may read the same cache
  if (ec) throw Error(fmt::format("{}: cannot rename into place: {}", file.string(), ec.message()));
  evict(file);
  return file;
}

void SceneCache::evict(const std::filesystem::path& keep) const {
  namespace fs = std::filesystem;
  struct Cached {
    fs::path path;
    uint64_t bytes;
    fs::file_time_type used;
  };
  std::vector<Cached> scenes;
  uint64_t total = 0;
  std::error_code ec;
  const fs::file_time_type now = fs::file_time_type::clock::now();
  for (const auto& entry : fs::directory_iterator(dir_, ec)) {
    std::error_code e;
    if (!entry.is_regular_file(e)) continue;
    const fs::path& p = entry.path();
    const fs::file_time_type used = fs::last_write_time(p, e);
    if (e) continue;  // gone meanwhile (another sampler's eviction)
    if (p.extension() == ".part") {
      if (now - used > kStalePart) fs::remove(p, e);
      continue;
    }
    if (!is_cached_scene(p) || p == keep) continue;
    const uint64_t bytes = entry.file_size(e);
    if (e) continue;
    scenes.push_back({p, bytes, used});
    total += bytes;
  }
  const uint64_t kept = fs::file_size(keep, ec);
  total += ec ? 0 : kept;
  std::sort(scenes.begin(), scenes.end(),
            [](const Cached& a, const Cached& b) { return a.used < b.used; });
  int removed = 0;
  uint64_t freed = 0;
  for (const Cached& c : scenes) {
    if (total <= max_bytes_) break;
    std::error_code e;
    if (fs::remove(c.path, e)) {
      ++removed;
      freed += c.bytes;
    }
    total -= c.bytes;
  }
  if (removed > 0) {
    spdlog::info(
        "scene cache {}: removed the {} least recently used scene(s) ({:.1f} MB) to stay "
        "within {:.0f} MB",
        dir_.string(), removed, double(freed) / 1e6, double(max_bytes_) / 1e6);
  }
}

Scene load_scene_payload(const std::filesystem::path& file) {
  if (file.extension() == ".builtin") {
    try {
      return builtin_scene_from_payload(read_file(file));
    } catch (const Error& e) {
      throw Error(fmt::format("{}: {}", file.string(), e.what()));
    }
  }
  return load_gltf(file);
}

Scene load_scene_payload(std::span<const uint8_t> bytes, const std::string& name) {
  if (is_builtin_scene_payload(bytes)) {
    try {
      return builtin_scene_from_payload(bytes);
    } catch (const Error& e) {
      throw Error(fmt::format("{}: {}", name, e.what()));
    }
  }
  return load_gltf_bytes(bytes, name);
}

std::filesystem::path default_scene_cache_dir() {
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg) {
    return std::filesystem::path(xdg) / "afr" / "scenes";
  }
  if (const char* home = std::getenv("HOME"); home && *home) {
    return std::filesystem::path(home) / ".cache" / "afr" / "scenes";
  }
  return std::filesystem::path(fmt::format("/tmp/afr-scenes-{}", ::getuid()));
}

}  // namespace afr::service
