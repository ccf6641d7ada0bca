// skintune_bench_glvertex: where the GLSL vertex-shader path's time goes.
//
// The paper's GLSL form skins in a vertex shader and captures the result with
// transform feedback. On the H100 that path costs ~5 ns per vertex whatever
// the influence count, 300x the compute shader (docs/PERFORMANCE.md). This
// probe takes the path apart, one stage at a time, on the same EGL context:
//
//   points-empty       glDrawArrays(GL_POINTS) of a vertex shader that writes
//                      only gl_Position, rasteriser discard on, no capture:
//                      the graphics front end's vertex rate alone;
//   points-raster      the same with the rasteriser on (a 1x1 framebuffer);
//   points-empty-inst  the same as an instanced draw (N/64 vertices x 64);
//   tris-empty         the same vertices as GL_TRIANGLES (a third the primitives);
//   xfb-write          + transform feedback of one vec3 per vertex (12 B out);
//   ssbo-xfb           + the vec3 read from a storage buffer by gl_VertexID
//                      (the form skintune's glsl-vertex kernels take; 24 B);
//   attrib-xfb         the vec3 as a vertex attribute instead (the paper's form);
//   ssbo-ssbo-vs       a vertex shader that copies storage buffer to storage
//                      buffer, no capture (the vertex stage used as compute);
//   compute-copy       the same copy as a compute shader (work-group 256).
//
// Each case is checked (the copy cases' outputs read back and compared), warmed
// for 300 ms of host time, then timed in bursts of --draws draws, each burst in
// one GL_TIME_ELAPSED query; the fastest burst per draw is printed with ns per
// vertex and GB/s of the bytes the case moves. Needs a GL 4.3 context (EGL).
#include <epoxy/gl.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "gl_probe_shaders.h"
#include "runtime/backends/gl/gl_context.h"

