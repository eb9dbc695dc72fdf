#include "aff_to_gltf.h"

#include "gltf_eval.h"
#include "hand_scene.h"
#include "test_paths.h"

#include "support/numbers.h"

#include <afr/common/gltf_loader.h>
#include <afr/common/image.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <numbers>

namespace afr::aff {
namespace {

using test::evaluate_sampler;
using test::find_node;
using test::find_sampler;
using test::node_property;

using afr::testing::kDeg;

nlohmann::json read_json(const std::filesystem::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// Rotates v by the glTF quaternion q = (x, y, z, w).
glm::dvec3 rotate(const std::vector<double>& q, const glm::dvec3& v) {
  return glm::dquat(q[3], q[0], q[1], q[2]) * v;
}

// |dot| of a glTF quaternion with angle/axis: 1 when they are the same rotation.
double same_rotation(const std::vector<double>& q, double degrees, glm::dvec3 axis) {
  const glm::dquat r = glm::angleAxis(degrees * kDeg, glm::normalize(axis));
  return std::abs(q[0] * r.x + q[1] * r.y + q[2] * r.z + q[3] * r.w);
}

void expect_near(const std::vector<double>& a, const glm::dvec3& b, double tolerance) {
  ASSERT_GE(a.size(), 3u);
  EXPECT_NEAR(a[0], b.x, tolerance);
  EXPECT_NEAR(a[1], b.y, tolerance);
  EXPECT_NEAR(a[2], b.z, tolerance);
}

// A binary P6 file as RGB bytes, read independently of OpenImageIO.
std::vector<uint8_t> read_p6(const std::filesystem::path& path, int* w, int* h) {
  std::ifstream in(path, std::ios::binary);
  std::string magic;
  int maxval = 0;
  in >> magic >> *w >> *h >> maxval;
  in.get();  // the one whitespace byte after maxval
  std::vector<uint8_t> rgb(size_t(*w) * size_t(*h) * 3);
  in.read(reinterpret_cast<char*>(rgb.data()), std::streamsize(rgb.size()));
  return magic == "P6" && maxval == 255 && in ? rgb : std::vector<uint8_t>();
}

// ---- The hand-written scene with every directive --------------------------------------------

class HandSceneGltfTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::filesystem::path(test::fresh_temp_dir("aff-gltf"));
    const auto aff = test::write_hand_scene(*dir_);
    report_ = new ConvertReport(convert_aff_to_gltf(aff, *dir_ / "out" / "scene.gltf"));
    model_ = new tinygltf::Model(test::load_gltf((*dir_ / "out" / "scene.gltf").string()));
  }
  static void TearDownTestSuite() {
    std::filesystem::remove_all(*dir_);
    delete model_;
    delete report_;
    delete dir_;
  }
  const tinygltf::Model& m() const { return *model_; }
  int node(const std::string& name) const {
    const int n = find_node(*model_, name);
    EXPECT_GE(n, 0) << name;
    return n;
  }
  static std::filesystem::path* dir_;
  static ConvertReport* report_;
  static tinygltf::Model* model_;
};
std::filesystem::path* HandSceneGltfTest::dir_ = nullptr;
ConvertReport* HandSceneGltfTest::report_ = nullptr;
tinygltf::Model* HandSceneGltfTest::model_ = nullptr;

TEST_F(HandSceneGltfTest, KeepsEveryTriangle) {
  EXPECT_TRUE(report_->warnings.empty()) << report_->warnings.front();
  EXPECT_EQ(test::scene_triangles(m()), test::kHandSceneTriangles);
  EXPECT_EQ(report_->triangles, test::kHandSceneTriangles);
  for (const auto& a : m().accessors) {
    if (a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT) {
      EXPECT_EQ(a.componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);  // 32-bit indices
    }
  }
}

TEST_F(HandSceneGltfTest, MapsMaterialsToMetallicRoughness) {
  const tinygltf::Material* f = nullptr;
  const tinygltf::Material* textured = nullptr;
  for (const auto& mat : m().materials) {
    EXPECT_TRUE(mat.doubleSided);
    const double shine = mat.extras.Get("afr_shine").GetNumberAsDouble();
    if (shine == 20.0) f = &mat;
    if (shine == 8.0 && mat.pbrMetallicRoughness.baseColorTexture.index >= 0) {
      const auto& tex = m().textures[size_t(mat.pbrMetallicRoughness.baseColorTexture.index)];
      if (m().images[size_t(tex.source)].uri == "checker.png") textured = &mat;
    }
  }
  // Diffuse D and mean specular s: metallic s / (d + s), base D / (1 - metallic), scaled to a
  // largest channel of 1 where it exceeds 1 (docs/aff2gltf.md).
  ASSERT_NE(f, nullptr);  // f 1 0.5 0.25 0.8 0.3 20: D = (0.8, 0.4, 0.2), d = 1.4 / 3, s = 0.3
  const double f_metallic = 0.3 / (1.4 / 3.0 + 0.3);
  EXPECT_NEAR(f->pbrMetallicRoughness.metallicFactor, f_metallic, 1e-12);
  expect_near(f->pbrMetallicRoughness.baseColorFactor, {1.0, 0.5, 0.25}, 1e-12);  // 0.8 / 0.61 > 1
  EXPECT_DOUBLE_EQ(f->pbrMetallicRoughness.roughnessFactor, std::sqrt(2.0 / 22.0));  // shine 20
  EXPECT_EQ(f->extras.Get("afr_ambient").Get(0).GetNumberAsDouble(), 0.0);
  EXPECT_TRUE(f->extensions.empty());  // T = 0: opaque, no transmission or ior
  ASSERT_NE(textured, nullptr);        // D = (0.6, 0.5, 0.4), s = 0.2: metallic 2 / 7, base 1.4 D
  EXPECT_NEAR(textured->pbrMetallicRoughness.metallicFactor, 0.2 / 0.7, 1e-12);
  expect_near(textured->pbrMetallicRoughness.baseColorFactor, {0.84, 0.7, 0.56}, 1e-12);
  EXPECT_DOUBLE_EQ(textured->pbrMetallicRoughness.roughnessFactor, std::sqrt(2.0 / 10.0));
  EXPECT_EQ(textured->extras.Get("afr_ambient").Get(1).GetNumberAsDouble(), 0.1);
  EXPECT_EQ(textured->emissiveFactor, (std::vector<double>{0, 0, 0}));
  EXPECT_EQ(m().samplers.at(0).wrapS, TINYGLTF_TEXTURE_WRAP_REPEAT);
  EXPECT_EQ(m().samplers.at(0).wrapT, TINYGLTF_TEXTURE_WRAP_REPEAT);
}

TEST_F(HandSceneGltfTest, WritesPpmTexturesAsPngReferencedByUriOnly) {
  const auto out = *dir_ / "out";
  const DecodedImage checker = decode_image_file(out / "checker.png");
  ASSERT_EQ(checker.width, 2);
  ASSERT_EQ(checker.height, 2);
  ASSERT_EQ(checker.channels, 3);
  // P3, maxval 15: scaled by 255 / 15; rows top to bottom as in the file.
  EXPECT_EQ(checker.data, (std::vector<uint8_t>{255, 0, 0, 0, 255, 0, 0, 0, 255, 119, 119, 119}));
  const DecodedImage gray = decode_image_file(out / "gray.png");
  EXPECT_EQ(gray.data, (std::vector<uint8_t>{10, 20, 30, 40, 50, 60}));
  const nlohmann::json json = read_json(out / "scene.gltf");
  ASSERT_EQ(json["images"].size(), 2u);
  for (const auto& image : json["images"]) {
    EXPECT_FALSE(image.contains("bufferView"));
    EXPECT_EQ(image["uri"].get<std::string>().find("data:"), std::string::npos);
  }
  EXPECT_EQ(json["buffers"][0]["uri"], "scene.bin");
}

TEST_F(HandSceneGltfTest, WritesTheStaticTransformAsNodeTrs) {
  // The root node (named after the file) has the xs, spinner and blinker as children.
  const tinygltf::Node& root = m().nodes[size_t(node("scene.aff"))];
  ASSERT_EQ(root.children.size(), 3u + 1u);  // and the node of the tpa triangle
  const tinygltf::Node& xs = m().nodes[size_t(root.children[0])];
  EXPECT_EQ(xs.name.rfind("xs ", 0), 0u);
  EXPECT_EQ(xs.translation, (std::vector<double>{1, 0, 0}));
  EXPECT_EQ(xs.scale, (std::vector<double>{2, 2, 2}));
  ASSERT_EQ(xs.rotation.size(), 4u);
  EXPECT_NEAR(same_rotation(xs.rotation, 90.0, {0, 1, 0}), 1.0, 1e-12);
}

TEST_F(HandSceneGltfTest, AnimatesTheAnimatedTransform) {
  const int spinner = node("spinner");
  // transl keys x = 0, 1, 2, 3 at t = 0, 0.5, 1.5, 2 (TCB 0): by hand from section 4.1,
  // segment 1 has h = 1, D_o = D_i = 4/3, so x(u) = 1 + 4/3 u - u^2 + 2/3 u^3.
  EXPECT_EQ(find_sampler(m(), spinner, "translation")->interpolation, "CUBICSPLINE");
  expect_near(node_property(m(), spinner, "translation", 0.5), {1, 0, 0}, 1e-6);
  expect_near(node_property(m(), spinner, "translation", 1.0), {1.5, 0, 0}, 1e-6);
  expect_near(node_property(m(), spinner, "translation", 0.75),
              {1 + 4.0 / 12 - 1.0 / 16 + 2.0 / 3 / 64, 0, 0}, 1e-6);
  expect_near(node_property(m(), spinner, "translation", 5.0), {2, 0, 0}, 1e-6);
  EXPECT_NEAR(same_rotation(node_property(m(), spinner, "rotation", 0.5), 90, {0, 1, 0}), 1.0,
              1e-7);
  EXPECT_NEAR(same_rotation(node_property(m(), spinner, "rotation", 1.5), 180, {0, 1, 0}), 1.0,
              1e-7);
  expect_near(node_property(m(), spinner, "scale", 1.5), {2, 2, 2}, 1e-6);
}

// Section 4.3: hidden is scale 0 with STEP, visible before the first key. The spinner's `k`
// also animates scale, so its visibility sits on a child node; the blinker's on itself.
TEST_F(HandSceneGltfTest, WritesVisibilityAsStepScale) {
  const int holder = node("spinner.visibility");
  const auto* s = find_sampler(m(), holder, "scale");
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->interpolation, "STEP");
  expect_near(node_property(m(), holder, "scale", 0.25), {1, 1, 1}, 0);
  expect_near(node_property(m(), holder, "scale", 0.75), {0, 0, 0}, 0);
  expect_near(node_property(m(), holder, "scale", 1.6), {1, 1, 1}, 0);
  const auto& children = m().nodes[size_t(node("spinner"))].children;
  EXPECT_EQ(children, std::vector<int>{holder});
  EXPECT_GE(m().nodes[size_t(holder)].mesh, 0);
  const int blinker = node("blinker");
  expect_near(node_property(m(), blinker, "scale", 0.5), {1, 1, 1}, 0);
  expect_near(node_property(m(), blinker, "scale", 1.2), {0, 0, 0}, 0);
}

