// The runner driver (runtime/runner.h): the orchestration every API shares,
// over its DeviceApi.
#include "runtime/runner.h"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cstring>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <map>
#include <string_view>
#include <utility>

#include "base/error.h"
#include "generator/copy_kernel.h"
#include "runtime/output_check.h"
#include "runtime/run_shape.h"

namespace skintune::internal {

struct Prepared::Impl {
  // One palette buffer of a set and its launches, bound with the set's inputs
  // and outputs; `done` is signalled once the slot's last upload and launches
  // have completed (the palette ring: runner.h).
  struct Slot {
    DeviceBuffer* palette = nullptr;
    // Morph variants: the K instances' morph weights, uploaded with the palette.
    DeviceBuffer* morph_weights = nullptr;
    // The bound launches in order; animated (Runner::Animate), the first
    // `palette_launches` are the palette kernel bound to write `palette`: a
    // live frame runs them as its prologue when the instances changed, a
    // verified, timed or cold frame every time, as the frame's first launch.
    std::vector<std::unique_ptr<DeviceObject>> launches;
    std::size_t palette_launches = 0;
    // Animated: the instances the palette kernel reads.
    DeviceBuffer* instances = nullptr;
    // The instances changed since the prologue last ran: the next LaunchSet
    // runs it (a Skin again with the same states reuses the palette computed).
    bool prologue_pending = false;
    // The prologue's scalars: fresh, the states of the slot's last upload;
    // else the states kept on the device advanced by delta seconds
    // (AdvanceAnimation).
    bool fresh = true;
    float delta = 0.0f;
    // What PaletteStaging and UploadPalette fill: the instances where animated.
    DeviceBuffer& Uploaded() const { return instances ? *instances : *palette; }
    // Whether a new upload into the slot's buffers must wait for its fence:
    // a launch read them since their last upload, or the API runs uploads
    // after the launches queued before them.
    bool UploadFenced(const DeviceApi& api) const { return done && (launched || api.OrdersUploadsAfterLaunches()); }
    std::unique_ptr<DeviceObject> done;
    std::string fence_name;  // "palette slot N of <key>", built on the slot's first wait
    bool launched = false;   // a launch read the slot (and so waited for its upload) since that upload
    std::optional<std::size_t> paced_by;  // fused: the Set::pace fence its last frame marked
    std::uint64_t submitted = 0;  // the submit thread's number of the slot's last upload or launch
  };
  // One input set: every object it owns (released last first), the buffers
  // the driver reads and writes, and its palette slots (one but in a
  // Skinner's set).
  struct Set {
    std::vector<std::unique_ptr<DeviceObject>> objects;
    std::vector<std::shared_ptr<DeviceBuffer>> shared;  // inputs kept by the runner (ShareTimedInputs)
    std::vector<Slot> slots;
    std::array<DeviceBuffer*, kOutputCount> outputs{};  // by Output; null where the variant writes none
    std::size_t current = 0;  // the slot of the last upload: LaunchSet's
    std::optional<std::size_t> staged;  // the slot PaletteStaging gave, until its UploadPalette
    // Each launch's arguments as AddSet bound them (the palette and morph
    // weights left to the slots), and the set's options: Animate binds the
    // fused kernels with the same buffers.
    std::vector<std::vector<ArgumentBinding>> bindings;
    SetOptions options;
    bool animated = false;  // Animate ran on the set
    // Fused (PaletteKernel::fused): the skin launches make the palettes, from
    // the instances of the last upload advanced by `elapsed` seconds (the
    // frames' deltas since, summed here and passed with each launch).
    bool fused = false;
    double elapsed = 0.0;
    // Fused: the states of the last upload and the clips' ranges, so that the
    // runner can upload them advanced (AdvanceAnimation's rebase).
    std::vector<AnimInstance> uploaded_states;
    std::vector<float> clip_ranges;
    std::span<std::uint8_t> staging;  // PaletteStaging's, until its UploadPalette
    // Fused: AdvanceAnimation takes no palette slot, so these fences bound the
    // frames queued: LaunchSet marks entry `paced` and moves on;
    // AdvanceAnimation first waits for the entry the next frame marks, the
    // frame as many frames back as there are entries (AnimateFused: the
    // slots, or twice the API's frames a submission where that is more).
    std::vector<Slot> pace;
    std::size_t paced = 0;
  };
  DeviceApi* api = nullptr;  // the runner's; null in a Prepared that holds nothing
  SubmitThread* submit = nullptr;  // the runner's, where it has one
  std::string key;           // the variant's
  std::vector<std::unique_ptr<PlannedLaunch>> launches;
  std::unique_ptr<PlannedLaunch> palette_kernel;  // Animate's
  std::vector<std::unique_ptr<PlannedLaunch>> fused_launches;  // Animate's fused skin kernels, one per launch
  bool Animated() const { return palette_kernel || !fused_launches.empty(); }
  std::vector<Set> sets;
  std::size_t bytes_per_set = 0;
  std::size_t palettes_bytes = 0;  // the K palettes of a set
  std::size_t upload_bytes = 0;    // what a frame uploads: the K palettes, or K AnimInstances once animated
  int instances = 1;               // K
  // By Output: K x vertex_count x its stride (a verification set's guard follows); 0 where none.
  std::array<std::size_t, kOutputCount> out_bytes{};

  Impl() = default;
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
  ~Impl() {
    if (!api) return;
    if (submit) submit->DrainQuietly();  // no queued call still uses what goes below
    const bool ready = api->ReadyToRelease();
    for (Set& set : sets) {
      for (Slot& slot : set.slots) {
        if (!ready) {
          for (auto& o : slot.launches) o->Forget();
          if (slot.done) slot.done->Forget();
        }
        while (!slot.launches.empty()) slot.launches.pop_back();
        slot.done.reset();
      }
      if (!ready)
        for (auto& o : set.objects) o->Forget();
      while (!set.objects.empty()) set.objects.pop_back();
      set.shared.clear();  // after the launches bound to them
    }
  }

