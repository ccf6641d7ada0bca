// skintune runtime: run the tuned linear-blend-skinning kernel on your buffers.
//
//   v'[k] = sum_i w[k][i] * M[d[k][i]] * v[k]        (k: vertex, i < influences)
//
// The one public header of skintune. Tune offline once per device
// (`skintune tune`, `skintune db merge`), then at run time:
//
//   skintune::Result<skintune::Device> device = skintune::Device::OpenBest();
//   skintune::Result<skintune::WinnersDb> db = skintune::WinnersDb::Load("db.json");
//   skintune::Result<skintune::Skinner> skinner =
//       skintune::Skinner::Create(*device, *db, mesh_view, options);
//   per frame: skinner->SetPalette(...); skinner->Skin(); skinner->ReadPositions(...);
//
// Crowds: SkinnerOptions::instances skins K copies of a mesh in one launch;
// Skinner::CreateBatch skins different meshes in one launch.
//
// mesh_view is your arrays (MeshView), or Model::Load("model.gltf")->mesh(),
// whose Palette(animation, t, &matrices) gives each frame's palette
// (examples/skin_animation.cpp). Link skintune::runtime (find_package(skintune);
// docs/RUNTIME.md); the library exports this header's API and nothing else.
// The docs/ pages and examples/ this header cites are installed with it, in
// share/doc/skintune/.
//
// Errors are values: every function that can fail returns Status or Result<T>,
// whose message names what was wrong (the argument, the vertex, the device).
// No exception crosses this header: allocation failure inside the library is
// reported as a Status like any other error. Objects are move-only handles;
// a moved-from object reports "used after move" from every call.
//
// Threads: one Device and the Skinners created from it must be used from one
// thread at a time (they share a queue / stream / GL context). Different
// Devices may be used from different threads.
//
// This header needs only the C++17 standard library. Native handles
// (cl_device_id, CUstream, GLuint...) pass as void* / integer so the header
// includes no OpenCL, CUDA or GL headers.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace skintune {

// The library's own code lives in skintune::internal, which is not API; this
// header names it only to befriend one accessor.
namespace internal {
struct DeviceAccess;
struct ModelAccess;
}  // namespace internal

// ---------------------------------------------------------------- errors

enum class ErrorCode {
  kOk = 0,
  kInvalidArgument,    // a precondition of the call was broken (sizes, ranges, null handles)
  kNotFound,           // no device / file / database entry matches
  kUnavailable,        // the backend is not present on this machine (no driver, no extension)
  kBuildFailed,        // the kernel did not compile (message: first lines of the build log)
  kDeviceError,        // an API call failed on the device (message: the call and its error;
                       // "GL lost: ...": the driver reset the GL context, e.g. after a kernel
                       // ran past its time limit: open a new Device, nothing on the old one runs)
  kIoError,            // a file could not be read or written
  kInvalidState,       // use after move, destroyed context, palette not set yet
};

class Status {
 public:
  Status() = default;  // ok
  Status(ErrorCode code, std::string message) : code_(code), message_(std::move(message)) {}
  bool ok() const { return code_ == ErrorCode::kOk; }
  ErrorCode code() const { return code_; }
  const std::string& message() const { return message_; }  // empty when ok
  explicit operator bool() const { return ok(); }

 private:
  ErrorCode code_ = ErrorCode::kOk;
  std::string message_;
};

// A value or the Status saying why there is none. Dereferencing a Result that
// holds an error is a programming error (checked by assert in debug builds).
template <class T>
class Result {
 public:
  Result(T value) : value_(std::move(value)), has_value_(true) {}  // NOLINT: implicit by design
  Result(Status status) : status_(std::move(status)) {}            // NOLINT: implicit by design
  bool ok() const { return has_value_; }
  explicit operator bool() const { return has_value_; }
  const Status& status() const { return status_; }
  T& value() { return value_; }
  const T& value() const { return value_; }
  T& operator*() { return value_; }
  const T& operator*() const { return value_; }
  T* operator->() { return &value_; }
  const T* operator->() const { return &value_; }

 private:
  T value_{};
  Status status_;
  bool has_value_ = false;
};

// ---------------------------------------------------------------- devices

// kCpu: the host CPU running skintune's own fast-path kernels (language
// "cpu"; threads, chunks and streaming stores chosen per machine by
// measurement on the first frames a Skinner runs, which therefore take longer).
// Device::OpenBest ranks it last.
enum class Backend { kOpenCl, kCuda, kGl, kVulkan, kCpu };
const char* BackendName(Backend backend);  // "opencl", "cuda", "gl", "vulkan", "cpu"

// A device's identity, as `skintune tune` records it in its reports and winners databases.
struct DeviceInfo {
  Backend backend = Backend::kOpenCl;
  std::string id;              // "<backend>:<platform>/<name>/<driver_version>": the database key
  std::string platform;        // OpenCL platform name; "CUDA"; the EGL platform for GL
  std::string vendor;
  std::string name;            // device name / GL_RENDERER
  std::string driver_version;
  std::string type;            // "gpu", "cpu", "accelerator" (OpenCL types joined with '+'); GL: "cpu" for
                               // Mesa's software renderers, else "gpu"
  bool submit_thread = false;  // DeviceOptions::submit_thread was asked for and this device's API allows it
};

// A Vulkan instance, device and compute queue the caller already has
// (Device::FromVulkan), as void* (VkInstance, VkPhysicalDevice, VkDevice,
// VkQueue) so this header includes no Vulkan header.
struct VulkanHandles {
  void* instance = nullptr;
  void* physical_device = nullptr;
  void* device = nullptr;                // created with `queue_family`'s queue; Vulkan 1.1
  void* queue = nullptr;                 // a queue of `queue_family`, which must have compute
  std::uint32_t queue_family = 0;
  void* get_instance_proc_addr = nullptr;  // PFN_vkGetInstanceProcAddr; null: libvulkan.so.1's
};

struct DeviceOptions {
  // Compiled programs are cached here, keyed by device id (with its driver),
  // source hash and build options, so a second start compiles nothing.
  // Empty: $SKINTUNE_CACHE_DIR, else $XDG_CACHE_HOME/skintune, else
  // ~/.cache/skintune. "-": no disk cache. Files are written atomically; a
  // damaged or foreign file is rebuilt and rewritten, never an error, and a
  // directory that cannot be written only costs the rebuild next start.
  std::string program_cache_dir;
  // Make the driver calls of SetPalette's upload and of Skin on a thread of
  // the Device's own (CUDA and OpenCL devices; elsewhere ignored, see
  // DeviceInfo::submit_thread): SetPalette then only packs the palette and
  // Skin only hands the launch over, so the calling thread packs frame n+1
  // while the driver queues frame n. When SetPalette must wait for a palette
  // buffer, the thread polls its fence and the calling thread waits outside
  // the driver. Every other call (Read*, Finish, another
  // Skinner's creation) first waits until those calls are made, and an error
  // of a handed-over call is returned by the next call on the Device's
  // Skinners instead of its own. The thread polls for work for 0.5 ms after
  // each call, then sleeps.
  bool submit_thread = false;
};

