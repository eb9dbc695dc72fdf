#include <afr/common/gltf_loader.h>

#include <afr/common/error.h>
#include <afr/common/image.h>

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>
#include <meshoptimizer.h>

#include <gtest/gtest.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "support/base64.h"
#include "support/files.h"
#include "support/log_capture.h"
#include "support/srgb.h"
#include "support/webp.h"

namespace afr {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

constexpr int kByte = 5120;
constexpr int kUnsignedByte = 5121;
constexpr int kShort = 5122;
constexpr int kUnsignedShort = 5123;
constexpr int kUnsignedInt = 5125;
constexpr int kFloat = 5126;

using afr::testing::read_bytes;

void write_bytes(const fs::path& path, const void* data, size_t size) {
  std::ofstream out(path, std::ios::binary);
  out.write(static_cast<const char*>(data), std::streamsize(size));
}

using afr::testing::write_text;

// A glTF document and its one binary buffer, written as .gltf (embedded or external buffer)
// or as .glb.
class GltfBuilder {
 public:
  GltfBuilder() { doc_["asset"] = {{"version", "2.0"}}; }

  json& doc() { return doc_; }
  std::vector<uint8_t>& bin() { return bin_; }
  // Buffers written after the one binary buffer (buffer 0), as they are.
  json& more_buffers() { return more_buffers_; }

  // Appends `size` bytes as a new buffer view (4-byte aligned); returns its index.
  int add_view(const void* data, size_t size, size_t stride = 0) {
    while (bin_.size() % 4 != 0) bin_.push_back(0);
    json view = {{"buffer", 0}, {"byteOffset", bin_.size()}, {"byteLength", size}};
    if (stride != 0) view["byteStride"] = stride;
    const auto* bytes = static_cast<const uint8_t*>(data);
    bin_.insert(bin_.end(), bytes, bytes + size);
    doc_["bufferViews"].push_back(view);
    return int(doc_["bufferViews"].size()) - 1;
  }
  template <typename T>
  int add_view(const std::vector<T>& values, size_t stride = 0) {
    return add_view(values.data(), values.size() * sizeof(T), stride);
  }

  int add_accessor(int view, int component_type, const std::string& type, size_t count,
                   size_t offset = 0, bool normalized = false) {
    json accessor = {{"componentType", component_type}, {"type", type}, {"count", count}};
    if (view >= 0) accessor["bufferView"] = view;
    if (offset != 0) accessor["byteOffset"] = offset;
    if (normalized) accessor["normalized"] = true;
    doc_["accessors"].push_back(accessor);
    return int(doc_["accessors"].size()) - 1;
  }

  // A float accessor over its own buffer view, `width` components per element.
  int add_floats(const std::vector<float>& values, int width) {
    static const char* kTypes[] = {"", "SCALAR", "VEC2", "VEC3", "VEC4"};
    return add_accessor(add_view(values), kFloat, kTypes[width], values.size() / size_t(width));
  }
  int add_indices16(const std::vector<uint16_t>& indices) {
    return add_accessor(add_view(indices), kUnsignedShort, "SCALAR", indices.size());
  }

  void write_embedded(const fs::path& path) {
    json doc = doc_;
    doc["buffers"] =
        json::array({{{"byteLength", bin_.size()},
                      {"uri", "data:application/octet-stream;base64," + testing::base64(bin_)}}});
    for (const json& more : more_buffers_) doc["buffers"].push_back(more);
    write_text(path, doc.dump(2));
  }

  void write_external(const fs::path& path, const std::string& bin_name) {
    json doc = doc_;
    doc["buffers"] = json::array({{{"byteLength", bin_.size()}, {"uri", bin_name}}});
    for (const json& more : more_buffers_) doc["buffers"].push_back(more);
    write_text(path, doc.dump(2));
    write_bytes(path.parent_path() / bin_name, bin_.data(), bin_.size());
  }

  void write_glb(const fs::path& path) {
    json doc = doc_;
    doc["buffers"] = json::array({{{"byteLength", bin_.size()}}});
    for (const json& more : more_buffers_) doc["buffers"].push_back(more);
    std::string text = doc.dump();
    while (text.size() % 4 != 0) text += ' ';
    std::vector<uint8_t> bin = bin_;
    while (bin.size() % 4 != 0) bin.push_back(0);
    std::vector<uint8_t> glb;
    auto u32 = [&](uint32_t v) {
      for (int i = 0; i < 4; ++i) glb.push_back(uint8_t(v >> (8 * i)));
    };
    glb.insert(glb.end(), {'g', 'l', 'T', 'F'});
    u32(2);
    u32(uint32_t(12 + 8 + text.size() + 8 + bin.size()));
    u32(uint32_t(text.size()));
    u32(0x4E4F534A);  // JSON
    glb.insert(glb.end(), text.begin(), text.end());
    u32(uint32_t(bin.size()));
    u32(0x004E4942);  // BIN
    glb.insert(glb.end(), bin.begin(), bin.end());
    write_bytes(path, glb.data(), glb.size());
  }

 private:
  json doc_;
  std::vector<uint8_t> bin_;
  json more_buffers_ = json::array();
};

// An animation channel whose sampler drives the property a KHR_animation_pointer names.
json pointer_channel(int sampler, const std::string& pointer) {
  return json{
      {"sampler", sampler},
      {"target",
       {{"path", "pointer"}, {"extensions", {{"KHR_animation_pointer", {{"pointer", pointer}}}}}}}};
}

// The unit quad in the z = 0 plane, counter-clockwise seen from +z, as mesh 0 on node 0 of
// scene 0. Returns the POSITION accessor.
int add_quad(GltfBuilder* b) {
  const int positions = b->add_floats({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, 3);
  const int indices = b->add_indices16({0, 1, 2, 0, 2, 3});
  b->doc()["meshes"].push_back(
      {{"name", "quad"},
       {"primitives",
        json::array({{{"attributes", {{"POSITION", positions}}}, {"indices", indices}}})}});
  b->doc()["nodes"].push_back({{"mesh", 0}});
  b->doc()["scenes"] = json::array({{{"nodes", {0}}}});
  b->doc()["scene"] = 0;
  return positions;
}

using afr::testing::reference_srgb_to_linear;

size_t count_containing(const std::vector<std::string>& lines, const std::string& part) {
  size_t n = 0;
  for (const std::string& line : lines) n += line.find(part) != std::string::npos ? 1 : 0;
  return n;
}

class GltfLoaderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() /
            ("afr_gltf_test_" + std::to_string(getpid()) + "_" + info->name());
    fs::remove_all(root_);
    dir_ = root_ / "scenes";
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(root_); }

  // Loading `path` must fail with a message that names the file and contains `problem`.
  void expect_error(const fs::path& path, const std::string& problem) {
    try {
      load_gltf(path);
      ADD_FAILURE() << path << " loaded, expected an error about " << problem;
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(path.filename().string()), std::string::npos) << message;
      EXPECT_NE(message.find(problem), std::string::npos) << message;
    }
  }

  fs::path root_;  // removed afterwards
  fs::path dir_;   // where the scenes are written, one level below root_
};

// ---- Geometry ----

TEST_F(GltfLoaderTest, QuadLoadsWithPositionsIndicesGeneratedNormalsAndUvs) {
  GltfBuilder b;
  add_quad(&b);
  // UVs as normalized unsigned bytes, padded to the 4-byte stride vertex data must have.
  const std::vector<uint8_t> uv_bytes = {0, 0, 9, 9, 255, 0, 9, 9, 255, 255, 9, 9, 0, 51, 9, 9};
  const int uvs = b.add_accessor(b.add_view(uv_bytes, 4), kUnsignedByte, "VEC2", 4, 0, true);
  b.doc()["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = uvs;
  // A second primitive without indices, with its own (non-geometric) normals.
  const int tri = b.add_floats({0, 0, 1, 1, 0, 1, 0, 1, 1}, 3);
  const int normals = b.add_floats({1, 0, 0, 0, 2, 0, 0, 0, 1}, 3);
  b.doc()["meshes"][0]["primitives"].push_back(
      {{"attributes", {{"POSITION", tri}, {"NORMAL", normals}}}});
  // A third over the quad's vertices with unsigned byte indices, and one with unsigned int.
  const int quad_positions = 0;
  const std::vector<uint8_t> byte_indices = {2, 1, 0};
  const std::vector<uint32_t> int_indices = {3, 2, 0};
  b.doc()["meshes"][0]["primitives"].push_back(
      {{"attributes", {{"POSITION", quad_positions}}},
       {"indices", b.add_accessor(b.add_view(byte_indices), kUnsignedByte, "SCALAR", 3)}});
  b.doc()["meshes"][0]["primitives"].push_back(
      {{"attributes", {{"POSITION", quad_positions}}},
       {"indices", b.add_accessor(b.add_view(int_indices), kUnsignedInt, "SCALAR", 3)}});
  const fs::path path = dir_ / "quad.gltf";
  b.write_embedded(path);

  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty());
  EXPECT_EQ(scene.source, path.string());
  ASSERT_EQ(scene.meshes.size(), 1u);
  EXPECT_EQ(scene.meshes[0].name, "quad");
  ASSERT_EQ(scene.meshes[0].primitives.size(), 4u);

  const Primitive& quad = scene.meshes[0].primitives[0];
  const std::vector<glm::vec3> positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  EXPECT_EQ(quad.positions, positions);
  EXPECT_EQ(quad.indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
  EXPECT_EQ(quad.triangle_count(), 2u);
  EXPECT_EQ(quad.material, -1);
  ASSERT_EQ(quad.normals.size(), 4u);
  for (const glm::vec3& n : quad.normals) EXPECT_EQ(n, glm::vec3(0, 0, 1));
  ASSERT_EQ(quad.uvs.size(), 4u);
  EXPECT_EQ(quad.uvs[0], glm::vec2(0, 0));
  EXPECT_EQ(quad.uvs[1], glm::vec2(1, 0));
  EXPECT_EQ(quad.uvs[2], glm::vec2(1, 1));
  EXPECT_FLOAT_EQ(quad.uvs[3].y, 0.2f);  // 51 / 255

  const Primitive& triangle = scene.meshes[0].primitives[1];
  EXPECT_EQ(triangle.indices, (std::vector<uint32_t>{0, 1, 2}));
  EXPECT_TRUE(triangle.uvs.empty());
  ASSERT_EQ(triangle.normals.size(), 3u);
  EXPECT_EQ(triangle.normals[0], glm::vec3(1, 0, 0));
  EXPECT_EQ(triangle.normals[1], glm::vec3(0, 1, 0));  // normalised from (0, 2, 0)
  EXPECT_EQ(triangle.normals[2], glm::vec3(0, 0, 1));

  EXPECT_EQ(scene.meshes[0].primitives[2].indices, (std::vector<uint32_t>{2, 1, 0}));
  // Clockwise seen from +z: the generated normals point down.
  EXPECT_EQ(scene.meshes[0].primitives[2].normals[0], glm::vec3(0, 0, -1));
  EXPECT_EQ(scene.meshes[0].primitives[3].indices, (std::vector<uint32_t>{3, 2, 0}));
}

// COLOR_0 in each form glTF allows (float VEC3, normalized unsigned byte VEC4, normalized
// unsigned short VEC3) is read as linear RGB, alpha dropped without a word where the material
// is OPAQUE (which ignores it) and kept where it masks; negative floats warn once; a type or
// count glTF forbids fails naming the accessor.
TEST_F(GltfLoaderTest, VertexColorsAreReadInEveryAllowedFormAndBadOnesAreNamed) {
  GltfBuilder b;
  const int positions = add_quad(&b);
  json& primitives = b.doc()["meshes"][0]["primitives"];
  primitives[0]["attributes"]["COLOR_0"] =
      b.add_floats({1, 0, 0, 0, 1, 0, 0, 0, 1, 0.5f, -0.25f, 2}, 3);
  const std::vector<uint8_t> rgba = {255, 0, 0,   255, 0,   51,  0,   255,
                                     0,   0, 255, 128, 255, 255, 255, 255};
  primitives.push_back(
      {{"attributes",
        {{"POSITION", positions},
         {"COLOR_0", b.add_accessor(b.add_view(rgba), kUnsignedByte, "VEC4", 4, 0, true)}}},
       {"indices", 1}});
  const std::vector<uint16_t> rgb16 = {65535, 0, 0, 0, 65535, 0, 0, 0, 65535, 13107, 13107, 13107};
  primitives.push_back(
      {{"attributes",
        {{"POSITION", positions},
         {"COLOR_0", b.add_accessor(b.add_view(rgb16), kUnsignedShort, "VEC3", 4, 0, true)},
         {"COLOR_1", b.add_floats({0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}, 3)}}},
       {"indices", 1}});
  const fs::path path = dir_ / "colors.gltf";
  b.write_embedded(path);

  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  ASSERT_EQ(scene.meshes[0].primitives.size(), 3u);
  const std::vector<glm::vec3>& f = scene.meshes[0].primitives[0].colors;
  ASSERT_EQ(f.size(), 4u);
  EXPECT_EQ(f[0], glm::vec3(1, 0, 0));
  EXPECT_EQ(f[2], glm::vec3(0, 0, 1));
  EXPECT_EQ(f[3], glm::vec3(0.5f, 0.0f, 2.0f));  // the negative green taken as 0
  const std::vector<glm::vec3>& u8 = scene.meshes[0].primitives[1].colors;
  ASSERT_EQ(u8.size(), 4u);
  EXPECT_EQ(u8[0], glm::vec3(1, 0, 0));
  EXPECT_FLOAT_EQ(u8[1].y, 0.2f);  // 51 / 255, alpha dropped
  EXPECT_EQ(u8[3], glm::vec3(1, 1, 1));
  const std::vector<glm::vec3>& u16 = scene.meshes[0].primitives[2].colors;
  ASSERT_EQ(u16.size(), 4u);
  EXPECT_EQ(u16[1], glm::vec3(0, 1, 0));
  EXPECT_FLOAT_EQ(u16[3].x, 0.2f);  // 13107 / 65535
  EXPECT_EQ(count_containing(report.warnings, "negative vertex color"), 1u);
  EXPECT_EQ(count_containing(report.warnings, "COLOR_1"), 1u);
  EXPECT_EQ(report.warnings.size(), 2u);
  for (const Primitive& p : scene.meshes[0].primitives) EXPECT_TRUE(p.color_alpha.empty());

  // On a masking material the byte colors' alpha is kept; the float VEC3 has none to keep.
  {
    GltfBuilder m = b;
    m.doc()["materials"] = json::array({{{"alphaMode", "MASK"}}});
    for (json& p : m.doc()["meshes"][0]["primitives"]) p["material"] = 0;
    m.write_embedded(dir_ / "masked_colors.gltf");
    const Scene masked = load_gltf(dir_ / "masked_colors.gltf");
    EXPECT_TRUE(masked.meshes[0].primitives[0].color_alpha.empty());
    const std::vector<float>& a = masked.meshes[0].primitives[1].color_alpha;
    ASSERT_EQ(a.size(), 4u);
    EXPECT_EQ(a[0], 1.0f);
    EXPECT_FLOAT_EQ(a[2], 128.0f / 255.0f);
  }

  // Unsigned bytes that are not normalized, a SCALAR, too few colors: each an error.
  auto broken = [&](const std::function<int(GltfBuilder*)>& add_color, const std::string& name,
                    const std::string& problem) {
    GltfBuilder c = b;
    const int color = add_color(&c);
    c.doc()["meshes"][0]["primitives"] = json::array(
        {{{"attributes", {{"POSITION", positions}, {"COLOR_0", color}}}, {"indices", 1}}});
    const fs::path bad = dir_ / name;
    c.write_embedded(bad);
    expect_error(bad, problem);
  };
  broken(
      [&](GltfBuilder* c) { return c->add_accessor(c->add_view(rgba), kUnsignedByte, "VEC4", 4); },
      "raw.gltf", "vertex colors must be floats or normalized unsigned bytes or shorts");
  broken(
      [](GltfBuilder* c) {
        return c->add_floats({1, 1, 1, 1}, 1);
      },
      "scalar.gltf", "is SCALAR: vertex colors must be VEC3 or VEC4");
  broken(
      [](GltfBuilder* c) {
        return c->add_floats({1, 1, 1, 1, 1, 1}, 3);
      },
      "short.gltf", "2 vertex colors for 4 positions");
}

TEST_F(GltfLoaderTest, InterleavedStridedAndSparseAccessorsAreRead) {
  GltfBuilder b;
  // Position and normal of three vertices interleaved in one view of stride 24.
  const std::vector<float> interleaved = {0, 0, 0, 0, 0, 1, 2, 0, 0, 0, 0, 1, 0, 2, 0, 0, 0, 1};
  const int view = b.add_view(interleaved, 24);
  const int positions = b.add_accessor(view, kFloat, "VEC3", 3, 0);
  const int normals = b.add_accessor(view, kFloat, "VEC3", 3, 12);
  // Sparse: vertex 1 moves to (5, 6, 7).
  const std::vector<uint16_t> sparse_index = {1};
  const std::vector<float> sparse_value = {5, 6, 7};
  b.doc()["accessors"][positions]["sparse"] = {
      {"count", 1},
      {"indices", {{"bufferView", b.add_view(sparse_index)}, {"componentType", kUnsignedShort}}},
      {"values", {{"bufferView", b.add_view(sparse_value)}}}};
  // UVs with no buffer view at all (zeros) and one sparse value.
  const int uvs = b.add_accessor(-1, kFloat, "VEC2", 3);
  const std::vector<uint8_t> uv_index = {2};
  const std::vector<float> uv_value = {0.5f, 0.25f};
  b.doc()["accessors"][uvs]["sparse"] = {
      {"count", 1},
      {"indices", {{"bufferView", b.add_view(uv_index)}, {"componentType", kUnsignedByte}}},
      {"values", {{"bufferView", b.add_view(uv_value)}}}};
  b.doc()["meshes"].push_back(
      {{"primitives",
        json::array({{{"attributes",
                       {{"POSITION", positions}, {"NORMAL", normals}, {"TEXCOORD_0", uvs}}}}})}});
  b.doc()["nodes"].push_back({{"mesh", 0}});
  b.doc()["scenes"] = json::array({{{"nodes", {0}}}});
  const fs::path path = dir_ / "interleaved.gltf";
  b.write_embedded(path);

  const Scene scene = load_gltf(path);
  const Primitive& p = scene.meshes.at(0).primitives.at(0);
  EXPECT_EQ(p.positions, (std::vector<glm::vec3>{{0, 0, 0}, {5, 6, 7}, {0, 2, 0}}));
  EXPECT_EQ(p.normals, (std::vector<glm::vec3>(3, glm::vec3(0, 0, 1))));
  EXPECT_EQ(p.uvs, (std::vector<glm::vec2>{{0, 0}, {0, 0}, {0.5f, 0.25f}}));
  EXPECT_EQ(p.indices, (std::vector<uint32_t>{0, 1, 2}));
}

TEST_F(GltfLoaderTest, TriangleStripsAndFansBecomeListsWithTheirWinding) {
  GltfBuilder b;
  const int positions = b.add_floats({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0}, 3);
  b.doc()["meshes"].push_back(
      {{"primitives", json::array({{{"attributes", {{"POSITION", positions}}}, {"mode", 5}},
                                   {{"attributes", {{"POSITION", positions}}},
                                    {"mode", 6},
                                    {"indices", b.add_indices16({0, 1, 3, 2})}}})}});
  b.doc()["nodes"].push_back({{"mesh", 0}});
  b.doc()["scenes"] = json::array({{{"nodes", {0}}}});
  const fs::path path = dir_ / "strips.gltf";
  b.write_embedded(path);

  const Scene scene = load_gltf(path);
  ASSERT_EQ(scene.meshes.at(0).primitives.size(), 2u);
  // glTF 2.0, 3.7.2.1: strip triangle i is (i, i + 1 + i % 2, i + 2 - i % 2).
  EXPECT_EQ(scene.meshes[0].primitives[0].indices, (std::vector<uint32_t>{0, 1, 2, 1, 3, 2}));
  // Fan triangle i is (i + 1, i + 2, 0), through the index list {0, 1, 3, 2}.
  EXPECT_EQ(scene.meshes[0].primitives[1].indices, (std::vector<uint32_t>{1, 3, 0, 3, 2, 0}));
  for (const Primitive& p : scene.meshes[0].primitives) {
    for (const glm::vec3& n : p.normals) EXPECT_EQ(n, glm::vec3(0, 0, 1));
  }
}

// The glTF Validator only warns of a triangle list whose count is not a multiple of 3
// (MESH_PRIMITIVE_INCOMPATIBLE_MODE): its whole triangles are drawn, with one warning.
TEST_F(GltfLoaderTest, TrianglesBeyondTheLastWholeOneAreLeftOutWithAWarning) {
  GltfBuilder b;
  const int positions = b.add_floats({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0}, 3);
  b.doc()["meshes"].push_back(
      {{"primitives", json::array({{{"attributes", {{"POSITION", positions}}},
                                    {"indices", b.add_indices16({0, 1, 2, 2, 1})}},
                                   {{"attributes", {{"POSITION", positions}}}}})}});
  b.doc()["nodes"].push_back({{"mesh", 0}});
  b.doc()["scenes"] = json::array({{{"nodes", {0}}}});
  const fs::path path = dir_ / "incomplete.gltf";
  b.write_embedded(path);

  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  ASSERT_EQ(scene.meshes.at(0).primitives.size(), 2u);
  EXPECT_EQ(scene.meshes[0].primitives[0].indices, (std::vector<uint32_t>{0, 1, 2}));
  EXPECT_EQ(scene.meshes[0].primitives[1].indices, (std::vector<uint32_t>{0, 1, 2}));
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("mesh 0 primitive 0 has 5 indices, not a multiple of 3: the "
                                    "last two are not drawn"),
            std::string::npos)
      << report.warnings[0];
}

