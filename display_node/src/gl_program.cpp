#include "gl_program.h"

#include <afr/common/error.h>

#include <fmt/format.h>

#include <array>
#include <initializer_list>

namespace afr {

namespace {

GLuint compile(GLenum type, const char* source, const char* name) {
  const GLuint s = glCreateShader(type);
  glShaderSource(s, 1, &source, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    std::array<char, 4096> log{};
    glGetShaderInfoLog(s, GLsizei(log.size()), nullptr, log.data());
    glDeleteShader(s);
    throw Error(fmt::format("OpenGL: shader {} does not compile: {}", name, log.data()));
  }
  return s;
}

GLuint link(std::initializer_list<GLuint> shaders, const char* name) {
  const GLuint p = glCreateProgram();
  for (GLuint s : shaders) glAttachShader(p, s);
  glLinkProgram(p);
  for (GLuint s : shaders) glDeleteShader(s);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    std::array<char, 4096> log{};
    glGetProgramInfoLog(p, GLsizei(log.size()), nullptr, log.data());
    glDeleteProgram(p);
    throw Error(fmt::format("OpenGL: program {} does not link: {}", name, log.data()));
  }
  return p;
}

}  // namespace

GLuint graphics_program(const char* vertex, const char* fragment, const char* name) {
  return link(
      {compile(GL_VERTEX_SHADER, vertex, name), compile(GL_FRAGMENT_SHADER, fragment, name)}, name);
}

GLuint compute_program(const char* compute, const char* name) {
  return link({compile(GL_COMPUTE_SHADER, compute, name)}, name);
}

GLuint make_texture(GLenum format, int width, int height) {
  GLuint t = 0;
  glGenTextures(1, &t);
  glBindTexture(GL_TEXTURE_2D, t);
  glTexStorage2D(GL_TEXTURE_2D, 1, format, width, height);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  return t;
}

}  // namespace afr
