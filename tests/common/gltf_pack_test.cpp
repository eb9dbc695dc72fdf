#include <afr/common/gltf_pack.h>

#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>
#include <afr/common/image.h>

#include "support/png.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <meshoptimizer.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <vector>

#include "support/base64.h"
#include "support/files.h"

namespace afr {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

using afr::testing::read_bytes;

void write_bytes(const fs::path& path, std::span<const uint8_t> bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

using afr::testing::write_text;

template <typename T>
void append(std::vector<uint8_t>* out, const std::vector<T>& values) {
  const auto* p = reinterpret_cast<const uint8_t*>(values.data());
  out->insert(out->end(), p, p + values.size() * sizeof(T));
}

uint32_t u32_at(std::span<const uint8_t> b, size_t at) {
  uint32_t v = 0;
  std::memcpy(&v, b.data() + at, 4);  // little-endian hosts only, as afr is
  return v;
}

// What `select` (select_material_variant or select_camera) throws choosing `choice` in `bytes`,
// or "no error".
std::string selection_error(std::vector<uint8_t> (*select)(std::span<const uint8_t>,
                                                           const fs::path&, std::string_view),
                            std::span<const uint8_t> bytes, const fs::path& path,
                            std::string_view choice) {
  try {
    (void)select(bytes, path, choice);
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

// The JSON and binary chunks of a .glb, read by the format's layout (independently of the
// packer's own reader).
struct GlbParts {
  json doc;
  std::vector<uint8_t> bin;
};
GlbParts split(std::span<const uint8_t> glb) {
  GlbParts parts;
  EXPECT_EQ(u32_at(glb, 0), 0x46546C67u);
  EXPECT_EQ(u32_at(glb, 4), 2u);
  EXPECT_EQ(u32_at(glb, 8), glb.size());
  const uint32_t json_size = u32_at(glb, 12);
  EXPECT_EQ(u32_at(glb, 16), 0x4E4F534Au);
  EXPECT_EQ(json_size % 4, 0u);
  parts.doc = json::parse(glb.begin() + 20, glb.begin() + 20 + json_size);
  const size_t bin_at = 20 + json_size;
  if (bin_at < glb.size()) {
    const uint32_t bin_size = u32_at(glb, bin_at);
    EXPECT_EQ(u32_at(glb, bin_at + 4), 0x004E4942u);
    EXPECT_EQ(bin_size % 4, 0u);
    EXPECT_EQ(bin_at + 8 + bin_size, glb.size());
    parts.bin.assign(glb.begin() + ptrdiff_t(bin_at) + 8, glb.end());
  }
  return parts;
}

// A textured quad as a user's exporter writes it: positions and uvs in an external .bin, the
// indices in a second buffer embedded as a data: URI, the texture an external PNG.
class GltfPackTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("afr-gltf-pack-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "scene" / "textures");
    fs::create_directories(dir_ / "alone");

    const std::vector<float> positions = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    const std::vector<float> uvs = {0, 1, 1, 1, 1, 0, 0, 0};
    const std::vector<uint16_t> indices = {0, 1, 2, 0, 2, 3};
    std::vector<uint8_t> geometry(4, 0xEE);  // a header the views skip
    append(&geometry, positions);
    append(&geometry, uvs);
    write_bytes(dir_ / "scene" / "geometry.bin", geometry);
    std::vector<uint8_t> index_bytes;
    append(&index_bytes, indices);

    DecodedImage checker{2, 2, 3, {255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255}};
    testing::write_png(checker, dir_ / "scene" / "textures" / "checker.png");

    doc_ = {
        {"asset", {{"version", "2.0"}}},
        {"scene", 0},
        {"scenes", {{{"nodes", {0}}}}},
        {"nodes", {{{"mesh", 0}}}},
        {"meshes",
         {{{"primitives",
            {{{"attributes", {{"POSITION", 0}, {"TEXCOORD_0", 1}}},
              {"indices", 2},
              {"material", 0}}}}}}},
        {"materials", {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}}},
        {"textures", {{{"source", 0}}}},
        {"images", {{{"uri", "textures/checker.png"}}}},
        {"accessors",
         {{{"bufferView", 0},
           {"componentType", 5126},
           {"count", 4},
           {"type", "VEC3"},
           {"min", {0, 0, 0}},
           {"max", {1, 1, 0}}},
          {{"bufferView", 1}, {"componentType", 5126}, {"count", 4}, {"type", "VEC2"}},
          {{"bufferView", 2}, {"componentType", 5123}, {"count", 6}, {"type", "SCALAR"}}}},
        {"bufferViews",
         {{{"buffer", 0}, {"byteOffset", 4}, {"byteLength", 48}},
          {{"buffer", 0}, {"byteOffset", 52}, {"byteLength", 32}},
          {{"buffer", 1}, {"byteLength", 12}}}},
        {"buffers",
         {{{"uri", "geometry.bin"}, {"byteLength", geometry.size()}},
          {{"uri", "data:application/octet-stream;base64," + testing::base64(index_bytes)},
           {"byteLength", index_bytes.size()}}}},
    };
    gltf_ = dir_ / "scene" / "quad.gltf";
    write_text(gltf_, doc_.dump(2));
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  // Each buffer's bytes as the original document has them.
  std::vector<std::vector<uint8_t>> original_buffers() const {
    return {read_bytes(dir_ / "scene" / "geometry.bin"), [] {
              std::vector<uint8_t> b;
              append(&b, std::vector<uint16_t>{0, 1, 2, 0, 2, 3});
              return b;
            }()};
  }

  fs::path dir_;
  fs::path gltf_;
  json doc_;
};

TEST_F(GltfPackTest, PackedSceneLoadsAloneAsTheGltfDoesBesideItsFiles) {
  const PackedGltf packed = pack_gltf(read_bytes(gltf_), gltf_);
  EXPECT_EQ(packed.packed_files,
            (std::vector<std::string>{"geometry.bin", "textures/checker.png"}));
  const fs::path alone = dir_ / "alone" / "quad.glb";
  write_bytes(alone, packed.glb);

  const Scene a = load_gltf(gltf_);
  const Scene b = load_gltf(alone);
  ASSERT_EQ(a.meshes.size(), 1u);
  ASSERT_EQ(b.meshes.size(), 1u);
  ASSERT_EQ(a.meshes[0].primitives.size(), 1u);
  ASSERT_EQ(b.meshes[0].primitives.size(), 1u);
  const Primitive& pa = a.meshes[0].primitives[0];
  const Primitive& pb = b.meshes[0].primitives[0];
  EXPECT_EQ(pa.positions, pb.positions);
  EXPECT_EQ(pa.uvs, pb.uvs);
  EXPECT_EQ(pa.indices, pb.indices);
  EXPECT_EQ(pb.positions[2], glm::vec3(1, 1, 0));
  EXPECT_EQ(pb.indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
  EXPECT_EQ(a.triangle_count(), b.triangle_count());
  ASSERT_EQ(a.textures.size(), 1u);
  ASSERT_EQ(b.textures.size(), 1u);
  EXPECT_EQ(b.textures[0].width, 2);
  EXPECT_EQ(a.textures[0].codes, b.textures[0].codes);
  // The same bytes as a .glb name, and from memory: one payload, nothing else read.
  const Scene c = load_gltf_bytes(packed.glb, dir_ / "alone" / "elsewhere.glb");
  EXPECT_EQ(c.meshes[0].primitives[0].positions, pa.positions);
}

TEST_F(GltfPackTest, EveryViewKeepsItsBytesAndImagesBecomeViews) {
  const PackedGltf packed = pack_gltf(read_bytes(gltf_), gltf_);
  const GlbParts parts = split(packed.glb);
  const std::vector<std::vector<uint8_t>> buffers = original_buffers();
  ASSERT_EQ(parts.doc["buffers"].size(), 1u);
  EXPECT_FALSE(parts.doc["buffers"][0].contains("uri"));
  EXPECT_LE(parts.doc["buffers"][0]["byteLength"].get<size_t>(), parts.bin.size());
  const json& views = parts.doc["bufferViews"];
  ASSERT_EQ(views.size(), doc_["bufferViews"].size() + 1);  // + the image's
  for (size_t i = 0; i < doc_["bufferViews"].size(); ++i) {
    const json& before = doc_["bufferViews"][i];
    const json& after = views[i];
    EXPECT_EQ(after["buffer"], 0);
    const size_t n = before["byteLength"].get<size_t>();
    const size_t from = before.value("byteOffset", size_t(0));
    const size_t to = after["byteOffset"].get<size_t>();
    const std::vector<uint8_t>& source = buffers[before["buffer"].get<size_t>()];
    ASSERT_LE(to + n, parts.bin.size());
    EXPECT_EQ(std::vector<uint8_t>(source.begin() + ptrdiff_t(from),
                                   source.begin() + ptrdiff_t(from + n)),
              std::vector<uint8_t>(parts.bin.begin() + ptrdiff_t(to),
                                   parts.bin.begin() + ptrdiff_t(to + n)))
        << "view " << i;
    // A buffer starts on an 8-byte boundary: every view keeps its alignment within it.
    EXPECT_EQ(to % 4, from % 4) << "view " << i;
  }
  const json& image = parts.doc["images"][0];
  EXPECT_FALSE(image.contains("uri"));
  EXPECT_EQ(image["mimeType"], "image/png");
  const json& view = views[image["bufferView"].get<size_t>()];
  const std::vector<uint8_t> png = read_bytes(dir_ / "scene" / "textures" / "checker.png");
  const size_t at = view["byteOffset"].get<size_t>();
  ASSERT_EQ(view["byteLength"].get<size_t>(), png.size());
  EXPECT_EQ(std::vector<uint8_t>(parts.bin.begin() + ptrdiff_t(at),
                                 parts.bin.begin() + ptrdiff_t(at + png.size())),
            png);
  // Everything else as written.
  EXPECT_EQ(parts.doc["meshes"], doc_["meshes"]);
  EXPECT_EQ(parts.doc["accessors"], doc_["accessors"]);
  EXPECT_EQ(parts.doc["materials"], doc_["materials"]);
}

TEST_F(GltfPackTest, GlbThatNamesAnExternalBufferIsPackedWithIt) {
  // Buffer 0 is the .glb's own chunk; buffer 1 an external file beside it (valid glTF, but
  // only the .glb would travel).
  const PackedGltf first = pack_gltf(read_bytes(gltf_), gltf_);
  GlbParts parts = split(first.glb);
  const std::vector<uint8_t> extra = {1, 2, 3, 4, 5, 6, 7, 8};
  write_bytes(dir_ / "scene" / "extra.bin", extra);
  parts.doc["buffers"].push_back({{"uri", "extra.bin"}, {"byteLength", 8}});
  parts.doc["bufferViews"].push_back({{"buffer", 1}, {"byteOffset", 4}, {"byteLength", 4}});
  const fs::path glb = dir_ / "scene" / "with-extra.glb";
  write_bytes(glb, make_glb(parts.doc.dump(), parts.bin));

  const PackedGltf packed = pack_gltf(read_bytes(glb), glb);
  EXPECT_EQ(packed.packed_files, std::vector<std::string>{"extra.bin"});
  const GlbParts again = split(packed.glb);
  ASSERT_EQ(again.doc["buffers"].size(), 1u);
  const json& view = again.doc["bufferViews"].back();
  const size_t at = view["byteOffset"].get<size_t>();
  EXPECT_EQ(std::vector<uint8_t>(again.bin.begin() + ptrdiff_t(at),
                                 again.bin.begin() + ptrdiff_t(at + 4)),
            (std::vector<uint8_t>{5, 6, 7, 8}));
  EXPECT_EQ(load_gltf_bytes(packed.glb, dir_ / "alone" / "x.glb").triangle_count(), 2u);
}

TEST_F(GltfPackTest, MissingShortOrOutsideFilesAreNamed) {
  const auto error_of = [&](const json& doc) {
    write_text(gltf_, doc.dump());
    try {
      (void)pack_gltf(read_bytes(gltf_), gltf_);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  json missing = doc_;
  missing["images"][0]["uri"] = "textures/nowhere.png";
  EXPECT_EQ(error_of(missing), gltf_.string() +
                                   ": images[0] refers to textures/nowhere.png: no such file in "
                                   "the folder of the glTF file");
  write_text(dir_ / "outside.bin", std::string(64, 'x'));
  json outside = doc_;
  outside["buffers"][0]["uri"] = "../outside.bin";
  EXPECT_NE(error_of(outside).find("buffers[0] refers to ../outside.bin: not a file inside the "
                                   "folder of the glTF file"),
            std::string::npos);
  json shorter = doc_;
  shorter["buffers"][0]["byteLength"] = 1000;
  EXPECT_NE(error_of(shorter).find("buffers[0] has 84 bytes, fewer than its byteLength 1000"),
            std::string::npos);
  json bad_view = doc_;
  bad_view["bufferViews"][2]["buffer"] = 7;
  EXPECT_NE(error_of(bad_view).find("bufferViews[2] refers to buffer 7, but there are 2"),
            std::string::npos);
  EXPECT_NE(error_of(json::array()).find("invalid glTF: not a JSON object"), std::string::npos);
}

// KHR_materials_variants: choosing a variant gives the file (a .gltf as text, a packed .glb as
// a .glb with its binary chunk) with each primitive that maps a material to the variant on that
// material, the others unchanged, and without the extension; it loads as such. An unknown
// name lists the file's variants; a file without variants, or with a malformed mapping, is
// named.
TEST_F(GltfPackTest, ChosenMaterialVariantBecomesThePrimitivesMaterial) {
  json doc = doc_;
  doc["materials"].push_back({{"name", "red"}});
  doc["materials"].push_back({{"name", "blue"}});
  json primitive = doc["meshes"][0]["primitives"][0];
  primitive["extensions"]["KHR_materials_variants"]["mappings"] = {
      {{"material", 1}, {"variants", {0}}}, {{"material", 2}, {"variants", {1, 2}}}};
  doc["meshes"][0]["primitives"].push_back(primitive);
  // A second mesh whose primitive maps only the first variant; and a primitive without a
  // material of its own, which the first variant gives one.
  json other = doc["meshes"][0]["primitives"][0];
  other["extensions"]["KHR_materials_variants"]["mappings"] = {
      {{"material", 1}, {"variants", {0}}}};
  json bare = other;
  bare.erase("material");
  doc["meshes"].push_back({{"primitives", {other, bare}}});
  doc["nodes"].push_back({{"mesh", 1}});
  doc["scenes"][0]["nodes"].push_back(1);
  doc["extensions"]["KHR_materials_variants"]["variants"] = {
      {{"name", "Red"}}, {{"name", "Blue"}}, {{"name", "Dark blue"}}};
  doc["extensionsUsed"] = {"KHR_materials_variants"};
  doc["extensionsRequired"] = {"KHR_materials_variants"};
  write_text(gltf_, doc.dump());
  const std::vector<uint8_t> file = read_bytes(gltf_);

  const std::vector<uint8_t> blue = select_material_variant(file, gltf_, "Blue");
  const json chosen = json::parse(blue.begin(), blue.end());
  EXPECT_EQ(chosen["meshes"][0]["primitives"][0]["material"], 0);  // no mappings: kept
  EXPECT_EQ(chosen["meshes"][0]["primitives"][1]["material"], 2);
  EXPECT_EQ(chosen["meshes"][1]["primitives"][0]["material"], 0);  // none for Blue: kept
  EXPECT_FALSE(chosen["meshes"][1]["primitives"][1].contains("material"));
  EXPECT_FALSE(chosen["meshes"][0]["primitives"][1].contains("extensions"));
  EXPECT_FALSE(chosen.contains("extensions"));
  EXPECT_FALSE(chosen.contains("extensionsRequired"));
  EXPECT_EQ(chosen["buffers"], doc["buffers"]);
  const Scene scene = load_gltf_bytes(blue, gltf_);
  EXPECT_EQ(scene.meshes[0].primitives[1].material, 2);
  EXPECT_EQ(scene.meshes[1].primitives[0].material, 0);

  const PackedGltf packed = pack_gltf(file, gltf_);
  const std::vector<uint8_t> red = select_material_variant(packed.glb, gltf_, "Red");
  const GlbParts parts = split(red);
  EXPECT_EQ(parts.bin, split(packed.glb).bin);
  EXPECT_EQ(parts.doc["meshes"][0]["primitives"][1]["material"], 1);
  EXPECT_EQ(parts.doc["meshes"][1]["primitives"][0]["material"], 1);
  EXPECT_EQ(parts.doc["meshes"][1]["primitives"][1]["material"], 1);
  fs::create_directories(dir_ / "alone");
  EXPECT_EQ(load_gltf_bytes(red, dir_ / "alone" / "quad.glb").meshes[1].primitives[0].material, 1);

  const auto error_of = [&](std::span<const uint8_t> bytes, std::string_view variant) {
    return selection_error(&select_material_variant, bytes, gltf_, variant);
  };
  EXPECT_EQ(error_of(file, "Green"),
            gltf_.string() +
                ": no material variant \"Green\" (the file has \"Red\", \"Blue\", \"Dark blue\")");
  EXPECT_EQ(error_of(read_bytes(dir_ / "scene" / "geometry.bin"), "Red"),
            gltf_.string() + ": invalid glTF: not a JSON object");
  write_text(gltf_, doc_.dump());
  EXPECT_EQ(error_of(read_bytes(gltf_), "Red"),
            gltf_.string() + ": no material variant \"Red\": the file has none");
  doc["meshes"][0]["primitives"][1]["extensions"]["KHR_materials_variants"]["mappings"][0].erase(
      "material");
  write_text(gltf_, doc.dump());
  EXPECT_NE(error_of(read_bytes(gltf_), "Red")
                .find("mesh 0 primitive 1 KHR_materials_variants has a mapping without a "
                      "material index and a variants array"),
            std::string::npos);
}

// Choosing a camera leaves the camera on the chosen node alone, so that the loader's camera
// node is that one: by a node's name, by a camera's name or by index (each its first node), in
// a .gltf and a packed .glb alike. An unknown camera lists the file's; a camera on a node
// outside the displayed scene is named once the scene is loaded (check_chosen_camera).
TEST_F(GltfPackTest, ChosenCameraIsTheScenesCamera) {
  json doc = doc_;
  const json perspective = {{"type", "perspective"},
                            {"perspective", {{"yfov", 0.5}, {"znear", 0.1}}}};
  doc["cameras"] = {perspective, perspective, perspective};
  doc["cameras"][0]["name"] = "Main";
  doc["cameras"][1]["name"] = "Side";
  doc["cameras"][1]["perspective"]["yfov"] = 0.9;
  doc["nodes"].push_back({{"name", "main node"}, {"camera", 0}});  // 1
  doc["nodes"].push_back({{"name", "side node"}, {"camera", 1}});  // 2
  doc["nodes"].push_back({{"name", "far side"}, {"camera", 1}, {"translation", {0, 0, 9}}});
  doc["nodes"].push_back({{"name", "off stage"}, {"camera", 2}});  // 4
  doc["scenes"][0]["nodes"] = {0, 1, 2, 3};                        // node 4 is in no scene
  write_text(gltf_, doc.dump());
  const std::vector<uint8_t> file = read_bytes(gltf_);
  EXPECT_EQ(load_gltf_bytes(file, gltf_).camera_node(), 1);  // the default: the first

  const auto kept = [](std::span<const uint8_t> bytes) {
    const json chosen = is_glb(bytes) ? split(bytes).doc : json::parse(bytes.begin(), bytes.end());
    std::vector<int> nodes;
    for (size_t n = 0; n < chosen["nodes"].size(); ++n) {
      if (chosen["nodes"][n].contains("camera")) nodes.push_back(int(n));
    }
    return nodes;
  };
  EXPECT_EQ(kept(select_camera(file, gltf_, "Side")), std::vector<int>{2});
  EXPECT_EQ(kept(select_camera(file, gltf_, "1")), std::vector<int>{2});
  EXPECT_EQ(kept(select_camera(file, gltf_, "far side")), std::vector<int>{3});
  EXPECT_EQ(kept(select_camera(file, gltf_, "0")), std::vector<int>{1});
  const std::vector<uint8_t> side = select_camera(file, gltf_, "far side");
  const Scene scene = load_gltf_bytes(side, gltf_);
  EXPECT_EQ(scene.camera_node(), 3);
  EXPECT_NEAR(scene.camera_at(scene.evaluate(0.0)).yfov, 0.9, 1e-6);
  EXPECT_NO_THROW(check_chosen_camera(scene, "far side"));

  const PackedGltf packed = pack_gltf(file, gltf_);
  const std::vector<uint8_t> glb = select_camera(packed.glb, gltf_, "Main");
  EXPECT_EQ(split(glb).bin, split(packed.glb).bin);
  EXPECT_EQ(kept(glb), std::vector<int>{1});
  fs::create_directories(dir_ / "alone");
  EXPECT_EQ(load_gltf_bytes(glb, dir_ / "alone" / "quad.glb").camera_node(), 1);

  // Camera 2 is on node 4, which no scene shows: the loaded scene has no camera node.
  const Scene off = load_gltf_bytes(select_camera(file, gltf_, "2"), gltf_);
  EXPECT_EQ(off.camera_node(), -1);
  try {
    check_chosen_camera(off, "2");
    ADD_FAILURE() << "a camera outside the displayed scene was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              gltf_.string() + ": camera \"2\" is on no node of the displayed scene");
  }

  const auto error_of = [&](std::span<const uint8_t> bytes, std::string_view camera) {
    return selection_error(&select_camera, bytes, gltf_, camera);
  };
  EXPECT_EQ(error_of(file, "Top"),
            gltf_.string() +
                ": no camera \"Top\" (the file's cameras: 0 \"Main\" on node "
                "\"main node\", 1 \"Side\" on node \"side node\", 2 on node "
                "\"off stage\")");
  EXPECT_NE(error_of(file, "3").find("no camera \"3\""), std::string::npos);
  doc["nodes"].erase(4);
  doc["scenes"][0]["nodes"] = {0, 1, 2, 3};
  write_text(gltf_, doc.dump());
  EXPECT_EQ(error_of(read_bytes(gltf_), "2"),
            gltf_.string() + ": camera \"2\" (cameras[2]) is on no node");
  write_text(gltf_, doc_.dump());
  EXPECT_EQ(error_of(read_bytes(gltf_), "Main"),
            gltf_.string() + ": no camera \"Main\": the file has none");
}

// set_ray_depth writes the root's extras.afr_ray_depth, which the loader reads as
// Scene::ray_depth, in a .gltf and in a .glb (whose binary chunk stays as it was), beside other
// extras and over an earlier depth; a depth out of range and root extras that are not an object
// are errors naming the file.
TEST_F(GltfPackTest, RayDepthIsWrittenWhereTheLoaderReadsIt) {
  json doc = doc_;
  doc["extras"] = {{"author", "someone"}, {"afr_ray_depth", 2}};
  write_text(gltf_, doc.dump());
  const std::vector<uint8_t> file = read_bytes(gltf_);
  EXPECT_EQ(load_gltf_bytes(file, gltf_).ray_depth, std::optional<int>(2));
  const std::vector<uint8_t> deeper = set_ray_depth(file, gltf_, 6);
  const json written = json::parse(deeper.begin(), deeper.end());
  EXPECT_EQ(written["extras"]["afr_ray_depth"], 6);
  EXPECT_EQ(written["extras"]["author"], "someone");
  EXPECT_EQ(load_gltf_bytes(deeper, gltf_).ray_depth, std::optional<int>(6));

  write_text(gltf_, doc_.dump());
  EXPECT_EQ(load_gltf_bytes(read_bytes(gltf_), gltf_).ray_depth, std::nullopt);
  const PackedGltf packed = pack_gltf(read_bytes(gltf_), gltf_);
  const std::vector<uint8_t> glb = set_ray_depth(packed.glb, gltf_, 0);
  EXPECT_EQ(split(glb).bin, split(packed.glb).bin);
  fs::create_directories(dir_ / "alone");
  EXPECT_EQ(load_gltf_bytes(glb, dir_ / "alone" / "quad.glb").ray_depth, std::optional<int>(0));

  const auto error_of = [&](std::span<const uint8_t> bytes, int depth) -> std::string {
    try {
      (void)set_ray_depth(bytes, gltf_, depth);
    } catch (const Error& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_EQ(error_of(file, kMaxRayDepth + 1),
            fmt::format("{}: a ray depth of {} is outside 0 to {}", gltf_.string(),
                        kMaxRayDepth + 1, kMaxRayDepth));
  EXPECT_EQ(error_of(file, -1),
            fmt::format("{}: a ray depth of -1 is outside 0 to {}", gltf_.string(), kMaxRayDepth));
  doc["extras"] = "a note";
  write_text(gltf_, doc.dump());
  EXPECT_EQ(error_of(read_bytes(gltf_), 4),
            gltf_.string() +
                ": the root's extras is not an object, so afr_ray_depth cannot be added to it");
}

// EXT_meshopt_compression: the compressed data (an external .bin) is packed; the placeholder
// buffer without a uri and the fallback buffer (whose file is missing: a reader that decodes
// never needs it) are kept without data after the binary chunk's, the views that name them
// still naming them, and the packed scene loads alone as the file does. The fallback's file is
// not one of the scene's files.
TEST_F(GltfPackTest, MeshoptPlaceholderAndFallbackBuffersTravelWithoutData) {
  const std::vector<float> positions = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const std::vector<uint32_t> indices = {0, 1, 2, 0, 2, 3};
  std::vector<uint8_t> vertices(meshopt_encodeVertexBufferBound(4, 12));
  vertices.resize(
      meshopt_encodeVertexBuffer(vertices.data(), vertices.size(), positions.data(), 4, 12));
  std::vector<uint8_t> triangles(meshopt_encodeIndexBufferBound(6, 4));
  triangles.resize(
      meshopt_encodeIndexBuffer(triangles.data(), triangles.size(), indices.data(), 6));
  std::vector<uint8_t> compressed(4, 0xEE);  // a header the views skip
  compressed.insert(compressed.end(), vertices.begin(), vertices.end());
  const size_t triangles_at = (compressed.size() + 3) / 4 * 4;
  compressed.resize(triangles_at, 0);
  compressed.insert(compressed.end(), triangles.begin(), triangles.end());
  write_bytes(dir_ / "scene" / "compressed.bin", compressed);

  json doc = doc_;
  doc["meshes"][0]["primitives"][0]["attributes"].erase("TEXCOORD_0");
  doc["meshes"][0]["primitives"][0].erase("material");
  doc.erase("materials");
  doc.erase("textures");
  doc.erase("images");
  doc["accessors"][2]["componentType"] = 5123;
  doc["bufferViews"] = {{{"buffer", 1},
                         {"byteLength", 48},
                         {"extensions",
                          {{"EXT_meshopt_compression",
                            {{"buffer", 0},
                             {"byteOffset", 4},
                             {"byteLength", vertices.size()},
                             {"byteStride", 12},
                             {"count", 4},
                             {"mode", "ATTRIBUTES"}}}}}},
                        {{"buffer", 2}, {"byteLength", 8}},  // not read: accessor 1 is not used
                        {{"buffer", 2},
                         {"byteOffset", 8},
                         {"byteLength", 12},
                         {"extensions",
                          {{"EXT_meshopt_compression",
                            {{"buffer", 0},
                             {"byteOffset", triangles_at},
                             {"byteLength", triangles.size()},
                             {"byteStride", 2},
                             {"count", 6},
                             {"mode", "TRIANGLES"}}}}}}};
  doc["buffers"] = {{{"uri", "compressed.bin"}, {"byteLength", compressed.size()}},
                    {{"byteLength", 48}},
                    {{"uri", "fallback.bin"},
                     {"byteLength", 20},
                     {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}}};
  doc["extensionsUsed"] = {"EXT_meshopt_compression"};
  doc["extensionsRequired"] = {"EXT_meshopt_compression"};
  write_text(gltf_, doc.dump(2));

  EXPECT_EQ(gltf_external_files(read_bytes(gltf_), gltf_),
            std::vector<std::string>{"compressed.bin"});
  const PackedGltf packed = pack_gltf(read_bytes(gltf_), gltf_);
  EXPECT_EQ(packed.packed_files, std::vector<std::string>{"compressed.bin"});
  const GlbParts parts = split(packed.glb);
  ASSERT_EQ(parts.doc["buffers"].size(), 3u);
  EXPECT_FALSE(parts.doc["buffers"][1].contains("uri"));
  EXPECT_FALSE(parts.doc["buffers"][2].contains("uri"));
  EXPECT_EQ(parts.doc["buffers"][2]["extensions"], doc["buffers"][2]["extensions"]);
  EXPECT_EQ(parts.doc["bufferViews"][0]["buffer"], 1);
  EXPECT_EQ(parts.doc["bufferViews"][2]["buffer"], 2);
  EXPECT_EQ(parts.doc["bufferViews"][2]["byteOffset"], 8);
  const json& ext = parts.doc["bufferViews"][0]["extensions"]["EXT_meshopt_compression"];
  EXPECT_EQ(ext["buffer"], 0);
  const size_t at = ext["byteOffset"].get<size_t>();
  ASSERT_LE(at + vertices.size(), parts.bin.size());
  EXPECT_EQ(std::vector<uint8_t>(parts.bin.begin() + ptrdiff_t(at),
                                 parts.bin.begin() + ptrdiff_t(at + vertices.size())),
            vertices);

  const Scene a = load_gltf(gltf_);
  const Scene b = load_gltf_bytes(packed.glb, dir_ / "alone" / "quad.glb");
  const Primitive& pa = a.meshes.at(0).primitives.at(0);
  const Primitive& pb = b.meshes.at(0).primitives.at(0);
  EXPECT_EQ(pa.positions, pb.positions);
  EXPECT_EQ(pa.indices, pb.indices);
  EXPECT_EQ(pb.positions[2], glm::vec3(1, 1, 0));
  EXPECT_EQ(pb.indices.size(), 6u);
}

TEST(GlbTest, ChunksArePaddedAndTheHeaderGivesTheLength) {
  const std::vector<uint8_t> bin = {1, 2, 3, 4, 5};
  const std::vector<uint8_t> glb = make_glb(R"({"asset":{"version":"2.0"}})", bin);
  EXPECT_TRUE(is_glb(glb));
  const GlbParts parts = split(glb);
  EXPECT_EQ(parts.doc["asset"]["version"], "2.0");
  EXPECT_EQ(parts.bin, (std::vector<uint8_t>{1, 2, 3, 4, 5, 0, 0, 0}));
  const std::vector<uint8_t> bare = make_glb("{}", {});
  EXPECT_EQ(bare.size(), 12u + 8u + 4u);  // "{}" padded with two spaces; no binary chunk
  EXPECT_EQ(bare[22], ' ');
}

}  // namespace
}  // namespace afr