  // The frame of set `s` as Run, Time and TimeCold run it: its first slot's
  // bound launches, an animated set's palette kernel first.
  std::span<const std::unique_ptr<DeviceObject>> Frame(std::size_t s) const { return sets[s].slots.front().launches; }
  // A run of these frames for `use`: an animated set's palette kernel takes
  // the states uploaded last (fresh) and advances them by nothing, so every
  // frame makes the same palettes (the tuner's animated data sets: one
  // crowd's states per input set).
  FrameRun Run(FrameUse use) const {
    FrameRun run;
    run.use = use;
    run.key = key;
    if (palette_kernel) run.scalars = {{kAnimDelta, 0u}, {kAnimFresh, 1u}};
    if (!fused_launches.empty()) run.scalars = {{kAnimElapsed, 0u}};
    return run;
  }
};

Prepared::Prepared() : impl_(std::make_unique<Impl>()) {}
Prepared::~Prepared() = default;
Prepared::Prepared(Prepared&&) noexcept = default;
Prepared& Prepared::operator=(Prepared&&) noexcept = default;
int Prepared::input_sets() const { return impl_ ? static_cast<int>(impl_->sets.size()) : 0; }
std::size_t Prepared::bytes_per_set() const { return impl_ ? impl_->bytes_per_set : 0; }
std::size_t Prepared::output_bytes(Output output) const {
  return impl_ ? impl_->out_bytes[static_cast<std::size_t>(output)] : 0;
}

namespace {

// Prepared::Impl's set `set`, or Error("<API> launch: no input set ...").
template <typename ImplT>
auto& SetOf(ImplT* impl, int set, const DeviceApi& api) {
  const std::size_t count = impl ? impl->sets.size() : 0;
  if (!impl || set < 0 || static_cast<std::size_t>(set) >= count)
    throw Error(std::string(api.name()) + " launch: no input set " + std::to_string(set) + " (" +
                std::to_string(count) + " prepared)");
  return impl->sets[static_cast<std::size_t>(set)];
}

}  // namespace

Runner::Runner(std::unique_ptr<DeviceApi> api) : api_(std::move(api)) {}
Runner::~Runner() = default;

bool Runner::UseSubmitThread() {
  if (!api_->SubmitsFromAnyThread()) return false;
  if (!submit_) submit_ = std::make_unique<SubmitThread>();
  return true;
}

void Runner::Settle() {
  if (submit_) submit_->Drain();
}

void Runner::Fail(const std::string& stage, const std::string& message) const {
  throw Error(std::string(api_->name()) + " " + stage + ": " + message);
}

void Runner::ShareTimedInputs(std::size_t max_bytes) {
  shared_max_bytes_ = max_bytes;
  if (max_bytes == 0) {
    shared_buffers_.clear();
    shared_bytes_ = 0;
  }
}

void Runner::UseProgramCache(ProgramCache* cache, const std::string& device_id) {
  api_->UseProgramCache(cache, device_id);
}

void Runner::Build(const KernelSource& source) {
  api_->MakeCurrent();
  api_->Build(source);
}

// ---------------------------------------------------------------- input sets

Prepared Runner::PrepareSets(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                             std::span<const std::vector<std::uint8_t>> palettes, const RunShape& shape,
                             const SetOptions& options, int palette_slots) {
  Prepared prepared;
  Settle();
  Prepared::Impl& p = *prepared.impl_;
  p.api = api_.get();
  p.submit = submit_.get();
  p.key = mesh.variant.Key();
  for (std::size_t l = 0; l < mesh.launches.size(); ++l) {
    const Launch& launch = mesh.launches[l];
    if (launch.count == 0) continue;
    LaunchSpec spec;
    spec.variant = mesh.variant;
    spec.source = kernels[l];
    spec.index = l;
    spec.count = launch.count;
    spec.first = launch.first;
    spec.vertex_count = static_cast<std::uint32_t>(mesh.vertex_count);
    spec.instances = shape.instances;
    spec.instanced = shape.instanced;
    spec.palettes_bytes = static_cast<std::size_t>(shape.instances) * shape.palette_bytes;
    spec.palette_joints = mesh.palette_joints;
    spec.output_stride = mesh.output_stride_bytes;
    spec.where = "launch " + std::to_string(l) + " of " + p.key;
    p.launches.push_back(api_->Plan(spec));  // build errors before any upload
  }
  p.palettes_bytes = static_cast<std::size_t>(shape.instances) * shape.palette_bytes;
  p.upload_bytes = p.palettes_bytes;
  p.instances = shape.instances;
  p.out_bytes = shape.output_bytes;
  input_hashes_.clear();  // ShareTimedInputs: each input hashed once per Prepare, not per set
  for (std::size_t k = 0; k < palettes.size(); ++k) {
    SetOptions set_options = options;
    if (!options.verification) set_options.suffix = " (input set " + std::to_string(k) + ")";
    AddSet(p, mesh, kernels, palettes[k], shape, set_options, palette_slots);
  }
  return prepared;
}

std::string Runner::ShareKey(const SetOptions& options, std::size_t set, BufferUse use, const std::string& name,
                             std::span<const std::uint8_t> content) {
  if (shared_max_bytes_ == 0 || options.verification) return "";
  std::string key = std::to_string(set) + "|" + std::to_string(static_cast<int>(use)) + "|" + name + "|" +
                    std::to_string(content.size());
  if (use == BufferUse::kOutput) return key;  // a timed output's bytes are never read
  const std::string_view bytes(reinterpret_cast<const char*>(content.data()), content.size());
  if (use != BufferUse::kInput) return key + "|" + std::to_string(std::hash<std::string_view>{}(bytes));
  // Each packed input hashed once per Prepare (its sets bind the same mesh's bytes).
  auto hashed = input_hashes_.find(content.data());
  if (hashed == input_hashes_.end()) hashed = input_hashes_.emplace(content.data(), std::hash<std::string_view>{}(bytes)).first;
  return key + "|" + std::to_string(hashed->second);
}

DeviceBuffer* Runner::SetBuffer(Prepared::Impl& p, std::size_t set_index, BufferUse use, std::span<const std::uint8_t> content,
                                const std::string& what, const std::string& share_key) {
  Prepared::Impl::Set& set = p.sets[set_index];
  if (content.empty()) Fail("launch", "buffer '" + what + "' is empty");
  if (share_key.empty()) {
    set.objects.push_back(api_->Allocate(use, content.size(), content.data(), what));
    return static_cast<DeviceBuffer*>(set.objects.back().get());
  }
  auto found = std::find_if(shared_buffers_.begin(), shared_buffers_.end(),
                            [&](const SharedBuffer& k) { return k.key == share_key; });
  if (found == shared_buffers_.end()) {
    shared_buffers_.push_back({share_key, api_->Allocate(use, content.size(), content.data(), what)});
    shared_bytes_ += content.size();
    while (shared_bytes_ > shared_max_bytes_ && shared_buffers_.size() > 1) {
      shared_bytes_ -= shared_buffers_.front().buffer->bytes();
      shared_buffers_.erase(shared_buffers_.begin());  // a Prepared still holding it keeps it alive
    }
    found = shared_buffers_.end() - 1;
  }
  set.shared.push_back(found->buffer);
  return found->buffer.get();
}

std::vector<ArgumentBinding> Runner::InputBindings(Prepared::Impl& p, std::size_t set_index,
                                                   const LaunchSpec& spec, const Launch& launch,
                                                   const SetOptions& options, std::size_t& bytes) {
  const Prepared::Impl::Set& set = p.sets[set_index];
  std::vector<ArgumentBinding> arguments;
  for (const KernelArgument& arg : spec.source.arguments) {
    ArgumentBinding b{&arg, ArgumentRole::kScalar, nullptr, nullptr};
    if (arg.kind == ArgumentKind::kScalar) {
      arguments.push_back(b);
      continue;
    }
    if (arg.name == "palette") {
      b.role = ArgumentRole::kPalette;  // bound per slot (AddSet)
      arguments.push_back(b);
      continue;
    }
    if (arg.name == kMorphWeightsArgument) {
      b.role = ArgumentRole::kInput;  // a frame's, bound per slot (AddSet)
      arguments.push_back(b);
      continue;
    }
    if (const OutputSpec* output = OutputOfArgument(arg.name)) {
      b = {&arg, ArgumentRole::kOutput, set.outputs[static_cast<std::size_t>(output->output)], nullptr};
    } else {
      const auto input = std::find_if(launch.inputs.begin(), launch.inputs.end(),
                                      [&](const PackedBuffer& pb) { return pb.name == arg.name; });
      if (input == launch.inputs.end()) Fail("launch", spec.where + ": no packed buffer for argument '" + arg.name + "'");
      b = {&arg, ArgumentRole::kInput,
           SetBuffer(p, set_index, BufferUse::kInput, input->bytes, arg.name + options.suffix,
                     ShareKey(options, set_index, BufferUse::kInput, arg.name, input->bytes)),
           nullptr};
      bytes += input->bytes.size();
    }
    if (!b.buffer) Fail("launch", spec.where + ": nothing to bind to argument '" + arg.name + "'");
    arguments.push_back(b);
  }
  return arguments;
}

void Runner::AddSet(Prepared::Impl& p, const PackedMesh& mesh, std::span<const KernelSource> kernels,
                    const std::vector<std::uint8_t>& palettes, const RunShape& shape, const SetOptions& options,
                    int palette_slots) {
  const std::size_t index = p.sets.size();
  Prepared::Impl::Set& set = p.sets.emplace_back();
  std::size_t bytes = 0;
  // Outputs (K instances, one after another): poisoned; Run's followed by their guard.
  for (const OutputSpec& output : kOutputs) {
    if (!Writes(mesh.variant, output.output)) continue;
    const std::size_t out_bytes = p.out_bytes[static_cast<std::size_t>(output.output)];
    const std::vector<std::uint8_t> poison = PoisonedOutput(out_bytes);
    const std::span<const std::uint8_t> out(poison.data(), options.verification ? poison.size() : out_bytes);
    const std::string name = output.argument;
    set.outputs[static_cast<std::size_t>(output.output)] =
        SetBuffer(p, index, BufferUse::kOutput, out, name + options.suffix, ShareKey(options, index, BufferUse::kOutput, name, out));
    bytes += options.verification ? 0 : out.size();
  }

  // Every launch's arguments, inputs uploaded once for all the slots; the
  // palette bound per slot below.
  std::vector<std::vector<ArgumentBinding>> launch_arguments;
  for (const std::unique_ptr<PlannedLaunch>& planned : p.launches)
    launch_arguments.push_back(
        InputBindings(p, index, planned->spec, mesh.launches[planned->spec.index], options, bytes));

  // The palette slots: each its palette (padded where the API binds a larger
  // block), the storage's view of it, and every launch bound with it. (A
  // Skinner's several slots are never shared: only a timed set's one.)
  std::vector<std::uint8_t> palette(palettes.begin(), palettes.end());
  palette.resize(std::max(palette.size(), api_->PaletteBufferBytes(shape, kernels)), 0);
  for (int s = 0; s < std::max(palette_slots, 1); ++s) {
    Prepared::Impl::Slot& slot = set.slots.emplace_back();
    const std::string suffix = palette_slots > 1 ? options.suffix + " (palette slot " + std::to_string(s) + ")" : options.suffix;
    slot.palette = SetBuffer(p, index, BufferUse::kPalette, palette, "palette" + suffix,
                             palette_slots > 1 ? "" : ShareKey(options, index, BufferUse::kPalette, "palette", palette));
    bytes += palette.size();
    if (SkinsMorph(mesh.variant)) {
      // Each instance's weights where the packed mesh holds K runs, else its one run for every instance.
      const std::size_t one = static_cast<std::size_t>(mesh.morph_targets) * sizeof(float);
      std::vector<std::uint8_t> weights;
      if (mesh.morph_weights.size() == one * static_cast<std::size_t>(shape.instances)) {
        weights = mesh.morph_weights;
      } else {
        if (mesh.morph_weights.size() != one)
          Fail("launch", "the packed mesh's morph weights have " + std::to_string(mesh.morph_weights.size()) +
                             " bytes, expected " + std::to_string(one) + " (T) or " +
                             std::to_string(one * static_cast<std::size_t>(shape.instances)) + " (K x T)");
        for (int i = 0; i < shape.instances; ++i)
          weights.insert(weights.end(), mesh.morph_weights.begin(), mesh.morph_weights.end());
      }
      slot.morph_weights = SetBuffer(p, index, BufferUse::kPalette, weights, std::string(kMorphWeightsArgument) + suffix,
                                     palette_slots > 1 ? "" : ShareKey(options, index, BufferUse::kPalette,
                                                                       kMorphWeightsArgument, weights));
      bytes += weights.size();
    }
    std::unique_ptr<DeviceObject> view = api_->PaletteView(mesh.variant, *slot.palette, suffix);
    DeviceObject* palette_view = view.get();
    if (view) set.objects.push_back(std::move(view));
    for (std::size_t l = 0; l < p.launches.size(); ++l) {
      std::vector<ArgumentBinding> arguments = launch_arguments[l];
      for (ArgumentBinding& b : arguments) {
        if (b.role == ArgumentRole::kPalette) b = {b.argument, ArgumentRole::kPalette, slot.palette, palette_view};
        if (b.argument->name == kMorphWeightsArgument) b.buffer = slot.morph_weights;
      }
      slot.launches.push_back(api_->Bind(*p.launches[l], arguments, options, bytes));
    }
  }
  set.current = set.slots.size() - 1;  // the first WritePalette takes slot 0
  set.bindings = std::move(launch_arguments);
  set.options = options;
  p.bytes_per_set = bytes;
}

// ---------------------------------------------------------------- verification

RunResult Runner::Run(const PackedMesh& mesh, std::span<const std::uint8_t> palette) {
  return Run(mesh, EmitLaunchKernels(mesh), palette);
}

RunResult Runner::RunInstanced(const PackedMesh& mesh, int instances, std::span<const std::uint8_t> palettes) {
  return Run(mesh, EmitLaunchKernels(mesh, instances), palettes, instances);
}

RunResult Runner::Run(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                      std::span<const std::uint8_t> palettes, int instances) {
  return Run(mesh, kernels, palettes, instances, Animated{});
}

RunResult Runner::Run(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                      std::span<const std::uint8_t> palettes, int instances, const Animated& animated) {
  api_->MakeCurrent();
  const std::vector<std::vector<std::uint8_t>> palette = {PalettesOrMeshPalette(mesh, palettes, instances)};
  const RunShape shape = CheckRunShape(mesh, kernels, palette.front().size(), instances, api_->name());
  api_->CheckRun(mesh, kernels, shape);
  Prepared prepared = PrepareSets(mesh, kernels, palette, shape, SetOptions{true, ""}, 1);
  if (animated.animation && animated.kernel) {
    Animate(prepared, 0, *animated.animation, *animated.kernel);
    WritePalette(prepared, 0, animated.states);
    Settle();
    api_->FinishUploads(prepared.impl_->key);
  }
  const Prepared::Impl& p = *prepared.impl_;
  FrameRun run = p.Run(FrameUse::kVerify);
  run.frames = {p.Frame(0)};
  std::vector<std::vector<double>> times = api_->RunFrames(run);
  RunResult result;
  if (!times.empty()) result.launch_ms = std::move(times.front());
  ReadChecked(p, mesh, shape, result);
  return result;
}

// Reads the outputs of Run's set back, checks the guards, counts vertices never written.
void Runner::ReadChecked(const Prepared::Impl& p, const PackedMesh& mesh, const RunShape& shape, RunResult& result) {
  const Prepared::Impl::Set& set = p.sets.front();
  const auto read_back = [&](const DeviceBuffer& buffer, Output output, std::vector<std::uint8_t>& out) {
    const char* what = SpecOf(output).argument;
    const std::size_t out_bytes = p.out_bytes[static_cast<std::size_t>(output)];
    std::vector<std::uint8_t> bytes(out_bytes + kGuardBytes);
    api_->Read(buffer, bytes, std::string("'") + what + "'", false);
    const OutputCheck check = CheckGuardAndCountPoisoned(bytes, out_bytes, OutputStrideBytes(mesh.variant, output),
                                                         shape.out_vertices);
    if (!check.guard_ok)
      Fail("guard", p.key + ": " + what + ": the " + api_->OutputWriter(mesh.variant) + " " +
                        GuardFailure(check, out_bytes));
    result.poisoned_vertices += check.poisoned_vertices;
    out = std::move(bytes);
  };
  for (const OutputSpec& output : kOutputs) {
    if (const DeviceBuffer* buffer = set.outputs[static_cast<std::size_t>(output.output)])
      read_back(*buffer, output.output, result.Bytes(output.output));
  }
}

// ---------------------------------------------------------------- timing

Prepared Runner::Prepare(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                         std::span<const std::vector<std::uint8_t>> palettes, int instances, int palette_slots) {
  api_->MakeCurrent();
  if (palettes.empty()) Fail("launch", "no palette (input set) to time " + mesh.variant.Key() + " with");
  RunShape shape;
  for (const std::vector<std::uint8_t>& palette : palettes)
    shape = CheckRunShape(mesh, kernels, palette.size(), instances, api_->name());
  api_->CheckRun(mesh, kernels, shape);
  Prepared prepared = PrepareSets(mesh, kernels, palettes, shape, SetOptions{}, palette_slots);
  api_->FinishUploads(prepared.impl_->key);  // the uploads are done before anything is timed
  return prepared;
}

// Wall time of warm-up bursts before any timed frame (TimingPolicy::warm_until_stable):
// at least the first, at most the second.
constexpr double kWarmupMs = 200.0;
constexpr double kWarmupMaxMs = 1000.0;
// Warmth lasts across variants, checked by measurement: after a full warm-up
// the runner times a small copy (the clock probe: kProbeBytes, the median of
// a few runs) and keeps the fastest such time; before the next variant it
// times the probe again, and when the probe is within kStillWarm of that
// time the clock is still up, so the variant needs only the steadiness check
// (two bursts in a row within 3%), not the 200 ms floor. A probe slower than
// that (the driver lowered the clock while the device waited for the next
// kernel's compile, its verification and its uploads) means a full warm-up,
// as before. A probe that fails means a full warm-up too.
constexpr std::size_t kProbeBytes = 8u << 20;
constexpr double kStillWarm = 1.15;
// Within kStillBusyMs of the device's last timed or warm-up frames (the
// tuner times a variant's burst length, the variant and its copy back to
// back) the clock has had no time to fall: no probe, no warm-up.
constexpr double kStillBusyMs = 10.0;
// Warm-up bursts start at kWarmupFirstFrames frames and double (up to
// kWarmupMaxFrames) until one keeps the device busy for kWarmupBurstMs.
constexpr int kWarmupFirstFrames = 16;
constexpr int kWarmupMaxFrames = 4096;
constexpr double kWarmupBurstMs = 4.0;

std::optional<double> Runner::ProbeMs(const Prepared::Impl& p) {
  try {
    if (p.launches.empty()) return std::nullopt;
    const Lang lang = p.launches.front()->spec.variant.lang;
    if (!probe_ || probe_lang_ != lang) {
      probe_ = std::make_unique<Prepared>(PrepareCopy(lang, kProbeBytes, 1));
      probe_lang_ = lang;
    }
    std::vector<double> ms = TimeFrames(*probe_->impl_, 1, 5, 1);
    if (ms.empty()) return std::nullopt;
    std::sort(ms.begin(), ms.end());
    const double median = ms[ms.size() / 2];
    if (!(median > 0.0)) return std::nullopt;
    return median;
  } catch (const Error&) {
    return std::nullopt;
  }
}

// SKINTUNE_TIMING_LOG=FILE appends one line per warm-up decision (the probe,
// the warm probe, full or short warm-up, its wall time and bursts) to FILE:
// a diagnostic for devices whose clocks move (docs/PERFORMANCE.md). "-"
// writes to standard error instead (a run whose files are not kept).
const char* TimingLogPath() {
  static const char* path = std::getenv("SKINTUNE_TIMING_LOG");
  return path && *path ? path : nullptr;
}

void AppendTimingLog(const std::string& line) {
  const char* path = TimingLogPath();
  if (!path) return;
  const double now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  if (std::strcmp(path, "-") == 0) {
    std::fprintf(stderr, "%.3f %s\n", now, line.c_str());
  } else if (std::FILE* f = std::fopen(path, "a")) {
    std::fprintf(f, "%.3f %s\n", now, line.c_str());
    std::fclose(f);
  }
}

void Runner::WarmUntilStable(const Prepared::Impl& p) {
  using Clock = std::chrono::steady_clock;
  const auto ms_since = [](Clock::time_point t) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
  };
  if (warm_probe_ms_ && busy_until_ && ms_since(*busy_until_) < kStillBusyMs) {
    TimingLog([&] { return p.key + " no warm-up: busy " + std::to_string(ms_since(*busy_until_)) + " ms ago"; });
    return;
  }
  bool warm = false;
  double probed = -1.0;
  if (warm_probe_ms_) {
    const std::optional<double> probe = ProbeMs(p);
    probed = probe ? *probe : -1.0;
    warm = probe && *probe <= kStillWarm * *warm_probe_ms_;
    if (warm) warm_probe_ms_ = std::min(*warm_probe_ms_, *probe);
  }
  const double floor_ms = warm ? 0.0 : kWarmupMs;
  const auto start = Clock::now();
  double previous = 0.0;  // ms per frame of the last burst of the same size
  int bursts = 0, frames_per_burst = kWarmupFirstFrames;
  double after = -1.0;
  bool capped = false;  // stopped by kWarmupMaxMs
  for (std::size_t frame = 0;; ++bursts) {
    FrameRun burst = p.Run(FrameUse::kTime);
    for (int i = 0; i < frames_per_burst; ++i, ++frame) burst.frames.push_back(p.Frame(frame % p.sets.size()));
    burst.untimed = static_cast<int>(burst.frames.size());
    const auto burst_start = Clock::now();
    api_->RunFrames(burst);  // waits for the burst
    const double elapsed = ms_since(burst_start), total = ms_since(start);
    if (total >= kWarmupMaxMs) {
      capped = true;
      break;
    }
    // Still warm (the probe says the clock is up): one burst long enough to
    // keep the device busy is all it needs.
    if (warm && elapsed >= kWarmupBurstMs) break;
    const double per_frame = elapsed / frames_per_burst;
    // Keep the device busy: a burst shorter than kWarmupBurstMs is mostly
    // the host's submit and wait, and a device busy a third of the time is
    // not raised from its idle clock (Vulkan on the H100 stayed at ~600 MHz
    // through 200 ms of 16-frame bursts). Double it and start the
    // steadiness check again.
    if (elapsed < kWarmupBurstMs && frames_per_burst < kWarmupMaxFrames) {
      frames_per_burst *= 2;
      previous = 0.0;
      continue;
    }
    const bool steady = previous > 0.0 && std::abs(per_frame - previous) <= 0.03 * previous;
    previous = per_frame;
    if (total < floor_ms || !steady) continue;
    if (warm || !warm_probe_ms_) break;
    // A full warm-up ends only when the clock probe is back within
    // kStillWarm of the fastest probe seen: steady at a low clock is not warm.
    const std::optional<double> probe = ProbeMs(p);
    if (!probe) break;
    after = *probe;
    if (*probe <= kStillWarm * *warm_probe_ms_) break;
  }
  const double warm_ms = ms_since(start);
  busy_until_ = Clock::now();
  if (!warm) {
    // Just warmed: the probe's time at this clock (the fastest seen is kept).
    // After a whole second of load the clock is as high as it gets now: a
    // probe still slower than the fastest seen (a lucky one, or a device
    // slower since: NVIDIA's Vulkan on the H100 late in a tuning run) is the
    // new reference, or every later variant would pay the full second again.
    if (const std::optional<double> probe = ProbeMs(p)) {
      after = *probe;
      warm_probe_ms_ = warm_probe_ms_ && !capped ? std::min(*warm_probe_ms_, *probe) : *probe;
    }
  }
  TimingLog([&] {
    return p.key + (warm ? " short" : capped ? " full (capped)" : " full") + " warm-up " + std::to_string(warm_ms) + " ms, " +
           std::to_string(bursts + 1) + " bursts of up to " + std::to_string(frames_per_burst) + " frames; probe " +
           std::to_string(probed) + " ms before, " + std::to_string(after) + " after, warm probe " +
           std::to_string(warm_probe_ms_.value_or(-1.0));
  });
}

