// skintune run: the main job on the built-in default config. A quick check of
// the CPU implementations against the float64 gold (one line), then the tuning
// job of `skintune tune` on every device found (progress bar with ETA on
// stderr), writing report.json, report.t4.json, winners-db.json and
// report.html into results/ (or --out) together, then per device the winner
// of each language and dataset (time, GB/s, time over a same-size copy,
// verification error), the HTML report's path and the `skintune emit --db`
// command that takes the kernels into another build.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>

#include "base/error.h"
#include "reference/skinning.h"
#include "model/synthetic.h"
#include "tools/commands.h"
#include "tools/progress.h"
#include "tools/tune_job.h"

namespace skintune::internal::tools {

namespace {

namespace fs = std::filesystem;

struct RunOptions {
  TuneJobOptions job;
  std::string cpu_dataset = "default";  // the CPU check's dataset; "none" skips it
};

template <typename F>
double MedianMs(int repetitions, F&& f) {
  std::vector<double> ms;
  for (int r = 0; r < repetitions; ++r) {
    const auto start = std::chrono::steady_clock::now();
    f();
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  }
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

// One line: the serial loop and the fast path against the float64 gold.
void CheckCpu(const std::string& key) {
  const SkinnedAsset asset = GenerateDataset(ParseDatasetKey(key));
  const SkinnedMesh& mesh = asset.mesh;
  const std::vector<glm::mat4> palette = asset.PaletteAt(0, 0.5);
  const std::size_t n = mesh.vertex_count();
  std::vector<glm::vec3> serial(n), fast(n);
  const GoldResult gold = SkinGold(mesh, palette);
  FastSkinner skinner(mesh);
  const double serial_ms = MedianMs(3, [&] { SkinSerial(mesh, palette, serial); });
  const double fast_ms = MedianMs(3, [&] { skinner.Run(palette, fast); });
  const double worst = std::max(CompareToGold(gold.positions, serial).max_relative,
                                CompareToGold(gold.positions, fast).max_relative);
  constexpr double kTolerance = 1e-5;
  char line[256];
  std::snprintf(line, sizeof line, " (%s: serial %.2f ms, fast %.2f ms on %d threads; max relative error %.1e)",
                asset.source.c_str(), serial_ms, fast_ms, skinner.threads(), worst);
  if (!(worst <= kTolerance)) throw Error("CPU implementations disagree with the float64 gold beyond 1e-5" + std::string(line));
  std::cout << "CPU reference: serial and fast agree with the float64 gold within 1e-5" << line << "\n";
}

std::string ShellQuoted(const std::string& text) {
  std::string quoted = "'";
  for (const char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

std::string Fixed(double value, int decimals) {
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", decimals, value);
  return text;
}

// The winner's time over a copy of the same bytes timed the same way
// (Measurement::x_copy, docs/TUNING.md "Timing"), "-" when there is none.
std::string TimesCopy(const Winner& w) { return w.x_copy > 0.0 ? Fixed(w.x_copy, 2) : "-"; }

// "3.79 [3.76, 3.81]": the kernel time's median and 95% interval, us.
std::string KernelInterval(const Winner& w) {
  std::string text = Fixed(w.median_ms * 1e3, 2);
  if (w.high_ms > w.low_ms) text += " [" + Fixed(w.low_ms * 1e3, 2) + ", " + Fixed(w.high_ms * 1e3, 2) + "]";
  return text;
}

// The lowest and highest positive value of `field` among the device's
// measurements; {0, 0} where none is.
std::pair<double, double> RangeOf(const TuningReport& report, const std::string& device_id,
                                  double (*field)(const Measurement&)) {
  double low = 0.0, high = 0.0;
  for (const Measurement& m : report.measurements) {
    const double v = m.device_id == device_id ? field(m) : 0.0;
    if (v <= 0.0) continue;
    low = low > 0.0 ? std::min(low, v) : v;
    high = std::max(high, v);
  }
  return {low, high};
}

// The GPU's SM clock around the device's kernel-time samples, where it was
// read (timing.sm_clock_mhz: NVIDIA's GPUs, docs/TUNING.md "Kernel time"),
// and its contexts' launch start, where probed (timing.launch_start_ms: a
// GPU's); nothing elsewhere.
// Where the run table's winner was picked among its ties (tuner/statistics.h Choice).
const char* ChoiceText(Choice choice) {
  switch (choice) {
    case Choice::kContenders: return "those within the margin";
    case Choice::kTieSet: return "them";
    case Choice::kTieSetUnseparated: return "those the race did not separate from the fastest";
  }
  return "?";
}

void PrintSmClocksAndLaunchStart(const TuningReport& report, const std::string& device_id) {
  const auto [low, high] = RangeOf(report, device_id, [](const Measurement& m) { return m.timing.sm_clock_mhz; });
  if (high > 0.0)
    std::cout << "SM clock around the samples: " << Fixed(low, 0) << (high > low ? "-" + Fixed(high, 0) : "")
              << " MHz\n";
  const auto [first, last] = RangeOf(report, device_id, [](const Measurement& m) { return m.timing.launch_start_ms; });
  if (last > 0.0)
    std::cout << "launch start: " << Fixed(first * 1e3, 2) << (last > first ? "-" + Fixed(last * 1e3, 2) : "")
              << " us (a 4 KiB copy after the flush, timed as the kernels are: each API's device cost of a timed "
                 "launch; the kernel time less it compares one kernel across APIs)\n";
}

// The line under a device's table naming its classes over the budget that
// are faster than their row's winner (nothing when there are none).
void PrintFasterOverBudget(const std::vector<FasterOverBudget>& faster, const std::string& device_id,
                           double max_error) {
  std::vector<std::string> over;
  for (const FasterOverBudget& f : faster)
    if (f.over.device_id == device_id) over.push_back(Describe(f));
  if (over.empty()) return;
  std::cout << over.size() << " faster precision class(es) over the budget max_error " << Sci(max_error)
            << " are in the winners database (skintune emit --db --max-error): ";
  for (std::size_t i = 0; i < over.size(); ++i) std::cout << (i ? "; " : "") << over[i];
  std::cout << "\n";
}

// Per device (in report order): its winners within the budget, one per
// language, B and vertex count, with what they cost against the unquantised
// source (docs/TUNING.md "Precision"); the classes over the budget that are
// faster than a row's winner beyond the tie margin are named below each
// table (the winners database keeps them).
void PrintDeviceWinners(const TuningReport& report) {
  const std::vector<Winner> all = ComputeWinners(report);
  const std::vector<Winner> winners = BudgetWinners(all, report.tie_margin);
  const std::vector<FasterOverBudget> faster = FasterClassesOverBudget(all, report.tie_margin);
  for (const DeviceIdentity& d : report.devices) {
    std::vector<std::vector<std::string>> rows = {{"lang", "B", "vertices", "dataset", "variant", "kernel us [95%]",
                                                   "frame us", "GB/s", "x copy", "ties", "err/diag", "format costs"}};
    std::vector<std::string> noisy;
    for (const Winner& w : winners) {
      if (w.device_id != d.Id()) continue;
      const SourceError& e = w.source_error;
      rows.push_back({Name(w.lang), std::to_string(w.influences), VertexCountName(w.vertices), w.dataset,
                      w.variant.Key(), KernelInterval(w), w.frame_ms > 0.0 ? Fixed(w.frame_ms * 1e3, 2) : "-",
                      Fixed(w.gbps, 1), TimesCopy(w), std::to_string(w.tie_set.size() > 0 ? w.tie_set.size() - 1 : 0),
                      e.known ? Sci(e.position_rel) : "-", e.known ? Sci(e.quantisation_rel) : "-"});
      if (w.within_noise) noisy.push_back(std::string(Name(w.lang)) + " " + w.dataset);
    }
    std::cout << "\n== " << d.backend << ": " << d.name << " (" << d.platform << ")\n";
    if (rows.size() == 1) {
      std::cout << "no variant passed verification within the budget on this device\n";
    } else {
      std::cout << FormatTable(rows, {1, 2, 5, 6, 7, 8, 9, 10, 11});
      std::cout << "kernel: the kernel's own device time from a flushed cache, median and 95% interval; frame: Skin() "
                   "issued back to back; ties: other candidates within the tie margin "
                << Fixed(report.TieMarginOf(d.Id()) * 100.0, 1) << "% plus the spread between processes "
                << Fixed(report.TieSpreadOf(d.Id()) * 100.0, 1) << "% (the winner among "
                << ChoiceText(report.ChoiceOf(d.Id()))
                << ": fewest bytes, then lower error, then the palette storage with the fewest limits)\n";
      PrintSmClocksAndLaunchStart(report, d.Id());
      if (!noisy.empty()) {
        std::cout << "every candidate within noise of the winner in: ";
        for (std::size_t i = 0; i < noisy.size(); ++i) std::cout << (i ? ", " : "") << noisy[i];
        std::cout << "\n";
      }
    }
    PrintFasterOverBudget(faster, d.Id(), report.max_error);
  }
  for (const std::string& s : report.skipped) std::cout << "not tuned: " << s << "\n";
  const std::string counts = MeasurementCounts(report);
  std::cout << "\nmeasurements: " << (counts.empty() ? "none" : counts) << "\n";
}

int RunMain(const RunOptions& o) {
  if (o.cpu_dataset != "none") CheckCpu(o.cpu_dataset);
  const TuneJobResult result = RunTuneJob(o.job);
  const fs::path db = result.out / "winners-db.json";
  PrintDeviceWinners(result.report);
  std::cout << "report: " << fs::absolute(result.out / "report.html").string() << "\n";
  std::cout << "files: ";
  for (std::size_t i = 0; i < result.written.size(); ++i) std::cout << (i ? ", " : "") << result.written[i].string();
  std::cout << " (measurement cache " << result.cache.string() << ": the next run reuses it)\n";
  std::cout << "take the winning kernels into another build:\n  skintune emit --db " << ShellQuoted(db.string())
            << " --device '' --out skintune-kernels\n";
  return 0;
}

}  // namespace

Command RegisterRun(CLI::App& app) {
  auto o = std::make_shared<RunOptions>();
  o->job.command = "run";
  o->job.html = true;
  auto* sub = app.add_subcommand(
      "run", "the main job: tune every device found with the default config, write the report (HTML too) and the "
             "winners database, print the winners");
  AddTuneJobOptions(*sub, o->job);
  sub->add_option("--cpu-check", o->cpu_dataset,
                  "dataset key of the CPU reference check before tuning, or none (default: 100k-b2, the paper's "
                  "Fig. 1 data set)");
  return {sub, [o] { return RunMain(*o); }};
}

}  // namespace skintune::internal::tools
