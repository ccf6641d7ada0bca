#include "tools/experiments/cpu_timing.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "base/error.h"
#include "reference/skinning.h"
#include "base/thread_pool.h"
#include "tuner/datasets.h"
#include "tuner/measure_job.h"

namespace skintune::internal {

namespace {

using Clock = std::chrono::steady_clock;

double Median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

// Runs `frame(set, palette)` warm-up + timed times over `sets` input sets and
// the palettes, returning per-frame milliseconds.
template <typename Frame>
std::vector<double> TimeFrames(const CpuTimingOptions& options, int sets, std::size_t palettes, Frame&& frame) {
  std::size_t next = 0;
  auto run = [&] {
    const int set = static_cast<int>(next % static_cast<std::size_t>(sets));
    const std::size_t palette = next % palettes;
    ++next;
    const Clock::time_point start = Clock::now();
    frame(set, palette);
    return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  };
  for (int i = 0; i < options.warmup; ++i) run();
  std::vector<double> ms;
  double total = 0.0;
  const int most = std::max(options.repetitions, 1) * 10;
  while (static_cast<int>(ms.size()) < std::max(options.repetitions, 1) ||
         (total < options.min_seconds * 1e3 && static_cast<int>(ms.size()) < most)) {
    ms.push_back(run());
    total += ms.back();
  }
  return ms;
}

CpuTiming Summarise(const std::vector<double>& ms, int sets, unsigned threads, double bytes) {
  CpuTiming t;
  t.median_ms = Median(ms);
  t.min_ms = *std::min_element(ms.begin(), ms.end());
  t.max_ms = *std::max_element(ms.begin(), ms.end());
  t.repetitions = static_cast<int>(ms.size());
  t.input_sets = sets;
  t.threads = threads;
  t.bytes_per_frame = bytes;
  t.gbps = t.median_ms > 0.0 ? bytes / (t.median_ms * 1e6) : 0.0;
  return t;
}

// The error of `out` (skinned with `palette`) against the gold; Error when
// beyond the tolerance.
double Check(const char* what, const SkinnedAsset& asset, const std::vector<glm::mat4>& palette,
             const std::vector<glm::vec3>& out, double tolerance) {
  const GoldResult gold = SkinGold(asset.mesh, palette);
  const GoldComparison c = CompareToGold(gold.positions, out);
  if (c.non_finite > 0 || !(c.max_relative <= tolerance)) {
    char text[256];
    std::snprintf(text, sizeof text, "%s: %s is off the gold: max relative error %.3g at vertex %zu (tolerance %.3g)",
                  asset.source.c_str(), what, c.max_relative, c.worst_vertex, tolerance);
    throw Error(text);
  }
  return c.max_relative;
}

int SetsFor(const CpuTimingOptions& options, double bytes) {
  return tuner_internal::InputSetsFor(HostLastLevelCacheBytes(), static_cast<std::uint64_t>(bytes),
                                      options.max_input_sets);
}

// Times `run(set, palette, output)` over `sets` input sets and the frame
// palettes, then checks the last output of every set that ran against the gold.
template <typename Run>
CpuTiming TimeAndCheck(const char* what, const SkinnedAsset& asset, const CpuTimingOptions& options, int sets,
                       unsigned threads, double bytes, Run&& run) {
  const auto palettes = tuner_internal::FramePalettes(asset, 8);
  std::vector<std::vector<glm::vec3>> outputs(static_cast<std::size_t>(sets),
                                              std::vector<glm::vec3>(asset.mesh.vertex_count()));
  std::vector<long> last_palette(static_cast<std::size_t>(sets), -1);  // -1: not run
  const std::vector<double> ms = TimeFrames(options, sets, palettes.size(), [&](int set, std::size_t p) {
    run(set, palettes[p], outputs[set]);
    last_palette[set] = static_cast<long>(p);
  });
  CpuTiming t = Summarise(ms, sets, threads, bytes);
  for (int s = 0; s < sets; ++s) {
    if (last_palette[s] < 0) continue;  // fewer frames than copies
    t.max_relative_error =
        std::max(t.max_relative_error, Check(what, asset, palettes[last_palette[s]], outputs[s], options.tolerance));
  }
  return t;
}

}  // namespace

CpuTiming TimeSerial(const SkinnedAsset& asset, const CpuTimingOptions& options) {
  const SkinnedMesh& mesh = asset.mesh;
  ThrowIfInvalid(mesh, asset.source);
  // The array-of-structures inputs the loop reads and the positions it writes.
  const double bytes = static_cast<double>(mesh.vertex_count()) *
                       (sizeof(glm::vec3) * 2 + mesh.influences * (sizeof(std::uint16_t) + sizeof(float)));
  const int sets = SetsFor(options, bytes);
  const std::vector<SkinnedMesh> copies(static_cast<std::size_t>(sets), mesh);
  return TimeAndCheck("the serial CPU loop", asset, options, sets, 1, bytes,
                      [&](int set, const std::vector<glm::mat4>& palette, std::vector<glm::vec3>& out) {
                        SkinSerial(copies[set], palette, out);
                      });
}

CpuTiming TimeFast(const SkinnedAsset& asset, const CpuTimingOptions& options, unsigned threads) {
  // The first skinner tells the bytes, hence how many copies to rotate.
  std::vector<std::unique_ptr<FastSkinner>> skinners;
  skinners.push_back(std::make_unique<FastSkinner>(asset.mesh, threads));
  const double bytes = static_cast<double>(skinners.front()->BytesPerRun(false));
  const int sets = SetsFor(options, bytes);
  while (static_cast<int>(skinners.size()) < sets) skinners.push_back(std::make_unique<FastSkinner>(asset.mesh, threads));
  return TimeAndCheck("the fast CPU path", asset, options, sets, skinners.front()->threads(), bytes,
                      [&](int set, const std::vector<glm::mat4>& palette, std::vector<glm::vec3>& out) {
                        skinners[set]->Run(palette, out);
                      });
}

double HostCopyBandwidthGBps(unsigned threads) {
  const std::size_t bytes = std::max<std::size_t>(std::size_t(256) << 20, 4 * HostLastLevelCacheBytes());
  std::vector<char> src(bytes, 1), dst(bytes, 0);
  ThreadPool pool(threads);
  const std::size_t grain = std::max<std::size_t>(bytes / (4 * pool.size()), 4096);
  std::vector<double> ms;
  for (int i = 0; i < 9; ++i) {
    const Clock::time_point start = Clock::now();
    pool.ParallelFor(bytes, grain, [&](std::size_t begin, std::size_t end) {
      std::memcpy(dst.data() + begin, src.data() + begin, end - begin);
    });
    const double elapsed = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    if (i >= 2) ms.push_back(elapsed);
  }
  volatile char sink = dst[bytes / 2];  // the copy is observable
  (void)sink;
  return 2.0 * static_cast<double>(bytes) / (Median(ms) * 1e6);
}

}  // namespace skintune::internal
