#include <afr/display/glfw_window.h>

#include <afr/display/gl_reconstructor.h>

// epoxy before GLFW, and GLFW without its own GL header.
#include <epoxy/egl.h>
#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <fmt/format.h>

#include <vector>

namespace afr {

namespace {

// A thread has one current context across EGL and GLX (libglvnd refuses a GLX context with
// BadAccess while an EGL one is current), so a headless context made current on this thread
// earlier is released before the window's is made current.
void release_current_egl() {
  if (!epoxy_has_egl()) return;
  const EGLContext current = eglGetCurrentContext();
  if (current != EGL_NO_CONTEXT) {
    eglMakeCurrent(eglGetCurrentDisplay(), EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  }
}

}  // namespace

std::unique_ptr<GlfwWindow> GlfwWindow::create(int width, int height, const std::string& title,
                                               std::string* error) {
  if (!glfwInit()) {
    const char* description = nullptr;
    glfwGetError(&description);
    *error = fmt::format("GLFW cannot start: {}", description ? description : "no display?");
    return nullptr;
  }
  glfwDefaultWindowHints();
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  release_current_egl();  // GLFW makes the new context current while it creates it
  GLFWwindow* window = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
  if (window == nullptr) {
    const char* description = nullptr;
    glfwGetError(&description);
    *error = fmt::format("GLFW cannot make an OpenGL 4.3 core window: {}",
                         description ? description : "unknown error");
    glfwTerminate();
    return nullptr;
  }
  std::unique_ptr<GlfwWindow> w(new GlfwWindow());
  w->window_ = window;
  glfwMakeContextCurrent(window);
  glfwSwapInterval(1);
  w->query_strings();
  return w;
}

GlfwWindow::~GlfwWindow() {
  if (window_ != nullptr && image_texture_ != 0) {
    make_current();
    glDeleteFramebuffers(1, &image_framebuffer_);
    glDeleteTextures(1, &image_texture_);
  }
  if (window_ != nullptr) glfwDestroyWindow(window_);
  glfwTerminate();
}

void GlfwWindow::make_current() {
  if (glfwGetCurrentContext() != window_) {
    release_current_egl();
    glfwMakeContextCurrent(window_);
  }
}

bool GlfwWindow::should_close() const { return glfwWindowShouldClose(window_); }

void GlfwWindow::poll_events() { glfwPollEvents(); }

void GlfwWindow::framebuffer_size(int* width, int* height) const {
  glfwGetFramebufferSize(window_, width, height);
}

void GlfwWindow::draw(GlReconstructor& reconstructor) {
  make_current();
  int w = 0, h = 0;
  framebuffer_size(&w, &h);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glViewport(0, 0, w, h);
  glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  reconstructor.draw_output(w, h);
}

void GlfwWindow::draw_image(const Image& image) {
  make_current();
  if (image.width < 1 || image.height < 1) return;
  // sRGB bytes, rows bottom to top as GL keeps them.
  std::vector<uint8_t> rgb(size_t(image.width) * size_t(image.height) * 3);
  for (int y = 0; y < image.height; ++y) {
    uint8_t* row = rgb.data() + size_t(image.height - 1 - y) * size_t(image.width) * 3;
    for (int x = 0; x < image.width; ++x) {
      for (int c = 0; c < 3; ++c) row[3 * x + c] = linear_to_srgb8(image.at(x, y)[c]);
    }
  }
  if (image_texture_ == 0) {
    glGenTextures(1, &image_texture_);
    glGenFramebuffers(1, &image_framebuffer_);
  }
  glBindTexture(GL_TEXTURE_2D, image_texture_);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB8, image.width, image.height, 0, GL_RGB, GL_UNSIGNED_BYTE,
               rgb.data());
  glBindFramebuffer(GL_READ_FRAMEBUFFER, image_framebuffer_);
  glFramebufferTexture2D(GL_READ_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, image_texture_,
                         0);
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
  int w = 0, h = 0;
  framebuffer_size(&w, &h);
  // The bytes are already what the display shows: no conversion on the way.
  glDisable(GL_FRAMEBUFFER_SRGB);
  glBlitFramebuffer(0, 0, image.width, image.height, 0, 0, w, h, GL_COLOR_BUFFER_BIT,
                    image.width == w && image.height == h ? GL_NEAREST : GL_LINEAR);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

void GlfwWindow::set_title(const std::string& title) { glfwSetWindowTitle(window_, title.c_str()); }

void GlfwWindow::swap() { glfwSwapBuffers(window_); }

Image GlfwWindow::read_back_buffer() {
  make_current();
  int w = 0, h = 0;
  framebuffer_size(&w, &h);
  Image image(w, h);
  std::vector<uint8_t> rgb(size_t(w) * size_t(h) * 3);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glReadBuffer(GL_BACK);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE, rgb.data());
  // GL rows run bottom to top; the image's row 0 is the top. Values are the sRGB bytes shown.
  for (int y = 0; y < h; ++y) {
    const uint8_t* row = rgb.data() + size_t(h - 1 - y) * size_t(w) * 3;
    for (int x = 0; x < w; ++x) {
      image.at(x, y) = glm::vec3(row[3 * x], row[3 * x + 1], row[3 * x + 2]) / 255.0f;
    }
  }
  return image;
}

}  // namespace afr