namespace {

using skintune::internal::GlContext;

using skintune::internal::bench::Check;
using skintune::internal::bench::Link;

GLuint Buffer(std::size_t bytes, const void* data) {
  GLuint buffer = 0;
  glGenBuffers(1, &buffer);
  glBindBuffer(GL_COPY_WRITE_BUFFER, buffer);
  glBufferData(GL_COPY_WRITE_BUFFER, static_cast<GLsizeiptr>(bytes), data, GL_STATIC_DRAW);
  glBindBuffer(GL_COPY_WRITE_BUFFER, 0);
  return buffer;
}

const char* kHeader = "#version 430 core\n";

struct Case {
  std::string name;
  std::string what;
  std::size_t bytes_per_vertex;  // moved to or from memory
  bool copy;                      // output must equal the input
};

const std::vector<Case> kCases = {
    {"points-empty", "GL_POINTS, gl_Position only, discard, no capture", 0, false},
    {"points-raster", "the same with the rasteriser on (1x1 framebuffer)", 0, false},
    {"points-empty-inst", "the same, instanced: N/64 vertices x 64 instances", 0, false},
    {"tris-empty", "the same vertices as GL_TRIANGLES", 0, false},
    {"xfb-write", "+ transform feedback of a vec3 (12 B/vertex)", 12, false},
    {"ssbo-xfb", "vec3 from a storage buffer -> transform feedback (skintune's form)", 24, true},
    {"attrib-xfb", "vec3 vertex attribute -> transform feedback (the paper's form)", 24, true},
    {"ssbo-ssbo-vs", "vertex shader: storage buffer -> storage buffer, no capture", 24, true},
    {"compute-copy", "compute shader: storage buffer -> storage buffer", 24, true},
};

struct Result {
  std::string name;
  std::size_t vertices = 0;
  double ms = 0;  // per draw, fastest burst
};

class Probe {
 public:
  Probe(std::size_t vertices, int draws) : n_(vertices), draws_(draws) {
    std::vector<float> input(n_ * 3);
    for (std::size_t i = 0; i < input.size(); ++i) input[i] = static_cast<float>(i % 100003) * 0.25f;
    input_ = input;
    in_ = Buffer(input.size() * 4, input.data());
    out_ = Buffer(input.size() * 4, nullptr);
    glGenVertexArrays(1, &vao_);
    glGenTransformFeedbacks(1, &xfb_);
    // Draws need a complete framebuffer even with the rasteriser discarding
    // (a surfaceless context has none): 1x1, as the runner's vertex path.
    glGenRenderbuffers(1, &renderbuffer_);
    glBindRenderbuffer(GL_RENDERBUFFER, renderbuffer_);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_R8, 1, 1);
    glBindRenderbuffer(GL_RENDERBUFFER, 0);
    glGenFramebuffers(1, &framebuffer_);
    glBindFramebuffer(GL_FRAMEBUFFER, framebuffer_);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, renderbuffer_);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("the 1x1 framebuffer is incomplete");
    glViewport(0, 0, 1, 1);
    Check("set-up");
  }
  ~Probe() {
    glDeleteBuffers(1, &in_);
    glDeleteBuffers(1, &out_);
    glDeleteVertexArrays(1, &vao_);
    glDeleteTransformFeedbacks(1, &xfb_);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glDeleteFramebuffers(1, &framebuffer_);
    glDeleteRenderbuffers(1, &renderbuffer_);
  }

  // The GPU's time per draw (GL_TIME_ELAPSED, fastest burst); host_ms() then
  // gives the wall time per draw of the fastest burst between two glFinish
  // calls (Mesa's software renderers report ~0 on the GPU clock).
  double host_ms() const { return host_ms_; }
  double Run(const Case& c) {
    GLuint program = 0;
    std::function<void()> draw;
    const GLsizei n = static_cast<GLsizei>(n_);
    const bool capture = c.name == "xfb-write" || c.name == "ssbo-xfb" || c.name == "attrib-xfb";
    glBindVertexArray(vao_);
    glDisableVertexAttribArray(0);
    if (c.name == "points-empty" || c.name == "points-raster" || c.name == "points-empty-inst" ||
        c.name == "tris-empty") {
      program = Link(GL_VERTEX_SHADER, std::string(kHeader) + "void main() { gl_Position = vec4(0.0); }\n", false);
      const GLenum mode = c.name == "tris-empty" ? GL_TRIANGLES : GL_POINTS;
      const GLsizei count = c.name == "tris-empty" ? n - n % 3 : n;
      if (c.name == "points-empty-inst")
        draw = [n] { glDrawArraysInstanced(GL_POINTS, 0, n / 64, 64); };
      else
        draw = [mode, count] { glDrawArrays(mode, 0, count); };
    } else if (c.name == "xfb-write") {
      program = Link(GL_VERTEX_SHADER,
                     std::string(kHeader) + "out vec3 captured;\nvoid main() { captured = vec3(float(gl_VertexID)); }\n",
                     true);
    } else if (c.name == "ssbo-xfb") {
      program = Link(GL_VERTEX_SHADER,
                     std::string(kHeader) +
                         "layout(std430, binding = 0) readonly buffer In { float v[]; };\nout vec3 captured;\n"
                         "void main() { int i = 3 * gl_VertexID; captured = vec3(v[i], v[i + 1], v[i + 2]); }\n",
                     true);
    } else if (c.name == "attrib-xfb") {
      program = Link(GL_VERTEX_SHADER,
                     std::string(kHeader) +
                         "layout(location = 0) in vec3 p;\nout vec3 captured;\nvoid main() { captured = p; }\n",
                     true);
      glBindBuffer(GL_ARRAY_BUFFER, in_);
      glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 12, nullptr);
      glEnableVertexAttribArray(0);
      glBindBuffer(GL_ARRAY_BUFFER, 0);
    } else if (c.name == "ssbo-ssbo-vs") {
      program = Link(GL_VERTEX_SHADER,
                     std::string(kHeader) +
                         "layout(std430, binding = 0) readonly buffer In { float v[]; };\n"
                         "layout(std430, binding = 1) writeonly buffer Out { float o[]; };\n"
                         "void main() { int i = 3 * gl_VertexID; o[i] = v[i]; o[i + 1] = v[i + 1]; o[i + 2] = v[i + 2];"
                         " gl_Position = vec4(0.0); }\n",
                     false);
    } else if (c.name == "compute-copy") {
      program = Link(GL_COMPUTE_SHADER,
                     std::string(kHeader) +
                         "layout(local_size_x = 256) in;\nuniform uint n;\n"
                         "layout(std430, binding = 0) readonly buffer In { float v[]; };\n"
                         "layout(std430, binding = 1) writeonly buffer Out { float o[]; };\n"
                         "void main() { uint k = gl_GlobalInvocationID.x; if (k >= n) return; uint i = 3u * k;"
                         " o[i] = v[i]; o[i + 1u] = v[i + 1u]; o[i + 2u] = v[i + 2u]; }\n",
                     false);
      const GLuint groups = static_cast<GLuint>((n_ + 255) / 256);
      draw = [groups] { glDispatchCompute(groups, 1, 1); };
    }
    if (!draw) {
      if (capture)
        draw = [n] {
          glBeginTransformFeedback(GL_POINTS);
          glDrawArrays(GL_POINTS, 0, n);
          glEndTransformFeedback();
        };
      else
        draw = [n] { glDrawArrays(GL_POINTS, 0, n); };
    }
    glUseProgram(program);
    if (c.name == "compute-copy") glUniform1ui(glGetUniformLocation(program, "n"), static_cast<GLuint>(n_));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, in_);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, out_);
    glBindTransformFeedback(GL_TRANSFORM_FEEDBACK, xfb_);
    glBindBufferBase(GL_TRANSFORM_FEEDBACK_BUFFER, 0, out_);
    if (c.name == "points-raster") glDisable(GL_RASTERIZER_DISCARD); else glEnable(GL_RASTERIZER_DISCARD);
    Check("binding " + c.name);

    // Correctness first: one draw into a poisoned output.
    if (c.copy) {
      std::vector<float> poison(n_ * 3, -1.0f);
      glBindBuffer(GL_COPY_WRITE_BUFFER, out_);
      glBufferSubData(GL_COPY_WRITE_BUFFER, 0, static_cast<GLsizeiptr>(poison.size() * 4), poison.data());
      draw();
      glMemoryBarrier(GL_ALL_BARRIER_BITS);
      std::vector<float> got(n_ * 3);
      glGetBufferSubData(GL_COPY_WRITE_BUFFER, 0, static_cast<GLsizeiptr>(got.size() * 4), got.data());
      glBindBuffer(GL_COPY_WRITE_BUFFER, 0);
      if (got != input_) throw std::runtime_error(c.name + ": output differs from the input");
    }
    Check("checking " + c.name);

    // Warm for 300 ms of host time (the NVIDIA GL driver lowers the clock
    // between short bursts of work), then time.
    const auto start = std::chrono::steady_clock::now();
    while (std::chrono::steady_clock::now() - start < std::chrono::milliseconds(300)) {
      for (int d = 0; d < draws_; ++d) draw();
      glFinish();
    }
    std::vector<GLuint> queries(5);
    glGenQueries(static_cast<GLsizei>(queries.size()), queries.data());
    double host_best = 1e300;
    for (GLuint query : queries) {
      const auto t0 = std::chrono::steady_clock::now();
      glBeginQuery(GL_TIME_ELAPSED, query);
      for (int d = 0; d < draws_; ++d) draw();
      glEndQuery(GL_TIME_ELAPSED);
      glFinish();
      const std::chrono::duration<double, std::milli> wall = std::chrono::steady_clock::now() - t0;
      host_best = std::min(host_best, wall.count() / draws_);
    }
    double best = 1e300;
    for (GLuint query : queries) {
      GLuint64 ns = 0;
      glGetQueryObjectui64v(query, GL_QUERY_RESULT, &ns);
      best = std::min(best, static_cast<double>(ns) * 1e-6 / draws_);
    }
    glDeleteQueries(static_cast<GLsizei>(queries.size()), queries.data());
    host_ms_ = host_best;
    glDisable(GL_RASTERIZER_DISCARD);
    glBindTransformFeedback(GL_TRANSFORM_FEEDBACK, 0);
    glUseProgram(0);
    glBindVertexArray(0);
    glDeleteProgram(program);
    Check("timing " + c.name);
    if (!(best >= 0) || best >= 1e300 || !(host_best > 0)) throw std::runtime_error(c.name + ": impossible time");
    return best;
  }

 private:
  std::size_t n_;
  int draws_;
  double host_ms_ = 0;
  std::vector<float> input_;
  GLuint in_ = 0, out_ = 0, vao_ = 0, xfb_ = 0, renderbuffer_ = 0, framebuffer_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"skintune_bench_glvertex: the GLSL vertex-shader path taken apart stage by stage (GL timer queries)"};
  std::vector<std::size_t> sizes = {100000, 400000, 1600000, 6400000};
  int draws = 20;
  std::string json_path;
  std::vector<std::string> only;
  app.add_option("--vertices", sizes, "vertex counts to probe")->delimiter(',');
  app.add_option("--draws", draws, "draws per timed burst")->check(CLI::Range(1, 1000));
  app.add_option("--case", only, "only these cases (default: all)")->delimiter(',');
  app.add_option("--json", json_path, "also write the results here");
  CLI11_PARSE(app, argc, argv);
  for (const std::string& name : only)
    if (std::none_of(kCases.begin(), kCases.end(), [&](const Case& c) { return c.name == name; })) {
      std::fprintf(stderr, "skintune_bench_glvertex: --case %s: no such case\n", name.c_str());
      return 2;
    }
  for (std::size_t n : sizes)
    if (n < 64 || n > 100000000) {
      std::fprintf(stderr, "skintune_bench_glvertex: --vertices %zu: outside 64..100000000\n", n);
      return 2;
    }

  GlContext context;
  if (!context.ok()) {
    std::fprintf(stderr, "skintune_bench_glvertex: no GL 4.3 context: %s\n", context.reason().c_str());
    return 1;
  }
  std::printf("GL_RENDERER %s, GL_VERSION %s\n", context.info().renderer.c_str(), context.info().version.c_str());
  nlohmann::json out = {{"renderer", context.info().renderer}, {"version", context.info().version}, {"results", nlohmann::json::array()}};
  try {
    for (std::size_t n : sizes) {
      Probe probe(n, draws);
      std::printf("\n%zu vertices\n%-18s %10s %10s %9s %9s  %s\n", n, "case", "gpu ms", "host ms", "ns/vert", "GB/s",
                  "what (per draw; ns/vert and GB/s from the GPU time)");
      for (const Case& c : kCases) {
        if (!only.empty() && std::find(only.begin(), only.end(), c.name) == only.end()) continue;
        const double ms = probe.Run(c);
        const double gbs = c.bytes_per_vertex ? static_cast<double>(c.bytes_per_vertex * n) / (ms * 1e6) : 0;
        std::printf("%-18s %10.4f %10.4f %9.3f %9.1f  %s\n", c.name.c_str(), ms, probe.host_ms(),
                    ms * 1e6 / static_cast<double>(n), gbs, c.what.c_str());
        std::fflush(stdout);
        out["results"].push_back({{"case", c.name}, {"vertices", n}, {"ms", ms}, {"host_ms", probe.host_ms()}, {"ns_per_vertex", ms * 1e6 / n}, {"gbs", gbs}});
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "skintune_bench_glvertex: %s\n", e.what());
    return 1;
  }
  if (!json_path.empty()) {
    if (FILE* f = std::fopen(json_path.c_str(), "w")) {
      std::fputs(out.dump(1).c_str(), f);
      std::fclose(f);
    }
  }
  return 0;
}