// Counters for the program cache (tests and diagnostics).
struct ProgramCacheStats {
  int builds = 0;       // programs compiled from source this Device's lifetime
  int disk_hits = 0;    // programs loaded from the disk cache
  int memory_hits = 0;  // programs reused within this Device
};

class Device {
 public:
  // Every device skintune can run on here, in discovery order: OpenCL devices
  // (all platforms), CUDA devices, and one GL device when a headless EGL
  // context (GL 4.3 core) opens. Absent backends are simply missing from the
  // list. Never fails; the calling thread's current GL context is left as it was.
  static std::vector<DeviceInfo> List();

  // The best available device: a GPU before anything else, then CUDA before
  // OpenCL before GL on the same GPU; a CPU OpenCL device when there is no GPU.
  // kNotFound when there is no device at all; kDeviceError (each device's
  // reason) when none of them can be opened. A GL device opened here owns a
  // headless EGL context and makes it current on the calling thread for
  // every call.
  static Result<Device> OpenBest(const DeviceOptions& options = {});

  // The first device of List() that `pattern` matches and, unless `backend`
  // is null, is of that backend (the other backends are then not probed).
  // The rule is the one of every `skintune --device` (docs/RUNTIME.md
  // "Choosing a device"): `pattern`, case-insensitive, is a substring of the
  // device's id "<backend>:<platform>/<name>/<driver_version>", its vendor or
  // type, or its platform's short name ("pocl" matches PoCL's "Portable
  // Computing Language"); "" matches any.
  // kNotFound naming the pattern and listing the devices there are.
  static Result<Device> Open(const std::string& pattern, const Backend* backend = nullptr,
                             const DeviceOptions& options = {});

  // An OpenCL device, context and queue the caller already has (cl_device_id,
  // cl_context, cl_command_queue as void*). skintune retains them and releases
  // them when the Device (and every Skinner made from it) is gone; the queue
  // must be in-order. Null handles, a device not in the context, a queue of
  // another context or device, an out-of-order queue: kInvalidArgument.
  // Handles that are not OpenCL objects at all are undefined behaviour (the
  // OpenCL driver cannot tell them from live ones). has_gl_sharing() is true
  // when the context was created with CL_GL_CONTEXT_KHR. Frames go on the
  // given queue; one made without CL_QUEUE_PROFILING_ENABLE is faster: on
  // NVIDIA a launch returning an event (each frame's last does) took ~10.5 us
  // of host time on a profiling queue against ~5 on a plain one. skintune's
  // own queues (Open) have no profiling.
  static Result<Device> FromOpenCl(void* cl_device, void* cl_context, void* cl_queue,
                                   const DeviceOptions& options = {});

  // A CUDA context and stream the caller already has (CUcontext, CUstream as
  // void*; a null stream is the legacy default stream). The context must
  // outlive the Device. kUnavailable without a CUDA driver.
  static Result<Device> FromCuda(void* cu_context, void* cu_stream, const DeviceOptions& options = {});

  // The GL context current on the calling thread (EGL; GL 4.3+, which both
  // the compute-shader and the vertex-shader path need for storage
  // buffers). skintune never makes it current itself: it must be current
  // whenever the Device or its Skinners are called (kInvalidState
  // otherwise, also once the context is destroyed), and is never destroyed
  // here. Skin() restores the program, vertex array, framebuffers, transform
  // feedback object and rasteriser-discard state it found; the indexed buffer
  // bindings and texture units the kernel used stay bound. Its DeviceInfo's
  // platform is "current", so its id never equals a tuned headless one: the
  // database matches it from the same-device-name level down. kUnavailable
  // when no EGL context is current or it is older than 4.3.
  static Result<Device> FromCurrentGl(const DeviceOptions& options = {});

  // The caller's Vulkan instance, device and queue (VulkanHandles), adopted:
  // skintune creates no device and destroys none of them; they must outlive
  // the Device and its Skinners. Skin() submits to that queue (palette copies
  // too), and Skinner::SkinIntoVulkan records into the caller's command
  // buffer instead. The queue must not be used from another thread during a
  // call. kUnavailable without a Vulkan loader; kInvalidArgument for a null
  // handle or a queue family without compute.
  static Result<Device> FromVulkan(const VulkanHandles& handles, const DeviceOptions& options = {});

  // An OpenCL device that shares buffers with the GL context current on the
  // calling thread (cl_khr_gl_sharing, as in the paper): a new OpenCL context
  // created with CL_GL_CONTEXT_KHR and CL_EGL_DISPLAY_KHR for the current EGL
  // context, on the device clGetGLContextInfoKHR names, with an in-order
  // queue. has_gl_sharing() is true and Skinner::SkinIntoGlBuffer writes into
  // that GL context's buffers. kUnavailable, saying why for each platform,
  // when no EGL context is current or no OpenCL platform offers the
  // extension for it (PoCL does not).
  static Result<Device> OpenClForCurrentGl(const DeviceOptions& options = {});

  Device();
  ~Device();
  Device(Device&&) noexcept;
  Device& operator=(Device&&) noexcept;

  // A moved-from (or default-constructed) Device reports an empty info and
  // zero stats; Skinner::Create with it fails with kInvalidState.
  const DeviceInfo& info() const;
  ProgramCacheStats cache_stats() const;
  // Whether OpenCL here can write into GL buffer objects (cl_khr_gl_sharing with
  // a context created for the current GL context).
  bool has_gl_sharing() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
  friend class Skinner;
  friend struct internal::DeviceAccess;  // the library's own, not part of the API
};

// ---------------------------------------------------------------- winners

// The default error budget (SkinnerOptions::max_error, `skintune tune
// --max-error`): the largest error, relative to the mesh's bounding-box
// diagonal, that quantising the weights may add. 1e-4 admits 16-bit weights
// (unorm16) and rejects 8-bit ones (unorm8) for float weights; weights already
// on a format's grid (a glTF's unorm8 WEIGHTS in unorm8) cost nothing in it.
inline constexpr double kDefaultMaxError = 1e-4;