// ---- Materials and textures ----

TEST_F(GltfLoaderTest, MaterialsAndEmbeddedPngTexturesDecodeToLinearTexels) {
  // A 2 x 2 texture, row 0 at the top.
  const DecodedImage png{2, 2, 3, {255, 0, 0, 0, 128, 255, 10, 20, 30, 255, 255, 255}};
  const fs::path png_path = dir_ / "texture.png";
  write_image8(png, png_path);
  const std::vector<uint8_t> png_bytes = read_bytes(png_path);

  auto build = [&](GltfBuilder* b) {
    add_quad(b);
    b->doc()["meshes"][0]["primitives"][0]["material"] = 0;
    b->doc()["extensionsUsed"] = {"KHR_materials_emissive_strength"};
    b->doc()["textures"] = json::array({{{"source", 0}}});
    b->doc()["materials"] = json::array(
        {{{"name", "painted"},
          {"pbrMetallicRoughness",
           {{"baseColorFactor", {0.5, 0.25, 1.0, 1.0}},
            {"baseColorTexture", {{"index", 0}}},
            {"metallicFactor", 0.25},
            {"roughnessFactor", 0.75}}},
          {"emissiveFactor", {1.0, 0.5, 0.25}},
          {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 4.0}}}}},
          {"doubleSided", true},
          {"extras", {{"afr_ambient", {0.1, 0.2, 0.3}}}}},
         // A second material on the same texture, and a plain one.
         {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}},
         {{"name", "plain"}}});
  };
  // The same image three ways: a data URI, a file beside the .gltf, a buffer view of a .glb.
  GltfBuilder data_uri;
  build(&data_uri);
  data_uri.doc()["images"] =
      json::array({{{"uri", "data:image/png;base64," + testing::base64(png_bytes)}}});
  data_uri.write_embedded(dir_ / "data_uri.gltf");
  GltfBuilder file;
  build(&file);
  file.doc()["images"] = json::array({{{"uri", "texture.png"}}});
  file.write_embedded(dir_ / "file.gltf");
  GltfBuilder glb;
  build(&glb);
  glb.doc()["images"] =
      json::array({{{"bufferView", glb.add_view(png_bytes)}, {"mimeType", "image/png"}}});
  glb.write_glb(dir_ / "binary.glb");

  for (const char* name : {"data_uri.gltf", "file.gltf", "binary.glb"}) {
    SCOPED_TRACE(name);
    GltfLoadReport report;
    const Scene scene = load_gltf(dir_ / name, &report);
    EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
    ASSERT_EQ(scene.materials.size(), 3u);
    const Material& m = scene.materials[0];
    EXPECT_EQ(m.name, "painted");
    EXPECT_EQ(m.base_color_factor, glm::vec4(0.5f, 0.25f, 1.0f, 1.0f));
    EXPECT_EQ(m.metallic, 0.25f);
    EXPECT_EQ(m.roughness, 0.75f);
    EXPECT_EQ(m.emissive, glm::vec3(4.0f, 2.0f, 1.0f));
    EXPECT_TRUE(m.double_sided);
    ASSERT_TRUE(m.ambient.has_value());
    EXPECT_EQ(*m.ambient, glm::vec3(0.1f, 0.2f, 0.3f));
    EXPECT_EQ(scene.meshes[0].primitives[0].material, 0);

    // One decoded texture, shared by both materials that use it.
    ASSERT_EQ(scene.textures.size(), 1u);
    EXPECT_EQ(m.base_color_texture, 0);
    EXPECT_EQ(scene.materials[1].base_color_texture, 0);
    EXPECT_EQ(scene.materials[2].base_color_texture, -1);
    EXPECT_FALSE(scene.materials[2].ambient.has_value());
    EXPECT_EQ(scene.materials[2].base_color_factor, glm::vec4(1.0f));
    EXPECT_FALSE(scene.materials[2].double_sided);

    const Texture& t = scene.textures[0];
    ASSERT_EQ(t.width, 2);
    ASSERT_EQ(t.height, 2);
    // Kept as the image's codes, a quarter of the floats' memory, decoded at each lookup.
    ASSERT_EQ(t.codes.size(), 4u);
    EXPECT_TRUE(t.texels.empty());
    for (size_t i = 0; i < 4; ++i) {
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(t.texel(i)[c], reference_srgb_to_linear(png.data[3 * i + size_t(c)] / 255.0),
                    1e-6)
            << "texel " << i << " channel " << c;
      }
    }
  }
}

// TANGENT is read where the material has a normal texture (w taken by its sign) and not
// otherwise (nor generated); a count other than the positions' fails naming the primitive.
TEST_F(GltfLoaderTest, TangentsAreReadForNormalMappedMaterialsOnly) {
  write_image8(DecodedImage{1, 1, 3, {128, 128, 255}}, dir_ / "normal.png");
  GltfBuilder b;
  add_quad(&b);
  json& primitive = b.doc()["meshes"][0]["primitives"][0];
  primitive["material"] = 0;
  primitive["attributes"]["TEXCOORD_0"] = b.add_floats({0, 1, 1, 1, 1, 0, 0, 0}, 2);
  primitive["attributes"]["TANGENT"] =
      b.add_floats({1, 0, 0, 1, 1, 0, 0, 1, 0, 1, 0, -1, 0, 1, 0, -0.5f}, 4);
  b.doc()["images"] = json::array({{{"uri", "normal.png"}}});
  b.doc()["textures"] = json::array({{{"source", 0}}});
  b.doc()["materials"] = json::array({{{"normalTexture", {{"index", 0}}}}});
  b.write_embedded(dir_ / "tangents.gltf");
  const Scene scene = load_gltf(dir_ / "tangents.gltf");
  const std::vector<glm::vec4>& t = scene.meshes[0].primitives[0].tangents;
  ASSERT_EQ(t.size(), 4u);
  EXPECT_EQ(t[0], glm::vec4(1, 0, 0, 1));
  EXPECT_EQ(t[2], glm::vec4(0, 1, 0, -1));
  EXPECT_EQ(t[3], glm::vec4(0, 1, 0, -1));  // w -0.5: its sign

  GltfBuilder plain = b;
  plain.doc()["materials"] = json::array({json::object()});
  plain.write_embedded(dir_ / "plain.gltf");
  EXPECT_TRUE(load_gltf(dir_ / "plain.gltf").meshes[0].primitives[0].tangents.empty());

  b.doc()["meshes"][0]["primitives"][0]["attributes"]["TANGENT"] =
      b.add_floats({1, 0, 0, 1, 1, 0, 0, 1}, 4);
  b.write_embedded(dir_ / "short.gltf");
  expect_error(dir_ / "short.gltf", "mesh 0 primitive 0 has 2 tangents for 4 positions");
}

// Where the file has no TANGENT, a material that needs a tangent frame gets smooth tangents:
// per vertex, the area-weighted directions of +u of its triangles, w making the bitangent point
// against dp/dv (glTF's v runs down the image). Upright coordinates on the quad give +x and
// w = 1, mirrored ones -x and w = -1; where the two triangles map u differently, the vertices
// they share blend both directions. Anisotropy asks for them too; a plain material does not.
TEST_F(GltfLoaderTest, TangentsAreGeneratedWhereTheFileHasNone) {
  write_image8(DecodedImage{1, 1, 3, {128, 128, 255}}, dir_ / "normal.png");
  const auto tangents_of = [&](std::vector<float> uvs, const json& material) {
    GltfBuilder b;
    add_quad(&b);
    json& primitive = b.doc()["meshes"][0]["primitives"][0];
    primitive["material"] = 0;
    primitive["attributes"]["TEXCOORD_0"] = b.add_floats(uvs, 2);
    b.doc()["images"] = json::array({{{"uri", "normal.png"}}});
    b.doc()["textures"] = json::array({{{"source", 0}}});
    b.doc()["extensionsUsed"] = {"KHR_materials_anisotropy"};
    b.doc()["materials"] = json::array({material});
    b.write_embedded(dir_ / "generated.gltf");
    return load_gltf(dir_ / "generated.gltf").meshes[0].primitives[0].tangents;
  };
  const json normal_mapped = {{"normalTexture", {{"index", 0}}}};
  const auto expect_tangent = [](const glm::vec4& t, glm::vec3 direction, float w,
                                 const char* what) {
    const glm::vec3 d = glm::normalize(direction);
    EXPECT_NEAR(t.x, d.x, 1e-6f) << what;
    EXPECT_NEAR(t.y, d.y, 1e-6f) << what;
    EXPECT_NEAR(t.z, d.z, 1e-6f) << what;
    EXPECT_EQ(t.w, w) << what;
  };
  const std::vector<glm::vec4> upright = tangents_of({0, 1, 1, 1, 1, 0, 0, 0}, normal_mapped);
  ASSERT_EQ(upright.size(), 4u);
  for (const glm::vec4& t : upright) expect_tangent(t, {1, 0, 0}, 1.0f, "upright");
  const std::vector<glm::vec4> mirrored = tangents_of({1, 1, 0, 1, 0, 0, 1, 0}, normal_mapped);
  ASSERT_EQ(mirrored.size(), 4u);
  for (const glm::vec4& t : mirrored) expect_tangent(t, {-1, 0, 0}, -1.0f, "mirrored");
  // Triangle (0, 1, 2): dp/du = +x; triangle (0, 2, 3): dp/du = (2, 1, 0); both of area 1. v
  // runs up (+y) here: w = -1.
  const std::vector<glm::vec4> blended = tangents_of({0, 0, 1, 0, 1, 1, 1, 2}, normal_mapped);
  ASSERT_EQ(blended.size(), 4u);
  const glm::vec3 second = glm::normalize(glm::vec3(2, 1, 0));
  expect_tangent(blended[1], {1, 0, 0}, -1.0f, "vertex 1: the first triangle's");
  expect_tangent(blended[3], second, -1.0f, "vertex 3: the second's");
  expect_tangent(blended[0], glm::vec3(1, 0, 0) + second, -1.0f, "vertex 0: both");
  expect_tangent(blended[2], glm::vec3(1, 0, 0) + second, -1.0f, "vertex 2: both");

  const json anisotropic = {
      {"extensions", {{"KHR_materials_anisotropy", {{"anisotropyStrength", 0.5}}}}}};
  EXPECT_EQ(tangents_of({0, 1, 1, 1, 1, 0, 0, 0}, anisotropic).size(), 4u);
  EXPECT_TRUE(tangents_of({0, 1, 1, 1, 1, 0, 0, 0}, json::object()).empty());
}

// The metallic-roughness, emissive, occlusion and normal slots are read: data textures
// (metallic-roughness, occlusion, normal) decoded as they are, color ones (base color, emissive)
// from sRGB; one image decoded once per way it is read; a slot whose transform differs from the
// material's first slot's reads a set of coordinates of its own; an occlusion strength outside
// [0, 1] fails naming the material.
TEST_F(GltfLoaderTest, MaterialTextureSlotsDecodeColorFromSrgbAndDataAsItIs) {
  const DecodedImage color{1, 1, 3, {128, 64, 255}}, orm{1, 1, 3, {200, 128, 51}};
  const fs::path color_path = dir_ / "color.png", orm_path = dir_ / "orm.png";
  write_image8(color, color_path);
  write_image8(orm, orm_path);
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["images"] = json::array({{{"uri", "color.png"}}, {{"uri", "orm.png"}}});
  b.doc()["textures"] = json::array({{{"source", 0}}, {{"source", 1}}, {{"source", 0}}});
  const json shifted = {{"KHR_texture_transform", {{"offset", {0.5, 0.0}}}}};
  b.doc()["extensionsUsed"] = {"KHR_texture_transform"};
  b.doc()["materials"] = json::array(
      {{{"pbrMetallicRoughness",
         {{"baseColorTexture", {{"index", 0}}}, {"metallicRoughnessTexture", {{"index", 1}}}}},
        {"emissiveFactor", {1.0, 1.0, 1.0}},
        {"emissiveTexture", {{"index", 2}}},  // the base color's image through another texture
        {"occlusionTexture", {{"index", 1}, {"strength", 0.75}}}},
       // The color image read as occlusion data, its transform unlike its base color's; the
       // orm image as a normal texture (data) with a scale.
       {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 1}}}}},
        {"occlusionTexture", {{"index", 0}, {"extensions", shifted}}},
        {"normalTexture", {{"index", 1}, {"scale", 0.5}}}}});
  b.write_embedded(dir_ / "slots.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "slots.gltf", &report);
  ASSERT_EQ(scene.materials.size(), 2u);
  const Material& m = scene.materials[0];
  // color (sRGB), orm (data), orm (sRGB, material 1's base color), color (data).
  ASSERT_EQ(scene.textures.size(), 4u);
  EXPECT_EQ(m.base_color_texture, 0);
  EXPECT_EQ(m.metallic_roughness_texture, 1);
  EXPECT_EQ(m.occlusion_texture, 1);
  EXPECT_EQ(m.emissive_texture, 0);
  EXPECT_FLOAT_EQ(m.occlusion_strength, 0.75f);
  EXPECT_EQ(scene.materials[1].base_color_texture, 2);
  EXPECT_EQ(scene.materials[1].occlusion_texture, 3);
  EXPECT_EQ(scene.materials[1].metallic_roughness_texture, -1);
  EXPECT_EQ(scene.materials[1].emissive_texture, -1);
  EXPECT_EQ(scene.materials[1].normal_texture, 1);
  EXPECT_FLOAT_EQ(scene.materials[1].normal_scale, 0.5f);
  EXPECT_EQ(m.normal_texture, -1);
  EXPECT_NEAR(scene.textures[0].texel(0).r, reference_srgb_to_linear(128 / 255.0), 1e-6);
  EXPECT_NEAR(scene.textures[1].texel(0).g, 128 / 255.0, 1e-6);  // roughness
  EXPECT_NEAR(scene.textures[1].texel(0).b, 51 / 255.0, 1e-6);   // metallic
  EXPECT_NEAR(scene.textures[3].texel(0).r, 128 / 255.0, 1e-6);
  EXPECT_EQ(m.uv_set, Material::TextureSets{});
  EXPECT_EQ(scene.materials[1].uv_set, (Material::TextureSets{.occlusion = 1}));
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();

  b.doc()["materials"][0]["occlusionTexture"]["strength"] = 1.5;
  b.write_embedded(dir_ / "strength.gltf");
  expect_error(dir_ / "strength.gltf", "material 0 has an invalid occlusionTexture strength");
  b.doc()["materials"][0]["occlusionTexture"]["strength"] = 1.0;
  b.doc()["materials"][0]["emissiveTexture"]["index"] = 7;
  b.write_embedded(dir_ / "index.gltf");
  expect_error(dir_ / "index.gltf",
               "material 0 emissiveTexture refers to texture 7, but there are 3");
}