std::vector<double> Runner::Time(const Prepared& prepared, int warmup, int bursts, int burst_frames) {
  Settle();
  api_->MakeCurrent();
  const Prepared::Impl* p = prepared.impl_.get();
  if (!p || p->sets.empty()) Fail("launch", "Time: nothing prepared");
  warmup = std::max(warmup, 0);
  bursts = std::max(bursts, 0);
  burst_frames = std::max(burst_frames, 1);
  if (api_->timing_policy().warm_until_stable) WarmUntilStable(*p);
  const auto start = std::chrono::steady_clock::now();
  std::vector<double> ms = TimeFrames(*p, warmup, bursts, burst_frames);
  if (!ms.empty()) {
    // The host's wall time over every frame of the call (warm-up frames
    // included, and the final wait): an upper bound of the device's time, a
    // check on the device timers in the log.
    const double wall_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    TimingLog([&] {
      std::vector<double> sorted = ms;
      std::sort(sorted.begin(), sorted.end());
      return p->key + " timed: " + std::to_string(bursts) + " bursts of " + std::to_string(burst_frames) +
             " frames, median " + std::to_string(sorted[sorted.size() / 2]) + " ms, min " +
             std::to_string(sorted.front()) + ", max " + std::to_string(sorted.back()) + "; wall " +
             std::to_string(wall_ms / (warmup + bursts * burst_frames)) + " ms per frame";
    });
  }
  return ms;
}

