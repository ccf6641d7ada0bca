// skintune_bench_glupload: can GL overlap a palette upload with the kernel
// before it? (On the H100, 2026-11, GL's pipelined frame was ~2x its Skin-only frame,
// because its one queue runs each 236 KB upload after the dispatch before it.)
//
// A stand-in for the crowd frame on one EGL context: a compute dispatch that
// streams --mib MiB (read + write) and reads the whole of a 236 544-byte
// palette (64 x 77 mat3x4), with a ring of 3 palette buffers and 3
// persistently mapped staging buffers. Per frame, in each mode:
//
//   dispatch-only   the dispatch alone (palette slot 0, no upload): the floor;
//   same            the host fills staging slot f % 3, glCopyBufferSubData into
//                   palette slot f % 3, the dispatch reads it: one context, one
//                   thread (what skintune's GL Skinner does);
//   same-nofill     the same without the host's fill (the staging filled once);
//   shared          a second context, shared with the first, on a thread of its
//                   own makes the fill, the copy and a fence; the first waits for
//                   that fence on the GPU (glWaitSync) before the dispatch; the
//                   slot is reused once the dispatch three frames back is done
//                   (a fence the first context makes after each dispatch);
//   shared-nofill   the same without the fill;
//   kcopy           as same, the copy made by a compute dispatch that reads the
//                   staging as a storage buffer (the GPU's cores read the host
//                   memory over PCIe, no copy command);
//   direct          no staging and no copy: the palette ring's buffers are
//                   themselves persistently mapped, the host fills slot f % 3
//                   and the dispatch reads it where the driver placed it;
//   direct-nofill   the same without the fill.
//
// The frames' output is checked after each run (the last frame's palette value
// in every output element that reads it). Each mode runs --frames frames after
// 100 untimed ones, wall time to a glFinish, --repeat times interleaved; the
// median us per frame is printed. Needs a GL 4.3 context (EGL) and
// EGL_KHR_surfaceless_context.
#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "gl_probe_shaders.h"
#include "runtime/backends/gl/gl_context.h"

namespace {

using Clock = std::chrono::steady_clock;
constexpr std::size_t kPaletteBytes = 236544;
constexpr std::size_t kPaletteVec4 = kPaletteBytes / 16;
constexpr int kSlots = 3;

using skintune::internal::bench::Check;
using skintune::internal::bench::Link;

const char* kShader = R"(#version 430
layout(local_size_x = 256) in;
layout(std430, binding = 0) readonly buffer In { vec4 a[]; };
layout(std430, binding = 1) writeonly buffer Out { vec4 b[]; };
layout(std430, binding = 2) readonly buffer Pal { vec4 p[]; };
uniform uint n;
void main() {
  uint i = gl_GlobalInvocationID.x;
  if (i < n) b[i] = a[i] + p[i % )" "14784" R"(u];
}
)";

const char* kCopyShader = R"(#version 430
layout(local_size_x = 256) in;
layout(std430, binding = 3) readonly buffer From { vec4 from[]; };
layout(std430, binding = 4) writeonly buffer To { vec4 to[]; };
void main() {
  uint i = gl_GlobalInvocationID.x;
  if (i < 14784u) to[i] = from[i];
}
)";

struct Gl {
  GLuint program = 0, copy = 0, in = 0, out = 0;
  GLuint palette[kSlots] = {}, staging[kSlots] = {}, direct[kSlots] = {};
  float* mapped[kSlots] = {};
  float* direct_mapped[kSlots] = {};
  std::size_t n = 0;  // vec4 elements
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext main = EGL_NO_CONTEXT, second = EGL_NO_CONTEXT;
};

