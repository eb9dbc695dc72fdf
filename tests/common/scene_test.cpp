#include <afr/common/image.h>
#include <afr/common/scene.h>

#include <afr/common/error.h>

#include <gtest/gtest.h>

#include <cmath>

namespace afr {
namespace {

Primitive triangle() {
  Primitive p;
  p.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  p.indices = {0, 1, 2};
  return p;
}

Scene one_mesh_scene() {
  Scene s;
  s.source = "test scene";
  s.meshes.push_back(Mesh{"tri", {triangle()}});
  s.nodes.push_back(Node{});
  s.nodes[0].mesh = 0;
  return s;
}

TEST(SceneTest, FinalizeGeneratesNormalsWhenAbsent) {
  Scene s = one_mesh_scene();
  s.finalize();
  const Primitive& p = s.meshes[0].primitives[0];
  ASSERT_EQ(p.normals.size(), 3u);
  for (const glm::vec3& n : p.normals) EXPECT_EQ(n, glm::vec3(0, 0, 1));
}

TEST(SceneTest, GeneratedNormalsAreAreaWeighted) {
  // Two triangles share vertex 0: a large one facing +Z and a small one facing +X.
  Primitive p;
  p.positions = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0, 0.1f, 0}, {0, 0, 0.1f}};
  p.indices = {0, 1, 2, 0, 3, 4};
  generate_normals(&p);
  // Area 2 toward +Z, area 0.005 toward +X: normalize((0.01, 0, 4)).
  const glm::vec3 expected = glm::normalize(glm::vec3(0.01f, 0.0f, 4.0f));
  EXPECT_NEAR(p.normals[0].x, expected.x, 1e-6f);
  EXPECT_NEAR(p.normals[0].z, expected.z, 1e-6f);
}

TEST(SceneTest, DegenerateTrianglesGiveAFiniteDefaultNormal) {
  Primitive p;
  p.positions = {{1, 1, 1}, {1, 1, 1}, {1, 1, 1}};
  p.indices = {0, 1, 2};
  generate_normals(&p);
  for (const glm::vec3& n : p.normals) EXPECT_EQ(n, glm::vec3(0, 0, 1));
}

TEST(SceneTest, FinalizeRejectsOutOfRangeReferencesNamingTheSource) {
  {
    Scene s = one_mesh_scene();
    s.meshes[0].primitives[0].indices[2] = 3;
    try {
      s.finalize();
      FAIL();
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("test scene"), std::string::npos);
      EXPECT_NE(std::string(e.what()).find("index 3"), std::string::npos);
    }
  }
  {
    Scene s = one_mesh_scene();
    s.nodes[0].mesh = 4;
    EXPECT_THROW(s.finalize(), Error);
  }
  {
    Scene s = one_mesh_scene();
    s.meshes[0].primitives[0].material = 0;  // no materials
    EXPECT_THROW(s.finalize(), Error);
  }
  {
    Scene s = one_mesh_scene();
    s.meshes[0].primitives[0].positions[1].x = NAN;
    EXPECT_THROW(s.finalize(), Error);
  }
}

TEST(SceneTest, FinalizeRejectsCyclesAndSharedChildren) {
  Scene cycle = one_mesh_scene();
  cycle.nodes.resize(2);
  cycle.nodes[0].children = {1};
  cycle.nodes[1].children = {0};
  EXPECT_THROW(cycle.finalize(), Error);

  Scene shared = one_mesh_scene();
  shared.nodes.resize(3);
  shared.nodes[0].children = {2};
  shared.nodes[1].children = {2};
  EXPECT_THROW(shared.finalize(), Error);
}

TEST(SceneTest, WorldTransformsComposeParentTimesChild) {
  Scene s = one_mesh_scene();
  s.nodes.resize(2);
  s.nodes[0].translation = {1, 0, 0};
  s.nodes[0].rotation = glm::angleAxis(glm::radians(90.0), glm::dvec3(0, 0, 1));
  s.nodes[0].children = {1};
  s.nodes[1].translation = {2, 0, 0};
  s.nodes[1].scale = {3, 3, 3};
  s.finalize();
  const SceneState st = s.evaluate(0.0);
  // Child origin: parent maps (2,0,0) by a 90 degree turn about Z to (0,2,0), then + (1,0,0).
  const glm::dvec3 origin(st.world[1] * glm::dvec4(0, 0, 0, 1));
  EXPECT_NEAR(origin.x, 1.0, 1e-12);
  EXPECT_NEAR(origin.y, 2.0, 1e-12);
  // Child's local (1,0,0): scaled to 3, rotated to (0,3,0).
  const glm::dvec3 p(st.world[1] * glm::dvec4(1, 0, 0, 1));
  EXPECT_NEAR(p.x, 1.0, 1e-12);
  EXPECT_NEAR(p.y, 5.0, 1e-12);
}

