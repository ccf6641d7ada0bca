#include "runtime/backends/cpu/cpu_runner.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <map>
#include <sstream>
#include <thread>
#include <type_traits>
#include <utility>

#include "base/cache_eviction.h"
#include "base/error.h"
#include "base/thread_pool.h"
#include "cpu_kernels/palette_kernel.h"
#include "generator/palette_kernel.h"
#include "runtime/backends/cpu/cpu_streams.h"

namespace skintune::internal {

namespace {

[[noreturn]] void Fail(const std::string& stage, const std::string& message) {
  throw Error("CPU " + stage + ": " + message);
}

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// Host memory, 64-byte aligned (cache lines; the kernels' 16-byte streaming
// stores need 16).
class CpuBuffer final : public DeviceBuffer {
 public:
  CpuBuffer(std::size_t bytes, const void* initial) : DeviceBuffer(bytes) {
    data_ = static_cast<std::uint8_t*>(std::aligned_alloc(64, (std::max<std::size_t>(bytes, 1) + 63) / 64 * 64));
    if (!data_) throw std::bad_alloc();
    if (initial) std::memcpy(data_, initial, bytes);
  }
  ~CpuBuffer() override { std::free(data_); }
  void* native() const override { return data_; }
  std::uint8_t* data() const { return data_; }

 private:
  std::uint8_t* data_ = nullptr;
};

// A built kernel text: the parameters it defines.
struct Parsed {
  std::map<std::string, long long> defines;
  bool copy = false;
  bool palette = false;  // the palette kernel (generator/palette_kernel.h): RunPaletteKernel
};

class CpuPlanned final : public PlannedLaunch {
 public:
  using PlannedLaunch::PlannedLaunch;
  bool copy = false;
  bool flush = false;  // the copy's flush form (SKINTUNE_FLUSH): read every item, write none
  CpuKernelFn kernel = nullptr;
  int palette_rows = 4;
  bool fault_wrong = false, fault_hang = false;
  bool palette = false;  // the palette kernel: clip_count and palette_rows its parameters
  std::uint32_t clip_count = 0;
  // A baked animation's kernel (ANIM_BAKED): baked palette records read no
  // joints buffer, so this holds ANIM_JOINT_COUNT records for the view's
  // joint count; local records (ANIM_BAKED 3, 4) read nodes and joints.
  bool baked = false, baked_local = false;
  std::uint32_t baked_rows = 0;  // ANIM_BAKED 1, 3: kBakedRowsSimilar; 2: kBakedRowsAffine; 4: kBakedRowsLocalScaled
  std::uint32_t steady_rows = 0;  // ANIM_STEADY: hybrid records' palette records (buffer steady), 0: none
  std::vector<AnimJointRecord> baked_joints;
  int morph_targets = 0;  // MORPH_TARGETS of a morph variant, else 0
};

class CpuBound final : public DeviceObject {
 public:
  const CpuPlanned* plan = nullptr;
  std::vector<const std::uint8_t*> inputs;  // the kernel's input buffers in argument order
  const CpuBuffer* palette = nullptr;
  // Each output by Output (null where the variant writes none), at output
  // vertex 0 (the launch adds first); the copy and the flush write out_positions.
  std::array<float*, kOutputCount> outputs{};
  float* Out(Output o) const { return outputs[static_cast<std::size_t>(o)]; }
  CpuPalette converted;            // this launch's palette in the kernels' form, per frame
  std::vector<std::span<const std::uint8_t>> buffers;  // every buffer bound to it (what kCold evicts)
  float* palette_out = nullptr;  // the palette kernel's output
  CpuMorphScratch morph;          // a morph variant's morphed vertex streams, per instance
  CpuPackScratch packing;         // a packed normal_format's float32 normals and tangents, per instance
};

// The kernel a skinning kernel text's parameters select (ParsedOf checked
// that each is defined and in range).
CpuKernelKey KeyOf(const std::map<std::string, long long>& d) {
  CpuKernelKey k;
  k.influences = static_cast<int>(d.at("INFLUENCES"));
  k.index = static_cast<CpuIndex>(d.at("INDEX_FORMAT"));     // the axes' define values: i32 0, u16 1, u8 2
  k.weight = static_cast<CpuWeight>(d.at("WEIGHT_FORMAT"));  // f32 0, unorm16 1, unorm8 2
  k.palette_rows = static_cast<int>(d.at("PALETTE_ROWS"));   // 4 mat4, 3 mat3x4, 2 dualquat
  k.point_blend = d.at("BLEND") == 1;                        // 0 matrix, 1 point, 2 dual quaternion
  k.dual_quaternion = d.at("BLEND") == 2;
  return k;
}

// `output` advanced by `floats`, or null for an output the variant does not write.
float* At(float* output, std::size_t floats) { return output ? output + floats : nullptr; }

}  // namespace

std::string Describe(const CpuChoice& choice) {
  return Describe(choice.schedule) + (choice.stream_stores ? ", streaming stores" : ", plain stores");
}

class CpuApi final : public DeviceApi {
 public:
  std::string kernel_clock() const override { return "the host's steady clock"; }
  bool evicts_own_buffers() const override { return true; }
  explicit CpuApi(unsigned threads)
      : max_threads_(threads ? threads : std::max(1u, std::thread::hardware_concurrency())),
        name_(std::string("host CPU (") + CpuKernelIsa() + " kernels)") {}

