// The public API on Vulkan (lavapipe here): a Device skintune opens, and the
// caller's VkInstance / VkDevice / queue adopted (Device::FromVulkan): the
// Skinner against the gold through Skin() on the caller's queue, and through
// SkinIntoVulkan recorded into the caller's command buffer writing the
// caller's VkBuffer; skintune creates no second device and destroys neither
// the caller's device nor its instance (counted through the
// vkGetInstanceProcAddr the caller hands over), and the caller's validation
// layer reports nothing. Each test skips, with the reason, when no Vulkan
// device is there.
#include <gtest/gtest.h>
#include <vulkan/vulkan.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "model/gltf_import.h"
#include "reference/skinning.h"
#include "runtime/program_cache.h"
#include "skintune/skintune.h"
#include "tests/runtime/api_test_support.h"

namespace skintune::internal {
namespace {

using testing::ExpectSkinsLikeTheGold;
using testing::View;

const SkinnedAsset& Cesium() {
  static const SkinnedAsset asset = ImportGltf(std::string(SKINTUNE_TEST_DATA_DIR) + "/CesiumMan.gltf").asset;
  return asset;
}

// ---------------------------------------------------------------- counting loader

struct Counts {
  int create_instance = 0, destroy_instance = 0, create_device = 0, destroy_device = 0, queue_submit = 0;
  // Fence calls in order: 'p' a poll (vkGetFenceStatus), 'w' a wait (vkWaitForFences).
  std::string fence_calls;
  // Submissions and fence resets in order: 's' vkQueueSubmit, 'r' vkResetFences.
  std::string submit_calls;
  // Recorded commands in order: 'd' a dispatch, 'B' a barrier that orders
  // compute after compute, 'b' any other barrier.
  std::string commands;
} counts;

VKAPI_ATTR void VKAPI_CALL CountCmdDispatch(VkCommandBuffer cb, std::uint32_t x, std::uint32_t y, std::uint32_t z) {
  counts.commands += 'd';
  vkCmdDispatch(cb, x, y, z);
}
VKAPI_ATTR void VKAPI_CALL CountCmdPipelineBarrier(VkCommandBuffer cb, VkPipelineStageFlags from, VkPipelineStageFlags to,
                                                   VkDependencyFlags flags, std::uint32_t memory_count,
                                                   const VkMemoryBarrier* memory, std::uint32_t buffer_count,
                                                   const VkBufferMemoryBarrier* buffers, std::uint32_t image_count,
                                                   const VkImageMemoryBarrier* images) {
  constexpr VkPipelineStageFlags kCompute = VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_ALL_COMMANDS_BIT;
  counts.commands += (from & kCompute) && (to & kCompute) ? 'B' : 'b';
  vkCmdPipelineBarrier(cb, from, to, flags, memory_count, memory, buffer_count, buffers, image_count, images);
}

VKAPI_ATTR VkResult VKAPI_CALL CountQueueSubmit(VkQueue q, std::uint32_t n, const VkSubmitInfo* s, VkFence f) {
  ++counts.queue_submit;
  counts.submit_calls += 's';
  return vkQueueSubmit(q, n, s, f);
}
VKAPI_ATTR VkResult VKAPI_CALL CountResetFences(VkDevice d, std::uint32_t n, const VkFence* f) {
  counts.submit_calls += 'r';
  return vkResetFences(d, n, f);
}

VKAPI_ATTR VkResult VKAPI_CALL CountGetFenceStatus(VkDevice d, VkFence f) {
  counts.fence_calls += 'p';
  return vkGetFenceStatus(d, f);
}
VKAPI_ATTR VkResult VKAPI_CALL CountWaitForFences(VkDevice d, std::uint32_t n, const VkFence* f, VkBool32 all,
                                                  std::uint64_t timeout) {
  counts.fence_calls += 'w';
  return vkWaitForFences(d, n, f, all, timeout);
}

VKAPI_ATTR VkResult VKAPI_CALL CountCreateDevice(VkPhysicalDevice p, const VkDeviceCreateInfo* i,
                                                 const VkAllocationCallbacks* a, VkDevice* d) {
  ++counts.create_device;
  return vkCreateDevice(p, i, a, d);
}
VKAPI_ATTR void VKAPI_CALL CountDestroyDevice(VkDevice d, const VkAllocationCallbacks* a) {
  ++counts.destroy_device;
  vkDestroyDevice(d, a);
}
VKAPI_ATTR VkResult VKAPI_CALL CountCreateInstance(const VkInstanceCreateInfo* i, const VkAllocationCallbacks* a,
                                                   VkInstance* out) {
  ++counts.create_instance;
  return vkCreateInstance(i, a, out);
}
VKAPI_ATTR void VKAPI_CALL CountDestroyInstance(VkInstance i, const VkAllocationCallbacks* a) {
  ++counts.destroy_instance;
  vkDestroyInstance(i, a);
}
VKAPI_ATTR PFN_vkVoidFunction VKAPI_CALL CountGetDeviceProcAddr(VkDevice d, const char* name) {
  if (std::strcmp(name, "vkDestroyDevice") == 0) return reinterpret_cast<PFN_vkVoidFunction>(CountDestroyDevice);
  if (std::strcmp(name, "vkQueueSubmit") == 0) return reinterpret_cast<PFN_vkVoidFunction>(CountQueueSubmit);
  if (std::strcmp(name, "vkGetFenceStatus") == 0) return reinterpret_cast<PFN_vkVoidFunction>(CountGetFenceStatus);
  if (std::strcmp(name, "vkResetFences") == 0) return reinterpret_cast<PFN_vkVoidFunction>(CountResetFences);
  if (std::strcmp(name, "vkWaitForFences") == 0) return reinterpret_cast<PFN_vkVoidFunction>(CountWaitForFences);
  if (std::strcmp(name, "vkCmdDispatch") == 0) return reinterpret_cast<PFN_vkVoidFunction>(CountCmdDispatch);
  if (std::strcmp(name, "vkCmdPipelineBarrier") == 0) return reinterpret_cast<PFN_vkVoidFunction>(CountCmdPipelineBarrier);
  return vkGetDeviceProcAddr(d, name);
}
// What the test hands skintune as its vkGetInstanceProcAddr.
VKAPI_ATTR PFN_vkVoidFunction VKAPI_CALL CountGetInstanceProcAddr(VkInstance i, const char* name) {
  const std::string n = name;
  if (n == "vkCreateDevice") return reinterpret_cast<PFN_vkVoidFunction>(CountCreateDevice);
  if (n == "vkDestroyDevice") return reinterpret_cast<PFN_vkVoidFunction>(CountDestroyDevice);
  if (n == "vkCreateInstance") return reinterpret_cast<PFN_vkVoidFunction>(CountCreateInstance);
  if (n == "vkDestroyInstance") return reinterpret_cast<PFN_vkVoidFunction>(CountDestroyInstance);
  if (n == "vkGetDeviceProcAddr") return reinterpret_cast<PFN_vkVoidFunction>(CountGetDeviceProcAddr);
  return vkGetInstanceProcAddr(i, name);
}

// ---------------------------------------------------------------- the caller's Vulkan

std::vector<std::string> caller_messages;

VKAPI_ATTR VkBool32 VKAPI_CALL OnMessage(VkDebugUtilsMessageSeverityFlagBitsEXT, VkDebugUtilsMessageTypeFlagsEXT,
                                         const VkDebugUtilsMessengerCallbackDataEXT* data, void*) {
  caller_messages.push_back(data->pMessage ? data->pMessage : "?");
  return VK_FALSE;
}

// An engine's Vulkan: instance (validation layer and messenger), the first
// device with compute, one queue; and a host-visible buffer to skin into.
// `synchronization`: the layer also checks every command's hazards against
// the commands before it (synchronization validation).
class CallerVulkan {
 public:
  explicit CallerVulkan(bool synchronization = false) {
    VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    app.apiVersion = VK_API_VERSION_1_2;
    const char* layer = "VK_LAYER_KHRONOS_validation";
    const char* extension = VK_EXT_DEBUG_UTILS_EXTENSION_NAME;
    VkInstanceCreateInfo info{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    info.pApplicationInfo = &app;
    info.enabledLayerCount = 1;
    info.ppEnabledLayerNames = &layer;
    info.enabledExtensionCount = 1;
    info.ppEnabledExtensionNames = &extension;
    const VkValidationFeatureEnableEXT sync = VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT;
    VkValidationFeaturesEXT features{VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT};
    features.enabledValidationFeatureCount = 1;
    features.pEnabledValidationFeatures = &sync;
    if (synchronization) info.pNext = &features;
    if (vkCreateInstance(&info, nullptr, &instance) != VK_SUCCESS) {
      info.pNext = nullptr;
      // No validation layer (a GPU machine may have the driver only): the same test without it.
      info.enabledLayerCount = 0;
      info.enabledExtensionCount = 0;
      if (vkCreateInstance(&info, nullptr, &instance) != VK_SUCCESS) {
        why = "vkCreateInstance failed (no Vulkan driver?)";
        instance = VK_NULL_HANDLE;
        return;
      }
    }
    auto create_messenger = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance, "vkCreateDebugUtilsMessengerEXT"));
    VkDebugUtilsMessengerCreateInfoEXT m{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
    m.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    m.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                    VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
    m.pfnUserCallback = OnMessage;
    if (info.enabledLayerCount > 0 && create_messenger) create_messenger(instance, &m, nullptr, &messenger);
    std::uint32_t count = 0;
    vkEnumeratePhysicalDevices(instance, &count, nullptr);
    std::vector<VkPhysicalDevice> devices(count);
    vkEnumeratePhysicalDevices(instance, &count, devices.data());
    for (VkPhysicalDevice d : devices) {
      std::uint32_t families = 0;
      vkGetPhysicalDeviceQueueFamilyProperties(d, &families, nullptr);
      std::vector<VkQueueFamilyProperties> props(families);
      vkGetPhysicalDeviceQueueFamilyProperties(d, &families, props.data());
      for (std::uint32_t f = 0; f < families && !physical; ++f) {
        if (props[f].queueFlags & VK_QUEUE_COMPUTE_BIT) {
          physical = d;
          family = f;
        }
      }
      if (physical) break;
    }
    if (!physical) {
      why = "no Vulkan device with a compute queue";
      return;
    }
    const float priority = 1.0f;
    VkDeviceQueueCreateInfo queue_info{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    queue_info.queueFamilyIndex = family;
    queue_info.queueCount = 1;
    queue_info.pQueuePriorities = &priority;
    VkDeviceCreateInfo device_info{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    device_info.queueCreateInfoCount = 1;
    device_info.pQueueCreateInfos = &queue_info;
    if (vkCreateDevice(physical, &device_info, nullptr, &device) != VK_SUCCESS) {
      why = "vkCreateDevice failed";
      return;
    }
    vkGetDeviceQueue(device, family, 0, &queue);
    VkCommandPoolCreateInfo pool_info{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pool_info.queueFamilyIndex = family;
    vkCreateCommandPool(device, &pool_info, nullptr, &pool);
  }
  ~CallerVulkan() {
    if (device) {
      vkDeviceWaitIdle(device);
      if (buffer) vkDestroyBuffer(device, buffer, nullptr);
      if (memory) vkFreeMemory(device, memory, nullptr);
      if (pool) vkDestroyCommandPool(device, pool, nullptr);
      vkDestroyDevice(device, nullptr);
    }
    if (messenger) {
      reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
          vkGetInstanceProcAddr(instance, "vkDestroyDebugUtilsMessengerEXT"))(instance, messenger, nullptr);
    }
    if (instance) vkDestroyInstance(instance, nullptr);
  }
  bool ok() const { return device != VK_NULL_HANDLE; }

  // A host-visible, coherent storage buffer of `bytes`, mapped.
  void* NewBuffer(std::size_t bytes) {
    VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    info.size = bytes;
    info.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    vkCreateBuffer(device, &info, nullptr, &buffer);
    VkMemoryRequirements needs{};
    vkGetBufferMemoryRequirements(device, buffer, &needs);
    VkPhysicalDeviceMemoryProperties memory_properties{};
    vkGetPhysicalDeviceMemoryProperties(physical, &memory_properties);
    const VkMemoryPropertyFlags want = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    VkMemoryAllocateInfo allocate{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    allocate.allocationSize = needs.size;
    for (std::uint32_t t = 0; t < memory_properties.memoryTypeCount; ++t) {
      if ((needs.memoryTypeBits & (1u << t)) && (memory_properties.memoryTypes[t].propertyFlags & want) == want) {
        allocate.memoryTypeIndex = t;
        break;
      }
    }
    vkAllocateMemory(device, &allocate, nullptr, &memory);
    vkBindBufferMemory(device, buffer, memory, 0);
    void* mapped = nullptr;
    vkMapMemory(device, memory, 0, VK_WHOLE_SIZE, 0, &mapped);
    return mapped;
  }

  VulkanHandles Handles() const {
    VulkanHandles h;
    h.instance = instance;
    h.physical_device = physical;
    h.device = device;
    h.queue = queue;
    h.queue_family = family;
    h.get_instance_proc_addr = reinterpret_cast<void*>(&CountGetInstanceProcAddr);
    return h;
  }

  std::string why;
  VkInstance instance = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  std::uint32_t family = 0;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  VkCommandPool pool = VK_NULL_HANDLE;
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
};

constexpr const char* kVariant = "vulkan.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg64";

TEST(VulkanAdopted, SkinsOnTheCallersDeviceAndQueueAndIntoItsCommandBufferCreatingAndDestroyingNothing) {
  CallerVulkan caller;
  if (!caller.ok()) GTEST_SKIP() << caller.why;
  counts = {};
  caller_messages.clear();
  const SkinnedAsset& asset = Cesium();
  const View view(asset.mesh);
  const std::vector<glm::mat4> palette = asset.PaletteAt(0, 0.5);
  const std::size_t out_bytes = asset.mesh.vertex_count() * 16;
  auto* skinned_into = static_cast<const float*>(caller.NewBuffer(out_bytes));
  {
    Result<Device> device = Device::FromVulkan(caller.Handles());
    ASSERT_TRUE(device.ok()) << device.status().message();
    EXPECT_EQ(device->info().backend, Backend::kVulkan);
    SkinnerOptions options;
    options.variant = kVariant;
    Result<Skinner> skinner = Skinner::Create(*device, WinnersDb::Empty(), view.mesh, options);
    ASSERT_TRUE(skinner.ok()) << skinner.status().message();
    ASSERT_EQ(skinner->output_stride_bytes(), 16u);
    ExpectSkinsLikeTheGold(*skinner, asset.mesh, palette);  // Skin() on the caller's queue

    // Recorded into the caller's command buffer, written into the caller's buffer.
    VkCommandBufferAllocateInfo allocate{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    allocate.commandPool = caller.pool;
    allocate.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    allocate.commandBufferCount = 1;
    VkCommandBuffer cb = VK_NULL_HANDLE;
    ASSERT_EQ(vkAllocateCommandBuffers(caller.device, &allocate, &cb), VK_SUCCESS);
    VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    vkBeginCommandBuffer(cb, &begin);
    const Status recorded = skinner->SkinIntoVulkan(cb, caller.buffer);
    ASSERT_TRUE(recorded.ok()) << recorded.message();
    vkEndCommandBuffer(cb);
    VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    submit.commandBufferCount = 1;
    submit.pCommandBuffers = &cb;
    ASSERT_EQ(vkQueueSubmit(caller.queue, 1, &submit, VK_NULL_HANDLE), VK_SUCCESS);
    ASSERT_EQ(vkQueueWaitIdle(caller.queue), VK_SUCCESS);
    const GoldResult gold = SkinGold(QuantisedMesh(asset.mesh, ParseVariantKey(kVariant)), palette, false);
    std::vector<glm::vec3> positions(asset.mesh.vertex_count());
    for (std::size_t v = 0; v < positions.size(); ++v)
      positions[v] = {skinned_into[4 * v], skinned_into[4 * v + 1], skinned_into[4 * v + 2]};
    const GoldComparison c = CompareToGold(gold.positions, positions);
    EXPECT_EQ(c.non_finite, 0u);
    EXPECT_LT(c.max_relative, 1e-5) << "worst vertex " << c.worst_vertex;
    EXPECT_TRUE(skinner->Finish().ok());
  }
  EXPECT_EQ(counts.create_device, 0);
  EXPECT_EQ(counts.destroy_device, 0);
  EXPECT_EQ(counts.create_instance, 0);
  EXPECT_EQ(counts.destroy_instance, 0);
  // The caller's device still works.
  EXPECT_EQ(vkDeviceWaitIdle(caller.device), VK_SUCCESS);
  VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  info.size = 256;
  info.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  VkBuffer after = VK_NULL_HANDLE;
  EXPECT_EQ(vkCreateBuffer(caller.device, &info, nullptr, &after), VK_SUCCESS);
  vkDestroyBuffer(caller.device, after, nullptr);
  for (const std::string& m : caller_messages) ADD_FAILURE() << "validation: " << m;
}

// CesiumMan's Skinner (kVariant) on the caller's device, one pose's palette;
// skipped where there is no Vulkan device.
class VulkanAdoptedFrames : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!caller_.ok()) GTEST_SKIP() << caller_.why;
    caller_messages.clear();
    device_.emplace(Device::FromVulkan(caller_.Handles()));
    ASSERT_TRUE(device_->ok()) << device_->status().message();
    SkinnerOptions options;
    options.variant = kVariant;
    skinner_.emplace(Skinner::Create(**device_, WinnersDb::Empty(), view_.mesh, options));
    ASSERT_TRUE(skinner_->ok()) << skinner_->status().message();
  }
  void TearDown() override {
    for (const std::string& m : caller_messages) ADD_FAILURE() << "validation: " << m;
  }
  Device& device() { return **device_; }
  Skinner& skinner() { return **skinner_; }
  bool SetPalette() { return skinner().SetPalette(matrices_.data(), matrices_.size()).ok(); }

 private:
  CallerVulkan caller_;
  View view_{Cesium().mesh};
  std::vector<float> matrices_ = testing::Floats(Cesium().PaletteAt(0, 0.5));
  std::optional<Result<Device>> device_;
  std::optional<Result<Skinner>> skinner_;
};

// On the caller's queue every Skin() is submitted before it returns, so that
// the caller's own submissions after it find the frame ahead of them: frames
// are not held back to share a submission as on a device skintune opens
// (where back-to-back frames do: vulkan_runner_test.cpp).
TEST_F(VulkanAdoptedFrames, EverySkinIsOnTheCallersQueueWhenItReturns) {
  ASSERT_TRUE(SetPalette());
  for (int f = 0; f < 12; ++f) {
    const int before = counts.queue_submit;
    ASSERT_TRUE(skinner().Skin().ok());
    EXPECT_GT(counts.queue_submit, before) << "frame " << f << " was not submitted when Skin() returned";
  }
  EXPECT_TRUE(skinner().Finish().ok());
}

// A wait for a GPU polls the frame's fence before it sleeps on it: NVIDIA's
// driver wakes a thread sleeping in vkWaitForFences tens of microseconds
// after the fence signals, longer than a crowd's frame. A wait for a CPU
// device (lavapipe) sleeps at once, leaving the host's cores to its work.
TEST_F(VulkanAdoptedFrames, FinishPollsAGpusFenceBeforeItSleepsOnIt) {
  const bool cpu = device().info().type == "cpu";
  for (int f = 0; f < 4; ++f) {
    ASSERT_TRUE(SetPalette());
    ASSERT_TRUE(skinner().Skin().ok());
    counts.fence_calls.clear();
    ASSERT_TRUE(skinner().Finish().ok());
    ASSERT_FALSE(counts.fence_calls.empty()) << "frame " << f << ": Finish called no fence function";
    if (cpu)
      EXPECT_EQ(counts.fence_calls, "w") << "frame " << f << ", " << device().info().name << ": a CPU device's wait polled";
    else
      EXPECT_EQ(counts.fence_calls.front(), 'p') << "frame " << f << ", " << device().info().name
                                                 << ": Finish slept on the fence first (" << counts.fence_calls.size()
                                                 << " calls: " << counts.fence_calls.substr(0, 40) << ")";
  }
}

// A frame that is waited for (SetPalette + Skin + Finish) reaches the queue
// before any fence is reset: the fence of the next submission is reset while
// the device runs this one (NVIDIA's vkResetFences took 5-13 us of host time).
TEST_F(VulkanAdoptedFrames, AWaitedForFrameIsSubmittedBeforeAFenceIsReset) {
  for (int f = 0; f < 6; ++f) {
    ASSERT_TRUE(SetPalette());
    counts.submit_calls.clear();
    ASSERT_TRUE(skinner().Skin().ok());
    ASSERT_TRUE(skinner().Finish().ok());
    ASSERT_FALSE(counts.submit_calls.empty()) << "frame " << f << " was not submitted";
    EXPECT_EQ(counts.submit_calls.front(), 's')
        << "frame " << f << " reset a fence before its submission (" << counts.submit_calls << ")";
    if (f >= 1) {
      EXPECT_EQ(counts.submit_calls, "sr") << "frame " << f << ": one submission, then one fence reset ahead";
    }
  }
}

// A crowd animated on the device (CesiumMan's clip, the palette kernel
// before each frame's skin launch) on the caller's device, whose validation
// layer checks synchronization within each command buffer, with a ring of
// GetParam() palette slots.
class VulkanAdoptedAnimatedFrames : public ::testing::TestWithParam<int> {
 protected:
  void SetUp() override {
    if (!caller_.ok()) GTEST_SKIP() << caller_.why;
    caller_messages.clear();
    Result<Model> model = Model::Load(std::string(SKINTUNE_TEST_DATA_DIR) + "/CesiumMan.gltf");
    ASSERT_TRUE(model.ok()) << model.status().message();
    model_.emplace(std::move(*model));
    device_.emplace(Device::FromVulkan(caller_.Handles()));
    ASSERT_TRUE(device_->ok()) << device_->status().message();
  }
  void TearDown() override {
    for (const std::string& m : caller_messages) ADD_FAILURE() << "validation: " << m;
  }
  Result<Skinner> Crowd(int instances) {
    SkinnerOptions options;
    options.variant = kVariant;
    options.instances = instances;
    options.palette_buffers = GetParam();
    Result<Skinner> skinner = Skinner::CreateAnimated(**device_, WinnersDb::Empty(), *model_, options);
    if (!skinner.ok()) return skinner;
    std::vector<AnimationState> states(static_cast<std::size_t>(instances));
    for (int k = 0; k < instances; ++k) {
      states[static_cast<std::size_t>(k)].animation = 0;
      states[static_cast<std::size_t>(k)].time = 0.3f * static_cast<float>(k);
    }
    EXPECT_TRUE(skinner->SetAnimation(states.data(), states.size()).ok());
    return skinner;
  }
  bool validated() const { return caller_.messenger != VK_NULL_HANDLE; }

