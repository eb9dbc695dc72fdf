// The identity of a scene file: a BLAKE2b-256 hash of its bytes (libsodium). A sampler keeps
// scenes it has received by this hash and checks every transfer against it.
#pragma once

#include <afr/protocol/messages.h>

#include <cstdint>
#include <span>
#include <string>

namespace afr::protocol {

SceneHash scene_hash(std::span<const uint8_t> bytes);

// Incremental form, for files read in pieces.
class SceneHasher {
 public:
  SceneHasher();
  void update(std::span<const uint8_t> bytes);
  SceneHash finish();  // once

 private:
  alignas(64) unsigned char state_[384];  // crypto_generichash_state (checked in the .cpp)
};

// 64 lowercase hex digits.
std::string to_hex(const SceneHash& hash);

}  // namespace afr::protocol