// What one launch skins (docs/RUNTIME.md "Scene shapes"): one mesh, K
// instances of one mesh (SkinnerOptions::instances), or a batch of different
// meshes (Skinner::CreateBatch). A winners database records the shape each
// entry was tuned on; Selection::Find and Skinner::Create prefer an entry of
// the scene's shape and fall back to a single-mesh entry of the same total
// vertex count.
enum class SceneShape { kSingle, kInstances, kBatch };

// The format the kernel writes skinned normals and tangents in
// (docs/VARIANTS.md "Packed normals and tangents"): float32, or one 32-bit
// word a vector, octahedral 2 x unorm16 (Godot 4's layout) or 4 x snorm8.
enum class NormalFormat { kF32, kOct16, kSnorm8 };

// What baking a model's clips stores (SkinnerOptions::bake_space): each
// joint's palette entry, or each node's local transform, or both (hybrid).
enum class BakeSpace { kPalette, kLocal, kHybrid };
const char* SceneShapeName(SceneShape shape);  // "single", "instances", "batch"

// How the database entry for a device was found (the fallback chain).
enum class MatchLevel {
  kExactDevice,      // same device id (backend, platform, name and driver version)
  kSameDeviceName,   // same backend and device name, another driver
  kSameVendorType,   // same backend, vendor and device type
  kGenericDefault,   // no entry: the built-in default variant, correct everywhere
  kForced,           // SkinnerOptions::variant named the variant; no lookup
};
// "exact-device", "same-device-name", "same-vendor-type", "generic-default", "forced".
const char* MatchLevelName(MatchLevel level);

// A winners database, as written by `skintune tune` or `skintune db merge`.
class WinnersDb {
 public:
  // kIoError when the file cannot be read; kInvalidArgument naming the file
  // and element ("db.json: entries[3]: 'lang' must be a string") when it is
  // not a 1.x winners database. A tuning report is refused with the command
  // that makes its database (`skintune tune` also writes winners-db.json).
  static Result<WinnersDb> Load(const std::string& path);
  // The same from the file's text; `name_for_errors` stands for the file.
  static Result<WinnersDb> Parse(const std::string& json_text, const std::string& name_for_errors);
  static WinnersDb Empty();  // every lookup ends at kGenericDefault

  WinnersDb();  // empty, like Empty()
  ~WinnersDb();
  WinnersDb(const WinnersDb&);
  WinnersDb& operator=(const WinnersDb&);
  WinnersDb(WinnersDb&&) noexcept;
  WinnersDb& operator=(WinnersDb&&) noexcept;

  std::size_t size() const;  // entries

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
  friend class Skinner;
  friend struct Selection;
};

// What a Skinner runs and why.
struct Selection {
  std::string variant;     // the variant key (docs/VARIANTS.md), e.g. "opencl.b4.padded.soa..."
  MatchLevel level = MatchLevel::kGenericDefault;
  std::string entry;       // the database entry used: "<device id> <lang> b<B> <vertices>[ <shape>]", or
                           // "built-in default"
  std::string reason;      // e.g. "no entry for this device; same vendor and type: NVIDIA gpu"

  // The lookup alone, for diagnostics: the fallback chain (docs/RUNTIME.md)
  // over the entries of the device's languages whose influences are at least
  // `influences`. Skinner::Create also checks each candidate against the real
  // device's limits and the mesh and skips those that cannot run, so it may
  // choose a later entry. The database keeps a winner per precision class
  // (weight format); only entries whose recorded quantisation error is within
  // `max_error` (relative to the bounding-box diagonal) are candidates, so a
  // larger budget gets the faster kernel without re-tuning (f32 entries and
  // 1.3.0 entries within budget; an older database's unorm16/unorm8 entry,
  // whose error is not recorded, is over any budget). `shape` is the scene's
  // and `vertex_count` its total (K x the mesh's for instances, the sum of a
  // batch's meshes): entries tuned on that shape come first (the nearest
  // instance or mesh count among them), then single-mesh entries of the
  // nearest total, and `reason` says when it fell back to one (databases
  // before 1.4.0 hold single-mesh entries only). kInvalidArgument for
  // influences outside 1..8 or a max_error that is negative or not finite;
  // kInvalidState for a moved-from `db`.
  static Result<Selection> Find(const WinnersDb& db, const DeviceInfo& device, int influences,
                                std::size_t vertex_count, double max_error = kDefaultMaxError,
                                SceneShape shape = SceneShape::kSingle);
};

// ---------------------------------------------------------------- skinning

// The mesh, in the caller's memory, read during Skinner::Create only.
// Every pointer holds vertex_count * its per-vertex count; strides are implied.
struct MeshView {
  std::size_t vertex_count = 0;
  int influences = 0;                // B, 1..8: slots per vertex
  int joint_count = 0;               // palette entries; every joint index < joint_count
  const float* positions = nullptr;  // 3 per vertex (x, y, z)
  const float* normals = nullptr;    // 3 per vertex, or null (then no normals are skinned)
  // 4 per vertex (x, y, z, then the handedness w: +1 or -1, as glTF's
  // TANGENT), or null (then no tangents are skinned).
  const float* tangents = nullptr;
  const std::uint32_t* joints = nullptr;  // B per vertex
  const float* weights = nullptr;         // B per vertex, each >= 0, summing to 1 within 1e-3
  // Morph targets (glTF `targets`; docs/VARIANTS.md "Morph targets"), applied
  // before skinning in the same launch: p = p0 + sum_t w_t * dp_t, normals
  // and tangents likewise. 0: none (the pointers below are then ignored).
  int morph_target_count = 0;
  // morph_target_count x vertex_count x 3 floats: target t's offset of vertex
  // v at [(t * vertex_count + v) * 3]. Required with morph targets.
  const float* morph_positions = nullptr;
  const float* morph_normals = nullptr;   // likewise, or null: no normal offsets (read only with normals)
  const float* morph_tangents = nullptr;  // likewise (x, y, z; w is kept), or null (read only with tangents)
  // morph_target_count weights until the first Skinner::SetMorphWeights, or
  // null: every weight 0 (the mesh as it is).
  const float* morph_weights = nullptr;
};

// SkinnerOptions::palette_buffers: its default and its range.
inline constexpr int kDefaultPaletteBuffers = 3;
inline constexpr int kMinPaletteBuffers = 2;
inline constexpr int kMaxPaletteBuffers = 16;
// SkinnerOptions::palette_threads: its largest value (0 is skintune's choice).
inline constexpr int kMaxPaletteThreads = 8;

