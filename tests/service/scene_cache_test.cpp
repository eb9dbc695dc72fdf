#include <afr/common/builtin_scene.h>
#include <afr/display/service/display_service.h>
#include <afr/protocol/scene_hash.h>
#include <afr/sampler/service/scene_cache.h>

#include <gtest/gtest.h>

#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

namespace afr::service {
namespace {

// The display serves the built-in scene as builtin_scene_payload's text; the sampler's cache
// keeps it by hash and builds the scene from it, ray depth and all.
TEST(SceneCacheTest, TheDisplaysBuiltinPayloadLoadsAsTheBuiltinSceneWithItsRayDepth) {
  for (const std::optional<int> depth : {std::optional<int>(), std::optional<int>(2)}) {
    const ScenePayload served = read_scene_payload("", "", "", depth);
    EXPECT_EQ(served.name, "builtin");
    const Scene scene = load_scene_payload(served.bytes, served.name);
    EXPECT_EQ(scene.triangle_count(), make_builtin_scene().triangle_count());
    EXPECT_EQ(scene.ray_depth, depth);
  }
  // Two depths are two scenes to the cache.
  EXPECT_NE(read_scene_payload("", "", "", 2).hash, read_scene_payload("", "", "", 3).hash);
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
  const std::string text = builtin_scene_payload(4);
  const std::vector<uint8_t> bytes(text.begin(), text.end());
  const protocol::SceneHash hash = protocol::scene_hash(bytes);
  EXPECT_FALSE(cache.find(hash));
  const std::filesystem::path file = cache.store(hash, "builtin", bytes);
  ASSERT_TRUE(cache.find(hash));
  EXPECT_EQ(*cache.find(hash), file);
  EXPECT_EQ(file.extension(), ".builtin");
  EXPECT_GT(load_scene_payload(file).triangle_count(), 0u);
  EXPECT_EQ(load_scene_payload(file).ray_depth, 4);
  std::ofstream(file, std::ios::app) << "x";  // corrupt: the hash no longer matches
  EXPECT_FALSE(cache.find(hash));
  std::filesystem::remove_all(dir);
}

// The cache keeps at most its bound: storing a scene removes the least recently used others
// (a scene found counts as used) until the rest fit; the scene just stored stays even when it
// alone is larger; a write that never finished goes once it is an hour old, a recent one and
// files that are no cached scene stay.
TEST(SceneCacheTest, StoringKeepsTheCacheWithinItsBoundByDroppingTheLeastRecentlyUsed) {
  namespace fs = std::filesystem;
  const fs::path dir =
      fs::temp_directory_path() / ("afr-cache-bound-test-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  auto scene_of = [](int k, size_t size) {
    std::vector<uint8_t> bytes(size, uint8_t(k));
    std::memcpy(bytes.data(), "glTF", 4);
    return bytes;
  };
  // Four scenes of 1000 bytes in a cache of 2500: at most two fit.
  SceneCache cache(dir, 2500);
  std::vector<protocol::SceneHash> hashes;
  std::vector<fs::path> files;
  const auto old = fs::file_time_type::clock::now() - std::chrono::hours(3);
  for (int k = 0; k < 2; ++k) {
    const std::vector<uint8_t> bytes = scene_of(k, 1000);
    hashes.push_back(protocol::scene_hash(bytes));
    files.push_back(cache.store(hashes.back(), "s.glb", bytes));
    // Stored k hours apart (the first the oldest), without waiting for the clock.
    fs::last_write_time(files.back(), old + std::chrono::hours(k));
  }
  const fs::path stale = dir / "unfinished.glb.123.part", fresh = dir / "writing.glb.456.part";
  const fs::path other = dir / "notes.txt";
  for (const fs::path& p : {stale, fresh, other}) std::ofstream(p) << "x";
  fs::last_write_time(stale, old);
  ASSERT_TRUE(cache.find(hashes[0]));  // the older one, used now: the newer one is now the least
  const std::vector<uint8_t> third = scene_of(2, 1000);
  const fs::path third_file = cache.store(protocol::scene_hash(third), "s.glb", third);
  EXPECT_TRUE(fs::exists(files[0]));
  EXPECT_FALSE(fs::exists(files[1]));
  EXPECT_TRUE(fs::exists(third_file));
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(fresh));
  EXPECT_TRUE(fs::exists(other));
  // A scene larger than the whole bound stays, alone.
  const std::vector<uint8_t> big = scene_of(3, 4000);
  const fs::path big_file = cache.store(protocol::scene_hash(big), "s.glb", big);
  EXPECT_TRUE(fs::exists(big_file));
  EXPECT_FALSE(fs::exists(files[0]));
  EXPECT_FALSE(fs::exists(third_file));
  ASSERT_TRUE(cache.find(protocol::scene_hash(big)));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace afr::service
