// The GL DeviceApi (gl_api.h), part two: running frames. A launch binds its
// program, uniforms and buffers, then draws (glsl-vertex: transform feedback
// with rasterisation discarded, staged captures copied into place) or
// dispatches (glsl-compute). Run's frame is checked call by call and counts
// the captured points; Time's bursts are timed by GL_TIME_ELAPSED queries,
// or by the host clock on software renderers; the kernel time's frames
// (kCold) run after the flush, each launch between GL_TIMESTAMP counters;
// the Skinner's frame puts back the GL state it changed on the caller's
// context.
#include <algorithm>
#include <bit>
#include <cctype>
#include <chrono>

#include "base/error.h"
#include "runtime/backends/gl/gl_api.h"

namespace skintune::internal::gl {

namespace {

// Mesa's software renderers answer GL_TIME_ELAPSED from their rasteriser
// threads, which neither compute dispatches nor vertex processing with
// rasterisation discarded pass through: their queries read ~0. There each
// launch is timed by the host clock between two glFinish calls instead.
bool HostClockTimesLaunches(const GlContextInfo& info) {
  std::string renderer = info.renderer;
  std::transform(renderer.begin(), renderer.end(), renderer.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (const char* software : {"llvmpipe", "softpipe", "swrast"})
    if (renderer.find(software) != std::string::npos) return true;
  return false;
}

// Times `launch` on the host clock between glFinish calls, in ms.
template <typename F>
double HostMs(F&& launch) {
  glFinish();
  const auto start = std::chrono::steady_clock::now();
  launch();
  glFinish();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

double QueryMs(const GlObject& query) {
  GLuint64 elapsed = 0;
  glGetQueryObjectui64v(query.get(), GL_QUERY_RESULT, &elapsed);
  return static_cast<double>(elapsed) * 1e-6;
}

void CopyStagedCapture(GLuint staging, GLuint out, const CapturePlan& c) {
  glBindBuffer(GL_COPY_READ_BUFFER, staging);
  glBindBuffer(GL_COPY_WRITE_BUFFER, out);
  for (const CapturePlan::Copy& copy : c.copies)
    glCopyBufferSubData(GL_COPY_READ_BUFFER, GL_COPY_WRITE_BUFFER, static_cast<GLintptr>(copy.from),
                        static_cast<GLintptr>(copy.to), static_cast<GLsizeiptr>(copy.bytes));
  glBindBuffer(GL_COPY_READ_BUFFER, 0);
  glBindBuffer(GL_COPY_WRITE_BUFFER, 0);
}

// Binds the launch's program, uniforms and buffers; `checked`: each binding
// checked for GL errors (Run).
void BindLaunch(const GlBound& bound, bool checked) {
  using Target = GlBound::Target;
  const GlPlanned& plan = *bound.plan;
  glUseProgram(plan.program);
  if (plan.n_location >= 0) glUniform1ui(plan.n_location, plan.spec.count);
  if (plan.first_location >= 0) glUniform1ui(plan.first_location, plan.spec.first);
  if (plan.vertex_count_location >= 0) glUniform1ui(plan.vertex_count_location, plan.spec.vertex_count);
  for (const GlBound::Binding& b : bound.bindings) {
    switch (b.target) {
      case Target::kUniform: glBindBufferBase(GL_UNIFORM_BUFFER, b.index, b.object); break;
      case Target::kStorage: glBindBufferBase(GL_SHADER_STORAGE_BUFFER, b.index, b.object); break;
      case Target::kTexture:
        glActiveTexture(GL_TEXTURE0 + b.index);
        glBindTexture(GL_TEXTURE_BUFFER, b.object);
        glActiveTexture(GL_TEXTURE0);
        break;
      case Target::kFeedback:
        glBindBufferRange(GL_TRANSFORM_FEEDBACK_BUFFER, b.index, b.object, b.offset, b.size);
        break;
    }
    if (checked) CheckGl("launch", plan.spec.where + ": binding argument '" + *b.name + "' at " + std::to_string(b.index));
  }
}

// Draws or dispatches a bound launch (the vertex draw state must be set for glsl-vertex).
void DrawLaunch(const GlBound& bound) {
  const GlPlanned& plan = *bound.plan;
  const auto instances = static_cast<GLsizei>(plan.spec.instances);
  if (plan.vertex) {
    glBeginTransformFeedback(GL_POINTS);
    if (plan.spec.instanced) {
      glDrawArraysInstanced(GL_POINTS, 0, static_cast<GLsizei>(plan.spec.count), instances);
    } else {
      glDrawArrays(GL_POINTS, 0, static_cast<GLsizei>(plan.spec.count));
    }
    glEndTransformFeedback();
    for (const GlBound::Staged& st : bound.staged) CopyStagedCapture(st.staging, st.out, *st.capture);
  } else {
    glDispatchCompute(static_cast<GLuint>(plan.groups), static_cast<GLuint>(instances), 1);
  }
}

// What Run names a launch by when it raised a GL error.
std::string Described(const GlPlanned& plan) {
  const LaunchSpec& s = plan.spec;
  if (!plan.vertex)
    return s.where + ": glDispatchCompute(" + std::to_string(plan.groups) + ", " + std::to_string(s.instances) +
           ") of groups of " + std::to_string(s.source.launch.wg_size);
  return s.where + ": glDrawArrays" + (s.instanced ? "Instanced" : "") + "(GL_POINTS, 0, " + std::to_string(s.count) +
         (s.instanced ? ", " + std::to_string(s.instances) : "") + ") captured at vertex " + std::to_string(s.first) +
         (plan.captures.front().staged ? " through a staging buffer" : "");
}

// The frames' first skin launch (an animated set's palette kernel, a compute
// dispatch before it, says nothing of whether the frames draw).
const GlPlanned* FirstPlan(const FrameRun& run) {
  for (const auto& frame : run.frames)
    for (const std::unique_ptr<DeviceObject>& launch : frame)
      if (!static_cast<const GlBound&>(*launch).plan->spec.feeds_frame) return static_cast<const GlBound&>(*launch).plan;
  return nullptr;
}

// A bound launch's scalar uniforms from `run` (the palette kernel's delta
// and fresh: FrameRun::scalars); nothing for a launch without any.
void SetScalars(const GlBound& bound, const FrameRun& run) {
  for (const GlPlanned::Scalar& scalar : bound.plan->scalars) {
    const std::uint32_t bits = ScalarOf(run, scalar.name, "GL");
    if (scalar.location < 0) continue;
    if (scalar.f32) {
      glUniform1f(scalar.location, std::bit_cast<float>(bits));
    } else {
      glUniform1ui(scalar.location, bits);
    }
  }
}

// After a launch whose writes the frame's later launches read (the palette
// kernel: LaunchSpec::feeds_frame), however they read them.
void BarrierIfItFeeds(const GlBound& bound) {
  if (bound.plan->spec.feeds_frame)
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_UNIFORM_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT);
}

// The state a Skinner's frame changes on a context the caller also draws with, put back afterwards.
class KeptGlState {
 public:
  // `vertex`: the draws change the vertex array, framebuffers, transform
  // feedback and rasteriser discard too; a dispatch only the program and
  // the active texture unit (each glGet is a round trip into the driver).
  explicit KeptGlState(bool vertex) : vertex_(vertex) {
    glGetIntegerv(GL_CURRENT_PROGRAM, &program_);
    glGetIntegerv(GL_ACTIVE_TEXTURE, &active_texture_);
    if (!vertex_) return;
    glGetIntegerv(GL_VERTEX_ARRAY_BINDING, &vertex_array_);
    glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &draw_framebuffer_);
    glGetIntegerv(GL_READ_FRAMEBUFFER_BINDING, &read_framebuffer_);
    glGetIntegerv(GL_TRANSFORM_FEEDBACK_BINDING, &transform_feedback_);
    discard_ = glIsEnabled(GL_RASTERIZER_DISCARD);
  }
  ~KeptGlState() {
    glUseProgram(static_cast<GLuint>(program_));
    glActiveTexture(static_cast<GLenum>(active_texture_));
    if (!vertex_) return;
    glBindVertexArray(static_cast<GLuint>(vertex_array_));
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, static_cast<GLuint>(draw_framebuffer_));
    glBindFramebuffer(GL_READ_FRAMEBUFFER, static_cast<GLuint>(read_framebuffer_));
    glBindTransformFeedback(GL_TRANSFORM_FEEDBACK, static_cast<GLuint>(transform_feedback_));
    if (discard_) {
      glEnable(GL_RASTERIZER_DISCARD);
    } else {
      glDisable(GL_RASTERIZER_DISCARD);
    }
  }
  KeptGlState(const KeptGlState&) = delete;
  KeptGlState& operator=(const KeptGlState&) = delete;