struct SkinnerOptions {
  // K >= 1 copies of the mesh (a crowd) skinned in one launch, each with its
  // own palette (docs/VARIANTS.md "Instancing"). The variant must hold K
  // palettes where it keeps them all (constant and image storage) and the
  // device must launch K instances at once; database entries that cannot are
  // skipped, a forced variant that cannot is kInvalidArgument. K x
  // vertex_count must stay below 2^32.
  int instances = 1;
  bool normals = false;     // also skin normals (MeshView::normals required)
  // Also skin tangents, and normals with them (MeshView::tangents and
  // MeshView::normals required): each tangent is turned by the blended
  // matrix, renormalised, and its w flipped where that matrix mirrors. The
  // variant is a `tangents` one (docs/VARIANTS.md), in the float4 position
  // format; database entries in float3 are skipped with their reason.
  bool tangents = false;
  // Skin with dual quaternions instead of linear blending (docs/VARIANTS.md
  // "Dual quaternions"): each vertex's joints' rotations and translations
  // blended as unit dual quaternions, which keeps the volume that linear
  // blending loses at twisting joints. A different result, so the user's
  // choice: only database entries tuned with blend "dq" serve it (else the
  // built-in default's dq twin), and linear entries never do. The palette is
  // uploaded as 2 float4 rows a joint instead of 3 or 4. Every SetPalette
  // matrix must then be rigid (a rotation and a translation, within
  // skintune_kernels::kRigidTolerance): one that scales, shears or mirrors
  // is kInvalidArgument naming it. Not with CreateAnimated (its palettes are
  // matrices): kInvalidArgument.
  bool dual_quaternions = false;
  // The format of the skinned normals and tangents on the device, what the
  // consumer of device buffers reads: kF32, or one word a vector (kOct16:
  // within 8e-5 of the float32 direction, tangents 2.2e-4; kSnorm8: 8.5e-3).
  // A packed format is the user's choice, never a silent trade: entries tuned
  // in it serve first, else the chosen entry's variant with this format (the
  // reason says so). ReadNormals / ReadTangents decode it to floats;
  // ReadPackedNormals / ReadPackedTangents give the words. Needs normals
  // (kInvalidArgument otherwise).
  NormalFormat normal_format = NormalFormat::kF32;
  // Force a variant key (docs/VARIANTS.md; omitted axes take their defaults)
  // instead of the database's choice; Selection::level is then kForced. It
  // must be of one of the device's languages, padded (a bucketed variant
  // reorders the vertices on the device) and pass every constraint on this
  // device and mesh (e.g. B at least the mesh's largest per-vertex count);
  // otherwise kInvalidArgument naming the constraint ("influences_too_few:
  // ..."). Its `normals` axis follows `normals` and `tangents` above, its
  // `normal_format` `normal_format` above; its blend must be "dq" exactly
  // when `dual_quaternions` is set.
  std::string variant;
  // The error budget: the largest error quantising the weights may add to the
  // skinned positions, relative to the mesh's bounding-box diagonal
  // (docs/RUNTIME.md "Precision"). Database entries whose recorded error is
  // larger are skipped, except in a weight format that holds this mesh's
  // weights exactly (every weight a multiple of 1/255 in unorm8, 1/65535 in
  // unorm16, summing to 1 on that grid): those cost nothing. 0 takes exact
  // formats only. Negative or not finite: kInvalidArgument. A forced `variant`
  // is not checked against it.
  double max_error = kDefaultMaxError;
  // The palette ring's depth (docs/RUNTIME.md "The frame loop"): how many
  // frames SetPalette + Skin may have queued on the device before SetPalette
  // waits for the oldest, each with a palette buffer (and its page-locked
  // staging) of its own, kMinPaletteBuffers (2) to kMaxPaletteBuffers (16),
  // else kInvalidArgument: SetPalette packs into a buffer no queued frame
  // reads, so a palette it rejects never touches the one in use. With 2 it
  // waits for the frame before the last. A deeper ring lets
  // the host run further ahead of the device where its frames come unevenly;
  // with DeviceOptions::submit_thread on the H200 machine, 64 x 25k-b4 ran
  // at 0.76-0.78 of the Skin-only rate with 3 buffers and 0.86-0.87 with 6
  // (measured 2026-11-26; docs/RUNTIME.md "The frame loop").
  int palette_buffers = kDefaultPaletteBuffers;
  // How many threads may pack a palette of 1024 matrices or more in
  // SetPalette: the calling thread and helpers of skintune's own, shared by
  // the process's Skinners, which poll for 0.5 ms after each packing before
  // they sleep (up to that many cores busy for 0.5 ms after each SetPalette).
  // 0: skintune's choice, half the host's cores from 2 to kMaxPaletteThreads
  // (8), the most there are; 1: the calling thread alone, and no helper
  // thread is started for this Skinner (a job system that owns the cores);
  // 2 to kMaxPaletteThreads: at most that many, never more than skintune's
  // choice. Else kInvalidArgument. Fewer threads only cost time: the bytes
  // uploaded are the same. On the H100 machine's 16-core host, 64 x 77
  // matrices packed inside a pipelined frame loop in 6-7.5 us with 8
  // threads, 7.3-10.9 with 4, 10.1 with 2 and 14.2-14.4 with 1
  // (docs/RUNTIME.md "The frame loop").
  int palette_threads = 0;
  // CreateAnimated only (kInvalidArgument for any other Skinner): 0 samples
  // the model's keyframes on the device every frame. A rate in (0,
  // kMaxBakeRate] frames a second bakes every clip once, when the Skinner is
  // made (docs/ANIMATION.md "Baked clips"): each joint's palette entry at
  // evenly spaced frames, as a rotation, a translation and a stretch (32
  // bytes a joint and frame; 64 where a joint scales unevenly), so that the
  // device reads two frames a joint instead of keys and the hierarchy.
  // Between frames, rotations are nlerped
  // along the shortest path, translations and stretches lerped; a blend of two
  // clips mixes their palette entries the same way (in the model's space, not
  // each joint's local space as sampled clips do; bake_space kLocal does).
  // What each clip costs and loses: baked_clips(). A different result, so
  // the user's choice.
  // kBakeRateTuned: the form the chosen winners-database entry was tuned
  // in, on a scene animated on the device (`skintune tune` of a "-anim"
  // scene, docs/ANIMATION.md "Baked clips"): sampled, or baked at its rate
  // in its space, within SkinnerOptions::max_error as its recorded error
  // says; sampled where the entry was tuned with the host's palettes.
  // selection() says which.
  double bake_rate = 0.0;
  // What a bake_rate above 0 bakes (kInvalidArgument with bake_rate 0 or
  // kBakeRateTuned, which takes the entry's). kPalette: each joint's palette
  // entry, as above. kLocal: each node's local transform, as a rotation, a
  // translation and a scale (32 bytes a node and frame; 48 where a node
  // scales unevenly), which the device composes through the hierarchy each
  // frame: a blend of two clips then mixes each node's local transform, as
  // sampled clips do, for a little more device time than kPalette's
  // (docs/ANIMATION.md "Baked in local space"). kHybrid: both records, of
  // the same frames (their bytes together); an instance that plays one clip
  // reads palette records (kPalette's time and error), one that cross-fades
  // mixes local ones (kLocal's), so that a crowd of which a few cross-fade
  // pays for the walk only there (docs/ANIMATION.md "Hybrid records").
  BakeSpace bake_space = BakeSpace::kPalette;
  // CreateAnimated with a bake_rate above 0 only (kInvalidArgument
  // otherwise; kBakeRateTuned takes the entry's): no palette kernel runs.
  // Each work-group of the skin launch makes its instance's palette from the
  // records of bake_space into its local copy of the palette (the variant's
  // storage becomes local): kPalette's palette records; kLocal's local ones,
  // each group walking the hierarchy in its local memory; kHybrid's, palette
  // records for one clip and the walk for a cross-fade. So a frame is one
  // launch and nothing waits for a palette (docs/ANIMATION.md "The palette in
  // the skin launch"). The same palettes and error as the bake_space's
  // palette kernel; what a frame uploads is the same (nothing after
  // AdvanceAnimation, the K states after SetAnimation). Not for a model with
  // morph targets, nor the cpu device, nor GL's vertex-shader variants
  // (kInvalidArgument).
  bool fuse_palette = false;
  // CreateAnimated only (false is kInvalidArgument for any other Skinner):
  // whether the crowd's instances may cross-fade two clips
  // (AnimationState::weight above 0). true, the default: entries tuned on
  // crowds that cross-fade come first, and with kBakeRateTuned an entry tuned
  // on a crowd that did not never lends its baked palette records, whose
  // recorded error holds no blend's (palette records mix a blend in the
  // model's space: docs/ANIMATION.md "Baked clips"). false: entries of crowds
  // that do not cross-fade come first, their baked palette records included,
  // and SetAnimation refuses a weight above 0 (kInvalidArgument), so the
  // error the tuner recorded is the error the crowd gets.
  bool cross_fades = true;
};

