// CPU skinning on this machine, two ways.
//
// 1. The comparison (the default): at one dataset (--dataset=KEY, default
//    1600k-b4), the cpu device's kernels in several formats and PoCL's
//    OpenCL variants, each measured exactly as `skintune tune` measures a
//    variant (tuner_internal::MeasureJob over the runner driver: verified
//    on poisoned, guarded outputs against the float64 gold, its error
//    against the unquantised source and the default budget, bursts of
//    frames rotating input sets, and the same-size copy timed the same way:
//    for the cpu device an all-thread memcpy of the same bytes). The list is
//    measured --repeat=N times (default 3) one variant after another, and
//    the medians are printed with the ratios the cpu device is judged by: the f32 fast
//    path's share of the copy bandwidth, the fastest format the budget
//    allows against f32, and PoCL's best against the fast path.
//
//      skintune_bench_cpu [--dataset=KEY] [--repeat=N] [--pocl=default|none|KEY[,KEY...]]
//
//    (CLI11: --opt=value or --opt value; --help prints the usage. The
//    last of an option given twice counts.)
//
// 2. Any --benchmark_* flag runs the Google Benchmark suite instead: the
//    paper's datasets (configs/paper.json: 25k/100k/400k/1600k vertices x
//    1..4 influences, 77 bones, bone locality) through the serial loop, the
//    fast path and the gold (on every core since 2026-11-26: base/thread_pool.h
//    ParallelChunks), plus the memory copy bandwidth measured by the
//    same harness, so every GB/s figure can be read as a fraction of what
//    memory can do.
//
//      skintune_bench_cpu --benchmark_filter=REGEX [google benchmark flags]
//
//    Counters: vertices/s, and bytes/s = the bytes the implementation's
//    layout must move per frame (inputs read + outputs written, palette
//    excluded) per second. Each iteration skins a different animation frame
//    (8 palettes rotate). The 25k and 100k datasets (1-5 MB) fit in this
//    machine's caches: their GB/s can exceed the copy bandwidth measured on
//    256 MiB buffers.
#include <benchmark/benchmark.h>

#include <CLI/CLI.hpp>

#include <cstring>
#include <map>
#include <memory>
#include <vector>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>

#include "generator/constraints.h"
#include "base/error.h"
#include "reference/skinning.h"
#include "model/synthetic.h"
#include "base/thread_pool.h"
#include "runtime/backend_table.h"
#include "runtime/backends/cpu/cpu_runner.h"
#include "runtime/source_error.h"
#include "tuner/datasets.h"
#include "tuner/executor.h"
#include "tuner/measure_job.h"

namespace skintune::internal {
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
}  // namespace skintune::internal

