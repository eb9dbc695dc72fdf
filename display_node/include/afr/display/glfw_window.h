// A GLFW window with an OpenGL 4.3 core context, to show what a GlReconstructor makes. A thin
// class: the display node owns the event loop.
#pragma once

#include <afr/common/image.h>
#include <afr/display/gl_context.h>

#include <memory>
#include <string>
#include <vector>

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
  // Lines of text over the top left of the back buffer, white on a dark translucent panel,
  // `scale` window pixels per font pixel (a 6 x 11 pixel font: stb_easy_font). Call after
  // draw() or draw_image(), before swap().
  void draw_text(const std::vector<std::string>& lines, int scale = 2);
  // The keys pressed since the last call (GLFW key codes, in order), from GLFW's key events:
  // a tap between two frames counts, however short (polling once a frame would miss it).
  std::vector<int> take_key_presses();
  // What the key callback does with a GLFW event (tests call it with made-up events).
  void on_key(int key, int action);
  void swap();
  // The back buffer as drawn (before swap), row 0 at the top: for tests and screenshots.
  Image read_back_buffer();

 private:
  GlfwWindow() = default;
  GLFWwindow* window_ = nullptr;
  unsigned image_texture_ = 0, image_framebuffer_ = 0;          // draw_image's
  unsigned text_program_ = 0, text_vao_ = 0, text_buffer_ = 0;  // draw_text's
  std::vector<int> key_presses_;
};

}  // namespace afr
