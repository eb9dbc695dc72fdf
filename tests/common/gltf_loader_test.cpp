// The glTF loader's tests of the file as a whole: parsing, broken and hostile files, the
// extensions it does not read, loading from memory, and the built-in scene.
#include "gltf_loader_test.h"

namespace afr {
namespace {

using namespace gltf_test;

// The root's extras.afr_ray_depth is the scene's ray depth (Scene::ray_depth): a whole number
// from 0 to kMaxRayDepth; anything else is an error naming the file and the extra.
TEST_F(GltfLoaderTest, RayDepthExtraIsAWholeNumberInRange) {
  const fs::path path = dir_ / "deep.gltf";
  const auto write_with = [&](const json& depth) {
    GltfBuilder b;
    add_quad(&b);
    b.doc()["extras"] = {{"afr_ray_depth", depth}};
    b.write_embedded(path);
  };
  for (int depth : {0, 5, kMaxRayDepth}) {
    write_with(depth);
    EXPECT_EQ(load_gltf(path).ray_depth, std::optional<int>(depth));
  }
  write_with(4.0);  // a whole number written as a float
  EXPECT_EQ(load_gltf(path).ray_depth, std::optional<int>(4));
  write_with(nullptr);  // null, as JSON reads it: not given
  EXPECT_EQ(load_gltf(path).ray_depth, std::nullopt);
  for (const json& bad : {json(kMaxRayDepth + 1), json(-1), json(2.5), json("deep")}) {
    SCOPED_TRACE(bad.dump());
    write_with(bad);
    expect_error(path, "extras \"afr_ray_depth\" is not a whole number from 0 to 10");
  }
}

TEST_F(GltfLoaderTest, UnsupportedFeaturesWarnOnceEachAndTheSceneStillLoads) {
  GltfBuilder b;
  const int positions = add_quad(&b);
  // An unknown extension in two places, two line primitives, an unknown interpolation used
  // twice, a morph target of texture coordinates used twice and two
  // channels without a target node (glTF allows them, for extensions to drive).
  b.doc()["nodes"] = json::array({{{"mesh", 0}, {"children", {1}}}, {{"mesh", 0}}});
  b.doc()["extensionsUsed"] = {"EXT_made_up"};
  b.doc()["materials"] = json::array({{{"extensions", {{"EXT_made_up", {{"x", 1}}}}}}});
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["meshes"][0]["primitives"][0]["extensions"] = {{"EXT_made_up", json::object()}};
  const int uv_deltas = b.add_floats({0, 0, 0, 0, 0, 0, 0, 0}, 2);
  const json targets = json::array(
      {{{"POSITION", positions}, {"TEXCOORD_0", uv_deltas}}, {{"TEXCOORD_0", uv_deltas}}});
  b.doc()["meshes"][0]["primitives"][0]["targets"] = targets;
  b.doc()["meshes"][0]["primitives"].push_back(
      {{"attributes", {{"POSITION", positions}}}, {"mode", 1}, {"targets", targets}});
  b.doc()["meshes"][0]["primitives"].push_back(
      {{"attributes", {{"POSITION", positions}}}, {"mode", 1}, {"targets", targets}});
  // Two primitives without positions, which glTF allows and asks readers to skip.
  b.doc()["meshes"][0]["primitives"].push_back(
      {{"attributes", {{"TEXCOORD_0", uv_deltas}}}, {"targets", targets}});
  b.doc()["meshes"][0]["primitives"].push_back({{"attributes", json::object()},
                                                {"indices", b.add_indices16({0, 1, 2})},
                                                {"targets", targets}});
  const int times = b.add_floats({0, 1}, 1);
  const int values = b.add_floats({0, 0, 0, 1, 1, 1}, 3);
  // Empty tracks, as exporters write them: two channels of a sampler with no keys.
  json no_keys = b.doc()["accessors"][size_t(times)];
  no_keys["count"] = 0;
  no_keys.erase("min");
  no_keys.erase("max");
  b.doc()["accessors"].push_back(no_keys);
  const int empty_times = int(b.doc()["accessors"].size()) - 1;
  no_keys["type"] = "VEC3";
  b.doc()["accessors"].push_back(no_keys);
  const int empty_values = int(b.doc()["accessors"].size()) - 1;
  b.doc()["animations"] =
      json::array({{{"channels",
                     {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}},
                      {{"sampler", 0}, {"target", {{"node", 1}, {"path", "translation"}}}},
                      {{"sampler", 1}, {"target", {{"node", 1}, {"path", "scale"}}}},
                      {{"sampler", 1}, {"target", {{"path", "scale"}}}},
                      {{"sampler", 1}, {"target", {{"path", "translation"}}}},
                      {{"sampler", 2}, {"target", {{"node", 0}, {"path", "scale"}}}},
                      {{"sampler", 2}, {"target", {{"node", 1}, {"path", "translation"}}}}}},
                    {"samplers",
                     {{{"input", times}, {"output", values}, {"interpolation", "SMOOTHSTEP"}},
                      {{"input", times}, {"output", values}},
                      {{"input", empty_times}, {"output", empty_values}}}}}});
  const fs::path path = dir_ / "unsupported.gltf";
  b.write_embedded(path);

  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  for (const std::string& w : report.warnings) {
    EXPECT_NE(w.find(path.string()), std::string::npos) << w;
  }
  EXPECT_EQ(count_containing(report.warnings, "EXT_made_up"), 1u);
  EXPECT_EQ(count_containing(report.warnings, "mode 1"), 1u);
  EXPECT_EQ(count_containing(report.warnings, "SMOOTHSTEP"), 1u);
  EXPECT_EQ(count_containing(report.warnings, "morph targets of TEXCOORD_0"), 1u);
  EXPECT_EQ(count_containing(report.warnings, "without a target node"), 1u);
  EXPECT_EQ(count_containing(report.warnings,
                             "without a POSITION attribute draw nothing and are skipped, as glTF "
                             "asks (mesh 0 primitive 3 is the first)"),
            1u);
  EXPECT_EQ(count_containing(report.warnings,
                             "without keyframes animate nothing and are skipped (animation 0 "
                             "channel 5 is the first)"),
            1u);
  EXPECT_EQ(report.warnings.size(), 7u);