  const char* name() const override { return "CPU"; }
  const std::string& device_name() const override { return name_; }
  void Build(const KernelSource& source) override { ParsedOf(source); }
  void CheckRun(const PackedMesh&, std::span<const KernelSource>, const RunShape&) const override {}
  std::unique_ptr<PlannedLaunch> Plan(const LaunchSpec& spec) override;
  std::unique_ptr<DeviceBuffer> Allocate(BufferUse, std::size_t bytes, const void* initial,
                                         const std::string& what) override {
    try {
      return std::make_unique<CpuBuffer>(bytes, initial);
    } catch (const std::bad_alloc&) {
      Fail("launch", "cannot allocate '" + what + "' (" + std::to_string(bytes) + " bytes)");
    }
  }
  std::unique_ptr<DeviceObject> PaletteView(const Variant&, DeviceBuffer&, const std::string&) override {
    return nullptr;  // the kernels read the buffer itself (storage global)
  }
  std::unique_ptr<DeviceObject> Bind(const PlannedLaunch& launch, std::span<const ArgumentBinding> arguments,
                                     const SetOptions& options, std::size_t& allocated) override;
  void FinishUploads(const std::string&) override {}
  std::vector<std::vector<double>> RunFrames(const FrameRun& run) override;
  // The frame loop (the Skinner's palette ring): buffers are host memory
  // and frames run synchronously, done when RunFrames returns, so the
  // palette is written in place, read-backs read the buffer itself, and no
  // slot is ever still in use: nothing to stage, mark or wait for.
  std::span<std::uint8_t> Staging(DeviceBuffer& buffer, const std::string&, bool) override {
    return {static_cast<CpuBuffer&>(buffer).data(), buffer.bytes()};
  }
  void Upload(DeviceBuffer&, std::size_t, const std::string&) override {}
  void Read(const DeviceBuffer& buffer, std::span<std::uint8_t> out, const std::string&, bool) override {
    std::memcpy(out.data(), static_cast<const CpuBuffer&>(buffer).data(), std::min(out.size(), buffer.bytes()));
  }
  std::span<const std::uint8_t> ReadPinned(const DeviceBuffer& buffer, std::size_t bytes, const std::string&) override {
    return {static_cast<const CpuBuffer&>(buffer).data(), std::min(bytes, buffer.bytes())};
  }
  void Mark(std::unique_ptr<DeviceObject>&, const std::string&) override {}
  void Wait(DeviceObject&, const std::string&) override {}
  void Finish() override {}

  std::size_t evicted_bytes() const override { return evicted_bytes_; }
  std::optional<CpuChoice> ScheduleOf(const std::string& key) const {
    if (const auto found = latest_.find(key); found != latest_.end()) return found->second;
    return std::nullopt;
  }
  std::string schedule_of(const std::string& key) const override {
    const std::optional<CpuChoice> choice = ScheduleOf(key);
    return choice ? Describe(*choice) : "";
  }