// Baking's limit (SkinnerOptions::bake_rate), frames a second.
inline constexpr double kMaxBakeRate = 1000.0;
// SkinnerOptions::bake_rate: the winners database decides (sampled or a rate).
inline constexpr double kBakeRateTuned = -1.0;

// A clip as SkinnerOptions::bake_rate baked it (Skinner::baked_clips).
struct BakedClip {
  std::string name;        // the model's animation name ("" where it has none)
  int frames = 0;          // at least the clip's duration x the rate, plus one
  std::size_t bytes = 0;   // its frames on the device
  // The largest distance between a vertex of the mesh skinned by the baked
  // palettes and by the sampled float64 ones, relative to the mesh's
  // bounding-box diagonal, at the frames and 1/4, 1/2 and 3/4 between them.
  double max_error = 0.0;
};

class Model;

// One instance's animation on the device (Skinner::CreateAnimated,
// Skinner::SetAnimation; docs/ANIMATION.md): animation `animation` of the
// Model at `time` seconds (its own clip time: clamped to its first and last
// key, as Model::Palette does; loop it yourself), blended in local space with
// `animation2` at `time2` by `weight` (0: the first alone; 1: the second
// alone; rotations by shortest-path nlerp, translations and scales by lerp).
// -1 is the rest pose. 16 bytes a frame on the device.
struct AnimationState {
  int animation = -1;
  float time = 0.0f;
  int animation2 = -1;
  float time2 = 0.0f;
  float weight = 0.0f;
};

class Skinner {
 public:
  // Picks the variant for (device, B, mesh.vertex_count) from `db`
  // (Selection::Find's fallback chain, docs/RUNTIME.md), where B is the
  // largest number of non-zero weights of any vertex; an entry that cannot run
  // on this device and mesh (its constraints) is skipped and named in
  // selection().reason. A bucketed winner runs as its padded twin, so the
  // device output is always in the mesh's vertex order. Packs the mesh into
  // the variant's layout on the device, and builds (or loads from the
  // program cache) its kernels.
  // Errors: kInvalidArgument naming the first bad vertex and slot for a joint
  // out of range, a negative, NaN or infinite weight, weights not summing to
  // 1 within 1e-3, a NaN position, a null array, zero sizes, influences
  // outside 1..8, joint_count outside 1..65536, normals requested without
  // MeshView::normals, a bad forced variant; kInvalidState for a moved-from
  // Device or WinnersDb, and for a GL Device whose context is not current;
  // kBuildFailed (the build log's first lines) or kDeviceError from the
  // device.
  // The database is asked for the scene's shape and total vertex count
  // (Selection::Find): instances() > 1 is an instances scene of K x
  // vertex_count vertices.
  static Result<Skinner> Create(Device& device, const WinnersDb& db, const MeshView& mesh,
                                const SkinnerOptions& options = {});

  // A batch: `mesh_count` different meshes (each its own vertex count, B and
  // joint count) skinned by ONE launch, as an engine draws a scene of
  // different characters (docs/VARIANTS.md "Batches"). They are packed as one
  // mesh: mesh m's vertices follow mesh m-1's (vertex_offset(m)), its joint
  // indices are offset by the earlier meshes' joint counts into one palette
  // (joint_offset(m)), and every mesh is padded with zero-weight slots to the
  // batch's B (the largest of the meshes'). Then the Skinner is a Skinner of
  // that mesh: vertex_count() and joint_count() are the batch's totals,
  // SetPalette takes every mesh's palette one after another (joint_count() x
  // 16 floats: mesh m's at joint_offset(m) x 16), Read* give every mesh's
  // vertices in its own order, mesh after mesh (mesh m's at
  // vertex_offset(m) x 3). The variant is chosen as by Create for a scene of
  // shape kBatch and the total vertex count, and its constraints hold for the
  // batch: its index format must address the total joint count and its
  // palette storage hold every palette (a database entry that cannot is
  // skipped; a forced variant that cannot is kInvalidArgument naming the
  // constraint and the total). `options` apply to the whole batch
  // (instances > 1: K copies of the batch; normals: every mesh needs them).
  // Errors: those of Create, each naming the mesh: "Skinner::CreateBatch:
  // meshes[2]: vertex 17 slot 3: joint 80 out of range (24 joints)";
  // kInvalidArgument for a null `meshes` or `mesh_count` 0, and for more
  // than 65536 joints in all. Blocks while packing, uploading and building,
  // like Create.
  static Result<Skinner> CreateBatch(Device& device, const WinnersDb& db, const MeshView* meshes,
                                     std::size_t mesh_count, const SkinnerOptions& options = {});

