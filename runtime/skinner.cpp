// The public Skinner (skintune/skintune.h): what is the same on every backend.
#include "runtime/skinner.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <thread>

#include <glm/glm.hpp>

#include "generator/clip_packer.h"
#include "generator/constraints.h"
#include "generator/palette_kernel.h"
#include "model/mesh.h"
#include "model/scene.h"
#include "runtime/api_errors.h"
#include "runtime/host_work.h"
#include "runtime/model_access.h"
#include "runtime/runner.h"
#include "runtime/selection.h"
#include "runtime/winners_db.h"

namespace skintune::internal {

namespace {

constexpr std::size_t kMaxVertices = std::size_t{1} << 31;  // launches address vertices with 32-bit counts
constexpr int kMaxJoints = 65536;                          // SkinnedMesh stores joint indices in 16 bits

// The MeshView as a validated SkinnedMesh (normals and tangents only when
// wanted: tangents come with normals); errors start with `where`
// ("Skinner::Create: MeshView", "Skinner::CreateBatch: meshes[2]").
SkinnedMesh ToSkinnedMesh(const MeshView& view, bool normals, bool tangents, const std::string& where) {
  auto BadMesh = [&](const std::string& message) { FailWith(ErrorCode::kInvalidArgument, where + ": " + message); };
  if (view.vertex_count == 0) BadMesh("vertex_count is 0");
  if (view.vertex_count > kMaxVertices)
    BadMesh("vertex_count " + std::to_string(view.vertex_count) + " above " + std::to_string(kMaxVertices));
  if (view.influences < 1 || view.influences > kMaxInfluences)
    BadMesh("influences " + std::to_string(view.influences) + " outside 1..8");
  if (view.joint_count < 1 || view.joint_count > kMaxJoints)
    BadMesh("joint_count " + std::to_string(view.joint_count) + " outside 1..65536");
  if (!view.positions) BadMesh("positions is null");
  if (!view.joints) BadMesh("joints is null");
  if (!view.weights) BadMesh("weights is null");
  if (normals && !view.normals) BadMesh("SkinnerOptions::normals is set but MeshView::normals is null");
  if (tangents && !view.tangents) BadMesh("SkinnerOptions::tangents is set but MeshView::tangents is null");
  if (tangents && !view.normals)
    BadMesh("SkinnerOptions::tangents is set but MeshView::normals is null (tangents are skinned with normals)");

  SkinnedMesh mesh;
  mesh.name = "MeshView";
  mesh.influences = view.influences;
  mesh.joint_count = view.joint_count;
  const std::size_t n = view.vertex_count;
  const auto b = static_cast<std::size_t>(view.influences);
  mesh.positions.resize(n);
  std::memcpy(mesh.positions.data(), view.positions, n * sizeof(glm::vec3));
  if (normals || tangents) {
    mesh.normals.resize(n);
    std::memcpy(mesh.normals.data(), view.normals, n * sizeof(glm::vec3));
  }
  if (tangents) {
    mesh.tangents.resize(n);
    std::memcpy(mesh.tangents.data(), view.tangents, n * sizeof(glm::vec4));
  }
  mesh.joints.resize(n * b);
  for (std::size_t i = 0; i < n * b; ++i) {
    const std::uint32_t joint = view.joints[i];
    if (joint >= static_cast<std::uint32_t>(view.joint_count))
      BadMesh("vertex " + std::to_string(i / b) + " slot " + std::to_string(i % b) + ": joint " +
              std::to_string(joint) + " out of range (" + std::to_string(view.joint_count) + " joints)");
    mesh.joints[i] = static_cast<std::uint16_t>(joint);
  }
  mesh.weights.assign(view.weights, view.weights + n * b);
  if (view.morph_target_count < 0 || view.morph_target_count > kMaxMorphTargets)
    BadMesh("morph_target_count " + std::to_string(view.morph_target_count) + " outside 0.." +
            std::to_string(kMaxMorphTargets));
  if (view.morph_target_count > 0) {
    if (!view.morph_positions) BadMesh("morph_target_count is " + std::to_string(view.morph_target_count) +
                                       " but morph_positions is null");
    MorphTargets& m = mesh.morph;
    m.where = "MeshView morph targets";
    const auto targets = static_cast<std::size_t>(view.morph_target_count);
    const auto copy = [&](const float* from, std::vector<std::vector<glm::vec3>>& into) {
      for (std::size_t t = 0; t < targets; ++t) {
        into.emplace_back(n);
        std::memcpy(into.back().data(), from + t * n * 3, n * sizeof(glm::vec3));
      }
    };
    copy(view.morph_positions, m.positions);
    if ((normals || tangents) && view.morph_normals) copy(view.morph_normals, m.normals);
    if (tangents && view.morph_tangents) copy(view.morph_tangents, m.tangents);
    m.weights.assign(targets, 0.0);
    if (view.morph_weights) m.weights.assign(view.morph_weights, view.morph_weights + targets);
  }
  const ValidationReport report = Validate(mesh, ValidateOptions{kWeightSumTolerance, 1});
  if (!report.ok()) BadMesh(report.Summary());
  return mesh;
}

int LargestInfluenceCount(const SkinnedMesh& mesh) {
  int largest = 1;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) largest = std::max(largest, mesh.InfluencesOf(v));
  return largest;
}

std::string Joined(const std::vector<Violation>& violations) {
  std::string out;
  for (const Violation& v : violations) out += (out.empty() ? "" : "; ") + std::string(Name(v.constraint)) + ": " + v.message;
  return out;
}

// SkinnerOptions::normal_format as the variant axis spells it.
NormalFormat NormalFormatOf(skintune::NormalFormat format) {
  static_assert(static_cast<int>(skintune::NormalFormat::kSnorm8) == static_cast<int>(NormalFormat::kSnorm8));
  return static_cast<NormalFormat>(static_cast<int>(format));
}

// The constraints `v`'s skin kernel breaks on `shape`: where the palettes
// come from (the variant's animation, the shape's animated) is the
// Skinner's, checked apart.
std::vector<Violation> SkinKernelViolations(Variant v, const DeviceLimits& limits, ProblemShape shape) {
  v.animation = Animation::kHost;
  shape.animated = false;
  return CheckVariant(v, limits, shape);
}

Chosen Forced(const std::string& call, const std::string& key, const DeviceState& device, const ProblemShape& shape,
              bool dual_quaternions, NormalFormat normal_format) {
  Variant v;
  try {
    v = ParseVariantKey(key);
  } catch (const Error& e) {
    FailWith(ErrorCode::kInvalidArgument, call + ": SkinnerOptions::variant: " + e.what());
  }
  v.normals = NormalsFor(shape.has_normals, shape.has_tangents);
  const std::string where = call + ": SkinnerOptions::variant " + v.Key() + ": ";
  if (PacksNormals(v) && v.normal_format != normal_format)
    FailWith(ErrorCode::kInvalidArgument, where + "it writes " + Name(v.normal_format) +
                                              " normals, and SkinnerOptions::normal_format asks for " +
                                              Name(normal_format));
  if (SkinsNormals(v)) v.normal_format = normal_format;
  if (std::find(device.langs.begin(), device.langs.end(), v.lang) == device.langs.end())
    FailWith(ErrorCode::kInvalidArgument,
             where + "language " + Name(v.lang) + " does not run on " + BackendName(device.info.backend) + " devices");
  if ((v.blend == Blend::kDualQuaternion) != dual_quaternions)
    FailWith(ErrorCode::kInvalidArgument,
             where + (dual_quaternions ? "SkinnerOptions::dual_quaternions asks for blend dq, and this variant blends "
                                         "linearly"
                                       : "blend dq skins with dual quaternions: set SkinnerOptions::dual_quaternions"));
  if (v.mixed == MixedCounts::kBucketed)
    FailWith(ErrorCode::kInvalidArgument,
             where + "bucketed variants reorder the vertices, and a Skinner keeps the mesh's order on the device; "
                     "use the padded twin");
  if (AnimatesOnDevice(v) && !shape.animated)
    FailWith(ErrorCode::kInvalidArgument, where + "animation " + Name(v.animation) +
                                              " makes the palettes on the device: a Skinner::CreateAnimated's form, "
                                              "and this Skinner takes them from SetPalette");
  const std::vector<Violation> violations = SkinKernelViolations(v, device.limits, shape);
  if (!violations.empty()) FailWith(ErrorCode::kInvalidArgument, where + Joined(violations));
  Chosen chosen;
  chosen.variant = v;
  chosen.selection.variant = v.Key();
  chosen.selection.level = MatchLevel::kForced;
  chosen.selection.entry = "SkinnerOptions::variant";
  chosen.selection.reason = "forced by SkinnerOptions::variant";
  return chosen;
}

Skinner::Impl& Usable(const std::unique_ptr<Skinner::Impl>& impl, const char* call) {
  if (!impl) FailWith(ErrorCode::kInvalidState, std::string("Skinner::") + call + ": the Skinner was used after move");
  impl->backend->CheckUsable();
  return *impl;
}

// `what` (how `expected` is made up) is built only for the error: SetPalette runs every frame.
template <typename What>
void CheckCount(const char* call, std::size_t given, std::size_t expected, What&& what) {
  if (given != expected)
    FailWith(ErrorCode::kInvalidArgument, std::string("Skinner::") + call + ": float_count is " + std::to_string(given) +
                                              ", expected " + what() + " = " + std::to_string(expected));
}

}  // namespace