 private:
  bool vertex_;
  GLint program_ = 0, vertex_array_ = 0, draw_framebuffer_ = 0, read_framebuffer_ = 0, transform_feedback_ = 0;
  GLint active_texture_ = GL_TEXTURE0;
  GLboolean discard_ = GL_FALSE;
};

}  // namespace

bool GlApi::host_timed() const { return HostClockTimesLaunches(info()); }

std::vector<std::vector<double>> GlApi::RunFrames(const FrameRun& run) {
  if (run.use != FrameUse::kLive) ReadyForReads();
  switch (run.use) {
    case FrameUse::kVerify: return RunVerified(run);
    case FrameUse::kTime: return RunTimed(run);
    case FrameUse::kCold: return RunCold(run);
    case FrameUse::kLive: RunLive(run); break;
  }
  return {};
}

// Run's frame: every call checked, each launch inside a GL_TIME_ELAPSED query
// and (glsl-vertex) a GL_TRANSFORM_FEEDBACK_PRIMITIVES_WRITTEN query that must
// count every vertex of every instance.
std::vector<std::vector<double>> GlApi::RunVerified(const FrameRun& run) {
  const GlPlanned* first = FirstPlan(run);
  const bool vertex = first && first->vertex;
  if (vertex) BeginVertexDraws();
  std::vector<GlObject> timers, written;
  for (const std::unique_ptr<DeviceObject>& launch : run.frames.front()) {
    const auto& bound = static_cast<const GlBound&>(*launch);
    BindLaunch(bound, true);
    SetScalars(bound, run);
    timers.push_back(NewQuery());
    glBeginQuery(GL_TIME_ELAPSED, timers.back().get());
    const bool draws = bound.plan->vertex;
    written.push_back(draws ? NewQuery() : GlObject());
    if (draws) glBeginQuery(GL_TRANSFORM_FEEDBACK_PRIMITIVES_WRITTEN, written.back().get());
    DrawLaunch(bound);
    if (draws) glEndQuery(GL_TRANSFORM_FEEDBACK_PRIMITIVES_WRITTEN);
    glEndQuery(GL_TIME_ELAPSED);
    BarrierIfItFeeds(bound);
    CheckGl("launch", Described(*bound.plan));
  }
  if (vertex) {
    EndVertexDraws(first->spec.variant);
  } else {
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  }
  glUseProgram(0);
  glFinish();
  CheckGl("launch", "finishing " + run.key);
  CheckReset("finishing " + run.key);  // a reset context may have run nothing, and said nothing
  std::vector<double> ms;
  for (std::size_t t = 0; t < timers.size(); ++t) {
    ms.push_back(QueryMs(timers[t]));
    if (!static_cast<const GlBound&>(*run.frames.front()[t]).plan->vertex) continue;
    GLuint64 points = 0;
    glGetQueryObjectui64v(written[t].get(), GL_QUERY_RESULT, &points);
    const LaunchSpec& spec = static_cast<const GlBound&>(*run.frames.front()[t]).plan->spec;
    const std::uint64_t expected = static_cast<std::uint64_t>(spec.count) * static_cast<std::uint64_t>(spec.instances);
    if (points != expected)
      Fail("launch", spec.where + ": transform feedback captured " + std::to_string(points) + " of " +
                         std::to_string(expected) + " vertices");
  }
  CheckGl("launch", "reading the timer queries of " + run.key);
  return {ms};
}

