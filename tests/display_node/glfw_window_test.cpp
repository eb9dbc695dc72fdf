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

// The HUD: white text on a dark panel over the top left, the image untouched elsewhere.
TEST(GlfwWindowTest, DrawsTheHudTextOverTheImage) {
  std::string error;
  std::shared_ptr<GlfwWindow> window = GlfwWindow::create(240, 120, "afr test", &error);
  if (window == nullptr) GTEST_SKIP() << error;
  Image gray(240, 120);
  for (glm::vec3& p : gray.pixels) p = glm::vec3(0.5f);
  window->draw_image(gray);
  window->draw_text({"afr 12.3 Hz", "#1 87 k/s"}, 2);
  const Image shown = window->read_back_buffer();
  window->swap();
  const float background = linear_to_srgb8(0.5f) / 255.0f;
  // The panel spans the widest line (11 characters of about 6 font pixels, x2) and two lines
  // of 12 (x2), plus margins: some of its pixels are text (white), the rest darkened gray.
  int white = 0, dark = 0;
  for (int y = 0; y < 50; ++y) {
    for (int x = 0; x < 120; ++x) {
      const float v = shown.at(x, y).g;
      white += v > 0.95f ? 1 : 0;
      dark += v < background - 0.2f ? 1 : 0;
    }
  }
  EXPECT_GT(white, 100);
  EXPECT_GT(dark, 1000);
  // Away from the panel the image is as drawn.
  EXPECT_NEAR(shown.at(200, 100).g, background, 1.5f / 255);
  EXPECT_NEAR(shown.at(10, 110).g, background, 1.5f / 255);
}

// Keys come from GLFW's key events: a tap between two frames is kept until read, in order,
// held repeats are not presses, and nobody reading bounds what is kept.
TEST(GlfwWindowTest, KeyTapsAreKeptUntilReadInOrder) {
  std::string error;
  std::shared_ptr<GlfwWindow> window = GlfwWindow::create(32, 32, "afr test", &error);
  if (window == nullptr) GTEST_SKIP() << error;
  window->poll_events();
  (void)window->take_key_presses();
  window->on_key(50, 1);  // GLFW_PRESS of '2'
  window->on_key(50, 0);  // its release
  window->on_key(77, 1);  // 'M'
  window->on_key(77, 2);  // GLFW_REPEAT: held, not a new press
  EXPECT_EQ(window->take_key_presses(), (std::vector<int>{50, 77}));
  EXPECT_TRUE(window->take_key_presses().empty());
  for (int i = 0; i < 10000; ++i) window->on_key(72, 1);
  EXPECT_LE(window->take_key_presses().size(), 256u);
}

}  // namespace
}  // namespace afr