TEST_F(HandSceneGltfTest, AnimatedTriangleMorphsLinearly) {
  int tpa = -1;
  for (size_t i = 0; i < m().nodes.size(); ++i) {
    if (m().nodes[i].name.rfind("tpa ", 0) == 0) tpa = int(i);
  }
  ASSERT_GE(tpa, 0);
  const auto& prim = m().meshes[size_t(m().nodes[size_t(tpa)].mesh)].primitives.at(0);
  ASSERT_EQ(prim.targets.size(), 1u);
  const auto base = test::read_accessor(m(), prim.attributes.at("POSITION"));
  const auto delta = test::read_accessor(m(), prim.targets[0].at("POSITION"));
  const auto w = evaluate_sampler(m(), *find_sampler(m(), tpa, "weights"), 1.0, false);
  ASSERT_EQ(w.size(), 1u);
  for (size_t i = 2; i < base.size(); i += 3) EXPECT_NEAR(base[i] + w[0] * delta[i], 0.5, 1e-6);
}

// The same triangle through afr's own loader: its morph target animates (section 5: z goes
// from 0 at time 0 to 1 at time 2, linearly, clamped outside), as the sampler traces it.
TEST_F(HandSceneGltfTest, AnimatedTriangleMovesInAfrsLoader) {
  const afr::Scene scene = afr::load_gltf(*dir_ / "out" / "scene.gltf");
  int tpa = -1;
  for (size_t i = 0; i < scene.nodes.size(); ++i) {
    if (scene.nodes[i].name.rfind("tpa ", 0) == 0) tpa = int(i);
  }
  ASSERT_GE(tpa, 0);
  ASSERT_TRUE(scene.node_deforms(tpa));
  const afr::Mesh& mesh = scene.meshes[size_t(scene.nodes[size_t(tpa)].mesh)];
  ASSERT_EQ(mesh.primitives.size(), 1u);
  std::vector<glm::vec3> positions(mesh.primitives[0].positions.size());
  for (const double t : {-1.0, 0.0, 0.5, 1.0, 2.0, 3.0}) {
    scene.deform(tpa, 0, scene.evaluate(t), positions.data(), nullptr);
    const float z = float(std::clamp(t / 2.0, 0.0, 1.0));
    for (const glm::vec3& p : positions) EXPECT_NEAR(p.z, z, 1e-5) << "t = " << t;
  }
}