namespace skintune::internal {
namespace {

// ---------------------------------------------------------------- the comparison

struct CompareOptions {
  std::string dataset = "1600k-b4";
  int repeat = 3;
  std::vector<std::string> pocl;  // variant keys; empty: none
};

// The cpu variants compared: the fast path's own format first (u16 joints,
// f32 weights, mat4), then the compressed formats, packed records, the
// 12-float mat3x4 blend and point blending. B and normals follow the dataset.
const char* const kCpuVariants[] = {
    "cpu.padded.soa-split.float3.u16.f32.mat4.global.matrix.v1c.wg0",
    "cpu.padded.soa-split.float3.u8.f32.mat4.global.matrix.v1c.wg0",
    "cpu.padded.soa-split.float3.u16.unorm16.mat4.global.matrix.v1c.wg0",
    "cpu.padded.soa-split.float3.u8.unorm16.mat4.global.matrix.v1c.wg0",
    "cpu.padded.soa-split.float3.u8.unorm8.mat4.global.matrix.v1c.wg0",
    "cpu.padded.aos.float3.u8.unorm16.mat4.global.matrix.v1c.wg0",
    "cpu.padded.soa.float3.u8.unorm16.mat4.global.matrix.v1c.wg0",
    "cpu.padded.soa-split.float4.u8.unorm16.mat4.global.matrix.v1c.wg0",
    "cpu.padded.soa-split.float3.u16.f32.mat3x4.global.matrix.v1c.wg0",
    "cpu.padded.soa-split.float3.u16.f32.mat4.global.point.v1c.wg0",
};

// PoCL's default set: the layouts and formats above in OpenCL, at the
// work-group sizes and vertices per item PoCL's tuned winners use here
// (docs/PERFORMANCE.md).
const char* const kPoclVariants[] = {
    "opencl.padded.soa-split.float3.u16.f32.mat4.global.matrix.v1c.wg128",
    "opencl.padded.soa-split.float3.u16.f32.mat4.global.matrix.v4c.wg64",
    "opencl.padded.soa-split.float3.u8.unorm16.mat4.global.matrix.v4c.wg64",
    "opencl.padded.aos.float3.u8.unorm16.mat4.global.matrix.v1c.wg128",
    "opencl.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg256",
    "opencl.padded.soa-split.float3.u16.f32.mat4.global.matrix.v8c.wg512",
};

// One variant's medians over the repeats.
struct Row {
  Variant variant;
  std::string status;       // the last measurement's status (ok, too_imprecise, ...) and detail
  std::vector<double> ms, x_copy, gbps;
  double quantisation_rel = 0.0;
  std::string schedule;     // cpu: the threads, chunks and stores chosen
  bool ok() const { return !ms.empty(); }
  double Ms() const { return tuner_internal::Median(ms); }
  double XCopy() const { return tuner_internal::Median(x_copy); }
  double GBps() const { return tuner_internal::Median(gbps); }
  bool WithinBudget() const { return ok() && quantisation_rel <= kDefaultBudget; }
};

struct Device {
  FoundDevice found;
  std::unique_ptr<Runner> runner;
};

std::optional<Device> OpenDevice(const char* backend, bool cpu_type_only) {
  Discovered d = DiscoverDevices(backend);
  for (FoundDevice& f : d.devices) {
    if (cpu_type_only && f.identity.type.find("cpu") == std::string::npos) continue;
    Device device{f, nullptr};
    device.runner = f.open();
    return device;
  }
  return std::nullopt;
}

void Measure(Device& device, tuner_internal::DatasetCache& datasets, const CompareOptions& options, Row& row) {
  tuner_internal::RunnerExecutor executor(*device.runner, device.found.identity);
  TimingOptions timing;  // the tuner's defaults: 3 warm-up frames, 10 bursts of ~2 ms, up to 8 input sets
  const Measurement m = tuner_internal::MeasurementOf({&executor, &datasets, &device.found.identity, device.found.limits,
                                                      {row.variant.lang}, row.variant, {options.dataset}, timing});
  row.status = std::string(Name(m.status)) + (m.detail.empty() ? "" : ": " + m.detail);
  if (m.source_error.known) row.quantisation_rel = m.source_error.quantisation_rel;
  if (m.status != MeasureStatus::kOk && m.status != MeasureStatus::kTooImprecise) return;
  row.ms.push_back(m.timing.median_ms);
  row.gbps.push_back(m.gbps);
  if (m.x_copy > 0.0) row.x_copy.push_back(m.x_copy);
  if (auto* cpu = dynamic_cast<CpuRunner*>(device.runner.get()))
    if (const auto choice = cpu->ScheduleOf(row.variant.Key())) row.schedule = Describe(*choice);
}

std::vector<Row> RowsOf(const std::vector<std::string>& keys, const SkinnedMesh& mesh) {
  std::vector<Row> rows;
  for (const std::string& key : keys) {
    Row row;
    row.variant = ParseVariantKey(key);
    row.variant.influences = mesh.influences;
    row.variant.normals = NormalsFor(mesh.has_normals(), false);
    rows.push_back(row);
  }
  return rows;
}

std::string Fixed(double value, int digits) {
  std::ostringstream out;
  out.setf(std::ios::fixed);
  out.precision(digits);
  out << value;
  return out.str();
}

void PrintRows(const char* title, const std::vector<Row>& rows) {
  std::printf("\n%s\n%-78s %9s %7s %7s %10s  %s\n", title, "variant", "ms", "GB/s", "x copy", "quant/diag",
              "status (schedule)");
  for (const Row& r : rows) {
    std::printf("%-78s %9s %7s %7s %10.1e  %s%s\n", r.variant.Key().c_str(), r.ok() ? Fixed(r.Ms(), 3).c_str() : "-",
                r.ok() ? Fixed(r.GBps(), 1).c_str() : "-", r.x_copy.empty() ? "-" : Fixed(r.XCopy(), 2).c_str(),
                r.quantisation_rel, r.status.c_str(), r.schedule.empty() ? "" : (" (" + r.schedule + ")").c_str());
  }
}

// The ratios the cpu device is judged by (docs/PERFORMANCE.md "The CPU"), within this run.
void PrintRatios(const std::vector<Row>& cpu, const std::vector<Row>& pocl) {
  std::printf("\nratios (medians of this run):\n");
  const Row& f32 = cpu.front();
  if (!f32.ok() || f32.x_copy.empty()) {
    std::printf("  the f32 fast path was not measured: %s\n", f32.status.c_str());
    return;
  }
  std::printf("  f32 fast path / all-thread copy bandwidth of the same bytes: %.2f (goal >= 0.80)\n", 1.0 / f32.XCopy());
  const Row* best = nullptr;
  for (const Row& r : cpu)
    if (r.WithinBudget() && (!best || r.Ms() < best->Ms())) best = &r;
  if (best) {
    std::printf("  fastest cpu variant the default budget (%.0e) allows: %s, %.2fx faster than f32 (goal >= 1.4)\n",
                kDefaultBudget, best->variant.Key().c_str(), f32.Ms() / best->Ms());
  }
  const Row* pocl_best = nullptr;
  for (const Row& r : pocl)
    if (r.WithinBudget() && (!pocl_best || r.Ms() < pocl_best->Ms())) pocl_best = &r;
  if (pocl_best) {
    std::printf("  PoCL's best (%s): %.2fx the f32 fast path's time, %.2fx the fastest cpu variant's (goal <= 1.5)\n",
                pocl_best->variant.Key().c_str(), pocl_best->Ms() / f32.Ms(), best ? pocl_best->Ms() / best->Ms() : 0.0);
  } else if (!pocl.empty()) {
    std::printf("  PoCL: no variant measured\n");
  }
}

int Compare(const CompareOptions& options) {
  tuner_internal::DatasetCache datasets;
  const SkinnedMesh& mesh = datasets.Get(options.dataset).mesh();
  std::optional<Device> cpu = OpenDevice("cpu", false);
  if (!cpu) throw Error("no cpu device");
  std::optional<Device> pocl;
  if (!options.pocl.empty()) {
    pocl = OpenDevice("opencl", true);
    if (!pocl) std::printf("PoCL: no OpenCL CPU device here; its rows are skipped\n");
  }
  std::vector<std::string> cpu_keys(std::begin(kCpuVariants), std::end(kCpuVariants));
  std::vector<Row> cpu_rows = RowsOf(cpu_keys, mesh);
  std::vector<Row> pocl_rows = pocl ? RowsOf(options.pocl, mesh) : std::vector<Row>{};
  std::printf("dataset %s: %zu vertices, B = %d; cpu device: %s (%s kernels, %u threads); %d repeats\n",
              options.dataset.c_str(), mesh.vertex_count(), mesh.influences, cpu->found.identity.name.c_str(),
              CpuKernelIsa(), cpu->found.identity.compute_units, options.repeat);
  if (pocl) std::printf("PoCL device: %s\n", pocl->found.identity.Id().c_str());
  for (int r = 0; r < options.repeat; ++r) {
    for (Row& row : cpu_rows) Measure(*cpu, datasets, options, row);
    if (pocl)
      for (Row& row : pocl_rows) Measure(*pocl, datasets, options, row);
    std::fprintf(stderr, "skintune_bench_cpu: repeat %d of %d done\n", r + 1, options.repeat);
  }
  PrintRows("cpu device (the fast path's kernels), each timed as skintune tune does:", cpu_rows);
  if (pocl) PrintRows("PoCL (OpenCL on the same CPU), the same way:", pocl_rows);
  PrintRatios(cpu_rows, pocl_rows);
  return 0;
}

// The --pocl list: default (PoCL's set above), none, or opencl variant keys
// separated by commas. Throws Error naming what is wrong.
std::vector<std::string> PoclList(const std::string& value) {
  if (value == "none") return {};
  if (value == "default") return {std::begin(kPoclVariants), std::end(kPoclVariants)};
  if (value.empty()) throw Error("expected default, none or opencl variant keys separated by commas");
  std::vector<std::string> list;
  std::stringstream keys(value);
  for (std::string key; std::getline(keys, key, ',');) {
    const Variant parsed = ParseVariantKey(key);  // throws Error naming a bad token
    if (parsed.lang != Lang::kOpenCl) throw Error("'" + key + "' is not an opencl variant");
    list.push_back(key);
  }
  return list;
}

// A CLI11 check from a function that throws on a bad value: its message
// becomes the option's error ("--dataset: dataset '12q': ...").
CLI::Validator Throwing(const char* name, std::function<void(const std::string&)> check) {
  return CLI::Validator(
      [check](std::string& value) {
        try {
          check(value);
        } catch (const std::exception& e) {
          return std::string(e.what());
        }
        return std::string();
      },
      "", name);
}

// CLI11 2.1 reads integers with strtoll's base 0 ("010" is 8, "0x10" 16):
// --repeat is decimal digits, leading zeros dropped before CLI11 converts it.
const CLI::Validator kDecimal(
    [](std::string& value) {
      if (value.empty() || value.find_first_not_of("0123456789") != std::string::npos)
        return "Value " + value + " is not a whole number";
      value.erase(0, std::min(value.find_first_not_of('0'), value.size() - 1));
      return std::string();
    },
    "", "DECIMAL");

// This harness's options (CLI11); what it does not know is left in argv for
// Google Benchmark, and must be a --benchmark_* flag, which asks for the
// Google Benchmark suite instead of the comparison (true). --help prints the
// usage and exits 0; a bad option prints one line and exits 2.
bool ParseArguments(int& argc, char** argv, CompareOptions& options) {
  const auto fail = [](const std::string& message) {
    std::fprintf(stderr, "skintune_bench_cpu: error: %s\n", message.c_str());
    std::exit(2);
  };
  CLI::App app{"skintune_bench_cpu: the cpu device's formats and PoCL's variants at one dataset, measured as "
               "skintune tune does (the comparison), or with any --benchmark_* flag the Google Benchmark suite"};
  app.allow_extras();
  app.footer("Any --benchmark_* flag (e.g. --benchmark_filter=REGEX) runs the Google Benchmark suite instead of the "
             "comparison; --dataset, --repeat and --pocl apply to the comparison only.");
  // Given twice, the last one counts (as before CLI11).
  app.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
  app.add_option("--dataset", options.dataset, "the comparison's dataset key (<vertices>-b<influences>..., e.g. 100k-b2)")
      ->capture_default_str()
      ->check(Throwing("DATASET", [](const std::string& key) { ParseDatasetKey(key); }));
  app.add_option("--repeat", options.repeat, "times the list of variants is measured (medians are printed)")
      ->capture_default_str()
      ->check(CLI::Range(1, 100))
      ->transform(kDecimal);
  std::string pocl = "default";
  app.add_option("--pocl", pocl, "PoCL's variants: default, none or opencl variant keys separated by commas")
      ->capture_default_str()
      ->check(Throwing("POCL", [](const std::string& value) { PoclList(value); }));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) std::exit(app.exit(e));  // --help
    fail(e.what());
  }
  options.pocl = PoclList(pocl);
  // The extras, in order, after the program's name (their strings outlive argv's use).
  static std::vector<std::string> rest;
  rest = app.remaining();
  for (const std::string& r : rest)
    if (r.rfind("--benchmark_", 0) != 0)
      fail("unknown argument '" + r +
           "' (expected --dataset=KEY, --repeat=N, --pocl=default|none|KEY[,KEY...] or --benchmark_* flags; see --help)");
  argc = 1;
  for (std::string& r : rest) argv[argc++] = r.data();
  return !rest.empty();
}

}  // namespace
}  // namespace skintune::internal

int main(int argc, char** argv) {
  skintune::internal::CompareOptions options;
  const bool gbench = skintune::internal::ParseArguments(argc, argv, options);
  if (!gbench) {
    try {
      return skintune::internal::Compare(options);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "skintune_bench_cpu: error: %s\n", e.what());
      return 1;
    }
  }
  skintune::internal::RegisterAll();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