// Each texture slot reads its own TEXCOORD_n through its own KHR_texture_transform: slots that
// agree share a set, the first textured slot's (base color first) is set 0, each other pair adds
// one (Primitive::more_uvs), transformed at load. A primitive without a set has none there (one
// warning naming the slot), and keeps the others.
TEST_F(GltfLoaderTest, EachTextureSlotReadsItsOwnTextureCoordinateSet) {
  const DecodedImage gray{1, 1, 3, {128, 128, 128}};
  write_image8(gray, dir_ / "gray.png");
  GltfBuilder b;
  const int positions = add_quad(&b);
  json& primitives = b.doc()["meshes"][0]["primitives"];
  primitives[0]["material"] = 0;
  const int uv0 = b.add_floats({0, 0, 1, 0, 1, 1, 0, 1}, 2);
  primitives[0]["attributes"]["TEXCOORD_0"] = uv0;
  primitives[0]["attributes"]["TEXCOORD_1"] =
      b.add_floats({0.25f, 0.5f, 0.75f, 0.5f, 0.75f, 1.0f, 0.25f, 1.0f}, 2);
  primitives.push_back(  // the same material, without TEXCOORD_1
      {{"attributes", {{"POSITION", positions}, {"TEXCOORD_0", uv0}}},
       {"indices", primitives[0]["indices"]},
       {"material", 0}});
  b.doc()["images"] = json::array({{{"uri", "gray.png"}}});
  b.doc()["textures"] = json::array({{{"source", 0}}});
  b.doc()["extensionsUsed"] = {"KHR_texture_transform"};
  const json shifted = {{"KHR_texture_transform", {{"offset", {0.5, 0.0}}}}};
  b.doc()["materials"] =
      json::array({{{"pbrMetallicRoughness",
                     {{"baseColorTexture", {{"index", 0}, {"texCoord", 1}}},
                      {"metallicRoughnessTexture", {{"index", 0}, {"texCoord", 1}}}}},
                    {"emissiveFactor", {1.0, 1.0, 1.0}},
                    {"emissiveTexture", {{"index", 0}, {"texCoord", 1}, {"extensions", shifted}}},
                    {"occlusionTexture", {{"index", 0}}},  // on TEXCOORD_0
                    {"normalTexture", {{"index", 0}, {"texCoord", 1}}}}});
  b.write_embedded(dir_ / "sets.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "sets.gltf", &report);
  const Material& m = scene.materials[0];
  EXPECT_EQ(m.base_color_texture, 0);
  EXPECT_EQ(m.metallic_roughness_texture, 1);  // data: decoded linear
  EXPECT_EQ(m.occlusion_texture, 1);
  EXPECT_EQ(m.normal_texture, 1);
  EXPECT_EQ(m.emissive_texture, 0);
  EXPECT_EQ(
      m.uv_set,
      (Material::TextureSets{
          .base_color = 0, .metallic_roughness = 0, .emissive = 1, .occlusion = 2, .normal = 0}));
  ASSERT_EQ(scene.meshes[0].primitives.size(), 2u);
  const Primitive& both = scene.meshes[0].primitives[0];
  const std::vector<glm::vec2> uv1 = {{0.25f, 0.5f}, {0.75f, 0.5f}, {0.75f, 1.0f}, {0.25f, 1.0f}};
  EXPECT_EQ(both.uvs, uv1);
  ASSERT_EQ(both.more_uvs.size(), 2u);
  EXPECT_EQ(both.uv_set(2), (std::vector<glm::vec2>{{0, 0}, {1, 0}, {1, 1}, {0, 1}}));
  EXPECT_EQ(both.uv_set(1),
            (std::vector<glm::vec2>{{0.75f, 0.5f}, {1.25f, 0.5f}, {1.25f, 1.0f}, {0.75f, 1.0f}}));
  EXPECT_TRUE(both.uv_set(3).empty());
  const Primitive& first_only = scene.meshes[0].primitives[1];
  EXPECT_TRUE(first_only.uvs.empty());
  EXPECT_TRUE(first_only.uv_set(1).empty());
  EXPECT_EQ(first_only.uv_set(2), both.uv_set(2));
  EXPECT_EQ(count_containing(report.warnings,
                             "mesh 0 primitive 1 has no TEXCOORD_1, which its material's "
                             "baseColorTexture reads"),
            1u);
  EXPECT_EQ(report.warnings.size(), 1u);

  // A material without textures: its primitives keep TEXCOORD_0 as it is, and no more.
  b.doc()["materials"] = json::array({json::object()});
  b.write_embedded(dir_ / "plain.gltf");
  const Scene plain = load_gltf(dir_ / "plain.gltf");
  EXPECT_EQ(plain.meshes[0].primitives[0].uvs, both.uv_set(2));
  EXPECT_TRUE(plain.meshes[0].primitives[0].more_uvs.empty());
}

// A texture's sampler is read: its wrap modes and magFilter NEAREST go with the texture; one
// image through two samplers is two textures of the same texels; an invalid mode fails naming
// the sampler.
TEST_F(GltfLoaderTest, SamplersSetWrapModesAndNearestMagnification) {
  write_image8(DecodedImage{2, 1, 3, {0, 0, 0, 255, 255, 255}}, dir_ / "bw.png");
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["images"] = json::array({{{"uri", "bw.png"}}});
  b.doc()["samplers"] =
      json::array({{{"wrapS", 33071}, {"wrapT", 33648}, {"magFilter", 9728}}, json::object()});
  b.doc()["textures"] =
      json::array({{{"source", 0}, {"sampler", 0}}, {{"source", 0}, {"sampler", 1}}});
  b.doc()["materials"] = json::array(
      {{{"pbrMetallicRoughness",
         {{"baseColorTexture", {{"index", 0}}}, {"metallicRoughnessTexture", {{"index", 0}}}}},
        {"emissiveTexture", {{"index", 1}}}}});
  b.write_embedded(dir_ / "samplers.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "samplers.gltf", &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  // Color through sampler 0, data through sampler 0, color through the default sampler.
  ASSERT_EQ(scene.textures.size(), 3u);
  const Material& m = scene.materials[0];
  const Texture& clamped = scene.textures[size_t(m.base_color_texture)];
  EXPECT_EQ(clamped.wrap_s, Texture::Wrap::kClampToEdge);
  EXPECT_EQ(clamped.wrap_t, Texture::Wrap::kMirroredRepeat);
  EXPECT_TRUE(clamped.nearest);
  EXPECT_TRUE(scene.textures[size_t(m.metallic_roughness_texture)].nearest);
  const Texture& plain = scene.textures[size_t(m.emissive_texture)];
  EXPECT_EQ(plain.wrap_s, Texture::Wrap::kRepeat);
  EXPECT_EQ(plain.wrap_t, Texture::Wrap::kRepeat);
  EXPECT_FALSE(plain.nearest);
  EXPECT_EQ(plain.codes, clamped.codes);
  EXPECT_NE(m.base_color_texture, m.emissive_texture);

  b.doc()["samplers"][0]["wrapS"] = 1234;
  b.write_embedded(dir_ / "wrap.gltf");
  expect_error(dir_ / "wrap.gltf", "sampler 0 has an invalid wrapS (1234");
  b.doc()["samplers"][0]["wrapS"] = 10497;
  b.doc()["samplers"][0]["magFilter"] = 9987;
  b.write_embedded(dir_ / "mag.gltf");
  expect_error(dir_ / "mag.gltf", "sampler 0 has an invalid magFilter (9987");
}

// EXT_texture_webp: the WebP image it names replaces the texture's `source` (a fallback for
// viewers without it), also where the file requires the extension; a texture with only the
// extension needs no fallback; a bad index fails naming the texture.
TEST_F(GltfLoaderTest, WebpTexturesAreReadThroughExtTextureWebp) {
  write_image8(DecodedImage{1, 1, 3, {128, 128, 128}}, dir_ / "gray.png");
  const DecodedImage colors{2, 1, 3, {255, 0, 0, 0, 0, 255}};
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  const std::vector<uint8_t> webp_bytes = testing::lossless_webp(colors);
  const int view = b.add_view(webp_bytes);
  // The same WebP as a data URI too, which tinygltf does not decode itself.
  b.doc()["images"] =
      json::array({{{"uri", "gray.png"}},
                   {{"bufferView", view}, {"mimeType", "image/webp"}},
                   {{"uri", "data:image/webp;base64," + testing::base64(webp_bytes)}}});
  const json webp = {{"EXT_texture_webp", {{"source", 1}}}};
  b.doc()["textures"] = json::array({{{"source", 0}, {"extensions", webp}},
                                     {{"extensions", webp}},
                                     {{"extensions", {{"EXT_texture_webp", {{"source", 2}}}}}}});
  b.doc()["extensionsUsed"] = {"EXT_texture_webp"};
  b.doc()["extensionsRequired"] = {"EXT_texture_webp"};
  b.doc()["materials"] = json::array(
      {{{"pbrMetallicRoughness",
         {{"baseColorTexture", {{"index", 0}}}, {"metallicRoughnessTexture", {{"index", 1}}}}},
        {"emissiveTexture", {{"index", 2}}}}});
  b.write_embedded(dir_ / "webp.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "webp.gltf", &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  const Material& m = scene.materials[0];
  const Texture& color = scene.textures[size_t(m.base_color_texture)];
  ASSERT_EQ(color.width, 2);
  EXPECT_EQ(color.texel(0), glm::vec3(1.0f, 0.0f, 0.0f));
  EXPECT_EQ(color.texel(1), glm::vec3(0.0f, 0.0f, 1.0f));
  const Texture& data = scene.textures[size_t(m.metallic_roughness_texture)];
  EXPECT_EQ(data.codes, color.codes);  // the image's bytes, whichever way they decode
  EXPECT_EQ(scene.textures[size_t(m.emissive_texture)].codes, color.codes);

  b.doc()["textures"][1]["extensions"]["EXT_texture_webp"]["source"] = 5;
  b.write_embedded(dir_ / "index.gltf");
  expect_error(dir_ / "index.gltf", "texture 1 refers to image 5, but there are 3");
  b.doc()["textures"][1]["extensions"]["EXT_texture_webp"] = json::object();
  b.write_embedded(dir_ / "none.gltf");
  expect_error(dir_ / "none.gltf", "texture 1 EXT_texture_webp has no valid \"source\"");
}

// KHR_draco_mesh_compression: a primitive's indices and the attributes the extension names are
// decoded from its Draco data (here a quad of two triangles with texture coordinates, encoded
// by libdraco without quantization, so exactly), also where the file requires the extension;
// the triangles and each corner's coordinates come out as they went in, whatever order the
// encoder gave the points. Broken Draco data fails naming the primitive.
TEST_F(GltfLoaderTest, DracoCompressedPrimitivesAreDecoded) {
  const std::vector<glm::vec3> corners = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  const std::vector<glm::vec2> corner_uvs = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};
  const int triangles[2][3] = {{0, 1, 2}, {0, 2, 3}};
  draco::TriangleSoupMeshBuilder builder;
  builder.Start(2);
  const int position =
      builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  const int uv = builder.AddAttribute(draco::GeometryAttribute::TEX_COORD, 2, draco::DT_FLOAT32);
  for (uint32_t f = 0; f < 2; ++f) {
    const int* t = triangles[f];
    builder.SetAttributeValuesForFace(position, draco::FaceIndex(f), &corners[size_t(t[0])],
                                      &corners[size_t(t[1])], &corners[size_t(t[2])]);
    builder.SetAttributeValuesForFace(uv, draco::FaceIndex(f), &corner_uvs[size_t(t[0])],
                                      &corner_uvs[size_t(t[1])], &corner_uvs[size_t(t[2])]);
  }
  const std::unique_ptr<draco::Mesh> mesh = builder.Finalize();
  ASSERT_TRUE(mesh);
  draco::EncoderBuffer encoded;
  ASSERT_TRUE(draco::Encoder().EncodeMeshToBuffer(*mesh, &encoded).ok());
  const std::vector<uint8_t> bytes(encoded.data(), encoded.data() + encoded.size());
  // The accessors' counts are the points and triangles the data holds.
  draco::DecoderBuffer peek;
  peek.Init(encoded.data(), encoded.size());
  const size_t points = draco::Decoder().DecodeMeshFromBuffer(&peek).value()->num_points();

  GltfBuilder b;
  const int view = b.add_view(bytes);
  auto accessor = [&](int component, const char* type, size_t count) {
    b.doc()["accessors"].push_back(
        {{"componentType", component}, {"type", type}, {"count", count}});
    return int(b.doc()["accessors"].size()) - 1;
  };
  const int positions = accessor(5126, "VEC3", points);
  const int uvs = accessor(5126, "VEC2", points);
  const int indices = accessor(5123, "SCALAR", 6);
  b.doc()["meshes"] = json::array(
      {{{"primitives",
         json::array({{{"attributes", {{"POSITION", positions}, {"TEXCOORD_0", uvs}}},
                       {"indices", indices},
                       {"extensions",
                        {{"KHR_draco_mesh_compression",
                          {{"bufferView", view},
                           {"attributes",
                            {{"POSITION", mesh->attribute(position)->unique_id()},
                             {"TEXCOORD_0", mesh->attribute(uv)->unique_id()}}}}}}}}})}}});
  b.doc()["nodes"] = json::array({{{"mesh", 0}}});
  b.doc()["scenes"] = json::array({{{"nodes", {0}}}});
  b.doc()["extensionsUsed"] = {"KHR_draco_mesh_compression"};
  b.doc()["extensionsRequired"] = {"KHR_draco_mesh_compression"};
  b.write_embedded(dir_ / "draco.gltf");
  b.write_glb(dir_ / "draco.glb");
  for (const char* file : {"draco.gltf", "draco.glb"}) {
    SCOPED_TRACE(file);
    GltfLoadReport report;
    const Scene scene = load_gltf(dir_ / file, &report);
    EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
    const Primitive& p = scene.meshes.at(0).primitives.at(0);
    ASSERT_EQ(p.positions.size(), points);
    ASSERT_EQ(p.uvs.size(), points);
    ASSERT_EQ(p.indices.size(), 6u);
    // The triangles (each turned to start at its least corner, so that only the winding counts)
    // and each point's coordinates.
    using Triangle = std::array<glm::vec3, 3>;
    const auto less = [](const glm::vec3& a, const glm::vec3& c) {
      return std::lexicographical_compare(&a.x, &a.x + 3, &c.x, &c.x + 3);
    };
    const auto canonical = [&](Triangle t) {
      std::rotate(t.begin(), std::min_element(t.begin(), t.end(), less), t.end());
      return t;
    };
    const auto order = [&](const Triangle& a, const Triangle& c) {
      return std::lexicographical_compare(a.begin(), a.end(), c.begin(), c.end(), less);
    };
    std::vector<Triangle> got, want;
    for (size_t t = 0; t < 2; ++t) {
      Triangle g, w;
      for (size_t k = 0; k < 3; ++k) {
        g[k] = p.positions[p.indices[3 * t + k]];
        w[k] = corners[size_t(triangles[t][k])];
      }
      got.push_back(canonical(g));
      want.push_back(canonical(w));
    }
    std::sort(got.begin(), got.end(), order);
    std::sort(want.begin(), want.end(), order);
    EXPECT_EQ(got, want);
    for (size_t i = 0; i < points; ++i) {
      const size_t corner =
          size_t(std::find(corners.begin(), corners.end(), p.positions[i]) - corners.begin());
      ASSERT_LT(corner, corners.size()) << "point " << i;
      EXPECT_EQ(p.uvs[i], corner_uvs[corner]) << "point " << i;
    }
  }

  // The same file with its Draco data cut short.
  GltfBuilder cut = b;
  std::vector<uint8_t> half(bytes.begin(), bytes.begin() + bytes.size() / 2);
  cut.doc()["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]
           ["bufferView"] = cut.add_view(half);
  cut.write_embedded(dir_ / "cut.gltf");
  expect_error(dir_ / "cut.gltf", "mesh 0 primitive 0 KHR_draco_mesh_compression: cannot decode");

  // Draco data whose attribute is of a type no glTF component type matches (a bool, which
  // libdraco would read byte by byte whatever the byte: found by afr_fuzz_gltf).
  draco::TriangleSoupMeshBuilder flags;
  flags.Start(2);
  const int flag_position =
      flags.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  const int flag = flags.AddAttribute(draco::GeometryAttribute::GENERIC, 1, draco::DT_BOOL);
  const bool on[3] = {true, false, true};
  for (uint32_t f = 0; f < 2; ++f) {
    const int* t = triangles[f];
    flags.SetAttributeValuesForFace(flag_position, draco::FaceIndex(f), &corners[size_t(t[0])],
                                    &corners[size_t(t[1])], &corners[size_t(t[2])]);
    flags.SetAttributeValuesForFace(flag, draco::FaceIndex(f), &on[0], &on[1], &on[2]);
  }
  const std::unique_ptr<draco::Mesh> flagged = flags.Finalize();
  ASSERT_TRUE(flagged);
  draco::EncoderBuffer flagged_encoded;
  ASSERT_TRUE(draco::Encoder().EncodeMeshToBuffer(*flagged, &flagged_encoded).ok());
  GltfBuilder typed = b;
  typed.doc()["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"] = {
      {"bufferView", typed.add_view(std::vector<uint8_t>(
                         flagged_encoded.data(), flagged_encoded.data() + flagged_encoded.size()))},
      {"attributes",
       {{"POSITION", flagged->attribute(flag_position)->unique_id()},
        {"TEXCOORD_0", flagged->attribute(flag)->unique_id()}}}};
  draco::DecoderBuffer flagged_peek;
  flagged_peek.Init(flagged_encoded.data(), flagged_encoded.size());
  const size_t flagged_points =
      draco::Decoder().DecodeMeshFromBuffer(&flagged_peek).value()->num_points();
  typed.doc()["accessors"][positions]["count"] = flagged_points;
  typed.doc()["accessors"][uvs]["count"] = flagged_points;
  typed.write_embedded(dir_ / "typed.gltf");
  expect_error(dir_ / "typed.gltf",
               "mesh 0 primitive 0 KHR_draco_mesh_compression: its attribute TEXCOORD_0 has Draco "
               "data type 11, which no glTF component type matches");
}

// EXT_ and KHR_meshopt_compression: buffer views compressed with meshoptimizer's encoders (the
// three modes, and the three filters afr's meshoptimizer decodes, under vertex data, indices and
// an animation) read as the data they stand for, whether the placeholder buffer has no uri
// (.gltf, .glb) or is a fallback whose file is missing (never read). Broken data, what the
// extension forbids and what afr cannot decode fail naming the buffer view.
TEST_F(GltfLoaderTest, MeshoptCompressedBufferViewsAreDecoded) {
  GltfBuilder b;
  size_t placeholder = 0;  // the bytes of buffer 1, which holds nothing
  // A buffer view over buffer 1 standing for `count` elements of `stride` bytes, `encoded` in
  // buffer 0; returns its index.
  const auto add = [&](const std::vector<uint8_t>& encoded, size_t count, size_t stride,
                       const char* mode, const char* filter, bool view_stride) {
    while (b.bin().size() % 4 != 0) b.bin().push_back(0);
    json ext = {{"buffer", 0},
                {"byteOffset", b.bin().size()},
                {"byteLength", encoded.size()},
                {"byteStride", stride},
                {"count", count},
                {"mode", mode}};
    if (filter != nullptr) ext["filter"] = filter;
    b.bin().insert(b.bin().end(), encoded.begin(), encoded.end());
    json view = {{"buffer", 1},
                 {"byteOffset", placeholder},
                 {"byteLength", count * stride},
                 {"extensions", {{"EXT_meshopt_compression", ext}}}};
    if (view_stride) view["byteStride"] = stride;
    placeholder += (count * stride + 3) / 4 * 4;
    b.doc()["bufferViews"].push_back(view);
    return int(b.doc()["bufferViews"].size()) - 1;
  };
  const auto attributes = [](const void* data, size_t count, size_t stride) {
    std::vector<uint8_t> out(meshopt_encodeVertexBufferBound(count, stride));
    out.resize(meshopt_encodeVertexBuffer(out.data(), out.size(), data, count, stride));
    return out;
  };
  const std::vector<float> positions = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const int p =
      b.add_accessor(add(attributes(positions.data(), 4, 12), 4, 12, "ATTRIBUTES", nullptr, true),
                     kFloat, "VEC3", 4);
  // Normals as normalized bytes (KHR_mesh_quantization), octahedral.
  const std::vector<glm::vec3> normals = {{0, 0, 1}, {0.6f, 0, 0.8f}, {0, -0.6f, 0.8f}, {0, 0, 1}};
  std::vector<float> normal_in;
  for (const glm::vec3& v : normals) normal_in.insert(normal_in.end(), {v.x, v.y, v.z, 0.0f});
  std::vector<int8_t> octahedral(16);
  meshopt_encodeFilterOct(octahedral.data(), 4, 4, 8, normal_in.data());
  const int n = b.add_accessor(
      add(attributes(octahedral.data(), 4, 4), 4, 4, "ATTRIBUTES", "OCTAHEDRAL", true), kByte,
      "VEC3", 4, 0, /*normalized=*/true);
  // Mesh 0's indices as triangles, mesh 1's as a sequence.
  const std::vector<uint32_t> triangles = {0, 1, 2, 0, 2, 3};
  std::vector<uint8_t> encoded(meshopt_encodeIndexBufferBound(6, 4));
  encoded.resize(meshopt_encodeIndexBuffer(encoded.data(), encoded.size(), triangles.data(), 6));
  const int i0 =
      b.add_accessor(add(encoded, 6, 2, "TRIANGLES", nullptr, false), kUnsignedShort, "SCALAR", 6);
  encoded.assign(meshopt_encodeIndexSequenceBound(6, 4), 0);
  encoded.resize(meshopt_encodeIndexSequence(encoded.data(), encoded.size(), triangles.data(), 6));
  const int i1 =
      b.add_accessor(add(encoded, 6, 4, "INDICES", nullptr, false), kUnsignedInt, "SCALAR", 6);
  // An animation: key times through the exponential filter (24 bits of mantissa: exact), the
  // rotations as normalized shorts through the quaternion filter.
  const std::vector<float> times = {0.0f, 0.5f, 1.25f};
  std::vector<uint32_t> exponential(3);
  meshopt_encodeFilterExp(exponential.data(), 3, 4, 24, times.data());
  const int t = b.add_accessor(
      add(attributes(exponential.data(), 3, 4), 3, 4, "ATTRIBUTES", "EXPONENTIAL", false), kFloat,
      "SCALAR", 3);
  const float h = std::sqrt(0.5f);
  const std::vector<glm::vec4> rotations = {{0, 0, 0, 1}, {0, 0, h, h}, {0, 1, 0, 0}};
  std::vector<int16_t> quaternion(12);
  meshopt_encodeFilterQuat(quaternion.data(), 3, 8, 16, &rotations[0].x);
  const int r = b.add_accessor(
      add(attributes(quaternion.data(), 3, 8), 3, 8, "ATTRIBUTES", "QUATERNION", false), kShort,
      "VEC4", 3, 0, /*normalized=*/true);

  b.doc()["meshes"] = json::array(
      {{{"primitives",
         json::array({{{"attributes", {{"POSITION", p}, {"NORMAL", n}}}, {"indices", i0}}})}},
       {{"primitives", json::array({{{"attributes", {{"POSITION", p}}}, {"indices", i1}}})}}});
  b.doc()["nodes"] = json::array({{{"mesh", 0}}, {{"mesh", 1}}});
  b.doc()["scenes"] = json::array({{{"nodes", {0, 1}}}});
  b.doc()["animations"] = json::array(
      {{{"channels", {{{"sampler", 0}, {"target", {{"node", 1}, {"path", "rotation"}}}}}},
        {"samplers", {{{"input", t}, {"output", r}}}}}});
  b.doc()["extensionsUsed"] = {"EXT_meshopt_compression", "KHR_mesh_quantization"};
  b.doc()["extensionsRequired"] = {"EXT_meshopt_compression", "KHR_mesh_quantization"};
  b.more_buffers() = json::array({{{"byteLength", placeholder}}});
  b.write_embedded(dir_ / "meshopt.gltf");
  b.write_glb(dir_ / "meshopt.glb");
  GltfBuilder with_fallback = b;
  with_fallback.more_buffers()[0]["uri"] = "missing.bin";
  with_fallback.more_buffers()[0]["extensions"]["EXT_meshopt_compression"]["fallback"] = true;
  with_fallback.write_embedded(dir_ / "fallback.gltf");
  // The same under the KHR extension's name.
  const auto as_khr = [&](const fs::path& from, const fs::path& to) {
    std::ifstream in(from);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (size_t at; (at = text.find("EXT_meshopt_compression")) != std::string::npos;) {
      text.replace(at, 3, "KHR");
    }
    write_text(to, text);
  };
  as_khr(dir_ / "meshopt.gltf", dir_ / "khr.gltf");

  // A triangle turned to start at its least index (the codec may turn triangles).
  const auto canonical = [](const std::vector<uint32_t>& indices) {
    std::vector<uint32_t> out = indices;
    for (size_t k = 0; k + 3 <= out.size(); k += 3) {
      std::rotate(out.begin() + ptrdiff_t(k),
                  std::min_element(out.begin() + ptrdiff_t(k), out.begin() + ptrdiff_t(k + 3)),
                  out.begin() + ptrdiff_t(k + 3));
    }
    return out;
  };
  for (const char* file : {"meshopt.gltf", "meshopt.glb", "fallback.gltf", "khr.gltf"}) {
    SCOPED_TRACE(file);
    GltfLoadReport report;
    const Scene scene = load_gltf(dir_ / file, &report);
    EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
    ASSERT_EQ(scene.meshes.size(), 2u);
    const Primitive& a = scene.meshes[0].primitives.at(0);
    ASSERT_EQ(a.positions.size(), 4u);
    for (size_t v = 0; v < 4; ++v) {
      EXPECT_EQ(a.positions[v],
                glm::vec3(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]))
          << "vertex " << v;
      ASSERT_EQ(a.normals.size(), 4u);
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(a.normals[v][c], normals[v][c], 0.02) << v;
    }
    EXPECT_EQ(canonical(a.indices), triangles);
    EXPECT_EQ(scene.meshes[1].primitives.at(0).indices, triangles);  // a sequence keeps its order
    ASSERT_EQ(scene.channels.size(), 1u);
    EXPECT_EQ(scene.channels[0].times, (std::vector<double>{0.0, 0.5, 1.25}));
    ASSERT_EQ(scene.channels[0].values.size(), 3u);
    for (size_t k = 0; k < 3; ++k) {
      for (int c = 0; c < 4; ++c) {
        EXPECT_NEAR(scene.channels[0].values[k][c], rotations[k][c], 1e-4) << "key " << k;
      }
    }
  }

  // What fails, each naming the buffer view.
  const auto broken = [&](const char* name, const std::function<void(GltfBuilder*)>& change,
                          const std::string& problem, bool khr = false) {
    SCOPED_TRACE(name);
    GltfBuilder c = b;
    change(&c);
    const fs::path path = dir_ / (std::string(name) + ".gltf");
    c.write_embedded(path);
    if (khr) as_khr(path, path);
    expect_error(path, problem);
  };
  const auto ext = [](GltfBuilder* c, int view) -> json& {
    return c->doc()["bufferViews"][size_t(view)]["extensions"]["EXT_meshopt_compression"];
  };
  broken(
      "cut", [&](GltfBuilder* c) { ext(c, 0)["byteLength"] = 10; },
      "buffer view 0 EXT_meshopt_compression: cannot decode its ATTRIBUTES data");
  broken(
      "length", [&](GltfBuilder* c) { c->doc()["bufferViews"][0]["byteLength"] = 40; },
      "buffer view 0 EXT_meshopt_compression: count x byteStride is 4 x 12 = 48 bytes, but the "
      "buffer view's byteLength is 40");
  broken(
      "filter", [&](GltfBuilder* c) { ext(c, 0)["filter"] = "QUATERNION"; },
      "buffer view 0 EXT_meshopt_compression: the QUATERNION filter does not take a byteStride "
      "of 12");
  broken(
      "mode", [&](GltfBuilder* c) { ext(c, 2)["mode"] = "STRIPS"; },
      "buffer view 2 EXT_meshopt_compression has mode \"STRIPS\"");
  broken(
      "source", [&](GltfBuilder* c) { ext(c, 0)["buffer"] = 1; },
      "buffer view 0 EXT_meshopt_compression reads its compressed data from buffer 1, which "
      "holds no data");
  broken(
      "plain",
      [&](GltfBuilder* c) {
        c->doc()["bufferViews"][0].erase("extensions");
        c->doc()["bufferViews"][0].erase("byteStride");
      },
      "buffer view 0 (accessor 0 (mesh 0 primitive 0 POSITION)) is not compressed but reads "
      "buffer 1, which holds no data");
  broken(
      "version1", [&](GltfBuilder* c) { c->bin()[ext(c, 0)["byteOffset"].get<size_t>()] = 0xa1; },
      "buffer view 0 KHR_meshopt_compression uses version 1 of the attribute codec, which afr's "
      "meshoptimizer",
      /*khr=*/true);
  broken(
      "color", [&](GltfBuilder* c) { ext(c, 1)["filter"] = "COLOR"; },
      "buffer view 1 KHR_meshopt_compression uses the COLOR filter, which afr's meshoptimizer",
      /*khr=*/true);
}

// EXT_mesh_gpu_instancing: a node's mesh is drawn once per instance, each instance's TRS (its
// rotation here as normalized shorts) applied before the node's own: instance k becomes node
// (the file's node count + k), a child of the node carrying its mesh, and the node keeps none.
// Attributes of different counts, or a node without a mesh, fail naming the node.
TEST_F(GltfLoaderTest, GpuInstancingDrawsTheMeshOncePerInstance) {
  GltfBuilder b;
  add_quad(&b);
  const int t = b.add_floats({0, 0, 0, 5, 0, 0, 0, 5, 0}, 3);
  const std::vector<int16_t> r = {0, 0, 0, 32767, 0, 0, 32767, 0, 0, 0, 0, 32767};
  const int rot = b.add_accessor(b.add_view(r), kShort, "VEC4", 3, 0, /*normalized=*/true);
  const int scale = b.add_floats({1, 1, 1, 2, 2, 2, 1, 1, 1}, 3);
  b.doc()["nodes"][0]["translation"] = {0, 0, -10};
  b.doc()["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"] = {
      {"TRANSLATION", t}, {"ROTATION", rot}, {"SCALE", scale}};
  b.doc()["extensionsUsed"] = {"EXT_mesh_gpu_instancing"};
  b.doc()["extensionsRequired"] = {"EXT_mesh_gpu_instancing"};
  b.write_glb(dir_ / "instanced.glb");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "instanced.glb", &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  ASSERT_EQ(scene.nodes.size(), 4u);
  EXPECT_EQ(scene.nodes[0].mesh, -1);
  EXPECT_EQ(scene.nodes[0].children, (std::vector<int>{1, 2, 3}));
  const SceneState state = scene.evaluate(0.0);
  // The quad's corner (1, 0, 0): as it is, turned half round z and doubled, raised.
  const glm::dvec3 want[3] = {{1, 0, -10}, {3, 0, -10}, {1, 5, -10}};
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(scene.nodes[1 + k].mesh, 0);
    EXPECT_EQ(scene.nodes[1 + k].parent, 0);
    const glm::dvec3 corner = glm::dvec3(state.world[1 + k] * glm::dvec4(1, 0, 0, 1));
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(corner[c], want[k][c], 1e-4) << "instance " << k;
  }

  GltfBuilder short_scale = b;
  short_scale.doc()["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]["SCALE"] =
      short_scale.add_floats({1, 1, 1, 2, 2, 2}, 3);
  short_scale.write_embedded(dir_ / "counts.gltf");
  expect_error(dir_ / "counts.gltf",
               "node 0 EXT_mesh_gpu_instancing has 2 instances in SCALE but 3 in another "
               "attribute");
  GltfBuilder no_mesh = b;
  no_mesh.doc()["nodes"].push_back(
      {{"extensions", {{"EXT_mesh_gpu_instancing", {{"attributes", {{"TRANSLATION", t}}}}}}}});
  no_mesh.doc()["nodes"][0]["children"] = {1};
  no_mesh.write_embedded(dir_ / "no_mesh.gltf");
  expect_error(dir_ / "no_mesh.gltf", "node 1 EXT_mesh_gpu_instancing: the node has no mesh");
  GltfBuilder none = b;
  none.doc()["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"] = {{"_ID", t}};
  none.write_embedded(dir_ / "none.gltf");
  expect_error(dir_ / "none.gltf",
               "node 0 EXT_mesh_gpu_instancing has none of TRANSLATION, ROTATION and SCALE");
}

// CESIUM_RTC (3D Tiles' batched models, here required as such files require it): the scene is
// drawn relative to its center, which the log names: nodes keep their own transforms, so a
// center far out on the Earth costs no precision. A center that is not 3 finite numbers fails.
TEST_F(GltfLoaderTest, RtcCenterIsNamedAndTheSceneDrawnRelativeToIt) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["nodes"][0]["translation"] = {0, 0, -3};
  b.doc()["extensions"]["CESIUM_RTC"]["center"] = {1215012.5, -4736313.0, 4081605.25};
  b.doc()["extensionsUsed"] = {"CESIUM_RTC"};
  b.doc()["extensionsRequired"] = {"CESIUM_RTC"};
  b.write_glb(dir_ / "rtc.glb");
  testing::LogCapture log;
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "rtc.glb", &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  EXPECT_EQ(log.lines_with("CESIUM_RTC: drawn relative to its center (1215012.5, -4736313, "
                           "4081605.25)")
                .size(),
            1u);
  const glm::dvec3 corner = glm::dvec3(scene.evaluate(0.0).world[0] * glm::dvec4(1, 0, 0, 1));
  EXPECT_EQ(corner, glm::dvec3(1, 0, -3));

  for (const json& center : {json::array({1, 2}), json::array({1, 2, "3"}), json(7)}) {
    GltfBuilder bad = b;
    bad.doc()["extensions"]["CESIUM_RTC"]["center"] = center;
    bad.write_embedded(dir_ / "bad_rtc.gltf");
    expect_error(dir_ / "bad_rtc.gltf",
                 "CESIUM_RTC: \"center\" must be an array of 3 finite numbers");
  }
}

// KHR_node_visibility: a node whose `visible` is false hides its own and its descendants'
// meshes and lights (a child's own `true` does not show it again); cameras stay, and an
// animation of a hidden mesh's morph weights is dropped with it. A `visible` that is not a
// boolean fails naming the node.
TEST_F(GltfLoaderTest, NodeVisibilityHidesTheMeshesAndLightsBelowAHiddenNode) {
  GltfBuilder b;
  const int positions = add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["targets"] = {{{"POSITION", positions}}};
  b.doc()["meshes"][0]["weights"] = {0.0};
  const json hidden = {{"KHR_node_visibility", {{"visible", false}}}};
  const json shown = {{"KHR_node_visibility", {{"visible", true}}}};
  b.doc()["nodes"] = json::array(
      {{{"mesh", 0}, {"children", {1}}, {"extensions", hidden}},
       {{"mesh", 0},
        {"camera", 0},
        {"extensions",
         {{"KHR_node_visibility", {{"visible", true}}}, {"KHR_lights_punctual", {{"light", 0}}}}}},
       {{"mesh", 0}},
       {{"mesh", 0}, {"extensions", shown}, {"translation", {0, 0, 1}}}});
  b.doc()["scenes"][0]["nodes"] = {0, 2, 3};
  b.doc()["cameras"] = {
      {{"type", "perspective"}, {"perspective", {{"yfov", 0.8}, {"znear", 0.1}}}}};
  b.doc()["extensions"]["KHR_lights_punctual"]["lights"] = {{{"type", "point"}}};
  b.doc()["extensionsUsed"] = {"KHR_node_visibility", "KHR_lights_punctual"};
  b.doc()["extensionsRequired"] = {"KHR_node_visibility"};
  const int times = b.add_floats({0, 1}, 1);
  const int weights = b.add_floats({0, 1}, 1);
  b.doc()["animations"] = {
      {{"channels", {{{"sampler", 0}, {"target", {{"node", 1}, {"path", "weights"}}}}}},
       {"samplers", {{{"input", times}, {"output", weights}}}}}};
  const fs::path path = dir_ / "visibility.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  ASSERT_EQ(scene.nodes.size(), 4u);
  EXPECT_EQ(scene.nodes[0].mesh, -1);
  EXPECT_EQ(scene.nodes[1].mesh, -1);  // its own `true` does not show it below a hidden node
  EXPECT_EQ(scene.nodes[1].light, -1);
  EXPECT_EQ(scene.nodes[1].camera, 0);
  EXPECT_EQ(scene.nodes[2].mesh, 0);
  EXPECT_EQ(scene.nodes[3].mesh, 0);
  EXPECT_EQ(scene.triangle_count(), 4u);
  EXPECT_EQ(scene.camera_node(), 1);
  EXPECT_TRUE(scene.channels.empty());

  b.doc()["nodes"][0]["extensions"]["KHR_node_visibility"]["visible"] = "no";
  b.write_embedded(path);
  expect_error(path, "node 0 KHR_node_visibility has an invalid visible (true or false)");
}

// EXT_mesh_gpu_instancing where afr does not follow it: an animation of an instanced node's
// morph weights warns and is skipped (the instances keep the weights they load with); on a
// skinned node the extension warns and the mesh is drawn once, where its joints put it.
TEST_F(GltfLoaderTest, GpuInstancingOfWeightAnimatedOrSkinnedNodesWarns) {
  GltfBuilder b;
  add_quad(&b);
  const int up = b.add_floats({0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1}, 3);
  b.doc()["meshes"][0]["primitives"][0]["targets"] = json::array({{{"POSITION", up}}});
  b.doc()["meshes"][0]["weights"] = {0.5};
  const int t = b.add_floats({0, 0, 0, 2, 0, 0}, 3);
  b.doc()["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"] = {{"TRANSLATION", t}};
  b.doc()["extensionsUsed"] = {"EXT_mesh_gpu_instancing"};
  const int times = b.add_floats({0, 1}, 1);
  const int weights = b.add_floats({0, 1}, 1);
  b.doc()["animations"] = json::array(
      {{{"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "weights"}}}}}},
        {"samplers", {{{"input", times}, {"output", weights}}}}}});
  b.write_embedded(dir_ / "weights.gltf");
  GltfLoadReport report;
  const Scene morphed = load_gltf(dir_ / "weights.gltf", &report);
  EXPECT_EQ(count_containing(report.warnings,
                             "animated morph weights of a node with "
                             "EXT_mesh_gpu_instancing are not supported"),
            1u);
  EXPECT_TRUE(morphed.channels.empty());
  ASSERT_EQ(morphed.nodes.size(), 3u);
  EXPECT_EQ(morphed.nodes[1].mesh, 0);
  EXPECT_EQ(morphed.nodes[2].mesh, 0);

  GltfBuilder k;
  add_quad(&k);
  const int joints =
      k.add_accessor(k.add_view(std::vector<uint8_t>(16, 0)), kUnsignedByte, "VEC4", 4);
  const int joint_weights = k.add_floats({1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0}, 4);
  k.doc()["meshes"][0]["primitives"][0]["attributes"]["JOINTS_0"] = joints;
  k.doc()["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"] = joint_weights;
  k.doc()["nodes"] = json::array(
      {{{"mesh", 0},
        {"skin", 0},
        {"extensions", {{"EXT_mesh_gpu_instancing", {{"attributes", {{"TRANSLATION", t}}}}}}}},
       {{"translation", {0, 0, -5}}}});
  k.doc()["skins"] = json::array({{{"joints", {1}}}});
  k.doc()["scenes"] = json::array({{{"nodes", {0, 1}}}});
  k.doc()["extensionsUsed"] = {"EXT_mesh_gpu_instancing"};
  k.write_embedded(dir_ / "skinned.gltf");
  report = {};
  const Scene skinned = load_gltf(dir_ / "skinned.gltf", &report);
  EXPECT_EQ(count_containing(report.warnings,
                             "EXT_mesh_gpu_instancing on a node with a skin is not supported"),
            1u);
  ASSERT_EQ(skinned.nodes.size(), 2u);
  EXPECT_EQ(skinned.nodes[0].mesh, 0);
  EXPECT_EQ(skinned.nodes[0].skin, 0);
}

// KHR_materials_clearcoat: its factors are read (default 0), also where a file requires it; a
// factor out of range fails naming the material.
TEST_F(GltfLoaderTest, ClearcoatFactorsAreRead) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["extensionsUsed"] = {"KHR_materials_clearcoat"};
  b.doc()["extensionsRequired"] = {"KHR_materials_clearcoat"};
  b.doc()["materials"] =
      json::array({{{"extensions",
                     {{"KHR_materials_clearcoat",
                       {{"clearcoatFactor", 0.75}, {"clearcoatRoughnessFactor", 0.25}}}}}},
                   {{"extensions", {{"KHR_materials_clearcoat", json::object()}}}}});
  b.write_embedded(dir_ / "clearcoat.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "clearcoat.gltf", &report);
  ASSERT_EQ(scene.materials.size(), 2u);
  EXPECT_EQ(scene.materials[0].clearcoat, 0.75f);
  EXPECT_EQ(scene.materials[0].clearcoat_roughness, 0.25f);
  EXPECT_EQ(scene.materials[1].clearcoat, 0.0f);
  EXPECT_EQ(scene.materials[1].clearcoat_roughness, 0.0f);
  EXPECT_EQ(scene.materials[0].clearcoat_texture, -1);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();

  b.doc()["materials"][0]["extensions"]["KHR_materials_clearcoat"]["clearcoatRoughnessFactor"] =
      -0.5;
  b.write_embedded(dir_ / "bad.gltf");
  expect_error(dir_ / "bad.gltf",
               "material 0 KHR_materials_clearcoat has an invalid clearcoatRoughnessFactor");
}

// KHR_materials_volume: thickness, attenuation color and distance are read (defaults 0, white,
// infinity), also where a file requires it; the thickness texture is not (one warning); a
// distance of 0 or a color out of range fails naming the material.
TEST_F(GltfLoaderTest, VolumeFactorsAreRead) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["extensionsUsed"] = {"KHR_materials_volume", "KHR_materials_transmission"};
  b.doc()["extensionsRequired"] = {"KHR_materials_volume"};
  b.doc()["materials"] =
      json::array({{{"extensions",
                     {{"KHR_materials_transmission", {{"transmissionFactor", 1.0}}},
                      {"KHR_materials_volume",
                       {{"thicknessFactor", 0.5},
                        {"attenuationDistance", 2.0},
                        {"attenuationColor", {1.0, 0.5, 0.25}},
                        {"thicknessTexture", {{"index", 0}}}}}}}},
                   {{"extensions", {{"KHR_materials_volume", json::object()}}}}});
  b.write_embedded(dir_ / "volume.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "volume.gltf", &report);
  ASSERT_EQ(scene.materials.size(), 2u);
  EXPECT_EQ(scene.materials[0].thickness, 0.5f);
  EXPECT_EQ(scene.materials[0].attenuation_distance, 2.0f);
  EXPECT_EQ(scene.materials[0].attenuation_color, glm::vec3(1.0f, 0.5f, 0.25f));
  EXPECT_EQ(scene.materials[1].thickness, 0.0f);
  EXPECT_TRUE(std::isinf(scene.materials[1].attenuation_distance));
  EXPECT_EQ(scene.materials[1].attenuation_color, glm::vec3(1.0f));
  EXPECT_EQ(count_containing(report.warnings, "thicknessTexture is not read"), 1u);
  EXPECT_EQ(report.warnings.size(), 1u);

  GltfBuilder zero = b;
  zero.doc()["materials"][0]["extensions"]["KHR_materials_volume"]["attenuationDistance"] = 0;
  zero.write_embedded(dir_ / "zero.gltf");
  expect_error(dir_ / "zero.gltf",
               "material 0 KHR_materials_volume has an invalid attenuationDistance");
  b.doc()["materials"][0]["extensions"]["KHR_materials_volume"]["attenuationColor"] = {1, 2, 0};
  b.write_embedded(dir_ / "color.gltf");
  expect_error(dir_ / "color.gltf",
               "material 0 KHR_materials_volume has an invalid attenuationColor");
}

// KHR_materials_dispersion: read (default 0), also where a file requires it; on a material
// without a volume, which it builds on, it warns; a negative value fails naming the material.
TEST_F(GltfLoaderTest, DispersionIsRead) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["extensionsUsed"] = {"KHR_materials_dispersion", "KHR_materials_volume",
                               "KHR_materials_transmission"};
  b.doc()["extensionsRequired"] = {"KHR_materials_dispersion"};
  const json glass = {{"KHR_materials_transmission", {{"transmissionFactor", 1.0}}},
                      {"KHR_materials_volume", {{"thicknessFactor", 0.5}}},
                      {"KHR_materials_dispersion", {{"dispersion", 0.36}}}};
  b.doc()["materials"] = json::array(
      {{{"extensions", glass}}, {{"extensions", {{"KHR_materials_dispersion", json::object()}}}}});
  b.write_embedded(dir_ / "dispersion.gltf");
  GltfLoadReport report;
  Scene scene = load_gltf(dir_ / "dispersion.gltf", &report);
  ASSERT_EQ(scene.materials.size(), 2u);
  EXPECT_EQ(scene.materials[0].dispersion, 0.36f);
  EXPECT_EQ(scene.materials[1].dispersion, 0.0f);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();

  json thin = glass;  // a thin wall: nothing to disperse in
  thin["KHR_materials_volume"]["thicknessFactor"] = 0;
  b.doc()["materials"][1] = {{"extensions", thin}};
  b.write_embedded(dir_ / "thin.gltf");
  report = {};
  scene = load_gltf(dir_ / "thin.gltf", &report);
  EXPECT_EQ(scene.materials[1].dispersion, 0.36f);
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("material 1 KHR_materials_dispersion: dispersion has no "
                                    "effect without transmission and a volume"),
            std::string::npos)
      << report.warnings[0];

  b.doc()["materials"][0]["extensions"]["KHR_materials_dispersion"]["dispersion"] = -1;
  b.write_embedded(dir_ / "negative.gltf");
  expect_error(dir_ / "negative.gltf",
               "material 0 KHR_materials_dispersion has an invalid dispersion");
}