std::vector<double> Runner::TimeFrames(const Prepared::Impl& p, int warmup, int bursts, int burst_frames) {
  FrameRun run = p.Run(FrameUse::kTime);
  run.untimed = warmup;
  run.burst = burst_frames;
  for (int frame = 0; frame < warmup + bursts * burst_frames; ++frame)
    run.frames.push_back(p.Frame(static_cast<std::size_t>(frame) % p.sets.size()));
  std::vector<double> ms;
  for (const std::vector<double>& burst : api_->RunFrames(run)) {
    if (burst.size() != 1)
      Fail("launch", "timing " + p.key + ": the device gave " + std::to_string(burst.size()) + " times for a burst");
    ms.push_back(burst.front() / burst_frames);
  }
  busy_until_ = std::chrono::steady_clock::now();
  return ms;
}

Prepared Runner::PrepareFlush(Lang lang, std::size_t read_bytes) {
  const CopyKernel flush = EmitFlush(lang, read_bytes);
  const std::vector<std::vector<std::uint8_t>> palette = {flush.mesh.palette};
  return Prepare(flush.mesh, std::span(&flush.kernel, 1), palette);
}

std::vector<double> Runner::TimeCold(const Prepared& prepared, const Prepared& flush, int untimed, int samples,
                                     std::vector<std::vector<double>>* launch_ms, const std::function<void()>& before_each) {
  Settle();
  api_->MakeCurrent();
  const Prepared::Impl* p = prepared.impl_.get();
  const Prepared::Impl* f = flush.impl_.get();
  if (!p || p->sets.empty() || !f || f->sets.empty()) Fail("launch", "TimeCold: nothing prepared");
  if (api_->timing_policy().warm_until_stable) WarmUntilStable(*p);
  untimed = std::max(untimed, 0);
  samples = std::max(samples, 0);
  // One device submission of frames [first, first + count), the first `skip` untimed.
  auto run_frames = [&](int first, int count, int skip) {
    FrameRun run = p->Run(FrameUse::kCold);
    run.untimed = skip;
    run.flush = f->Frame(0);
    for (int frame = first; frame < first + count; ++frame)
      run.frames.push_back(p->Frame(static_cast<std::size_t>(frame) % p->sets.size()));
    return api_->RunFrames(run);
  };
  std::vector<std::vector<double>> frames;
  if (!before_each) {
    frames = run_frames(0, untimed + samples, untimed);
  } else {
    if (untimed > 0) (void)run_frames(0, untimed, untimed);
    for (int s = 0; s < samples; ++s) {
      before_each();
      for (std::vector<double>& frame : run_frames(untimed + s, 1, 0)) frames.push_back(std::move(frame));
    }
  }
  std::vector<double> ms;
  if (frames.size() != static_cast<std::size_t>(samples))
    Fail("launch", "timing " + p->key + ": the device gave " + std::to_string(frames.size()) + " frames of " +
                       std::to_string(samples));
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const std::vector<double>& launches = frames[i];
    const std::size_t expected = p->Frame((static_cast<std::size_t>(untimed) + i) % p->sets.size()).size();
    if (launches.size() != expected)
      Fail("launch", "timing " + p->key + ": the device gave " + std::to_string(launches.size()) + " launch times for a frame of " +
                         std::to_string(expected));
    double sum = 0.0;
    for (const double launch : launches) sum += launch;
    ms.push_back(sum);
  }
  if (launch_ms) *launch_ms = std::move(frames);
  busy_until_ = std::chrono::steady_clock::now();
  return ms;
}