TEST(SceneTest, AnimatedParentMovesChildAndDurationCoversKeys) {
  Scene s = one_mesh_scene();
  s.nodes.resize(3);
  s.nodes[1].children = {0};  // the mesh node hangs under an animated parent
  AnimationChannel ch;
  ch.node = 1;
  ch.path = AnimatedPath::kTranslation;
  ch.interpolation = Interpolation::kLinear;
  ch.times = {0.0, 4.0};
  ch.values = {{0, 0, 0, 0}, {8, 0, 0, 0}};
  s.channels.push_back(ch);
  s.finalize();
  EXPECT_TRUE(s.node_moves(0));
  EXPECT_TRUE(s.node_moves(1));
  EXPECT_FALSE(s.node_moves(2));
  EXPECT_TRUE(s.has_moving_geometry());
  EXPECT_DOUBLE_EQ(s.duration(), 4.0);
  EXPECT_DOUBLE_EQ(s.evaluate(1.0).world[0][3].x, 2.0);
}

TEST(SceneTest, MatrixNodesCannotBeAnimated) {
  Scene s = one_mesh_scene();
  s.nodes[0].matrix = glm::dmat4(1.0);
  AnimationChannel ch;
  ch.node = 0;
  ch.times = {0.0};
  ch.values = {{0, 0, 0, 0}};
  s.channels.push_back(ch);
  EXPECT_THROW(s.finalize(), Error);
}

TEST(SceneTest, DefaultCameraSeesTheWholeScene) {
  Scene s = one_mesh_scene();
  s.finalize();
  const SceneState st = s.evaluate(0.0);
  const Camera cam = s.camera_at(st);
  for (const glm::vec3& v : s.meshes[0].primitives[0].positions) {
    glm::dvec2 xy;
    ASSERT_TRUE(cam.project(glm::dvec3(v), 100, 100, &xy, nullptr));
    EXPECT_GE(xy.x, 0.0);
    EXPECT_LE(xy.x, 100.0);
    EXPECT_GE(xy.y, 0.0);
    EXPECT_LE(xy.y, 100.0);
  }
}

TEST(SceneTest, TextureSamplingIsBilinearAndRepeats) {
  Texture t;
  t.width = 2;
  t.height = 1;
  t.texels = {glm::vec3(0.0f), glm::vec3(1.0f)};
  // Texel centers at u = 0.25 and 0.75.
  EXPECT_NEAR(t.sample_bilinear({0.25f, 0.5f}).x, 0.0f, 1e-6f);
  EXPECT_NEAR(t.sample_bilinear({0.75f, 0.5f}).x, 1.0f, 1e-6f);
  EXPECT_NEAR(t.sample_bilinear({0.5f, 0.5f}).x, 0.5f, 1e-6f);
  // u = 0 lies halfway between the last texel (wrapped) and the first.
  EXPECT_NEAR(t.sample_bilinear({0.0f, 0.5f}).x, 0.5f, 1e-6f);
  EXPECT_NEAR(t.sample_bilinear({7.75f, -3.5f}).x, 1.0f, 1e-5f);
  EXPECT_TRUE(std::isfinite(t.sample_bilinear({NAN, INFINITY}).x));
}

