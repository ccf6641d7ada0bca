// skintune (internal): the one list of GPU APIs skintune runs on.
//
// Each entry is one API (its code in runtime/backends/<name>/): its name, the
// kernel languages it runs, how to find its devices on this machine and open
// one (a Runner over its DeviceApi, runtime/runner.h), how Device::OpenBest
// ranks its devices, and its Skinner glue. Device discovery and opening
// (runtime/device.cpp), the fallback chain's languages (selection.h), the
// winners database's backend names, and the tuner's backends all iterate over
// this table: a new API adds one entry (backend_table.cpp) and its folder
// (docs/ARCHITECTURE.md).
//
// An entry's position in the table is also its skintune::Backend value
// (skintune/skintune.h): the table lists the APIs in that enum's order,
// which is the discovery order.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "generator/constraints.h"
#include "generator/variant.h"
#include "runtime/device_identity.h"

namespace skintune::internal {

class Runner;
class SkinnerBackend;
struct DeviceState;
struct KernelSource;
struct PackedMesh;

// A device that discovery found: who it is, what it allows, how to open it.
struct FoundDevice {
  DeviceIdentity identity;                 // index 0: the caller numbers the devices it keeps
  DeviceLimits limits;                     // the constraints' view of the device
  std::uint64_t max_allocation_bytes = 0;  // the largest buffer (0: unknown): caps the copy kernel
  // A runner on the device (its context, queue or stream); throws Error("<API> setup: ...").
  std::function<std::unique_ptr<Runner>()> open;
  // A runner on a context made for it alone (CUDA: cuCtxCreate, where
  // `open` shares the primary context; OpenCL on a GPU: `open`, which makes a
  // cl_context per runner); empty where kernel times are not the context's.
  // The tuner opens several and times on the quickest (docs/TUNING.md
  // "Kernel time": the device's start of a launch is the context's).
  std::function<std::unique_ptr<Runner>()> open_own;
};

struct Discovered {
  std::vector<FoundDevice> devices;
  std::vector<std::string> skipped;  // why an API or a device is missing: "cuda: skipped: libcuda.so.1 ..."
};

// What a Skinner's input set is prepared for: its instances and the depth
// of its palette ring (SkinnerOptions::palette_buffers).
struct SkinnerSetup {
  int instances;
  int palette_buffers;
};

struct BackendEntry {
  const char* name;             // "opencl": device ids, databases, DeviceIdentity::backend
  const char* title;            // "OpenCL": messages (the first word of its runner's errors)
  std::vector<Lang> languages;  // the kernel languages its devices run, preferred first
  // Appends every device of the API on this machine, or "<name>: skipped: <why>"
  // lines. A throw is caught and reported as skipped.
  void (*discover)(Discovered& out);
  // Device::OpenBest's rank of one of its devices (smaller first, over every API).
  int (*preference)(const DeviceIdentity& device);
  // The Skinner's device work on `device` (whose runner is this API's): one
  // prepared input set of `kernels` (one per launch) as `setup` says.
  std::unique_ptr<SkinnerBackend> (*make_skinner)(DeviceState& device, const PackedMesh& mesh,
                                                  const std::vector<KernelSource>& kernels, const SkinnerSetup& setup);
};

// Every API, in skintune::Backend order (which is the discovery order).
const std::vector<BackendEntry>& Backends();
// The entry named `name` ("opencl"), or null.
const BackendEntry* FindBackend(std::string_view name);
// Every device of every API (only those of the API named `only` when given;
// the others are not even looked for), in table order. Never throws. Each
// identity's last_level_cache_bytes is the physical chip's, matched across
// the devices found (runtime/physical_device.h: the same GPU through several
// APIs by UUID or PCI bus id, CPU devices as the host), with its source; the
// API's own figure moves to reported_cache_bytes. With `only`, only that
// API's devices are matched (a datasheet figure still applies).
Discovered DiscoverDevices(const char* only = nullptr);
// The entries' names or titles joined: "opencl, cuda or gl".
std::string JoinedBackendNames(bool titles = false);
// The names of every backend's languages, in table order: "opencl", "cuda",
// "glsl-compute", "glsl-vertex".
std::vector<std::string> LanguageNames();

}  // namespace skintune::internal