// Time's frames: after `untimed` frames, each burst of frames inside one
// GL_TIME_ELAPSED query, or between two glFinish calls on the host clock
// (host_timed()). Nothing inside a burst waits or queries.
std::vector<std::vector<double>> GlApi::RunTimed(const FrameRun& run) {
  const GlPlanned* first = FirstPlan(run);
  const bool vertex = first && first->vertex;
  ClearGlErrors();
  if (vertex) BeginVertexDraws();
  const bool host_clock = host_timed();
  const auto untimed = static_cast<std::size_t>(std::max(run.untimed, 0));
  const auto burst = static_cast<std::size_t>(std::max(run.burst, 1));
  const std::size_t bursts = run.TimedBursts();
  const auto frame = [&](std::size_t f) {
    for (const std::unique_ptr<DeviceObject>& launch : run.frames[f]) {
      const auto& bound = static_cast<const GlBound&>(*launch);
      BindLaunch(bound, false);
      SetScalars(bound, run);
      DrawLaunch(bound);
      BarrierIfItFeeds(bound);
    }
  };
  for (std::size_t f = 0; f < untimed; ++f) frame(f);
  if (untimed > 0) CheckGl("launch", "the first frame of timing " + run.key);
  std::vector<GlObject> timers;
  std::vector<std::vector<double>> ms;
  for (std::size_t b = 0; b < bursts; ++b) {
    const auto go = [&] {
      for (std::size_t f = untimed + b * burst; f < untimed + (b + 1) * burst; ++f) frame(f);
    };
    if (host_clock) {
      ms.push_back({HostMs(go)});
    } else {
      timers.push_back(NewQuery());
      glBeginQuery(GL_TIME_ELAPSED, timers.back().get());
      go();
      glEndQuery(GL_TIME_ELAPSED);
    }
    if (b == 0) CheckGl("launch", "the first burst of timing " + run.key);
  }
  if (vertex) EndVertexDraws(first->spec.variant);
  glUseProgram(0);
  glFinish();
  CheckGl("launch", "timing " + run.key);
  CheckReset("timing " + run.key);
  for (const GlObject& query : timers) ms.push_back({QueryMs(query)});
  CheckGl("launch", "reading the timer queries of " + run.key);
  return ms;
}