 private:
  const Parsed& ParsedOf(const KernelSource& source);
  void RunLaunch(CpuBound& bound, const CpuChoice& choice);
  void RunFrame(std::span<const std::unique_ptr<DeviceObject>> frame, const CpuChoice& choice);
  const CpuChoice& ChoiceFor(const FrameRun& run);

  unsigned max_threads_;
  const FrameRun* frame_run_ = nullptr;  // while RunFrames runs: its run (the palette kernel's scalars)
  std::size_t evicted_bytes_ = 0;  // by kCold, in all
  std::uint64_t flush_sink_ = 0;  // what the flush read, kept so that no compiler drops the reads
  std::string name_;
  std::map<std::string, Parsed> built_;  // by source hash
  std::map<std::string, CpuChoice> choices_;  // by ChoiceKey: the variant and its frame's shape
  std::map<std::string, CpuChoice> latest_;   // by variant key: the choice for its latest frame shape
  CpuPools pools_;
};

const Parsed& CpuApi::ParsedOf(const KernelSource& source) {
  if (source.lang != Lang::kCpu) Fail("build", std::string("kernel language is ") + Name(source.lang));
  const std::string key = HashOf(source);
  if (const auto found = built_.find(key); found != built_.end()) return found->second;
  Parsed parsed;
  parsed.copy = source.entry_point == "skintune_copy";
  parsed.palette = source.entry_point == "skintune_palette";
  std::istringstream lines(source.text);
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    const std::size_t start = line.find_first_not_of(" \t\r");
    if (start == std::string::npos || line.compare(start, 2, "//") == 0 || line.compare(start, 6, "#line ") == 0)
      continue;
    std::istringstream words(line.substr(start));
    std::string directive, name, value, rest;
    words >> directive >> name >> value;
    long long number_value = 0;
    std::size_t used = 0;
    bool ok = directive == "#define" && !name.empty() && !value.empty();
    if (ok) {
      try {
        number_value = std::stoll(value, &used);
      } catch (const std::exception&) {
        ok = false;
      }
    }
    if (ok && used != value.size()) ok = false;
    if (ok && (words >> rest) && rest.compare(0, 2, "//") != 0) ok = false;
    if (!ok)
      Fail("build", "kernel " + key + " line " + std::to_string(number) + ": '" + line.substr(start) +
                        "' is not a parameter (#define NAME INTEGER), a #line or a comment");
    parsed.defines[name] = number_value;
  }
  if (parsed.palette) {
    for (const char* required : {"ANIM_NODE_COUNT", "ANIM_JOINT_COUNT", "ANIM_CLIP_COUNT", "ANIM_PALETTE_ROWS"})
      if (!parsed.defines.contains(required)) Fail("build", "kernel " + key + ": no #define " + required);
  } else if (!parsed.copy) {
    for (const char* required : {"INFLUENCES", "INDEX_FORMAT", "WEIGHT_FORMAT", "PALETTE_ROWS", "BLEND"})
      if (!parsed.defines.contains(required)) Fail("build", "kernel " + key + ": no #define " + required);
    const auto& d = parsed.defines;
    if (d.at("INDEX_FORMAT") < 0 || d.at("INDEX_FORMAT") > 2 || d.at("WEIGHT_FORMAT") < 0 || d.at("WEIGHT_FORMAT") > 2)
      Fail("build", "kernel " + key + ": INDEX_FORMAT and WEIGHT_FORMAT must be 0, 1 or 2");
    if (d.at("BLEND") < 0 || d.at("BLEND") > 2)
      Fail("build", "kernel " + key + ": BLEND " + std::to_string(d.at("BLEND")) +
                        " (expected 0 matrix, 1 point or 2 dual quaternion)");
    if ((d.at("PALETTE_ROWS") == 2) != (d.at("BLEND") == 2))
      Fail("build", "kernel " + key + ": PALETTE_ROWS " + std::to_string(d.at("PALETTE_ROWS")) + " with BLEND " +
                        std::to_string(d.at("BLEND")) + ": a dual-quaternion palette (PALETTE_ROWS 2) is read by " +
                        "BLEND 2 only, and BLEND 2 reads no other");
    if (d.contains("MORPH") && d.at("MORPH") != 0 && (!d.contains("MORPH_TARGETS") || d.at("MORPH_TARGETS") < 1))
      Fail("build", "kernel " + key + ": MORPH " + std::to_string(d.at("MORPH")) + " without MORPH_TARGETS >= 1");
    try {
      FindCpuKernel(KeyOf(d));
    } catch (const Error& e) {
      Fail("build", "kernel " + key + ": " + e.what());
    }
  }
  return built_.emplace(key, std::move(parsed)).first->second;
}

