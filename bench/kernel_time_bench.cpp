// skintune_bench_kernel_time: the tuner's kernel time of chosen variants,
// and the same kernels launched plainly for an independent profiler to time.
//
//   skintune_bench_kernel_time --device PATTERN --dataset KEY --variant KEY [--variant KEY...]
//       [--launches N] [--fresh-inputs] [--json FILE]
//
// Without --launches: each variant measured as `skintune tune` measures it
// (tuner_internal::MeasureJob: verification against the float64 gold, the
// kernel time from a flushed cache to the stop rule, the frame time, the
// same-size copy), one line each, and with --json one JSON object per line.
// As in a tuning run, the variants of one packing time the same input sets
// (Runner::ShareTimedInputs); --fresh-inputs allocates each measurement's
// own, so that a variant named twice is timed over two allocations.
// With --launches N: each variant run once (Runner::Run, no timing), then
// its frame launched N times back to back and waited for
// (Runner::LaunchSet): what Nsight Compute profiles, e.g.
//
//   ncu --cache-control all --clock-control none -k regex:^skin$ --metrics gpu__time_duration.sum
//       skintune_bench_kernel_time --device cuda: --dataset 100k-b4 --variant ... --launches 20
//
// docs/TUNING.md "Kernel time" says why those ncu options match skintune's
// definition. Exit 1 when a variant fails verification or the device is not found.
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "generator/variant.h"
#include "base/error.h"
#include "runtime/backend_table.h"
#include "runtime/device_clock.h"
#include "runtime/device_identity.h"
#include "tuner/datasets.h"
#include "tuner/executor.h"
#include "tuner/measure_job.h"

namespace {

using namespace skintune::internal;

int Run(const std::string& pattern, const std::string& dataset, const std::vector<std::string>& keys, int launches,
        bool fresh_inputs, const std::string& json_path) {
  Discovered found = DiscoverDevices();
  FoundDevice* device = nullptr;
  for (FoundDevice& f : found.devices)
    if (!device && MatchesDevice(pattern, f.identity)) device = &f;
  if (!device) {
    std::cerr << "skintune_bench_kernel_time: no device matches '" << pattern << "'\n";
    return 1;
  }
  // As a tuning run does: the GPU at a compute context's clocks (runtime/device_clock.h).
  std::string unheld;
  const std::unique_ptr<ClockHold> clocks = ClockHold::ForDevices({device->identity}, &unheld);
  std::unique_ptr<Runner> runner = device->open();
  // As the tuner's runners: an eighth of the device's memory, at most 1 GiB (tuner/runner_device.cpp).
  constexpr std::size_t kShared = std::size_t{1} << 30;
  const std::size_t memory = device->identity.global_memory_bytes;
  if (!fresh_inputs) runner->ShareTimedInputs(memory > 0 ? std::min(kShared, memory / 8) : kShared / 4);
  tuner_internal::RunnerExecutor executor(*runner, device->identity);
  tuner_internal::DatasetCache datasets;
  std::ofstream json;
  if (!json_path.empty()) json.open(json_path);
  int failed = 0;
  std::printf("device: %s (kernel clock: %s)\n", device->identity.Id().c_str(), runner->api().kernel_clock().c_str());
  for (const std::string& key : keys) {
    const Variant variant = ParseVariantKey(key);
    if (launches > 0) {
      tuner_internal::DatasetCache::Entry& entry = datasets.Get(dataset);
      std::vector<KernelSource> kernels;
      const PackedMesh& packed = tuner_internal::PackScene(datasets, entry, variant, kernels);
      const std::vector<std::vector<std::uint8_t>> palettes = tuner_internal::TimedPalettes(datasets, entry, variant, 1);
      (void)runner->Run(packed, kernels, palettes.front(), entry.instances());
      Prepared prepared = runner->Prepare(packed, kernels, palettes, entry.instances());
      for (int i = 0; i < launches; ++i) runner->LaunchSet(prepared, 0);
      runner->Finish();
      std::printf("%s: %d launches\n", key.c_str(), launches);
      continue;
    }
    const Measurement m = tuner_internal::MeasurementOf(
        {&executor, &datasets, &device->identity, device->limits, {variant.lang}, variant, {dataset}, TimingOptions{}});
    if (m.status != MeasureStatus::kOk && m.status != MeasureStatus::kTooImprecise) {
      std::printf("%s: %s %s\n", key.c_str(), Name(m.status), m.detail.c_str());
      ++failed;
      continue;
    }
    std::printf("%s: kernel %.3f us [%.3f, %.3f] (%d samples%s), frame %.3f us, %.0f GB/s, x_copy %.2f\n", key.c_str(),
                m.timing.median_ms * 1e3, m.timing.low_ms * 1e3, m.timing.high_ms * 1e3, m.timing.repetitions,
                m.timing.tight ? "" : ", capped", m.timing.frame_ms * 1e3, m.gbps, m.x_copy);
    if (json.is_open()) json << nlohmann::json(m).dump() << "\n";
  }
  return failed ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"skintune_bench_kernel_time: the tuner's kernel time of variants, or plain launches for a profiler"};
  std::string device, dataset = "100k-b4", json;
  std::vector<std::string> variants;
  int launches = 0;
  bool fresh_inputs = false;
  app.add_option("--device", device, "device pattern (skintune devices)")->required();
  app.add_option("--dataset", dataset, "dataset or scene key");
  app.add_option("--variant", variants, "variant key (repeatable)")->required();
  app.add_option("--launches", launches, "launch each variant's frame N times instead (for ncu)")->check(CLI::Range(0, 100000));
  app.add_flag("--fresh-inputs", fresh_inputs, "allocate each measurement's input sets (the tuner shares one packing's)");
  app.add_option("--json", json, "write each measurement as a JSON line");
  CLI11_PARSE(app, argc, argv);
  try {
    return Run(device, dataset, variants, launches, fresh_inputs, json);
  } catch (const skintune::internal::Error& e) {
    std::cerr << "skintune_bench_kernel_time: " << e.what() << "\n";
    return 1;
  }
}
