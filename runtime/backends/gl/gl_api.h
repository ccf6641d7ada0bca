// skintune (internal to runtime/backends/gl/): the GL DeviceApi
// (runtime/device_api.h) shared by gl_runner.cpp (programs, buffers,
// bindings) and gl_frames.cpp (draws, dispatches, timers, the copy shader),
// and the GL object helpers both use. Every call needs the context current:
// the driver calls MakeCurrent() first.
#pragma once

#include <epoxy/gl.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "runtime/backends/gl/gl_context.h"
#include "runtime/device_api.h"

namespace skintune::internal::gl {

[[noreturn]] void Fail(const std::string& stage, const std::string& message);
// Throws when GL recorded an error since the last check (all pending errors
// named); GL_CONTEXT_LOST among them throws stage "lost" with the driver's
// reason (the context was reset: nothing it runs from now on happens).
void CheckGl(const std::string& stage, const std::string& what);
// Throws stage "lost" when the driver has reset the current context (GL 4.5's
// glGetGraphicsResetStatus; a context made without reset notification never
// reports one).
void CheckReset(const std::string& what);
void ClearGlErrors();

// Owns one GL object name; deleted with its glDelete* (the context must be current).
class GlObject {
 public:
  using Deleter = void (*)(GLuint);
  GlObject() = default;
  GlObject(GLuint id, Deleter deleter) : id_(id), deleter_(deleter) {}
  ~GlObject() { reset(); }
  GlObject(GlObject&& other) noexcept : id_(other.id_), deleter_(other.deleter_) { other.id_ = 0; }
  GlObject& operator=(GlObject&& other) noexcept {
    if (this != &other) {
      reset();
      id_ = other.id_;
      deleter_ = other.deleter_;
      other.id_ = 0;
    }
    return *this;
  }
  GlObject(const GlObject&) = delete;
  GlObject& operator=(const GlObject&) = delete;
  GLuint get() const { return id_; }
  void reset() {
    if (id_ && deleter_) deleter_(id_);
    id_ = 0;
  }
  // Gives the name up without deleting it (when no context can be made current).
  void forget() { id_ = 0; }
  // Deletes the name when its context is current, else gives it up: a GL call
  // with no current context aborts inside libepoxy.
  void release(bool context_current) {
    if (context_current) reset(); else forget();
  }