std::unique_ptr<PlannedLaunch> CpuApi::Plan(const LaunchSpec& spec) {
  CheckLaunchKernel(spec, "CPU");
  const Parsed& parsed = ParsedOf(spec.source);
  auto plan = std::make_unique<CpuPlanned>(spec);
  plan->copy = parsed.copy;
  const auto flag = [&](const char* name) {
    const auto found = parsed.defines.find(name);
    return found != parsed.defines.end() && found->second != 0;
  };
  plan->fault_wrong = flag("SKINTUNE_FAULT_WRONG");
  plan->fault_hang = flag("SKINTUNE_FAULT_HANG");
  plan->flush = parsed.copy && flag("SKINTUNE_FLUSH");
  if (parsed.copy) return plan;
  if (parsed.palette) {
    plan->palette = true;
    plan->clip_count = static_cast<std::uint32_t>(parsed.defines.at("ANIM_CLIP_COUNT"));
    plan->palette_rows = static_cast<int>(parsed.defines.at("ANIM_PALETTE_ROWS"));
    plan->baked = flag("ANIM_BAKED");
    const BakedForm form = BakedFormOf(plan->baked ? parsed.defines.at("ANIM_BAKED") : 0);
    plan->baked_local = form.local;
    plan->baked_rows = form.rows;
    if (const auto steady = parsed.defines.find("ANIM_STEADY"); steady != parsed.defines.end())
      plan->steady_rows = static_cast<std::uint32_t>(steady->second);
    if (plan->baked && !plan->baked_local)
      plan->baked_joints.resize(static_cast<std::size_t>(parsed.defines.at("ANIM_JOINT_COUNT")));
    return plan;
  }
  if (spec.variant.storage != PaletteStorage::kGlobal)
    Fail("launch", spec.where + ": storage " + Name(spec.variant.storage) +
                       ": the cpu kernels read the palette from host memory (storage global only)");
  const CpuKernelKey k = KeyOf(parsed.defines);
  plan->kernel = FindCpuKernel(k);
  plan->palette_rows = k.palette_rows;
  if (SkinsMorph(spec.variant)) plan->morph_targets = static_cast<int>(parsed.defines.at("MORPH_TARGETS"));
  if (SkinsMorph(spec.variant) != (parsed.defines.contains("MORPH") && parsed.defines.at("MORPH") != 0))
    Fail("launch", spec.where + ": the kernel's MORPH does not match the variant's morph " + Name(spec.variant.morph));
  const long long normal_format = parsed.defines.contains("NORMAL_FORMAT") ? parsed.defines.at("NORMAL_FORMAT") : 0;
  if (normal_format != static_cast<long long>(spec.variant.normal_format))
    Fail("launch", spec.where + ": the kernel's NORMAL_FORMAT does not match the variant's normal_format " +
                       Name(spec.variant.normal_format));
  return plan;
}

std::unique_ptr<DeviceObject> CpuApi::Bind(const PlannedLaunch& launch, std::span<const ArgumentBinding> arguments,
                                           const SetOptions&, std::size_t&) {
  auto bound = std::make_unique<CpuBound>();
  bound->plan = static_cast<const CpuPlanned*>(&launch);
  for (const ArgumentBinding& a : arguments) {
    const auto* buffer = static_cast<const CpuBuffer*>(a.buffer);
    if (a.role != ArgumentRole::kScalar && buffer) bound->buffers.emplace_back(buffer->data(), buffer->bytes());
    switch (a.role) {
      case ArgumentRole::kScalar: break;
      case ArgumentRole::kInput: bound->inputs.push_back(buffer->data()); break;
      case ArgumentRole::kPalette: bound->palette = buffer; break;
      case ArgumentRole::kOutput: {
        auto* out = reinterpret_cast<float*>(buffer->data());
        if (bound->plan->palette) {
          bound->palette_out = out;
          break;
        }
        const OutputSpec* output = OutputOfArgument(a.argument->name);
        if (!output) Fail("launch", launch.spec.where + ": output '" + a.argument->name + "' is no kernel output");
        bound->outputs[static_cast<std::size_t>(output->output)] = out;
        break;
      }
    }
  }
  // The palette kernel: every buffer argument bound (RunLaunch reads them by name).
  std::size_t palette_buffers = 0;
  for (const KernelArgument& a : launch.spec.source.arguments) palette_buffers += a.kind == ArgumentKind::kBuffer;
  if (bound->plan->palette ? !bound->palette_out || bound->buffers.size() != palette_buffers
                           : !bound->Out(Output::kPositions))
    Fail("launch", launch.spec.where + ": not every argument bound");
  return bound;
}

