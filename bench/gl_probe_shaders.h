// The GL probes' shared pieces (skintune_bench_glvertex, skintune_bench_glupload):
// a GL error check and one-shader programs, each throwing std::runtime_error
// with the driver's log.
#pragma once

#include <epoxy/gl.h>

#include <cstdio>
#include <stdexcept>
#include <string>

namespace skintune::internal::bench {

inline void Check(const std::string& what) {
  const GLenum error = glGetError();
  if (error == GL_NO_ERROR) return;
  char hex[16];
  std::snprintf(hex, sizeof hex, "0x%04x", static_cast<unsigned>(error));
  throw std::runtime_error(what + ": GL error " + hex);
}

inline GLuint Compile(GLenum stage, const std::string& text) {
  const GLuint shader = glCreateShader(stage);
  const char* source = text.c_str();
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetShaderInfoLog(shader, sizeof log, nullptr, log);
    throw std::runtime_error(std::string("shader: ") + log);
  }
  return shader;
}

// A program of one shader of `stage`; `capture`: its "captured" output goes to
// transform feedback.
inline GLuint Link(GLenum stage, const std::string& text, bool capture = false) {
  const GLuint program = glCreateProgram();
  const GLuint shader = Compile(stage, text);
  glAttachShader(program, shader);
  if (capture) {
    const char* varyings[] = {"captured"};
    glTransformFeedbackVaryings(program, 1, varyings, GL_INTERLEAVED_ATTRIBS);
  }
  glLinkProgram(program);
  glDeleteShader(shader);
  GLint ok = 0;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetProgramInfoLog(program, sizeof log, nullptr, log);
    throw std::runtime_error(std::string("link: ") + log);
  }
  return program;
}

}  // namespace skintune::internal::bench