TEST_F(HandSceneGltfTest, WritesCameraLightsAndSceneExtras) {
  ASSERT_EQ(m().cameras.size(), 1u);
  const auto& p = m().cameras[0].perspective;
  EXPECT_DOUBLE_EQ(p.yfov, 45 * kDeg);
  EXPECT_DOUBLE_EQ(p.aspectRatio, 320.0 / 240.0);
  EXPECT_EQ(p.znear, 1.0);
  const nlohmann::json json = read_json(*dir_ / "out" / "scene.gltf");
  EXPECT_FALSE(json["cameras"][0]["perspective"].contains("zfar"));  // infinite

  const int camera = node("camera");
  EXPECT_EQ(m().nodes[size_t(camera)].camera, 0);
  expect_near(node_property(m(), camera, "translation", 0.0), {0, 1, 5}, 1e-6);
  expect_near(node_property(m(), camera, "translation", 2.0), {0, 1, 3}, 1e-6);
  EXPECT_NEAR(same_rotation(node_property(m(), camera, "rotation", 2.0), 30, {0, 1, 0}), 1.0, 1e-7);

  ASSERT_EQ(m().lights.size(), 3u);
  for (const auto& light : m().lights) {
    EXPECT_EQ(light.type, "point");
    EXPECT_DOUBLE_EQ(light.intensity, M_PI);  // glTF's BRDF divides by pi; NFF does not
    EXPECT_EQ(light.extras.Get("afr_falloff").Get<std::string>(), "none");
  }
  EXPECT_EQ(m().lights[1].color, (std::vector<double>{0.5, 0.25, 1}));
  const int lamp = node("lamp");
  EXPECT_EQ(m().nodes[size_t(lamp)].extensions.at("KHR_lights_punctual").Get("light").Get<int>(),
            2);
  expect_near(node_property(m(), lamp, "translation", 2.0), {2, 3, 0}, 1e-6);
  expect_near(node_property(m(), node("light1"), "translation", 0.0), {4, 5, 6}, 0);

  const auto& extras = m().scenes[0].extras;
  EXPECT_EQ(extras.Get("afr_background").Get(2).GetNumberAsDouble(), 0.3);
  EXPECT_EQ(extras.Get("afr_ambient").Get(0).GetNumberAsDouble(), 0.5);
}

// ---- Timelines glTF cannot hold as they are ------------------------------------------------

GltfScene build_from_text(const std::string& text) {
  const auto dir = test::fresh_temp_dir("aff-text");
  const Scene scene = parse_aff_text(text, "t.aff", dir);
  std::filesystem::remove_all(dir);
  return build_gltf(scene);
}

