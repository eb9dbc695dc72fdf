// The glTF loader's tests of meshes: primitives, vertex colors, tangents, indices.
#include "gltf_loader_test.h"
#include "support/png.h"

namespace afr {
namespace {

using namespace gltf_test;

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

// TANGENT is read where the material has a normal texture (w taken by its sign) and not
// otherwise (nor generated); a count other than the positions' fails naming the primitive.
TEST_F(GltfLoaderTest, TangentsAreReadForNormalMappedMaterialsOnly) {
  testing::write_png(DecodedImage{1, 1, 3, {128, 128, 255}}, dir_ / "normal.png");
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
  testing::write_png(DecodedImage{1, 1, 3, {128, 128, 255}}, dir_ / "normal.png");
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

TEST_F(GltfLoaderTest, IndexOutOfRangeOfTheVerticesFails) {
  GltfBuilder b;
  add_quad(&b);
  b.bin()[48 + 2] = 9;  // the second index (u16 after 48 bytes of positions) becomes 9
  const fs::path path = dir_ / "bad_index.gltf";
  b.write_embedded(path);
  expect_error(path, "out of range");
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

}  // namespace
}  // namespace afr