void CpuApi::RunLaunch(CpuBound& b, const CpuChoice& choice) {
  const CpuPlanned& plan = *b.plan;
  const LaunchSpec& spec = plan.spec;
  if (plan.palette) {  // the buffers by argument name, each as bound (b.buffers: in argument order)
    const auto span_of = [&](const char* name, auto* type) {
      using T = std::remove_const_t<std::remove_pointer_t<decltype(type)>>;
      std::size_t i = 0;
      for (const KernelArgument& a : spec.source.arguments) {
        if (a.kind != ArgumentKind::kBuffer) continue;
        if (a.name == name)
          return std::span<const T>(reinterpret_cast<const T*>(b.buffers[i].data()), b.buffers[i].size() / sizeof(T));
        ++i;
      }
      Fail("launch", spec.where + ": no buffer '" + name + "'");
    };
    AnimationView view;
    view.clip_count = plan.clip_count;
    if (plan.baked_local) {
      view.nodes = span_of(kAnimInputs[0], static_cast<const AnimNodeRecord*>(nullptr));
      view.frames = span_of(kAnimFrames, static_cast<const float*>(nullptr));
      view.baked_rows = plan.baked_rows;
      view.baked_local = true;
      view.joints = span_of(kAnimInputs[4], static_cast<const AnimJointRecord*>(nullptr));
      if (plan.steady_rows != 0) {
        view.steady = span_of(kAnimSteady, static_cast<const float*>(nullptr));
        view.steady_rows = plan.steady_rows;
      }
    } else if (plan.baked) {
      view.frames = span_of(kAnimFrames, static_cast<const float*>(nullptr));
      view.baked_rows = plan.baked_rows;
      view.joints = plan.baked_joints;
    } else {
      view.nodes = span_of(kAnimInputs[0], static_cast<const AnimNodeRecord*>(nullptr));
      view.channels = span_of(kAnimInputs[1], static_cast<const AnimChannelHeader*>(nullptr));
      view.times = span_of(kAnimInputs[2], static_cast<const float*>(nullptr));
      view.values = span_of(kAnimInputs[3], static_cast<const float*>(nullptr));
      view.joints = span_of(kAnimInputs[4], static_cast<const AnimJointRecord*>(nullptr));
    }
    view.clip_ranges = span_of(kAnimClips, static_cast<const float*>(nullptr)).first(4 * std::size_t{plan.clip_count});
    const auto count = static_cast<std::size_t>(spec.instances);
    const auto instances = span_of(kAnimInputs[5], static_cast<const AnimInstance*>(nullptr)).first(count);
    // The states kept on the device (read and written: the buffer is the runner's, host memory).
    const std::span<AnimInstance> states(const_cast<AnimInstance*>(span_of(kAnimStates, static_cast<const AnimInstance*>(nullptr)).data()),
                                         count);
    if (!frame_run_) Fail("launch", spec.where + ": no value for the palette kernel's scalars");
    if (ScalarOf(*frame_run_, kAnimFresh, "CPU") != 0) {
      std::copy(instances.begin(), instances.end(), states.begin());
    } else {
      AdvanceAnimInstances(view, states, std::bit_cast<float>(ScalarOf(*frame_run_, kAnimDelta, "CPU")));
    }
    // Instances spread over the device's threads, in chunks of 4 (each a few
    // microseconds of sampling and walks); checked first, so no chunk throws.
    ValidateAnimInstances(view, states);
    const std::size_t floats = view.joints.size() * static_cast<std::size_t>(plan.palette_rows) * 4;
    ThreadPool& pool = pools_.Get(max_threads_);
    pool.ParallelFor(count, 4, [&](std::size_t begin, std::size_t end) {
      RunPaletteKernel(view, std::span<const AnimInstance>(states).subspan(begin, end - begin),
                       b.palette_out + begin * floats, plan.palette_rows);
    });
    return;
  }
  if (plan.fault_hang) {
    for (;;) std::this_thread::sleep_for(std::chrono::milliseconds(10));  // the tuner's hang test: never returns
  }
  if (plan.flush) {
    // Every 8-byte word read on every thread and, as the templates' flush
    // does, only an item of all ones (which no flush input holds) written:
    // so what the flush wrote shows that it ran (tests), and nothing else.
    const auto* in = reinterpret_cast<const std::uint64_t*>(b.inputs.at(0));
    auto* out = reinterpret_cast<std::uint64_t*>(reinterpret_cast<std::uint8_t*>(b.Out(Output::kPositions)) +
                                                 std::size_t{spec.first} * 16);
    const std::size_t words = std::size_t{spec.count} * 2;
    ThreadPool& pool = pools_.Get(max_threads_);
    std::atomic<std::uint64_t> sink{0};
    pool.ParallelFor(words, std::max<std::size_t>((words / pool.size() + 511) / 512 * 512, 512),
                     [&](std::size_t begin, std::size_t end) {  // begin: a multiple of the (even) grain
                       std::uint64_t all = ~std::uint64_t{0};
                       for (std::size_t w = begin; w < end; w += 2) {
                         const std::uint64_t item = in[w] & in[w + 1];
                         all &= item;
                         if (item == ~std::uint64_t{0}) {
                           out[w] = in[w];
                           out[w + 1] = in[w + 1];
                         }
                       }
                       sink.fetch_or(all, std::memory_order_relaxed);
                     });
    flush_sink_ ^= sink.load();
    return;
  }
  if (plan.copy) {  // n 16-byte items, one chunk per thread
    const std::uint8_t* in = b.inputs.at(0);
    auto* out = reinterpret_cast<std::uint8_t*>(b.Out(Output::kPositions)) + std::size_t{spec.first} * 16;
    const std::size_t bytes = std::size_t{spec.count} * 16;
    ThreadPool& pool = pools_.Get(max_threads_);
    const std::size_t grain = (bytes / pool.size() + 4095) / 4096 * 4096;
    pool.ParallelFor(bytes, std::max<std::size_t>(grain, 4096),
                     [&](std::size_t begin, std::size_t end) { std::memcpy(out + begin, in + begin, end - begin); });
    return;
  }
  const std::size_t floats = spec.output_stride / sizeof(float);
  const std::size_t joint_bytes = spec.palette_joints * static_cast<std::size_t>(plan.palette_rows) * 16;
  ThreadPool& pool = pools_.Get(choice.schedule.threads);
  for (int i = 0; i < std::max(spec.instances, 1); ++i) {
    const std::size_t out_first = static_cast<std::size_t>(i) * spec.vertex_count + spec.first;
    LoadCpuPalette(std::span(b.palette->data() + static_cast<std::size_t>(i) * joint_bytes, joint_bytes),
                   plan.palette_rows, b.converted);
    const std::size_t vertex_inputs = std::min(CpuVertexInputCount(spec.variant), b.inputs.size());
    const bool packs = PacksNormals(spec.variant);  // then normals and tangents are one word a vertex
    CpuStreams s = CpuStreamsOf(spec.variant, spec.source.influences, spec.count,
                                std::span(b.inputs).first(vertex_inputs),
                                At(b.Out(Output::kPositions), out_first * floats),
                                At(b.Out(Output::kNormals), packs ? out_first : out_first * floats),
                                At(b.Out(Output::kTangents), packs ? out_first : out_first * floats),
                                choice.stream_stores);
    auto* const packed_normals = reinterpret_cast<std::uint32_t*>(s.out_normals);
    auto* const packed_tangents = reinterpret_cast<std::uint32_t*>(s.out_tangents);
    if (packs) s = PackingStreams(s, b.packing, spec.count);
    if (plan.morph_targets > 0) {
      // The morph targets first, into scratch streams the kernel then reads
      // (morph_weights, the last input, holds every instance's).
      const std::span<const std::uint8_t* const> morph =
          std::span(b.inputs).subspan(vertex_inputs, b.inputs.size() - vertex_inputs - 1);
      const float* weights = reinterpret_cast<const float*>(b.inputs.back()) +
                             static_cast<std::size_t>(i) * static_cast<std::size_t>(plan.morph_targets);
      const CpuStreams morphed = MorphedStreams(s, b.morph, spec.count);
      pool.ParallelFor(spec.count, std::max<std::size_t>(choice.schedule.chunk, 64),
                       [&](std::size_t begin, std::size_t end) {
                         MorphCpuStreams(spec.variant, spec.count, plan.morph_targets, morph, weights, s, b.morph,
                                         begin, end);
                       });
      s = morphed;
    }
    RunCpuKernel(plan.kernel, s, b.converted, spec.count, pool, choice.schedule.chunk);
    if (packs)
      pool.ParallelFor(spec.count, std::max<std::size_t>(choice.schedule.chunk, 64), [&](std::size_t begin, std::size_t end) {
        PackCpuOutputs(spec.variant.normal_format, s, packed_normals, packed_tangents, begin, end);
      });
    if (plan.fault_wrong && spec.index == 0) s.out_positions[0] += 1.0f;  // the tuner's wrong-result test
  }
}