  ASSERT_EQ(scene.meshes.size(), 1u);
  ASSERT_EQ(scene.meshes[0].primitives.size(), 1u);
  EXPECT_EQ(scene.meshes[0].primitives[0].triangle_count(), 2u);
  EXPECT_EQ(scene.meshes[0].primitives[0].targets.size(), 2u);  // positions kept
  ASSERT_EQ(scene.channels.size(), 1u);
  EXPECT_EQ(scene.channels[0].path, AnimatedPath::kScale);
}

TEST_F(GltfLoaderTest, MissingFileFails) { expect_error(dir_ / "absent.gltf", "no such file"); }

TEST_F(GltfLoaderTest, TruncatedGlbFails) {
  GltfBuilder b;
  add_quad(&b);
  const fs::path path = dir_ / "cut.glb";
  b.write_glb(path);
  EXPECT_EQ(load_gltf(path).meshes.at(0).primitives.at(0).positions.size(), 4u);
  std::vector<uint8_t> bytes = read_bytes(path);
  bytes.resize(bytes.size() / 2);
  write_bytes(path, bytes.data(), bytes.size());
  expect_error(path, "truncated");
}

// What is wrong with a .glb's header and chunks is named (tinygltf says only "Invalid glTF
// binary."), and a chunk of an unknown type is skipped, as glTF 2.0 (4.4.3.1) asks.
TEST_F(GltfLoaderTest, GlbLayoutErrorsAreNamedAndUnknownChunksSkipped) {
  GltfBuilder b;
  add_quad(&b);
  const fs::path good = dir_ / "good.glb";
  b.write_glb(good);
  const std::vector<uint8_t> bytes = read_bytes(good);
  const auto u32 = [](std::vector<uint8_t>* v, size_t at, uint32_t x) {
    for (int i = 0; i < 4; ++i) (*v)[at + size_t(i)] = uint8_t(x >> (8 * i));
  };
  const auto variant = [&](const std::string& name, std::vector<uint8_t> v) {
    const fs::path path = dir_ / name;
    write_bytes(path, v.data(), v.size());
    return path;
  };
  std::vector<uint8_t> v = bytes;
  u32(&v, 4, 1);
  expect_error(variant("version.glb", v), "version 1");
  v.assign(bytes.begin(), bytes.begin() + 12);
  u32(&v, 8, 12);
  expect_error(variant("header_only.glb", v), "no JSON chunk");
  v.assign(bytes.begin(), bytes.begin() + 16);
  u32(&v, 8, 16);
  expect_error(variant("half_chunk_header.glb", v), "has 4 of its 8 header bytes");
  v = bytes;
  u32(&v, 12, 1u << 30);
  expect_error(variant("chunk_too_long.glb", v), "chunk 0 declares 1073741824 bytes");
  v = bytes;
  u32(&v, 16, 0x004E4942);
  expect_error(variant("bin_first.glb", v), "not JSON");

  // An unknown chunk between the JSON and the BIN chunk: skipped, with a warning.
  const uint32_t json_length = uint32_t(bytes[12]) | uint32_t(bytes[13]) << 8 |
                               uint32_t(bytes[14]) << 16 | uint32_t(bytes[15]) << 24;
  v.assign(bytes.begin(), bytes.begin() + 20 + json_length);
  const std::vector<uint8_t> extra = {4, 0, 0, 0, 'X', 'T', 'R', 'A', 1, 2, 3, 4};
  v.insert(v.end(), extra.begin(), extra.end());
  v.insert(v.end(), bytes.begin() + 20 + json_length, bytes.end());
  u32(&v, 8, uint32_t(v.size()));
  GltfLoadReport report;
  const Scene scene = load_gltf(variant("extra_chunk.glb", v), &report);
  EXPECT_EQ(scene.meshes.at(0).primitives.at(0).positions.size(), 4u);
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("unknown type"), std::string::npos) << report.warnings[0];

  // A second BIN chunk (one is allowed): the first is the buffer, the second is skipped.
  v = bytes;
  const std::vector<uint8_t> second_bin = {4, 0, 0, 0, 'B', 'I', 'N', 0, 9, 9, 9, 9};
  v.insert(v.end(), second_bin.begin(), second_bin.end());
  u32(&v, 8, uint32_t(v.size()));
  GltfLoadReport report2;
  const Scene scene2 = load_gltf(variant("two_bin.glb", v), &report2);
  EXPECT_EQ(scene2.meshes.at(0).primitives.at(0).positions.at(2), glm::vec3(1, 1, 0));
  ASSERT_EQ(report2.warnings.size(), 1u);
  EXPECT_NE(report2.warnings[0].find("second BIN chunk"), std::string::npos) << report2.warnings[0];

  // Chunks left unpadded (the format pads each to 4 bytes; some writers do not): read as if
  // padded, with one warning. Here both are 2 bytes short of a multiple of 4.
  GltfBuilder odd;
  add_quad(&odd);
  odd.add_view(std::vector<uint8_t>{7, 7});  // the buffer ends 2 bytes past a multiple of 4
  json doc = odd.doc();
  doc["buffers"] = json::array({{{"byteLength", odd.bin().size()}}});
  std::string text = doc.dump();
  while (text.size() % 4 != 2) text += ' ';
  v.clear();
  const auto put = [&](uint32_t x) {
    for (int i = 0; i < 4; ++i) v.push_back(uint8_t(x >> (8 * i)));
  };
  v.insert(v.end(), {'g', 'l', 'T', 'F'});
  put(2);
  put(uint32_t(12 + 8 + text.size() + 8 + odd.bin().size()));
  put(uint32_t(text.size()));
  put(0x4E4F534A);
  v.insert(v.end(), text.begin(), text.end());
  put(uint32_t(odd.bin().size()));
  put(0x004E4942);
  v.insert(v.end(), odd.bin().begin(), odd.bin().end());
  ASSERT_EQ(odd.bin().size() % 4, 2u);
  GltfLoadReport report3;
  const Scene scene3 = load_gltf(variant("unpadded.glb", v), &report3);
  EXPECT_EQ(scene3.meshes.at(0).primitives.at(0).positions.at(2), glm::vec3(1, 1, 0));
  EXPECT_EQ(scene3.meshes.at(0).primitives.at(0).indices.size(), 6u);
  EXPECT_EQ(count_containing(report3.warnings, "not a multiple of 4"), 1u);
}