// glTF's samplers: each axis wraps by its own mode, a magnified lookup may take the nearest
// texel, and the mip levels wrap as the lookups do. A row of 4 texels 0, 1, 2, 3 (u at texel
// centers 0.125 + k / 4), a column of 2 (v at 0.25, 0.75).
TEST(SceneTest, TextureWrapModesAndNearestFollowTheSampler) {
  using Wrap = Texture::Wrap;
  Texture t;
  t.width = 4;
  t.height = 2;
  for (int y = 0; y < 2; ++y) {
    for (int x = 0; x < 4; ++x) t.texels.push_back(glm::vec3(float(x), float(y), 0.0f));
  }
  auto at = [&](Wrap s, Wrap w, float u, float v) {
    t.wrap_s = s;
    t.wrap_t = w;
    return t.sample_bilinear({u, v});
  };
  // Texel -1 and texel 4: REPEAT 3 and 0, CLAMP_TO_EDGE 0 and 3, MIRRORED_REPEAT 0 and 3.
  EXPECT_NEAR(at(Wrap::kRepeat, Wrap::kRepeat, -0.125f, 0.25f).x, 3.0f, 1e-5f);
  EXPECT_NEAR(at(Wrap::kRepeat, Wrap::kRepeat, 1.125f, 0.25f).x, 0.0f, 1e-5f);
  EXPECT_NEAR(at(Wrap::kClampToEdge, Wrap::kRepeat, -0.125f, 0.25f).x, 0.0f, 1e-5f);
  EXPECT_NEAR(at(Wrap::kClampToEdge, Wrap::kRepeat, 1.125f, 0.25f).x, 3.0f, 1e-5f);
  EXPECT_NEAR(at(Wrap::kClampToEdge, Wrap::kRepeat, -1e9f, 0.25f).x, 0.0f, 1e-5f);
  EXPECT_NEAR(at(Wrap::kMirroredRepeat, Wrap::kRepeat, -0.125f, 0.25f).x, 0.0f, 1e-5f);
  EXPECT_NEAR(at(Wrap::kMirroredRepeat, Wrap::kRepeat, 1.125f, 0.25f).x, 3.0f, 1e-5f);
  EXPECT_NEAR(at(Wrap::kMirroredRepeat, Wrap::kRepeat, 1.375f, 0.25f).x, 2.0f, 1e-5f);
  // Two periods on, the mirror is where it began; far out it keeps its precision.
  EXPECT_NEAR(at(Wrap::kMirroredRepeat, Wrap::kRepeat, 2.375f, 0.25f).x, 1.0f, 1e-5f);
  EXPECT_NEAR(at(Wrap::kMirroredRepeat, Wrap::kRepeat, 4000.625f, 0.25f).x, 2.0f, 1e-3f);
  // Each axis its own: v = 1.25 is row 0 under REPEAT, row 1 under CLAMP_TO_EDGE.
  EXPECT_NEAR(at(Wrap::kRepeat, Wrap::kRepeat, 0.125f, 1.25f).y, 0.0f, 1e-5f);
  EXPECT_NEAR(at(Wrap::kRepeat, Wrap::kClampToEdge, 0.125f, 1.25f).y, 1.0f, 1e-5f);
  // Between centers bilinear blends; NEAREST takes the texel the point falls in.
  EXPECT_NEAR(at(Wrap::kRepeat, Wrap::kRepeat, 0.3f, 0.25f).x, 0.7f, 1e-5f);
  t.nearest = true;
  EXPECT_EQ(at(Wrap::kRepeat, Wrap::kRepeat, 0.3f, 0.25f).x, 1.0f);
  EXPECT_EQ(at(Wrap::kClampToEdge, Wrap::kRepeat, -0.3f, 0.25f).x, 0.0f);
  t.alpha = {0.0f, 0.25f, 0.5f, 0.75f, 1.0f, 1.0f, 1.0f, 1.0f};
  EXPECT_EQ(t.sample_alpha({0.3f, 0.25f}), 0.25f);

  // Mip levels wrap as the lookups do: a row 1 0 0 0, halved, its first texel's taps -2, -1
  // reach texels 2, 3 (REPEAT: 0) or texel 0 (CLAMP_TO_EDGE: 1 each).
  Texture row;
  row.width = 4;
  row.height = 1;
  row.texels = {glm::vec3(1.0f), glm::vec3(0.0f), glm::vec3(0.0f), glm::vec3(0.0f)};
  row.build_mips();
  EXPECT_NEAR(row.mips[0].texels[0].x, 10.0f / 32, 1e-6f);
  row.wrap_s = Wrap::kClampToEdge;
  row.build_mips();
  EXPECT_NEAR(row.mips[0].texels[0].x, (1.0f + 5.0f + 10.0f) / 32, 1e-6f);
}