// glTF times start at 0; a scene whose `a` starts at -1 (BART's museum) is shifted by +1 s.
TEST(GltfTimelineTest, NegativeAnimationStartShiftsTheTimeline) {
  const GltfScene g = build_from_text(
      "a -1 5 7\nx obj { p 3 0 0 0 1 0 0 0 1 0 }\n"
      "k obj { transl 4\n -2 0 0 0 0 0 0\n -1 1 0 0 0 0 0\n 3 5 0 0 0 0 0\n"
      " 4 6 0 0 0 0 0 }\n");
  EXPECT_EQ(g.time_offset, 1.0);
  EXPECT_EQ(g.model.scenes[0].extras.Get("afr_time_offset").GetNumberAsDouble(), 1.0);
  const int obj = find_node(g.model, "obj");
  const auto* sampler = find_sampler(g.model, obj, "translation");
  ASSERT_NE(sampler, nullptr);
  EXPECT_GE(test::read_accessor(g.model, sampler->input).front(), 0.0);
  // By hand (section 4.1): D_o = D_i = 4 on the segment from t = -1 to 3, so x = 1 + 4 u.
  expect_near(node_property(g.model, obj, "translation", 0.0), {1, 0, 0}, 1e-6);
  expect_near(node_property(g.model, obj, "translation", 2.0), {3, 0, 0}, 1e-6);
  expect_near(node_property(g.model, obj, "translation", 4.0), {5, 0, 0}, 1e-6);
}

// Two keys at one time make the spline jump; glTF forbids equal times, so such a channel is
// baked to LINEAR samples with the jump between two samples a fraction of a millisecond apart.
TEST(GltfTimelineTest, RepeatedKeyTimesAreBakedWithTheJump) {
  const GltfScene g = build_from_text(
      "x obj { p 3 0 0 0 1 0 0 0 1 0 }\n"
      "k obj { transl 6\n 0 0 0 0 0 0 0\n 1 1 0 0 0 0 0\n 2 2 0 0 0 0 0\n"
      " 2 5 0 0 0 0 0\n 3 6 0 0 0 0 0\n 4 7 0 0 0 0 0 }\n");
  const int obj = find_node(g.model, "obj");
  const auto* sampler = find_sampler(g.model, obj, "translation");
  ASSERT_NE(sampler, nullptr);
  EXPECT_EQ(sampler->interpolation, "LINEAR");
  const auto times = test::read_accessor(g.model, sampler->input);
  for (size_t i = 1; i < times.size(); ++i) EXPECT_GT(times[i], times[i - 1]);
  expect_near(node_property(g.model, obj, "translation", 1.0), {1, 0, 0}, 1e-6);
  expect_near(node_property(g.model, obj, "translation", 2.0), {5, 0, 0}, 1e-6);
  EXPECT_NEAR(node_property(g.model, obj, "translation", 2.0 - 1e-3)[0], 2.0, 0.01);
  expect_near(node_property(g.model, obj, "translation", 3.0), {6, 0, 0}, 1e-6);
}

// ---- Materials as BART means them ----------------------------------------------------------

// The diffuse part that afr's BRDF takes from a glTF material: base (1 - metallic).
glm::dvec3 gltf_diffuse(const tinygltf::Material& mat) {
  const auto& c = mat.pbrMetallicRoughness.baseColorFactor;
  return glm::dvec3(c[0], c[1], c[2]) * (1.0 - mat.pbrMetallicRoughness.metallicFactor);
}

// BART's glass (kitchen: T 0.85, ior 1.55) becomes KHR_materials_transmission and
// KHR_materials_ior, listed as used but not required; an opaque scene lists neither.
TEST(AffMaterialsGltfTest, TransparentMaterialsWriteTransmissionAndIor) {
  const GltfScene g = build_from_text(
      "fm 0.065 0.065 0.065  0.065 0.065 0.065  0.05 0.05 0.05  20 0.85 1.55\n"
      "p 3 0 0 0 1 0 0 0 1 0\n"
      "fm 0 0 0  0.2 0.4 0.8  0 0 0  0 0.5 0\n"  // transmissive, index 0: no KHR_materials_ior
      "p 3 0 0 1 1 0 1 0 1 1\n"
      "fm 0.3 0.3 0.3  0.2 0.2 0.2  0 0 0  0 0 0\n"
      "p 3 0 0 2 1 0 2 0 1 2\n");
  ASSERT_EQ(g.model.materials.size(), 3u);
  const tinygltf::Material& glass = g.model.materials[0];
  ASSERT_TRUE(glass.extensions.count("KHR_materials_transmission"));
  EXPECT_DOUBLE_EQ(glass.extensions.at("KHR_materials_transmission")
                       .Get("transmissionFactor")
                       .GetNumberAsDouble(),
                   0.85);
  ASSERT_TRUE(glass.extensions.count("KHR_materials_ior"));
  EXPECT_DOUBLE_EQ(glass.extensions.at("KHR_materials_ior").Get("ior").GetNumberAsDouble(), 1.55);
  // glTF tints transmitted light by the base color: grey glass gets white, not 0.065.
  expect_near(glass.pbrMetallicRoughness.baseColorFactor, {1, 1, 1}, 1e-12);
  EXPECT_EQ(glass.pbrMetallicRoughness.metallicFactor, 0.0);

  const tinygltf::Material& tinted = g.model.materials[1];
  ASSERT_TRUE(tinted.extensions.count("KHR_materials_transmission"));
  EXPECT_FALSE(tinted.extensions.count("KHR_materials_ior"));
  expect_near(tinted.pbrMetallicRoughness.baseColorFactor, {0.25, 0.5, 1.0}, 1e-12);  // hue
  EXPECT_TRUE(g.model.materials[2].extensions.empty());

  const auto& used = g.model.extensionsUsed;
  EXPECT_NE(std::find(used.begin(), used.end(), "KHR_materials_transmission"), used.end());
  EXPECT_NE(std::find(used.begin(), used.end(), "KHR_materials_ior"), used.end());
  EXPECT_TRUE(g.model.extensionsRequired.empty());

  const GltfScene opaque =
      build_from_text("fm 0 0 0  0.5 0.5 0.5  0 0 0  0 0 0\np 3 0 0 0 1 0 0 0 1 0\n");
  EXPECT_TRUE(opaque.model.extensionsUsed.empty());

  // The afr loader reads both back.
  const auto dir = test::fresh_temp_dir("aff-glass");
  GltfScene written = g;
  write_gltf(&written, dir / "glass.gltf");
  const afr::Scene loaded = afr::load_gltf(dir / "glass.gltf");
  std::filesystem::remove_all(dir);
  ASSERT_EQ(loaded.materials.size(), 3u);
  EXPECT_FLOAT_EQ(loaded.materials[0].transmission, 0.85f);
  EXPECT_FLOAT_EQ(loaded.materials[0].ior, 1.55f);
  EXPECT_FLOAT_EQ(loaded.materials[1].ior, 1.5f);
  EXPECT_EQ(loaded.materials[2].transmission, 0.0f);
}