 private:
  GLuint id_ = 0;
  Deleter deleter_ = nullptr;
};

GlObject NewBuffer(std::size_t bytes, const void* data, const std::string& what);
GlObject NewQuery();

// Host-visible staging of a buffer: persistently mapped (glBufferStorage,
// GL 4.4 or ARB_buffer_storage; `map` null without it).
struct GlStaging {
  GlObject buffer;
  void* map = nullptr;
  std::vector<std::uint8_t> copy;  // the bytes themselves without buffer storage
};

// A buffer, or the texture buffer over the palette (`image` storage); a
// palette also keeps the staging of its uploads (Write), an output that of
// its read-backs (ReadPinned).
class GlBuffer final : public DeviceBuffer {
 public:
  GlBuffer(GlObject o, std::size_t bytes) : DeviceBuffer(bytes), object(std::move(o)) {}
  void* native() const override { return reinterpret_cast<void*>(static_cast<std::uintptr_t>(object.get())); }
  void Forget() override {
    object.forget();
    if (upload) upload->buffer.forget();
    if (readback) readback->buffer.forget();
    read_fences.clear();
  }
  GLuint id() const { return object.get(); }
  GlObject object;
  std::unique_ptr<GlStaging> upload;
  mutable std::unique_ptr<GlStaging> readback;
  mutable std::vector<GLsync> read_fences;  // ReadPinnedChunks': one per chunk, of the last read
  ~GlBuffer() override { DeleteReadFences(); }
  void DeleteReadFences() const {
    for (GLsync fence : read_fences) glDeleteSync(fence);
    read_fences.clear();
  }
};

// The palette ring's fence: a fence sync.
class GlFence final : public DeviceObject {
 public:
  explicit GlFence(GLsync s) : sync(s) {}
  ~GlFence() override {
    if (sync) glDeleteSync(sync);
  }
  void Forget() override { sync = nullptr; }
  GLsync sync = nullptr;
};

// Where the transform feedback of one glsl-vertex launch goes. An instanced
// draw captures its K instances one after another, n vertices each: straight
// into the outputs at `first` when they lie that way there too (one instance,
// or one draw for the whole mesh), else into a staging buffer whose K parts
// are then copied to i * vertex_count + first (glCopyBufferSubData).
struct CapturePlan {
  bool staged = false;
  std::size_t offset = 0, bytes = 0;  // the capture range: in the outputs, or the whole staging buffer
  struct Copy {
    std::size_t from = 0, to = 0, bytes = 0;
  };
  std::vector<Copy> copies;  // staging -> outputs, when staged
};

class GlPlanned final : public PlannedLaunch {
 public:
  using PlannedLaunch::PlannedLaunch;
  bool vertex = false;
  GLuint program = 0;  // owned by the API
  GLint n_location = -1, first_location = -1, vertex_count_location = -1;
  // A prologue's scalars (the palette kernel's delta and fresh): uniforms set
  // from the frame's run at each launch; location -1 where the compiler dropped one.
  struct Scalar {
    std::string name;
    GLint location = -1;
    bool f32 = false;
  };
  std::vector<Scalar> scalars;
  std::size_t groups = 0;  // glsl-compute
  std::array<CapturePlan, kOutputCount> captures;  // glsl-vertex, by Output (each output's own stride)
};

// One launch of one set: what to bind where, and the staged captures.
class GlBound final : public DeviceObject {
 public:
  enum class Target { kUniform, kStorage, kTexture, kFeedback };
  struct Binding {
    const std::string* name = nullptr;  // the kernel argument
    Target target = Target::kStorage;
    GLuint index = 0;  // binding point, texture unit or feedback buffer
    GLuint object = 0;
    GLintptr offset = 0;
    GLsizeiptr size = 0;  // kFeedback: the capture range
  };
  struct Staged {
    GLuint staging = 0, out = 0;
    const CapturePlan* capture = nullptr;  // the output's
  };
  void Forget() override {
    for (GlObject& o : staging) o.forget();
  }
  const GlPlanned* plan = nullptr;
  std::vector<Binding> bindings;
  std::vector<Staged> staged;    // positions (and normals) when the capture is staged
  std::vector<GlObject> staging;  // their buffers
};

struct BuiltProgram {
  GlObject program;
  GLint n_location = -1;
  GLint first_location = -1;
  GLint vertex_count_location = -1;  // instanced glsl-compute
};

class GlApi final : public DeviceApi {
 public:
  explicit GlApi(std::unique_ptr<GlContext> context) : context_(std::move(context)) {}
  ~GlApi() override;

  const GlContextInfo& info() const { return context_->info(); }
  // Whether frames and copies are timed with the host clock (software renderers).
  bool host_timed() const;

