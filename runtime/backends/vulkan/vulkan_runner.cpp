// The Vulkan DeviceApi (vulkan_runner.h): SPIR-V (shaderc, with the program
// cache), pipelines, buffers, descriptor sets, command buffers with
// timestamps; and VulkanRunner.
#include "runtime/backends/vulkan/vulkan_runner.h"

#include <algorithm>
#include <array>
#include <cstdlib>
#include <cstring>
#include <map>
#include <set>
#include <utility>

#include "generator/axes.h"
#include "base/error.h"
#include "base/thread_pool.h"
#include "runtime/backends/vulkan/vulkan_spirv.h"
#include "runtime/host_work.h"
#include "runtime/output_check.h"

namespace skintune::internal {
namespace vk {

namespace {

class VulkanBuffer;

// The device, its queue and its memory types: owned, or the caller's.
struct Context {
  std::shared_ptr<VulkanInstance> instance;
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  VulkanDeviceInfo info;
  VkDevice device = VK_NULL_HANDLE;
  bool owns_device = true;
  DeviceFunctions fn;
  VkQueue queue = VK_NULL_HANDLE;
  std::uint32_t family = 0;
  VkPhysicalDeviceMemoryProperties memory{};
  // $SKINTUNE_VULKAN_STAGING=1: kernel buffers are never mapped, so a device
  // whose memory is all host-visible (lavapipe) takes the staging paths of a
  // discrete GPU (tests).
  bool staging_only = [] {
    const char* env = std::getenv("SKINTUNE_VULKAN_STAGING");
    return env && *env && std::string(env) != "0";
  }();

  // Palette uploads written into their staging and not yet recorded: the
  // next frame's command buffer copies them first (VulkanApi::Write).
  mutable std::vector<std::pair<VulkanBuffer*, std::size_t>> pending_uploads;

  Context() = default;
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;
  ~Context() {
    if (!owns_device || !device) return;
    fn.vkDeviceWaitIdle(device);
    fn.vkDestroyDevice(device, nullptr);
  }

  // A memory type of `bits` with every flag of `need`, one with `prefer` too first.
  std::uint32_t MemoryType(std::uint32_t bits, VkMemoryPropertyFlags need, VkMemoryPropertyFlags prefer,
                           const std::string& what) const {
    for (const VkMemoryPropertyFlags flags : {need | prefer, need}) {
      for (std::uint32_t t = 0; t < memory.memoryTypeCount; ++t)
        if ((bits & (1u << t)) && (memory.memoryTypes[t].propertyFlags & flags) == flags) return t;
    }
    Fail("launch", "no memory type for " + what);
  }
};

constexpr VkBufferUsageFlags kKernelBufferUsage =
    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT |
    VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
constexpr VkBufferUsageFlags kStagingUsage = VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
constexpr VkMemoryPropertyFlags kHostMemory = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;

// A buffer and its memory; mapped when the memory is host-visible and coherent.
class VulkanBuffer final : public DeviceBuffer {
 public:
  VulkanBuffer(const Context& c, std::size_t bytes, VkBufferUsageFlags usage, bool host, const std::string& what)
      : DeviceBuffer(bytes), c_(c) {
    VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    info.size = bytes;
    info.usage = usage;
    info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    Check(c.fn.vkCreateBuffer(c.device, &info, nullptr, &buffer), "launch", "vkCreateBuffer '" + what + "' (" +
                                                                              std::to_string(bytes) + " bytes)");
    VkMemoryRequirements needs{};
    c.fn.vkGetBufferMemoryRequirements(c.device, buffer, &needs);
    VkMemoryAllocateInfo allocate{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    allocate.allocationSize = needs.size;
    allocate.memoryTypeIndex = host ? c.MemoryType(needs.memoryTypeBits, kHostMemory, VK_MEMORY_PROPERTY_HOST_CACHED_BIT, what)
                                    : c.MemoryType(needs.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0, what);
    const VkResult allocated = c.fn.vkAllocateMemory(c.device, &allocate, nullptr, &memory);
    if (allocated != VK_SUCCESS) {
      c.fn.vkDestroyBuffer(c.device, buffer, nullptr);
      buffer = VK_NULL_HANDLE;
      Check(allocated, "launch", "vkAllocateMemory for '" + what + "' (" + std::to_string(bytes) + " bytes)");
    }
    c.fn.vkBindBufferMemory(c.device, buffer, memory, 0);
    const VkMemoryPropertyFlags flags = c.memory.memoryTypes[allocate.memoryTypeIndex].propertyFlags;
    if ((flags & kHostMemory) == kHostMemory && (host || !c.staging_only))
      Check(c.fn.vkMapMemory(c.device, memory, 0, VK_WHOLE_SIZE, 0, &mapped), "launch", "vkMapMemory '" + what + "'");
  }
  ~VulkanBuffer() override {
    auto& pending = c_.pending_uploads;
    pending.erase(std::remove_if(pending.begin(), pending.end(), [&](const auto& p) { return p.first == this; }),
                  pending.end());
    staging.reset();
    readback.reset();
    if (mapped) c_.fn.vkUnmapMemory(c_.device, memory);
    if (buffer) c_.fn.vkDestroyBuffer(c_.device, buffer, nullptr);
    if (memory) c_.fn.vkFreeMemory(c_.device, memory, nullptr);
  }
  void* native() const override { return reinterpret_cast<void*>(buffer); }

  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  void* mapped = nullptr;
  std::unique_ptr<VulkanBuffer> staging;            // Write's, host-visible, reused
  mutable std::unique_ptr<VulkanBuffer> readback;   // ReadPinned's, host-visible, reused

 private:
  const Context& c_;
};

// `image` storage: the uniform texel buffer view of the palette.
class VulkanView final : public DeviceObject {
 public:
  VulkanView(const Context& c, VkBufferView v) : c_(c), view(v) {}
  ~VulkanView() override { c_.fn.vkDestroyBufferView(c_.device, view, nullptr); }
  const Context& c_;
  VkBufferView view;
};

struct Pipeline {
  VkShaderModule module = VK_NULL_HANDLE;
  VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  VkPipeline pipeline = VK_NULL_HANDLE;
  std::vector<VkDescriptorType> types;  // per binding
};

class VulkanPlanned final : public PlannedLaunch {
 public:
  using PlannedLaunch::PlannedLaunch;
  const Pipeline* pipeline = nullptr;
  std::uint32_t groups_x = 1, groups_y = 1;
  std::uint32_t push[kPushConstantBytes / 4] = {};  // n, first, vertex_count; a fused kernel's elapsed from the run
};

// One launch of one set: its descriptor set (and one per buffer the Skinner
// writes positions into instead: FrameRun::out_positions).
class VulkanBound final : public DeviceObject {
 public:
  explicit VulkanBound(const Context& c) : c_(c) {}
  ~VulkanBound() override {
    if (pool) c_.fn.vkDestroyDescriptorPool(c_.device, pool, nullptr);
  }
  const Context& c_;
  const VulkanPlanned* plan = nullptr;
  const VulkanBuffer* palette = nullptr;  // the slot's (its staged upload goes first: RecordPendingUploads)
  std::vector<const VulkanBuffer*> inputs;  // likewise (a palette kernel's per-frame instances)
  VkDescriptorPool pool = VK_NULL_HANDLE;
  VkDescriptorSet set = VK_NULL_HANDLE;
  std::vector<VkWriteDescriptorSet> writes;  // how `set` was written (pointing into the two vectors below)
  std::vector<VkDescriptorBufferInfo> buffers;
  std::vector<VkBufferView> views;
  int out_positions_binding = -1;
  std::map<VkBuffer, VkDescriptorSet> redirected;  // out_positions -> a caller's buffer
};

// A timestamp query pool, destroyed with this.
class QueryPool {
 public:
  QueryPool(const Context& c, VkQueryPool pool) : c_(c), pool_(pool) {}
  QueryPool(QueryPool&& other) noexcept : c_(other.c_), pool_(other.pool_) { other.pool_ = VK_NULL_HANDLE; }
  QueryPool(const QueryPool&) = delete;
  QueryPool& operator=(const QueryPool&) = delete;
  QueryPool& operator=(QueryPool&&) = delete;
  ~QueryPool() {
    if (pool_) c_.fn.vkDestroyQueryPool(c_.device, pool_, nullptr);
  }
  VkQueryPool get() const { return pool_; }