// KHR_materials_specular: its factors are read (defaults 1), also where a file requires it; a
// factor out of range fails naming the material.
TEST_F(GltfLoaderTest, SpecularExtensionFactorsAreRead) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["extensionsUsed"] = {"KHR_materials_specular"};
  b.doc()["extensionsRequired"] = {"KHR_materials_specular"};
  b.doc()["materials"] =
      json::array({{{"extensions",
                     {{"KHR_materials_specular",
                       {{"specularFactor", 0.5}, {"specularColorFactor", {1.0, 0.5, 2.0}}}}}}},
                   {{"extensions", {{"KHR_materials_specular", json::object()}}}},
                   json::object()});
  b.write_embedded(dir_ / "specular.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "specular.gltf", &report);
  ASSERT_EQ(scene.materials.size(), 3u);
  EXPECT_TRUE(scene.materials[0].has_specular_extension);
  EXPECT_EQ(scene.materials[0].specular, 0.5f);
  EXPECT_EQ(scene.materials[0].specular_color, glm::vec3(1.0f, 0.5f, 2.0f));
  EXPECT_TRUE(scene.materials[1].has_specular_extension);
  EXPECT_EQ(scene.materials[1].specular, 1.0f);
  EXPECT_EQ(scene.materials[1].specular_color, glm::vec3(1.0f));
  EXPECT_FALSE(scene.materials[2].has_specular_extension);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();

  b.doc()["materials"][0]["extensions"]["KHR_materials_specular"]["specularFactor"] = 2.0;
  b.write_embedded(dir_ / "bad.gltf");
  expect_error(dir_ / "bad.gltf",
               "material 0 KHR_materials_specular has an invalid specularFactor");
}

