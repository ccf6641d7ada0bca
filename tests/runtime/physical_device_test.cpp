// One chip seen through several APIs, and its real last-level cache (runtime/physical_device.h).
#include "runtime/physical_device.h"

#include <gtest/gtest.h>

namespace skintune::internal {
namespace {

constexpr std::uint64_t kMiB = 1ull << 20;

CacheReport Gpu(const std::string& backend, std::uint64_t llc, const std::string& uuid, const std::string& pci = "") {
  return {backend, "gpu", "NVIDIA H100 80GB HBM3", uuid, pci, llc, 80ull << 30};
}

TEST(PhysicalDevice, EveryApiOfOneChipTakesTheLargestCredibleFigure) {
  // NVIDIA's OpenCL says 4.3 MB, CUDA 50 MiB, GL nothing: one chip, by UUID.
  const std::string uuid = "0123456789abcdef0123456789abcdef";
  CacheReport opencl = Gpu("opencl", 4325376, uuid);
  opencl.name = "Some GPU";  // no datasheet entry: the figure must come from CUDA
  CacheReport cuda = Gpu("cuda", 50 * kMiB, uuid);
  cuda.name = "Some GPU";
  CacheReport gl = Gpu("gl", 0, uuid);
  gl.name = "Some GPU/PCIe/SSE2";
  const std::vector<CacheFigure> f = ResolveLastLevelCaches({opencl, cuda, gl}, 0);
  ASSERT_EQ(f.size(), 3u);
  for (const CacheFigure& x : f) EXPECT_EQ(x.bytes, 50 * kMiB) << x.source;
  EXPECT_NE(f[0].source.find("cuda 'Some GPU' reports it"), std::string::npos) << f[0].source;
  EXPECT_NE(f[0].source.find("UUID " + uuid), std::string::npos) << f[0].source;
  EXPECT_EQ(f[1].source, "cuda 'Some GPU' reports it");
}

TEST(PhysicalDevice, PciBusIdMatchesWhenThereIsNoUuid) {
  CacheReport opencl = Gpu("opencl", 4 * kMiB, "", "0000:65:00.0");
  opencl.name = "X";
  CacheReport cuda = Gpu("cuda", 40 * kMiB, "", "0000:65:00.0");
  cuda.name = "X";
  CacheReport other = Gpu("cuda", 6 * kMiB, "", "0000:66:00.0");
  other.name = "X";
  const std::vector<CacheFigure> f = ResolveLastLevelCaches({opencl, cuda, other}, 0);
  EXPECT_EQ(f[0].bytes, 40 * kMiB);
  EXPECT_EQ(f[2].bytes, 6 * kMiB);  // another chip keeps its own
}

TEST(PhysicalDevice, TheDatasheetCoversAChipNoApiReportsTruthfully) {
  const std::vector<CacheFigure> f = ResolveLastLevelCaches({Gpu("opencl", 4325376, "")}, 0);
  EXPECT_EQ(f[0].bytes, 50 * kMiB);
  EXPECT_NE(f[0].source.find("datasheet"), std::string::npos) << f[0].source;
}

TEST(PhysicalDevice, CpuDevicesAreTheHostAndAFigureAboveMemoryIsNotCredible) {
  const CacheReport pocl{"opencl", "cpu", "cpu-znver4", "", "", 1 * kMiB, 24ull << 30};
  const CacheReport llvmpipe{"gl", "cpu", "llvmpipe (LLVM 15.0.6, 256 bits)", "", "", 0, 24ull << 30};
  const CacheReport liar{"opencl", "gpu", "Y", "", "", 1ull << 40, 8ull << 30};
  const std::vector<CacheFigure> f = ResolveLastLevelCaches({pocl, llvmpipe, liar}, 32 * kMiB);
  EXPECT_EQ(f[0].bytes, 32 * kMiB);
  EXPECT_EQ(f[1].bytes, 32 * kMiB);
  EXPECT_NE(f[1].source.find("the host"), std::string::npos) << f[1].source;
  EXPECT_EQ(f[2].bytes, 0u);  // 1 TiB of cache on an 8 GiB device: unknown
}

TEST(PhysicalDevice, UuidHexIsEmptyForAllZeroBytes) {
  unsigned char zero[16] = {};
  EXPECT_EQ(UuidHex(zero), "");
  unsigned char id[16] = {0x01, 0x23, 0x45, 0x67, 0x89, 0xab, 0xcd, 0xef, 0, 0, 0, 0, 0, 0, 0, 0xff};
  EXPECT_EQ(UuidHex(id), "0123456789abcdef00000000000000ff");
}

}  // namespace
}  // namespace skintune::internal
