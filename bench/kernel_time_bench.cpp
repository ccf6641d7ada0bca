// skintune_bench_kernel_time: the tuner's kernel time of chosen variants,
// and the same kernels launched plainly for an independent profiler to time.
//
//   skintune_bench_kernel_time --device PATTERN --dataset KEY --variant KEY [--variant KEY...]
//       [--launches N] [--fresh-inputs] [--sequence STEPS] [--contexts K] [--json FILE]
//
// Without --launches: the device's copy bandwidth first, as a tuning run's
// worker measures it before its first measurement; then each variant measured
// as `skintune tune` measures it (tuner_internal::MeasureJob: verification
// against the float64 gold, the kernel time from a flushed cache to the stop
// rule, the frame time, the same-size copy, the context's launch start),
// one line each, and with --json
// one JSON object per line.
// As in a tuning run, the variants of one packing time the same input sets
// (Runner::ShareTimedInputs); --fresh-inputs allocates each measurement's
// own, so that a variant named twice is timed over two allocations.
// With --sequence STEPS (a comma-separated list of cold, frame, copy,
// prepare, reprepare, reflush, verify, probe): the first variant prepared
// once, then each step in turn, to find what moves a kernel time from one
// measurement to the next: cold prints the median of 100 kernel-time samples
// (after 3 untimed) in one submission with their 10th and 90th percentiles
// (cold:N takes N), frame the frame time, copy prepares the same-size copy
// and times it, prepare prepares the variant's input sets again, verify runs
// its verification launch, each releasing what it made as a measurement does;
// reprepare prepares the variant again and times that one from then on
// (bound to the same buffers where the runner shares them, to new ones with
// --fresh-inputs), reflush gives the steps after a flush buffer of their own;
// probe times the device's copy bandwidth as a worker does first (no other
// step does).
// With --json each cold step's samples are written as a JSON line.
// With --contexts K: K runners of the device open together (on contexts of
// their own where its API shares one), and in two rounds each one's launch
// start (the tuner's probe of a context: tuner/runner_device.h) and the first
// variant's median of 300 cold samples: how far a kernel time depends on the
// context it is taken on. Otherwise the variants are measured on the runner
// a tuning run's worker opens (OpenMeasuringRunner: the quickest of several
// contexts where the API has contexts of a runner's own).
// With --launches N: each variant run once (Runner::Run, no timing), then
// N cold frames as the kernel time takes them (one untimed first: the flush,
// then the frame, each waited for): the launches the tuner times, for Nsight
// Compute to time them too, e.g.
//
//   ncu --cache-control all --clock-control none -k regex:^skin$ --metrics gpu__time_duration.sum
//       skintune_bench_kernel_time --device cuda: --dataset 100k-b4 --variant ... --launches 20
//
// docs/TUNING.md "Kernel time" says why those ncu options match skintune's
// definition. Exit 1 when a variant fails verification or the device is not found.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <sstream>
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
#include "tuner/runner_device.h"