void SkinnerBackend::SkinIntoGlBuffer(unsigned int) {
  FailWith(ErrorCode::kUnavailable, "Skinner::SkinIntoGlBuffer: only OpenCL devices with GL sharing write into GL buffers");
}

void SkinnerBackend::SkinIntoVulkan(void*, void*) {
  FailWith(ErrorCode::kUnavailable, "Skinner::SkinIntoVulkan: only Vulkan devices record into a VkCommandBuffer");
}

ErrorCode CodeOfRunnerError(const std::string& message) {
  const std::size_t space = message.find(' ');
  return message.compare(space + 1, 6, "build:") == 0 ? ErrorCode::kBuildFailed : ErrorCode::kDeviceError;
}

std::vector<std::vector<std::uint8_t>> RestPalettes(const PackedMesh& mesh, int instances) {
  std::vector<std::vector<std::uint8_t>> palettes(1);
  for (int k = 0; k < instances; ++k) palettes[0].insert(palettes[0].end(), mesh.palette.begin(), mesh.palette.end());
  return palettes;
}

static_assert(kDefaultPaletteBuffers == kPaletteSlots, "the Skinner's default palette ring is the runner's");
static_assert(kMaxPaletteThreads == static_cast<int>(kMaxPaletteLanes), "palette_threads' range is the palette crew's");
static_assert(kMaxBakeRate == kAnimMaxBakeRate, "bake_rate's range is the clip packer's");

Prepared PrepareSkinnerSet(DeviceState& device, const PackedMesh& mesh, const std::vector<KernelSource>& kernels,
                           const SkinnerSetup& setup) {
  if (!device.runner) FailWith(ErrorCode::kInvalidState, "Skinner::Create: the Device has no runner");
  Prepared prepared;
  RunOnDevice([&] {
    prepared = device.runner->Prepare(mesh, kernels, RestPalettes(mesh, setup.instances), setup.instances,
                                      setup.palette_buffers);
  },
              "Skinner::Create: ");
  return prepared;
}

std::unique_ptr<SkinnerBackend> MakeRunnerSkinner(DeviceState& device, const PackedMesh& mesh,
                                                  const std::vector<KernelSource>& kernels, const SkinnerSetup& setup) {
  Prepared prepared = PrepareSkinnerSet(device, mesh, kernels, setup);
  return std::make_unique<RunnerSkinner>(*device.runner, std::move(prepared));
}

