#include <afr/display/service/display_service.h>
#include <afr/protocol/scene_hash.h>
#include <afr/sampler/service/scene_cache.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

namespace afr::service {
namespace {

TEST(SceneCacheTest, BuiltinPayloadTextsOfBothNodesAgree) {
  EXPECT_EQ(kBuiltinScenePayload, kBuiltinSceneBytes);
}

TEST(SceneCacheTest, ChunksInAnyOrderReassembleTheScene) {
  std::vector<uint8_t> bytes(10000);
  std::mt19937 rng(1);
  for (uint8_t& b : bytes) b = uint8_t(rng());
  const protocol::SceneHash hash = protocol::scene_hash(bytes);
  SceneAssembler a;
  a.reset(hash, bytes.size());
  const uint32_t count = 4;
  for (uint32_t i : {2u, 0u, 3u, 0u, 1u}) {
    protocol::SceneChunk c;
    c.scene_hash = hash;
    c.scene_size = bytes.size();
    c.index = i;
    c.count = count;
    c.offset = i * 2500;
    c.bytes.assign(bytes.begin() + c.offset, bytes.begin() + c.offset + 2500);
    EXPECT_EQ(a.add(c), "");
    if (i == 0) {
      EXPECT_EQ(a.next_chunk(), 1u);
    }
  }
  ASSERT_TRUE(a.complete());
  EXPECT_EQ(a.bytes(), bytes);
  protocol::SceneChunk other;
  other.scene_size = 5;
  EXPECT_NE(a.add(other), "");
}

TEST(SceneCacheTest, StoredSceneIsFoundByHashAndACorruptOneIsNot) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("afr-cache-test-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  SceneCache cache(dir);
  const std::vector<uint8_t> bytes(kBuiltinScenePayload.begin(), kBuiltinScenePayload.end());
  const protocol::SceneHash hash = protocol::scene_hash(bytes);
  EXPECT_FALSE(cache.find(hash));
  const std::filesystem::path file = cache.store(hash, "builtin", bytes);
  ASSERT_TRUE(cache.find(hash));
  EXPECT_EQ(*cache.find(hash), file);
  EXPECT_GT(load_scene_payload(file).triangle_count(), 0u);
  std::ofstream(file, std::ios::app) << "x";  // corrupt: the hash no longer matches
  EXPECT_FALSE(cache.find(hash));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace afr::service