// A texture kept as 8-bit codes (a glTF image's) looks up exactly as the same texture in
// floats at level 0, in either encoding; its mip levels are the floats' levels coded (filtered
// in linear values, each coded once); its alpha is the codes' fourth byte where kept.
TEST(SceneTest, CodedTexturesLookUpAsTheirFloatsAndCodeTheirMipLevels) {
  for (Texture::Encoding encoding : {Texture::Encoding::kSrgb, Texture::Encoding::kLinear}) {
    const bool srgb = encoding == Texture::Encoding::kSrgb;
    SCOPED_TRACE(srgb ? "sRGB" : "linear");
    Texture coded, floats;
    coded.width = floats.width = 7;
    coded.height = floats.height = 5;
    coded.encoding = encoding;
    for (uint32_t i = 0; i < 35; ++i) {
      const uint32_t r = (i * 37) % 256, g = (i * 91 + 5) % 256, b = (i * 13 + 200) % 256;
      coded.codes.push_back(r | (g << 8) | (b << 16) | ((i * 7 % 256) << 24));
      auto value = [&](uint32_t v) {
        return srgb ? srgb_to_linear(float(v) / 255.0f) : float(v) / 255.0f;
      };
      floats.texels.emplace_back(value(r), value(g), value(b));
    }
    for (size_t i = 0; i < 35; ++i) EXPECT_EQ(coded.texel(i), floats.texels[i]);
    coded.wrap_s = floats.wrap_s = Texture::Wrap::kMirroredRepeat;
    for (glm::vec2 uv : {glm::vec2(0.31f, 0.77f), glm::vec2(-2.4f, 9.1f), glm::vec2(0.0f)}) {
      // The same arithmetic on the same values, but in two instantiations of the lookup: a
      // compiler may contract them differently, so within a float's rounding.
      const glm::vec3 a = coded.sample_bilinear(uv), b = floats.sample_bilinear(uv);
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 1e-6f) << "channel " << c;
    }
    coded.build_mips();
    floats.build_mips();
    ASSERT_EQ(coded.mips.size(), floats.mips.size());
    for (size_t k = 0; k < coded.mips.size(); ++k) {
      const Texture::Level& c = coded.mips[k];
      const Texture::Level& f = floats.mips[k];
      EXPECT_TRUE(c.texels.empty());
      ASSERT_EQ(c.codes.size(), f.texels.size());
      for (size_t i = 0; i < c.codes.size(); ++i) {
        for (int channel = 0; channel < 3; ++channel) {
          const float v = f.texels[i][channel];
          const uint32_t want =
              srgb ? linear_to_srgb8(v) : uint32_t(std::lround(std::clamp(v, 0.0f, 1.0f) * 255));
          EXPECT_EQ((c.codes[i] >> (8 * channel)) & 0xff, want) << "level " << k + 1;
        }
      }
    }
    // Between levels the lookups stay within an 8-bit step of the floats'.
    const glm::vec3 a = coded.sample({0.4f, 0.6f}, 1.5f), b = floats.sample({0.4f, 0.6f}, 1.5f);
    EXPECT_NEAR(a.r, b.r, 1.0f / 255) << "trilinear";
    EXPECT_NEAR(a.b, b.b, 1.0f / 255) << "trilinear";

    // Alpha: the fourth byte, only where kept.
    EXPECT_EQ(coded.sample_alpha({0.5f / 7, 0.5f / 5}), 1.0f);
    coded.coded_alpha = true;
    EXPECT_EQ(coded.texel_alpha(3), float(21) / 255.0f);
    coded.nearest = true;
    EXPECT_EQ(coded.sample_alpha({3.5f / 7, 0.5f / 5}), float(21) / 255.0f);
  }
}