void CpuApi::RunFrame(std::span<const std::unique_ptr<DeviceObject>> frame, const CpuChoice& choice) {
  for (const std::unique_ptr<DeviceObject>& launch : frame) RunLaunch(static_cast<CpuBound&>(*launch), choice);
}

namespace {
// Writes back and invalidates every cache line of `frame`'s buffers
// (base/cache_eviction.h) on the threads of `pool`, the one that runs the
// frame next; the bytes evicted.
std::size_t EvictFrame(std::span<const std::unique_ptr<DeviceObject>> frame, ThreadPool& pool) {
  std::vector<std::span<const std::uint8_t>> buffers;
  std::size_t bytes = 0;
  for (const std::unique_ptr<DeviceObject>& launch : frame)
    for (const std::span<const std::uint8_t> buffer : static_cast<const CpuBound&>(*launch).buffers) {
      buffers.push_back(buffer);
      bytes += buffer.size();
    }
  EvictFromCaches(buffers, pool);
  return bytes;
}

// What a schedule is chosen for: the variant and the shape of its frame
// (each launch's vertices and instances). One variant runs on meshes of
// different sizes in one process (a tuner worker's data sets, a program's
// meshes): a chunk chosen for 100k vertices left a 5k-vertex crowd on one
// thread, 5x slower (H200 machine, 2026-11-29).
std::string ChoiceKey(const FrameRun& run) {
  std::string key = run.key;
  if (!run.frames.empty())
    for (const std::unique_ptr<DeviceObject>& launch : run.frames.front()) {
      const LaunchSpec& spec = static_cast<const CpuBound&>(*launch).plan->spec;
      key += " " + std::to_string(spec.count) + "x" + std::to_string(spec.instances);
    }
  return key;
}
}  // namespace

