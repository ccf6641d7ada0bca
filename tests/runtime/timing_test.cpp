// The driver's timing on every device found here (PoCL, llvmpipe; CUDA and
// the GPU's OpenCL and GL on a GPU machine): the same-size copy is a correct
// copy in every API, and bursts give one positive time per burst. No figure
// is judged here (docs/TUNING.md "Timing"; figures come from the tuner).
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "generator/copy_kernel.h"
#include "model/synthetic.h"
#include "runtime/backend_table.h"
#include "runtime/runner.h"

namespace skintune::internal {
namespace {

struct Opened {
  std::string name;
  Lang lang;
  std::unique_ptr<Runner> runner;
};

// One runner per device found, with its API's first language.
std::vector<Opened> Devices() {
  std::vector<Opened> out;
  for (FoundDevice& d : DiscoverDevices().devices) {
    const BackendEntry* entry = FindBackend(d.identity.backend);
    if (!entry || entry->languages.empty()) continue;
    out.push_back({d.identity.Id(), entry->languages.front(), d.open()});
  }
  return out;
}

TEST(CopyKernel, EmitsOneLaunchOfSixteenByteItemsAndStridesBeyondTheGroupLimit) {
  const CopyKernel small = EmitCopy(Lang::kCuda, 3200);
  EXPECT_EQ(small.items, 100u);
  EXPECT_EQ(CopyBytes(small), 3200u);
  ASSERT_EQ(small.mesh.launches.size(), 1u);
  EXPECT_EQ(small.mesh.launches[0].inputs.at(0).bytes.size(), 1600u);
  EXPECT_EQ(small.kernel.launch.vertices_per_item, 1);
  EXPECT_NE(small.kernel.text.find("skintune_copy"), std::string::npos);
  // Past 65535 groups of 256 a work item copies several items, so GL's
  // minimum GL_MAX_COMPUTE_WORK_GROUP_COUNT always holds.
  const std::size_t items = kCopyMaxGroups * kCopyWorkGroup + 1;
  const CopyKernel big = EmitCopy(Lang::kGlslVertex, items * 32);
  EXPECT_EQ(big.kernel.lang, Lang::kGlslCompute);  // GL's vertex path is judged against GL's compute copy
  EXPECT_EQ(big.kernel.launch.vertices_per_item, 2);
  EXPECT_LE(big.kernel.launch.GlobalItems(items) / kCopyWorkGroup, kCopyMaxGroups);
  // Every word of the source differs from the poison and from its neighbours.
  const std::vector<std::uint8_t>& in = small.mesh.launches[0].inputs[0].bytes;
  EXPECT_NE(std::vector<std::uint8_t>(in.begin(), in.begin() + 4), std::vector<std::uint8_t>(in.begin() + 4, in.begin() + 8));
}

// Every packing's copy and every flush is compiled once per process: the
// size is an argument, so copies of different sizes are one source (the
// runners reuse a built program by its source hash).
TEST(CopyKernel, CopiesOfDifferentSizesAreOneProgram) {
  for (const Language& language : kLanguages) {
    const Lang lang = language.lang;
    SCOPED_TRACE(language.name);
    const CopyKernel a = EmitCopy(lang, 3200), b = EmitCopy(lang, 5'200'000);
    EXPECT_EQ(a.kernel.text, b.kernel.text);
    EXPECT_EQ(a.kernel.source_hash, b.kernel.source_hash);
    EXPECT_EQ(EmitFlush(lang, 8 << 20).kernel.source_hash, EmitFlush(lang, 100 << 20).kernel.source_hash);
    EXPECT_NE(EmitFlush(lang, 3200).kernel.source_hash, a.kernel.source_hash);
  }
}

TEST(CopyKernel, CopiesEveryByteOnEveryDevice) {
  const std::vector<Opened> devices = Devices();
  if (devices.empty()) GTEST_SKIP() << "no device found (no OpenCL, CUDA or GL here)";
  for (const Opened& d : devices) {
    SCOPED_TRACE(d.name);
    const CopyKernel copy = EmitCopy(d.lang, 1 << 20);
    const RunResult result = d.runner->Run(copy.mesh, std::span<const KernelSource>(&copy.kernel, 1));
    EXPECT_EQ(result.poisoned_vertices, 0u);
    ASSERT_EQ(result.positions.size(), copy.mesh.launches[0].inputs[0].bytes.size());
    EXPECT_EQ(result.positions, copy.mesh.launches[0].inputs[0].bytes);
  }
}

TEST(Timing, BurstsGiveOnePositiveTimePerBurstInEveryApi) {
  const std::vector<Opened> devices = Devices();
  if (devices.empty()) GTEST_SKIP() << "no device found (no OpenCL, CUDA or GL here)";
  for (const Opened& d : devices) {
    SCOPED_TRACE(d.name);
    const Prepared copy = d.runner->PrepareCopy(d.lang, 1 << 20, 3);
    EXPECT_EQ(copy.input_sets(), 3);
    const std::vector<double> ms = d.runner->Time(copy, 1, 4, 5);
    ASSERT_EQ(ms.size(), 4u);
    for (const double t : ms) EXPECT_GT(t, 0.0);
    const int frames = d.runner->BurstFrames(copy, 1, 2.0);
    EXPECT_GE(frames, 1);
    EXPECT_LE(frames, kMaxBurstFrames);
  }
}

}  // namespace
}  // namespace skintune::internal