// The kernel time (FrameUse::kCold, device_api.h): a launch's time runs
// from the end of the command before it (the flush, or the frame's launch
// before) to its own end. Per frame: the flush's dispatches, a barrier, a
// glQueryCounter(GL_TIMESTAMP); then per launch: bound, drawn or dispatched
// (glsl-vertex: the draw and the copies of a staged capture into place, as
// Run's and Time's queries count a launch), a barrier, a counter. Untimed
// frames run the same way without counters; each frame is waited for
// (glFinish) before the next is queued, as every API's cold frames are
// (runtime/device_api.h), then the counters are read. Software renderers
// (host_timed()): each launch between two glFinish calls on the host clock
// instead (the first waits for the command before it).
//
// What keeps the launches apart, on NVIDIA's driver as on any:
// - glQueryCounter: "the time is recorded after all previous commands on
//   the GL client and server state and the framebuffer have been fully
//   realized" (GL 4.6, 4.3 "Time Queries"), so each counter stamps the end
//   of the command before it, and the flush's time is in no launch's. (The
//   reference page's one-line summary says "have reached the GL server but
//   have not yet necessarily executed"; its description and the
//   specification say fully realized.) So n + 1 counters a frame of n
//   launches stamp the end of every command, as the other APIs' end stamps
//   do; a GL_TIME_ELAPSED query per launch starts its timer by the same
//   rule, but would stamp the end of each launch twice (its own query's
//   end, the next one's start).
// - glMemoryBarrier(GL_ALL_BARRIER_BITS) after the flush and after every
//   launch, before its counter: a counter says when it is written, not that
//   the dispatch after it waits; the barrier does: shader writes before it
//   must be complete and visible to every shader access after it, and the
//   flush has a shader store (taken only for an all-ones item, which its
//   input never holds), so no driver can tell that it writes nothing and
//   skip the wait. Without barriers consecutive dispatches may overlap
//   (Time's bursts rely on that). So a launch never runs beside the flush
//   or another launch, starts on the cache the flush left, and pays its own
//   barrier (the one that waits for it), as every launch of a dependent
//   sequence does.
std::vector<std::vector<double>> GlApi::RunCold(const FrameRun& run) {
  const GlPlanned* first = FirstPlan(run);
  const bool vertex = first && first->vertex;
  ClearGlErrors();
  const bool host_clock = host_timed();
  const std::size_t untimed = std::min(run.frames.size(), static_cast<std::size_t>(std::max(run.untimed, 0)));
  std::size_t counters = 0;
  for (std::size_t f = untimed; f < run.frames.size(); ++f) counters += 1 + run.frames[f].size();
  GLint bits = 64;
  if (!host_clock && counters > 0) {
    glGetQueryiv(GL_TIMESTAMP, GL_QUERY_COUNTER_BITS, &bits);
    if (bits <= 0)
      Fail("launch", "timing " + run.key + ": " + info().renderer + " has no GL_TIMESTAMP counter (GL_QUERY_COUNTER_BITS 0)");
    if (cold_queries_.size() < counters) {
      std::vector<GLuint> names(counters - cold_queries_.size());
      glGenQueries(static_cast<GLsizei>(names.size()), names.data());
      for (const GLuint name : names) cold_queries_.emplace_back(name, [](GLuint id) { glDeleteQueries(1, &id); });
    }
  }
  if (vertex) BeginVertexDraws();  // the flush (a compute dispatch) runs under the draw state unaffected
  std::vector<std::vector<double>> ms(run.frames.size() - untimed);
  std::size_t query = 0;
  for (std::size_t f = 0; f < run.frames.size(); ++f) {
    const bool stamped = f >= untimed && !host_clock;
    for (const std::unique_ptr<DeviceObject>& launch : run.flush) {
      BindLaunch(static_cast<const GlBound&>(*launch), false);
      DrawLaunch(static_cast<const GlBound&>(*launch));
    }
    glMemoryBarrier(GL_ALL_BARRIER_BITS);
    if (stamped) glQueryCounter(cold_queries_[query++].get(), GL_TIMESTAMP);
    for (const std::unique_ptr<DeviceObject>& launch : run.frames[f]) {
      const auto& bound = static_cast<const GlBound&>(*launch);
      BindLaunch(bound, false);
      SetScalars(bound, run);
      if (f >= untimed && host_clock) {
        ms[f - untimed].push_back(HostMs([&] {
          DrawLaunch(bound);
          glMemoryBarrier(GL_ALL_BARRIER_BITS);
        }));
        continue;
      }
      DrawLaunch(bound);
      glMemoryBarrier(GL_ALL_BARRIER_BITS);
      if (stamped) glQueryCounter(cold_queries_[query++].get(), GL_TIMESTAMP);
    }
    if (f == 0) CheckGl("launch", "the first frame of timing " + run.key + " (kernel time)");
    if (!host_clock) glFinish();  // the next frame starts on an idle device
  }
  if (vertex) EndVertexDraws(first->spec.variant);
  glUseProgram(0);
  glFinish();
  CheckGl("launch", "timing " + run.key + " (kernel time)");
  CheckReset("timing " + run.key + " (kernel time)");  // a reset context may have run nothing, and said nothing
  if (!host_clock) {
    const std::uint64_t mask = bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1;
    query = 0;
    for (std::size_t f = untimed; f < run.frames.size(); ++f) {
      GLuint64 previous = 0;
      glGetQueryObjectui64v(cold_queries_[query++].get(), GL_QUERY_RESULT, &previous);
      for (std::size_t l = 0; l < run.frames[f].size(); ++l) {
        GLuint64 end = 0;
        glGetQueryObjectui64v(cold_queries_[query++].get(), GL_QUERY_RESULT, &end);
        ms[f - untimed].push_back(static_cast<double>(((end & mask) - (previous & mask)) & mask) * 1e-6);
        previous = end;
      }
    }
    CheckGl("launch", "reading the timestamps of " + run.key + " (kernel time)");
  }
  return ms;
}