  // Animation on the device (docs/ANIMATION.md): a Skinner of `model`'s mesh
  // (model.mesh(), as Create; SkinnerOptions as there: instances, normals,
  // tangents, a forced variant) whose palettes the device computes each
  // frame from the model's animations, instead of the host's SetPalette.
  // Every animation of the model (its skeleton, keyframes, inverse binds)
  // is packed and uploaded once here; per frame SetAnimation uploads
  // 16 bytes an instance, and Skin runs the palette kernel, then the skin
  // kernel, on the device's queue. Until the first SetAnimation every
  // instance is in the rest pose. SetPalette is then kInvalidState.
  // Errors: those of Create; kInvalidArgument for a model without a
  // skeleton to animate (an empty Model: kInvalidState), more than 512 nodes
  // (the palette kernel holds an instance's nodes in local memory), or an
  // animation the packer refuses (naming the file and element).
  static Result<Skinner> CreateAnimated(Device& device, const WinnersDb& db, const Model& model,
                                        const SkinnerOptions& options = {});
  Skinner();
  // Waits until the frames it queued have completed on the device, so a
  // program may return from main right after Skin() (a driver still
  // compiling or running them while exit() tears down its globals crashes).
  ~Skinner();
  Skinner(Skinner&&) noexcept;
  Skinner& operator=(Skinner&&) noexcept;

  const Selection& selection() const;
  std::size_t vertex_count() const;  // per instance (a batch's: every mesh's)
  int instances() const;
  int joint_count() const;           // palette entries per instance (a batch's: every mesh's)
  SceneShape shape() const;          // kSingle, kInstances (instances() > 1) or kBatch (CreateBatch)

  // The meshes of a batch (1 for Create): where mesh m (0..mesh_count()-1)
  // lies in the vertices and the palette of an instance. 0 for m out of range.
  std::size_t mesh_count() const;
  std::size_t vertex_offset(std::size_t m) const;
  std::size_t vertex_count(std::size_t m) const;
  int joint_offset(std::size_t m) const;
  int joint_count(std::size_t m) const;

  // Every call below on a moved-from Skinner returns kInvalidState "used
  // after move" (the accessors return 0 / null / an empty Selection). A
  // Skinner keeps its Device's context, queue and programs alive: it may
  // outlive the Device object. A GL Skinner needs its GL context current on
  // the calling thread (kInvalidState otherwise).
  //
  // The frame loop (docs/RUNTIME.md "The frame loop") is SetPalette + Skin
  // per frame, without Finish: a Skinner keeps SkinnerOptions::palette_buffers
  // palette buffers (a ring, 3 by default: N below), so up to N frames are
  // queued on the device while the host prepares the next. Which calls block:
  //   SetPalette  only when N frames are already in flight: it then waits
  //               for the oldest of them (the one whose palette buffer it
  //               reuses), never for the frame just queued;
  //   Skin        never (it queues the launches);
  //   Finish, ReadPositions, ReadNormals  wait for the device (everything
  //               queued so far).
  // With DeviceOptions::submit_thread the Device's thread makes the upload's
  // and the launch's driver calls: SetPalette also waits while that thread
  // has not yet queued the frame N SetPalette calls ago, and an error of a
  // handed-over call comes back from the next call instead.

  // Uploads the palettes: instances() * joint_count() column-major 4x4 float
  // matrices (16 floats each, as glm::mat4 stores them; instance k's joints
  // at [k * joint_count * 16]). `float_count` must equal
  // instances() * joint_count() * 16, else kInvalidArgument; null `matrices`:
  // kInvalidArgument; a NaN or infinite element: kInvalidArgument naming the
  // matrix and element. A rejected palette changes nothing: the next Skin()
  // uses the last palette accepted. The data is copied into page-locked
  // staging of the next palette buffer before SetPalette returns (a palette
  // of 1024 matrices or more on threads of skintune's own, half the host's
  // cores from 2 to 8, which poll for 0.5 ms after each SetPalette before
  // they sleep) and
  // uploaded asynchronously (CUDA and OpenCL: on a stream / queue of the
  // Skinner's own, which the next Skin waits for on the device, so the
  // upload overlaps the frame still running): the caller may reuse
  // `matrices` at once. Blocks only when the palette buffer it needs is
  // still read by a frame queued N SetPalette calls ago (N: palette_buffers;
  // or, when no Skin came between, while that buffer's upload is still in
  // flight). On GL it waits only for that buffer's upload N SetPalette calls
  // ago: GL runs the
  // new upload after the frames that read the buffer by itself.
  Status SetPalette(const float* matrices, std::size_t float_count);
  // The morph targets' weights (MeshView::morph_target_count per instance,
  // instance k's at [k * morph_target_count()]; `count` must equal
  // instances() * morph_target_count()), kept until the next call and
  // uploaded with every SetPalette from the next one on (a CreateAnimated
  // Skinner's: every SetAnimation and AdvanceAnimation), in the same palette
  // buffer's slot: weights and palette of one frame always go together. It
  // blocks never and uploads nothing by itself. kInvalidArgument for a null
  // `weights`, a wrong count or a weight that is not finite (naming it); a
  // rejected call changes nothing. kInvalidState on a Skinner whose mesh has
  // no morph targets.
  Status SetMorphWeights(const float* weights, std::size_t count);
  // The mesh's morph targets per instance (0: none).
  int morph_target_count() const;
  // A CreateAnimated Skinner's frame: every instance's animation state
  // (`count` must equal instances()), copied into the page-locked staging of
  // the next palette buffer's instances and uploaded asynchronously, as
  // SetPalette does with palettes (it blocks only as SetPalette does: the
  // same ring of SkinnerOptions::palette_buffers). The next Skin() computes
  // the palettes from them on the device. kInvalidArgument naming the state
  // and field for an animation outside -1..animation_count()-1 of the model
  // (animation2 only checked where weight != 0), a time, time2 or weight that
  // is not finite, a weight outside [0, 1], a null `states`, a wrong count;
  // a rejected frame changes nothing. kInvalidState on a Skinner made by
  // Create or CreateBatch.
  Status SetAnimation(const AnimationState* states, std::size_t count);
  // A CreateAnimated Skinner's frame with nothing uploaded: every instance's
  // time (and time2) advances by `seconds` from its last state (the last
  // SetAnimation's, advanced by every AdvanceAnimation since), on the
  // device: each clock loops within its clip's time range
  // (Model::animation_start .. + animation_duration), and the rest pose stays.
  // The delta is passed with the palette kernel's launch, so no copy to the
  // device precedes the frame (docs/ANIMATION.md: that copy is most of what a
  // frame costs above its kernels; a model with morph targets uploads its
  // instances' weights, SetMorphWeights's, into the buffer). It takes the
  // next palette buffer as SetAnimation does and blocks only as it does; the
  // next Skin() computes the palettes. With SkinnerOptions::fuse_palette it
  // takes no buffer: the launches add the seconds summed since the last
  // SetAnimation (blocking only for the frame palette_buffers frames back,
  // or 16 back on a Vulkan device skintune opened, which gathers 8 frames
  // into a submission: holding no buffer, a fused frame bounds only how far
  // the host runs ahead), and past 16 s of them it uploads the advanced
  // states once, as SetAnimation would. Negative seconds play backwards.
  // kInvalidArgument for seconds that are not finite; kInvalidState on a
  // Skinner made by Create or CreateBatch.
  Status AdvanceAnimation(float seconds);
  // Whether the palettes are computed on the device (CreateAnimated).
  bool animated() const;
  // A CreateAnimated Skinner with SkinnerOptions::bake_rate: every clip, in
  // the model's order, with what baking it cost and lost; else empty.
  std::vector<BakedClip> baked_clips() const;
  // The bytes of the animation on the device (the packed keys and hierarchy,
  // or the baked frames); 0 for a Skinner that is not animated.
  std::size_t animation_bytes() const;