// Mip levels: each the binomial 1 5 10 10 5 1 low-pass of the one before, halved (REPEAT at the
// edges), down to 1 x 1; a lookup at lod 0 is the bilinear one, at lod 1 the first level's, in
// between a blend.
TEST(SceneTest, MipLevelsAverageAndTrilinearLookupBlendsThem) {
  Texture t;
  t.width = 4;
  t.height = 4;
  for (int y = 0; y < 4; ++y) {
    for (int x = 0; x < 4; ++x) t.texels.push_back(glm::vec3(float((x + y) % 2)));  // checker
  }
  t.build_mips();
  ASSERT_EQ(t.mips.size(), 2u);  // 2 x 2, 1 x 1
  EXPECT_EQ(t.mips[0].width, 2);
  EXPECT_EQ(t.mips[1].width, 1);
  for (const glm::vec3& v : t.mips[0].texels) EXPECT_FLOAT_EQ(v.x, 0.5f);
  EXPECT_FLOAT_EQ(t.mips[1].texels[0].x, 0.5f);
  const glm::vec2 texel_center(0.125f, 0.125f);  // texel (0, 0): black
  EXPECT_FLOAT_EQ(t.sample(texel_center, 0.0f).x, 0.0f);
  EXPECT_FLOAT_EQ(t.sample(texel_center, -3.0f).x, 0.0f);  // magnification: level 0
  EXPECT_FLOAT_EQ(t.sample(texel_center, 1.0f).x, 0.5f);
  EXPECT_FLOAT_EQ(t.sample(texel_center, 0.5f).x, 0.25f);
  EXPECT_FLOAT_EQ(t.sample(texel_center, 40.0f).x, 0.5f);  // beyond the last level: the last
  EXPECT_FLOAT_EQ(t.sample(texel_center, NAN).x, 0.0f);

  // Odd sizes: 3 x 1 -> 2 x 1 -> 1 x 1, the taps 2i - 2 ... 2i + 3 wrapping (REPEAT):
  // texel 0 takes 1 2 0 1 2 0, texel 1 takes 0 1 2 0 1 2.
  Texture odd;
  odd.width = 3;
  odd.height = 1;
  odd.texels = {glm::vec3(0.0f), glm::vec3(0.3f), glm::vec3(0.9f)};
  odd.build_mips();
  ASSERT_EQ(odd.mips.size(), 2u);
  EXPECT_NEAR(odd.mips[0].texels[0].x, (0.3f + 5 * 0.9f + 10 * 0.3f + 5 * 0.9f) / 32, 1e-6f);
  EXPECT_NEAR(odd.mips[0].texels[1].x, (5 * 0.3f + 10 * 0.9f + 5 * 0.3f + 0.9f) / 32, 1e-6f);
  EXPECT_NEAR(odd.mips[1].texels[0].x, 0.5f * (odd.mips[0].texels[0].x + odd.mips[0].texels[1].x),
              1e-6f);
  // A scene's textures get their levels when it is finalized.
  Scene scene;
  scene.textures.push_back(t);
  scene.textures[0].mips.clear();
  scene.finalize();
  EXPECT_EQ(scene.textures[0].mips.size(), 2u);
}

// A pattern just above a level's Nyquist rate must not survive into that level as a beat: BART's
// robots floor (17 dots per 128 texels) came out in blotches one repeat wide when each level was
// the 2 x 2 box of the one before, which keeps 0.21 of this pattern's contrast at 32 texels and
// 0.043 at 16. Its mean stays, at every level.
TEST(SceneTest, MipLevelsRemoveAPatternAboveTheirNyquistRate) {
  Texture t;
  t.width = 128;
  t.height = 128;
  for (int y = 0; y < t.height; ++y) {
    for (int x = 0; x < t.width; ++x) {
      const double phase = std::fmod((x + 0.5) * 17.0 / t.width, 1.0);  // 17 dark bars
      t.texels.push_back(glm::vec3(std::abs(phase - 0.5) < 0.3 ? 0.0f : 0.8f));
    }
  }
  double mean0 = 0.0;
  for (const glm::vec3& v : t.texels) mean0 += v.x;
  mean0 /= double(t.texels.size());
  t.build_mips();
  ASSERT_EQ(t.mips.size(), 7u);  // 64, 32, 16, 8, 4, 2, 1
  for (const Texture::Level& l : t.mips) {
    double mean = 0.0, square = 0.0;
    for (const glm::vec3& v : l.texels) mean += v.x;
    mean /= double(l.texels.size());
    for (const glm::vec3& v : l.texels) square += (v.x - mean) * (v.x - mean);
    const double contrast = std::sqrt(square / double(l.texels.size()));  // its standard deviation
    EXPECT_NEAR(mean, mean0, 1e-5) << l.width << " texels";
    if (l.width == 32) {
      EXPECT_LT(contrast, 0.06);  // the box: 0.21
    } else if (l.width == 16) {
      EXPECT_LT(contrast, 0.02);  // the box: 0.043
    }
  }
}

}  // namespace
}  // namespace afr