// The Skinner's frame: puts back the program, vertex array, framebuffers,
// transform feedback object and rasteriser-discard state it found; the
// indexed buffer bindings and texture units it used stay bound.
//
// On a context skintune made, a frame of dispatches ends with no barrier:
// the next call that may read its outputs issues it (ReadyForReads), and the
// next frame orders its writes after this one's with a barrier for storage
// writes, which a palette kernel's own barrier is. So that palette kernel,
// which reads and writes only its slot (one the frame before does not read)
// and the instances' states (ordered by the barrier after the kernel before
// it), has nothing ordering it after the frame before, and NVIDIA's GL may
// run the two side by side. A context the caller made, where the caller may
// draw with the outputs as soon as Skin returns, and the vertex path keep a
// barrier for every use after each frame. A crowd in transition (1024 x 5k,
// its palette kernel each frame) ran its pipelined frame in 59.6-60.7 us this
// way against 68.2-68.4 with the barrier after each frame, its Skin-only
// frame 55.5-56.2 (H200, 2026-12-01).
void GlApi::RunLive(const FrameRun& run) {
  const GlPlanned* first = FirstPlan(run);
  const bool vertex = first && first->vertex;
  const bool deferred = !vertex && info().egl_platform != "current";
  ClearGlErrors();
  if (frames_unread_ && (run.prologue.empty() || run.prologue_after_frames))
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);  // this frame's writes (or the prologue's) after the frame before's
  {
    KeptGlState kept(vertex);
    for (const std::unique_ptr<DeviceObject>& launch : run.prologue) {  // the palette kernel, before the frames
      const auto& bound = static_cast<const GlBound&>(*launch);
      BindLaunch(bound, false);
      SetScalars(bound, run);
      DrawLaunch(bound);
      BarrierIfItFeeds(bound);
    }
    if (vertex) BeginVertexDraws();
    for (const auto& frame : run.frames) {
      for (const std::unique_ptr<DeviceObject>& launch : frame) {
        const auto& bound = static_cast<const GlBound&>(*launch);
        BindLaunch(bound, false);
        SetScalars(bound, run);  // a fused kernel's elapsed
        DrawLaunch(bound);
      }
    }
    if (vertex) EndVertexDraws(first->spec.variant);
  }
  frames_unread_ = true;
  if (!deferred) ReadyForReads();  // the outputs are read next: as vertices, buffers, or by Read*
  CheckGl("launch", "skinning with " + run.key);
}

void GlApi::ReadyForReads() {
  if (!frames_unread_) return;
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  frames_unread_ = false;
  ++read_barriers_;
}

}  // namespace skintune::internal::gl