// The material extensions' textures (transmission, specular, specular color, clearcoat,
// clearcoat roughness, clearcoat normal) are read as the core's are: their texture coordinate
// sets come after the core slots' and share where they agree; the specular texture is the
// image's alpha (held in red, green and blue as data), its color texture sRGB; the clearcoat
// normal keeps its scale. A slot that is not a textureInfo fails naming it.
TEST_F(GltfLoaderTest, MaterialExtensionTexturesAreRead) {
  // One RGBA texel: color 128, 64, 32, alpha 51.
  write_image8(DecodedImage{1, 1, 4, {128, 64, 32, 51}}, dir_ / "rgba.png");
  GltfBuilder b;
  add_quad(&b);
  json& primitive = b.doc()["meshes"][0]["primitives"][0];
  primitive["material"] = 0;
  primitive["attributes"]["TEXCOORD_0"] = b.add_floats({0, 0, 1, 0, 1, 1, 0, 1}, 2);
  primitive["attributes"]["TEXCOORD_1"] = b.add_floats({0, 0, 2, 0, 2, 2, 0, 2}, 2);
  b.doc()["images"] = json::array({{{"uri", "rgba.png"}}});
  b.doc()["textures"] = json::array({{{"source", 0}}});
  b.doc()["extensionsUsed"] = {"KHR_materials_transmission", "KHR_materials_specular",
                               "KHR_materials_clearcoat", "KHR_texture_transform"};
  const json scaled = {{"KHR_texture_transform", {{"scale", {2.0, 2.0}}}}};
  b.doc()["materials"] =
      json::array({{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}},
                    {"extensions",
                     {{"KHR_materials_transmission",
                       {{"transmissionFactor", 1.0}, {"transmissionTexture", {{"index", 0}}}}},
                      {"KHR_materials_specular",
                       {{"specularTexture", {{"index", 0}, {"texCoord", 1}}},
                        {"specularColorTexture", {{"index", 0}, {"texCoord", 1}}}}},
                      {"KHR_materials_clearcoat",
                       {{"clearcoatFactor", 1.0},
                        {"clearcoatTexture", {{"index", 0}, {"extensions", scaled}}},
                        {"clearcoatRoughnessTexture", {{"index", 0}}},
                        {"clearcoatNormalTexture", {{"index", 0}, {"scale", 0.5}}}}}}}}});
  b.write_embedded(dir_ / "extension_textures.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "extension_textures.gltf", &report);
  ASSERT_EQ(scene.materials.size(), 1u);
  const Material& m = scene.materials[0];
  // The image as sRGB color (base color, specular color), as data (transmission, clearcoat,
  // its roughness and normal) and as its alpha (specular).
  ASSERT_EQ(scene.textures.size(), 3u);
  EXPECT_EQ(m.base_color_texture, 0);
  EXPECT_EQ(m.transmission_texture, 1);
  EXPECT_EQ(m.specular_texture, 2);
  EXPECT_EQ(m.specular_color_texture, 0);
  EXPECT_EQ(m.clearcoat_texture, 1);
  EXPECT_EQ(m.clearcoat_roughness_texture, 1);
  EXPECT_EQ(m.clearcoat_normal_texture, 1);
  EXPECT_FLOAT_EQ(m.clearcoat_normal_scale, 0.5f);
  EXPECT_NEAR(scene.textures[1].texel(0).g, 64 / 255.0, 1e-6);
  EXPECT_NEAR(scene.textures[0].texel(0).r, reference_srgb_to_linear(128 / 255.0), 1e-6);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(scene.textures[2].texel(0)[c], 51 / 255.0, 1e-6);
  EXPECT_FALSE(scene.textures[2].coded_alpha);
  EXPECT_EQ(m.uv_set, (Material::TextureSets{.specular = 1, .specular_color = 1, .clearcoat = 2}));
  const Primitive& p = scene.meshes[0].primitives[0];
  ASSERT_EQ(p.more_uvs.size(), 2u);
  EXPECT_EQ(p.uv_set(1)[2], glm::vec2(2.0f, 2.0f));  // TEXCOORD_1
  EXPECT_EQ(p.uv_set(2)[2], glm::vec2(2.0f, 2.0f));  // TEXCOORD_0 scaled by 2
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();

  json& clearcoat = b.doc()["materials"][0]["extensions"]["KHR_materials_clearcoat"];
  clearcoat["clearcoatTexture"] = {{"texCoord", 0}};
  b.write_embedded(dir_ / "no_index.gltf");
  expect_error(dir_ / "no_index.gltf",
               "material 0 KHR_materials_clearcoat clearcoatTexture has no valid index");
  clearcoat["clearcoatTexture"] = {{"index", 0}, {"texCoord", -1}};
  b.write_embedded(dir_ / "tex_coord.gltf");
  expect_error(dir_ / "tex_coord.gltf",
               "material 0 KHR_materials_clearcoat clearcoatTexture has an invalid texCoord");
  clearcoat["clearcoatTexture"] = {{"index", 3}};
  b.write_embedded(dir_ / "index.gltf");
  expect_error(dir_ / "index.gltf",
               "material 0 clearcoatTexture refers to texture 3, but there are 1");
  clearcoat["clearcoatTexture"] = 0;
  b.write_embedded(dir_ / "not_object.gltf");
  expect_error(dir_ / "not_object.gltf",
               "material 0 KHR_materials_clearcoat clearcoatTexture is not an object");
  clearcoat["clearcoatTexture"] = {{"index", 0}};
  clearcoat["clearcoatNormalTexture"]["scale"] = "big";
  b.write_embedded(dir_ / "scale.gltf");
  expect_error(dir_ / "scale.gltf",
               "material 0 KHR_materials_clearcoat clearcoatNormalTexture has an invalid scale");
}

