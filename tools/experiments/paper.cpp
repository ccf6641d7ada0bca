// skintune: the paper's experiment (tools/experiments/paper.h): one tuning run
// over the paper's data sets with the paper's kernels measured first on every
// device and language, then the CPU baselines.
#include "tools/experiments/paper.h"

#include <algorithm>
#include <set>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "model/synthetic.h"
#include "tools/experiments/cpu_timing.h"
#include "tuner/measurement.h"
#include "tuner/tune.h"
#include "tuner/worker.h"

namespace skintune::internal {

namespace {

// --quick: a search of this many evaluations per device x language x data set
// (the full run takes the paper config's budget).
constexpr std::size_t kQuickBudget = 8;

}  // namespace

PaperResult RunPaper(const PaperOptions& options) {
  auto progress = [&](const std::string& what) {
    if (options.progress) options.progress(0, 0, what);
  };
  const nlohmann::json config_json = nlohmann::json::parse(EmbeddedConfig("paper"));
  TuneConfig config = ConfigFromJson(config_json, "paper");

  PaperResult result;
  result.quick = options.quick;
  result.command = options.command;
  result.reported = BuiltInPaperReported();
  result.paper_kernels = PaperKernels();
  result.figure1_dataset = config_json.at("figure1").at("dataset").get<std::string>();

  // The data sets: checked before anything is measured.
  config.datasets = options.datasets.empty() ? PaperDatasets(options.quick) : options.datasets;
  std::set<std::string> seen;
  for (const std::string& key : config.datasets) {
    try {
      ParseDatasetKey(key).Validate();
    } catch (const Error& e) {
      throw Error(std::string("--dataset: ") + e.what());
    }
    if (!seen.insert(key).second) throw Error("--dataset: '" + key + "' is listed twice");
  }
  if (options.budget > 0) {
    config.strategy.budget = options.budget;
  } else if (options.quick) {
    config.strategy.budget = kQuickBudget;
  }
  if (options.quick) {
    // A first look in minutes on a laptop's CPU devices: fewer, shorter
    // kernel-time samplings (each sample flushes the cache first, which on a
    // CPU device costs more than the kernel) and races of two.
    config.timing.warmup = 2;
    config.timing.repetitions = 7;
    config.timing.stop.min_samples = 5;
    config.timing.stop.batch = 5;
    config.timing.stop.max_samples = 20;
    config.timing.stop.max_ms = 20.0;
    config.timing.race = 2;
    config.variant_timeout_s = 30.0;
  }
  for (const PaperKernel& k : result.paper_kernels) config.baselines.push_back(k.variant);

  TuneOptions tune;
  tune.device_pattern = options.device_pattern;
  tune.software_rasterizers = options.software_rasterizers;
  tune.languages = options.languages;
  tune.cache_path = options.cache_path;
  tune.worker_executable = options.worker_executable;
  tune.progress = options.progress;
  result.tuning = RunTuning(config, tune);
  result.tuning.config = "paper" + std::string(options.quick ? " --quick" : "");
  // The space's invalid points (tens of thousands per device: `skintune
  // variants --device` counts them) are left out of the result; a paper
  // kernel that is invalid on a device stays, with its constraint.
  std::erase_if(result.tuning.measurements, [&](const Measurement& m) {
    if (m.status != MeasureStatus::kInvalid) return false;
    return std::none_of(config.baselines.begin(), config.baselines.end(), [&](Variant b) {
      b.influences = m.variant.influences;
      return b == m.variant;
    });
  });
  // The CPU after the devices (whose workers have exited by then): a bad
  // --device pattern fails at once, before minutes of CPU timing.
  CpuTimingOptions cpu_options;
  if (options.quick) {
    cpu_options.repetitions = 5;
    cpu_options.min_seconds = 0.1;
  }
  if (!options.skip_cpu) {
    progress("host: copy bandwidth");
    result.host.copy_bandwidth_gbps = HostCopyBandwidthGBps();
  }
  for (const std::string& key : config.datasets) {
    if (options.skip_cpu) break;
    const SkinnedAsset asset = GenerateDataset(ParseDatasetKey(key));
    CpuResult cpu;
    cpu.dataset = key;
    progress(key + ": serial CPU baseline");
    cpu.serial = TimeSerial(asset, cpu_options);
    progress(key + ": fast CPU path");
    cpu.fast = TimeFast(asset, cpu_options);
    result.host.threads = cpu.fast.threads;
    result.cpu.push_back(cpu);
  }

  const nlohmann::json& machine = result.tuning.machine;
  result.host.cpu_model = machine.contains("cpu_model") ? machine["cpu_model"].get<std::string>() : std::string();
  if (result.host.threads == 0 && machine.contains("logical_cpus")) {
    result.host.threads = machine["logical_cpus"].get<unsigned>();
  }
  result.created = UtcTimestamp();  // when the run finished
  return result;
}

}  // namespace skintune::internal
