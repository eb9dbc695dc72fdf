// A GLFW window with an OpenGL 4.3 core context, to show what a GlReconstructor makes. A thin
// class: the display node owns the event loop.
#pragma once

#include <afr/common/image.h>
#include <afr/display/gl_context.h>

#include <memory>
#include <string>

struct GLFWwindow;

namespace afr {

class GlReconstructor;

class GlfwWindow final : public GlContext {
 public:
  // nullptr, with the reason in *error, when GLFW cannot start (no display) or the context
  // cannot be made. Initialises GLFW (one window at a time); leaves the context current.
  static std::unique_ptr<GlfwWindow> create(int width, int height, const std::string& title,
                                            std::string* error);
  ~GlfwWindow() override;
  void make_current() override;

  bool should_close() const;
  void poll_events();
  void framebuffer_size(int* width, int* height) const;
  // Draws the reconstructor's last image into the back buffer; swap() shows it.
  void draw(GlReconstructor& reconstructor);
  // Draws a linear-RGB image (an overlay: the tiling, gradients, sample density), scaled to
  // the window, into the back buffer as the sRGB values a display shows.
  void draw_image(const Image& image);
  void set_title(const std::string& title);
  void swap();
  // The back buffer as drawn (before swap), row 0 at the top: for tests and screenshots.
  Image read_back_buffer();

 private:
  GlfwWindow() = default;
  GLFWwindow* window_ = nullptr;
  unsigned image_texture_ = 0, image_framebuffer_ = 0;  // draw_image's
};

}  // namespace afr