// KHR_materials_sheen: its factors (defaults 0) and textures are read, the roughness texture
// from the image's alpha; a factor out of range fails naming the material.
TEST_F(GltfLoaderTest, SheenIsRead) {
  write_image8(DecodedImage{1, 1, 4, {128, 64, 32, 51}}, dir_ / "rgba.png");
  GltfBuilder b;
  add_quad(&b);
  json& primitive = b.doc()["meshes"][0]["primitives"][0];
  primitive["material"] = 0;
  primitive["attributes"]["TEXCOORD_0"] = b.add_floats({0, 0, 1, 0, 1, 1, 0, 1}, 2);
  b.doc()["images"] = json::array({{{"uri", "rgba.png"}}});
  b.doc()["textures"] = json::array({{{"source", 0}}});
  b.doc()["extensionsUsed"] = {"KHR_materials_sheen"};
  b.doc()["extensionsRequired"] = {"KHR_materials_sheen"};
  b.doc()["materials"] = json::array({{{"extensions",
                                        {{"KHR_materials_sheen",
                                          {{"sheenColorFactor", {1.0, 0.5, 0.25}},
                                           {"sheenRoughnessFactor", 0.75},
                                           {"sheenColorTexture", {{"index", 0}}},
                                           {"sheenRoughnessTexture", {{"index", 0}}}}}}}},
                                      {{"extensions", {{"KHR_materials_sheen", json::object()}}}}});
  b.write_embedded(dir_ / "sheen.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "sheen.gltf", &report);
  ASSERT_EQ(scene.materials.size(), 2u);
  const Material& m = scene.materials[0];
  EXPECT_EQ(m.sheen_color, glm::vec3(1.0f, 0.5f, 0.25f));
  EXPECT_EQ(m.sheen_roughness, 0.75f);
  ASSERT_EQ(scene.textures.size(), 2u);
  EXPECT_EQ(m.sheen_color_texture, 0);
  EXPECT_EQ(m.sheen_roughness_texture, 1);
  EXPECT_NEAR(scene.textures[0].texel(0).g, reference_srgb_to_linear(64 / 255.0), 1e-6);
  EXPECT_NEAR(scene.textures[1].texel(0).r, 51 / 255.0, 1e-6);
  EXPECT_EQ(scene.materials[1].sheen_color, glm::vec3(0.0f));
  EXPECT_EQ(scene.materials[1].sheen_roughness, 0.0f);
  EXPECT_EQ(scene.materials[1].sheen_color_texture, -1);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();

  b.doc()["materials"][0]["extensions"]["KHR_materials_sheen"]["sheenColorFactor"] = {1.0, 2.0,
                                                                                      0.0};
  b.write_embedded(dir_ / "bad.gltf");
  expect_error(dir_ / "bad.gltf", "material 0 KHR_materials_sheen has an invalid sheenColorFactor");
}

// KHR_materials_anisotropy: its strength (default 0), rotation (default 0) and texture (data)
// are read; a strength out of range or a rotation that is not a number fails naming them.
TEST_F(GltfLoaderTest, AnisotropyIsRead) {
  write_image8(DecodedImage{1, 1, 3, {255, 128, 64}}, dir_ / "direction.png");
  GltfBuilder b;
  add_quad(&b);
  json& primitive = b.doc()["meshes"][0]["primitives"][0];
  primitive["material"] = 0;
  primitive["attributes"]["TEXCOORD_0"] = b.add_floats({0, 0, 1, 0, 1, 1, 0, 1}, 2);
  b.doc()["images"] = json::array({{{"uri", "direction.png"}}});
  b.doc()["textures"] = json::array({{{"source", 0}}});
  b.doc()["extensionsUsed"] = {"KHR_materials_anisotropy"};
  b.doc()["extensionsRequired"] = {"KHR_materials_anisotropy"};
  b.doc()["materials"] =
      json::array({{{"extensions",
                     {{"KHR_materials_anisotropy",
                       {{"anisotropyStrength", 0.5},
                        {"anisotropyRotation", 1.25},
                        {"anisotropyTexture", {{"index", 0}}}}}}}},
                   {{"extensions", {{"KHR_materials_anisotropy", json::object()}}}}});
  b.write_embedded(dir_ / "anisotropy.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "anisotropy.gltf", &report);
  ASSERT_EQ(scene.materials.size(), 2u);
  const Material& m = scene.materials[0];
  EXPECT_EQ(m.anisotropy, 0.5f);
  EXPECT_EQ(m.anisotropy_rotation, 1.25f);
  ASSERT_EQ(m.anisotropy_texture, 0);
  EXPECT_NEAR(scene.textures[0].texel(0).g, 128 / 255.0, 1e-6);  // data, not sRGB
  EXPECT_EQ(scene.materials[1].anisotropy, 0.0f);
  EXPECT_EQ(scene.materials[1].anisotropy_rotation, 0.0f);
  EXPECT_EQ(scene.materials[1].anisotropy_texture, -1);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();

  json& e = b.doc()["materials"][0]["extensions"]["KHR_materials_anisotropy"];
  e["anisotropyStrength"] = 1.5;
  b.write_embedded(dir_ / "strength.gltf");
  expect_error(dir_ / "strength.gltf",
               "material 0 KHR_materials_anisotropy has an invalid anisotropyStrength");
  e["anisotropyStrength"] = 0.5;
  e["anisotropyRotation"] = "left";
  b.write_embedded(dir_ / "rotation.gltf");
  expect_error(dir_ / "rotation.gltf",
               "material 0 KHR_materials_anisotropy has an invalid anisotropyRotation");
}

// KHR_materials_pbrSpecularGlossiness replaces the material's pbrMetallicRoughness (whose
// textures are then not decoded): its diffuse is the base color, its specular color F0 (sRGB),
// the texture's alpha the glossiness (data), 1 - glossinessFactor the roughness, metallic 0.
// Factors out of range fail naming them.
TEST_F(GltfLoaderTest, SpecularGlossinessMaterialsAreRead) {
  write_image8(DecodedImage{1, 1, 4, {128, 64, 32, 51}}, dir_ / "specgloss.png");
  write_image8(DecodedImage{1, 1, 3, {10, 20, 30}}, dir_ / "fallback.png");
  GltfBuilder b;
  add_quad(&b);
  json& primitive = b.doc()["meshes"][0]["primitives"][0];
  primitive["material"] = 0;
  primitive["attributes"]["TEXCOORD_0"] = b.add_floats({0, 0, 1, 0, 1, 1, 0, 1}, 2);
  b.doc()["images"] = json::array({{{"uri", "specgloss.png"}}, {{"uri", "fallback.png"}}});
  b.doc()["textures"] = json::array({{{"source", 0}}, {{"source", 1}}});
  b.doc()["extensionsUsed"] = {"KHR_materials_pbrSpecularGlossiness"};
  b.doc()["extensionsRequired"] = {"KHR_materials_pbrSpecularGlossiness"};
  b.doc()["materials"] =
      json::array({{{"pbrMetallicRoughness",
                     {{"baseColorFactor", {0.1, 0.1, 0.1, 1.0}},
                      {"baseColorTexture", {{"index", 1}}},
                      {"metallicRoughnessTexture", {{"index", 1}}}}},
                    {"extensions",
                     {{"KHR_materials_pbrSpecularGlossiness",
                       {{"diffuseFactor", {1.0, 0.5, 0.25, 0.75}},
                        {"specularFactor", {0.5, 0.25, 1.0}},
                        {"glossinessFactor", 0.8},
                        {"diffuseTexture", {{"index", 0}}},
                        {"specularGlossinessTexture", {{"index", 0}}}}}}}},
                   {{"extensions", {{"KHR_materials_pbrSpecularGlossiness", json::object()}}}}});
  b.write_embedded(dir_ / "specgloss.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "specgloss.gltf", &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  ASSERT_EQ(scene.materials.size(), 2u);
  const Material& m = scene.materials[0];
  EXPECT_TRUE(m.specular_glossiness);
  EXPECT_TRUE(m.has_specular_extension);
  EXPECT_EQ(m.base_color_factor, glm::vec4(1.0f, 0.5f, 0.25f, 0.75f));
  EXPECT_EQ(m.specular_color, glm::vec3(0.5f, 0.25f, 1.0f));
  EXPECT_EQ(m.specular, 1.0f);
  EXPECT_NEAR(m.roughness, 0.2f, 1e-6f);
  EXPECT_EQ(m.metallic, 0.0f);
  EXPECT_EQ(m.metallic_roughness_texture, -1);
  // The image read twice (color and alpha); the fallback's image never.
  ASSERT_EQ(scene.textures.size(), 2u);
  ASSERT_GE(m.base_color_texture, 0);
  EXPECT_EQ(m.specular_color_texture, m.base_color_texture);
  ASSERT_GE(m.glossiness_texture, 0);
  EXPECT_NE(m.glossiness_texture, m.base_color_texture);
  const Texture& color = scene.textures[size_t(m.specular_color_texture)];
  EXPECT_NEAR(color.texel(0).g, reference_srgb_to_linear(64 / 255.0), 1e-6);
  EXPECT_NEAR(scene.textures[size_t(m.glossiness_texture)].texel(0).r, 51 / 255.0, 1e-6);
  EXPECT_EQ(m.uv_set.glossiness, m.uv_set.base_color);
  // The defaults: white diffuse, white specular, glossiness 1.
  const Material& plain = scene.materials[1];
  EXPECT_TRUE(plain.specular_glossiness);
  EXPECT_EQ(plain.base_color_factor, glm::vec4(1.0f));
  EXPECT_EQ(plain.specular_color, glm::vec3(1.0f));
  EXPECT_EQ(plain.roughness, 0.0f);
  EXPECT_EQ(plain.glossiness_texture, -1);

  json& e = b.doc()["materials"][0]["extensions"]["KHR_materials_pbrSpecularGlossiness"];
  e["glossinessFactor"] = 1.5;
  b.write_embedded(dir_ / "gloss.gltf");
  expect_error(dir_ / "gloss.gltf",
               "material 0 KHR_materials_pbrSpecularGlossiness has an invalid glossinessFactor");
  e["glossinessFactor"] = 0.5;
  e["diffuseFactor"] = {1.0, 0.5, 0.25};
  b.write_embedded(dir_ / "diffuse.gltf");
  expect_error(dir_ / "diffuse.gltf",
               "material 0 KHR_materials_pbrSpecularGlossiness has an invalid diffuseFactor");
  e["diffuseFactor"] = {1.0, 0.5, 0.25, 1.0};
  e["specularGlossinessTexture"] = {{"index", 7}};
  b.write_embedded(dir_ / "texture.gltf");
  expect_error(dir_ / "texture.gltf", "refers to texture 7, but there are 2");
}

// KHR_materials_variants: a file that requires it loads with each primitive's own material
// (what a viewer shows when no variant is chosen); a malformed variant list, which is not drawn,
// warns naming what is wrong.
TEST_F(GltfLoaderTest, MaterialVariantsLoadWithTheDefaultMaterials) {
  GltfBuilder b;
  add_quad(&b);
  json& primitive = b.doc()["meshes"][0]["primitives"][0];
  primitive["material"] = 1;
  primitive["extensions"]["KHR_materials_variants"]["mappings"] =
      json::array({{{"material", 0}, {"variants", {0}}}, {{"material", 1}, {"variants", {1}}}});
  b.doc()["extensionsUsed"] = {"KHR_materials_variants"};
  b.doc()["extensionsRequired"] = {"KHR_materials_variants"};
  b.doc()["extensions"]["KHR_materials_variants"]["variants"] =
      json::array({{{"name", "red"}}, {{"name", "blue"}}});
  b.doc()["materials"] =
      json::array({{{"pbrMetallicRoughness", {{"baseColorFactor", {1.0, 0.0, 0.0, 1.0}}}}},
                   {{"pbrMetallicRoughness", {{"baseColorFactor", {0.0, 0.0, 1.0, 1.0}}}}}});
  b.write_embedded(dir_ / "variants.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "variants.gltf", &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  ASSERT_EQ(scene.meshes.size(), 1u);
  EXPECT_EQ(scene.meshes[0].primitives[0].material, 1);

  for (const json& variants : {json::array({{{"name", "red"}}, {{"name", 3}}}), json::array()}) {
    b.doc()["extensions"]["KHR_materials_variants"]["variants"] = variants;
    b.write_embedded(dir_ / "malformed.gltf");
    GltfLoadReport warned;
    const Scene drawn = load_gltf(dir_ / "malformed.gltf", &warned);
    EXPECT_EQ(drawn.meshes[0].primitives[0].material, 1);
    ASSERT_EQ(warned.warnings.size(), 1u);
    EXPECT_NE(warned.warnings[0].find(variants.empty()
                                          ? "KHR_materials_variants has no \"variants\" array"
                                          : "KHR_materials_variants variant 1 has no name"),
              std::string::npos)
        << warned.warnings[0];
  }
}

// KHR_materials_iridescence: its factor, ior, thickness range and textures (data) are read,
// with the extension's defaults; an ior below 1 or a negative thickness fails naming them.
TEST_F(GltfLoaderTest, IridescenceIsRead) {
  write_image8(DecodedImage{1, 1, 3, {255, 128, 64}}, dir_ / "film.png");
  GltfBuilder b;
  add_quad(&b);
  json& primitive = b.doc()["meshes"][0]["primitives"][0];
  primitive["material"] = 0;
  primitive["attributes"]["TEXCOORD_0"] = b.add_floats({0, 0, 1, 0, 1, 1, 0, 1}, 2);
  b.doc()["images"] = json::array({{{"uri", "film.png"}}});
  b.doc()["textures"] = json::array({{{"source", 0}}});
  b.doc()["extensionsUsed"] = {"KHR_materials_iridescence"};
  b.doc()["extensionsRequired"] = {"KHR_materials_iridescence"};
  b.doc()["materials"] =
      json::array({{{"extensions",
                     {{"KHR_materials_iridescence",
                       {{"iridescenceFactor", 0.75},
                        {"iridescenceIor", 1.8},
                        {"iridescenceThicknessMinimum", 50.0},
                        {"iridescenceThicknessMaximum", 800.0},
                        {"iridescenceTexture", {{"index", 0}}},
                        {"iridescenceThicknessTexture", {{"index", 0}}}}}}}},
                   {{"extensions", {{"KHR_materials_iridescence", json::object()}}}}});
  b.write_embedded(dir_ / "iridescence.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "iridescence.gltf", &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  ASSERT_EQ(scene.materials.size(), 2u);
  const Material& m = scene.materials[0];
  EXPECT_EQ(m.iridescence, 0.75f);
  EXPECT_EQ(m.iridescence_ior, 1.8f);
  EXPECT_EQ(m.iridescence_thickness_min, 50.0f);
  EXPECT_EQ(m.iridescence_thickness_max, 800.0f);
  ASSERT_EQ(m.iridescence_texture, 0);
  EXPECT_EQ(m.iridescence_thickness_texture, 0);
  EXPECT_NEAR(scene.textures[0].texel(0).g, 128 / 255.0, 1e-6);  // data, not sRGB
  const Material& plain = scene.materials[1];
  EXPECT_EQ(plain.iridescence, 0.0f);
  EXPECT_EQ(plain.iridescence_ior, 1.3f);
  EXPECT_EQ(plain.iridescence_thickness_min, 100.0f);
  EXPECT_EQ(plain.iridescence_thickness_max, 400.0f);
  EXPECT_EQ(plain.iridescence_texture, -1);

  json& e = b.doc()["materials"][0]["extensions"]["KHR_materials_iridescence"];
  e["iridescenceIor"] = 0.5;
  b.write_embedded(dir_ / "ior.gltf");
  expect_error(dir_ / "ior.gltf",
               "material 0 KHR_materials_iridescence has an invalid iridescenceIor");
  e["iridescenceIor"] = 1.3;
  e["iridescenceThicknessMaximum"] = -1.0;
  b.write_embedded(dir_ / "thickness.gltf");
  expect_error(dir_ / "thickness.gltf",
               "material 0 KHR_materials_iridescence has an invalid iridescenceThicknessMaximum");
}

// KHR_materials_unlit is read, also where a file requires it.
TEST_F(GltfLoaderTest, UnlitMaterialsAreRead) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["extensionsUsed"] = {"KHR_materials_unlit"};
  b.doc()["extensionsRequired"] = {"KHR_materials_unlit"};
  b.doc()["materials"] =
      json::array({{{"extensions", {{"KHR_materials_unlit", json::object()}}}}, json::object()});
  b.write_embedded(dir_ / "unlit.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "unlit.gltf", &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  ASSERT_EQ(scene.materials.size(), 2u);
  EXPECT_TRUE(scene.materials[0].unlit);
  EXPECT_FALSE(scene.materials[1].unlit);
}

// alphaMode MASK keeps its cutoff and its base-color texture's alpha, and so does BLEND; an
// image with alpha that no masking or blending material reads, or whose alpha is 1 everywhere,
// keeps none; neither warns; an alphaCutoff below 0 fails naming the material.
TEST_F(GltfLoaderTest, MaskedMaterialsKeepTheirCutoffAndTheirTexturesAlpha) {
  const DecodedImage leaf{2, 1, 4, {10, 200, 30, 0, 10, 200, 30, 255}};
  const DecodedImage solid{1, 1, 4, {50, 50, 50, 255}};
  write_image8(leaf, dir_ / "leaf.png");
  write_image8(solid, dir_ / "solid.png");
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["images"] = json::array({{{"uri", "leaf.png"}}, {{"uri", "solid.png"}}});
  b.doc()["textures"] = json::array({{{"source", 0}}, {{"source", 1}}});
  b.doc()["materials"] =
      json::array({{{"alphaMode", "MASK"},
                    {"alphaCutoff", 0.25},
                    {"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}},
                   {{"alphaMode", "MASK"},  // a solid image: nothing to cut
                    {"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 1}}}}}},
                   {{"alphaMode", "BLEND"}}});
  b.write_embedded(dir_ / "mask.gltf");
  GltfLoadReport report;
  const Scene scene = load_gltf(dir_ / "mask.gltf", &report);
  ASSERT_EQ(scene.materials.size(), 3u);
  EXPECT_EQ(scene.materials[0].alpha_mode, Material::AlphaMode::kMask);
  EXPECT_FLOAT_EQ(scene.materials[0].alpha_cutoff, 0.25f);
  EXPECT_EQ(scene.materials[1].alpha_mode, Material::AlphaMode::kMask);
  EXPECT_FLOAT_EQ(scene.materials[1].alpha_cutoff, 0.5f);  // glTF's default
  EXPECT_EQ(scene.materials[2].alpha_mode, Material::AlphaMode::kBlend);
  ASSERT_EQ(scene.textures.size(), 2u);
  EXPECT_TRUE(scene.textures[0].coded_alpha);
  EXPECT_EQ(scene.textures[0].texel_alpha(0), 0.0f);
  EXPECT_EQ(scene.textures[0].texel_alpha(1), 1.0f);
  EXPECT_FALSE(scene.textures[1].coded_alpha);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();

  // The same leaf on an opaque material: its alpha is not kept; on a blending one it is.
  b.doc()["materials"][0]["alphaMode"] = "OPAQUE";
  b.write_embedded(dir_ / "opaque.gltf");
  EXPECT_FALSE(load_gltf(dir_ / "opaque.gltf").textures[0].coded_alpha);
  b.doc()["materials"][0]["alphaMode"] = "BLEND";
  b.write_embedded(dir_ / "blend.gltf");
  const Texture blended = load_gltf(dir_ / "blend.gltf").textures[0];
  EXPECT_TRUE(blended.coded_alpha);
  EXPECT_EQ(blended.texel_alpha(0), 0.0f);

  b.doc()["materials"][0]["alphaMode"] = "MASK";
  b.doc()["materials"][0]["alphaCutoff"] = -1.0;
  b.write_embedded(dir_ / "cutoff.gltf");
  expect_error(dir_ / "cutoff.gltf", "material 0 has an invalid alphaCutoff");
}

TEST_F(GltfLoaderTest, UndecodableTextureFailsNamingTheImage) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["materials"] =
      json::array({{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}});
  b.doc()["textures"] = json::array({{{"source", 0}}});
  const std::vector<uint8_t> not_png = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A, 1, 2, 3};
  b.doc()["images"] = json::array({{{"uri", "data:image/png;base64," + testing::base64(not_png)}}});
  const fs::path path = dir_ / "bad_texture.gltf";
  b.write_embedded(path);
  expect_error(path, "image 0");
  // An image file the folder lacks is named with the path looked for.
  b.doc()["images"] = json::array({{{"uri", "textures/absent.png"}}});
  b.write_embedded(path);
  expect_error(path, "image 0 (textures/absent.png) of " + path.string() +
                         ": no such file: " + (dir_ / "textures" / "absent.png").string());
}

// An image of a format afr does not decode (KTX2, which files for KHR_texture_basisu viewers
// name without the extension) leaves its textures out with one warning, as a texture without
// a source does.
TEST_F(GltfLoaderTest, ATextureOfAnUndecodedFormatIsIgnoredWithAWarning) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["materials"] = json::array(
      {{{"pbrMetallicRoughness",
         {{"baseColorTexture", {{"index", 0}}}, {"metallicRoughnessTexture", {{"index", 0}}}}}}});
  b.doc()["textures"] = json::array({{{"source", 0}}});
  const std::vector<uint8_t> ktx2 = {0xAB, 'K',  'T', 'X', ' ', '2', '0', 0xBB, 0x0D, 0x0A,
                                     0x1A, 0x0A, 0,   0,   0,   0,   0,   0,    0,    0};
  b.doc()["images"] = json::array({{{"uri", "data:image/ktx2;base64," + testing::base64(ktx2)}}});
  const fs::path path = dir_ / "ktx2.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  ASSERT_EQ(scene.materials.size(), 1u);
  EXPECT_EQ(scene.materials[0].base_color_texture, -1);
  EXPECT_EQ(scene.materials[0].metallic_roughness_texture, -1);
  EXPECT_TRUE(scene.textures.empty());
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find(path.string() +
                                    ": image 0: KTX2 is not an image format afr decodes as a "
                                    "texture (PNG, JPEG or WebP): the textures of it are ignored"),
            std::string::npos)
      << report.warnings[0];
}

TEST_F(GltfLoaderTest, EmptyImageDataUriFails) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["images"] = json::array({{{"uri", "data:image/png;base64,"}}});
  const fs::path path = dir_ / "empty_image.gltf";
  b.write_embedded(path);
  EXPECT_THROW(load_gltf(path), Error);
}

// ---- Nodes, animations, cameras, lights ----

TEST_F(GltfLoaderTest, NodeHierarchyWorldTransformsMatchHandComputedMatrices) {
  GltfBuilder b;
  add_quad(&b);
  const double h = std::sqrt(0.5);
  b.doc()["nodes"] = json::array({// Translation (1, 2, 3), 90 degrees about +z, uniform scale 2.
                                  {{"name", "parent"},
                                   {"children", {1}},
                                   {"translation", {1, 2, 3}},
                                   {"rotation", {0, 0, h, h}},
                                   {"scale", {2, 2, 2}}},
                                  // A translation by (0, 1, 0) given as a column-major matrix.
                                  {{"name", "child"},
                                   {"children", {2}},
                                   {"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 1, 0, 1}}},
                                  {{"name", "grandchild"}, {"translation", {0, 0, 5}}, {"mesh", 0}},
                                  {{"name", "other root"}}});
  b.doc()["scenes"] = json::array({{{"nodes", {0, 3}}}});
  const fs::path path = dir_ / "hierarchy.gltf";
  b.write_embedded(path);

  const Scene scene = load_gltf(path);
  ASSERT_EQ(scene.nodes.size(), 4u);
  EXPECT_EQ(scene.roots, (std::vector<int>{0, 3}));
  EXPECT_EQ(scene.nodes[1].parent, 0);
  EXPECT_EQ(scene.nodes[2].parent, 1);
  EXPECT_EQ(scene.nodes[2].mesh, 0);
  EXPECT_TRUE(scene.nodes[1].matrix.has_value());
  EXPECT_FALSE(scene.is_animated());

  // By hand: R S maps x to (0, 2, 0), y to (-2, 0, 0), z to (0, 0, 2). The child's origin
  // (0, 1, 0) goes to (-2, 0, 0) + (1, 2, 3) = (-1, 2, 3); the grandchild's (0, 0, 5) on top of
  // that adds (0, 0, 10).
  const glm::dmat4 parent(0, 2, 0, 0, -2, 0, 0, 0, 0, 0, 2, 0, 1, 2, 3, 1);
  const glm::dmat4 child(0, 2, 0, 0, -2, 0, 0, 0, 0, 0, 2, 0, -1, 2, 3, 1);
  const glm::dmat4 grandchild(0, 2, 0, 0, -2, 0, 0, 0, 0, 0, 2, 0, -1, 2, 13, 1);
  const SceneState state = scene.evaluate(0.0);
  ASSERT_EQ(state.world.size(), 4u);
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      EXPECT_NEAR(state.world[0][c][r], parent[c][r], 1e-12) << c << "," << r;
      EXPECT_NEAR(state.world[1][c][r], child[c][r], 1e-12) << c << "," << r;
      EXPECT_NEAR(state.world[2][c][r], grandchild[c][r], 1e-12) << c << "," << r;
      EXPECT_EQ(state.world[3][c][r], c == r ? 1.0 : 0.0);
    }
  }
}

TEST_F(GltfLoaderTest, AnimationChannelsLoadWithTheirInterpolationAndValues) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["nodes"] =
      json::array({{{"mesh", 0}, {"children", {1, 2}}}, json::object(), json::object()});
  const int linear_times = b.add_floats({0.0f, 0.5f, 1.25f}, 1);
  const int translations = b.add_floats({0, 0, 0, 1, 2, 3, 4, 5, 6}, 3);
  const int step_times = b.add_floats({0.0f, 1.0f}, 1);
  // Rotations as normalized shorts: (0, 0, 0, 1) and (0, 0, 1, 0).
  const std::vector<int16_t> rotation_shorts = {0, 0, 0, 32767, 0, 0, 32767, 0};
  const int rotations =
      b.add_accessor(b.add_view(rotation_shorts), kShort, "VEC4", 2, 0, /*normalized=*/true);
  const int cubic_times = b.add_floats({0.0f, 2.0f}, 1);
  // In-tangent, value, out-tangent per key.
  const int cubic_scales = b.add_floats({0, 0, 0, 1, 1, 1, 1, 0, 0,  //
                                         0, 1, 0, 2, 3, 4, 0, 0, 0},
                                        3);
  b.doc()["animations"] = json::array(
      {{{"channels",
         {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}},
          {{"sampler", 1}, {"target", {{"node", 1}, {"path", "rotation"}}}}}},
        {"samplers",
         {{{"input", linear_times}, {"output", translations}},  // LINEAR is the default
          {{"input", step_times}, {"output", rotations}, {"interpolation", "STEP"}}}}},
       {{"channels", {{{"sampler", 0}, {"target", {{"node", 2}, {"path", "scale"}}}}}},
        {"samplers",
         {{{"input", cubic_times}, {"output", cubic_scales}, {"interpolation", "CUBICSPLINE"}}}}}});
  const fs::path path = dir_ / "animated.gltf";
  b.write_embedded(path);

  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty());
  EXPECT_TRUE(scene.is_animated());
  EXPECT_DOUBLE_EQ(scene.duration(), 2.0);
  ASSERT_EQ(scene.channels.size(), 3u);

  const AnimationChannel& t = scene.channels[0];
  EXPECT_EQ(t.node, 0);
  EXPECT_EQ(t.path, AnimatedPath::kTranslation);
  EXPECT_EQ(t.interpolation, Interpolation::kLinear);
  EXPECT_EQ(t.times, (std::vector<double>{0.0, 0.5, 1.25}));
  ASSERT_EQ(t.values.size(), 3u);
  EXPECT_EQ(glm::dvec3(t.values[1]), glm::dvec3(1, 2, 3));
  EXPECT_EQ(glm::dvec3(t.values[2]), glm::dvec3(4, 5, 6));

  const AnimationChannel& r = scene.channels[1];
  EXPECT_EQ(r.node, 1);
  EXPECT_EQ(r.path, AnimatedPath::kRotation);
  EXPECT_EQ(r.interpolation, Interpolation::kStep);
  EXPECT_EQ(r.times, (std::vector<double>{0.0, 1.0}));
  ASSERT_EQ(r.values.size(), 2u);
  EXPECT_EQ(r.values[0], glm::dvec4(0, 0, 0, 1));  // (x, y, z, w)
  EXPECT_EQ(r.values[1], glm::dvec4(0, 0, 1, 0));

  const AnimationChannel& s = scene.channels[2];
  EXPECT_EQ(s.node, 2);
  EXPECT_EQ(s.path, AnimatedPath::kScale);
  EXPECT_EQ(s.interpolation, Interpolation::kCubicSpline);
  EXPECT_EQ(s.times, (std::vector<double>{0.0, 2.0}));
  ASSERT_EQ(s.values.size(), 6u);
  EXPECT_EQ(glm::dvec3(s.values[1]), glm::dvec3(1, 1, 1));
  EXPECT_EQ(glm::dvec3(s.values[2]), glm::dvec3(1, 0, 0));
  EXPECT_EQ(glm::dvec3(s.values[3]), glm::dvec3(0, 1, 0));
  EXPECT_EQ(glm::dvec3(s.values[4]), glm::dvec3(2, 3, 4));
}

