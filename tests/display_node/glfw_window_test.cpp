// The window path: a GL reconstructor drawing into a GLFW window. Needs a display; skipped
// without one (run under xvfb-run to exercise it headless).
#include <afr/display/glfw_window.h>

#include <afr/common/random.h>
#include <afr/display/gl_reconstructor.h>

#include "test_support.h"

#include <gtest/gtest.h>

namespace afr {
namespace {

TEST(GlfwWindowTest, ShowsTheReconstructedImageTopUp) {
  std::string error;
  std::shared_ptr<GlfwWindow> window = GlfwWindow::create(64, 48, "afr test", &error);
  if (window == nullptr) GTEST_SKIP() << error;
  int fw = 0, fh = 0;
  window->framebuffer_size(&fw, &fh);
  ASSERT_EQ(fw, 64);
  ASSERT_EQ(fh, 48);
  ReconstructorConfig cfg;
  cfg.image.width = 64;
  cfg.image.height = 48;
  GlReconstructor gl(cfg, window);
  // Top half red, bottom half blue.
  Pcg32 rng(41);
  SampleBatch b = test::random_batch(rng, 64 * 48 * 4, 64, 48, 0.0, 1.0);
  for (Sample& s : b.samples) s.color = s.y < 24 ? glm::vec3(1, 0, 0) : glm::vec3(0, 0, 1);
  gl.add_batch(b);
  gl.set_tiling(test::uniform_tiling(64, 48, 0.01f, 1.0f, 0.0f, 4.0f));
  Image image;
  gl.reconstruct(Camera{}, 1.0, 64, 48, nullptr);  // no readback: the window shows it
  window->draw(gl);
  const Image shown = window->read_back_buffer();
  window->swap();
  window->poll_events();
  EXPECT_FALSE(window->should_close());
  ASSERT_EQ(shown.width, 64);
  // The window shows the sRGB bytes of the linear image, image row 0 at the top.
  EXPECT_NEAR(shown.at(10, 3).r, 1.0f, 1e-6f);
  EXPECT_NEAR(shown.at(10, 3).b, 0.0f, 1e-6f);
  EXPECT_NEAR(shown.at(50, 44).b, 1.0f, 1e-6f);
  EXPECT_NEAR(shown.at(50, 44).r, 0.0f, 1e-6f);
  // And what read back as an image is the same picture.
  gl.reconstruct(Camera{}, 1.0, 64, 48, &image);
  for (int y : {3, 20, 27, 44}) {
    for (int x = 0; x < 64; x += 7) {
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(shown.at(x, y)[c], linear_to_srgb8(image.at(x, y)[c]) / 255.0f, 1.5f / 255)
            << x << "," << y;
      }
    }
  }
}

TEST(GlfwWindowTest, DrawsAnImageAsItsSrgbValuesScaledToTheWindow) {
  std::string error;
  std::shared_ptr<GlfwWindow> window = GlfwWindow::create(64, 48, "afr test", &error);
  if (window == nullptr) GTEST_SKIP() << error;
  // Left half a dim grey, right half green; row 0 (top) white.
  Image img(32, 24, glm::vec3(0.2f));
  for (int y = 0; y < 24; ++y) {
    for (int x = 16; x < 32; ++x) img.at(x, y) = glm::vec3(0.0f, 1.0f, 0.0f);
  }
  for (int x = 0; x < 32; ++x) img.at(x, 0) = glm::vec3(1.0f);
  window->draw_image(img);  // 32 x 24 scaled 2x
  const Image shown = window->read_back_buffer();
  window->swap();
  ASSERT_EQ(shown.width, 64);
  EXPECT_NEAR(shown.at(10, 24).r, linear_to_srgb8(0.2f) / 255.0f, 1.5f / 255);
  EXPECT_NEAR(shown.at(50, 24).g, 1.0f, 1e-6f);
  EXPECT_NEAR(shown.at(50, 24).r, 0.0f, 1e-6f);
  EXPECT_NEAR(shown.at(10, 0).b, 1.0f, 1e-6f);  // the top row at the top
}

}  // namespace
}  // namespace afr
