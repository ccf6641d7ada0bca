// A program that skins one frame and exits at once, as a user's tool might:
// `skin_and_exit BACKEND CACHE_DIR` opens the first device of BACKEND
// ("opencl", "gl", "vulkan", "cuda", "cpu") with its program cache in
// CACHE_DIR, creates a Skinner, sets a palette, calls Skin() and returns from
// main without Finish() or a read-back. Exit code 0 when it did (3 when the
// backend has no device here: the caller skips), 1 when a call failed.
//
// A driver may still be working on that frame when main returns: PoCL
// compiles a kernel for its launch on a thread of its own, and exit() runs
// LLVM's exit-time destructors under it ("Failed to create kernel compiler
// pass inline-kernels", abort). Skinner's destructor must wait for the work
// it queued. The race is made certain, not rare: an exit handler registered
// before any driver is loaded runs after the drivers' exit-time destructors
// and holds the process there for a second, so a thread still working
// crashes every time instead of in a few runs out of a hundred.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "skintune/skintune.h"

namespace {

void HoldExitAfterDriversAreGone() { std::this_thread::sleep_for(std::chrono::seconds(1)); }

// A strip of `n` vertices, each bound to joints 0 and 1 with weights 0.75 and 0.25.
struct Strip {
  explicit Strip(std::size_t n) : positions(3 * n), joints(2 * n), weights(2 * n) {
    for (std::size_t v = 0; v < n; ++v) {
      positions[3 * v] = static_cast<float>(v);
      joints[2 * v] = 0;
      joints[2 * v + 1] = 1;
      weights[2 * v] = 0.75f;
      weights[2 * v + 1] = 0.25f;
    }
    view.vertex_count = n;
    view.influences = 2;
    view.joint_count = 2;
    view.positions = positions.data();
    view.joints = joints.data();
    view.weights = weights.data();
  }
  std::vector<float> positions;
  std::vector<std::uint32_t> joints;
  std::vector<float> weights;
  skintune::MeshView view;
};

bool BackendNamed(const std::string& name, skintune::Backend& out) {
  for (skintune::Backend b : {skintune::Backend::kOpenCl, skintune::Backend::kCuda, skintune::Backend::kGl,
                              skintune::Backend::kVulkan, skintune::Backend::kCpu})
    if (name == skintune::BackendName(b)) {
      out = b;
      return true;
    }
  return false;
}

int Fail(const char* what, const skintune::Status& status) {
  std::fprintf(stderr, "skin_and_exit: %s: %s\n", what, status.message().c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  std::atexit(HoldExitAfterDriversAreGone);  // before any driver registers its own
  skintune::Backend backend;
  if (argc != 3 || !BackendNamed(argv[1], backend)) {
    std::fprintf(stderr, "usage: skin_and_exit opencl|cuda|gl|vulkan|cpu CACHE_DIR\n");
    return 2;
  }
  skintune::DeviceOptions options;
  options.program_cache_dir = argv[2];
  skintune::Result<skintune::Device> device = skintune::Device::Open("", &backend, options);
  if (!device.ok()) {
    std::fprintf(stderr, "skin_and_exit: no device: %s\n", device.status().message().c_str());
    return 3;
  }
  Strip strip(4096);
  skintune::Result<skintune::Skinner> skinner =
      skintune::Skinner::Create(*device, skintune::WinnersDb::Empty(), strip.view);
  if (!skinner.ok()) return Fail("Skinner::Create", skinner.status());
  std::vector<float> palette(2 * 16, 0.0f);
  for (int j = 0; j < 2; ++j)
    for (int d = 0; d < 4; ++d) palette[16 * j + 5 * d] = 1.0f;
  if (skintune::Status s = skinner->SetPalette(palette.data(), palette.size()); !s.ok()) return Fail("SetPalette", s);
  if (skintune::Status s = skinner->Skin(); !s.ok()) return Fail("Skin", s);
  return 0;
}