namespace {

// The meshes validated one by one; a batch concatenated as one mesh
// (ConcatenateMeshes, model/scene.h). Throws ApiError.
MeshBatch SceneOf(const std::string& call, const MeshView* views, std::size_t count, bool batch,
                  const SkinnerOptions& options) {
  std::vector<SkinnedMesh> meshes;
  for (std::size_t m = 0; m < count; ++m)
    meshes.push_back(
        ToSkinnedMesh(views[m], options.normals, options.tangents, call + (batch ? ": meshes[" + std::to_string(m) + "]" : ": MeshView")));
  MeshBatch scene;
  if (batch) {
    std::vector<const SkinnedMesh*> pointers;
    for (const SkinnedMesh& mesh : meshes) pointers.push_back(&mesh);
    try {
      scene = ConcatenateMeshes(pointers);
    } catch (const Error& e) {
      FailWith(ErrorCode::kInvalidArgument, call + ": " + e.what());
    }
  } else {
    scene.mesh = std::move(meshes.front());
    scene.vertex_offsets = {0, scene.mesh.vertex_count()};
    scene.joint_offsets = {0, scene.mesh.joint_count};
  }
  const auto instances = static_cast<std::size_t>(options.instances);
  if (instances * scene.mesh.vertex_count() >= (std::size_t{1} << 32))
    FailWith(ErrorCode::kInvalidArgument, call + ": " + std::to_string(instances) + " instances x " +
                                              std::to_string(scene.mesh.vertex_count()) +
                                              " vertices exceed the kernels' 32-bit output indices");
  return scene;
}

// The skin kernel's problem shape of a Skinner of `mesh`: rigid joints
// assumed (SetPalette refuses each matrix that is not, dual quaternions
// only); a mesh that has morph targets takes a morph variant whatever its
// first weights, as SetMorphWeights may move it any frame.
ProblemShape SkinShapeOf(const SkinnedMesh& mesh, const SkinnerOptions& options) {
  return WithMorphOf({mesh.joint_count, LargestInfluenceCount(mesh), options.normals || options.tangents,
                      options.instances, options.tangents, true},
                     mesh.morph);
}

// The variant for the scene: forced, or the winners database's choice for
// its shape and total size (a bucketed winner runs padded). Throws ApiError.
Chosen ChooseVariant(const std::string& call, const std::vector<WinnersEntry>& entries, DeviceState& state,
                     const SkinnedMesh& mesh, SceneShape scene_shape, std::size_t count,
                     const SkinnerOptions& options) {
  ProblemShape shape = SkinShapeOf(mesh, options);
  // CreateAnimated: the palettes are made on the device; the skin kernel's
  // constraints are checked without it (SkinKernelViolations).
  shape.animated = call == "Skinner::CreateAnimated";
  if (!options.variant.empty())
    return Forced(call, options.variant, state, shape, options.dual_quaternions, NormalFormatOf(options.normal_format));
  SelectionRequest request;
  request.device = state.info;
  request.langs = state.langs;
  request.influences = shape.max_influences;
  request.vertex_count = static_cast<std::size_t>(options.instances) * mesh.vertex_count();
  request.shape = static_cast<SceneKind>(scene_shape);
  request.instances = options.instances;
  request.meshes = static_cast<int>(count);
  request.normals = NormalsFor(options.normals, options.tangents);
  request.dual_quaternions = options.dual_quaternions;
  request.normal_format = NormalFormatOf(options.normal_format);
  request.morph = mesh.has_morph();
  request.morph_targets = static_cast<int>(mesh.morph.count());
  request.animated = shape.animated;
  request.cross_fades = options.cross_fades;
  request.tuned_form = options.bake_rate == kBakeRateTuned;
  request.max_error = options.max_error;
  request.max_error_name = "SkinnerOptions::max_error";
  // Weights already on a format's grid cost nothing in it, whatever the tuning dataset's did.
  for (WeightFormat format : {WeightFormat::kUnorm16, WeightFormat::kUnorm8})
    if (HoldsWeightsExactly(mesh, format)) request.exact_formats.push_back(format);
  request.limits = state.limits;
  request.check = [&](const Variant& v) { return Joined(SkinKernelViolations(v, state.limits, shape)); };
  Chosen chosen = Select(entries, request);
  if (chosen.variant.mixed == MixedCounts::kBucketed) {
    // Bucketed kernels write vertices grouped by influence count; the padded twin keeps the mesh's order.
    chosen.variant.mixed = MixedCounts::kPadded;
    chosen.selection.variant = chosen.variant.Key();
    chosen.selection.reason += "; the bucketed winner runs padded (mesh order kept on the device)";
  }
  return chosen;
}

// Create and CreateBatch: the scene (SceneOf), then one path for both: the
// variant chosen for the scene's shape and total size, packed, emitted and
// prepared on the device.
// `entries`: the WinnersDb's (null when it was moved from). Throws ApiError.
std::unique_ptr<Skinner::Impl> CreateScene(const std::string& call, Device& device,
                                           const std::vector<WinnersEntry>* entries, const MeshView* views,
                                           std::size_t count, bool batch, const SkinnerOptions& options) {
  const std::shared_ptr<DeviceState>* state_ptr = DeviceAccess::State(device);
  if (!state_ptr) FailWith(ErrorCode::kInvalidState, call + ": the Device was used after move");
  if (!entries) FailWith(ErrorCode::kInvalidState, call + ": the WinnersDb was used after move");
  if (!views || count == 0) FailWith(ErrorCode::kInvalidArgument, call + ": the batch is empty (no meshes)");
  if (options.instances < 1)
    FailWith(ErrorCode::kInvalidArgument,
             call + ": SkinnerOptions::instances is " + std::to_string(options.instances) + ", at least 1");
  if (const std::string bad = BadMaxError(options.max_error); !bad.empty())
    FailWith(ErrorCode::kInvalidArgument, call + ": SkinnerOptions::max_error " + bad);
  if (const int format = static_cast<int>(options.normal_format); format < 0 || format > 2)
    FailWith(ErrorCode::kInvalidArgument,
             call + ": SkinnerOptions::normal_format is " + std::to_string(format) + ", not a NormalFormat");
  if (options.normal_format != skintune::NormalFormat::kF32 && !options.normals && !options.tangents)
    FailWith(ErrorCode::kInvalidArgument,
             call + ": SkinnerOptions::normal_format " + Name(NormalFormatOf(options.normal_format)) +
                 " packs normals, and the Skinner skins none (set SkinnerOptions::normals)");
  if (options.palette_buffers < kMinPaletteBuffers || options.palette_buffers > kMaxPaletteBuffers)
    FailWith(ErrorCode::kInvalidArgument, call + ": SkinnerOptions::palette_buffers is " +
                                              std::to_string(options.palette_buffers) + ", expected " +
                                              std::to_string(kMinPaletteBuffers) + " to " +
                                              std::to_string(kMaxPaletteBuffers));
  if (options.bake_rate != 0.0 && call != "Skinner::CreateAnimated")
    FailWith(ErrorCode::kInvalidArgument, call + ": SkinnerOptions::bake_rate bakes a model's clips (Skinner::"
                                                 "CreateAnimated); this Skinner takes its palettes from SetPalette");
  if (!options.cross_fades && call != "Skinner::CreateAnimated")
    FailWith(ErrorCode::kInvalidArgument, call + ": SkinnerOptions::cross_fades says whether Skinner::CreateAnimated's "
                                                 "crowd cross-fades clips; this Skinner takes its palettes from SetPalette");
  if (options.bake_space != skintune::BakeSpace::kPalette && call != "Skinner::CreateAnimated")
    FailWith(ErrorCode::kInvalidArgument, call + ": SkinnerOptions::bake_space is what Skinner::CreateAnimated "
                                                 "bakes; this Skinner takes its palettes from SetPalette");
  if (options.fuse_palette && call != "Skinner::CreateAnimated")
    FailWith(ErrorCode::kInvalidArgument, call + ": SkinnerOptions::fuse_palette makes Skinner::CreateAnimated's "
                                                 "palettes in the skin launch; this Skinner takes them from SetPalette");
  if (options.palette_threads < 0 || options.palette_threads > kMaxPaletteThreads)
    FailWith(ErrorCode::kInvalidArgument, call + ": SkinnerOptions::palette_threads is " +
                                              std::to_string(options.palette_threads) + ", expected 0 (skintune's choice) to " +
                                              std::to_string(kMaxPaletteThreads));
  DeviceState& state = **state_ptr;
  const MeshBatch scene = SceneOf(call, views, count, batch, options);
  const SkinnedMesh& mesh = scene.mesh;
  const SceneShape scene_shape = batch                   ? SceneShape::kBatch
                                 : options.instances > 1 ? SceneShape::kInstances
                                                         : SceneShape::kSingle;
  Chosen chosen = ChooseVariant(call, *entries, state, mesh, scene_shape, count, options);
  if (options.fuse_palette && options.bake_rate != kBakeRateTuned) {
    // Each work-group makes its palette into its local copy (EmitFused).
    const std::string where = call + ": SkinnerOptions::fuse_palette with " + chosen.variant.Key() + ": ";
    if (chosen.variant.lang == Lang::kCpu)
      FailWith(ErrorCode::kInvalidArgument, where + "the cpu device runs its palette kernel as a call before the skin "
                                                    "kernels', and has no work-groups' local copies to fuse it into");
    if (chosen.variant.blend == Blend::kDualQuaternion)
      FailWith(ErrorCode::kInvalidArgument, where + "palette records are matrices; it blends dual quaternions");
    if (chosen.variant.storage != PaletteStorage::kLocal) {
      chosen.variant.storage = PaletteStorage::kLocal;
      chosen.selection.reason += "; storage local: each work-group makes its palette (SkinnerOptions::fuse_palette)";
    }
    // Each work-group pays for making the palette once, so a variant not
    // tuned fused (nor forced) skins many vertices a group, as fused winners
    // do (InFusedShape, generator/variant.h).
    if (chosen.selection.level != MatchLevel::kForced && !FusesPalette(chosen.variant.animation) &&
        chosen.variant.wg_size * chosen.variant.vertices_per_item < kFusedVerticesPerGroup &&
        state.limits.max_wg_size >= kFusedGroup) {
      chosen.variant = InFusedShape(chosen.variant);
      chosen.selection.reason += "; " + std::to_string(kFusedVerticesPerGroup / kFusedGroup) +
                                 " vertices an item, strided, in groups of " + std::to_string(kFusedGroup) +
                                 ", palette rows 3x4: each group makes its palette once";
    }
    chosen.selection.variant = chosen.variant.Key();
    if (const std::vector<Violation> v = SkinKernelViolations(chosen.variant, state.limits, SkinShapeOf(mesh, options));
        !v.empty())
      FailWith(ErrorCode::kInvalidArgument, where + Joined(v));
  }

  PackedMesh packed;
  std::vector<KernelSource> kernels;
  try {
    packed = Pack(mesh, chosen.variant);
    // One instance: the plain kernel; K: the instanced one (docs/VARIANTS.md "Instancing").
    EmitOptions emit;
    emit.instanced = options.instances > 1;
    emit.max_instances = emit.instanced ? options.instances : 0;
    emit.morph_targets = packed.morph_targets;
    for (const Launch& launch : packed.launches)
      kernels.push_back(Emit(chosen.variant, launch.influences, mesh.joint_count, emit));
  } catch (const Error& e) {
    FailWith(ErrorCode::kInvalidArgument, call + ": " + chosen.variant.Key() + ": " + e.what());
  }

  auto impl = std::make_unique<Skinner::Impl>();
  Skinner::Impl& im = *impl;
  im.device = *state_ptr;
  im.selection = chosen.selection;
  im.variant = chosen.variant;
  im.vertex_count = mesh.vertex_count();
  im.joint_count = mesh.joint_count;
  im.instances = options.instances;
  im.shape = scene_shape;
  im.vertex_offsets = scene.vertex_offsets;
  im.joint_offsets = scene.joint_offsets;
  im.output_stride = packed.output_stride_bytes;
  im.order = packed.order;
  im.identity_order = true;
  for (std::size_t p = 0; p < im.order.size() && im.identity_order; ++p) im.identity_order = im.order[p] == p;
  // Morph targets move positions by weights SetMorphWeights may change any
  // frame: no bound holds, so read-backs scan first.
  im.output_bound = mesh.has_morph() ? std::numeric_limits<double>::infinity() : OutputBound(mesh);
  im.morph_targets = static_cast<int>(mesh.morph.count());
  for (int k = 0; k < options.instances; ++k)
    for (const double w : mesh.morph.weights) im.morph_weights.push_back(static_cast<float>(w));
  im.backend = state.backend->make_skinner(state, packed, kernels, {options.instances, options.palette_buffers});
  im.palette_threads = static_cast<unsigned>(options.palette_threads);
  if (internal::TimingLogPath()) im.set_palette_times = std::make_unique<internal::SetPaletteTimes>();
  return impl;
}

// A morph Skinner's weights into the staged slot, before its UploadPalette.
void StageMorphWeights(Skinner::Impl& im, const char* call) {
  if (im.morph_targets == 0) return;
  const std::span<std::uint8_t> weights = im.backend->MorphWeightsStaging();
  if (weights.size() != im.morph_weights.size() * sizeof(float))
    FailWith(ErrorCode::kDeviceError, std::string("Skinner::") + call + ": the morph weights' staging has " +
                                          std::to_string(weights.size()) + " bytes, expected " +
                                          std::to_string(im.morph_weights.size() * sizeof(float)));
  std::memcpy(weights.data(), im.morph_weights.data(), weights.size());
}

}  // namespace

}  // namespace skintune::internal