  // Queues the skinning of every instance with the last palette set and
  // returns without waiting for the device (skintune waits on nothing here).
  // On a Vulkan Device skintune opened, frames queued while earlier ones
  // still run share one submission (up to 8), which goes to the queue before
  // any call that reads, waits or submits (docs/RUNTIME.md "The frame loop");
  // on one made by Device::FromVulkan each Skin() is submitted to the
  // caller's queue before it returns.
  // Several Skin() calls after one SetPalette each skin with it.
  // kInvalidState before the first SetPalette.
  Status Skin();

  // Waits until the last Skin() has completed on the device, e.g. before
  // timing a frame or using device_positions() from another queue or API
  // (OpenCL clFinish, CUDA stream synchronise, GL glFinish; Vulkan polls the
  // fence for up to 1 ms on a GPU, then sleeps in vkWaitForFences). Nothing
  // to wait for before the first Skin() (returns ok). Blocks.
  Status Finish();

  // Skinned positions (and normals) of the last Skin() in the mesh's vertex
  // order: 3 floats per vertex, instance after instance; `float_count` must
  // equal instances() * vertex_count() * 3 (else kInvalidArgument), `out`
  // not null. Blocks: waits for everything queued, copies the output into
  // page-locked read-back memory the Skinner keeps, and from there into
  // `out`. kInvalidState before the first Skin(). A NaN or infinite output
  // is kDeviceError naming the vertex and instance, and never reaches `out`:
  // - where the palette's largest |element| times the mesh's largest
  //   |position| and weight sum could overflow float32, the whole output is
  //   scanned before anything is copied, and on such an error nothing is
  //   written to `out`;
  // - otherwise (every realistic palette) overflow is impossible, so each
  //   part is scanned as it is copied, in one pass over the bytes; a
  //   non-finite output can then only come from a broken kernel, and `out`
  //   may hold some of the other vertices when it is reported (as it may
  //   when the device fails in the middle of this read-back).
  Status ReadPositions(float* out, std::size_t float_count);
  // Likewise (blocks likewise), always scanned before it is copied (normals
  // are normalised: no bound holds); kInvalidState when the Skinner skins no
  // normals.
  Status ReadNormals(float* out, std::size_t float_count);
  // Skinned tangents likewise: 4 floats per vertex (x, y, z normalised, then
  // the handedness w), `float_count` = instances() * vertex_count() * 4;
  // always scanned before it is copied; kInvalidState when the Skinner skins
  // no tangents (SkinnerOptions::tangents).
  Status ReadTangents(float* out, std::size_t float_count);
  // The packed words of a Skinner whose SkinnerOptions::normal_format packs
  // them, as the kernel wrote them (one per vertex, instance after instance,
  // in the mesh's order): `word_count` = instances() * vertex_count().
  // Blocks as ReadNormals does. kInvalidState when the Skinner skins no
  // normals (tangents) or writes them as floats.
  Status ReadPackedNormals(std::uint32_t* out, std::size_t word_count);
  Status ReadPackedTangents(std::uint32_t* out, std::size_t word_count);

  // Output left on the device (no read-back): the native buffer holding the
  // positions of the last Skin(): a cl_mem (OpenCL), a CUdeviceptr
  // (CUDA, as reinterpret_cast<void*>(uintptr_t)) or a GL buffer name (GL,
  // likewise), `output_stride_bytes()` per vertex (12: float3, 16: float4
  // with w = 1), in the mesh's vertex order, instance after instance. Owned by
  // the Skinner; valid while it lives. Synchronise before reading it on
  // another queue / stream (OpenCL: the Device's queue is in-order; GL, on
  // your context (Device::FromCurrentGl): glMemoryBarrier is issued after
  // each Skin(); on a context skintune made, whose buffer names only its own
  // calls use, before the next read instead).
  void* device_positions() const;
  std::size_t output_stride_bytes() const;
  // The normals (tangents) of the last Skin() left on the device likewise,
  // `normal_stride_bytes()` (`tangent_stride_bytes()`) per vertex: the
  // position format's for float32 normals (16 for tangents), 4 where
  // SkinnerOptions::normal_format packs them (one word a vector, the format
  // of docs/VARIANTS.md "Packed normals and tangents", for a vertex buffer
  // of that format). Null (and 0) when the Skinner skins none. Owned by the
  // Skinner; synchronise as for device_positions().
  void* device_normals() const;
  void* device_tangents() const;
  std::size_t normal_stride_bytes() const;
  std::size_t tangent_stride_bytes() const;

