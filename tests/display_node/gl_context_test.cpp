#include <afr/display/gl_context.h>

#include <gtest/gtest.h>

#include <string>

namespace afr {
namespace {

// Whatever EGL this machine has (Mesa's software device here, a GPU's device elsewhere), the
// headless context says where it runs, and a device that is not there is refused with a reason
// that names what EGL does list.
TEST(GlContextTest, HeadlessContextNamesItsDeviceAndAMissingDeviceIsRefusedByName) {
  std::string error;
  auto context = EglContext::create_headless(&error);
  if (context == nullptr) {
    // No context at all: the reason names every device and platform tried.
    EXPECT_NE(error.find("no headless OpenGL context"), std::string::npos) << error;
    GTEST_SKIP() << error;
  }
  EXPECT_TRUE(context->device().rfind("EGL device ", 0) == 0 ||
              context->device() == "Mesa surfaceless platform")
      << context->device();
  EXPECT_FALSE(context->renderer().empty());

  std::string why;
  const std::vector<EglDevice> devices = egl_devices(&why);
  for (const EglDevice& d : devices) {
    EXPECT_EQ(d.describe().rfind("EGL device " + std::to_string(d.index) + " (", 0), 0u);
    // Auto takes a hardware device whenever one gives a context.
    if (!d.software && context->device() == "Mesa surfaceless platform") {
      ADD_FAILURE() << "auto passed over " << d.describe();
    }
  }
  std::string refused;
  EXPECT_EQ(EglContext::create_headless(HeadlessGlOptions{63}, &refused), nullptr);
  EXPECT_NE(refused.find("--gpu 63: no such EGL device"), std::string::npos) << refused;
  if (!devices.empty()) {
    EXPECT_NE(refused.find("EGL lists " + std::to_string(devices.size()) + " device"),
              std::string::npos)
        << refused;
    EXPECT_NE(refused.find(devices[0].describe()), std::string::npos) << refused;
    // Each listed device either gives a context that names it or is refused by its number.
    std::string picked_error;
    auto picked = EglContext::create_headless(HeadlessGlOptions{0}, &picked_error);
    if (picked != nullptr) {
      EXPECT_EQ(picked->device(), devices[0].describe());
    } else {
      EXPECT_EQ(picked_error.rfind("--gpu 0: ", 0), 0u) << picked_error;
    }
  }
  context->make_current();
}

}  // namespace
}  // namespace afr