TEST_F(GltfLoaderTest, CameraAndAllThreeLightTypesLoadWithExtras) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["extensionsUsed"] = {"KHR_lights_punctual"};
  b.doc()["cameras"] = json::array(
      {{{"name", "eye"},
        {"type", "perspective"},
        {"perspective", {{"yfov", 0.6}, {"znear", 0.05}, {"zfar", 100}, {"aspectRatio", 1.5}}}}});
  b.doc()["extensions"]["KHR_lights_punctual"]["lights"] = json::array(
      {{{"name", "bulb"},
        {"type", "point"},
        {"color", {1.0, 0.5, 0.25}},
        {"intensity", 3.0},
        {"range", 10.0},
        {"extras", {{"afr_falloff", "none"}}}},
       {{"type", "directional"}, {"intensity", 2.0}},
       {{"type", "spot"}, {"spot", {{"innerConeAngle", 0.25}, {"outerConeAngle", 0.5}}}}});
  b.doc()["nodes"] = json::array({{{"mesh", 0}},
                                  {{"name", "camera"}, {"camera", 0}, {"translation", {0, 1, 5}}},
                                  {{"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}},
                                  {{"extensions", {{"KHR_lights_punctual", {{"light", 1}}}}}},
                                  {{"extensions", {{"KHR_lights_punctual", {{"light", 2}}}}}}});
  b.doc()["scenes"] = json::array(
      {{{"nodes", {0, 1, 2, 3, 4}},
        {"extras", {{"afr_background", {0.1, 0.2, 0.3}}, {"afr_ambient", {0.05, 0.04, 0.03}}}}}});
  const fs::path path = dir_ / "lit.gltf";
  b.write_embedded(path);

  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty());
  ASSERT_EQ(scene.cameras.size(), 1u);
  EXPECT_EQ(scene.cameras[0].name, "eye");
  EXPECT_DOUBLE_EQ(scene.cameras[0].yfov, 0.6);
  EXPECT_DOUBLE_EQ(scene.cameras[0].znear, 0.05);
  EXPECT_EQ(scene.nodes[1].camera, 0);
  EXPECT_EQ(scene.camera_node(), 1);
  const Camera camera = scene.camera_at(scene.evaluate(0.0));
  EXPECT_NEAR(glm::length(camera.eye - glm::dvec3(0, 1, 5)), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(camera.yfov, 0.6);

  ASSERT_EQ(scene.lights.size(), 3u);
  const Light& point = scene.lights[0];
  EXPECT_EQ(point.name, "bulb");
  EXPECT_EQ(point.type, Light::Type::kPoint);
  EXPECT_EQ(point.color, glm::vec3(1.0f, 0.5f, 0.25f));
  EXPECT_EQ(point.intensity, 3.0f);
  EXPECT_EQ(point.range, 10.0f);
  EXPECT_FALSE(point.inverse_square_falloff);
  const Light& directional = scene.lights[1];
  EXPECT_EQ(directional.type, Light::Type::kDirectional);
  EXPECT_EQ(directional.intensity, 2.0f);
  EXPECT_EQ(directional.color, glm::vec3(1.0f));
  EXPECT_EQ(directional.range, 0.0f);
  EXPECT_TRUE(directional.inverse_square_falloff);
  const Light& spot = scene.lights[2];
  EXPECT_EQ(spot.type, Light::Type::kSpot);
  EXPECT_EQ(spot.inner_cone_angle, 0.25f);
  EXPECT_EQ(spot.outer_cone_angle, 0.5f);
  EXPECT_TRUE(spot.inverse_square_falloff);
  EXPECT_EQ(scene.nodes[2].light, 0);
  EXPECT_EQ(scene.nodes[3].light, 1);
  EXPECT_EQ(scene.nodes[4].light, 2);
  EXPECT_EQ(scene.nodes[0].light, -1);

  EXPECT_EQ(scene.background, glm::vec3(0.1f, 0.2f, 0.3f));
  EXPECT_EQ(scene.ambient, glm::vec3(0.05f, 0.04f, 0.03f));
}

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

// ---- Unsupported features ----

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

// KHR_animation_pointer: channels whose pointer names a node's translation, rotation, scale or
// morph weights animate it as a channel of that node and path would; a pointer to another
// property (here a factor of KHR_materials_diffuse_transmission, which afr does not read) warns
// once per kind and is skipped; a pointer to a node the file lacks, or a channel without a pointer,
// fails naming the channel.
TEST_F(GltfLoaderTest, AnimationPointersToANodesTransformAreAnimated) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["materials"] = json::array({json::object(), json::object()});
  const int times = b.add_floats({0, 2}, 1);
  const int moves = b.add_floats({0, 0, 0, 4, 0, 0}, 3);
  const int colors = b.add_floats({1, 0, 0, 1, 0, 0, 1, 1}, 4);
  b.doc()["animations"] = {
      {{"channels",
        {pointer_channel(1,
                         "/materials/0/extensions/KHR_materials_diffuse_transmission/"
                         "diffuseTransmissionFactor"),
         pointer_channel(0, "/nodes/0/translation"),
         pointer_channel(1,
                         "/materials/1/extensions/KHR_materials_diffuse_transmission/"
                         "diffuseTransmissionFactor")}},
       {"samplers",
        {{{"input", times}, {"output", moves}}, {{"input", times}, {"output", colors}}}}}};
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer"};
  const fs::path path = dir_ / "pointer.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  ASSERT_EQ(scene.channels.size(), 1u);
  EXPECT_EQ(scene.channels[0].node, 0);
  EXPECT_EQ(scene.channels[0].path, AnimatedPath::kTranslation);
  EXPECT_NEAR(scene.evaluate(1.0).world[0][3].x, 2.0, 1e-9);  // halfway to x = 4
  ASSERT_EQ(report.warnings.size(), 1u) << report.warnings.back();
  EXPECT_NE(report.warnings[0].find("KHR_animation_pointer animations of "
                                    "/materials/#/extensions/KHR_materials_diffuse_transmission/"
                                    "diffuseTransmissionFactor are not supported"),
            std::string::npos)
      << report.warnings[0];
  EXPECT_TRUE(scene.property_channels.empty());

  b.doc()["animations"][0]["channels"][1] = pointer_channel(0, "/nodes/7/translation");
  b.write_embedded(path);
  expect_error(path,
               "animation 0 channel 1 KHR_animation_pointer \"/nodes/7/translation\" "
               "targets node 7, but there are 1");
  b.doc()["animations"][0]["channels"][1]["target"].erase("extensions");
  b.write_embedded(path);
  expect_error(path, "animation 0 channel 1 KHR_animation_pointer has no \"pointer\" string");
}

// A pointer to a mesh's weights animates the morph weights of every node that shows the mesh
// with the mesh's own weights (a node with weights of its own keeps them, as glTF has it).
TEST_F(GltfLoaderTest, AnimationPointersToAMeshsWeightsAnimateTheNodesShowingIt) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["targets"] = {
      {{"POSITION", b.add_floats({0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1}, 3)}}};
  b.doc()["meshes"][0]["weights"] = {0};
  b.doc()["nodes"].push_back({{"mesh", 0}, {"weights", {0.5}}});
  b.doc()["nodes"].push_back({{"mesh", 0}, {"translation", {3, 0, 0}}});
  b.doc()["scenes"][0]["nodes"] = {0, 1, 2};
  b.doc()["animations"] = {
      {{"channels", {pointer_channel(0, "/meshes/0/weights")}},
       {"samplers", {{{"input", b.add_floats({0, 1}, 1)}, {"output", b.add_floats({0, 1}, 1)}}}}}};
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer"};
  const fs::path path = dir_ / "mesh_weights.gltf";
  b.write_embedded(path);
  const Scene scene = load_gltf(path);
  ASSERT_EQ(scene.channels.size(), 2u);
  for (const AnimationChannel& c : scene.channels) {
    EXPECT_EQ(c.path, AnimatedPath::kWeights);
    EXPECT_NE(c.node, 1);  // its own weights
  }
  EXPECT_NE(scene.channels[0].node, scene.channels[1].node);

  b.doc()["animations"][0]["channels"][0] = pointer_channel(0, "/meshes/4/weights");
  b.write_embedded(path);
  expect_error(path, "\"/meshes/4/weights\" targets mesh 4, but there are 1");
}

// An orthographic camera's ymag and znear are animated through their own pointers; its near
// plane may reach 0 (glTF allows it there), its ymag may not.
TEST_F(GltfLoaderTest, AnimationPointersToAnOrthographicCameraAnimateItsView) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["cameras"] = {
      {{"type", "orthographic"},
       {"orthographic", {{"xmag", 1}, {"ymag", 2}, {"znear", 0.5}, {"zfar", 9}}}}};
  b.doc()["nodes"].push_back({{"camera", 0}, {"translation", {0, 0, 5}}});
  b.doc()["scenes"][0]["nodes"] = {0, 1};
  const int times = b.add_floats({0, 2}, 1);
  const int ymags = b.add_floats({2, 4}, 1);
  const int nears = b.add_floats({0.5, 0}, 1);
  b.doc()["animations"] = {
      {{"channels",
        {pointer_channel(0, "/cameras/0/orthographic/ymag"),
         pointer_channel(1, "/cameras/0/orthographic/znear")}},
       {"samplers",
        {{{"input", times}, {"output", ymags}}, {{"input", times}, {"output", nears}}}}}};
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer"};
  const fs::path path = dir_ / "ortho_zoom.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings[0];
  ASSERT_EQ(scene.property_channels.size(), 2u);
  const Camera half = scene.camera_at(scene.evaluate(1.0));
  EXPECT_TRUE(half.orthographic());
  EXPECT_NEAR(half.ymag, 3.0, 1e-6);
  EXPECT_NEAR(half.znear, 0.25, 1e-6);
  const Camera end = scene.camera_at(scene.evaluate(2.0));
  EXPECT_NEAR(end.ymag, 4.0, 1e-6);
  EXPECT_GT(end.znear, 0.0);  // kept just in front of the eye's plane

  GltfBuilder zero;
  add_quad(&zero);
  zero.doc()["cameras"] = b.doc()["cameras"];
  zero.doc()["nodes"].push_back({{"camera", 0}});
  zero.doc()["scenes"][0]["nodes"] = {0, 1};
  const int zero_times = zero.add_floats({0, 2}, 1);
  const int zero_ymags = zero.add_floats({2, 0}, 1);
  zero.doc()["animations"] = {{{"channels", {pointer_channel(0, "/cameras/0/orthographic/ymag")}},
                               {"samplers", {{{"input", zero_times}, {"output", zero_ymags}}}}}};
  zero.doc()["extensionsUsed"] = {"KHR_animation_pointer"};
  zero.write_embedded(path);
  expect_error(path,
               "animation 0 channel 0 (KHR_animation_pointer \"/cameras/0/orthographic/ymag\"): "
               "key 1 sets the camera ymag to 0 (glTF forbids a view of height 0)");
}

// KHR_animation_pointer's pointers to a light's, a camera's and a material's properties animate
// them (SceneState's lights, cameras and materials; Scene::camera_at takes the camera's yfov);
// a key outside the property's range, or a light, camera or material the file lacks, fails
// naming the channel.
TEST_F(GltfLoaderTest, AnimationPointersToLightsCamerasAndMaterialsAreAnimated) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 1;
  b.doc()["materials"] = json::array(
      {json::object(),
       {{"emissiveFactor", {1, 0.5, 0}},
        {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 2}}}}}}});
  b.doc()["cameras"] = {
      {{"type", "perspective"}, {"perspective", {{"yfov", 0.5}, {"znear", 0.1}}}}};
  b.doc()["extensions"]["KHR_lights_punctual"]["lights"] = {
      {{"type", "spot"}, {"intensity", 3}, {"spot", {{"outerConeAngle", 0.5}}}}};
  b.doc()["nodes"].push_back({{"camera", 0}, {"translation", {0, 0, 5}}});
  b.doc()["nodes"].push_back({{"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  b.doc()["scenes"][0]["nodes"] = {0, 1, 2};
  const int times = b.add_floats({0, 2}, 1);
  const int scalars = b.add_floats({0.5, 1.5}, 1);
  const int colors = b.add_floats({1, 1, 1, 0, 0, 1}, 3);
  const int factors = b.add_floats({1, 0, 0, 1, 0, 0, 1, 0.5}, 4);
  b.doc()["animations"] = {
      {{"channels",
        {pointer_channel(0, "/cameras/0/perspective/yfov"),
         pointer_channel(0, "/extensions/KHR_lights_punctual/lights/0/intensity"),
         pointer_channel(1, "/extensions/KHR_lights_punctual/lights/0/color"),
         pointer_channel(0, "/extensions/KHR_lights_punctual/lights/0/spot/innerConeAngle"),
         pointer_channel(2, "/materials/1/pbrMetallicRoughness/baseColorFactor"),
         pointer_channel(0, "/materials/1/pbrMetallicRoughness/roughnessFactor"),
         pointer_channel(0,
                         "/materials/1/extensions/KHR_materials_emissive_strength/"
                         "emissiveStrength"),
         pointer_channel(0, "/materials/1/alphaCutoff"),
         pointer_channel(0, "/materials/1/normalTexture/scale")}},
       {"samplers",
        {{{"input", times}, {"output", scalars}},
         {{"input", times}, {"output", colors}},
         {{"input", times}, {"output", factors}}}}}};
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer", "KHR_lights_punctual",
                               "KHR_materials_emissive_strength"};
  const fs::path path = dir_ / "properties.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  // Roughness 0.5 to 1.5 goes past 1: clamped, as a roughness factor without an animation is.
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find(
                "animation 0 channel 5 (KHR_animation_pointer "
                "\"/materials/1/pbrMetallicRoughness/roughnessFactor\"): key 1 sets the roughness "
                "factor to 1.5, outside [0, 1]: clamped where it is used"),
            std::string::npos)
      << report.warnings[0];
  ASSERT_EQ(scene.property_channels.size(), 9u);
  EXPECT_EQ(scene.channels.size(), 0u);
  EXPECT_TRUE(scene.is_animated());
  EXPECT_DOUBLE_EQ(scene.duration(), 2.0);
  EXPECT_EQ(scene.animated_materials(), std::vector<int>{1});

  const SceneState at1 = scene.evaluate(1.0);  // halfway
  EXPECT_NEAR(scene.camera_at(at1).yfov, 1.0, 1e-6);
  EXPECT_NEAR(scene.camera_at(scene.evaluate(0.0)).yfov, 0.5, 1e-6);
  const Light& light = scene.light_at(at1, 0);
  EXPECT_NEAR(light.intensity, 1.0f, 1e-6f);
  EXPECT_NEAR(light.inner_cone_angle, 1.0f, 1e-6f);
  EXPECT_NEAR(light.outer_cone_angle, 0.5f, 1e-6f);  // not animated
  EXPECT_NEAR(light.color.x, 0.5f, 1e-6f);
  EXPECT_NEAR(light.color.z, 1.0f, 1e-6f);
  const Material& m = scene.material_at(at1, 1);
  EXPECT_NEAR(m.base_color_factor.a, 0.75f, 1e-6f);
  EXPECT_NEAR(m.emissive.x, 1.0f, 1e-6f);  // factor 1 x strength 1
  EXPECT_NEAR(m.emissive.y, 0.5f, 1e-6f);
  EXPECT_NEAR(scene.material_at(scene.evaluate(2.0), 1).emissive.x, 1.5f, 1e-6f);
  EXPECT_NEAR(scene.materials[1].emissive.x, 2.0f, 1e-6f);  // the file's, unanimated
  EXPECT_NEAR(scene.material_at(scene.evaluate(2.0), 1).alpha_cutoff, 1.5f, 1e-6f);
  EXPECT_NEAR(scene.material_at(scene.evaluate(2.0), 1).normal_scale, 1.5f, 1e-6f);
  EXPECT_NEAR(scene.material_at(scene.evaluate(2.0), 1).roughness, 1.0f, 1e-6f);

  // What is an error without an animation is one with it.
  b.doc()["animations"][0]["channels"].push_back(
      pointer_channel(0, "/materials/0/occlusionTexture/strength"));
  b.write_embedded(path);
  expect_error(path,
               "animation 0 channel 9 (KHR_animation_pointer "
               "\"/materials/0/occlusionTexture/strength\"): key 1 sets the occlusion strength to "
               "1.5, outside [0, 1]");
  b.doc()["animations"][0]["channels"][9] = pointer_channel(0, "/materials/2/emissiveFactor");
  b.write_embedded(path);
  expect_error(path, "targets material 2, but there are 2");
  b.doc()["animations"][0]["channels"][9] =
      pointer_channel(1, "/extensions/KHR_lights_punctual/lights/3/color");
  b.write_embedded(path);
  expect_error(path, "targets light 3, but there are 1");
  b.doc()["animations"][0]["channels"][9] = pointer_channel(0, "/cameras/0/perspective/znear");
  b.doc()["animations"][0]["samplers"][0]["output"] = b.add_floats({0.5, 0}, 1);
  b.write_embedded(path);
  expect_error(path, "key 1 sets the camera yfov to 0, outside (0, 3.14159]");
}

