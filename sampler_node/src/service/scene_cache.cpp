#include <afr/sampler/service/scene_cache.h>

#include <afr/common/builtin_scene.h>
#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>
#include <afr/protocol/scene_hash.h>

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
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

}  // namespace

std::optional<std::filesystem::path> SceneCache::find(const protocol::SceneHash& hash) const {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir_, ec)) return std::nullopt;
  const std::string hex = protocol::to_hex(hash);
  for (const auto& entry : std::filesystem::directory_iterator(dir_, ec)) {
    if (!entry.is_regular_file() || !is_payload_file(entry.path(), hex)) continue;
    try {
      if (protocol::scene_hash(read_file(entry.path())) == hash) return entry.path();
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
  return file;
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
