// skintune (internal): what a Skinner is made of.
//
// Skinner::Create (skinner.cpp) does everything that is the same on every
// backend: it validates the MeshView into a SkinnedMesh, chooses the variant
// (Select with the constraints of the real device and mesh), packs the mesh
// and emits the kernels. A SkinnerBackend (RunnerSkinner, or an API's
// runtime/backends/<api>/skinner_<api>.cpp) then owns the device buffers: it
// uploads the packed inputs once through the runner's Prepare, and per frame
// writes the palette, launches and reads back, all in the packed vertex
// order; Skinner puts read-backs into the mesh's order.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "generator/emit.h"
#include "generator/packer.h"
#include "generator/palette_kernel.h"
#include "runtime/api_errors.h"
#include "runtime/device.h"
#include "skintune/skintune.h"

namespace skintune::internal {

class SkinnerBackend {
 public:
  virtual ~SkinnerBackend() = default;
  // Throws ApiError(kInvalidState) when the backend cannot be used now (GL:
  // its context is not current on this thread).
  virtual void CheckUsable() const {}
  // Every instance's palette, one after another (PackPalette of K x J
  // matrices), in two steps: the page-locked staging to pack them into (may
  // wait for the palette ring's slot), then its upload. A staging never
  // uploaded changes nothing.
  virtual std::span<std::uint8_t> PaletteStaging() = 0;
  // Morph variants: the staged slot's morph weights (K x T float32), between
  // PaletteStaging and UploadPalette, which uploads them with the palettes.
  virtual std::span<std::uint8_t> MorphWeightsStaging() = 0;
  virtual void UploadPalette() = 0;
  // From now on the palettes are the palette kernel's (Runner::Animate):
  // PaletteStaging and UploadPalette then take K AnimInstance records.
  virtual void Animate(const AnimationView& animation, const PaletteKernel& kernel) = 0;
  // The next frame advances the states kept on the device by `delta` seconds
  // instead of uploading any (Runner::AdvanceAnimation).
  // `morph_weights`: a morph Skinner's K instances' weights (float32), uploaded into the slot.
  virtual void AdvanceAnimation(float delta, std::span<const std::uint8_t> morph_weights) = 0;
  virtual void Skin() = 0;
  // Waits until every Skin() so far has completed on the device.
  virtual void Finish() = 0;
  // Gives the positions (or normals, or tangents) in packed order, instance after
  // instance (instances x vertex_count x output stride), in the backend's
  // page-locked read-back staging (valid until the next Read), read back in
  // chunks of `chunk_bytes` (0: at once) after the work queued so far:
  // `ready(end)` waits until the first `end` bytes are in (runner.h
  // ReadOutputChunks).
  virtual DeviceApi::PinnedRead Read(Output output, std::size_t chunk_bytes) = 0;
  // The native buffer of `output` (null where the Skinner writes none).
  virtual void* DeviceOutput(Output output) const = 0;
  // Default: kUnavailable.
  virtual void SkinIntoGlBuffer(unsigned int gl_buffer);
  // Default: kUnavailable (Vulkan's Skinner records into the command buffer).
  virtual void SkinIntoVulkan(void* command_buffer, void* buffer);
};

// The code for a runner's Error: its message names the stage ("OpenCL
// build: ...", "CUDA setup: ..."): build -> kBuildFailed, else kDeviceError.
ErrorCode CodeOfRunnerError(const std::string& message);

// Runs `call` (a runner's), turning its Error into the ApiError of its stage,
// prefixed with `context` when given; ApiErrors pass through unchanged.
template <typename F>
void RunOnDevice(F&& call, const std::string& context = "") {
  try {
    call();
  } catch (const ApiError&) {
    throw;
  } catch (const Error& e) {
    FailWith(CodeOfRunnerError(e.what()), context + e.what());
  }
}

// The one input set a Skinner prepares (with SkinnerOptions::palette_buffers
// palette slots): `instances` copies of the mesh's rest-pose palette
// (SetPalette overwrites it before the first Skin).
std::vector<std::vector<std::uint8_t>> RestPalettes(const PackedMesh& mesh, int instances);

// A SkinnerBackend over one prepared input set of the device's runner
// (runtime/runner.h): WritePalette, LaunchSet, Finish, ReadOutput,
// OutputBuffer. An API's Skinner glue (the make_skinner of its entry in
// runtime/backend_table.h) derives from it to add what differs.
class RunnerSkinner : public SkinnerBackend {
 public:
  RunnerSkinner(Runner& runner, Prepared prepared) : runner_(runner), prepared_(std::move(prepared)) {}

