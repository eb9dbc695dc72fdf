#include <afr/display/backend.h>

#include <afr/common/error.h>
#include <afr/display/gl_context.h>

#include "test_support.h"

#include <gtest/gtest.h>

namespace afr {
namespace {

TEST(BackendTest, ParsesTheThreeNamesAndRejectsOthers) {
  EXPECT_EQ(parse_backend("gl"), Backend::kGl);
  EXPECT_EQ(parse_backend("cpu"), Backend::kCpu);
  EXPECT_EQ(parse_backend("auto"), Backend::kAuto);
  EXPECT_THROW(parse_backend("vulkan"), Error);
  EXPECT_THROW(parse_backend(""), Error);
  EXPECT_STREQ(backend_name(Backend::kAuto), "auto");
}

TEST(BackendTest, SoftwareRasterisersAreRecognisedByName) {
  EXPECT_TRUE(is_software_renderer("llvmpipe (LLVM 15.0.6, 256 bits)"));
  EXPECT_TRUE(is_software_renderer("softpipe"));
  EXPECT_TRUE(is_software_renderer("Mesa X11 swrast"));
  EXPECT_TRUE(is_software_renderer("Google SwiftShader"));
  EXPECT_FALSE(is_software_renderer("NVIDIA GeForce RTX 3080/PCIe/SSE2"));
  EXPECT_FALSE(is_software_renderer("AMD Radeon RX 6800 (radeonsi, navi21, LLVM 15.0.6)"));
  EXPECT_FALSE(is_software_renderer("Mesa Intel(R) UHD Graphics 620 (KBL GT2)"));
}

TEST(BackendTest, CpuIsCpu) {
  ReconstructorConfig cfg;
  const BackendChoice c = make_reconstructor(Backend::kCpu, cfg);
  EXPECT_EQ(c.chosen, Backend::kCpu);
  EXPECT_STREQ(c.reconstructor->backend_name(), "cpu");
  EXPECT_NE(c.reason.find("cpu"), std::string::npos);
}

TEST(BackendTest, AutoTakesGlOnHardwareAndTheCpuOnASoftwareRasteriser) {
  ReconstructorConfig cfg;
  std::string why;
  const std::shared_ptr<GlContext> probe = test::shared_gl_context(&why);
  const BackendChoice c = make_reconstructor(Backend::kAuto, cfg);
  ASSERT_NE(c.reconstructor, nullptr);
  EXPECT_STREQ(c.reconstructor->backend_name(), backend_name(c.chosen));
  if (probe == nullptr) {
    EXPECT_EQ(c.chosen, Backend::kCpu);
    EXPECT_NE(c.reason.find("no OpenGL context"), std::string::npos) << c.reason;
  } else if (probe->software()) {
    EXPECT_EQ(c.chosen, Backend::kCpu);
    EXPECT_NE(c.reason.find(probe->renderer()), std::string::npos) << c.reason;
    EXPECT_NE(c.reason.find("software"), std::string::npos) << c.reason;
  } else {
    EXPECT_EQ(c.chosen, Backend::kGl);
  }
}

TEST(BackendTest, GlWhenAskedForAndAContextExists) {
  std::string why;
  if (test::shared_gl_context(&why) == nullptr) GTEST_SKIP() << "no EGL/OpenGL context: " << why;
  ReconstructorConfig cfg;
  cfg.image.width = 32;
  cfg.image.height = 16;
  const BackendChoice c = make_reconstructor(Backend::kGl, cfg);
  EXPECT_EQ(c.chosen, Backend::kGl);
  EXPECT_STREQ(c.reconstructor->backend_name(), "gl");
  const Image image = c.reconstructor->reconstruct(Camera{}, 0.0, 32, 16);
  EXPECT_EQ(image.width, 32);
}

}  // namespace
}  // namespace afr