namespace skintune {

using namespace internal;  // the public calls are written over the library's internals

Skinner::Impl::~Impl() {
  if (!skinned || !backend) return;
  try {
    backend->Finish();
  } catch (const std::exception&) {  // ApiError or Error: nothing left to wait for
  }
}

Skinner::Skinner() = default;
Skinner::~Skinner() = default;
Skinner::Skinner(Skinner&&) noexcept = default;
Skinner& Skinner::operator=(Skinner&&) noexcept = default;

Result<Skinner> Skinner::Create(Device& device, const WinnersDb& db, const MeshView& mesh_view,
                                const SkinnerOptions& options) {
  return GuardedResult<Skinner>(ErrorCode::kInvalidArgument, [&] {
    Skinner skinner;
    skinner.impl_ = CreateScene("Skinner::Create", device, db.impl_ ? &db.impl_->entries : nullptr, &mesh_view, 1,
                                false, options);
    return skinner;
  });
}

Result<Skinner> Skinner::CreateAnimated(Device& device, const WinnersDb& db, const Model& model,
                                        const SkinnerOptions& options) {
  return GuardedResult<Skinner>(ErrorCode::kInvalidArgument, [&] {
    const std::string call = "Skinner::CreateAnimated";
    const SkinnedAsset* asset = ModelAccess::Asset(model);
    if (!asset) FailWith(ErrorCode::kInvalidState, call + ": the Model is empty (moved from, or default-made)");
    if (options.dual_quaternions)
      FailWith(ErrorCode::kInvalidArgument, call + ": SkinnerOptions::dual_quaternions: the palette kernel writes "
                                                   "matrices; animation on the device skins with linear blending only");
    const bool tuned = options.bake_rate == kBakeRateTuned;
    const bool hybrid = options.bake_space == skintune::BakeSpace::kHybrid;
    const bool local = options.bake_space == skintune::BakeSpace::kLocal || hybrid;  // hybrid: local records too
    if (options.bake_space != skintune::BakeSpace::kPalette && !local)
      FailWith(ErrorCode::kInvalidArgument, call + ": SkinnerOptions::bake_space is " +
                                                std::to_string(static_cast<int>(options.bake_space)) + ", not a BakeSpace");
    if (options.fuse_palette && (tuned || !(options.bake_rate > 0.0)))
      FailWith(ErrorCode::kInvalidArgument,
               call + ": SkinnerOptions::fuse_palette makes the palettes from baked records (bake_rate above 0), "
                      "and " +
                   (tuned ? std::string("bake_rate is kBakeRateTuned (the tuned entry's form decides)")
                          : "bake_rate is " + std::to_string(options.bake_rate) + " (sampled)"));
    if (local && !(options.bake_rate > 0.0))
      FailWith(ErrorCode::kInvalidArgument,
               call + ": SkinnerOptions::bake_space " + (hybrid ? "kHybrid" : "kLocal") +
                   " bakes clips at SkinnerOptions::bake_rate, which is " +
                   (tuned ? std::string("kBakeRateTuned (the tuned entry's form decides the space)")
                          : std::to_string(options.bake_rate) + " (sampled: nothing is baked)"));
    if (!tuned && options.bake_rate != 0.0 && !(options.bake_rate > 0.0 && options.bake_rate <= kMaxBakeRate))
      FailWith(ErrorCode::kInvalidArgument, call + ": SkinnerOptions::bake_rate is " +
                                                std::to_string(options.bake_rate) + ", expected 0 (sampled), (0, " +
                                                std::to_string(kMaxBakeRate) + "] frames a second or kBakeRateTuned");
    const auto pack = [&](const auto& make) {
      try {
        return make();
      } catch (const Error& e) {
        FailWith(ErrorCode::kInvalidArgument, call + ": " + e.what());
      }
    };
    const auto asked = [&] {
      return options.bake_rate > 0.0
                 ? BakeAnimation(*asset, options.bake_rate,
                                 hybrid  ? internal::BakeSpace::kHybrid
                                 : local ? internal::BakeSpace::kLocal
                                         : internal::BakeSpace::kPalette)
                 : PackAnimation(*asset);
    };
    // The clips are packed (and checked) before anything goes to the device,
    // but for a form the winners database decides, which comes with the variant.
    PackedAnimation animation;
    if (!tuned) animation = pack(asked);
    // The palette kernel animates joints; a model's morph targets stay, their
    // weights set from the host (SetMorphWeights; the model's defaults until
    // then) and uploaded with every frame, K x T floats.
    const MeshView view = model.mesh();
    Skinner skinner;
    skinner.impl_ = CreateScene(call, device, db.impl_ ? &db.impl_->entries : nullptr, &view, 1, false, options);
    Impl& im = *skinner.impl_;
    if (tuned) {  // the form the variant's entry was tuned in: sampled, or baked at its rate (host: sampled)
      animation = pack([&] {
        return AnimatesOnDevice(im.variant) ? PackForm(*asset, im.variant.animation) : PackAnimation(*asset);
      });
      im.selection.reason += std::string("; palettes ") +
                             (AnimatesOnDevice(im.variant) ? std::string("made as tuned: ") + Name(im.variant.animation)
                                                           : "sampled (kBakeRateTuned, and the entry was not tuned animated)");
    } else if (AnimatesOnDevice(im.variant) &&
               (BakeRateOf(im.variant.animation) != options.bake_rate ||
                (options.bake_rate > 0.0 && (BakesLocally(im.variant.animation) != local ||
                                             BakesHybrid(im.variant.animation) != hybrid)))) {
      im.selection.reason += std::string("; palettes made as SkinnerOptions::bake_rate asks, not as tuned (") +
                             Name(im.variant.animation) + "): kBakeRateTuned takes the tuned form";
    }
    const bool fused = tuned ? FusesPalette(im.variant.animation) : options.fuse_palette;
    if (fused && model.mesh().morph_target_count != 0)
      FailWith(ErrorCode::kInvalidArgument, call + ": " + (tuned ? "the tuned entry's " + im.variant.Key() : std::string("SkinnerOptions::fuse_palette")) +
                                                ": the palettes made in the skin launch, and the model has " +
                                                std::to_string(model.mesh().morph_target_count) +
                                                " morph targets, whose weights go up with every frame; a fused Skinner "
                                                "uploads nothing after AdvanceAnimation");
    PaletteKernel kernel;
    try {
      if (fused) {
        kernel.fused = true;  // the skin launches make the palettes (Runner::Animate)
      } else {
        kernel = EmitPalette(im.variant.lang, animation.View(), static_cast<int>(PaletteMatrixBytes(im.variant) / 16));
      }
    } catch (const Error& e) {
      FailWith(ErrorCode::kInvalidArgument, call + ": " + e.what());
    }
    im.backend->Animate(animation.View(), kernel);
    im.animated = true;
    im.cross_fades = options.cross_fades;
    im.animation_count = static_cast<int>(animation.clips.size());
    im.animation_bytes = animation.Bytes();
    for (std::size_t c = 0; c < animation.baked.size(); ++c)
      im.baked_clips.push_back({asset->animations[static_cast<std::size_t>(animation.clips[c])].name,
                                static_cast<int>(animation.baked[c].frames), animation.baked[c].bytes,
                                animation.baked[c].max_error});
    im.palette_set = true;  // the rest pose, until the first SetAnimation
    // The device's palettes are not seen by the host: every read-back is scanned before it is copied.
    im.palette_magnitude = std::numeric_limits<float>::infinity();
    return skinner;
  });
}

Result<Skinner> Skinner::CreateBatch(Device& device, const WinnersDb& db, const MeshView* meshes,
                                     std::size_t mesh_count, const SkinnerOptions& options) {
  return GuardedResult<Skinner>(ErrorCode::kInvalidArgument, [&] {
    for (std::size_t m = 0; meshes && m < mesh_count; ++m)
      if (meshes[m].morph_target_count != 0)
        FailWith(ErrorCode::kInvalidArgument,
                 "Skinner::CreateBatch: meshes[" + std::to_string(m) + "]: " +
                     std::to_string(meshes[m].morph_target_count) +
                     " morph targets: a batch skins meshes without morph targets (Skinner::Create skins one with them)");
    Skinner skinner;
    skinner.impl_ = CreateScene("Skinner::CreateBatch", device, db.impl_ ? &db.impl_->entries : nullptr, meshes,
                                mesh_count, true, options);
    return skinner;
  });
}

const Selection& Skinner::selection() const {
  static const Selection none;
  return impl_ ? impl_->selection : none;
}
std::size_t Skinner::vertex_count() const { return impl_ ? impl_->vertex_count : 0; }
int Skinner::instances() const { return impl_ ? impl_->instances : 0; }
int Skinner::joint_count() const { return impl_ ? impl_->joint_count : 0; }
SceneShape Skinner::shape() const { return impl_ ? impl_->shape : SceneShape::kSingle; }
std::size_t Skinner::mesh_count() const { return impl_ ? impl_->vertex_offsets.size() - 1 : 0; }
std::size_t Skinner::vertex_offset(std::size_t m) const { return m < mesh_count() ? impl_->vertex_offsets[m] : 0; }
std::size_t Skinner::vertex_count(std::size_t m) const {
  return m < mesh_count() ? impl_->vertex_offsets[m + 1] - impl_->vertex_offsets[m] : 0;
}
int Skinner::joint_offset(std::size_t m) const { return m < mesh_count() ? impl_->joint_offsets[m] : 0; }
int Skinner::joint_count(std::size_t m) const {
  return m < mesh_count() ? impl_->joint_offsets[m + 1] - impl_->joint_offsets[m] : 0;
}
std::size_t Skinner::output_stride_bytes() const { return impl_ ? impl_->output_stride : 0; }
void* Skinner::device_positions() const { return impl_ ? impl_->backend->DeviceOutput(Output::kPositions) : nullptr; }
void* Skinner::device_normals() const { return impl_ ? impl_->backend->DeviceOutput(Output::kNormals) : nullptr; }
void* Skinner::device_tangents() const { return impl_ ? impl_->backend->DeviceOutput(Output::kTangents) : nullptr; }
std::size_t Skinner::normal_stride_bytes() const {
  return impl_ && SkinsNormals(impl_->variant) ? OutputStrideBytes(impl_->variant, Output::kNormals) : 0;
}
std::size_t Skinner::tangent_stride_bytes() const {
  return impl_ && SkinsTangents(impl_->variant) ? OutputStrideBytes(impl_->variant, Output::kTangents) : 0;
}

Status Skinner::SetPalette(const float* matrices, std::size_t float_count) {
  return Guarded(ErrorCode::kDeviceError, [&] {
    Impl& im = Usable(impl_, "SetPalette");
    if (im.animated)
      FailWith(ErrorCode::kInvalidState,
               "Skinner::SetPalette: this Skinner computes its palettes on the device (CreateAnimated): call SetAnimation");
    const std::size_t joints = static_cast<std::size_t>(im.instances) * static_cast<std::size_t>(im.joint_count);
    CheckCount("SetPalette", float_count, joints * 16, [&] {
      return std::to_string(im.instances) + " instances x " + std::to_string(im.joint_count) + " joints x 16";
    });
    if (!matrices) FailWith(ErrorCode::kInvalidArgument, "Skinner::SetPalette: matrices is null");
    // Checked and packed in one pass straight into the next palette slot's
    // page-locked staging; a non-finite element stops before the upload, so
    // the slot is not taken and the last palette stays the Skinner's.
    using Clock = std::chrono::steady_clock;
    internal::SetPaletteTimes* times = im.set_palette_times.get();
    const Clock::time_point t0 = times ? Clock::now() : Clock::time_point{};
    const std::span<std::uint8_t> staging = im.backend->PaletteStaging();
    const Clock::time_point t1 = times ? Clock::now() : Clock::time_point{};
    if (staging.size() != joints * PaletteMatrixBytes(im.variant))
      FailWith(ErrorCode::kDeviceError, "Skinner::SetPalette: the palette staging has " + std::to_string(staging.size()) +
                                            " bytes, expected " + std::to_string(joints * PaletteMatrixBytes(im.variant)));
    float magnitude = 0.0f;
    const std::size_t bad =
        PackPaletteOnPool(matrices, joints, im.variant, staging.data(), &magnitude, im.palette_threads);
    const Clock::time_point t2 = times ? Clock::now() : Clock::time_point{};
    const auto matrix_name = [&](std::size_t j) {
      return "Skinner::SetPalette: matrix " + std::to_string(j) + " (instance " +
             std::to_string(j / static_cast<std::size_t>(im.joint_count)) + ", joint " +
             std::to_string(j % static_cast<std::size_t>(im.joint_count)) + ")";
    };
    for (std::size_t i = bad * 16; i < joints * 16 && i < (bad + 1) * 16; ++i) {
      if (std::isfinite(matrices[i])) continue;
      FailWith(ErrorCode::kInvalidArgument, matrix_name(i / 16) + " element [" + std::to_string(i % 16 / 4) + "][" +
                                                std::to_string(i % 4) + "] is " + std::to_string(matrices[i]) +
                                                ": a palette entry must be finite");
    }
    if (bad < joints) {  // finite, so not rigid: a dual-quaternion palette
      glm::mat4 m;
      std::memcpy(&m[0][0], matrices + bad * 16, sizeof m);
      FailWith(ErrorCode::kInvalidArgument, matrix_name(bad) + ": " + NotRigid(m, bad));
    }
    StageMorphWeights(im, "SetPalette");
    im.backend->UploadPalette();
    if (times) {
      const Clock::time_point t3 = Clock::now();
      ++times->calls;
      times->wait_s += std::chrono::duration<double>(t1 - t0).count();
      times->pack_s += std::chrono::duration<double>(t2 - t1).count();
      times->upload_s += std::chrono::duration<double>(t3 - t2).count();
    }
    im.palette_set = true;
    im.palette_magnitude = magnitude;
  });
}

Status Skinner::SetMorphWeights(const float* weights, std::size_t count) {
  return Guarded(ErrorCode::kDeviceError, [&] {
    Impl& im = Usable(impl_, "SetMorphWeights");
    if (im.morph_targets == 0)
      FailWith(ErrorCode::kInvalidState,
               "Skinner::SetMorphWeights: the mesh has no morph targets (MeshView::morph_target_count is 0)");
    const std::size_t expected = static_cast<std::size_t>(im.instances) * static_cast<std::size_t>(im.morph_targets);
    CheckCount("SetMorphWeights", count, expected, [&] {
      return std::to_string(im.instances) + " instances x " + std::to_string(im.morph_targets) + " morph targets";
    });
    if (!weights) FailWith(ErrorCode::kInvalidArgument, "Skinner::SetMorphWeights: weights is null");
    for (std::size_t i = 0; i < count; ++i)
      if (!std::isfinite(weights[i]))
        FailWith(ErrorCode::kInvalidArgument,
                 "Skinner::SetMorphWeights: weight " + std::to_string(i) + " (instance " +
                     std::to_string(i / static_cast<std::size_t>(im.morph_targets)) + ", target " +
                     std::to_string(i % static_cast<std::size_t>(im.morph_targets)) + ") is " +
                     std::to_string(weights[i]) + ": a weight must be finite");
    im.morph_weights.assign(weights, weights + count);
  });
}

int Skinner::morph_target_count() const { return impl_ ? impl_->morph_targets : 0; }

Status Skinner::SetAnimation(const AnimationState* states, std::size_t count) {
  return Guarded(ErrorCode::kDeviceError, [&] {
    Impl& im = Usable(impl_, "SetAnimation");
    if (!im.animated)
      FailWith(ErrorCode::kInvalidState,
               "Skinner::SetAnimation: this Skinner takes palettes (SetPalette); Skinner::CreateAnimated makes one "
               "that animates on the device");
    CheckCount("SetAnimation", count, static_cast<std::size_t>(im.instances),
               [&] { return std::to_string(im.instances) + " instances"; });
    if (!states) FailWith(ErrorCode::kInvalidArgument, "Skinner::SetAnimation: states is null");
    // Every state checked before the staging is taken (a rejected frame takes
    // no slot), then written straight into it, as SetPalette packs palettes.
    const auto bad = [&](std::size_t i, const std::string& what) {
      FailWith(ErrorCode::kInvalidArgument, "Skinner::SetAnimation: states[" + std::to_string(i) + "]." + what);
    };
    const auto clip = [&](std::size_t i, const char* field, int animation) {
      if (animation < -1 || animation >= im.animation_count)
        bad(i, std::string(field) + " is " + std::to_string(animation) + ", expected -1 (the rest pose) to " +
                   std::to_string(im.animation_count - 1));
      return animation < 0 ? kAnimRestPose : static_cast<std::uint16_t>(animation);
    };
    const auto instance = [&](std::size_t i) {
      const AnimationState& a = states[i];
      if (!std::isfinite(a.time)) bad(i, "time is not finite");
      if (!std::isfinite(a.time2)) bad(i, "time2 is not finite");
      if (!(a.weight >= 0.0f && a.weight <= 1.0f)) bad(i, "weight is " + std::to_string(a.weight) + ", outside [0, 1]");
      if (a.weight != 0.0f && !im.cross_fades)
        bad(i, "weight is " + std::to_string(a.weight) +
                   ": this Skinner's crowd does not cross-fade clips (SkinnerOptions::cross_fades is false, so its "
                   "kernels' recorded errors hold no blend's)");
      return AnimInstance{clip(i, "animation", a.animation),
                          a.weight != 0.0f ? clip(i, "animation2", a.animation2) : kAnimRestPose, a.time, a.time2,
                          a.weight};
    };
    for (std::size_t i = 0; i < count; ++i) (void)instance(i);
    const std::span<std::uint8_t> staging = im.backend->PaletteStaging();
    if (staging.size() != count * sizeof(AnimInstance))
      FailWith(ErrorCode::kDeviceError, "Skinner::SetAnimation: the staging has " + std::to_string(staging.size()) +
                                            " bytes, expected " + std::to_string(count * sizeof(AnimInstance)));
    for (std::size_t i = 0; i < count; ++i) {
      const AnimInstance in = instance(i);
      std::memcpy(staging.data() + i * sizeof in, &in, sizeof in);
    }
    StageMorphWeights(im, "SetAnimation");
    im.backend->UploadPalette();
  });
}

Status Skinner::AdvanceAnimation(float seconds) {
  return Guarded(ErrorCode::kDeviceError, [&] {
    Impl& im = Usable(impl_, "AdvanceAnimation");
    if (!im.animated)
      FailWith(ErrorCode::kInvalidState,
               "Skinner::AdvanceAnimation: this Skinner takes palettes (SetPalette); Skinner::CreateAnimated makes one "
               "that animates on the device");
    if (!std::isfinite(seconds))
      FailWith(ErrorCode::kInvalidArgument, "Skinner::AdvanceAnimation: seconds is " + std::to_string(seconds) +
                                                ", not finite");
    im.backend->AdvanceAnimation(
        seconds, std::span(reinterpret_cast<const std::uint8_t*>(im.morph_weights.data()),
                           im.morph_weights.size() * sizeof(float)));
  });
}

bool Skinner::animated() const { return impl_ && impl_->animated; }
std::vector<BakedClip> Skinner::baked_clips() const { return impl_ ? impl_->baked_clips : std::vector<BakedClip>{}; }
std::size_t Skinner::animation_bytes() const { return impl_ ? impl_->animation_bytes : 0; }

Status Skinner::Skin() {
  return Guarded(ErrorCode::kDeviceError, [&] {
    Impl& im = Usable(impl_, "Skin");
    if (!im.palette_set) FailWith(ErrorCode::kInvalidState, "Skinner::Skin: no palette yet (call SetPalette first)");
    im.backend->Skin();
    im.skinned = true;
    im.skinned_magnitude = im.palette_magnitude;  // the output is this palette's alone (animated: unknown, infinite)
  });
}

Status Skinner::Finish() {
  return Guarded(ErrorCode::kDeviceError, [&] {
    Impl& im = Usable(impl_, "Finish");
    if (im.skinned) im.backend->Finish();
  });
}

}  // namespace skintune