  std::span<std::uint8_t> PaletteStaging() override {
    std::span<std::uint8_t> staging;
    RunOnDevice([&] { staging = runner_.PaletteStaging(prepared_, 0); });
    return staging;
  }
  std::span<std::uint8_t> MorphWeightsStaging() override {
    std::span<std::uint8_t> staging;
    RunOnDevice([&] { staging = runner_.MorphWeightsStaging(prepared_, 0); });
    return staging;
  }
  void UploadPalette() override {
    RunOnDevice([&] { runner_.UploadPalette(prepared_, 0); });
  }
  void Animate(const AnimationView& animation, const PaletteKernel& kernel) override {
    RunOnDevice([&] { runner_.Animate(prepared_, 0, animation, kernel); }, "Skinner::CreateAnimated: ");
  }
  void AdvanceAnimation(float delta, std::span<const std::uint8_t> morph_weights) override {
    RunOnDevice([&] { runner_.AdvanceAnimation(prepared_, 0, delta, morph_weights); });
  }
  void Skin() override {
    RunOnDevice([&] { runner_.LaunchSet(prepared_, 0); });
  }
  void Finish() override {
    RunOnDevice([&] { runner_.Finish(); });
  }
  DeviceApi::PinnedRead Read(Output output, std::size_t chunk_bytes) override {
    DeviceApi::PinnedRead out;
    RunOnDevice([&] { out = runner_.ReadOutputChunks(prepared_, 0, output, chunk_bytes); });
    return out;
  }
  // A cl_mem, or a CUdeviceptr / GL buffer name as a pointer-sized integer.
  void* DeviceOutput(Output output) const override { return runner_.OutputBuffer(prepared_, 0, output); }

 protected:
  Runner& runner_;
  Prepared prepared_;
};

// The runner's Prepare of the one input set a Skinner uses (RestPalettes),
// its Error turned into ApiError ("Skinner::Create: " + the runner's message):
// kBuildFailed when a kernel does not compile, kDeviceError when the device
// refuses (allocation, launch set-up). `kernels`: one per launch, instanced
// when setup.instances > 1; setup.palette_buffers palette slots.
Prepared PrepareSkinnerSet(DeviceState& device, const PackedMesh& mesh, const std::vector<KernelSource>& kernels,
                           const SkinnerSetup& setup);

// The Skinner of an API that needs nothing more than RunnerSkinner.
std::unique_ptr<SkinnerBackend> MakeRunnerSkinner(DeviceState& device, const PackedMesh& mesh,
                                                  const std::vector<KernelSource>& kernels, const SkinnerSetup& setup);

// SKINTUNE_TIMING_LOG (runtime/runner.h): where a Skinner's SetPalette host
// time went (the wait for a free palette buffer, the packing, the hand-over
// of the upload), summed; logged in one line when it goes (nothing without
// a call).
struct SetPaletteTimes {
  std::uint64_t calls = 0;
  double wait_s = 0.0, pack_s = 0.0, upload_s = 0.0;
  ~SetPaletteTimes();
};

}  // namespace skintune::internal

namespace skintune {

struct Skinner::Impl {
  // Waits for the frames still on the device (quietly: a lost device or a GL
  // context no longer current has nothing to wait for), so that no driver
  // thread works on them after the Skinner, or the program, is gone. Hidden:
  // skintune.map's `skintune::Skinner::*` would export it, and it is no API.
  __attribute__((visibility("hidden"))) ~Impl();

  std::shared_ptr<internal::DeviceState> device;  // keeps the runner (and its programs) alive
  Selection selection;
  internal::Variant variant;
  std::size_t vertex_count = 0;
  int joint_count = 0;
  int instances = 1;
  std::size_t output_stride = 0;
  std::vector<std::uint32_t> order;     // packed position p holds mesh vertex order[p]
  bool identity_order = false;          // order[p] == p: a read-back of float3 is one memcpy
  SceneShape shape = SceneShape::kSingle;
  std::vector<std::size_t> vertex_offsets;  // per mesh of a batch (one for Create), then vertex_count
  std::vector<int> joint_offsets;           // per mesh, then joint_count
  bool palette_set = false;
  bool skinned = false;
  bool animated = false;     // CreateAnimated: SetAnimation, not SetPalette
  bool cross_fades = true;   // SkinnerOptions::cross_fades: SetAnimation takes weights above 0
  int animation_count = 0;   // the model's (the packed clips, in order)
  std::size_t animation_bytes = 0;     // on the device (PackedAnimation::Bytes)
  std::vector<BakedClip> baked_clips;  // SkinnerOptions::bake_rate's
  int morph_targets = 0;     // per instance (0: none)
  std::vector<float> morph_weights;  // instances x morph_targets: uploaded with every SetPalette
  // The read-back's overflow bound (ReadPositions; OutputBound and
  // CannotOverflow, runtime/host_work.h): every position output's |component|
  // is at most output_bound x the largest |element| of the palette it was
  // skinned with; palette_magnitude is the last SetPalette's largest
  // |element|, skinned_magnitude the largest of the palettes the output read
  // back may have been written with.
  double output_bound = 0.0;
  float palette_magnitude = 0.0f;
  float skinned_magnitude = 0.0f;
  unsigned palette_threads = 0;  // SkinnerOptions::palette_threads (0: all the palette crew's)
  std::unique_ptr<internal::SetPaletteTimes> set_palette_times;  // null while SKINTUNE_TIMING_LOG is off
  std::unique_ptr<internal::SkinnerBackend> backend;  // declared last: destroyed before `device`
};

}  // namespace skintune