double Runner::FrameMs(Prepared& prepared, int untimed, int frames) {
  using Clock = std::chrono::steady_clock;
  const bool animated = prepared.impl_ && !prepared.impl_->sets.empty() && prepared.impl_->sets.front().animated;
  const auto frame = [&] {
    if (animated) AdvanceAnimation(prepared, 0, kFrameDelta);
    LaunchSet(prepared, 0);
  };
  for (int i = 0; i < std::max(untimed, 0); ++i) frame();
  Finish();
  frames = std::max(frames, 1);
  const Clock::time_point start = Clock::now();
  for (int i = 0; i < frames; ++i) frame();
  Finish();
  busy_until_ = Clock::now();
  return std::chrono::duration<double, std::milli>(*busy_until_ - start).count() / frames;
}

int Runner::BurstFrames(const Prepared& prepared, int warmup, double burst_ms) {
  std::vector<double> one = Time(prepared, warmup, 3, 1);
  if (one.empty()) return 1;
  std::sort(one.begin(), one.end());
  const double frame_ms = one[one.size() / 2];
  if (!(frame_ms > 0.0) || !(burst_ms > 0.0)) return frame_ms > 0.0 ? 1 : kMaxBurstFrames;
  // The power of two nearest to burst_ms / frame_ms on a log scale: bursts of
  // 0.71 to 1.41 x burst_ms.
  const double wanted = std::clamp(burst_ms / frame_ms, 1.0, static_cast<double>(kMaxBurstFrames));
  return 1 << static_cast<int>(std::lround(std::log2(wanted)));
}

Prepared Runner::PrepareCopy(Lang lang, std::size_t bytes, int input_sets) {
  const CopyKernel copy = EmitCopy(lang, bytes);
  const std::vector<std::vector<std::uint8_t>> palettes(static_cast<std::size_t>(std::max(input_sets, 1)),
                                                        copy.mesh.palette);
  Prepared prepared = Prepare(copy.mesh, std::span<const KernelSource>(&copy.kernel, 1), palettes);
  prepared.impl_->key = "the copy of " + std::to_string(CopyBytes(copy)) + " bytes";
  return prepared;
}

// ---------------------------------------------------------------- skinning

// The palette ring (runner.h): frame n+1's palette goes into the slot after
// frame n's, once that slot's last frame (as many frames back as there are
// slots) is done.
// A slot written and never launched needs no fence of its own (no launch
// reads it before its next upload); the API's Staging waits for its last
// upload instead (upload_fenced false). Where the API orders uploads after
// the launches before them (OrdersUploadsAfterLaunches: GL), the fence follows
// the slot's upload instead of each launch, and covers it.
namespace {

// Waits until `slot`'s fence (when it has one) is signalled: the calls of its
// last upload and launch made (`submit`'s, where the runner has one), then the
// device's work up to them. `name_of()` names the fence in errors (made on its first wait).
template <typename Name>
void AwaitSlot(DeviceApi& device, SubmitThread* submit, Prepared::Impl::Slot& slot, const Name& name_of) {
  // With a submit thread: only the calls of this slot's last upload and launch
  // must have been made (its fence exists), not those of the frames since.
  if (submit) submit->WaitFor(slot.submitted);
  if (slot.done) {
    if (slot.fence_name.empty()) slot.fence_name = name_of();
    // With a submit thread: one query here, and when the fence is not yet
    // signalled the thread polls it (SubmitThread::Await), so the caller does
    // not wait in the driver beside the thread's calls. The query first: when
    // the thread, not the device, sets the pace, the fence is long signalled
    // and handing the check over would wait for the thread's current call.
    if (!submit) {
      device.Wait(*slot.done, slot.fence_name);
    } else if (!device.Signalled(*slot.done, slot.fence_name)) {
      DeviceApi* api = &device;
      DeviceObject& fence = *slot.done;
      const std::string& name = slot.fence_name;
      submit->Await(
          [api, &fence, &name] {
            api->MakeCurrent();
            return api->Signalled(fence, name);
          },
          [api, &fence, &name] {
            api->MakeCurrent();
            api->Wait(fence, name);
          });
    }
  }
}

}  // namespace

std::size_t Runner::TakeNextSlot(Prepared& prepared, int set) {
  Prepared::Impl::Set& s = SetOf(prepared.impl_.get(), set, *api_);
  const Prepared::Impl& p = *prepared.impl_;
  const std::size_t next = (s.current + 1) % s.slots.size();
  Prepared::Impl::Slot& slot = s.slots[next];
  if (slot.paced_by) {  // fused: the fence of the last frame that read the slot, or of a later one
    AwaitSlot(*api_, submit_.get(), s.pace[*slot.paced_by],
              [&] { return "frame " + std::to_string(*slot.paced_by) + " of the fused frames of " + p.key; });
  } else {
    AwaitSlot(*api_, submit_.get(), slot, [&] { return "palette slot " + std::to_string(next) + " of " + p.key; });
  }
  return next;
}