// A material with high specular and a real diffuse part keeps its diffuse (it rendered black
// when the mean specular became metallicFactor); one without diffuse is a metal whose color is
// its specular; one without specular is plain diffuse.
TEST(AffMaterialsGltfTest, SpecularMaterialsKeepTheirDiffusePart) {
  const GltfScene g = build_from_text(
      "fm 0.2 0.1 0.1  0.5 0.2 0.2  0.9 0.9 0.9  100 0 0\n"
      "p 3 0 0 0 1 0 0 0 1 0\n"
      "fm 0 0 0  0 0 0  0.8 0.7 0.6  200 0 0\n"
      "p 3 0 0 1 1 0 1 0 1 1\n"
      "fm 0.1 0.1 0.1  0.3 0.6 0.9  0 0 0  5 0 0\n"
      "p 3 0 0 2 1 0 2 0 1 2\n");
  ASSERT_EQ(g.model.materials.size(), 3u);
  // D = (0.5, 0.2, 0.2), d = 0.3, s = 0.9: metallic 0.75, base = 4 D = (2, 0.8, 0.8) scaled to
  // (1, 0.4, 0.4); the diffuse part base (1 - metallic) = (0.25, 0.1, 0.1): half of D, not 0.
  const tinygltf::Material& shiny = g.model.materials[0];
  EXPECT_NEAR(shiny.pbrMetallicRoughness.metallicFactor, 0.75, 1e-12);
  expect_near(shiny.pbrMetallicRoughness.baseColorFactor, {1.0, 0.4, 0.4}, 1e-12);
  const glm::dvec3 diffuse = gltf_diffuse(shiny);
  EXPECT_NEAR(diffuse.r, 0.25, 1e-12);
  EXPECT_GT(std::min(diffuse.r, std::min(diffuse.g, diffuse.b)), 0.05);
  // Specular RGB, metallic 1: a tinted mirror (shine 200: roughness 0.1, afr's mirror limit).
  const tinygltf::Material& metal = g.model.materials[1];
  EXPECT_EQ(metal.pbrMetallicRoughness.metallicFactor, 1.0);
  expect_near(metal.pbrMetallicRoughness.baseColorFactor, {0.8, 0.7, 0.6}, 1e-12);
  const tinygltf::Material& matte = g.model.materials[2];
  EXPECT_EQ(matte.pbrMetallicRoughness.metallicFactor, 0.0);
  expect_near(matte.pbrMetallicRoughness.baseColorFactor, {0.3, 0.6, 0.9}, 1e-12);
}

// Section 4.4: with only `transl`, the camera moves and keeps looking at v's `at`.
TEST(GltfTimelineTest, CameraWithOnlyTranslationKeepsLookingAtTheTarget) {
  const GltfScene g = build_from_text(
      "v from 0 0 5 at 0 0 0 up 0 1 0 angle 40 hither 0.1 resolution 4 3\n"
      "k camera { transl 4\n -1 5 0 0 0 0 0\n 0 5 0 0 0 0 0\n 1 0 0 5 0 0 0\n"
      " 2 0 0 5 0 0 0 }\n");
  const int camera = find_node(g.model, "camera");
  // Within the baking's angular tolerance (0.01 degrees by default), wherever between samples.
  const double tolerance = GltfOptions{}.rotation_tolerance_deg * std::numbers::pi / 180.0;
  for (double t = 0.0; t <= 1.0; t += 0.05) {
    const auto eye = node_property(g.model, camera, "translation", t);
    const glm::dvec3 expected = -glm::normalize(glm::dvec3(eye[0], eye[1], eye[2]));
    const glm::dvec3 dir = rotate(node_property(g.model, camera, "rotation", t), {0, 0, -1});
    EXPECT_LE(glm::length(dir - expected), tolerance) << "t " << t;
    EXPECT_NEAR(rotate(node_property(g.model, camera, "rotation", t), {0, 1, 0}).y, 1.0, 1e-6);
  }
}

// ---- The BART kitchen -----------------------------------------------------------------------

class KitchenGltfTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const auto aff = test::kitchen_aff();
    if (aff.empty()) return;
    dir_ = new std::filesystem::path(test::fresh_temp_dir("aff-kitchen"));
    report_ = new ConvertReport(convert_aff_to_gltf(aff, *dir_ / "kitchen.gltf"));
    model_ = new tinygltf::Model(test::load_gltf((*dir_ / "kitchen.gltf").string()));
  }
  static void TearDownTestSuite() {
    if (dir_) std::filesystem::remove_all(*dir_);
    delete model_;
    delete report_;
    delete dir_;
  }
  void SetUp() override {
    if (!model_) GTEST_SKIP() << "BART kitchen not found (AFR_SHARED_DIR)";
  }
  const tinygltf::Model& m() const { return *model_; }
  static std::filesystem::path* dir_;
  static ConvertReport* report_;
  static tinygltf::Model* model_;
};
std::filesystem::path* KitchenGltfTest::dir_ = nullptr;
ConvertReport* KitchenGltfTest::report_ = nullptr;
tinygltf::Model* KitchenGltfTest::model_ = nullptr;

TEST_F(KitchenGltfTest, HasTheTrianglesOfTheExpandedScene) {
  EXPECT_TRUE(report_->warnings.empty()) << report_->warnings.front();
  EXPECT_EQ(test::scene_triangles(m()), 110561u);  // aff-format.md section 2
}

// The reference values of aff-format.md section 7, read back from the glTF samplers.
TEST_F(KitchenGltfTest, ToyCarMatchesTheReferenceValues) {
  const int car = find_node(m(), "toycar");
  ASSERT_GE(car, 0);
  EXPECT_EQ(find_sampler(m(), car, "translation")->interpolation, "CUBICSPLINE");
  expect_near(node_property(m(), car, "translation", 6.0), {3.511199, 0, 2.638651}, 1e-5);
  expect_near(node_property(m(), car, "translation", 4.0), {4.152388, 0, 2.761433}, 1e-5);
  expect_near(node_property(m(), car, "translation", 10.0), {2.678804, 0, 0.603692}, 1e-5);
  expect_near(node_property(m(), car, "translation", 20.0), {2.75, 0, 3.40}, 1e-6);
  // Rotations are baked within 0.01 degrees (GltfOptions::rotation_tolerance_deg): a
  // quaternion's components within half that angle in radians, 8.7e-5.
  const double half_tolerance = 0.5 * GltfOptions{}.rotation_tolerance_deg * kDeg;
  EXPECT_NEAR(same_rotation(node_property(m(), car, "rotation", 6.0), 125.883545, {0, 1, 0}), 1.0,
              half_tolerance * half_tolerance);
  auto q = node_property(m(), car, "rotation", 6.1);
  if (q[3] < 0) {
    for (double& x : q) x = -x;
  }
  EXPECT_NEAR(q[3], 0.492486, half_tolerance + 1e-6);
  EXPECT_NEAR(q[1], 0.870320, half_tolerance + 1e-6);
  EXPECT_NEAR(q[0], 0.0, 1e-6);
  EXPECT_NEAR(q[2], 0.0, 1e-6);
  expect_near(node_property(m(), car, "scale", 19.78), {0.755220, 1, 1}, 1e-5);
  expect_near(node_property(m(), car, "scale", 20.0), {0.5, 1, 1}, 1e-6);
}

TEST_F(KitchenGltfTest, CameraMatchesTheReferenceAtSixSeconds) {
  const int camera = find_node(m(), "camera");
  ASSERT_GE(camera, 0);
  EXPECT_EQ(m().nodes[size_t(camera)].camera, 0);
  EXPECT_NE(std::find(m().scenes[0].nodes.begin(), m().scenes[0].nodes.end(), camera),
            m().scenes[0].nodes.end());
  const auto q = node_property(m(), camera, "rotation", 6.0);
  expect_near(node_property(m(), camera, "translation", 6.0), {3.45734, 0.14686, 0.30611}, 2e-5);
  const glm::dvec3 dir = rotate(q, {0, 0, -1}), up = rotate(q, {0, 1, 0});
  // The reference's 5 decimals, and the baking's 0.01 degrees (1.75e-4 rad).
  const double tolerance = 1e-5 + GltfOptions{}.rotation_tolerance_deg * kDeg;
  EXPECT_NEAR(dir.x, 0.11773, tolerance);
  EXPECT_NEAR(dir.y, 0.00114, tolerance);
  EXPECT_NEAR(dir.z, 0.99305, tolerance);
  EXPECT_NEAR(up.x, 0.01519, tolerance);
  EXPECT_NEAR(up.y, 0.99988, tolerance);
  EXPECT_NEAR(up.z, -0.00295, tolerance);
}