namespace skintune::internal {

namespace {

// Read-backs come from the device in chunks of kReadChunkVertices (each
// copy queued at once, each waited for by the host thread that needs it) and
// are scanned and copied in grains of kReadGrainVertices on the runtime's
// host pool (runtime/host_work.h), each grain as soon as its chunk is in.
constexpr std::size_t kReadChunkVertices = 1 << 16;
constexpr std::size_t kReadGrainVertices = 1 << 14;

// The words of packed normals or tangents: put(where vertex v of instance k
// goes in the mesh's order, its word) for every one, on the host pool, once
// the whole output is in (Usable and the counts checked by the caller).
template <typename Put>
void ReadWords(Skinner::Impl& im, Output output, const char* call, Put put) {
  const std::size_t vertices = static_cast<std::size_t>(im.instances) * im.vertex_count;
  const DeviceApi::PinnedRead read = im.backend->Read(output, 0);
  const std::span<const std::uint8_t> packed = read.bytes;
  if (packed.size() != vertices * 4)
    FailWith(ErrorCode::kDeviceError, std::string("Skinner::") + call + ": the device read back " +
                                          std::to_string(packed.size()) + " bytes, expected " +
                                          std::to_string(vertices * 4));
  read.ready(packed.size());
  ForChunks(vertices, kReadGrainVertices, [&](std::size_t begin, std::size_t end) {
    for (std::size_t v = begin; v < end; ++v) {
      const std::size_t k = v / im.vertex_count, p = v % im.vertex_count;
      std::uint32_t word;
      std::memcpy(&word, packed.data() + 4 * v, 4);
      put(im.identity_order ? v : k * im.vertex_count + im.order[p], word);
    }
  });
}

// The packed words themselves (ReadPackedNormals, ReadPackedTangents).
Status ReadPacked(const std::unique_ptr<Skinner::Impl>& impl, Output output, std::uint32_t* out, std::size_t count) {
  const char* call = output == Output::kNormals ? "ReadPackedNormals" : "ReadPackedTangents";
  return Guarded(ErrorCode::kDeviceError, [&] {
    Skinner::Impl& im = Usable(impl, call);
    if (!Writes(im.variant, output) || !PacksNormals(im.variant))
      FailWith(ErrorCode::kInvalidState, std::string("Skinner::") + call + ": this Skinner writes no packed " +
                                             SpecOf(output).what + " (SkinnerOptions::normal_format is f32, or " +
                                             SpecOf(output).what + " are not skinned)");
    const std::size_t vertices = static_cast<std::size_t>(im.instances) * im.vertex_count;
    CheckCount(call, count, vertices, [&] {
      return std::to_string(im.instances) + " instances x " + std::to_string(im.vertex_count) + " vertices";
    });
    if (!out) FailWith(ErrorCode::kInvalidArgument, std::string("Skinner::") + call + ": out is null");
    if (!im.skinned) FailWith(ErrorCode::kInvalidState, std::string("Skinner::") + call + ": nothing skinned yet (call Skin first)");
    ReadWords(im, output, call, [&](std::size_t at, std::uint32_t word) { out[at] = word; });
  });
}

// Positions and normals are 3 floats per vertex, tangents 4 (xyz, handedness w).
Status Read(const std::unique_ptr<Skinner::Impl>& impl, Output output, float* out, std::size_t float_count) {
  const char* call = output == Output::kPositions ? "ReadPositions" : output == Output::kNormals ? "ReadNormals"
                                                                                                 : "ReadTangents";
  const bool normalised = output != Output::kPositions;  // normals, tangents: no bound holds, always scanned first
  const std::size_t floats = output == Output::kTangents ? 4 : 3;
  return Guarded(ErrorCode::kDeviceError, [&] {
    Skinner::Impl& im = Usable(impl, call);
    if (output == Output::kNormals && !SkinsNormals(im.variant))
      FailWith(ErrorCode::kInvalidState,
               "Skinner::ReadNormals: this Skinner skins no normals (SkinnerOptions::normals was not set)");
    if (output == Output::kTangents && !SkinsTangents(im.variant))
      FailWith(ErrorCode::kInvalidState,
               "Skinner::ReadTangents: this Skinner skins no tangents (SkinnerOptions::tangents was not set)");
    const std::size_t vertices = static_cast<std::size_t>(im.instances) * im.vertex_count;
    CheckCount(call, float_count, vertices * floats, [&] {
      return std::to_string(im.instances) + " instances x " + std::to_string(im.vertex_count) + " vertices x " +
             std::to_string(floats);
    });
    if (!out) FailWith(ErrorCode::kInvalidArgument, std::string("Skinner::") + call + ": out is null");
    if (!im.skinned) FailWith(ErrorCode::kInvalidState, std::string("Skinner::") + call + ": nothing skinned yet (call Skin first)");
    if (normalised && PacksNormals(im.variant)) {  // one word a vertex, decoded (always finite)
      const NormalFormat format = im.variant.normal_format;
      ReadWords(im, output, call, [&](std::size_t at, std::uint32_t word) {
        if (output == Output::kNormals) {
          const glm::vec3 n = UnpackedNormal(format, word);
          std::memcpy(out + 3 * at, &n, sizeof n);
        } else {
          const glm::vec4 t = UnpackedTangent(format, word);
          std::memcpy(out + 4 * at, &t, sizeof t);
        }
      });
      return;
    }
    // Straight from the page-locked read-back staging into the caller's array,
    // in mesh order; each grain's work while later chunks are still in flight.
    const std::size_t stride = im.output_stride;
    const DeviceApi::PinnedRead read = im.backend->Read(output, kReadChunkVertices * stride);
    const std::span<const std::uint8_t> packed = read.bytes;
    if (packed.size() != vertices * im.output_stride)
      FailWith(ErrorCode::kDeviceError, std::string("Skinner::") + call + ": the device read back " +
                                            std::to_string(packed.size()) + " bytes, expected " +
                                            std::to_string(vertices * im.output_stride));
    // A NaN or infinite output never reaches the caller's buffer. Where the
    // palette may overflow float32, one scan of every word (float4 outputs'
    // w is 1) first, the vertex named when it finds one, then the copy: out
    // untouched on failure. Where it cannot (positions, CannotOverflow), each
    // grain is scanned and copied in one pass: a non-finite output can only
    // come from a broken kernel, and is an error with other grains possibly
    // written already (never a non-finite value).
    const bool one_pass = !normalised && CannotOverflow(im.output_bound, im.skinned_magnitude);
    std::atomic<bool> all_finite{true};
    std::mutex failed_mutex;
    std::string failed;  // the first chunk whose copy failed
    const bool same_order = im.identity_order;
    const bool streaming = StreamingWrite(vertices * floats * sizeof(float));
    const auto copy = [&](std::size_t begin, std::size_t end) {
      if (same_order && floats == 3) {
        CopyFloat3(packed.data(), stride, out, begin, end, streaming);
        return;
      }
      for (std::size_t v = begin; v < end; ++v) {
        const std::size_t k = v / im.vertex_count, p = v % im.vertex_count;
        const std::size_t at = same_order ? v : k * im.vertex_count + im.order[p];
        std::memcpy(out + at * floats, packed.data() + v * stride, floats * sizeof(float));
      }
    };
    const auto grain = [&](std::size_t begin, std::size_t end) {
      if (!read.caller_only) {
        try {
          read.ready(end * stride);
        } catch (const Error& e) {
          const std::lock_guard<std::mutex> lock(failed_mutex);
          if (failed.empty()) failed = e.what();
          return;
        }
      }
      if (!one_pass) {
        if (!AllFinite(packed.subspan(begin * stride, (end - begin) * stride))) all_finite = false;
      } else if (all_finite.load(std::memory_order_relaxed)) {  // nothing more written once one is found
        if (same_order) {
          if (!CopyFloat3Finite(packed.data(), stride, out, begin, end, streaming)) all_finite = false;
        } else if (!AllFinite(packed.subspan(begin * stride, (end - begin) * stride))) {
          all_finite = false;
        } else {
          copy(begin, end);
        }
      }
    };
    if (!read.caller_only) {
      ForChunks(vertices, kReadGrainVertices, grain);
    } else {
      // Chunk after chunk: this thread waits for it (the API's fences are
      // this thread's), then the pool works on its grains.
      const std::size_t chunk_vertices = std::max<std::size_t>(read.chunk / stride, 1);
      for (std::size_t first = 0; first < vertices; first += chunk_vertices) {
        const std::size_t last = std::min(vertices, first + chunk_vertices);
        read.ready(last * stride);
        ForChunks(last - first, kReadGrainVertices,
                  [&](std::size_t begin, std::size_t end) { grain(first + begin, first + end); });
      }
    }
    if (!failed.empty()) throw Error(failed);
    read.ready(packed.size());  // every chunk in, whatever the pool's split
    const bool finite = all_finite;
    for (std::size_t p = 0; p < vertices && !finite; ++p) {
      float xyz[3];
      std::memcpy(xyz, packed.data() + p * im.output_stride, sizeof xyz);
      if (std::isfinite(xyz[0]) && std::isfinite(xyz[1]) && std::isfinite(xyz[2])) continue;
      const std::size_t k = p / im.vertex_count;
      FailWith(ErrorCode::kDeviceError,
               std::string("Skinner::") + call + ": vertex " + std::to_string(im.order[p % im.vertex_count]) +
                   " of instance " + std::to_string(k) + " is (" + std::to_string(xyz[0]) + ", " +
                   std::to_string(xyz[1]) + ", " + std::to_string(xyz[2]) +
                   (one_pass ? "), not finite although this palette and mesh cannot overflow float32: the kernel is "
                               "broken; out may hold some of the other vertices, never a non-finite value"
                             : "), not finite: the palette times the mesh overflows float32 (or the kernel is broken); "
                               "out is not written"));
    }
    if (!one_pass) ForChunks(vertices, kReadGrainVertices, copy);
  });
}

}  // namespace

}  // namespace skintune::internal