  // OpenCL-OpenGL interop (cl_khr_gl_sharing, as in the paper): skin the
  // positions straight into GL buffer object `gl_buffer` of the shared GL
  // context, in the mesh's order, output_stride_bytes() per vertex
  // (clCreateFromGLBuffer once per buffer, then each call: glFinish, acquire,
  // skin, release, clFinish, so GL can draw from it on return). The buffer
  // must hold at least instances() * vertex_count() * output_stride_bytes()
  // bytes and belong to the shared context (kInvalidArgument otherwise); that
  // context must be current. Normals, when skinned, go to the Skinner's own
  // buffer, and Read* reads the Skinner's own output (of the last Skin()).
  // kUnavailable when the Device has no GL sharing (see
  // Device::OpenClForCurrentGl); kInvalidState before the first SetPalette.
  //
  // On a CUDA Device (CUDA-OpenGL interop, the paper's section 4.1): any
  // buffer object of the GL context current on the calling thread, which
  // must be on the same GPU (an EGL context on the NVIDIA device). The buffer
  // is registered once (cuGraphicsGLRegisterBuffer, write-discard) and each
  // call maps it on the Device's stream, skins into it and unmaps it; the
  // host does not wait: the map orders the kernel after GL's earlier use of
  // the buffer, the unmap GL's later use after the kernel. kInvalidState when
  // no GL context is current; kInvalidArgument for a name that is not a
  // buffer of that context, or one too small. Registrations are released
  // with the Skinner (its GL context should still exist then).
  Status SkinIntoGlBuffer(unsigned int gl_buffer);

  // Vulkan (how an engine records skinning into its frame): records the
  // dispatches of one Skin() into `vk_command_buffer` (a VkCommandBuffer of
  // the Device's queue family, recording, outside a render pass), writing the
  // positions into `vk_buffer` (a VkBuffer with storage-buffer usage of at
  // least instances() * vertex_count() * output_stride_bytes() bytes, bound
  // to memory), or into the Skinner's own output (device_positions(), a
  // VkBuffer) when null. The recording starts with the copy of the palette
  // SetPalette staged (where the palette is not host-visible) and a barrier
  // after earlier transfers and compute work, and ends with one making the
  // outputs visible to every later command. That copy reads staging which
  // the third SetPalette after this call reuses: submit the command buffer
  // before then. Normals go to the Skinner's own buffer. The caller submits the
  // command buffer; Read* and Finish then wait for the queue to be idle.
  // Each distinct `vk_buffer` takes a descriptor set (at most 7 per
  // Skinner). kUnavailable on a device of another backend; kInvalidArgument
  // for a null command buffer; kInvalidState before the first SetPalette.
  Status SkinIntoVulkan(void* vk_command_buffer, void* vk_buffer = nullptr);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// ---------------------------------------------------------------- models

// A skinned model with its skeleton and animations, loaded by skintune so a
// program can drive a Skinner without a glTF loader of its own: a glTF 2.0
// file or a synthetic dataset (the paper's meshes, docs/DATA.md). Copyable.
class Model {
 public:
  // A .gltf / .glb file: its first skinned mesh (every triangle primitive),
  // skin and animations (docs/DATA.md, "glTF import", says what is read). Weights
  // that do not sum to 1 are renormalised with one line in warnings().
  // kIoError when the file cannot be read; kInvalidArgument naming the file
  // and the element for anything malformed (accessor out of its buffer, joint
  // outside the skin, negative weights, not glTF at all...). Morph targets
  // come with the mesh (mesh(), MorphWeights).
  static Result<Model> Load(const std::string& path);
  // A synthetic dataset by key: "100k-b4", "1600k-b2-random",
  // "5000-b8-bones12-seed3-normals" (docs/DATA.md); kInvalidArgument naming
  // the bad part of the key.
  static Result<Model> Synthetic(const std::string& key);

  Model();  // empty: vertex_count() 0, mesh() all null
  ~Model();
  Model(const Model&);
  Model& operator=(const Model&);
  Model(Model&&) noexcept;
  Model& operator=(Model&&) noexcept;

  const std::string& source() const;  // file name or dataset key
  std::size_t vertex_count() const;
  int influences() const;    // largest number of non-zero weights of any vertex
  int joint_count() const;
  bool has_normals() const;
  bool has_tangents() const;  // the file's TANGENT, on every triangle primitive (with normals)
  // The mesh as a MeshView over this Model's arrays, for Skinner::Create
  // (normals, tangents null when the model has none; its morph targets at
  // their default weights); valid while the Model lives unchanged.
  MeshView mesh() const;
  int morph_target_count() const;  // the skinned mesh's morph targets (glTF `targets`)
  // The morph targets' weights of animation `animation` at time `t` (its
  // `weights` channel; the defaults where it has none), or the defaults
  // (glTF: the node's, else the mesh's, else 0) for animation -1:
  // morph_target_count() floats, ready for Skinner::SetMorphWeights.
  // kInvalidArgument for an animation outside -1..animation_count()-1 or a t
  // that is not finite.
  Status MorphWeights(int animation, double t, std::vector<float>* weights) const;
  const std::vector<std::string>& warnings() const;  // import warnings, whole lines

  int animation_count() const;
  // Index of the animation named `name`, or of `name` as a decimal index;
  // kNotFound listing the animations there are.
  Result<int> FindAnimation(const std::string& name) const;
  std::string animation_name(int animation) const;  // "" outside 0..animation_count()-1
  double animation_start(int animation) const;      // seconds (0 outside the range)
  double animation_duration(int animation) const;   // seconds (0 outside the range)

  // The palette of animation `animation` at time `t` seconds (clip time,
  // clamped to the keys as glTF does), or of the rest pose for animation -1:
  // joint_count() column-major 4x4 matrices, 16 floats each, ready for
  // Skinner::SetPalette. kInvalidArgument for an animation outside
  // -1..animation_count()-1, a t that is not finite, or a palette entry that
  // is not finite in float32 (naming the joint, its node and the element).
  Status Palette(int animation, double t, std::vector<float>* matrices) const;

  // The float64 reference ("gold") skinning of this model's positions with
  // `matrices` (joint_count() * 16 floats), rounded to float: 3 floats per
  // vertex. What the tests check every kernel against; slow, for checks.
  Status SkinReference(const float* matrices, std::size_t float_count, std::vector<float>* positions) const;
  // The same with the morph targets at `morph_weights` (morph_target_count()
  // of them; the first overload: the default weights), applied first.
  Status SkinReference(const float* matrices, std::size_t float_count, const float* morph_weights,
                       std::size_t weight_count, std::vector<float>* positions) const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
  friend struct internal::ModelAccess;  // the library's own, not part of the API
};

}  // namespace skintune
