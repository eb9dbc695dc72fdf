#include <afr/protocol/scene_hash.h>

#include <afr/common/check.h>
#include <afr/common/error.h>

#include <sodium.h>

#include <cstring>

namespace afr::protocol {

static_assert(sizeof(crypto_generichash_state) <= 384);
static_assert(crypto_generichash_BYTES_MAX >= 32);

namespace {
crypto_generichash_state* state_of(unsigned char* storage) {
  return reinterpret_cast<crypto_generichash_state*>(storage);
}
}  // namespace

SceneHasher::SceneHasher() {
  if (sodium_init() < 0) throw Error("libsodium could not be initialised");
  AFR_CHECK(crypto_generichash_init(state_of(state_), nullptr, 0, 32) == 0);
}

void SceneHasher::update(std::span<const uint8_t> bytes) {
  AFR_CHECK(crypto_generichash_update(state_of(state_), bytes.data(), bytes.size()) == 0);
}

SceneHash SceneHasher::finish() {
  SceneHash h{};
  AFR_CHECK(crypto_generichash_final(state_of(state_), h.data(), h.size()) == 0);
  return h;
}

SceneHash scene_hash(std::span<const uint8_t> bytes) {
  SceneHasher hasher;
  hasher.update(bytes);
  return hasher.finish();
}

std::string to_hex(const SceneHash& hash) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string s(64, '0');
  for (size_t i = 0; i < hash.size(); ++i) {
    s[2 * i] = kDigits[hash[i] >> 4];
    s[2 * i + 1] = kDigits[hash[i] & 15];
  }
  return s;
}

}  // namespace afr::protocol
