#include <afr/display/glfw_window.h>

#include <afr/common/error.h>
#include <afr/display/gl_reconstructor.h>

#include "gl_program.h"

// epoxy before GLFW, and GLFW without its own GL header.
#include <epoxy/egl.h>
#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <fmt/format.h>

// A 6 x 11 pixel font as quads (Debian's libstb-dev); its functions are static, used here only.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#include <stb/stb_easy_font.h>
#pragma GCC diagnostic pop

#include <algorithm>
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

// draw_text's program: positions in window pixels (y down), one color per draw.
constexpr const char* kTextVertex = R"(#version 430 core
layout(location = 0) in vec2 a_pixel;
uniform vec2 u_size;
void main() { gl_Position = vec4(2.0 * a_pixel.x / u_size.x - 1.0, 1.0 - 2.0 * a_pixel.y / u_size.y, 0.0, 1.0); }
)";
constexpr const char* kTextFragment = R"(#version 430 core
uniform vec4 u_color;
out vec4 o_color;
void main() { o_color = u_color; }
)";

// The key presses a window keeps for take_key_presses() at most (a window nobody reads).
constexpr size_t kMaxKeyPresses = 256;

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
  glfwSetWindowUserPointer(window, w.get());
  glfwSetKeyCallback(window, [](GLFWwindow* win, int key, int, int action, int) {
    static_cast<GlfwWindow*>(glfwGetWindowUserPointer(win))->on_key(key, action);
  });
  glfwMakeContextCurrent(window);
  glfwSwapInterval(1);
  w->query_strings();
  return w;
}

GlfwWindow::~GlfwWindow() {
  if (window_ != nullptr && (image_texture_ != 0 || text_program_ != 0)) {
    make_current();
    glDeleteFramebuffers(1, &image_framebuffer_);
    glDeleteTextures(1, &image_texture_);
    glDeleteProgram(text_program_);
    glDeleteVertexArrays(1, &text_vao_);
    glDeleteBuffers(1, &text_buffer_);
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

void GlfwWindow::on_key(int key, int action) {
  if (action == GLFW_PRESS && key_presses_.size() < kMaxKeyPresses) key_presses_.push_back(key);
}

std::vector<int> GlfwWindow::take_key_presses() {
  std::vector<int> keys;
  keys.swap(key_presses_);
  return keys;
}

void GlfwWindow::draw_text(const std::vector<std::string>& lines, int scale) {
  if (lines.empty()) return;
  make_current();
  if (text_program_ == 0) {
    text_program_ = graphics_program(kTextVertex, kTextFragment, "window text");
    glGenVertexArrays(1, &text_vao_);
    glGenBuffers(1, &text_buffer_);
    glBindVertexArray(text_vao_);
    glBindBuffer(GL_ARRAY_BUFFER, text_buffer_);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, 0, nullptr);
    glBindVertexArray(0);
  }
  // The font's quads (4 vertices of x, y, z and a color each) as triangles, in window pixels.
  constexpr float kLine = 12.0f, kMargin = 4.0f;
  const float s = float(std::max(scale, 1));
  std::vector<glm::vec2> text;
  float widest = 0.0f;
  std::vector<char> buffer(64 * 1024);
  for (size_t i = 0; i < lines.size(); ++i) {
    std::string line = lines[i];
    // The font draws ASCII 32-126; anything else shows as '?'.
    for (char& c : line) c = (c >= 32 && c < 127) ? c : '?';
    widest = std::max(widest, float(stb_easy_font_width(line.data())));
    const int quads = stb_easy_font_print(0.0f, float(i) * kLine, line.data(), nullptr,
                                          buffer.data(), int(buffer.size()));
    const float* v = reinterpret_cast<const float*>(buffer.data());
    for (int q = 0; q < quads; ++q) {
      glm::vec2 c[4];
      for (int k = 0; k < 4; ++k) {
        const float* p = v + size_t(q * 4 + k) * 4;  // x, y, z, color (4 bytes)
        c[k] = (glm::vec2(p[0], p[1]) + kMargin) * s;
      }
      for (int k : {0, 1, 2, 0, 2, 3}) text.push_back(c[k]);
    }
  }
  const glm::vec2 lo(0.0f),
      hi = glm::vec2(widest + 2.0f * kMargin, float(lines.size()) * kLine + 2.0f * kMargin) * s;
  const glm::vec2 panel[6] = {lo, {hi.x, lo.y}, hi, lo, hi, {lo.x, hi.y}};

  int w = 0, h = 0;
  framebuffer_size(&w, &h);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glViewport(0, 0, w, h);
  glDisable(GL_FRAMEBUFFER_SRGB);
  glUseProgram(text_program_);
  glUniform2f(glGetUniformLocation(text_program_, "u_size"), float(w), float(h));
  const GLint color = glGetUniformLocation(text_program_, "u_color");
  glBindVertexArray(text_vao_);
  glBindBuffer(GL_ARRAY_BUFFER, text_buffer_);
  glEnable(GL_BLEND);
  glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
  glBufferData(GL_ARRAY_BUFFER, sizeof(panel), panel, GL_STREAM_DRAW);
  glUniform4f(color, 0.0f, 0.0f, 0.0f, 0.65f);
  glDrawArrays(GL_TRIANGLES, 0, 6);
  glDisable(GL_BLEND);
  glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(text.size() * sizeof(glm::vec2)), text.data(),
               GL_STREAM_DRAW);
  glUniform4f(color, 1.0f, 1.0f, 1.0f, 1.0f);
  glDrawArrays(GL_TRIANGLES, 0, GLsizei(text.size()));
  glBindVertexArray(0);
  glUseProgram(0);
}

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