// KHR_animation_pointer drives a texture slot's KHR_texture_transform: the slot reads a set of
// its own that holds TEXCOORD_0 untransformed (where the same transform unanimated would share
// the emissive slot's set, transformed at load), and the material's uv_transforms carry the
// file's transform, then the animated one at each time, in a core slot and an extension's.
TEST_F(GltfLoaderTest, AnimationPointersToTextureTransformsAnimateTheirSlotsSets) {
  const DecodedImage gray{1, 1, 3, {128, 128, 128}};
  write_image8(gray, dir_ / "gray.png");
  GltfBuilder b;
  add_quad(&b);
  json& primitive = b.doc()["meshes"][0]["primitives"][0];
  primitive["material"] = 0;
  primitive["attributes"]["TEXCOORD_0"] = b.add_floats({0, 0, 1, 0, 1, 1, 0, 1}, 2);
  b.doc()["images"] = json::array({{{"uri", "gray.png"}}});
  b.doc()["textures"] = json::array({{{"source", 0}}});
  const json turned = {
      {"KHR_texture_transform", {{"offset", {0.5, 0.0}}, {"rotation", 0.5}, {"scale", {2, 3}}}}};
  b.doc()["materials"] = json::array(
      {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}, {"extensions", turned}}}}},
        {"emissiveFactor", {1, 1, 1}},
        {"emissiveTexture", {{"index", 0}, {"extensions", turned}}},
        {"extensions",
         {{"KHR_materials_clearcoat",
           {{"clearcoatFactor", 1}, {"clearcoatTexture", {{"index", 0}}}}}}}}});
  const int times = b.add_floats({0, 2}, 1);
  const int offsets = b.add_floats({0, 0, 1, 0.5f}, 2);
  const int angles = b.add_floats({0, 1}, 1);
  const int scales = b.add_floats({1, 1, 3, 5}, 2);
  const std::string base = "/materials/0/pbrMetallicRoughness/baseColorTexture";
  const std::string coat = "/materials/0/extensions/KHR_materials_clearcoat/clearcoatTexture";
  const std::string transform = "/extensions/KHR_texture_transform/";
  b.doc()["animations"] = {{{"channels",
                             {pointer_channel(0, base + transform + "offset"),
                              pointer_channel(1, base + transform + "rotation"),
                              pointer_channel(2, coat + transform + "scale")}},
                            {"samplers",
                             {{{"input", times}, {"output", offsets}},
                              {{"input", times}, {"output", angles}},
                              {{"input", times}, {"output", scales}}}}}};
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer", "KHR_texture_transform",
                               "KHR_materials_clearcoat"};
  const fs::path path = dir_ / "uvs.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  ASSERT_EQ(scene.property_channels.size(), 3u);
  EXPECT_EQ(scene.animated_materials(), std::vector<int>{0});
  EXPECT_DOUBLE_EQ(scene.duration(), 2.0);

  const Material& m = scene.materials[0];
  EXPECT_EQ(m.uv_set.base_color, 0);  // its own set
  EXPECT_EQ(m.uv_set.emissive, 1);    // the same transform, baked
  EXPECT_EQ(m.uv_set.clearcoat, 2);   // animated: its own, though it reads TEXCOORD_0 as it is
  const Primitive& p = scene.meshes[0].primitives[0];
  const std::vector<glm::vec2> raw = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  EXPECT_EQ(p.uv_set(0), raw);
  EXPECT_EQ(p.uv_set(2), raw);
  // The emissive set: T(0.5, 0) R(0.5) S(2, 3) applied at load; (1, 0) goes to
  // (0.5 + 2 cos 0.5, -2 sin 0.5).
  EXPECT_NEAR(p.uv_set(1)[1].x, 0.5 + 2 * std::cos(0.5), 1e-6);
  EXPECT_NEAR(p.uv_set(1)[1].y, -2 * std::sin(0.5), 1e-6);
  ASSERT_EQ(m.uv_transforms.size(), 3u);
  EXPECT_EQ(m.uv_transforms[0], (Material::UvTransform{{0.5, 0.0}, 0.5, {2.0, 3.0}}));
  EXPECT_EQ(m.uv_transforms[1], Material::UvTransform{});  // baked
  EXPECT_EQ(m.uv_transforms[2], Material::UvTransform{});  // the file has none there
  // The matrix maps (1, 0) where the load maps it.
  const glm::dvec3 moved = m.uv_transforms[0].matrix() * glm::dvec3(1, 0, 1);
  EXPECT_NEAR(moved.x, p.uv_set(1)[1].x, 1e-6);
  EXPECT_NEAR(moved.y, p.uv_set(1)[1].y, 1e-6);

  const SceneState at1 = scene.evaluate(1.0);
  const Material& half = scene.material_at(at1, 0);
  EXPECT_EQ(half.uv_transforms[0].offset, glm::dvec2(0.5, 0.25));
  EXPECT_DOUBLE_EQ(half.uv_transforms[0].rotation, 0.5);
  EXPECT_EQ(half.uv_transforms[0].scale, glm::dvec2(2.0, 3.0));  // not animated: the file's
  EXPECT_EQ(half.uv_transforms[2].scale, glm::dvec2(2.0, 3.0));
  EXPECT_EQ(half.uv_transforms[1], Material::UvTransform{});

  // A pointer to an empty slot is skipped with a warning naming the channel; one to texCoord
  // is a kind afr does not animate; one to a slot afr does not know, likewise.
  b.doc()["animations"][0]["channels"] = {
      pointer_channel(0, "/materials/0/normalTexture/extensions/KHR_texture_transform/offset"),
      pointer_channel(1, base + transform + "texCoord"),
      pointer_channel(0, "/materials/0/nosuchTexture/extensions/KHR_texture_transform/offset")};
  b.write_embedded(path);
  GltfLoadReport skipped;
  const Scene without = load_gltf(path, &skipped);
  EXPECT_TRUE(without.property_channels.empty());
  EXPECT_TRUE(without.materials[0].uv_transforms.empty());
  EXPECT_EQ(without.materials[0].uv_set.base_color, without.materials[0].uv_set.emissive);
  ASSERT_EQ(skipped.warnings.size(), 2u);
  EXPECT_EQ(count_containing(skipped.warnings,
                             "animation 0 channel 0 (KHR_animation_pointer "
                             "\"/materials/0/normalTexture/extensions/KHR_texture_transform/"
                             "offset\") animates the transform of a texture slot without a "
                             "texture (skipped)"),
            1u);
  EXPECT_EQ(count_containing(skipped.warnings, "KHR_texture_transform/texCoord, "), 1u);
  EXPECT_EQ(count_containing(skipped.warnings, "nosuchTexture"), 1u);

  // An offset of the wrong width or not finite, and a material the file lacks, are errors.
  // (json::array: a braced list of one json is that json itself under clang.)
  b.doc()["animations"][0]["channels"] =
      json::array({pointer_channel(1, base + transform + "offset")});
  b.write_embedded(path);
  expect_error(path, "animation 0 channel 0");
  b.doc()["animations"][0]["channels"] = json::array(
      {pointer_channel(0, "/materials/4/emissiveTexture/extensions/KHR_texture_transform/offset")});
  b.write_embedded(path);
  expect_error(path, "targets material 4, but there are 1");
}

// KHR_animation_pointer drives a node's KHR_node_visibility: the node keeps its mesh though the
// file hides it at rest (Node::visible false), its visibility and its child's vary, and each key
// holds until the next (a visibility does not blend, whatever the interpolation). A node hidden
// with no animation still loses its mesh.
TEST_F(GltfLoaderTest, AnimationPointersToANodesVisibilityShowAndHideItAndItsChildren) {
  GltfBuilder b;
  add_quad(&b);
  const json hidden = {{"KHR_node_visibility", {{"visible", false}}}};
  b.doc()["nodes"][0]["extensions"] = hidden;
  b.doc()["nodes"][0]["children"] = {1};
  b.doc()["nodes"].push_back({{"mesh", 0}, {"translation", {0, 2, 0}}});  // node 1: its child
  b.doc()["nodes"].push_back({{"mesh", 0}, {"extensions", hidden}});      // node 2: for good
  b.doc()["scenes"][0]["nodes"] = {0, 2};
  const int times = b.add_floats({0, 1, 2}, 1);
  const int keys = b.add_floats({0, 1, 0}, 1);
  b.doc()["animations"] = {
      {{"channels",
        json::array({pointer_channel(0, "/nodes/0/extensions/KHR_node_visibility/visible")})},
       {"samplers", {{{"input", times}, {"output", keys}}}}}};  // LINEAR, the default
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer", "KHR_node_visibility"};
  const fs::path path = dir_ / "blink.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  ASSERT_EQ(scene.property_channels.size(), 1u);
  EXPECT_TRUE(scene.animated_materials().empty());
  EXPECT_EQ(scene.nodes[0].mesh, 0);
  EXPECT_FALSE(scene.nodes[0].visible);
  EXPECT_TRUE(scene.nodes[1].visible);
  EXPECT_EQ(scene.nodes[2].mesh, -1);  // hidden for good: dropped
  EXPECT_TRUE(scene.node_visibility_varies(0));
  EXPECT_TRUE(scene.node_visibility_varies(1));
  EXPECT_FALSE(scene.node_visibility_varies(2));
  for (const auto& [t, shown] : std::vector<std::pair<double, bool>>{
           {0.0, false}, {0.9, false}, {1.0, true}, {1.5, true}, {2.0, false}, {5.0, false}}) {
    const SceneState state = scene.evaluate(t);
    EXPECT_EQ(scene.node_hidden(state, 0), !shown) << "t = " << t;
    EXPECT_EQ(scene.node_hidden(state, 1), !shown) << "t = " << t;  // with its parent
  }

  // A pointer to a node the file lacks is an error naming it; a negative key, one naming it.
  b.doc()["animations"][0]["channels"][0] =
      pointer_channel(0, "/nodes/7/extensions/KHR_node_visibility/visible");
  b.write_embedded(path);
  expect_error(path, "targets node 7, but there are 3");
  b.doc()["animations"][0]["channels"][0] =
      pointer_channel(0, "/nodes/1/extensions/KHR_node_visibility/visible");
  b.doc()["animations"][0]["samplers"][0]["output"] = b.add_floats({1, -1, 1}, 1);
  b.write_embedded(path);
  expect_error(path, "key 1 sets the node visibility to -1");
}

// The material extensions' factors are animated within the ranges the loader reads them in:
// a color's three components and a factor's one reach the material, a key outside the range is
// an error naming the channel and the key.
TEST_F(GltfLoaderTest, AnimationPointersToMaterialExtensionFactorsKeepTheirRanges) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["materials"] =
      json::array({{{"extensions",
                     {{"KHR_materials_sheen", {{"sheenColorFactor", {0, 0, 0}}}},
                      {"KHR_materials_iridescence", {{"iridescenceFactor", 1}}}}}}});
  const int times = b.add_floats({0, 2}, 1);
  b.doc()["animations"] = {
      {{"channels",
        {pointer_channel(0, "/materials/0/extensions/KHR_materials_sheen/sheenColorFactor"),
         pointer_channel(1, "/materials/0/extensions/KHR_materials_iridescence/iridescenceIor")}},
       {"samplers",
        {{{"input", times}, {"output", b.add_floats({0, 0, 0, 1, 0.5f, 0.25f}, 3)}},
         {{"input", times}, {"output", b.add_floats({1.2f, 2.0f}, 1)}}}}}};
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer", "KHR_materials_sheen",
                               "KHR_materials_iridescence"};
  const fs::path path = dir_ / "factors.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  const SceneState at1 = scene.evaluate(1.0);
  const Material& m = scene.material_at(at1, 0);
  EXPECT_NEAR(m.sheen_color.x, 0.5f, 1e-6f);
  EXPECT_NEAR(m.sheen_color.y, 0.25f, 1e-6f);
  EXPECT_NEAR(m.sheen_color.z, 0.125f, 1e-6f);
  EXPECT_NEAR(m.iridescence_ior, 1.6f, 1e-6f);

  b.doc()["animations"][0]["samplers"][1]["output"] = b.add_floats({1.2f, 0.9f}, 1);
  b.write_embedded(path);
  expect_error(path, "key 1 sets the iridescence ior to 0.9");
  b.doc()["animations"][0]["channels"][1] =
      pointer_channel(1, "/materials/0/extensions/KHR_materials_clearcoat/clearcoatFactor");
  b.doc()["animations"][0]["samplers"][1]["output"] = b.add_floats({0.5f, 1.5f}, 1);
  b.write_embedded(path);
  expect_error(path, "key 1 sets the clearcoat factor to 1.5, outside [0, 1]");
}

// Transmission, ior, volume and dispersion animate too (the tracer gives a material whose
// transmission is animated the glass filter whatever it is at the start), each within its
// range: an animated ior stays at or above 1 (KHR_materials_ior's 0 would pass through (0, 1)
// between keys) and an attenuation distance above 0.
TEST_F(GltfLoaderTest, AnimationPointersToTransmissionAndVolumeKeepTheirRanges) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["materials"] = json::array({json::object()});
  const int times = b.add_floats({0, 2}, 1);
  const std::string m = "/materials/0/extensions/";
  b.doc()["animations"] = {
      {{"channels",
        {pointer_channel(0, m + "KHR_materials_transmission/transmissionFactor"),
         pointer_channel(1, m + "KHR_materials_ior/ior"),
         pointer_channel(2, m + "KHR_materials_volume/thicknessFactor"),
         pointer_channel(3, m + "KHR_materials_volume/attenuationDistance"),
         pointer_channel(4, m + "KHR_materials_volume/attenuationColor"),
         pointer_channel(5, m + "KHR_materials_dispersion/dispersion")}},
       {"samplers",
        {{{"input", times}, {"output", b.add_floats({0, 1}, 1)}},
         {{"input", times}, {"output", b.add_floats({1.5f, 1.1f}, 1)}},
         {{"input", times}, {"output", b.add_floats({0, 2}, 1)}},
         {{"input", times}, {"output", b.add_floats({4, 2}, 1)}},
         {{"input", times}, {"output", b.add_floats({1, 1, 1, 0.5f, 0.25f, 0}, 3)}},
         {{"input", times}, {"output", b.add_floats({0, 3}, 1)}}}}}};
  b.doc()["extensionsUsed"] = {"KHR_animation_pointer"};
  const fs::path path = dir_ / "volume.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  EXPECT_EQ(scene.materials[0].transmission, 0.0f);  // the file's, where the animation starts
  const SceneState state = scene.evaluate(1.0);
  const Material& at1 = scene.material_at(state, 0);
  EXPECT_NEAR(at1.transmission, 0.5f, 1e-6f);
  EXPECT_NEAR(at1.ior, 1.3f, 1e-6f);
  EXPECT_NEAR(at1.thickness, 1.0f, 1e-6f);
  EXPECT_NEAR(at1.attenuation_distance, 3.0f, 1e-6f);
  EXPECT_NEAR(at1.attenuation_color.y, 0.625f, 1e-6f);
  EXPECT_NEAR(at1.dispersion, 1.5f, 1e-6f);

  const auto refused = [&](int sampler, const std::vector<float>& keys, int width,
                           const std::string& problem) {
    json doc = b.doc();
    b.doc()["animations"][0]["samplers"][sampler]["output"] = b.add_floats(keys, width);
    b.write_embedded(path);
    expect_error(path, problem);
    b.doc() = doc;
  };
  refused(0, {0, 1.2f}, 1, "key 1 sets the transmission factor to 1.2, outside [0, 1]");
  refused(1, {1.5f, 0}, 1, "key 1 sets the ior to 0, outside [1, inf]");
  refused(2, {-1, 0}, 1, "key 0 sets the thickness factor to -1, outside [0, inf]");
  refused(3, {4, 0}, 1, "key 1 sets the attenuation distance to 0, outside (0, inf]");
  refused(4, {1, 1, 1, 0.5f, 1.5f, 0}, 3,
          "key 1 sets the attenuation color to 1.5, outside [0, 1]");
  refused(5, {0, -2}, 1, "key 1 sets the dispersion to -2, outside [0, inf]");
}

// glTF requires strictly increasing keyframe times, but exporters write repeated and unordered
// ones: the channel is repaired with a warning naming it, not the whole scene refused.
TEST_F(GltfLoaderTest, KeyframeTimesOutOfOrderAreSortedWithAWarning) {
  GltfBuilder b;
  add_quad(&b);
  const int times = b.add_floats({0, 2, 1, 1}, 1);
  const int values = b.add_floats({0, 0, 0, 2, 0, 0, 5, 0, 0, 1, 0, 0}, 3);
  b.doc()["animations"] = json::array(
      {{{"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}}}},
        {"samplers", {{{"input", times}, {"output", values}}}}}});
  const fs::path path = dir_ / "unordered.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  const Scene scene = load_gltf(path, &report);
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("animation 0 channel 0"), std::string::npos)
      << report.warnings[0];
  EXPECT_NE(report.warnings[0].find("1 of 4 dropped"), std::string::npos) << report.warnings[0];
  ASSERT_EQ(scene.channels.size(), 1u);
  EXPECT_EQ(scene.channels[0].times, (std::vector<double>{0.0, 1.0, 2.0}));
  EXPECT_DOUBLE_EQ(scene.channels[0].evaluate(1.5).x, 1.5);  // keys (1, 1) and (2, 2)
}

// ---- Broken files ----

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

TEST_F(GltfLoaderTest, AccessorOutOfBoundsOfItsBufferViewFails) {
  GltfBuilder b;
  const int positions = add_quad(&b);
  b.doc()["accessors"][positions]["count"] = 5;
  const fs::path path = dir_ / "overrun.gltf";
  b.write_embedded(path);
  expect_error(path, "out of bounds");
}

TEST_F(GltfLoaderTest, BufferViewOutOfBoundsOfItsBufferFails) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["bufferViews"][1]["byteLength"] = 400;
  const fs::path path = dir_ / "long_view.gltf";
  b.write_embedded(path);
  expect_error(path, "out of bounds");
}

TEST_F(GltfLoaderTest, IndexOutOfRangeOfTheVerticesFails) {
  GltfBuilder b;
  add_quad(&b);
  b.bin()[48 + 2] = 9;  // the second index (u16 after 48 bytes of positions) becomes 9
  const fs::path path = dir_ / "bad_index.gltf";
  b.write_embedded(path);
  expect_error(path, "out of range");
}

// glTF requires a scene's nodes to be distinct roots; UniGLTF lists a child whose parent is
// outside the scene, which is drawn as a root with its own transform, as viewers draw it. A
// node listed with its ancestor, or twice, is drawn once.
TEST_F(GltfLoaderTest, SceneNodesThatAreNotRootsAreDrawnOnceWithAWarning) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["nodes"] =
      json::array({{{"name", "tmpParent"}, {"children", {1}}, {"translation", {5, 0, 0}}},
                   {{"mesh", 0}, {"translation", {0, 2, 0}}, {"children", {2}}},
                   {{"mesh", 0}, {"translation", {0, 0, 3}}}});
  b.doc()["scenes"] = json::array({{{"nodes", {1}}}});
  const fs::path path = dir_ / "unigltf.gltf";
  b.write_embedded(path);
  GltfLoadReport report;
  Scene scene = load_gltf(path, &report);
  EXPECT_EQ(scene.roots, (std::vector<int>{1}));
  SceneState state = scene.evaluate(0.0);
  EXPECT_EQ(glm::dvec3(state.world[1][3]), glm::dvec3(0, 2, 0));
  EXPECT_EQ(glm::dvec3(state.world[2][3]), glm::dvec3(0, 2, 3));
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("scene 0 lists node 1, a child of node 0, which is not in the "
                                    "scene; glTF requires a scene's nodes to be roots: it is drawn "
                                    "as one, without its parents' transforms"),
            std::string::npos)
      << report.warnings[0];

  b.doc()["scenes"] = json::array({{{"nodes", {2, 0, 0}}}});
  b.write_embedded(path);
  report = {};
  scene = load_gltf(path, &report);
  EXPECT_EQ(scene.roots, (std::vector<int>{0}));
  state = scene.evaluate(0.0);
  EXPECT_EQ(glm::dvec3(state.world[2][3]), glm::dvec3(5, 2, 3));
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("scene 0 lists node 2 and its ancestor node 0, which glTF "
                                    "forbids: it is drawn once"),
            std::string::npos)
      << report.warnings[0];
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

TEST_F(GltfLoaderTest, CycleInTheNodeGraphFails) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["nodes"] = json::array({{{"mesh", 0}}, {{"children", {2}}}, {{"children", {1}}}});
  const fs::path path = dir_ / "cycle.gltf";
  b.write_embedded(path);
  expect_error(path, "cycle");
}

TEST_F(GltfLoaderTest, NanPositionFails) {
  GltfBuilder b;
  add_quad(&b);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(&b.bin()[16], &nan, 4);  // y of vertex 1
  const fs::path path = dir_ / "nan.gltf";
  b.write_embedded(path);
  expect_error(path, "NaN");
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