 private:
  const Context& c_;
  VkQueryPool pool_;
};

// A submitted command buffer and what must live until it completes.
struct Submission {
  VkCommandBuffer cb = VK_NULL_HANDLE;
  VkFence fence = VK_NULL_HANDLE;
  std::uint64_t number = 0;  // 1, 2, ... in submission order
  std::vector<std::unique_ptr<VulkanBuffer>> keep;
};

// The palette ring's fence: every submission up to `number`, or (after
// launches recorded into a caller's command buffer) the queue idle.
class VulkanMarker final : public DeviceObject {
 public:
  std::uint64_t number = 0;
  bool queue_idle = false;
};

std::string Headline(const std::string& text) {
  std::size_t at = text.find("// Generated by");
  if (at == std::string::npos) at = 0;
  return text.substr(at, text.find('\n', at) - at);
}

// The palette storage a kernel was emitted for: its STORAGE define, read back
// through the axis table.
PaletteStorage StorageOf(const KernelSource& source) {
  const Axis& axis = AxisOf<&Variant::storage>();
  for (const auto& [name, value] : source.defines) {
    if (name != axis.define) continue;
    for (const AxisValueSpec& v : axis.values)
      if (v.define == value) return static_cast<PaletteStorage>(v.code);
  }
  return PaletteStorage::kGlobal;  // the template's default
}

VkDescriptorType DescriptorType(const KernelArgument& a, PaletteStorage storage) {
  if (a.name == "palette" && storage == PaletteStorage::kConstant) return VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
  if (a.name == "palette" && storage == PaletteStorage::kImage) return VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
  return VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
}

}  // namespace

class VulkanApi final : public DeviceApi {
 public:
  explicit VulkanApi(std::unique_ptr<Context> context) : c_(std::move(context)) {
    VkCommandPoolCreateInfo pool{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pool.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    pool.queueFamilyIndex = c_->family;
    Check(c_->fn.vkCreateCommandPool(c_->device, &pool, nullptr, &pool_), "setup", "vkCreateCommandPool");
  }
  ~VulkanApi() override {
    WaitAll();
    for (VkFence f : spare_fences_) c_->fn.vkDestroyFence(c_->device, f, nullptr);
    if (ready_fence_ != VK_NULL_HANDLE) c_->fn.vkDestroyFence(c_->device, ready_fence_, nullptr);
    for (VkCommandBuffer cb : spare_cbs_) c_->fn.vkFreeCommandBuffers(c_->device, pool_, 1, &cb);
    for (auto& [key, p] : pipelines_) DestroyPipeline(p);
    for (auto& [key, module] : modules_) c_->fn.vkDestroyShaderModule(c_->device, module, nullptr);
    c_->fn.vkDestroyCommandPool(c_->device, pool_, nullptr);
  }

  const Context& context() const { return *c_; }
  void RecordInto(VkCommandBuffer cb) { record_into_ = cb; }
  std::uint64_t submissions() const { return submitted_; }
  const std::vector<VkCommandBuffer>& cold_command_buffers() const { return cold_order_; }

  const char* name() const override { return "Vulkan"; }
  const std::string& device_name() const override { return c_->info.name; }
  // The pipeline too: its creation is the driver's compile (which the
  // driver's own disk cache keeps, so the tuner's compile-ahead threads warm
  // it for the measuring runner). The palette's storage is the kernel's.
  // (A source without its argument list, such as a bare template, is
  // compiled to SPIR-V only: its pipeline layout is unknown.)
  void Build(const KernelSource& source) override {
    if (source.arguments.empty()) {
      ModuleFor(source);
      return;
    }
    PipelineFor(source, StorageOf(source));
  }
  void CheckRun(const PackedMesh& mesh, std::span<const KernelSource> kernels, const RunShape& shape) const override;
  std::size_t PaletteBufferBytes(const RunShape& shape, std::span<const KernelSource> kernels) const override;
  std::unique_ptr<PlannedLaunch> Plan(const LaunchSpec& spec) override;
  std::unique_ptr<DeviceBuffer> Allocate(BufferUse use, std::size_t bytes, const void* initial,
                                         const std::string& what) override;
  std::unique_ptr<DeviceObject> PaletteView(const Variant& variant, DeviceBuffer& palette,
                                            const std::string& suffix) override;
  std::unique_ptr<DeviceObject> Bind(const PlannedLaunch& launch, std::span<const ArgumentBinding> arguments,
                                     const SetOptions& options, std::size_t& allocated) override;
  void FinishUploads(const std::string&) override { WaitAll(); }
  std::vector<std::vector<double>> RunFrames(const FrameRun& run) override;
  // On a GPU, warm up until the clock is steady, as GL on the same NVIDIA driver needs.
  TimingPolicy timing_policy() const override { return {c_->info.type == "gpu"}; }
  std::string kernel_clock() const override { return "Vulkan timestamp queries"; }
  std::span<std::uint8_t> Staging(DeviceBuffer& buffer, const std::string& key, bool upload_fenced) override;
  void Upload(DeviceBuffer& buffer, std::size_t bytes, const std::string& key) override;
  void Read(const DeviceBuffer& buffer, std::span<std::uint8_t> out, const std::string& what, bool wait) override;
  std::span<const std::uint8_t> ReadPinned(const DeviceBuffer& buffer, std::size_t bytes,
                                           const std::string& what) override;
  void Mark(std::unique_ptr<DeviceObject>& marker, const std::string& what) override;
  void Wait(DeviceObject& marker, const std::string& what) override;
  void Finish() override;
  std::size_t FramesPerSubmission() const override { return c_->owns_device ? kFramesPerSubmission : 1; }
  // Every submission (and the caller's, after SkinIntoVulkan) completes
  // before its buffers and descriptor sets are destroyed: lavapipe frees
  // them under a queue thread still running the frame otherwise.
  bool ReadyToRelease() override {
    try {
      Finish();
    } catch (const Error&) {  // a lost device: nothing runs any more
    }
    return true;
  }

 private:
  // The shader module of `source`: from memory, the disk cache or compiled;
  // `from_source` skips memory and disk (a cached module the driver refused).
  VkShaderModule ModuleFor(const KernelSource& source, bool from_source = false);
  // SPIR-V stored for `cache_key` that looks like SPIR-V (its magic number), or none.
  std::vector<std::uint32_t> CachedSpirv(const std::string& cache_key) const;
  const Pipeline& PipelineFor(const KernelSource& source, PaletteStorage storage);
  // Creates p's layouts and pipeline over p.module; throws build errors.
  void CreatePipeline(Pipeline& p, const KernelSource& source, PaletteStorage storage);
  void DestroyPipeline(Pipeline& p);
  // A new command buffer, recording. The open frames (below) go to the
  // queue first, so that submissions keep their order. `live`: for live
  // frames (RunFrames kLive); any other work sets unordered_since_frames_.
  VkCommandBuffer Begin(bool live = false);
  // Command buffers and fences kept for reuse (Retire).
  static constexpr std::size_t kSpares = 16;
  // The kernel time's frames (RunCold) are recorded into kColdCommandBuffers
  // command buffers taken in turn, not the one retired last: on NVIDIA's
  // driver a launch's stamped time depends on the command buffer it is
  // recorded into, steadily. One 100k-vertex kernel read 4.13-4.42 us by
  // command buffer (H200, driver 580.159.04, 2026-12-02), so a measurement
  // on one command buffer carried its level: medians 1.03-1.07x apart from
  // one process to the next. Sixteen in turn put four processes' medians
  // within 1.007x (skintune_bench_kernel_time --sequence).
  static constexpr std::size_t kColdCommandBuffers = 16;
  static_assert(kColdCommandBuffers <= kSpares, "the cold rotation's command buffers are kept as spares");
  // Tops the spares up to kColdCommandBuffers.
  void AllocateColdCommandBuffers();
  // Live frames on a device skintune opened are batched: each Skin() records
  // into the open command buffer, which goes to the queue when nothing of
  // this API's is running on it (so a frame never waits on an idle GPU),
  // when it holds kFramesPerSubmission frames, or before any other
  // submission, read or wait that blocks (Begin, WaitAll, Wait). NVIDIA's Vulkan driver
  // spends about 20 us of GPU time and 30 us of host time on each submission
  // of one frame (H200, 2026-12-01): a crowd's frame took 40-50 us for an
  // 18 us kernel. On adopted handles (Device::FromVulkan) every Skin()
  // submits, since the caller's own submissions share the queue and must
  // come after it.
  static constexpr std::size_t kFramesPerSubmission = 8;
  VkCommandBuffer OpenFrames();
  void SubmitOpenFrames();
  // Ends and submits `cb`; waits when `wait`, else keeps it (and `keep`) in flight.
  void Submit(VkCommandBuffer cb, bool wait, std::vector<std::unique_ptr<VulkanBuffer>> keep = {});
  void Retire(bool wait_all);
  VkResult MakeAFenceReady(const char** call);
  VkResult WaitForFence(VkFence fence) const;
  void WaitAll() {
    SubmitOpenFrames();
    Retire(true);
  }
  void Upload(VulkanBuffer& to, const void* bytes, std::size_t size, const std::string& what);
  void Barrier(VkCommandBuffer cb, VkPipelineStageFlags from, VkAccessFlags from_access, VkPipelineStageFlags to,
               VkAccessFlags to_access) const;
  void RecordPendingUploads(VkCommandBuffer cb, const FrameRun& run);
  void RecordFrames(VkCommandBuffer cb, const FrameRun& run, std::size_t begin, std::size_t end,
                    std::set<const void*>& used, VkQueryPool pool, int* query);
  void BarrierBeforeFrames(VkCommandBuffer cb) const;
  // kCold: every frame after the flush, each launch alone between timestamps.
  std::vector<std::vector<double>> RunCold(const FrameRun& run);
  void BarrierAfterFrames(VkCommandBuffer cb, bool for_caller) const;
  // Records one launch (optionally between timestamps `query`, `query + 1`).
  // A prologue's launch (`prologue`: its run) pushes the run's scalars instead.
  void RecordLaunch(VkCommandBuffer cb, const VulkanBound& bound, VkDescriptorSet set, VkQueryPool pool,
                    int query, const FrameRun* run = nullptr) const;
  VkDescriptorSet Redirected(VulkanBound& bound, VkBuffer out_positions);
  double TicksToMs(std::uint64_t start, std::uint64_t end) const;
  QueryPool NewQueryPool(std::uint32_t count);  // none for 0
  std::vector<std::uint64_t> QueryResults(VkQueryPool pool, std::uint32_t count);
  void CheckStorageRange(std::size_t bytes, const std::string& what) const;

  std::unique_ptr<Context> c_;
  VkCommandPool pool_ = VK_NULL_HANDLE;
  std::map<std::string, VkShaderModule> modules_;  // by source hash
  std::set<std::string> modules_from_disk_;        // those loaded from the disk cache
  std::map<std::string, Pipeline> pipelines_;      // by source hash and palette storage
  std::vector<Submission> in_flight_;  // oldest first
  std::vector<VkCommandBuffer> spare_cbs_;  // retired, for reuse, the last retired last
  bool spares_in_turn_ = false;  // Begin takes the longest retired (RunCold), not the last
  std::vector<VkCommandBuffer> cold_order_;  // the last RunCold's frames' command buffers, in order
  VkCommandBuffer open_frames_ = VK_NULL_HANDLE;  // recording live frames not yet submitted (OpenFrames)
  std::size_t open_frame_count_ = 0;
  std::vector<VkFence> spare_fences_;  // signalled, to be reset before reuse
  VkFence ready_fence_ = VK_NULL_HANDLE;  // made ready ahead of the next Submit (MakeAFenceReady)
  std::uint64_t submitted_ = 0;  // submissions so far
  VkCommandBuffer record_into_ = VK_NULL_HANDLE;
  bool recorded_for_caller_ = false;  // launches recorded into a caller's command buffer since the last wait
  // Work other than live frames (uploads, reads, timed runs) recorded since
  // the last live frame's BarrierBeforeFrames: the next prologue waits for it.
  bool unordered_since_frames_ = true;
};

// ---------------------------------------------------------------- programs

std::vector<std::uint32_t> VulkanApi::CachedSpirv(const std::string& cache_key) const {
  constexpr std::uint32_t kSpirvMagic = 0x07230203;
  const auto payload = cache_->Load("vulkan", cache_key);
  std::vector<std::uint32_t> words;
  if (!payload || payload->size() % 4 != 0 || payload->size() < 20) return words;  // 5 header words at least
  words.resize(payload->size() / 4);
  std::memcpy(words.data(), payload->data(), payload->size());
  if (words[0] != kSpirvMagic) words.clear();
  return words;
}

VkShaderModule VulkanApi::ModuleFor(const KernelSource& source, bool from_source) {
  if (!IsGlslText(source.lang) || source.lang == Lang::kGlslVertex)
    Fail("build", std::string("kernel language is ") + Name(source.lang) + ", not vulkan");
  const std::string key = HashOf(source);
  if (auto found = modules_.find(key); found != modules_.end()) {
    if (!from_source) {
      if (cache_) ++cache_->counters().memory_hits;
      return found->second;
    }
    c_->fn.vkDestroyShaderModule(c_->device, found->second, nullptr);
    modules_.erase(found);
    if (modules_from_disk_.erase(key) > 0 && cache_) --cache_->counters().disk_hits;  // no hit after all
  }
  const std::string what = "kernel " + key + " (" + Headline(source.text) + ") on " + c_->info.name;
  const std::string cache_key = cache_ ? ProgramKey("vulkan", cache_device_id_, key, "shaderc vulkan1.1 -O") : "";
  VkShaderModuleCreateInfo info{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  VkShaderModule module = VK_NULL_HANDLE;
  if (cache_ && !from_source) {
    const std::vector<std::uint32_t> words = CachedSpirv(cache_key);
    info.codeSize = words.size() * 4;
    info.pCode = words.data();
    if (!words.empty() && c_->fn.vkCreateShaderModule(c_->device, &info, nullptr, &module) == VK_SUCCESS) {
      ++cache_->counters().disk_hits;
      modules_from_disk_.insert(key);
      return modules_.emplace(key, module).first->second;
    }
  }
  const std::vector<std::uint32_t> words = CompileSpirv(source.text, what);
  if (cache_) {
    ++cache_->counters().builds;
    const auto* bytes = reinterpret_cast<const std::uint8_t*>(words.data());
    cache_->Store("vulkan", cache_key, std::vector<std::uint8_t>(bytes, bytes + words.size() * 4));
  }
  info.codeSize = words.size() * 4;
  info.pCode = words.data();
  Check(c_->fn.vkCreateShaderModule(c_->device, &info, nullptr, &module), "build", "vkCreateShaderModule " + what);
  return modules_.emplace(key, module).first->second;
}

const Pipeline& VulkanApi::PipelineFor(const KernelSource& source, PaletteStorage storage) {
  const std::string key = HashOf(source) + "/" + Name(storage);
  if (auto found = pipelines_.find(key); found != pipelines_.end()) {
    if (cache_) ++cache_->counters().memory_hits;  // its program, found in memory
    return found->second;
  }
  Pipeline p;
  p.module = ModuleFor(source);
  try {
    CreatePipeline(p, source, storage);
  } catch (const Error&) {
    // A module from the disk cache whose checksum holds may still be damaged
    // SPIR-V (written so, or by another tool): rebuilt from source, as GL and
    // OpenCL rebuild a binary their driver refuses, and stored over the file.
    if (!modules_from_disk_.count(HashOf(source))) throw;
    p = Pipeline{};
    p.module = ModuleFor(source, true);
    CreatePipeline(p, source, storage);
  }
  return pipelines_.emplace(key, p).first->second;
}

void VulkanApi::CreatePipeline(Pipeline& p, const KernelSource& source, PaletteStorage storage) {
  std::vector<VkDescriptorSetLayoutBinding> bindings;
  for (const KernelArgument& a : source.arguments) {
    if (a.kind == ArgumentKind::kScalar) continue;
    const VkDescriptorType type = DescriptorType(a, storage);
    bindings.push_back({static_cast<std::uint32_t>(bindings.size()), type, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
    p.types.push_back(type);
  }
  const std::string what = "pipeline of " + Headline(source.text);
  try {
    VkDescriptorSetLayoutCreateInfo set{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    set.bindingCount = static_cast<std::uint32_t>(bindings.size());
    set.pBindings = bindings.data();
    Check(c_->fn.vkCreateDescriptorSetLayout(c_->device, &set, nullptr, &p.set_layout), "build",
          "vkCreateDescriptorSetLayout " + what);
    const VkPushConstantRange push{VK_SHADER_STAGE_COMPUTE_BIT, 0, static_cast<std::uint32_t>(kPushConstantBytes)};
    VkPipelineLayoutCreateInfo layout{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    layout.setLayoutCount = 1;
    layout.pSetLayouts = &p.set_layout;
    layout.pushConstantRangeCount = 1;
    layout.pPushConstantRanges = &push;
    Check(c_->fn.vkCreatePipelineLayout(c_->device, &layout, nullptr, &p.layout), "build",
          "vkCreatePipelineLayout " + what);
    VkComputePipelineCreateInfo info{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    info.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    info.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    info.stage.module = p.module;
    info.stage.pName = source.entry_point.c_str();
    info.layout = p.layout;
    Check(c_->fn.vkCreateComputePipelines(c_->device, VK_NULL_HANDLE, 1, &info, nullptr, &p.pipeline), "build",
          "vkCreateComputePipelines " + what);
  } catch (...) {
    const VkShaderModule module = p.module;  // the module's owner is modules_
    DestroyPipeline(p);
    p.module = module;
    throw;
  }
}

void VulkanApi::DestroyPipeline(Pipeline& p) {
  if (p.pipeline) c_->fn.vkDestroyPipeline(c_->device, p.pipeline, nullptr);
  if (p.layout) c_->fn.vkDestroyPipelineLayout(c_->device, p.layout, nullptr);
  if (p.set_layout) c_->fn.vkDestroyDescriptorSetLayout(c_->device, p.set_layout, nullptr);
  p = Pipeline{};
}

// ---------------------------------------------------------------- runs and launches

void VulkanApi::CheckRun(const PackedMesh& mesh, std::span<const KernelSource> kernels, const RunShape& shape) const {
  const Variant& variant = mesh.variant;
  if (variant.lang != Lang::kVulkan) Fail("launch", variant.Key() + " is not a vulkan variant");
  const VkPhysicalDeviceLimits& l = c_->info.limits;
  const std::size_t palette_bytes = PaletteBufferBytes(shape, kernels);
  if (variant.storage == PaletteStorage::kConstant && palette_bytes > l.maxUniformBufferRange)
    Fail("launch", variant.Key() + ": palette of " + std::to_string(palette_bytes) +
                       " bytes exceeds maxUniformBufferRange " + std::to_string(l.maxUniformBufferRange));
  if (variant.storage == PaletteStorage::kImage && palette_bytes / 16 > l.maxTexelBufferElements)
    Fail("launch", variant.Key() + ": palette of " + std::to_string(palette_bytes / 16) +
                       " texels exceeds maxTexelBufferElements " + std::to_string(l.maxTexelBufferElements));
  if (static_cast<std::uint64_t>(shape.instances) > l.maxComputeWorkGroupCount[1])
    Fail("launch", variant.Key() + ": " + std::to_string(shape.instances) +
                       " instances exceed maxComputeWorkGroupCount[1] " + std::to_string(l.maxComputeWorkGroupCount[1]));
}

// As GL: instanced constant storage binds the whole uniform block the kernel declares.
std::size_t VulkanApi::PaletteBufferBytes(const RunShape& shape, std::span<const KernelSource> kernels) const {
  int declared = 0;
  for (const KernelSource& k : kernels) declared = std::max(declared, k.max_instances);
  return std::max(static_cast<std::size_t>(shape.instances), static_cast<std::size_t>(declared)) * shape.palette_bytes;
}

std::unique_ptr<PlannedLaunch> VulkanApi::Plan(const LaunchSpec& spec) {
  const Variant& variant = spec.variant;
  const KernelSource& source = spec.source;
  CheckLaunchKernel(spec, name());
  auto plan = std::make_unique<VulkanPlanned>(spec);
  plan->pipeline = &PipelineFor(source, variant.storage);
  const std::size_t groups = source.launch.GlobalItems(spec.count) / static_cast<std::size_t>(source.launch.wg_size);
  const std::uint32_t max_x = c_->info.limits.maxComputeWorkGroupCount[0];
  if (groups > max_x)
    Fail("launch", spec.where + ": " + std::to_string(groups) + " work-groups exceed maxComputeWorkGroupCount[0] " +
                       std::to_string(max_x));
  plan->groups_x = static_cast<std::uint32_t>(std::max<std::size_t>(groups, 1));
  plan->groups_y = spec.instanced ? static_cast<std::uint32_t>(spec.instances) : 1u;
  plan->push[0] = spec.count;
  plan->push[1] = spec.first;
  plan->push[2] = spec.vertex_count;
  return plan;
}

void VulkanApi::CheckStorageRange(std::size_t bytes, const std::string& what) const {
  if (bytes > c_->info.limits.maxStorageBufferRange)
    Fail("launch", what + " of " + std::to_string(bytes) + " bytes exceeds maxStorageBufferRange " +
                       std::to_string(c_->info.limits.maxStorageBufferRange));
}

std::unique_ptr<DeviceBuffer> VulkanApi::Allocate(BufferUse, std::size_t bytes, const void* initial,
                                                  const std::string& what) {
  auto buffer = std::make_unique<VulkanBuffer>(*c_, bytes, kKernelBufferUsage, false, what);
  if (initial) Upload(*buffer, initial, bytes, what);
  return buffer;
}

// Host-visible memory is written at once (nothing reads a new buffer yet);
// other memory through a staging buffer copied on the queue.
void VulkanApi::Upload(VulkanBuffer& to, const void* bytes, std::size_t size, const std::string& what) {
  if (to.mapped) {
    std::memcpy(to.mapped, bytes, size);
    return;
  }
  auto staging = std::make_unique<VulkanBuffer>(*c_, size, kStagingUsage, true, "staging of " + what);
  std::memcpy(staging->mapped, bytes, size);
  const VkCommandBuffer cb = Begin();
  const VkBufferCopy region{0, 0, size};
  c_->fn.vkCmdCopyBuffer(cb, staging->buffer, to.buffer, 1, &region);
  std::vector<std::unique_ptr<VulkanBuffer>> keep;
  keep.push_back(std::move(staging));
  Submit(cb, false, std::move(keep));
}

std::unique_ptr<DeviceObject> VulkanApi::PaletteView(const Variant& variant, DeviceBuffer& palette,
                                                     const std::string& suffix) {
  if (variant.storage != PaletteStorage::kImage) return nullptr;
  VkBufferViewCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO};
  info.buffer = static_cast<VulkanBuffer&>(palette).buffer;
  info.format = VK_FORMAT_R32G32B32A32_SFLOAT;
  info.offset = 0;
  info.range = VK_WHOLE_SIZE;
  VkBufferView view = VK_NULL_HANDLE;
  Check(c_->fn.vkCreateBufferView(c_->device, &info, nullptr, &view), "launch",
        "uniform texel buffer view (R32G32B32A32_SFLOAT, " + std::to_string(palette.bytes() / 16) +
            " texels) over the palette" + suffix);
  return std::make_unique<VulkanView>(*c_, view);
}

// Descriptor set 0: the buffers and the palette in argument order.
std::unique_ptr<DeviceObject> VulkanApi::Bind(const PlannedLaunch& launch, std::span<const ArgumentBinding> arguments,
                                              const SetOptions&, std::size_t&) {
  const auto& plan = static_cast<const VulkanPlanned&>(launch);
  const Pipeline& p = *plan.pipeline;
  auto bound = std::make_unique<VulkanBound>(*c_);
  bound->plan = &plan;
  // Room for the set and a few redirections of out_positions (the Skinner's caller buffers).
  constexpr std::uint32_t kSets = 8;
  const VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 8 * kSets},
                                        {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, kSets},
                                        {VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, kSets}};
  VkDescriptorPoolCreateInfo pool{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pool.maxSets = kSets;
  pool.poolSizeCount = 3;
  pool.pPoolSizes = sizes;
  Check(c_->fn.vkCreateDescriptorPool(c_->device, &pool, nullptr, &bound->pool), "launch",
        "vkCreateDescriptorPool for " + plan.spec.where);
  VkDescriptorSetAllocateInfo allocate{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  allocate.descriptorPool = bound->pool;
  allocate.descriptorSetCount = 1;
  allocate.pSetLayouts = &p.set_layout;
  Check(c_->fn.vkAllocateDescriptorSets(c_->device, &allocate, &bound->set), "launch",
        "vkAllocateDescriptorSets for " + plan.spec.where);
  std::size_t count = 0;
  for (const ArgumentBinding& a : arguments) count += a.role == ArgumentRole::kScalar ? 0 : 1;
  if (count != p.types.size()) Fail("launch", plan.spec.where + ": argument count differs from the pipeline's bindings");
  bound->buffers.reserve(count);
  bound->views.reserve(count);
  std::uint32_t binding = 0;
  for (const ArgumentBinding& a : arguments) {
    if (a.role == ArgumentRole::kScalar) continue;
    const auto* buffer = static_cast<const VulkanBuffer*>(a.buffer);
    if (a.role == ArgumentRole::kPalette) bound->palette = buffer;
    if (a.role == ArgumentRole::kInput) bound->inputs.push_back(buffer);
    VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    w.dstSet = bound->set;
    w.dstBinding = binding;
    w.descriptorCount = 1;
    w.descriptorType = p.types[binding];
    if (w.descriptorType == VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER) {
      bound->views.push_back(static_cast<const VulkanView*>(a.view)->view);
      w.pTexelBufferView = &bound->views.back();
    } else {
      if (w.descriptorType == VK_DESCRIPTOR_TYPE_STORAGE_BUFFER)
        CheckStorageRange(buffer->bytes(), plan.spec.where + ": buffer '" + a.argument->name + "'");
      bound->buffers.push_back({buffer->buffer, 0, VK_WHOLE_SIZE});
      w.pBufferInfo = &bound->buffers.back();
    }
    if (a.argument->name == "out_positions") bound->out_positions_binding = static_cast<int>(binding);
    bound->writes.push_back(w);
    ++binding;
  }
  c_->fn.vkUpdateDescriptorSets(c_->device, static_cast<std::uint32_t>(bound->writes.size()), bound->writes.data(), 0,
                                nullptr);
  return bound;
}

// A set like `bound`'s with out_positions at `out_positions`, made once per buffer.
VkDescriptorSet VulkanApi::Redirected(VulkanBound& bound, VkBuffer out_positions) {
  if (auto found = bound.redirected.find(out_positions); found != bound.redirected.end()) return found->second;
  if (bound.out_positions_binding < 0) Fail("launch", bound.plan->spec.where + ": no out_positions to redirect");
  VkDescriptorSetAllocateInfo allocate{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  allocate.descriptorPool = bound.pool;
  allocate.descriptorSetCount = 1;
  allocate.pSetLayouts = &bound.plan->pipeline->set_layout;
  VkDescriptorSet set = VK_NULL_HANDLE;
  Check(c_->fn.vkAllocateDescriptorSets(c_->device, &allocate, &set), "launch",
        "a descriptor set for another output buffer (at most 7 per Skinner)");
  std::vector<VkWriteDescriptorSet> writes = bound.writes;
  const VkDescriptorBufferInfo out{out_positions, 0, VK_WHOLE_SIZE};
  for (VkWriteDescriptorSet& w : writes) {
    w.dstSet = set;
    if (static_cast<int>(w.dstBinding) == bound.out_positions_binding) w.pBufferInfo = &out;
  }
  c_->fn.vkUpdateDescriptorSets(c_->device, static_cast<std::uint32_t>(writes.size()), writes.data(), 0, nullptr);
  return bound.redirected.emplace(out_positions, set).first->second;
}

// ---------------------------------------------------------------- command buffers

// Command buffers and fences are recycled (a frame loop submits one of each
// per Skin): a retired submission's go to `spare_cbs_` and `spare_fences_`,
// and the next Begin and Submit take them back, reset (a fence is reset ahead,
// after the submission before: MakeAFenceReady).
VkCommandBuffer VulkanApi::Begin(bool live) {
  if (!live) unordered_since_frames_ = true;
  SubmitOpenFrames();
  Retire(false);
  VkCommandBuffer cb = VK_NULL_HANDLE;
  if (!spare_cbs_.empty()) {
    const auto taken = spares_in_turn_ ? spare_cbs_.begin() : spare_cbs_.end() - 1;
    cb = *taken;
    spare_cbs_.erase(taken);
  } else {
    VkCommandBufferAllocateInfo allocate{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    allocate.commandPool = pool_;
    allocate.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    allocate.commandBufferCount = 1;
    Check(c_->fn.vkAllocateCommandBuffers(c_->device, &allocate, &cb), "launch", "vkAllocateCommandBuffers");
  }
  VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  c_->fn.vkBeginCommandBuffer(cb, &begin);  // resets it (the pool's RESET_COMMAND_BUFFER_BIT)
  return cb;
}

void VulkanApi::Submit(VkCommandBuffer cb, bool wait, std::vector<std::unique_ptr<VulkanBuffer>> keep) {
  Submission s;
  s.cb = cb;
  s.keep = std::move(keep);
  const auto drop = [&] { c_->fn.vkFreeCommandBuffers(c_->device, pool_, 1, &cb); };
  const VkResult ended = c_->fn.vkEndCommandBuffer(cb);
  if (ended != VK_SUCCESS) {
    drop();
    Check(ended, "launch", "vkEndCommandBuffer");
  }
  if (ready_fence_ == VK_NULL_HANDLE) {
    const char* call = nullptr;
    const VkResult ready = MakeAFenceReady(&call);
    if (ready != VK_SUCCESS) {
      drop();
      Check(ready, "launch", call);
    }
  }
  s.fence = std::exchange(ready_fence_, VK_NULL_HANDLE);
  VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  submit.commandBufferCount = 1;
  submit.pCommandBuffers = &cb;
  const VkResult submitted = c_->fn.vkQueueSubmit(c_->queue, 1, &submit, s.fence);
  if (submitted != VK_SUCCESS) {
    c_->fn.vkDestroyFence(c_->device, s.fence, nullptr);
    drop();
    Check(submitted, "launch", "vkQueueSubmit");
  }
  s.number = ++submitted_;
  in_flight_.push_back(std::move(s));
  // NVIDIA's vkResetFences took 5-13 us of host time (H200, 2026-12-01): the
  // next submission's fence is made ready here, while the device runs this
  // one, rather than in the next Submit, where a frame that is waited for
  // would pay it before its work reaches the device. A failure here is left
  // to the next Submit, which tries again and reports it.
  const char* call = nullptr;
  (void)MakeAFenceReady(&call);
  if (wait) WaitAll();
}

// ready_fence_, unsignalled: a spare fence reset, else a new one. On failure
// ready_fence_ stays null, a spare that failed to reset is destroyed, and
// `call` names the call that failed.
VkResult VulkanApi::MakeAFenceReady(const char** call) {
  if (spare_fences_.empty()) {
    *call = "vkCreateFence";
    VkFenceCreateInfo info{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    VkFence fence = VK_NULL_HANDLE;
    const VkResult created = c_->fn.vkCreateFence(c_->device, &info, nullptr, &fence);
    if (created == VK_SUCCESS) ready_fence_ = fence;
    return created;
  }
  *call = "vkResetFences";
  const VkFence fence = spare_fences_.back();
  spare_fences_.pop_back();
  const VkResult reset = c_->fn.vkResetFences(c_->device, 1, &fence);
  if (reset == VK_SUCCESS)
    ready_fence_ = fence;
  else
    c_->fn.vkDestroyFence(c_->device, fence, nullptr);
  return reset;
}

VkCommandBuffer VulkanApi::OpenFrames() {
  if (open_frames_ == VK_NULL_HANDLE) open_frames_ = Begin(true);
  return open_frames_;
}

void VulkanApi::SubmitOpenFrames() {
  if (open_frames_ == VK_NULL_HANDLE) return;
  const VkCommandBuffer cb = open_frames_;
  open_frames_ = VK_NULL_HANDLE;
  open_frame_count_ = 0;
  BarrierAfterFrames(cb, false);
  Submit(cb, false);
}

// Polls the fence for up to kDeviceWaitPoll, then sleeps on it: NVIDIA's
// driver wakes a thread sleeping in vkWaitForFences long after the fence
// signals (H200, 2026-12-01: a crowd's Skin + Finish took 65-67 us sleeping,
// 39 polling, where its Skin alone took 25). A CPU device (lavapipe) runs
// its work on the host's cores, which a polling thread would take from it.
VkResult VulkanApi::WaitForFence(VkFence fence) const {
  VkResult r = VK_NOT_READY;
  if (c_->info.type != "cpu" &&
      PollFor(kDeviceWaitPoll, [&] { return (r = c_->fn.vkGetFenceStatus(c_->device, fence)) != VK_NOT_READY; }))
    return r;
  return c_->fn.vkWaitForFences(c_->device, 1, &fence, VK_TRUE, UINT64_MAX);
}

// Frees what completed (or, with `wait_all`, waits for everything first),
// oldest first, stopping at the first submission still running: a frame
// loop keeps a few in flight, and polling every one of them per Begin would
// cost in proportion to the queue's depth. Their command buffers and fences
// are kept for reuse (at most kSpares; the rest are freed).
void VulkanApi::Retire(bool wait_all) {
  VkResult failure = VK_SUCCESS;
  std::size_t retired = 0;
  for (; retired < in_flight_.size(); ++retired) {
    Submission& s = in_flight_[retired];
    const VkResult r = wait_all ? WaitForFence(s.fence) : c_->fn.vkGetFenceStatus(c_->device, s.fence);
    if (r == VK_NOT_READY || r == VK_TIMEOUT) break;
    if (r != VK_SUCCESS) failure = r;
    if (r == VK_SUCCESS && spare_fences_.size() < kSpares) {
      spare_cbs_.push_back(s.cb);
      spare_fences_.push_back(s.fence);
    } else {
      c_->fn.vkDestroyFence(c_->device, s.fence, nullptr);
      c_->fn.vkFreeCommandBuffers(c_->device, pool_, 1, &s.cb);
    }
  }
  in_flight_.erase(in_flight_.begin(), in_flight_.begin() + static_cast<std::ptrdiff_t>(retired));
  Check(failure, "launch", "waiting for the queue");
}

void VulkanApi::Barrier(VkCommandBuffer cb, VkPipelineStageFlags from, VkAccessFlags from_access,
                        VkPipelineStageFlags to, VkAccessFlags to_access) const {
  VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  barrier.srcAccessMask = from_access;
  barrier.dstAccessMask = to_access;
  c_->fn.vkCmdPipelineBarrier(cb, from, to, 0, 1, &barrier, 0, nullptr, 0, nullptr);
}

void VulkanApi::RecordLaunch(VkCommandBuffer cb, const VulkanBound& bound, VkDescriptorSet set, VkQueryPool pool,
                             int query, const FrameRun* run) const {
  const VulkanPlanned& plan = *bound.plan;
  const Pipeline& p = *plan.pipeline;
  c_->fn.vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_COMPUTE, p.pipeline);
  c_->fn.vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_COMPUTE, p.layout, 0, 1, &set, 0, nullptr);
  std::array<std::uint32_t, kPushConstantBytes / 4> push{};
  static_assert(sizeof push == sizeof plan.push);
  std::memcpy(push.data(), plan.push, sizeof push);
  // The palette kernel's scalars (delta and fresh): word k the k-th scalar
  // argument. A skin kernel's: n, first and vertex_count planned, the rest
  // (a fused kernel's elapsed) from the run, at their PushConstantOffset.
  std::size_t k = 0;
  for (const KernelArgument& a : plan.spec.source.arguments) {
    if (a.kind != ArgumentKind::kScalar || k >= push.size()) continue;
    if (!plan.spec.feeds_frame && (a.name == "n" || a.name == "first" || a.name == "vertex_count")) continue;
    if (!run) Fail("launch", plan.spec.where + ": no value for the scalar '" + a.name + "'");
    const std::size_t word = plan.spec.feeds_frame ? k++ : PushConstantOffset(a.name) / 4;
    push[word] = ScalarOf(*run, a.name, "Vulkan");
  }
  c_->fn.vkCmdPushConstants(cb, p.layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof push, push.data());
  if (query >= 0)
    c_->fn.vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, pool, static_cast<std::uint32_t>(query));
  c_->fn.vkCmdDispatch(cb, plan.groups_x, plan.groups_y, 1);
  if (query >= 0)
    c_->fn.vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, pool, static_cast<std::uint32_t>(query + 1));
}

QueryPool VulkanApi::NewQueryPool(std::uint32_t count) {
  if (count == 0) return QueryPool(*c_, VK_NULL_HANDLE);
  if (c_->info.timestamp_valid_bits == 0)
    Fail("launch", "the compute queue family of " + c_->info.name + " has no timestamps (timestampValidBits 0)");
  VkQueryPoolCreateInfo info{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
  info.queryType = VK_QUERY_TYPE_TIMESTAMP;
  info.queryCount = count;
  VkQueryPool pool = VK_NULL_HANDLE;
  Check(c_->fn.vkCreateQueryPool(c_->device, &info, nullptr, &pool), "launch", "vkCreateQueryPool");
  return QueryPool(*c_, pool);
}

std::vector<std::uint64_t> VulkanApi::QueryResults(VkQueryPool pool, std::uint32_t count) {
  std::vector<std::uint64_t> ticks(count);
  const VkResult r = c_->fn.vkGetQueryPoolResults(c_->device, pool, 0, count, count * sizeof(std::uint64_t),
                                                  ticks.data(), sizeof(std::uint64_t),
                                                  VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT);
  Check(r, "launch", "vkGetQueryPoolResults");
  return ticks;
}

double VulkanApi::TicksToMs(std::uint64_t start, std::uint64_t end) const {
  const unsigned bits = c_->info.timestamp_valid_bits;
  const std::uint64_t mask = bits >= 64 ? ~0ull : (1ull << bits) - 1;
  const std::uint64_t ticks = ((end & mask) - (start & mask)) & mask;
  return static_cast<double>(ticks) * c_->info.timestamp_period_ns / 1e6;
}

// Records frames [begin, end) of `run` into `cb`: a barrier before a frame
// whose set an earlier frame of the same command buffer used (`used`: the
// sets since the last barrier), each launch between timestamps `query`,
// `query` + 1 (advanced by 2) when `per_launch`. Timed frames (kTime) get no
// barrier between them: they only read inputs and palettes that nothing in
// the burst writes, and their outputs are never read, so consecutive frames
// may overlap as GL's dispatches and CUDA's and OpenCL's two lanes do
// (FrameRun in runtime/device_api.h). With one input set (a footprint over
// twice the last-level cache, 6400k-b4 on the H100) a barrier before every
// frame drained the GPU each time: 0.21 ms against GL's 0.099 ms for the
// same kernel (an H100, November 2026).
void VulkanApi::RecordFrames(VkCommandBuffer cb, const FrameRun& run, std::size_t begin, std::size_t end,
                             std::set<const void*>& used, VkQueryPool pool, int* query) {
  constexpr VkAccessFlags kShaderAccess = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT;
  for (std::size_t f = begin; f < end; ++f) {
    const auto& frame = run.frames[f];
    if (!used.insert(frame.data()).second && run.use != FrameUse::kTime) {
      Barrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, kShaderAccess, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
              kShaderAccess);
      used = {frame.data()};
    }
    for (const std::unique_ptr<DeviceObject>& object : frame) {
      auto& bound = static_cast<VulkanBound&>(*object);
      const VkDescriptorSet set =
          run.out_positions ? Redirected(bound, reinterpret_cast<VkBuffer>(run.out_positions)) : bound.set;
      RecordLaunch(cb, bound, set, pool, query ? *query : -1, &run);
      if (query) *query += 2;
      if (bound.plan->spec.feeds_frame)  // the palette kernel: its storage writes, read by the frame's launches however they read them
        Barrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_UNIFORM_READ_BIT);
    }
  }
}

// Starts a command buffer of frames: after uploads and palette copies
// (earlier submissions) and earlier frames.
void VulkanApi::BarrierBeforeFrames(VkCommandBuffer cb) const {
  Barrier(cb, VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
          VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
          VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
}

// Ends one: the outputs for read-backs (copies, mapped memory) and, in a
// caller's command buffer, for any later command.
void VulkanApi::BarrierAfterFrames(VkCommandBuffer cb, bool for_caller) const {
  Barrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
          for_caller ? VK_PIPELINE_STAGE_ALL_COMMANDS_BIT : VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_HOST_BIT,
          for_caller ? VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT
                     : VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_HOST_READ_BIT);
}

// kLive: the set's launches, submitted without waiting, or recorded into the
// caller's command buffer. kVerify: one command buffer, each launch between
// two timestamps, then wait. kTime: the untimed frames in one command
// buffer, then one command buffer per burst: a timestamp once everything
// before it is done, the burst's launches back to back (a barrier only
// where a set is used again), a timestamp when they are done; a last,
// shorter group runs untimed; then wait and read the times.
std::vector<std::vector<double>> VulkanApi::RunFrames(const FrameRun& run) {
  const std::size_t frames = run.frames.size();
  std::set<const void*> used;
  if (run.use == FrameUse::kLive) {
    const bool for_caller = record_into_ != VK_NULL_HANDLE;
    const bool batched = !for_caller && c_->owns_device;
    if (for_caller) SubmitOpenFrames();  // earlier frames reach the queue before the caller's command buffer
    const VkCommandBuffer cb = for_caller ? record_into_ : batched ? OpenFrames() : Begin(true);
    RecordPendingUploads(cb, run);
    // A prologue (the palette kernel) after nothing but live frames starts
    // beside the frame before it: what it reads and writes (its palette slot,
    // the instances' states) the frames before it left ordered by their own
    // barrier after their prologue, as long as the ring has another slot for
    // the frame before to read. After any other work it waits for everything.
    const bool beside = !run.prologue.empty() && !run.prologue_after_frames && !unordered_since_frames_;
    if (!beside) {
      BarrierBeforeFrames(cb);
      unordered_since_frames_ = false;
    }
    if (!run.prologue.empty()) {  // its storage writes, read by the frames as storage or uniform buffers or texels
      for (const std::unique_ptr<DeviceObject>& launch : run.prologue) {
        const auto& bound = static_cast<const VulkanBound&>(*launch);
        RecordLaunch(cb, bound, bound.set, VK_NULL_HANDLE, -1, &run);
      }
      // Also the frames' writes after the earlier frames' (BarrierBeforeFrames
      // where the prologue went beside them) and the next prologue's after this one's.
      Barrier(cb, VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
              VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
              VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_UNIFORM_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
    }
    RecordFrames(cb, run, 0, frames, used, VK_NULL_HANDLE, nullptr);
    if (batched) {
      Retire(false);
      if (++open_frame_count_ >= kFramesPerSubmission || in_flight_.empty()) SubmitOpenFrames();
      return {};
    }
    BarrierAfterFrames(cb, for_caller);
    if (for_caller) {
      recorded_for_caller_ = true;
    } else {
      Submit(cb, false);
    }
    return {};
  }
  if (run.use == FrameUse::kVerify) {
    std::uint32_t launches = 0;
    for (const auto& frame : run.frames) launches += static_cast<std::uint32_t>(frame.size());
    const QueryPool pool = NewQueryPool(2 * launches);
    const VkCommandBuffer cb = Begin();
    if (pool.get()) c_->fn.vkCmdResetQueryPool(cb, pool.get(), 0, 2 * launches);
    RecordPendingUploads(cb, run);  // an animated set's instances, staged since its last frame
    BarrierBeforeFrames(cb);
    int query = 0;
    RecordFrames(cb, run, 0, frames, used, pool.get(), &query);
    BarrierAfterFrames(cb, false);
    Submit(cb, true);
    if (!pool.get()) return {{}};
    const std::vector<std::uint64_t> ticks = QueryResults(pool.get(), 2 * launches);
    std::vector<double> ms;
    for (std::size_t q = 0; q < ticks.size(); q += 2) ms.push_back(TicksToMs(ticks[q], ticks[q + 1]));
    return {ms};
  }
  if (run.use == FrameUse::kCold) return RunCold(run);
  const std::size_t untimed = std::min<std::size_t>(frames, static_cast<std::size_t>(std::max(run.untimed, 0)));
  const std::size_t burst = static_cast<std::size_t>(std::max(run.burst, 1));
  const std::size_t bursts = run.TimedBursts();
  const auto submit_untimed = [&](std::size_t begin, std::size_t end) {
    if (begin >= end) return;
    const VkCommandBuffer cb = Begin();
    RecordPendingUploads(cb, run);
    BarrierBeforeFrames(cb);
    used.clear();
    RecordFrames(cb, run, begin, end, used, VK_NULL_HANDLE, nullptr);
    BarrierAfterFrames(cb, false);
    Submit(cb, false);
  };
  submit_untimed(0, untimed);
  const QueryPool pool = NewQueryPool(static_cast<std::uint32_t>(2 * bursts));
  for (std::size_t b = 0; b < bursts; ++b) {
    const VkCommandBuffer cb = Begin();
    const auto first = static_cast<std::uint32_t>(2 * b);
    c_->fn.vkCmdResetQueryPool(cb, pool.get(), first, 2);
    RecordPendingUploads(cb, run);  // before the burst's first stamp
    BarrierBeforeFrames(cb);
    c_->fn.vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, pool.get(), first);
    used.clear();
    RecordFrames(cb, run, untimed + b * burst, untimed + (b + 1) * burst, used, VK_NULL_HANDLE, nullptr);
    c_->fn.vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, pool.get(), first + 1);
    BarrierAfterFrames(cb, false);
    Submit(cb, false);
  }
  submit_untimed(untimed + bursts * burst, frames);
  WaitAll();
  if (!pool.get()) return {};
  const std::vector<std::uint64_t> ticks = QueryResults(pool.get(), static_cast<std::uint32_t>(2 * bursts));
  std::vector<std::vector<double>> ms;
  for (std::size_t b = 0; b < bursts; ++b) ms.push_back({TicksToMs(ticks[2 * b], ticks[2 * b + 1])});
  return ms;
}

// The kernel time (FrameUse::kCold, device_api.h): a launch's time runs
// from the end of the command before it (the flush, or the frame's launch
// before) to its own end. One command buffer a frame, submitted and waited
// for before the next is recorded, as every API's cold frames are
// (runtime/device_api.h: sixteen frames a submission, NVIDIA's last four of
// every sixteen took 5.1 us where the others took 5.9): the flush's
// dispatches and a timestamp, then per launch a compute-to-compute barrier,
// the dispatch and a timestamp, then a barrier that hands the outputs to the
// transfers and the host (the next frame's command buffer starts with a
// barrier after everything submitted before). Untimed frames run the same
// way without timestamps. One query pool holds every timed frame's 1 +
// launches stamps; it is reset in the first command buffer and read after
// the last.
//
// The stamps (vkCmdWriteTimestamp): "the first synchronization scope
// includes all commands that occur earlier in submission order. The
// synchronization scope is limited to operations on the pipeline stage
// specified by pipelineStage", and an implementation "may write the
// timestamp at any stage that is logically later" (never earlier). Every
// stamp names VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, the end of every stage:
// it is written once every earlier command (the flush, the launches before
// and this one) has completed, the end of a command as the other APIs stamp
// it (and as Run's and Time's stamps on the same device). TOP_OF_PIPE would
// be written as soon as the earlier commands had started: the flush's time
// would land in the first launch's. A stamp waits for earlier work but holds
// no later command back ("the second synchronization scope includes only
// the timestamp write operation"), so the barrier before each dispatch is
// what keeps it from starting beside the flush or the launch before. Ticks
// become ms through timestampValidBits and timestampPeriod (TicksToMs).
std::vector<std::vector<double>> VulkanApi::RunCold(const FrameRun& run) {
  constexpr VkAccessFlags kShaderAccess = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT;
  const std::size_t frames = run.frames.size();
  const std::size_t untimed = std::min<std::size_t>(frames, static_cast<std::size_t>(std::max(run.untimed, 0)));
  std::uint32_t stamps = 0;
  for (std::size_t f = untimed; f < frames; ++f) stamps += static_cast<std::uint32_t>(1 + run.frames[f].size());
  const QueryPool pool = NewQueryPool(stamps);
  AllocateColdCommandBuffers();
  spares_in_turn_ = true;
  const struct InTurn {
    bool& on;
    ~InTurn() { on = false; }
  } in_turn{spares_in_turn_};
  cold_order_.clear();
  const auto serialise = [&](VkCommandBuffer cb) {
    Barrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, kShaderAccess, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, kShaderAccess);
  };
  std::uint32_t query = 0;
  const auto stamp = [&](VkCommandBuffer cb) {
    c_->fn.vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, pool.get(), query++);
  };
  for (std::size_t f = 0; f < frames; ++f) {
    const VkCommandBuffer cb = Begin();
    cold_order_.push_back(cb);
    if (f == 0 && pool.get()) c_->fn.vkCmdResetQueryPool(cb, pool.get(), 0, stamps);
    RecordPendingUploads(cb, run);  // an animated set's instances, staged since its last frame
    BarrierBeforeFrames(cb);  // after the uploads and everything submitted before
    const bool timed = f >= untimed;
    for (const std::unique_ptr<DeviceObject>& object : run.flush) {
      const auto& bound = static_cast<const VulkanBound&>(*object);
      RecordLaunch(cb, bound, bound.set, VK_NULL_HANDLE, -1);
    }
    if (timed) stamp(cb);
    for (const std::unique_ptr<DeviceObject>& object : run.frames[f]) {
      const auto& bound = static_cast<const VulkanBound&>(*object);
      serialise(cb);
      RecordLaunch(cb, bound, bound.set, VK_NULL_HANDLE, -1, &run);
      if (timed) stamp(cb);
      if (bound.plan->spec.feeds_frame)  // the palette it wrote, read as uniforms or texels too
        Barrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_UNIFORM_READ_BIT);
    }
    BarrierAfterFrames(cb, false);
    Submit(cb, true);
  }
  if (!pool.get()) return std::vector<std::vector<double>>(frames - untimed);
  const std::vector<std::uint64_t> ticks = QueryResults(pool.get(), stamps);
  std::vector<std::vector<double>> ms;
  query = 0;
  for (std::size_t f = untimed; f < frames; ++f) {
    std::vector<double>& launches = ms.emplace_back();
    for (std::size_t l = 0; l < run.frames[f].size(); ++l, ++query)
      launches.push_back(TicksToMs(ticks[query], ticks[query + 1]));
    ++query;  // past the frame's last stamp
  }
  return ms;
}

void VulkanApi::AllocateColdCommandBuffers() {
  SubmitOpenFrames();
  Retire(false);
  if (spare_cbs_.size() >= kColdCommandBuffers) return;
  std::vector<VkCommandBuffer> more(kColdCommandBuffers - spare_cbs_.size());
  VkCommandBufferAllocateInfo allocate{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  allocate.commandPool = pool_;
  allocate.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  allocate.commandBufferCount = static_cast<std::uint32_t>(more.size());
  Check(c_->fn.vkAllocateCommandBuffers(c_->device, &allocate, more.data()), "launch", "vkAllocateCommandBuffers");
  spare_cbs_.insert(spare_cbs_.end(), more.begin(), more.end());
}

// The palette (the driver's ring fence says no queued frame reads it, nor
// its staging): host-visible memory is its own staging, written in place;
// other memory has a staging buffer whose copy the next frame's command
// buffer records before its dispatches (RecordPendingUploads): no
// submission of its own.
std::span<std::uint8_t> VulkanApi::Staging(DeviceBuffer& buffer, const std::string& key, bool) {
  auto& b = static_cast<VulkanBuffer&>(buffer);
  if (b.mapped) return {static_cast<std::uint8_t*>(b.mapped), b.bytes()};
  if (!b.staging) b.staging = std::make_unique<VulkanBuffer>(*c_, b.bytes(), kStagingUsage, true, "palette staging of " + key);
  return {static_cast<std::uint8_t*>(b.staging->mapped), b.bytes()};
}

void VulkanApi::Upload(DeviceBuffer& buffer, std::size_t size, const std::string&) {
  auto& b = static_cast<VulkanBuffer&>(buffer);
  if (b.mapped) return;
  auto& pending = c_->pending_uploads;
  const auto found = std::find_if(pending.begin(), pending.end(), [&](const auto& p) { return p.first == &b; });
  if (found == pending.end()) {
    pending.emplace_back(&b, size);
  } else {
    found->second = size;
  }
}

// The copies Write left for the palettes `run` reads (another Skinner's stay
// for its own next frame), then a barrier to the dispatches that read them.
void VulkanApi::RecordPendingUploads(VkCommandBuffer cb, const FrameRun& run) {
  auto& pending = c_->pending_uploads;
  const auto read_by = [](std::span<const std::unique_ptr<DeviceObject>> launches, const VulkanBuffer* buffer) {
    for (const std::unique_ptr<DeviceObject>& launch : launches) {
      const auto& bound = static_cast<const VulkanBound&>(*launch);
      if (bound.palette == buffer || std::find(bound.inputs.begin(), bound.inputs.end(), buffer) != bound.inputs.end())
        return true;
    }
    return false;
  };
  const auto read_by_run = [&](const VulkanBuffer* buffer) {
    if (read_by(run.prologue, buffer)) return true;
    for (const auto& frame : run.frames)
      if (read_by(frame, buffer)) return true;
    return false;
  };
  bool recorded = false;
  for (auto p = pending.begin(); p != pending.end();) {
    if (!read_by_run(p->first)) {
      ++p;
      continue;
    }
    const VkBufferCopy region{0, 0, p->second};
    c_->fn.vkCmdCopyBuffer(cb, p->first->staging->buffer, p->first->buffer, 1, &region);
    p = pending.erase(p);
    recorded = true;
  }
  if (recorded)
    Barrier(cb, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
            VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_UNIFORM_READ_BIT);
}

void VulkanApi::Read(const DeviceBuffer& buffer, std::span<std::uint8_t> out, const std::string& what, bool wait) {
  const auto& b = static_cast<const VulkanBuffer&>(buffer);
  if (wait) Finish();
  if (b.mapped) {
    std::memcpy(out.data(), b.mapped, out.size());
    return;
  }
  auto staging = std::make_unique<VulkanBuffer>(*c_, out.size(), kStagingUsage, true, "read-back of " + what);
  const VkCommandBuffer cb = Begin();
  Barrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
          VK_ACCESS_TRANSFER_READ_BIT);
  const VkBufferCopy region{0, 0, out.size()};
  c_->fn.vkCmdCopyBuffer(cb, b.buffer, staging->buffer, 1, &region);
  Barrier(cb, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
          VK_ACCESS_HOST_READ_BIT);
  Submit(cb, true);
  std::memcpy(out.data(), staging->mapped, out.size());
}

// Host-visible outputs are read where they are once the queue is done;
// others are copied into the output's host-visible read-back buffer (kept)
// after the frames already submitted, and read there.
std::span<const std::uint8_t> VulkanApi::ReadPinned(const DeviceBuffer& buffer, std::size_t bytes,
                                                    const std::string& what) {
  const auto& b = static_cast<const VulkanBuffer&>(buffer);
  if (b.mapped || recorded_for_caller_) Finish();
  if (b.mapped) return {static_cast<const std::uint8_t*>(b.mapped), bytes};
  if (!b.readback) b.readback = std::make_unique<VulkanBuffer>(*c_, b.bytes(), kStagingUsage, true, "read-back of " + what);
  const VkCommandBuffer cb = Begin();
  Barrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
          VK_ACCESS_TRANSFER_READ_BIT);
  const VkBufferCopy region{0, 0, bytes};
  c_->fn.vkCmdCopyBuffer(cb, b.buffer, b.readback->buffer, 1, &region);
  Barrier(cb, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
          VK_ACCESS_HOST_READ_BIT);
  Submit(cb, true);
  return {static_cast<const std::uint8_t*>(b.readback->mapped), bytes};
}

void VulkanApi::Mark(std::unique_ptr<DeviceObject>& marker, const std::string&) {
  if (!marker) marker = std::make_unique<VulkanMarker>();
  auto& m = static_cast<VulkanMarker&>(*marker);
  m.queue_idle = recorded_for_caller_;
  m.number = submitted_ + (open_frames_ != VK_NULL_HANDLE ? 1 : 0);  // the open frames' number once submitted
}

void VulkanApi::Wait(DeviceObject& marker, const std::string& what) {
  const auto& m = static_cast<const VulkanMarker&>(marker);
  if (m.queue_idle) return Finish();
  // The open frames go to the queue before the host blocks: the awaited
  // frame may be among them, and otherwise the device runs them while the
  // host waits, so a frame loop that waits each frame for the one a ring
  // back never leaves the device idle (nor waits for the frames after it).
  bool blocks = m.number > submitted_;
  for (const Submission& s : in_flight_)
    if (!blocks && s.number <= m.number && c_->fn.vkGetFenceStatus(c_->device, s.fence) == VK_NOT_READY) blocks = true;
  if (blocks) SubmitOpenFrames();
  for (const Submission& s : in_flight_)
    if (s.number <= m.number)
      Check(WaitForFence(s.fence), "launch", "waiting for " + what);
  Retire(false);
}

// Everything skintune submitted; and, when launches went into a caller's
// command buffer, the queue they were submitted on.
void VulkanApi::Finish() {
  WaitAll();
  if (recorded_for_caller_) {
    Check(c_->fn.vkQueueWaitIdle(c_->queue), "launch", "vkQueueWaitIdle");
    recorded_for_caller_ = false;
  }
}

}  // namespace vk

// ---------------------------------------------------------------- VulkanRunner

namespace {

std::unique_ptr<vk::Context> OwnContext(int device_index, bool validation) {
  auto c = std::make_unique<vk::Context>();
  c->instance = std::make_shared<vk::VulkanInstance>(validation);
  const std::vector<VkPhysicalDevice> devices = c->instance->PhysicalDevices();
  if (device_index < 0 || static_cast<std::size_t>(device_index) >= devices.size())
    vk::Fail("setup", "no Vulkan device " + std::to_string(device_index) + " (" + std::to_string(devices.size()) +
                          " found)");
  c->physical = devices[static_cast<std::size_t>(device_index)];
  c->info = vk::QueryDevice(*c->instance, c->physical);
  if (c->info.compute_family == UINT32_MAX) vk::Fail("setup", c->info.name + " has no compute queue");
  c->family = c->info.compute_family;
  const float priority = 1.0f;
  VkDeviceQueueCreateInfo queue{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  queue.queueFamilyIndex = c->family;
  queue.queueCount = 1;
  queue.pQueuePriorities = &priority;
  VkDeviceCreateInfo info{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  info.queueCreateInfoCount = 1;
  info.pQueueCreateInfos = &queue;
  vk::Check(c->instance->fn().vkCreateDevice(c->physical, &info, nullptr, &c->device), "setup",
            "vkCreateDevice on " + c->info.name);
  c->fn = vk::DeviceFunctionsOf(c->instance->fn(), c->device);
  c->fn.vkGetDeviceQueue(c->device, c->family, 0, &c->queue);
  c->instance->fn().vkGetPhysicalDeviceMemoryProperties(c->physical, &c->memory);
  return c;
}

std::unique_ptr<vk::Context> AdoptedContext(const VulkanAdopted& a) {
  if (!a.instance || !a.physical_device || !a.device || !a.queue)
    vk::Fail("setup", "Device::FromVulkan needs a VkInstance, VkPhysicalDevice, VkDevice and VkQueue (one is null)");
  auto c = std::make_unique<vk::Context>();
  c->instance = std::make_shared<vk::VulkanInstance>(a.instance, a.get_instance_proc_addr);
  c->physical = a.physical_device;
  c->info = vk::QueryDevice(*c->instance, c->physical);
  std::uint32_t count = 0;
  c->instance->fn().vkGetPhysicalDeviceQueueFamilyProperties(c->physical, &count, nullptr);
  std::vector<VkQueueFamilyProperties> families(count);
  c->instance->fn().vkGetPhysicalDeviceQueueFamilyProperties(c->physical, &count, families.data());
  if (a.queue_family >= count || !(families[a.queue_family].queueFlags & VK_QUEUE_COMPUTE_BIT))
    vk::Fail("setup", "queue family " + std::to_string(a.queue_family) + " of " + c->info.name +
                          " has no compute (or does not exist)");
  c->info.timestamp_valid_bits = families[a.queue_family].timestampValidBits;
  c->device = a.device;
  c->owns_device = false;
  c->queue = a.queue;
  c->family = a.queue_family;
  c->fn = vk::DeviceFunctionsOf(c->instance->fn(), c->device);
  c->instance->fn().vkGetPhysicalDeviceMemoryProperties(c->physical, &c->memory);
  return c;
}

}  // namespace

VulkanRunner::VulkanRunner(int device_index, bool validation)
    : Runner(std::make_unique<vk::VulkanApi>(OwnContext(device_index, validation))) {}
VulkanRunner::VulkanRunner(const VulkanAdopted& adopted)
    : Runner(std::make_unique<vk::VulkanApi>(AdoptedContext(adopted))) {}

vk::VulkanApi& VulkanRunner::vk_api() const { return static_cast<vk::VulkanApi&>(api()); }
const vk::VulkanDeviceInfo& VulkanRunner::info() const { return vk_api().context().info; }
std::vector<std::string> VulkanRunner::validation_messages() const {
  return vk_api().context().instance->messages();
}
void VulkanRunner::RecordInto(VkCommandBuffer command_buffer) { vk_api().RecordInto(command_buffer); }
std::uint64_t VulkanRunner::submissions() const { return vk_api().submissions(); }

std::vector<std::uintptr_t> VulkanRunner::cold_command_buffers() const {
  std::vector<std::uintptr_t> handles;
  for (VkCommandBuffer cb : vk_api().cold_command_buffers()) handles.push_back(reinterpret_cast<std::uintptr_t>(cb));
  return handles;
}

}  // namespace skintune::internal