std::span<std::uint8_t> Runner::PaletteStaging(Prepared& prepared, int set) {
  api_->MakeCurrent();
  Prepared::Impl::Set& s = SetOf(prepared.impl_.get(), set, *api_);
  const Prepared::Impl& p = *prepared.impl_;
  if (p.Animated() && !s.animated)
    Fail("launch", "input set " + std::to_string(set) + " of " + p.key + " is not animated and its others are: animate every set");
  const std::size_t next = TakeNextSlot(prepared, set);
  Prepared::Impl::Slot& slot = s.slots[next];
  const std::span<std::uint8_t> staging = api_->Staging(slot.Uploaded(), p.key, slot.UploadFenced(*api_));
  if (staging.size() < p.upload_bytes)
    Fail("launch", "the palette staging of " + p.key + " has " + std::to_string(staging.size()) + " bytes, the frame " +
                       std::to_string(p.upload_bytes));
  s.staged = next;
  s.staging = staging.first(p.upload_bytes);
  return s.staging;
}

std::span<std::uint8_t> Runner::MorphWeightsStaging(Prepared& prepared, int set) {
  api_->MakeCurrent();
  Prepared::Impl::Set& s = SetOf(prepared.impl_.get(), set, *api_);
  const Prepared::Impl& p = *prepared.impl_;
  if (!s.staged) Fail("launch", "MorphWeightsStaging of " + p.key + " without PaletteStaging");
  Prepared::Impl::Slot& slot = s.slots[*s.staged];
  if (!slot.morph_weights) Fail("launch", p.key + " skins no morph targets: it has no morph weights");
  return api_->Staging(*slot.morph_weights, p.key, slot.UploadFenced(*api_)).first(slot.morph_weights->bytes());
}

namespace {

// Queues the uploads of a slot's staged buffers: `palette` (its first
// `palette_bytes`; null: none) and the morph weights where the slot has them,
// then its fence where the API runs uploads after the launches queued before
// them; on the submit thread where there is one (the Prepared drains it
// before `key` and the slot go).
void QueueSlotUploads(DeviceApi& api, SubmitThread* submit, Prepared::Impl::Slot& slot, DeviceBuffer* palette,
                      std::size_t palette_bytes, const std::string& key) {
  DeviceBuffer* morph_weights = slot.morph_weights;
  const bool mark = api.OrdersUploadsAfterLaunches();
  const auto uploads = [&api, palette, palette_bytes, morph_weights, &key, &slot, mark] {
    if (palette) api.Upload(*palette, palette_bytes, key);
    if (morph_weights) api.Upload(*morph_weights, morph_weights->bytes(), key);
    if (mark) api.Mark(slot.done, key);
  };
  if (!submit) return uploads();
  slot.submitted = submit->Push([&api, uploads] {
    api.MakeCurrent();
    uploads();
  });
}

}  // namespace

void Runner::UploadPalette(Prepared& prepared, int set) {
  api_->MakeCurrent();
  Prepared::Impl::Set& s = SetOf(prepared.impl_.get(), set, *api_);
  const Prepared::Impl& p = *prepared.impl_;
  if (!s.staged) Fail("launch", "UploadPalette of " + p.key + " without PaletteStaging");
  Prepared::Impl::Slot& slot = s.slots[*s.staged];
  QueueSlotUploads(*api_, submit_.get(), slot, &slot.Uploaded(), p.upload_bytes, p.key);
  slot.launched = false;
  slot.prologue_pending = slot.palette_launches > 0;
  slot.fresh = true;
  slot.delta = 0.0f;
  s.elapsed = 0.0;
  if (s.fused) {  // kept for AdvanceAnimation's rebase
    s.uploaded_states.resize(static_cast<std::size_t>(p.instances));
    std::memcpy(s.uploaded_states.data(), s.staging.data(), std::min(s.staging.size(), s.uploaded_states.size() * sizeof(AnimInstance)));
  }
  s.current = *s.staged;
  s.staged.reset();
}

// The size is checked first: a rejected palette takes no slot.
void Runner::WritePalette(Prepared& prepared, int set, std::span<const std::uint8_t> palettes) {
  const std::size_t expected = prepared.impl_ ? prepared.impl_->upload_bytes : 0;
  if (palettes.size() != expected)
    Fail("launch", "palettes have " + std::to_string(palettes.size()) + " bytes, expected " + std::to_string(expected));
  const std::span<std::uint8_t> staging = PaletteStaging(prepared, set);
  std::copy(palettes.begin(), palettes.end(), staging.begin());
  UploadPalette(prepared, set);
}

void Runner::LaunchSet(Prepared& prepared, int set, void* out_positions) {
  api_->MakeCurrent();
  Prepared::Impl::Set& s = SetOf(prepared.impl_.get(), set, *api_);
  const Prepared::Impl& p = *prepared.impl_;
  Prepared::Impl::Slot& slot = s.slots[s.current];
  FrameRun run;
  run.use = FrameUse::kLive;
  const std::span<const std::unique_ptr<DeviceObject>> launches = slot.launches;
  run.frames = {launches.subspan(slot.palette_launches)};
  if (slot.prologue_pending) {
    run.prologue = launches.first(slot.palette_launches);
    run.prologue_after_frames = s.slots.size() < 2;
    run.scalars = {{kAnimDelta, std::bit_cast<std::uint32_t>(slot.delta)}, {kAnimFresh, slot.fresh ? 1u : 0u}};
  }
  if (s.fused) run.scalars = {{kAnimElapsed, std::bit_cast<std::uint32_t>(static_cast<float>(s.elapsed))}};
  slot.prologue_pending = false;
  run.key = p.key;
  run.out_positions = out_positions;
  // A fused frame marks its pace fence only, which also stands for the
  // slot's: an upload into the slot waits for it (TakeNextSlot), or for a
  // later frame's where the fence was marked again since.
  const bool mark = !api_->OrdersUploadsAfterLaunches();
  Prepared::Impl::Slot* pace = s.fused && mark ? &s.pace[s.paced] : nullptr;
  if (pace) {
    slot.paced_by = s.paced;
    s.paced = (s.paced + 1) % s.pace.size();
  }
  if (submit_ && !out_positions) {
    DeviceApi* api = api_.get();
    const std::string& key = p.key;
    slot.submitted = submit_->Push([api, run = std::move(run), &slot, &key, mark, pace] {
      api->MakeCurrent();
      api->RunFrames(run);
      if (pace) {
        api->Mark(pace->done, key);
      } else if (mark) {
        api->Mark(slot.done, key);
      }
    });
    if (pace) pace->submitted = slot.submitted;
  } else {
    Settle();  // the positions go into the caller's buffer now (interop)
    api_->RunFrames(run);
    if (pace) {
      api_->Mark(pace->done, p.key);
    } else if (mark) {
      api_->Mark(slot.done, p.key);
    }
  }
  slot.launched = true;
}

namespace {

// An animation's buffer of set `s` (its objects keep it) holding `bytes`,
// at least 16 (OpenCL has no empty buffers); `allocated` grows by its size.
DeviceBuffer* KeptBuffer(DeviceApi& api, Prepared::Impl::Set& s, const std::string& name,
                         std::span<const std::uint8_t> bytes, BufferUse use, std::size_t& allocated) {
  std::vector<std::uint8_t> padded(bytes.begin(), bytes.end());
  padded.resize(std::max<std::size_t>(padded.size(), 16), 0);
  allocated += padded.size();
  std::unique_ptr<DeviceBuffer> buffer = api.Allocate(use, padded.size(), padded.data(), name);
  DeviceBuffer* raw = buffer.get();
  s.objects.push_back(std::move(buffer));
  return raw;
}

// K instances in the rest pose: what an animated set shows until its first upload.
std::vector<AnimInstance> RestPose(int instances) {
  std::vector<AnimInstance> rest(static_cast<std::size_t>(instances));
  for (AnimInstance& in : rest) in.clip = kAnimRestPose;
  return rest;
}

}  // namespace

