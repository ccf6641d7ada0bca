// CPU skinning benchmarks over the paper's datasets (configs/paper.json:
// 25k/100k/400k/1600k vertices x 1..4 influences, 77 bones, bone locality),
// plus the memory copy bandwidth of this machine measured by the same harness,
// so every GB/s figure can be read as a fraction of what memory can do.
//
//   skintune_bench_cpu [--benchmark_filter=REGEX] [google benchmark flags]
//
// Counters: vertices/s, and bytes/s = the bytes the implementation's layout
// must move per frame (inputs read + outputs written, palette excluded) per
// second. Each iteration skins a different animation frame (8 palettes
// rotate). The 25k and 100k datasets (1-5 MB) fit in this machine's caches:
// their GB/s can exceed the copy bandwidth measured on 256 MiB buffers.
#include <benchmark/benchmark.h>

#include <cstring>
#include <map>
#include <memory>
#include <vector>

#include "reference/skinning.h"
#include "reference/synthetic.h"
#include "reference/thread_pool.h"

namespace skintune {
namespace {

constexpr int kPalettes = 8;

struct Prepared {
  SkinnedAsset asset;
  std::vector<std::vector<glm::mat4>> palettes;
};

const Prepared& Dataset(const std::string& key) {
  static std::map<std::string, std::unique_ptr<Prepared>> cache;
  auto& slot = cache[key];
  if (!slot) {
    slot = std::make_unique<Prepared>();
    slot->asset = GenerateDataset(ParseDatasetKey(key));
    for (int f = 0; f < kPalettes; ++f) slot->palettes.push_back(slot->asset.PaletteAt(0, f / 30.0));
  }
  return *slot;
}

// Input bytes of the mesh's array-of-structures layout + output bytes.
double BytesPerFrame(const SkinnedMesh& mesh, std::size_t output_bytes_per_vertex) {
  const std::size_t in = sizeof(glm::vec3) + mesh.influences * (sizeof(std::uint16_t) + sizeof(float));
  return double(mesh.vertex_count()) * double(in + output_bytes_per_vertex);
}

void SetCounters(benchmark::State& state, std::size_t vertices, double bytes) {
  state.counters["vertices/s"] = benchmark::Counter(double(vertices), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["bytes/s"] = benchmark::Counter(bytes, benchmark::Counter::kIsIterationInvariantRate,
                                                 benchmark::Counter::kIs1000);
}

void BM_Gold(benchmark::State& state, std::string key) {
  const Prepared& d = Dataset(key);
  int frame = 0;
  for (auto _ : state) {
    GoldResult r = SkinGold(d.asset.mesh, d.palettes[frame++ % kPalettes]);
    benchmark::DoNotOptimize(r.positions.data());
  }
  SetCounters(state, d.asset.mesh.vertex_count(), BytesPerFrame(d.asset.mesh, sizeof(glm::dvec3)));
}

void BM_Serial(benchmark::State& state, std::string key) {
  const Prepared& d = Dataset(key);
  std::vector<glm::vec3> out(d.asset.mesh.vertex_count());
  int frame = 0;
  for (auto _ : state) {
    SkinSerial(d.asset.mesh, d.palettes[frame++ % kPalettes], out);
    benchmark::ClobberMemory();
  }
  SetCounters(state, d.asset.mesh.vertex_count(), BytesPerFrame(d.asset.mesh, sizeof(glm::vec3)));
}

void BM_Fast(benchmark::State& state, std::string key) {
  const Prepared& d = Dataset(key);
  FastSkinner skinner(d.asset.mesh);
  std::vector<glm::vec3> out(d.asset.mesh.vertex_count());
  int frame = 0;
  for (auto _ : state) {
    skinner.Run(d.palettes[frame++ % kPalettes], out);
    benchmark::ClobberMemory();
  }
  state.counters["threads"] = skinner.threads();
  SetCounters(state, d.asset.mesh.vertex_count(), double(skinner.BytesPerRun(false)));
}

// Copy bandwidth: bytes read + bytes written per second, 256 MiB buffers
// (far beyond any last-level cache), one thread and all threads.
void BM_Copy(benchmark::State& state, unsigned threads) {
  constexpr std::size_t kBytes = std::size_t(256) << 20;
  std::vector<char> src(kBytes, 1), dst(kBytes, 0);
  ThreadPool pool(threads);
  const std::size_t grain = kBytes / (4 * pool.size());
  for (auto _ : state) {
    pool.ParallelFor(kBytes, grain, [&](std::size_t begin, std::size_t end) {
      std::memcpy(dst.data() + begin, src.data() + begin, end - begin);
    });
    benchmark::ClobberMemory();
  }
  state.counters["threads"] = pool.size();
  state.counters["bytes/s"] =
      benchmark::Counter(2.0 * kBytes, benchmark::Counter::kIsIterationInvariantRate, benchmark::Counter::kIs1000);
}

void RegisterAll() {
  benchmark::RegisterBenchmark("copy/1-thread", BM_Copy, 1u)->UseRealTime()->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("copy/all-threads", BM_Copy, 0u)->UseRealTime()->Unit(benchmark::kMillisecond);
  for (const char* size : {"25k", "100k", "400k", "1600k"}) {
    for (int b = 1; b <= 4; ++b) {
      const std::string key = std::string(size) + "-b" + std::to_string(b);
      benchmark::RegisterBenchmark(("serial/" + key).c_str(), BM_Serial, key)->Unit(benchmark::kMillisecond);
      benchmark::RegisterBenchmark(("fast/" + key).c_str(), BM_Fast, key)
          ->UseRealTime()
          ->Unit(benchmark::kMillisecond);
      benchmark::RegisterBenchmark(("gold/" + key).c_str(), BM_Gold, key)->Unit(benchmark::kMillisecond);
    }
  }
}

}  // namespace
}  // namespace skintune

int main(int argc, char** argv) {
  skintune::RegisterAll();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
