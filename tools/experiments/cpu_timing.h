// skintune: timing the CPU implementations the way the tuner times kernels.
//
// The paper's speedups are over its serial CPU loop; skintune's figures are
// over reference/skinning.h's SkinSerial (the same loop) and are shown beside
// FastSkinner (every core, vectorised). Both are timed with a monotonic host
// clock per frame after a warm-up, rotating among enough copies of the mesh
// that they exceed twice the last-level cache (as the tuner rotates device
// inputs), each frame with another palette; the median is kept. The last
// frame of every copy is checked against the float64 gold.
#pragma once

#include <cstdint>

#include "model/asset.h"
#include "report/paper_result.h"
#include "runtime/physical_device.h"  // HostLastLevelCacheBytes

namespace skintune::internal {

struct CpuTimingOptions {
  int warmup = 2;            // untimed frames
  int repetitions = 9;       // timed frames (the median is reported)
  int max_input_sets = 8;    // copies of the mesh rotated between frames
  double min_seconds = 0.2;  // more repetitions (up to 10x) while the timed total is below this
  double tolerance = 1e-5;   // largest relative error against the gold
};

// SkinSerial on one thread. Throws Error when its output is off the gold by
// more than the tolerance (a CPU path that is wrong has no speedup to show).
CpuTiming TimeSerial(const SkinnedAsset& asset, const CpuTimingOptions& options = {});
// FastSkinner on `threads` threads (0: every logical CPU).
CpuTiming TimeFast(const SkinnedAsset& asset, const CpuTimingOptions& options = {}, unsigned threads = 0);

// The host's memory copy bandwidth (bytes read + written per second, GB/s):
// memcpy over buffers of 4x the last-level cache (at least 256 MiB) on
// `threads` threads (0: all), the median of 7 after 2 warm-ups.
double HostCopyBandwidthGBps(unsigned threads = 0);

}  // namespace skintune::internal