void Runner::Animate(Prepared& prepared, int set, const AnimationView& animation, const PaletteKernel& kernel) {
  api_->MakeCurrent();
  Settle();
  Prepared::Impl& p = *prepared.impl_;
  Prepared::Impl::Set& s = SetOf(&p, set, *api_);
  if (s.animated) Fail("launch", "input set " + std::to_string(set) + " of " + p.key + " is animated already");
  if (kernel.fused) {
    AnimateFused(prepared, set, animation);
    return;
  }
  const std::vector<KernelArgument>& declared = kernel.kernel.arguments;
  const auto output = std::find_if(declared.begin(), declared.end(), [](const KernelArgument& a) { return a.name == kAnimOutput; });
  if (output == declared.end()) Fail("launch", "the palette kernel of " + p.key + " declares no '" + kAnimOutput + "'");
  const std::size_t joints = animation.joints.size();
  if (p.palettes_bytes != static_cast<std::size_t>(p.instances) * joints * output->element_bytes)
    Fail("launch", "the palette kernel writes " + std::to_string(joints) + " joints of " +
                       std::to_string(output->element_bytes) + " bytes for each of " + std::to_string(p.instances) +
                       " instances, the palettes of " + p.key + " have " + std::to_string(p.palettes_bytes) + " bytes");
  LaunchSpec spec;
  spec.variant = kernel.variant;
  spec.source = kernel.kernel;
  spec.count = static_cast<std::uint32_t>(kernel.kernel.launch.wg_size);  // one work-group per instance
  spec.instances = p.instances;
  spec.instanced = true;
  spec.palette_joints = joints;
  spec.where = "the palette kernel of " + p.key;
  spec.feeds_frame = true;
  const bool first = !p.palette_kernel;  // the first set animated: the kernel is planned, its bytes counted
  if (first) {
    p.palette_kernel = api_->Plan(spec);
  } else if (HashOf(p.palette_kernel->spec.source) != HashOf(spec.source)) {
    Fail("launch", "input set " + std::to_string(set) + " of " + p.key + ": another palette kernel than its other sets'");
  }
  // The animation's buffers, uploaded once (at least 16 bytes: OpenCL has no
  // empty buffers); `allocated` counts them and what Bind adds.
  std::size_t allocated = 0;
  const auto upload = [&](const std::string& name, std::span<const std::uint8_t> bytes, BufferUse use) {
    return KeptBuffer(*api_, s, name, bytes, use, allocated);
  };
  const auto bytes_of = [](auto span) {
    return std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(span.data()), span.size_bytes());
  };
  const std::vector<AnimInstance> rest_pose = RestPose(p.instances);
  // Shared by the slots: the animation, and the states the kernel keeps
  // (read and written by it: an output's buffer; the rest pose to start).
  std::map<std::string, DeviceBuffer*> shared = {
      {kAnimStates, upload(kAnimStates, bytes_of(std::span<const AnimInstance>(rest_pose)), BufferUse::kOutput)}};
  for (const KernelArgument& a : p.palette_kernel->spec.source.arguments)  // the animation's own buffers
    if (a.kind == ArgumentKind::kBuffer && a.name != kAnimOutput && a.name != kAnimInputs[5] && a.name != kAnimStates)
      shared[a.name] = upload(a.name, AnimationBufferBytes(animation, a.name), BufferUse::kInput);
  // Each slot: its instances (the rest pose until the first upload) and the
  // kernel bound to write its palette; arguments by name.
  for (std::size_t k = 0; k < s.slots.size(); ++k) {
    Prepared::Impl::Slot& slot = s.slots[k];
    slot.instances = upload(kAnimInputs[5], bytes_of(std::span<const AnimInstance>(rest_pose)), BufferUse::kInput);
    std::vector<ArgumentBinding> arguments;
    for (const KernelArgument& a : p.palette_kernel->spec.source.arguments) {
      if (a.kind == ArgumentKind::kScalar) {
        arguments.push_back({&a, ArgumentRole::kScalar, nullptr, nullptr});
      } else if (a.name == kAnimOutput) {
        arguments.push_back({&a, ArgumentRole::kOutput, slot.palette, nullptr});
      } else if (a.name == kAnimInputs[5]) {
        arguments.push_back({&a, ArgumentRole::kInput, slot.instances, nullptr});
      } else if (const auto found = shared.find(a.name); found != shared.end()) {
        arguments.push_back({&a, ArgumentRole::kInput, found->second, nullptr});
      } else {
        Fail("launch", "the palette kernel of " + p.key + " takes an argument '" + a.name + "' the runner does not bind");
      }
    }
    slot.launches.insert(slot.launches.begin(), api_->Bind(*p.palette_kernel, arguments, SetOptions{}, allocated));
    slot.palette_launches = 1;
    slot.prologue_pending = true;
    slot.fresh = true;
  }
  api_->FinishUploads(p.key);
  p.upload_bytes = static_cast<std::size_t>(p.instances) * sizeof(AnimInstance);
  if (first) p.bytes_per_set += allocated;
  s.animated = true;
}

void Runner::AnimateFused(Prepared& prepared, int set, const AnimationView& animation) {
  Prepared::Impl& p = *prepared.impl_;
  Prepared::Impl::Set& s = SetOf(&p, set, *api_);
  if (p.palette_kernel) Fail("launch", "input set " + std::to_string(set) + " of " + p.key + ": fused, and its other sets are not");
  const bool first = p.fused_launches.empty();  // the first set animated: the kernels are planned, their bytes counted
  for (std::size_t l = 0; l < p.launches.size(); ++l) {
    LaunchSpec spec = p.launches[l]->spec;
    try {
      spec.source = EmitFused(spec.source, animation);
    } catch (const Error& e) {
      Fail("build", p.key + ": " + e.what());
    }
    spec.where += " (its palette made in the launch)";
    if (first) {
      p.fused_launches.push_back(api_->Plan(spec));
    } else if (HashOf(p.fused_launches[l]->spec.source) != HashOf(spec.source)) {
      Fail("launch", "input set " + std::to_string(set) + " of " + p.key + ": another animation than its other sets'");
    }
  }
  std::size_t allocated = 0;
  const auto upload = [&](const std::string& name, std::span<const std::uint8_t> bytes) {
    return KeptBuffer(*api_, s, name, bytes, BufferUse::kInput, allocated);
  };
  // The animation's buffers the fused kernels read (records, clips; local records: nodes and joints), by name.
  std::map<std::string, DeviceBuffer*> records;
  if (p.fused_launches.empty()) Fail("launch", p.key + ": no skin launches to fuse the palette into");
  for (const KernelArgument& a : p.fused_launches.front()->spec.source.arguments)
    if (a.kind != ArgumentKind::kScalar && !AnimationBufferBytes(animation, a.name).empty())
      records[a.name] = upload(a.name, AnimationBufferBytes(animation, a.name));
  const std::vector<AnimInstance> rest_pose = RestPose(p.instances);
  const std::span<const std::uint8_t> rest(reinterpret_cast<const std::uint8_t*>(rest_pose.data()),
                                           rest_pose.size() * sizeof(AnimInstance));
  api_->Finish();  // the launches bound before are replaced: nothing queued may still use them
  for (Prepared::Impl::Slot& slot : s.slots) {
    slot.instances = upload(kAnimInputs[5], rest);
    for (std::size_t l = 0; l < p.fused_launches.size(); ++l) {
      // The fused kernel's arguments by name: the animation's, the slot's
      // instances, and every other as AddSet bound the skin kernel's.
      std::vector<ArgumentBinding> arguments;
      for (const KernelArgument& a : p.fused_launches[l]->spec.source.arguments) {
        if (a.kind == ArgumentKind::kScalar) {
          arguments.push_back({&a, ArgumentRole::kScalar, nullptr, nullptr});
        } else if (records.contains(a.name) || a.name == kAnimInputs[5]) {
          arguments.push_back({&a, ArgumentRole::kInput,
                               a.name == kAnimInputs[5] ? slot.instances : records.at(a.name), nullptr});
        } else if (a.name == kMorphWeightsArgument) {
          arguments.push_back({&a, ArgumentRole::kInput, slot.morph_weights, nullptr});
        } else {
          const auto bound = std::find_if(s.bindings[l].begin(), s.bindings[l].end(),
                                          [&](const ArgumentBinding& b) { return b.argument->name == a.name; });
          if (bound == s.bindings[l].end() || !bound->buffer)
            Fail("launch", "the fused kernel of " + p.key + " takes an argument '" + a.name + "' the runner does not bind");
          arguments.push_back({&a, bound->role, bound->buffer, bound->view});
        }
      }
      slot.launches[l] = api_->Bind(*p.fused_launches[l], arguments, s.options, allocated);
    }
    slot.palette_launches = 0;
    slot.prologue_pending = false;
    slot.fresh = true;
  }
  api_->FinishUploads(p.key);
  p.upload_bytes = static_cast<std::size_t>(p.instances) * sizeof(AnimInstance);
  if (first) p.bytes_per_set += allocated;
  s.animated = true;
  s.fused = true;
  s.elapsed = 0.0;
  s.uploaded_states = rest_pose;
  // Where the API orders uploads after the launches before them (GL) nothing is marked, as for every set there.
  // A fused frame holds no buffer, so its bound is the caller's latency only:
  // as many frames back as the ring has slots, or twice what the API gathers
  // into one submission (Vulkan's 8) where that is more, so that a loop waiting
  // for the frame that far back fills one submission while the device runs the
  // one before (H200, 2026-12-01: Vulkan's pipelined fused frame 28.2-28.4 us
  // paced 3 back, 26.4 at 6, 25.5 at 9, 25.0 at 16, Skin-only 24.1-24.4).
  if (!api_->OrdersUploadsAfterLaunches())
    s.pace = std::vector<Prepared::Impl::Slot>(std::max(s.slots.size(), 2 * api_->FramesPerSubmission()));
  s.clip_ranges.assign(animation.clip_ranges.begin(), animation.clip_ranges.end());
}