// The schedule is chosen on the variant's own frame, timed as the use will
// time it: for the kernel time (kCold) each candidate's frame from its own
// buffers evicted and its pool awake, as the cold samples run, so that what
// ranks the candidates is the figure that ranks variants; otherwise back to
// back.
const CpuChoice& CpuApi::ChoiceFor(const FrameRun& run) {
  const std::string key = ChoiceKey(run);
  if (const auto found = choices_.find(key); found != choices_.end()) return latest_[run.key] = found->second;
  std::size_t vertices = 0;
  bool copy = false;
  for (const std::unique_ptr<DeviceObject>& launch : run.frames.front()) {
    const CpuPlanned& plan = *static_cast<const CpuBound&>(*launch).plan;
    vertices = std::max<std::size_t>(vertices, plan.spec.count);
    copy = copy || plan.copy;
  }
  CpuChoice best;
  best.schedule = {max_threads_, std::max<std::size_t>(64, vertices)};
  if (!copy && !run.frames.empty()) {
    std::vector<CpuChoice> candidates;
    for (const CpuSchedule& s : CpuScheduleCandidates(vertices, max_threads_))
      for (const bool stream : {true, false}) candidates.push_back({s, stream});
    const bool cold = run.use == FrameUse::kCold;
    const auto frame_ms = [&](std::size_t c) {
      if (cold) {
        ThreadPool& pool = pools_.Get(candidates[c].schedule.threads);
        (void)EvictFrame(run.frames.front(), pool);
        pool.Ready();
      }
      const Clock::time_point start = Clock::now();
      RunFrame(run.frames.front(), candidates[c]);
      return MsSince(start);
    };
    // One untimed frame per thread count: it starts that pool and touches the frame's pages for all of them.
    const auto pool_of = [&](std::size_t c) -> std::size_t { return candidates[c].schedule.threads; };
    best = candidates[FastestCandidate(candidates.size(), frame_ms, 3, pool_of)];
  }
  latest_[run.key] = best;
  return choices_.emplace(key, best).first->second;
}