// Rotations are baked as densely as the angular tolerance needs, not at every frame of `a`, and
// densely where they turn fast: the rear wheels make up to 165 degrees per frame around
// 7.16 s. Where two wheel keys share a time (7.16, 7.19, 7.21, 7.24 s) the spline jumps by 90
// degrees; the bake puts that jump between two samples a fraction of a millisecond apart.
TEST_F(KitchenGltfTest, BakedRotationsTurnLittleBetweenSamples) {
  size_t wheels = 0;
  for (const auto& anim : m().animations) {
    for (const auto& c : anim.channels) {
      if (c.target_path != "rotation") continue;
      const std::string& name = m().nodes[size_t(c.target_node)].name;
      const auto& s = anim.samplers[size_t(c.sampler)];
      EXPECT_EQ(s.interpolation, "LINEAR");
      const auto times = test::read_accessor(m(), s.input);
      const auto q = test::read_accessor(m(), s.output);
      double largest = 0.0;
      std::vector<double> jumps;
      for (size_t i = 1; i < times.size(); ++i) {
        double d = 0.0;
        for (size_t j = 0; j < 4; ++j) d += q[4 * (i - 1) + j] * q[4 * i + j];
        EXPECT_GE(d, 0.0);  // one hemisphere: LINEAR takes the short way
        const double turn = 2.0 * std::acos(std::min(1.0, d));
        if (times[i] - times[i - 1] < 1e-3 && turn > 10.01 * kDeg) {
          jumps.push_back(times[i]);
        } else {
          largest = std::max(largest, turn);
        }
      }
      EXPECT_LT(largest, 10.01 * kDeg) << name;
      if (name.rfind("rotating_wheel", 0) == 0) {
        ++wheels;
        ASSERT_EQ(jumps.size(), 4u) << name;
        const double expected[] = {7.16, 7.19, 7.21, 7.24};
        for (size_t j = 0; j < 4; ++j) EXPECT_NEAR(jumps[j], expected[j], 1e-6);
      } else {
        EXPECT_TRUE(jumps.empty()) << name;
      }
    }
  }
  EXPECT_EQ(wheels, 4u);  // two wheels, each `x` included twice
}

TEST_F(KitchenGltfTest, TexturesArePngsWithThePpmPixels) {
  const nlohmann::json json = read_json(*dir_ / "kitchen.gltf");
  ASSERT_EQ(json["images"].size(), 8u);
  const auto textures = test::kitchen_aff().parent_path().parent_path() / "TextureFiles";
  for (const auto& image : json["images"]) {
    ASSERT_FALSE(image.contains("bufferView"));
    const std::string uri = image["uri"];
    const DecodedImage png = decode_image_file(*dir_ / uri);
    int w = 0, h = 0;
    const auto ppm = read_p6(textures / (uri.substr(0, uri.size() - 4) + ".ppm"), &w, &h);
    ASSERT_FALSE(ppm.empty()) << uri;
    EXPECT_EQ(png.width, w);
    EXPECT_EQ(png.height, h);
    EXPECT_EQ(png.channels, 3);
    EXPECT_TRUE(png.data == ppm) << uri;
  }
}

// ---- BART's robots ------------------------------------------------------------------------

// The robots convert: one key block of Robot1.aff (k gun_rot1, rot) goes backwards in time and
// is repaired with a warning; nothing else is.
TEST(RobotsGltfTest, ConvertsWithTheOneBackwardsKeyBlockRepaired) {
  const auto aff = test::robots_aff();
  if (aff.empty()) GTEST_SKIP() << "BART robots not found (AFR_SHARED_DIR)";
  const auto dir = test::fresh_temp_dir("aff-robots");
  const ConvertReport report = convert_aff_to_gltf(aff, dir / "robots.gltf");
  std::vector<std::string> repaired;
  for (const std::string& w : report.warnings) {
    if (w.find("go backwards") != std::string::npos) repaired.push_back(w);
  }
  ASSERT_EQ(repaired.size(), 1u);
  EXPECT_NE(repaired[0].find("Robot1.aff:265: k gun_rot1: rot key times go backwards (48 then 42"),
            std::string::npos)
      << repaired[0];
  EXPECT_GT(report.triangles, 50000u);
  EXPECT_GT(report.animation_channels, 100u);
  const tinygltf::Model model = test::load_gltf((dir / "robots.gltf").string());
  EXPECT_EQ(model.cameras.size(), 1u);
  std::filesystem::remove_all(dir);
}

// A file that draws nothing (only a view, or emptied) converts, with a warning saying so.
TEST(AffToGltfTest, AFileWithoutGeometryConvertsWithAWarning) {
  const auto dir = test::fresh_temp_dir("aff-no-geometry");
  test::write_file(dir / "view.aff",
                   "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 0.1\n"
                   "resolution 64 64\n");
  const ConvertReport report = convert_aff_to_gltf(dir / "view.aff", dir / "view.gltf");
  EXPECT_EQ(report.triangles, 0u);
  EXPECT_EQ(report.warnings,
            std::vector<std::string>{"view.aff: no geometry: the glTF has no triangles to draw"});
  EXPECT_EQ(test::load_gltf((dir / "view.gltf").string()).cameras.size(), 1u);
  EXPECT_FALSE(std::filesystem::exists(dir / "view.bin"));  // glTF has no empty buffers
  convert_aff_to_gltf(dir / "view.aff", dir / "view.glb");
  EXPECT_EQ(test::load_gltf((dir / "view.glb").string()).cameras.size(), 1u);
  std::filesystem::remove_all(dir);
}

// ---- The program --------------------------------------------------------------------------

TEST(Aff2GltfProgramTest, PrintsFileAndLineAndExitsOneOnMalformedInput) {
  const auto dir = test::fresh_temp_dir("aff-program");
  test::write_file(dir / "bad.aff", "b 0 0 0\n\nxs 1 1 1 0 1 0 0 0 0 0\n");
  const std::string command = std::string(AFF2GLTF_PATH) + " " + (dir / "bad.aff").string() +
                              " -o " + (dir / "bad.gltf").string() + " 2> " +
                              (dir / "err.txt").string();
  const int status = std::system(command.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1);
  std::ifstream err(dir / "err.txt");
  const std::string message((std::istreambuf_iterator<char>(err)), {});
  EXPECT_NE(message.find((dir / "bad.aff").string() + ":4: "), std::string::npos) << message;
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.gltf"));
  std::filesystem::remove_all(dir);
}