void Runner::AdvanceAnimation(Prepared& prepared, int set, float delta, std::span<const std::uint8_t> morph_weights) {
  api_->MakeCurrent();
  Prepared::Impl::Set& s = SetOf(prepared.impl_.get(), set, *api_);
  const Prepared::Impl& p = *prepared.impl_;
  if (!s.animated)
    Fail("launch", "AdvanceAnimation of input set " + std::to_string(set) + " of " + p.key + ", which is not animated (Animate)");
  if (s.fused) {  // nothing goes up: the clocks' step travels with the next launches (LaunchSet)
    if (!morph_weights.empty())
      Fail("launch", "AdvanceAnimation of " + p.key + ": morph weights for a set whose launches make their palettes "
                                                      "(fused): a fused Skinner skins no morph targets");
    if (!s.pace.empty())
      AwaitSlot(*api_, submit_.get(), s.pace[s.paced],
                [&] { return "frame " + std::to_string(s.paced) + " of the fused frames of " + p.key; });
    s.elapsed += delta;
    if (std::abs(s.elapsed) > kFusedRebaseSeconds) {
      // A float32 time that far from the upload's loses precision the clips
      // would show: upload the states advanced instead, as the device
      // advances them (one frame's K records every kFusedRebaseSeconds).
      AnimationView clips;
      clips.clip_ranges = s.clip_ranges;
      clips.clip_count = static_cast<std::uint32_t>(s.clip_ranges.size() / 4);
      std::vector<AnimInstance> states = s.uploaded_states;
      AdvanceAnimInstances(clips, states, static_cast<float>(s.elapsed));
      WritePalette(prepared, set, {reinterpret_cast<const std::uint8_t*>(states.data()), states.size() * sizeof(AnimInstance)});
    }
    return;
  }
  const std::size_t next = TakeNextSlot(prepared, set);
  Prepared::Impl::Slot& slot = s.slots[next];
  if ((slot.morph_weights != nullptr) != !morph_weights.empty() ||
      (slot.morph_weights && morph_weights.size() != slot.morph_weights->bytes()))
    Fail("launch", "AdvanceAnimation of " + p.key + ": " + std::to_string(morph_weights.size()) +
                       " bytes of morph weights, the slot holds " +
                       std::to_string(slot.morph_weights ? slot.morph_weights->bytes() : 0));
  if (slot.morph_weights) {  // the frame's weights into this slot's buffer (its palette is computed on the device)
    const std::span<std::uint8_t> staging = api_->Staging(*slot.morph_weights, p.key, slot.UploadFenced(*api_));
    std::copy(morph_weights.begin(), morph_weights.end(), staging.begin());
    QueueSlotUploads(*api_, submit_.get(), slot, nullptr, 0, p.key);
  }
  slot.launched = false;
  slot.prologue_pending = true;
  slot.fresh = false;
  slot.delta = delta;
  s.current = next;
  s.staged.reset();  // a staging given and never uploaded takes no slot
}

std::span<const std::uint8_t> Runner::ReadOutput(const Prepared& prepared, int set, Output output) {
  return ReadOutputChunks(prepared, set, output, 0).bytes;
}

DeviceApi::PinnedRead Runner::ReadOutputChunks(const Prepared& prepared, int set, Output output, std::size_t chunk_bytes) {
  Settle();
  api_->MakeCurrent();
  const Prepared::Impl::Set& s = SetOf(prepared.impl_.get(), set, *api_);
  const Prepared::Impl& p = *prepared.impl_;
  const DeviceBuffer* buffer = s.outputs[static_cast<std::size_t>(output)];
  if (!buffer) Fail("launch", std::string("no ") + SpecOf(output).what + " output in " + p.key);
  const std::string what = std::string("'") + SpecOf(output).argument + "' of " + p.key;
  const std::size_t out_bytes = p.out_bytes[static_cast<std::size_t>(output)];
  if (chunk_bytes == 0 || chunk_bytes >= out_bytes) return {api_->ReadPinned(*buffer, out_bytes, what), [](std::size_t) {}};
  return api_->ReadPinnedChunks(*buffer, out_bytes, chunk_bytes, what);
}

void* Runner::OutputBuffer(const Prepared& prepared, int set, Output output) const {
  const Prepared::Impl::Set& s = SetOf(prepared.impl_.get(), set, *api_);
  const DeviceBuffer* buffer = s.outputs[static_cast<std::size_t>(output)];
  return buffer ? buffer->native() : nullptr;
}

int Runner::PaletteSlot(const Prepared& prepared, int set) const {
  return static_cast<int>(SetOf(prepared.impl_.get(), set, *api_).current);
}

void Runner::Finish() {
  Settle();
  api_->MakeCurrent();
  api_->Finish();
}

// ---------------------------------------------------------------- shared by the APIs

std::size_t DeviceApi::PaletteBufferBytes(const RunShape& shape, std::span<const KernelSource>) const {
  return static_cast<std::size_t>(shape.instances) * shape.palette_bytes;
}

const char* DeviceApi::OutputWriter(const Variant&) const { return "kernel"; }

void CheckLaunchKernel(const LaunchSpec& spec, const std::string& api) {
  const Variant& variant = spec.variant;
  const KernelSource& source = spec.source;
  if (source.lang != variant.lang)
    throw Error(api + " launch: " + spec.where + ": kernel language " + Name(source.lang) + " for a " +
                Name(variant.lang) + " variant");
  if ((variant.storage == PaletteStorage::kConstant || variant.storage == PaletteStorage::kLocal) &&
      source.joints != static_cast<int>(spec.palette_joints))
    throw Error(api + " launch: " + spec.where + ": kernel sized for " + std::to_string(source.joints) +
                " joints, the palette has " + std::to_string(spec.palette_joints));
}

std::uint32_t ScalarOf(const FrameRun& run, const std::string& name, const std::string& api) {
  for (const auto& [scalar, value] : run.scalars)
    if (scalar == name) return value;
  throw Error(api + " launch: " + run.key + ": no value for the palette kernel's scalar '" + name + "'");
}

std::string HashOf(const KernelSource& source) {
  return source.source_hash.empty() ? SourceHash(source.text) : source.source_hash;
}

}  // namespace skintune::internal