void Setup(Gl& gl, std::size_t mib) {
  gl.n = mib * 1024 * 1024 / 32;  // read 16 + write 16 bytes an element
  gl.program = Link(GL_COMPUTE_SHADER, kShader);
  gl.copy = Link(GL_COMPUTE_SHADER, kCopyShader);
  std::vector<float> input(gl.n * 4);
  for (std::size_t i = 0; i < gl.n; ++i)
    for (int c = 0; c < 4; ++c) input[4 * i + c] = static_cast<float>(i % 1024);
  glCreateBuffers(1, &gl.in);
  glNamedBufferStorage(gl.in, static_cast<GLsizeiptr>(gl.n * 16), input.data(), 0);
  glCreateBuffers(1, &gl.out);
  glNamedBufferStorage(gl.out, static_cast<GLsizeiptr>(gl.n * 16), nullptr, GL_DYNAMIC_STORAGE_BIT);
  const GLbitfield map = GL_MAP_WRITE_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
  for (int s = 0; s < kSlots; ++s) {
    glCreateBuffers(1, &gl.palette[s]);
    glNamedBufferStorage(gl.palette[s], kPaletteBytes, nullptr, 0);
    glCreateBuffers(1, &gl.staging[s]);
    glNamedBufferStorage(gl.staging[s], kPaletteBytes, nullptr, map | GL_CLIENT_STORAGE_BIT);
    gl.mapped[s] = static_cast<float*>(glMapNamedBufferRange(gl.staging[s], 0, kPaletteBytes, map));
    std::fill(gl.mapped[s], gl.mapped[s] + kPaletteBytes / 4, 0.0f);
    glCopyNamedBufferSubData(gl.staging[s], gl.palette[s], 0, 0, kPaletteBytes);
    glCreateBuffers(1, &gl.direct[s]);
    glNamedBufferStorage(gl.direct[s], kPaletteBytes, nullptr, map);
    gl.direct_mapped[s] = static_cast<float*>(glMapNamedBufferRange(gl.direct[s], 0, kPaletteBytes, map));
    std::fill(gl.direct_mapped[s], gl.direct_mapped[s] + kPaletteBytes / 4, 0.0f);
  }
  glFinish();
  Check("setup");
  gl.display = eglGetCurrentDisplay();
  gl.main = eglGetCurrentContext();
  EGLint config_id = 0;
  eglQueryContext(gl.display, gl.main, EGL_CONFIG_ID, &config_id);
  EGLConfig config = EGL_NO_CONFIG_KHR;
  if (config_id != 0) {
    const EGLint attributes[] = {EGL_CONFIG_ID, config_id, EGL_NONE};
    EGLint count = 0;
    eglChooseConfig(gl.display, attributes, &config, 1, &count);
  }
  // A shared context must have the reset notification strategy of the one it
  // shares with (skintune's asks for EGL_LOSE_CONTEXT_ON_RESET where offered).
  GLint strategy = GL_NO_RESET_NOTIFICATION;
  glGetIntegerv(GL_RESET_NOTIFICATION_STRATEGY, &strategy);
  const EGLint reset = strategy == GL_LOSE_CONTEXT_ON_RESET ? EGL_LOSE_CONTEXT_ON_RESET : EGL_NO_RESET_NOTIFICATION;
  const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 3,
                                       EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                       EGL_CONTEXT_OPENGL_RESET_NOTIFICATION_STRATEGY, reset, EGL_NONE};
  gl.second = eglCreateContext(gl.display, config, gl.main, context_attributes);
  if (gl.second == EGL_NO_CONTEXT) throw std::runtime_error("eglCreateContext (shared) failed: " + std::to_string(eglGetError()));
}

void Dispatch(const Gl& gl, int slot, bool direct = false) {
  glUseProgram(gl.program);
  glUniform1ui(glGetUniformLocation(gl.program, "n"), static_cast<GLuint>(gl.n));
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, gl.in);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, gl.out);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, direct ? gl.direct[slot] : gl.palette[slot]);
  glDispatchCompute(static_cast<GLuint>((gl.n + 255) / 256), 1, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
}

void Fill(const Gl& gl, int slot, float value, bool fill) {
  if (fill) std::fill(gl.mapped[slot], gl.mapped[slot] + kPaletteBytes / 4, value);
}

