// The glTF loader's tests of materials, their extensions and their textures.
#include "gltf_loader_test.h"
#include "support/png.h"

namespace afr {
namespace {

using namespace gltf_test;

TEST_F(GltfLoaderTest, MaterialsAndEmbeddedPngTexturesDecodeToLinearTexels) {
  // A 2 x 2 texture, row 0 at the top.
  const DecodedImage png{2, 2, 3, {255, 0, 0, 0, 128, 255, 10, 20, 30, 255, 255, 255}};
  const fs::path png_path = dir_ / "texture.png";
  testing::write_png(png, png_path);
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

// The metallic-roughness, emissive, occlusion and normal slots are read: data textures
// (metallic-roughness, occlusion, normal) decoded as they are, color ones (base color, emissive)
// from sRGB; one image decoded once per way it is read; a slot whose transform differs from the
// material's first slot's reads a set of coordinates of its own; an occlusion strength outside
// [0, 1] fails naming the material.
TEST_F(GltfLoaderTest, MaterialTextureSlotsDecodeColorFromSrgbAndDataAsItIs) {
  const DecodedImage color{1, 1, 3, {128, 64, 255}}, orm{1, 1, 3, {200, 128, 51}};
  const fs::path color_path = dir_ / "color.png", orm_path = dir_ / "orm.png";
  testing::write_png(color, color_path);
  testing::write_png(orm, orm_path);
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
  testing::write_png(gray, dir_ / "gray.png");
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
  testing::write_png(DecodedImage{2, 1, 3, {0, 0, 0, 255, 255, 255}}, dir_ / "bw.png");
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
  testing::write_png(DecodedImage{1, 1, 3, {128, 128, 128}}, dir_ / "gray.png");
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

// The unit quad (add_quad) with material 0, TEXCOORD_0 running 0 to 1 and TEXCOORD_1 0 to 2
// across it, and texture 0: one RGBA texel (color 128, 64, 32, alpha 51) in `dir`/rgba.png.
void add_rgba_textured_quad(GltfBuilder* b, const fs::path& dir) {
  testing::write_png(DecodedImage{1, 1, 4, {128, 64, 32, 51}}, dir / "rgba.png");
  add_quad(b);
  json& primitive = b->doc()["meshes"][0]["primitives"][0];
  primitive["material"] = 0;
  primitive["attributes"]["TEXCOORD_0"] = b->add_floats({0, 0, 1, 0, 1, 1, 0, 1}, 2);
  primitive["attributes"]["TEXCOORD_1"] = b->add_floats({0, 0, 2, 0, 2, 2, 0, 2}, 2);
  b->doc()["images"] = json::array({{{"uri", "rgba.png"}}});
  b->doc()["textures"] = json::array({{{"source", 0}}});
}

// KHR_materials_diffuse_transmission: its factors (defaults 0 and white) and textures are read,
// also where a file requires it: the factor's texture from the image's alpha, the color's as
// sRGB, each through its own texture coordinate set; a factor out of range fails naming the
// material and the factor.
TEST_F(GltfLoaderTest, DiffuseTransmissionIsRead) {
  GltfBuilder b;
  add_rgba_textured_quad(&b, dir_);
  b.doc()["extensionsUsed"] = {"KHR_materials_diffuse_transmission"};
  b.doc()["extensionsRequired"] = {"KHR_materials_diffuse_transmission"};
  const json leaf = {{"KHR_materials_diffuse_transmission",
                      {{"diffuseTransmissionFactor", 0.25},
                       {"diffuseTransmissionColorFactor", {1.0, 0.9, 0.85}},
                       {"diffuseTransmissionTexture", {{"index", 0}}},
                       {"diffuseTransmissionColorTexture", {{"index", 0}, {"texCoord", 1}}}}}};
  b.doc()["materials"] =
      json::array({{{"extensions", leaf}},
                   {{"extensions", {{"KHR_materials_diffuse_transmission", json::object()}}}}});
  b.write_embedded(dir_ / "leaf.gltf");
  GltfLoadReport report;
  Scene scene = load_gltf(dir_ / "leaf.gltf", &report);
  ASSERT_EQ(scene.materials.size(), 2u);
  const Material& m = scene.materials[0];
  EXPECT_EQ(m.diffuse_transmission, 0.25f);
  EXPECT_EQ(m.diffuse_transmission_color, glm::vec3(1.0f, 0.9f, 0.85f));
  ASSERT_EQ(scene.textures.size(), 2u);
  ASSERT_GE(m.diffuse_transmission_texture, 0);
  ASSERT_GE(m.diffuse_transmission_color_texture, 0);
  const Texture& strength = scene.textures[size_t(m.diffuse_transmission_texture)];
  const Texture& color = scene.textures[size_t(m.diffuse_transmission_color_texture)];
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(strength.texel(0)[c], 51 / 255.0, 1e-6);
  EXPECT_NEAR(color.texel(0).r, reference_srgb_to_linear(128 / 255.0), 1e-6);
  EXPECT_EQ(m.uv_set, (Material::TextureSets{.diffuse_transmission_color = 1}));
  EXPECT_EQ(scene.materials[1].diffuse_transmission, 0.0f);
  EXPECT_EQ(scene.materials[1].diffuse_transmission_color, glm::vec3(1.0f));
  EXPECT_EQ(scene.materials[1].diffuse_transmission_texture, -1);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();

  b.doc()["materials"][0]["extensions"]["KHR_materials_diffuse_transmission"]
         ["diffuseTransmissionFactor"] = 1.5;
  b.write_embedded(dir_ / "above_one.gltf");
  expect_error(dir_ / "above_one.gltf",
               "material 0 KHR_materials_diffuse_transmission has an "
               "invalid diffuseTransmissionFactor");
  b.doc()["materials"][0] = {{"extensions", leaf}};
  b.doc()["materials"][0]["extensions"]["KHR_materials_diffuse_transmission"]
         ["diffuseTransmissionColorFactor"] = {1.0, -0.5, 1.0};
  b.write_embedded(dir_ / "negative_color.gltf");
  expect_error(dir_ / "negative_color.gltf",
               "material 0 KHR_materials_diffuse_transmission has "
               "an invalid diffuseTransmissionColorFactor");
  b.doc()["materials"][0] = {{"extensions", leaf}};
  b.doc()["materials"][0]["extensions"]["KHR_materials_diffuse_transmission"]
         ["diffuseTransmissionTexture"] = {{"index", 4}};
  b.write_embedded(dir_ / "bad_texture.gltf");
  expect_error(dir_ / "bad_texture.gltf",
               "material 0 diffuseTransmissionTexture refers to texture 4, but there are 1");
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
  GltfBuilder b;
  add_rgba_textured_quad(&b, dir_);
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
  GltfBuilder b;
  add_rgba_textured_quad(&b, dir_);
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
  testing::write_png(DecodedImage{1, 1, 3, {255, 128, 64}}, dir_ / "direction.png");
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
  testing::write_png(DecodedImage{1, 1, 4, {128, 64, 32, 51}}, dir_ / "specgloss.png");
  testing::write_png(DecodedImage{1, 1, 3, {10, 20, 30}}, dir_ / "fallback.png");
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
  testing::write_png(DecodedImage{1, 1, 3, {255, 128, 64}}, dir_ / "film.png");
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
  testing::write_png(leaf, dir_ / "leaf.png");
  testing::write_png(solid, dir_ / "solid.png");
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

// Loaded without textures (GltfLoadOptions::textures, a display node's scene), a material's
// texture is one white texel in place of the 64 x 32 image, every other part of the scene as
// with textures; broken image data is still the same error.
TEST_F(GltfLoaderTest, WithoutTexturesEachImageIsCheckedAndKeptAsOneTexel) {
  DecodedImage image{64, 32, 3, std::vector<uint8_t>(64 * 32 * 3, 77)};
  testing::write_png(image, dir_ / "big.png");
  GltfBuilder b;
  add_quad(&b);
  b.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc()["materials"] =
      json::array({{{"pbrMetallicRoughness",
                     {{"baseColorTexture", {{"index", 0}}}, {"metallicFactor", 0.5}}}}});
  b.doc()["textures"] = json::array({{{"source", 0}}});
  b.doc()["images"] = json::array({{{"uri", "big.png"}}});
  const fs::path path = dir_ / "textured.gltf";
  b.write_embedded(path);
  GltfLoadOptions no_textures;
  no_textures.textures = false;
  const Scene with = load_gltf(path), without = load_gltf(path, nullptr, no_textures);
  ASSERT_EQ(with.textures.size(), 1u);
  ASSERT_EQ(without.textures.size(), 1u);
  EXPECT_EQ(with.textures[0].width, 64);
  EXPECT_EQ(without.textures[0].width, 1);
  EXPECT_EQ(without.textures[0].height, 1);
  EXPECT_EQ(without.textures[0].texel_count(), 1u);
  ASSERT_EQ(without.materials.size(), 1u);
  EXPECT_EQ(without.materials[0].base_color_texture, with.materials[0].base_color_texture);
  EXPECT_EQ(without.materials[0].metallic, with.materials[0].metallic);
  EXPECT_EQ(without.triangle_count(), with.triangle_count());
  EXPECT_EQ(without.nodes.size(), with.nodes.size());

  const std::vector<uint8_t> not_png = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A, 1, 2, 3};
  b.doc()["images"] = json::array({{{"uri", "data:image/png;base64," + testing::base64(not_png)}}});
  b.write_embedded(path);
  try {
    load_gltf(path, nullptr, no_textures);
    ADD_FAILURE() << "broken image data loaded";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("image 0"), std::string::npos) << e.what();
  }
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

}  // namespace
}  // namespace afr