TEST_F(GltfLoaderTest, TruncatedBinFails) {
  GltfBuilder b;
  add_quad(&b);
  const fs::path path = dir_ / "external.gltf";
  b.write_external(path, "external.bin");
  EXPECT_EQ(load_gltf(path).meshes.at(0).primitives.at(0).positions.size(), 4u);
  fs::resize_file(dir_ / "external.bin", b.bin().size() - 8);
  expect_error(path, "external.bin");
  expect_error(path, "size");
}

TEST_F(GltfLoaderTest, MalformedJsonFails) {
  const fs::path path = dir_ / "malformed.gltf";
  write_text(path, R"({"asset": {"version": "2.0"}, "nodes": [{"mesh": 0}, }])");
  expect_error(path, "parse error");
}

// glTF 1.0 (objects keyed by ID, which tinygltf reads as an empty scene) and a file that needs a
// later 2.x are refused naming the version; a later 2.x that 2.0 can read loads.
TEST_F(GltfLoaderTest, OtherGltfVersionsAreRefusedNamingTheVersion) {
  const fs::path v1 = dir_ / "v1.gltf";
  write_text(v1, R"({"asset": {"version": "1.0"}, "meshes": {"box": {"primitives": []}},
                     "scene": "main", "scenes": {"main": {"nodes": []}}})");
  expect_error(v1, "glTF 1.0: afr reads glTF 2.0");
  write_text(v1, R"({"asset": {"version": 1}, "meshes": {}})");  // as some 1.0 exporters wrote it
  expect_error(v1, "glTF 1: afr reads glTF 2.0");

  GltfBuilder b;
  add_quad(&b);
  const fs::path path = dir_ / "versions.gltf";
  b.doc()["asset"] = {{"version", "2.3"}};
  b.write_embedded(path);
  EXPECT_EQ(load_gltf(path).triangle_count(), 2u);
  b.doc()["asset"]["minVersion"] = "2.0";
  b.write_embedded(path);
  EXPECT_EQ(load_gltf(path).triangle_count(), 2u);
  b.doc()["asset"]["minVersion"] = "2.1";
  b.write_embedded(path);
  expect_error(path, "requires glTF 2.1 (asset.minVersion)");
  b.doc()["asset"] = {{"version", "3.0"}};
  b.write_glb(dir_ / "versions.glb");
  expect_error(dir_ / "versions.glb", "glTF 3.0: afr reads glTF 2.0");
  b.doc()["asset"] = {{"version", "two"}};
  b.write_embedded(path);
  expect_error(path, "asset.version \"two\" is not a glTF version");
}