 private:
  CallerVulkan caller_{true};
  std::optional<Model> model_;
  std::optional<Result<Device>> device_;
};

// Each frame's palette kernel reads and writes only its own palette slot and
// the instances' states, which the frames before it left ordered after their
// own palette kernels; the ring (two slots at least) holds another slot for
// the frame before to read. So nothing orders the palette kernel after that
// frame's skin launch, and the device may run them side by side (NVIDIA's
// Vulkan, H200: a crowd in transition's pipelined frame 64.7-64.9 us ->
// 62.8-62.9 against a 52.8 us Skin-only frame). vulkan_runner_test.cpp
// checks the frames that share a command buffer for hazards, and a ring of
// one slot, where the kernel waits.
TEST_P(VulkanAdoptedAnimatedFrames, APaletteKernelDoesNotWaitForTheFrameBefore) {
  Result<Skinner> crowd = Crowd(3);
  ASSERT_TRUE(crowd.ok()) << crowd.status().message();
  ASSERT_TRUE(crowd->Skin().ok());
  for (int f = 0; f < 8; ++f) {
    ASSERT_TRUE(crowd->AdvanceAnimation(1.0f / 60.0f).ok());
    counts.commands.clear();
    ASSERT_TRUE(crowd->Skin().ok());
    const std::string frame = counts.commands;
    const std::size_t first = frame.find_first_of("dB");
    ASSERT_NE(first, std::string::npos) << "frame " << f << " recorded no dispatch (" << frame << ")";
    ASSERT_GE(std::count(frame.begin(), frame.end(), 'd'), 2) << "frame " << f << ": no palette kernel (" << frame << ")";
    if (f == 0) continue;  // the first frame after SetAnimation's upload waits for everything before it
    EXPECT_EQ(frame[first], 'd') << "frame " << f << ": the palette kernel waited for the frame before (" << frame << ")";
  }
  ASSERT_TRUE(crowd->Finish().ok());
  if (!validated()) std::cout << "[ Vulkan   ] no validation layer: the hazards were not checked\n";
}

INSTANTIATE_TEST_SUITE_P(PaletteSlots, VulkanAdoptedAnimatedFrames, ::testing::Values(2, 3),
                         [](const ::testing::TestParamInfo<int>& i) { return std::to_string(i.param) + "Slots"; });

TEST(VulkanAdopted, NullHandlesAreInvalidArguments) {
  const Result<Device> device = Device::FromVulkan(VulkanHandles{});
  ASSERT_FALSE(device.ok());
  EXPECT_EQ(device.status().code(), ErrorCode::kInvalidArgument) << device.status().message();
  EXPECT_NE(device.status().message().find("null"), std::string::npos) << device.status().message();
}

TEST(VulkanDevice, OpensListsAndSkinsLikeTheGold) {
  const Backend vulkan = Backend::kVulkan;
  const testing::TempDir cache;
  Result<Device> device = Device::Open("", &vulkan, testing::CacheIn(cache));
  if (!device.ok()) GTEST_SKIP() << device.status().message();
  EXPECT_EQ(device->info().backend, Backend::kVulkan);
  EXPECT_EQ(device->info().id.rfind("vulkan:Vulkan/", 0), 0u) << device->info().id;
  const View view(Cesium().mesh);
  SkinnerOptions options;
  options.instances = 3;
  Result<Skinner> skinner = Skinner::Create(*device, WinnersDb::Empty(), view.mesh, options);
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  testing::ExpectInstancesLikeTheGold(*skinner, Cesium().mesh, testing::Poses(Cesium(), 3));
  // Recording into a command buffer is Vulkan's only.
  EXPECT_EQ(skinner->SkinIntoVulkan(nullptr).code(), ErrorCode::kInvalidArgument);
}

// ---------------------------------------------------------------- program cache

// The key a program-cache file was stored under (its second line, unescaped).
std::string StoredKey(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::string magic, escaped, key;
  std::getline(in, magic);
  std::getline(in, escaped);
  for (std::size_t i = 0; i < escaped.size(); ++i) {
    if (escaped[i] == '\\' && i + 1 < escaped.size()) {
      key += escaped[++i] == 'n' ? '\n' : escaped[i];
    } else {
      key += escaped[i];
    }
  }
  return key;
}

// GL and OpenCL rebuild a program the driver refuses to load from the cache;
// a damaged SPIR-V under a valid SHA-256 (a disk error before the checksum
// was taken, another tool's bytes) failed every Skinner::Create with
// VkResult -13 until the file was deleted.
TEST(VulkanProgramCache, ADamagedShaderWithAValidChecksumIsRebuiltNotAnError) {
  const Backend vulkan = Backend::kVulkan;
  const View view(Cesium().mesh);
  for (const char* damage : {"zeros", "body"}) {
    SCOPED_TRACE(damage);
    const testing::TempDir dir;
    {
      Result<Device> first = Device::Open("", &vulkan, testing::CacheIn(dir));
      if (!first.ok()) GTEST_SKIP() << first.status().message();
      ASSERT_TRUE(Skinner::Create(*first, WinnersDb::Empty(), view.mesh).ok());
    }
    const ProgramCache cache(dir.str());
    ASSERT_FALSE(dir.Files().empty());
    for (const std::filesystem::path& file : dir.Files()) {
      const std::string key = StoredKey(file);
      std::vector<std::uint8_t> spirv = *cache.Load("vulkan", key);
      // "zeros": no SPIR-V at all; "body": the header (magic, version,
      // generator, bound, schema) kept and every instruction after it garbled.
      const std::size_t from = std::string(damage) == "zeros" ? 0 : 20;
      for (std::size_t i = from; i < spirv.size(); ++i) spirv[i] = static_cast<std::uint8_t>(i * 37 + 11);
      cache.Store("vulkan", key, spirv);
      ASSERT_EQ(cache.Load("vulkan", key), spirv);  // its SHA-256 is valid
    }
    Result<Device> device = Device::Open("", &vulkan, testing::CacheIn(dir));
    ASSERT_TRUE(device.ok()) << device.status().message();
    Result<Skinner> skinner = Skinner::Create(*device, WinnersDb::Empty(), view.mesh);
    ASSERT_TRUE(skinner.ok()) << skinner.status().message();
    EXPECT_EQ(device->cache_stats().disk_hits, 0);
    ExpectSkinsLikeTheGold(*skinner, Cesium().mesh, Cesium().PaletteAt(0, 0.25));
    Result<Device> again = Device::Open("", &vulkan, testing::CacheIn(dir));  // rewritten: a hit again
    ASSERT_TRUE(again.ok()) << again.status().message();
    ASSERT_TRUE(Skinner::Create(*again, WinnersDb::Empty(), view.mesh).ok());
    EXPECT_GE(again->cache_stats().disk_hits, 1);
    EXPECT_EQ(again->cache_stats().builds, 0);
  }
}

}  // namespace
}  // namespace skintune::internal
