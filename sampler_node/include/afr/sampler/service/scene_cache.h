// The sampler's side of scene transfer: reassembling a scene from the display's chunks,
// checking it against its hash, and keeping received scenes on disk by hash so that a
// reconnecting sampler (or a restarted one) does not fetch the same scene twice.
//
// The scene payload is the scene file's bytes (a .glb, or a .gltf with embedded buffers); the
// built-in scene travels as a short text (builtin_scene_payload, afr/common/builtin_scene.h;
// docs/service.md, "Scenes").
#pragma once

#include <afr/common/scene.h>
#include <afr/protocol/messages.h>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace afr::service {

// Collects the chunks of one scene. Chunks may come in any order and more than once.
class SceneAssembler {
 public:
  // Starts over for a scene of this hash and size (size checked by the decoder: 1..4 GiB).
  void reset(const protocol::SceneHash& hash, uint64_t size);
  // Adds one chunk; returns an error text when it does not belong to the scene being
  // assembled (another hash or size), else an empty string.
  std::string add(const protocol::SceneChunk& chunk);
  bool complete() const { return received_ == size_ && size_ > 0; }
  // The index of the first chunk not yet received, for a request that resumes the transfer.
  uint32_t next_chunk() const { return next_chunk_; }
  const std::vector<uint8_t>& bytes() const { return bytes_; }
  // Hands the assembled bytes over and starts empty (nothing complete) again.
  std::vector<uint8_t> take_bytes();
  const protocol::SceneHash& hash() const { return hash_; }
  uint64_t size() const { return size_; }
  uint64_t received() const { return received_; }

 private:
  protocol::SceneHash hash_{};
  uint64_t size_ = 0;
  uint64_t received_ = 0;
  uint32_t next_chunk_ = 0;
  std::vector<uint8_t> bytes_;
  std::vector<char> have_;  // by chunk index
};

// Scenes on disk, one file per hash: DIR/<hex hash><extension>.
class SceneCache {
 public:
  explicit SceneCache(std::filesystem::path dir) : dir_(std::move(dir)) {}
  // The file of a cached scene whose bytes still match the hash, or nothing.
  std::optional<std::filesystem::path> find(const protocol::SceneHash& hash) const;
  // Writes the bytes (already checked against their hash) and returns the file. Throws
  // afr::Error naming the file when it cannot be written.
  std::filesystem::path store(const protocol::SceneHash& hash, std::string_view scene_name,
                              const std::vector<uint8_t>& bytes) const;
  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_;
};

// The scene of a payload file: the built-in scene for its payload (with its ray depth), else
// the glTF.
// Throws afr::Error naming the file and the problem.
Scene load_scene_payload(const std::filesystem::path& file);
// The same for payload bytes held in memory; `name` stands for the file in errors.
Scene load_scene_payload(std::span<const uint8_t> bytes, const std::string& name);

// The default cache folder: $XDG_CACHE_HOME/afr/scenes or ~/.cache/afr/scenes, else
// /tmp/afr-scenes-<uid>.
std::filesystem::path default_scene_cache_dir();

}  // namespace afr::service
