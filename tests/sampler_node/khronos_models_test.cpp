// Khronos glTF sample models (tests/data/khronos, their glTF-Embedded variants as published):
// each loads, renders non-black under afr's default lighting at two times, and the animated
// ones (a rotation, translation and rotation, a skin, morph weights) render differently at
// those two times while the static ones do not (issue 18, item 6).
#include <afr/common/gltf_loader.h>
#include <afr/common/gltf_pack.h>
#include <afr/sampler/tracer.h>

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace afr {
namespace {

constexpr int kSize = 64;

struct Model {
  const char* file;
  double t0, t1;  // two times of its animation
  bool animated;
};

// The times are where each model's animation has moved something well into view: the triangle
// a quarter turn, the inner box up and turning, the skin's joint bent, the morph half way.
const Model kModels[] = {
    {"AnimatedTriangle.gltf", 0.0, 0.25, true}, {"BoxAnimated.gltf", 0.0, 2.0, true},
    {"Cameras.gltf", 0.0, 1.0, false},          {"SimpleMorph.gltf", 0.0, 2.0, true},
    {"SimpleSkin.gltf", 0.0, 1.5, true},        {"BoxVertexColors.gltf", 0.0, 1.0, false},
};

std::filesystem::path model_path(const char* file) {
  return std::filesystem::path(AFR_KHRONOS_DIR) / file;
}

// Luminance of every pixel of a kSize x kSize image of the scene's camera at time t.
std::vector<float> render(Tracer* tracer, double t) {
  tracer->set_time(t);
  std::vector<float> image;
  TraceStats stats;
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) {
      const Ray ray = tracer->camera().ray(x + 0.5, y + 0.5, kSize, kSize);
      image.push_back(luminance(tracer->trace(ray, &stats).color));
    }
  }
  EXPECT_EQ(stats.sanitized, 0u);
  return image;
}

class KhronosModelTest : public ::testing::TestWithParam<Model> {};

TEST_P(KhronosModelTest, RendersNonBlackAndMovesWhereItAnimates) {
  const Model& model = GetParam();
  GltfLoadReport report;
  const Scene scene = load_gltf(model_path(model.file), &report);
  EXPECT_EQ(scene.has_moving_geometry(), model.animated);
  Tracer tracer(scene);
  const std::vector<float> first = render(&tracer, model.t0);
  const std::vector<float> second = render(&tracer, model.t1);
  int lit_first = 0, lit_second = 0, changed = 0;
  for (size_t i = 0; i < first.size(); ++i) {
    lit_first += first[i] > 0.05f;
    lit_second += second[i] > 0.05f;
    changed += std::abs(first[i] - second[i]) > 0.02f;
  }
  // Not black: at both times a lit surface covers more than 1% of the image (SimpleMorph at
  // 0 s, its smallest, covers about 2% under the camera that frames the whole animation).
  EXPECT_GT(lit_first, kSize * kSize / 100) << model.file;
  EXPECT_GT(lit_second, kSize * kSize / 100) << model.file;
  if (model.animated) {
    EXPECT_GT(changed, kSize * kSize / 200) << model.file;
  } else {
    EXPECT_EQ(changed, 0) << model.file;
  }
}

INSTANTIATE_TEST_SUITE_P(SampleModels, KhronosModelTest, ::testing::ValuesIn(kModels),
                         [](const ::testing::TestParamInfo<Model>& info) {
                           std::string name = info.param.file;
                           return name.substr(0, name.find('.'));
                         });

TEST(KhronosModelTest, SimpleSkinBendsAsItsJointTurns) {
  // SimpleSkin: a strip from y = 0 to 2, its upper joint at (0, 1, 0) turned about Z by the
  // animation. Its top corner (0.5, 2, 0), all on the upper joint, goes where that turn takes
  // it: the joint's rotation at t, applied about (0, 1, 0).
  const Scene scene = load_gltf(model_path("SimpleSkin.gltf"));
  ASSERT_EQ(scene.skins.size(), 1u);
  for (double t : {0.0, 1.0, 1.5, 3.0}) {
    const SceneState state = scene.evaluate(t);
    std::vector<glm::vec3> positions(scene.meshes[0].primitives[0].positions.size());
    scene.deform(0, 0, state, positions.data(), nullptr);
    glm::dquat q(1.0, 0.0, 0.0, 0.0);
    for (const AnimationChannel& ch : scene.channels) {
      if (ch.node == 2 && ch.path == AnimatedPath::kRotation) {
        const glm::dvec4 v = ch.evaluate(t);
        q = glm::dquat(v.w, v.x, v.y, v.z);
      }
    }
    const glm::dvec3 want = glm::dvec3(0.0, 1.0, 0.0) + q * glm::dvec3(0.5, 1.0, 0.0);
    const glm::vec3& got = positions[9];  // (0.5, 2, 0) in the file
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], want[c], 1e-5) << "t = " << t;
  }
}

// BoxVertexColors: a gray material (0.8) whose COLOR_0 paints the box's faces in strong hues.
// Under the white headlight a gray surface stays gray (its channels within a few percent of
// each other); with the vertex colors, much of the visible face is far from gray.
TEST(KhronosModelTest, BoxVertexColorsShowTheirHues) {
  const Scene scene = load_gltf(model_path("BoxVertexColors.gltf"));
  Tracer tracer(scene);
  TraceStats stats;
  int lit = 0, colored = 0;
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) {
      const glm::vec3 c =
          tracer.trace(tracer.camera().ray(x + 0.5, y + 0.5, kSize, kSize), &stats).color;
      if (luminance(c) <= 0.05f) continue;
      ++lit;
      const float hi = std::max(c.r, std::max(c.g, c.b)), lo = std::min(c.r, std::min(c.g, c.b));
      colored += hi > 2.0f * lo + 0.05f;
    }
  }
  ASSERT_GT(lit, kSize * kSize / 20);
  EXPECT_GT(colored, lit / 4) << lit << " lit pixels";
}

// Cameras: a square tilted away from its two cameras. The perspective one sees a trapezoid,
// narrower at the far (top) edge; the orthographic one a rectangle, as wide at the top as at
// the bottom, 1 of the view's 2 units (ymag 1): half the image.
TEST(KhronosModelTest, CamerasShowTheTiltedSquareInPerspectiveAndOrthographic) {
  const std::filesystem::path path = model_path("Cameras.gltf");
  std::ifstream in(path, std::ios::binary);
  const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                   std::istreambuf_iterator<char>());
  for (const char* camera : {"0", "1"}) {
    SCOPED_TRACE(std::string("camera ") + camera);
    const Scene scene = load_gltf_bytes(select_camera(bytes, path, camera), path);
    Tracer tracer(scene);
    ASSERT_EQ(tracer.camera().orthographic(), camera[0] == '1');
    TraceStats stats;
    // The square's width in pixels on each row that sees it, top to bottom.
    std::vector<int> widths;
    for (int y = 0; y < kSize; ++y) {
      int width = 0;
      for (int x = 0; x < kSize; ++x) {
        width += tracer.trace(tracer.camera().ray(x + 0.5, y + 0.5, kSize, kSize), &stats).hit;
      }
      if (width > 0) widths.push_back(width);
    }
    ASSERT_GT(widths.size(), size_t(kSize / 8));
    if (camera[0] == '1') {
      EXPECT_NEAR(widths.front(), kSize / 2, 1);
      EXPECT_NEAR(widths.back(), kSize / 2, 1);
    } else {
      EXPECT_LT(widths.front() + 2, widths.back());
    }
  }
}

}  // namespace
}  // namespace afr