std::vector<std::vector<double>> CpuApi::RunFrames(const FrameRun& run) {
  if (run.frames.empty()) return {};
  const CurrentRun current(frame_run_, run);
  if (run.use == FrameUse::kVerify) {
    const auto found = choices_.find(ChoiceKey(run));
    const CpuChoice choice =
        found != choices_.end() ? found->second : CpuChoice{{max_threads_, 16384}, /*stream_stores=*/true};
    std::vector<double> ms;
    for (const std::unique_ptr<DeviceObject>& launch : run.frames.front()) {
      const Clock::time_point start = Clock::now();
      RunLaunch(static_cast<CpuBound&>(*launch), choice);
      ms.push_back(MsSince(start));
    }
    return {ms};
  }
  const CpuChoice choice = ChoiceFor(run);
  if (run.use == FrameUse::kLive) {
    RunFrame(run.prologue, choice);
    for (const auto& frame : run.frames) RunFrame(frame, choice);
    return {};
  }
  if (run.use == FrameUse::kCold) {  // device_api.h: each launch on the host's clock, its buffers evicted
    const auto untimed = std::min(run.frames.size(), static_cast<std::size_t>(std::max(run.untimed, 0)));
    ThreadPool& pool = pools_.Get(choice.schedule.threads);
    std::vector<std::vector<double>> ms;
    for (std::size_t f = 0; f < run.frames.size(); ++f) {
      // The frame's own lines out of every cache (evicts_own_buffers: run.flush
      // is not run), then every thread of its pool awake, then the clock.
      evicted_bytes_ += EvictFrame(run.frames[f], pool);
      pool.Ready();
      if (f < untimed) {
        RunFrame(run.frames[f], choice);
        continue;
      }
      std::vector<double>& launches = ms.emplace_back();
      for (const std::unique_ptr<DeviceObject>& launch : run.frames[f]) {
        const Clock::time_point start = Clock::now();
        RunLaunch(static_cast<CpuBound&>(*launch), choice);
        launches.push_back(MsSince(start));
      }
    }
    return ms;
  }
  const auto untimed = std::min(run.frames.size(), static_cast<std::size_t>(std::max(run.untimed, 0)));
  const auto burst = static_cast<std::size_t>(std::max(run.burst, 1));
  for (std::size_t f = 0; f < untimed; ++f) RunFrame(run.frames[f], choice);
  std::vector<std::vector<double>> ms;
  for (std::size_t b = 0; b < run.TimedBursts(); ++b) {
    const Clock::time_point start = Clock::now();
    for (std::size_t i = 0; i < burst; ++i) RunFrame(run.frames[untimed + b * burst + i], choice);
    ms.push_back({MsSince(start)});
  }
  return ms;
}

CpuRunner::CpuRunner(unsigned threads) : Runner(std::make_unique<CpuApi>(threads)) {}

std::optional<CpuChoice> CpuRunner::ScheduleOf(const std::string& key) const {
  return static_cast<const CpuApi&>(api()).ScheduleOf(key);
}

}  // namespace skintune::internal
