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

// Scenes on disk, one file per hash: DIR/<hex hash><extension>. The folder holds at most
// max_bytes of scenes: storing one removes the least recently used others (stored or found
// longest ago; the files' modification times) until the rest fit, so that a host whose samplers
// serve one display after another, each with its scenes, does not fill its disk. The scene just
// stored stays, whatever its size. Several samplers may share the folder.
class SceneCache {
 public:
  static constexpr uint64_t kDefaultMaxBytes = uint64_t(4) << 30;

  explicit SceneCache(std::filesystem::path dir, uint64_t max_bytes = kDefaultMaxBytes)
      : dir_(std::move(dir)), max_bytes_(max_bytes) {}
  // The file of a cached scene whose bytes still match the hash, or nothing. A file found
  // counts as used now.
  std::optional<std::filesystem::path> find(const protocol::SceneHash& hash) const;
  // Writes the bytes (already checked against their hash), removes the least recently used
  // other scenes beyond max_bytes (and leftovers of writes that never finished), and returns
  // the file. Throws afr::Error naming the file when it cannot be written.
  std::filesystem::path store(const protocol::SceneHash& hash, std::string_view scene_name,
                              const std::vector<uint8_t>& bytes) const;
  const std::filesystem::path& dir() const { return dir_; }
  uint64_t max_bytes() const { return max_bytes_; }

 private:
  void evict(const std::filesystem::path& keep) const;

  std::filesystem::path dir_;
  uint64_t max_bytes_;
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