// A valid file whose displayed scene draws nothing loads, and says so once.
TEST_F(GltfLoaderTest, ASceneWithNothingToDrawLoadsWithAWarning) {
  GltfBuilder b;
  add_quad(&b);
  const fs::path path = dir_ / "empty.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  EXPECT_EQ(load_gltf(path, &report).triangle_count(), 2u);
  EXPECT_EQ(count_containing(report.warnings, "no triangles"), 0u);

  b.doc()["nodes"][0].erase("mesh");  // the mesh stays in the file, drawn by no node
  b.write_embedded(path);
  report = {};
  EXPECT_EQ(load_gltf(path, &report).triangle_count(), 0u);
  EXPECT_EQ(count_containing(report.warnings, "the displayed scene has no triangles"), 1u);
}

TEST_F(GltfLoaderTest, BadReferencesFail) {
  {
    GltfBuilder b;
    add_quad(&b);
    b.doc()["nodes"][0]["mesh"] = 7;
    b.write_embedded(dir_ / "bad_mesh.gltf");
  }
  expect_error(dir_ / "bad_mesh.gltf", "mesh 7");
  {
    GltfBuilder b;
    add_quad(&b);
    b.doc()["meshes"][0]["primitives"][0]["material"] = 3;
    b.write_embedded(dir_ / "bad_material.gltf");
  }
  expect_error(dir_ / "bad_material.gltf", "material 3");
  {
    GltfBuilder b;
    add_quad(&b);
    b.doc()["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = 42;
    b.write_embedded(dir_ / "bad_accessor.gltf");
  }
  expect_error(dir_ / "bad_accessor.gltf", "accessor 42");
  {  // an attribute afr has no use for, in a primitive it would skip for lack of positions
    GltfBuilder b;
    add_quad(&b);
    b.doc()["meshes"][0]["primitives"][0]["attributes"] = {{"TEXCOORD_5", 9}};
    b.write_embedded(dir_ / "bad_unused_accessor.gltf");
  }
  expect_error(dir_ / "bad_unused_accessor.gltf",
               "mesh 0 primitive 0 attribute TEXCOORD_5 refers to accessor 9, but there are");
  {
    GltfBuilder b;
    add_quad(&b);
    b.doc()["scenes"][0]["nodes"] = {0, 5};
    b.write_embedded(dir_ / "bad_root.gltf");
  }
  expect_error(dir_ / "bad_root.gltf", "node 5");
}

TEST_F(GltfLoaderTest, BuffersOutsideTheSceneFolderAreRefused) {
  GltfBuilder b;
  add_quad(&b);
  b.write_external(dir_ / "inside.gltf", "data.bin");
  fs::rename(dir_ / "data.bin", root_ / "secret.bin");
  json doc = json::parse(read_bytes(dir_ / "inside.gltf"));
  doc["buffers"][0]["uri"] = "../secret.bin";
  write_text(dir_ / "escape.gltf", doc.dump());
  expect_error(dir_ / "escape.gltf", "outside the folder");
}

// The fuzz target loads from memory (docs/robustness.md): the same scene and the same checks
// as the file.
TEST_F(GltfLoaderTest, BytesInMemoryLoadLikeTheFile) {
  GltfBuilder b;
  add_quad(&b);
  for (const char* name : {"quad.gltf", "quad.glb"}) {
    const fs::path path = dir_ / name;
    if (path.extension() == ".glb") {
      b.write_glb(path);
    } else {
      b.write_embedded(path);
    }
    std::vector<uint8_t> bytes = read_bytes(path);
    const Scene from_file = load_gltf(path);
    const Scene from_memory = load_gltf_bytes(bytes, path);
    EXPECT_EQ(from_memory.source, path.string());
    const Primitive& a = from_file.meshes.at(0).primitives.at(0);
    const Primitive& m = from_memory.meshes.at(0).primitives.at(0);
    EXPECT_EQ(m.positions, a.positions);
    EXPECT_EQ(m.normals, a.normals);
    EXPECT_EQ(m.indices, a.indices);
    bytes.resize(bytes.size() / 2);
    try {
      load_gltf_bytes(bytes, path);
      ADD_FAILURE() << name << ": half of it loaded";
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()).rfind(path.string() + ": ", 0), 0u) << e.what();
    }
  }
}