namespace {

using namespace skintune::internal;

// --sequence: the steps on the first variant (see the header).
int RunSequence(tuner_internal::RunnerExecutor& executor, tuner_internal::DatasetCache& datasets, const DeviceIdentity& device,
                const std::string& dataset, const std::string& key, const std::string& steps,
                const std::function<void()>& probe, std::ostream* json) {
  const Variant variant = ParseVariantKey(key);
  tuner_internal::DatasetCache::Entry& entry = datasets.Get(dataset);
  std::vector<KernelSource> kernels;
  const PackedMesh& packed = tuner_internal::PackScene(datasets, entry, variant, kernels);
  const std::uint64_t bytes = tuner_internal::FrameBytes(packed, entry.instances());
  const int sets = tuner_internal::InputSetsFor(device.last_level_cache_bytes, bytes, TimingOptions{}.max_input_sets);
  const std::vector<std::vector<std::uint8_t>> palettes = tuner_internal::TimedPalettes(datasets, entry, variant, sets);
  const auto prepare = [&] { return executor.Prepare(packed, kernels, palettes, entry.instances()); };
  const auto cold_us = [](tuner_internal::Executor::Timed& timed) { return tuner_internal::Median(timed.Cold(3, 100)) * 1e3; };
  std::unique_ptr<tuner_internal::Executor::Timed> timed = prepare();
  std::printf("%s on %s, %d input sets\n", key.c_str(), dataset.c_str(), sets);
  std::stringstream list(steps);
  for (std::string step; std::getline(list, step, ',');) {
    const std::string kind = step.substr(0, step.find(':'));
    if (kind == "cold") {
      const int n = step == kind ? 100 : std::atoi(step.c_str() + kind.size() + 1);
      if (n < 1 || n > 100000) {
        std::fprintf(stderr, "skintune_bench_kernel_time: --sequence: '%s' asks for no samples (%s:N, N 1-100000)\n",
                     step.c_str(), kind.c_str());
        return 2;
      }
      std::vector<double> us = timed->Cold(3, n);
      for (double& v : us) v *= 1e3;
      if (json) *json << nlohmann::json{{"step", step}, {"samples_us", us}}.dump() << "\n";
      std::sort(us.begin(), us.end());
      const auto at = [&](double q) { return us[static_cast<std::size_t>(q * static_cast<double>(us.size() - 1))]; };
      std::printf("  %-8s %.3f us [p10 %.3f, p90 %.3f] of %d\n", kind.c_str(), tuner_internal::Median(us), at(0.1), at(0.9), n);
    } else if (step == "frame") {
      std::printf("  frame    %.3f us\n", timed->FrameMs(3, 200) * 1e3);
    } else if (step == "copy") {
      const std::unique_ptr<tuner_internal::Executor::Timed> copy = executor.Copy(variant.lang, bytes, sets);
      std::printf("  copy     %.3f us\n", cold_us(*copy));
    } else if (step == "prepare") {
      (void)prepare();
      std::printf("  prepare\n");
    } else if (step == "reprepare") {
      timed.reset();  // released first, as a measurement releases its own
      timed = prepare();
      std::printf("  reprepare\n");
    } else if (step == "reflush") {
      executor.ReleaseFlushes();
      std::printf("  reflush\n");
    } else if (step == "probe") {
      probe();
    } else if (step == "verify") {
      (void)executor.Run(packed, kernels, palettes.front(), entry.instances());
      std::printf("  verify\n");
    } else {
      std::fprintf(stderr,
                   "skintune_bench_kernel_time: --sequence: unknown step '%s' (cold, cold:N, frame, copy, prepare, reprepare, reflush, verify, probe)\n",
                   step.c_str());
      return 2;
    }
  }
  return 0;
}

// --contexts K: K runners open together (on contexts of their own where the
// API shares one, as the tuner's choice opens them), then two rounds over
// them: each one's launch-start probe (the tuner's, its trimmed mean) and the
// variant's median of 300 cold samples.
int RunContexts(const FoundDevice& device, tuner_internal::DatasetCache& datasets, const std::string& dataset,
                const std::string& key, int contexts) {
  const Variant variant = ParseVariantKey(key);
  std::vector<std::unique_ptr<Runner>> runners;
  for (int c = 0; c < contexts; ++c) runners.push_back(device.open_own ? device.open_own() : device.open());
  tuner_internal::DatasetCache::Entry& entry = datasets.Get(dataset);
  std::vector<KernelSource> kernels;
  const PackedMesh& packed = tuner_internal::PackScene(datasets, entry, variant, kernels);
  const std::uint64_t bytes = tuner_internal::FrameBytes(packed, entry.instances());
  const int sets = tuner_internal::InputSetsFor(device.identity.last_level_cache_bytes, bytes, TimingOptions{}.max_input_sets);
  const std::vector<std::vector<std::uint8_t>> palettes = tuner_internal::TimedPalettes(datasets, entry, variant, sets);
  std::printf("%s on %s, %d contexts%s\n", key.c_str(), dataset.c_str(), contexts,
              device.open_own ? " of their own" : "");
  std::vector<std::unique_ptr<tuner_internal::LaunchStartProbe>> probes;
  for (const std::unique_ptr<Runner>& runner : runners)
    probes.push_back(
        std::make_unique<tuner_internal::LaunchStartProbe>(*runner, device.identity, variant.lang, nullptr));
  for (int round = 0; round < 2; ++round)
    for (int c = 0; c < contexts; ++c) {
      const double start_us = TrimmedMean(probes[c]->Samples(), 0.1) * 1e3;
      tuner_internal::RunnerExecutor executor(*runners[c], device.identity);
      const std::unique_ptr<tuner_internal::Executor::Timed> timed =
          executor.Prepare(packed, kernels, palettes, entry.instances());
      std::printf("  round %d context %d: launch start %.3f us, kernel %.3f us\n", round, c, start_us,
                  tuner_internal::Median(timed->Cold(3, 300)) * 1e3);
      std::fflush(stdout);
    }
  return 0;
}

int Run(const std::string& pattern, const std::string& dataset, const std::vector<std::string>& keys, int launches,
        bool fresh_inputs, const std::string& sequence, int contexts, const std::string& json_path) {
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
  tuner_internal::DatasetCache datasets;
  if (contexts > 0)
    return RunContexts(*device, datasets, dataset, keys.front(), contexts);
  // As a tuning run's worker opens it: on the quickest of several contexts where the API makes them.
  tuner_internal::MeasuringContext context;
  std::unique_ptr<Runner> runner =
      tuner_internal::OpenMeasuringRunner(*device, ParseVariantKey(keys.front()).lang, nullptr, &context);
  if (!fresh_inputs) runner->ShareTimedInputs(tuner_internal::SharedInputBytes(device->identity));  // as a tuning run's runner
  tuner_internal::RunnerExecutor executor(*runner, device->identity);
  executor.SetContext(context.choice, context.launch_start_ms);
  std::ofstream json;
  if (!json_path.empty()) json.open(json_path);
  int failed = 0;
  std::printf("device: %s (kernel clock: %s)\n", device->identity.Id().c_str(), runner->api().kernel_clock().c_str());
  // As a tuning run's worker starts: the device's copy bandwidth first. It also
  // warms the device as a run's measurements find it (PoCL's first kernel time
  // at 100k-b1 read 1.9x its later ones without it on the 2-core machine,
  // 2026-12-01). --sequence leaves it to a `probe` step.
  const auto probe = [&] {
    const std::size_t bytes =
        tuner_internal::CopyBytesCapped(tuner_internal::ProbeCopyBytes(device->identity), device->max_allocation_bytes);
    const std::unique_ptr<tuner_internal::Executor::Timed> copy =
        executor.Copy(ParseVariantKey(keys.front()).lang, 2 * bytes, 1);
    std::printf("copy bandwidth: %.0f GB/s\n", tuner_internal::ProbeCopyGBps(*copy, bytes));
  };
  if (!sequence.empty())
    return RunSequence(executor, datasets, device->identity, dataset, keys.front(), sequence, probe,
                       json.is_open() ? &json : nullptr);
  if (launches == 0) probe();
  for (const std::string& key : keys) {
    const Variant variant = ParseVariantKey(key);
    if (launches > 0) {
      tuner_internal::DatasetCache::Entry& entry = datasets.Get(dataset);
      std::vector<KernelSource> kernels;
      const PackedMesh& packed = tuner_internal::PackScene(datasets, entry, variant, kernels);
      const std::vector<std::vector<std::uint8_t>> palettes = tuner_internal::TimedPalettes(datasets, entry, variant, 1);
      (void)runner->Run(packed, kernels, palettes.front(), entry.instances());
      // The launches the kernel time times: each frame after the flush, waited for.
      (void)executor.Prepare(packed, kernels, palettes, entry.instances())->Cold(1, launches);
      std::printf("%s: %d cold frames\n", key.c_str(), launches);
      continue;
    }
    const TimingOptions timing = TimingOptions{}.ForDevice(device->identity);  // as the tuner times this device
    const Measurement m = tuner_internal::MeasurementOf(
        {&executor, &datasets, &device->identity, device->limits, {variant.lang}, variant, {dataset}, timing});
    if (m.status != MeasureStatus::kOk && m.status != MeasureStatus::kTooImprecise) {
      std::printf("%s: %s %s\n", key.c_str(), Name(m.status), m.detail.c_str());
      ++failed;
      continue;
    }
    std::printf("%s: kernel %.3f us [%.3f, %.3f] (%d samples%s), launch start %.3f us, frame %.3f us, %.0f GB/s, "
                "x_copy %.2f\n",
                key.c_str(), m.timing.median_ms * 1e3, m.timing.low_ms * 1e3, m.timing.high_ms * 1e3,
                m.timing.repetitions, m.timing.tight ? "" : ", capped", m.timing.launch_start_ms * 1e3,
                m.timing.frame_ms * 1e3, m.gbps, m.x_copy);
    if (json.is_open()) json << nlohmann::json(m).dump() << "\n";
  }
  return failed ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"skintune_bench_kernel_time: the tuner's kernel time of variants, or their cold frames for a profiler"};
  std::string device, dataset = "100k-b4", json;
  std::vector<std::string> variants;
  int launches = 0;
  bool fresh_inputs = false;
  std::string sequence;
  int contexts = 0;
  app.add_option("--device", device, "device pattern (skintune devices)")->required();
  app.add_option("--dataset", dataset, "dataset or scene key");
  app.add_option("--variant", variants, "variant key (repeatable)")->required();
  app.add_option("--launches", launches, "run N cold frames of each variant instead, as the kernel time takes them (for ncu)")->check(CLI::Range(0, 100000));
  app.add_flag("--fresh-inputs", fresh_inputs, "allocate each measurement's input sets (the tuner shares one packing's)");
  app.add_option("--sequence", sequence, "steps on the first variant: cold, cold:N, frame, copy, prepare, reprepare, reflush, verify, probe (comma-separated)");
  app.add_option("--contexts", contexts, "time the first variant on each of K contexts opened together, in two rounds")
      ->check(CLI::Range(1, 64));
  app.add_option("--json", json, "write each measurement as a JSON line");
  CLI11_PARSE(app, argc, argv);
  try {
    return Run(device, dataset, variants, launches, fresh_inputs, sequence, contexts, json);
  } catch (const skintune::internal::Error& e) {
    std::cerr << "skintune_bench_kernel_time: " << e.what() << "\n";
    return 1;
  }
}