// The last frame's value in every element (which reads the palette's element i % 14784).
void Verify(const Gl& gl, float value, const char* mode) {
  std::vector<float> out(kPaletteVec4 * 4);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  glGetNamedBufferSubData(gl.out, 0, static_cast<GLsizeiptr>(out.size() * 4), out.data());
  for (std::size_t i = 0; i < kPaletteVec4; ++i) {
    const float expected = static_cast<float>(i % 1024) + value;
    if (out[4 * i] != expected)
      throw std::runtime_error(std::string(mode) + ": element " + std::to_string(i) + " is " + std::to_string(out[4 * i]) +
                               ", expected " + std::to_string(expected));
  }
}

enum class Mode { kDispatchOnly, kSame, kShared, kKernelCopy, kDirect };

// Runs `frames` frames (after `untimed`), checks the last frame's output
// (Verify, as `name`); returns us per timed frame.
double Run(Gl& gl, const char* name, Mode mode, bool fill, int untimed, int frames, int run) {
  const int total = untimed + frames;
  const auto value = [&](int f) { return static_cast<float>((f + run * 7) % 1000); };
  // Without a fill the staging keeps the value written before the run.
  if (!fill)
    for (int s = 0; s < kSlots; ++s) {
      std::fill(gl.mapped[s], gl.mapped[s] + kPaletteBytes / 4, 5.0f);
      std::fill(gl.direct_mapped[s], gl.direct_mapped[s] + kPaletteBytes / 4, 5.0f);
    }
  Clock::time_point start;
  float last = 0.0f;
  if (mode == Mode::kDispatchOnly) {
    for (int f = 0; f < total; ++f) {
      if (f == untimed) {
        glFinish();
        start = Clock::now();
      }
      Dispatch(gl, 0);
    }
    glFinish();
    std::vector<float> p(4);  // palette slot 0: whatever the last upload left there
    glGetNamedBufferSubData(gl.palette[0], 0, 16, p.data());
    last = p[0];
  } else if (mode == Mode::kSame || mode == Mode::kKernelCopy || mode == Mode::kDirect) {
    GLsync done[kSlots] = {};
    for (int f = 0; f < total; ++f) {
      if (f == untimed) {
        glFinish();
        start = Clock::now();
      }
      const int slot = f % kSlots;
      if (done[slot]) {
        glClientWaitSync(done[slot], GL_SYNC_FLUSH_COMMANDS_BIT, GLuint64{10000000000});
        glDeleteSync(done[slot]);
        done[slot] = nullptr;
      }
      if (mode == Mode::kDirect) {
        if (fill) std::fill(gl.direct_mapped[slot], gl.direct_mapped[slot] + kPaletteBytes / 4, value(f));
        Dispatch(gl, slot, true);
      } else {
        Fill(gl, slot, value(f), fill);
        if (mode == Mode::kSame) {
          glCopyNamedBufferSubData(gl.staging[slot], gl.palette[slot], 0, 0, kPaletteBytes);
        } else {
          glUseProgram(gl.copy);
          glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, gl.staging[slot]);
          glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, gl.palette[slot]);
          glDispatchCompute(static_cast<GLuint>((kPaletteVec4 + 255) / 256), 1, 1);
          glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
        }
        Dispatch(gl, slot);
      }
      done[slot] = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
      glFlush();
    }
    glFinish();
    for (GLsync s : done)
      if (s) glDeleteSync(s);
    last = fill ? value(total - 1) : 5.0f;
  } else {
    // Slot handshakes: uploaded[f % 3] holds frame f's upload fence once made;
    // consumed[f % 3] the dispatch fence of the frame that last read the slot.
    std::atomic<GLsync> uploaded[kSlots] = {};
    std::atomic<GLsync> consumed[kSlots] = {};
    std::atomic<int> uploaded_frames{0}, consumed_frames{0};
    std::atomic<bool> failed{false};
    std::thread uploader([&] {
      if (!eglMakeCurrent(gl.display, EGL_NO_SURFACE, EGL_NO_SURFACE, gl.second)) {
        failed = true;
        return;
      }
      for (int f = 0; f < total && !failed; ++f) {
        const int slot = f % kSlots;
        if (f >= kSlots) {
          while (consumed_frames.load(std::memory_order_acquire) < f - kSlots + 1 && !failed) std::this_thread::yield();
          const GLsync d = consumed[slot].exchange(nullptr);
          glClientWaitSync(d, 0, GLuint64{10000000000});
          glDeleteSync(d);
        }
        Fill(gl, slot, value(f), fill);
        glCopyNamedBufferSubData(gl.staging[slot], gl.palette[slot], 0, 0, kPaletteBytes);
        uploaded[slot] = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
        glFlush();
        uploaded_frames.store(f + 1, std::memory_order_release);
      }
      glFinish();
      eglMakeCurrent(gl.display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    });
    for (int f = 0; f < total; ++f) {
      if (f == untimed) {
        glFinish();
        start = Clock::now();
      }
      const int slot = f % kSlots;
      while (uploaded_frames.load(std::memory_order_acquire) < f + 1 && !failed) std::this_thread::yield();
      if (failed) break;
      const GLsync u = uploaded[slot].exchange(nullptr);
      glWaitSync(u, 0, GL_TIMEOUT_IGNORED);
      glDeleteSync(u);
      Dispatch(gl, slot);
      consumed[slot] = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
      glFlush();
      consumed_frames.store(f + 1, std::memory_order_release);
    }
    glFinish();
    uploader.join();
    if (failed) throw std::runtime_error("the second context could not be made current");
    for (auto& c : consumed)
      if (GLsync s = c.exchange(nullptr)) glDeleteSync(s);
    last = fill ? value(total - 1) : 5.0f;
  }
  const double us = std::chrono::duration<double, std::micro>(Clock::now() - start).count() / frames;
  Check("run");
  Verify(gl, last, name);
  return us;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"skintune_bench_glupload: a palette upload beside the kernel in GL, one context or two"};
  std::size_t mib = 48;
  int frames = 2000, repeat = 3;
  app.add_option("--mib", mib, "MiB the dispatch reads and writes")->check(CLI::Range(1, 4096));
  app.add_option("--frames", frames, "timed frames per run")->check(CLI::Range(10, 1000000));
  app.add_option("--repeat", repeat, "runs of each mode, interleaved")->check(CLI::Range(1, 100));
  CLI11_PARSE(app, argc, argv);
  skintune::internal::GlContext context;
  if (!context.ok()) {
    std::fprintf(stderr, "skintune_bench_glupload: no GL 4.3 context: %s\n", context.reason().c_str());
    return 1;
  }
  try {
    Gl gl;
    Setup(gl, mib);
    std::printf("%s | %s; dispatch of %zu MiB, palette %zu bytes, %d frames\n", context.info().renderer.c_str(),
                context.info().version.c_str(), mib, kPaletteBytes, frames);
    struct Case {
      const char* name;
      Mode mode;
      bool fill;
    };
    const Case cases[] = {{"dispatch-only", Mode::kDispatchOnly, false}, {"same", Mode::kSame, true},
                          {"same-nofill", Mode::kSame, false},          {"shared", Mode::kShared, true},
                          {"shared-nofill", Mode::kShared, false},      {"kcopy", Mode::kKernelCopy, true},
                          {"direct", Mode::kDirect, true},              {"direct-nofill", Mode::kDirect, false}};
    std::vector<std::vector<double>> us(std::size(cases));
    for (int r = 0; r < repeat; ++r)
      for (std::size_t c = 0; c < std::size(cases); ++c)
        us[c].push_back(Run(gl, cases[c].name, cases[c].mode, cases[c].fill, 100, frames, r));
    for (std::size_t c = 0; c < std::size(cases); ++c) {
      std::vector<double> v = us[c];
      std::sort(v.begin(), v.end());
      std::printf("%-14s median %7.2f us per frame (runs:", cases[c].name, v[v.size() / 2]);
      for (double x : us[c]) std::printf(" %.2f", x);
      std::printf(")\n");
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "skintune_bench_glupload: %s\n", e.what());
    return 1;
  }
  return 0;
}