TEST(LoadSceneTest, EmptyPathGivesTheBuiltinScene) {
  const Scene scene = load_scene({});
  EXPECT_EQ(scene.source, "builtin");
  EXPECT_FALSE(scene.meshes.empty());
}

// What a .gltf refers to besides itself: buffers and images by URI, data: URIs excluded; the
// word "uri" elsewhere (a name, an extras field) is not a reference.
TEST(GltfExternalUrisTest, BuffersAndImagesThatNameFilesAndNothingElse) {
  const std::string text = R"({
    "asset": {"version": "2.0", "extras": {"uri": "not/a/reference.bin"}},
    "buffers": [{"uri": "data:application/octet-stream;base64,AAAA", "byteLength": 3},
                {"uri": "mesh.bin", "byteLength": 64, "name": "\"uri\": \"x\""}],
    "images": [{"uri": "textures/wood.png"}, {"bufferView": 0, "mimeType": "image/png"},
               {"uri": "data:image/png;base64,iVBORw0KGgo="}]
  })";
  EXPECT_EQ(gltf_external_uris(text, "scene.gltf"),
            (std::vector<std::string>{"mesh.bin", "textures/wood.png"}));
  EXPECT_TRUE(gltf_external_uris(R"({"asset": {"version": "2.0"}})", "a.gltf").empty());
  try {
    (void)gltf_external_uris(R"({"asset": {"version": "2.0"}, "buffers": [)", "cut.gltf");
    FAIL() << "a truncated document was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cut.gltf: invalid glTF"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace afr