// The formats leave light intensity open: 1 is NFF's unit, `spd` the Standard Procedural
// Databases' sqrt(N) / (2 N); anything else is refused naming the option.
TEST(Aff2GltfProgramTest, LightIntensityIsAFactorOrTheSpdFormula) {
  const auto dir = test::fresh_temp_dir("aff-lights");
  const auto aff = test::write_hand_scene(dir);  // 3 lights
  const auto run = [&](const std::string& flag, const std::string& name) {
    const std::string command = std::string(AFF2GLTF_PATH) + " " + aff.string() + " -o " +
                                (dir / name).string() + " " + flag + " > " +
                                (dir / "log.txt").string() + " 2>&1";
    return std::system(command.c_str());
  };
  const auto intensities = [&](const std::string& name) {
    std::vector<double> out;
    for (const auto& light : test::load_gltf((dir / name).string()).lights) {
      out.push_back(light.intensity);
    }
    return out;
  };
  ASSERT_EQ(run("--light-intensity 0.25", "quarter.gltf"), 0);
  for (const double i : intensities("quarter.gltf")) EXPECT_DOUBLE_EQ(i, 0.25 * M_PI);
  ASSERT_EQ(run("--light-intensity spd", "spd.gltf"), 0);
  const std::vector<double> spd = intensities("spd.gltf");
  ASSERT_EQ(spd.size(), 3u);
  for (const double i : spd) EXPECT_DOUBLE_EQ(i, std::sqrt(3.0) / 6.0 * M_PI);
  for (const std::string bad : {"-1", "nan", "bright", "2e6"}) {
    const int status = run("--light-intensity " + bad, "bad.gltf");
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_NE(WEXITSTATUS(status), 0) << bad;
    std::ifstream log(dir / "log.txt");
    const std::string message((std::istreambuf_iterator<char>(log)), {});
    EXPECT_NE(message.find("--light-intensity"), std::string::npos) << message;
    EXPECT_FALSE(std::filesystem::exists(dir / "bad.gltf")) << bad;
  }
  std::filesystem::remove_all(dir);
}

TEST(Aff2GltfProgramTest, GlbOutputIsOneBinaryFileWithTheGltfsContent) {
  const auto dir = test::fresh_temp_dir("aff-glb");
  const auto aff = test::write_hand_scene(dir);
  const auto run = [&](const std::filesystem::path& out) {
    const std::string command = std::string(AFF2GLTF_PATH) + " " + aff.string() + " -o " +
                                out.string() + " > " + (dir / "log.txt").string() + " 2>&1";
    return std::system(command.c_str());
  };
  ASSERT_EQ(run(dir / "gltf" / "scene.gltf"), 0);
  ASSERT_EQ(run(dir / "glb" / "scene.glb"), 0);
  // One file: no .bin, no textures, no scratch folder beside it.
  std::vector<std::string> written;
  for (const auto& e : std::filesystem::directory_iterator(dir / "glb")) {
    written.push_back(e.path().filename().string());
  }
  EXPECT_EQ(written, std::vector<std::string>{"scene.glb"});
  std::ifstream in(dir / "glb" / "scene.glb", std::ios::binary);
  const std::vector<uint8_t> glb{std::istreambuf_iterator<char>(in), {}};
  ASSERT_GE(glb.size(), 20u);
  EXPECT_EQ(std::string(glb.begin(), glb.begin() + 4), "glTF");
  EXPECT_EQ(glb[4], 2);  // version 2, little-endian
  EXPECT_EQ(size_t(glb[8]) | size_t(glb[9]) << 8 | size_t(glb[10]) << 16 | size_t(glb[11]) << 24,
            glb.size());

  // Read by tinygltf as a .glb, every accessor has the values of the .gltf's.
  const tinygltf::Model a = test::load_gltf((dir / "gltf" / "scene.gltf").string());
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader([](tinygltf::Image*, const int, std::string*, std::string*, int, int,
                           const unsigned char*, int, void*) { return true; },
                        nullptr);
  tinygltf::Model b;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadBinaryFromFile(&b, &err, &warn, (dir / "glb" / "scene.glb").string()))
      << err;
  ASSERT_EQ(a.accessors.size(), b.accessors.size());
  for (size_t i = 0; i < a.accessors.size(); ++i) {
    EXPECT_EQ(test::read_accessor(a, int(i)), test::read_accessor(b, int(i))) << "accessor " << i;
  }
  EXPECT_EQ(test::scene_triangles(a), test::scene_triangles(b));
  ASSERT_EQ(b.images.size(), 2u);
  for (const tinygltf::Image& image : b.images) {
    EXPECT_TRUE(image.uri.empty());
    EXPECT_EQ(image.mimeType, "image/png");
    EXPECT_GE(image.bufferView, 0);
  }
  // afr loads both to the same scene, textures included.
  const afr::Scene from_gltf = afr::load_gltf(dir / "gltf" / "scene.gltf");
  const afr::Scene from_glb = afr::load_gltf(dir / "glb" / "scene.glb");
  EXPECT_EQ(from_gltf.triangle_count(), from_glb.triangle_count());
  ASSERT_EQ(from_gltf.textures.size(), from_glb.textures.size());
  for (size_t i = 0; i < from_gltf.textures.size(); ++i) {
    EXPECT_EQ(from_gltf.textures[i].texels, from_glb.textures[i].texels) << "texture " << i;
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace afr::aff