  const char* name() const override { return "GL"; }
  const std::string& device_name() const override { return info().renderer; }
  void MakeCurrent() override { context_->MakeCurrent(); }
  bool ReadyToRelease() override;
  void Build(const KernelSource& source) override { ProgramFor(source); }
  void CheckRun(const PackedMesh& mesh, std::span<const KernelSource> kernels, const RunShape& shape) const override;
  std::size_t PaletteBufferBytes(const RunShape& shape, std::span<const KernelSource> kernels) const override;
  const char* OutputWriter(const Variant& variant) const override;
  std::unique_ptr<PlannedLaunch> Plan(const LaunchSpec& spec) override;
  std::unique_ptr<DeviceBuffer> Allocate(BufferUse use, std::size_t bytes, const void* initial,
                                         const std::string& what) override;
  std::unique_ptr<DeviceObject> PaletteView(const Variant& variant, DeviceBuffer& palette,
                                            const std::string& suffix) override;
  std::unique_ptr<DeviceObject> Bind(const PlannedLaunch& launch, std::span<const ArgumentBinding> arguments,
                                     const SetOptions& options, std::size_t& allocated) override;
  void FinishUploads(const std::string& key) override;
  std::vector<std::vector<double>> RunFrames(const FrameRun& run) override;
  TimingPolicy timing_policy() const override { return {!host_timed()}; }
  std::string kernel_clock() const override {
    return host_timed() ? "the host's clock between glFinish calls" : "GL_TIMESTAMP query counters";
  }
  std::span<std::uint8_t> Staging(DeviceBuffer& buffer, const std::string& key, bool upload_fenced) override;
  void Upload(DeviceBuffer& buffer, std::size_t bytes, const std::string& key) override;
  void Read(const DeviceBuffer& buffer, std::span<std::uint8_t> out, const std::string& what, bool wait) override;
  std::span<const std::uint8_t> ReadPinned(const DeviceBuffer& buffer, std::size_t bytes,
                                           const std::string& what) override;
  // One GPU copy and one fence per chunk into the persistently mapped
  // read-back buffer (at most 16 chunks); `caller_only`: the fences are
  // waited for on the context's thread, chunk after chunk, while the host
  // pool works on the chunks already in. ReadPinned without buffer storage.
  PinnedRead ReadPinnedChunks(const DeviceBuffer& buffer, std::size_t bytes, std::size_t chunk,
                              const std::string& what) override;
  void Mark(std::unique_ptr<DeviceObject>& marker, const std::string& what) override;
  void Wait(DeviceObject& marker, const std::string& what) override;
  // A fence sync waited for (WaitFence), glFinish without one.
  void Finish() override;
  // glCopyBufferSubData into a palette after the dispatches and draws that
  // read it: GL orders them (a Skin without SetPalette then needs no fence:
  // glFenceSync and its flush cost 7-10 us a frame on NVIDIA).
  bool OrdersUploadsAfterLaunches() const override { return true; }
  // Whether staging buffers are persistently mapped (GL 4.4 or
  // ARB_buffer_storage, unless $SKINTUNE_GL_NO_BUFFER_STORAGE=1 asks for the
  // glBufferSubData / glGetBufferSubData path).
  bool persistent_staging() const;
  // The barriers ReadyForReads issued so far (tests).
  std::uint64_t read_barriers() const { return read_barriers_; }

 private:
  const BuiltProgram& ProgramFor(const KernelSource& source);
  GlObject ProgramFromSource(const KernelSource& source, const std::vector<const char*>& varyings,
                             const std::string& what);
  // A program from the cache's binary (0 when absent, unsupported or refused).
  GLuint ProgramFromBinary(const std::string& cache_key);
  void StoreBinary(GLuint program, const std::string& cache_key);
  void CheckCapturedTypes(const KernelSource& source, GLuint program, const std::vector<const char*>& varyings,
                          const std::string& what);
  // glsl-vertex: an empty vertex array, a 1x1 framebuffer (a surfaceless
  // context has no complete default framebuffer, and draws need one even with
  // rasterisation discarded) and a transform feedback object; the draw state
  // of glsl-vertex launches (vertex array, framebuffer, rasteriser discard,
  // transform feedback object), and back to none.
  void PrepareVertexState();
  void BeginVertexDraws();
  void EndVertexDraws(const Variant& variant);
  std::vector<std::vector<double>> RunVerified(const FrameRun& run);
  std::vector<std::vector<double>> RunTimed(const FrameRun& run);
  std::vector<std::vector<double>> RunCold(const FrameRun& run);
  void RunLive(const FrameRun& run);
  // The barrier that makes live frames' outputs readable by anything (reads,
  // copies, draws), where RunLive left it to the next call that could read
  // them: the reads, Finish and the timed runs call this first. (Uploads go
  // only into buffers no kernel writes: palettes, instances, morph weights.)
  void ReadyForReads();

  std::unique_ptr<GlContext> context_;  // declared first: destroyed after every GL object below
  bool frames_unread_ = false;  // RunLive issued frames since the last ReadyForReads
  std::uint64_t read_barriers_ = 0;
  std::map<std::string, BuiltProgram> built_;  // by source hash
  GlObject vertex_array_, framebuffer_, renderbuffer_, transform_feedback_;
  // RunCold's GL_TIMESTAMP queries (a timed frame's: one after the flush,
  // one after each launch), kept between calls (each result is read before
  // the call returns) and grown as needed.
  std::vector<GlObject> cold_queries_;
};

}  // namespace skintune::internal::gl