namespace skintune {

Status Skinner::ReadPositions(float* out, std::size_t float_count) {
  return Read(impl_, Output::kPositions, out, float_count);
}
Status Skinner::ReadNormals(float* out, std::size_t float_count) {
  return Read(impl_, Output::kNormals, out, float_count);
}
Status Skinner::ReadTangents(float* out, std::size_t float_count) {
  return Read(impl_, Output::kTangents, out, float_count);
}
Status Skinner::ReadPackedNormals(std::uint32_t* out, std::size_t word_count) {
  return ReadPacked(impl_, Output::kNormals, out, word_count);
}
Status Skinner::ReadPackedTangents(std::uint32_t* out, std::size_t word_count) {
  return ReadPacked(impl_, Output::kTangents, out, word_count);
}

Status Skinner::SkinIntoGlBuffer(unsigned int gl_buffer) {
  return Guarded(ErrorCode::kDeviceError, [&] {
    Impl& im = Usable(impl_, "SkinIntoGlBuffer");
    if (!im.palette_set)
      FailWith(ErrorCode::kInvalidState, "Skinner::SkinIntoGlBuffer: no palette yet (call SetPalette first)");
    im.backend->SkinIntoGlBuffer(gl_buffer);
    im.skinned_magnitude = std::max(im.skinned_magnitude, im.palette_magnitude);  // whichever output Read reads
  });
}

Status Skinner::SkinIntoVulkan(void* vk_command_buffer, void* vk_buffer) {
  return Guarded(ErrorCode::kDeviceError, [&] {
    Impl& im = Usable(impl_, "SkinIntoVulkan");
    if (!im.palette_set)
      FailWith(ErrorCode::kInvalidState, "Skinner::SkinIntoVulkan: no palette yet (call SetPalette first)");
    if (!vk_command_buffer) FailWith(ErrorCode::kInvalidArgument, "Skinner::SkinIntoVulkan: a null VkCommandBuffer");
    im.backend->SkinIntoVulkan(vk_command_buffer, vk_buffer);
    im.skinned = true;
    im.skinned_magnitude = std::max(im.skinned_magnitude, im.palette_magnitude);  // whichever output Read reads
  });
}

}  // namespace skintune

namespace skintune::internal {

SetPaletteTimes::~SetPaletteTimes() {
  if (calls == 0) return;
  const double per_call_us = 1e6 / static_cast<double>(calls);
  char line[256];
  std::snprintf(line, sizeof line,
                "skinner: %llu SetPalette calls, host us per call: buffer wait %.2f, packing %.2f, upload hand-over %.2f",
                static_cast<unsigned long long>(calls), wait_s * per_call_us, pack_s * per_call_us,
                upload_s * per_call_us);
  AppendTimingLog(line);
}

}  // namespace skintune::internal
