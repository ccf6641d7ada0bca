// skintune: the seed paper's experiment on the present machine (`skintune paper`).
//
// RunPaper repeats the paper's measurements on every device found: one tuning
// run over the paper's data sets (configs/paper.json) with the paper's kernels
// measured first on every device and language, each device's copy bandwidth,
// then the CPU baselines (cpu_timing.h) and the host's copy bandwidth. What it
// finds is a PaperResult (report/paper_result.h), which report/ renders.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "generator/variant.h"
#include "report/paper_result.h"

namespace skintune::internal {

struct PaperOptions {
  bool quick = false;                 // 25k and 100k only, a smaller search
  std::vector<std::string> datasets;  // override the data-set list (keys); empty: the paper's (or quick) list
  std::string device_pattern;         // as TuneOptions
  bool software_rasterizers = false;  // as TuneOptions
  std::vector<Lang> languages;        // as TuneOptions
  std::size_t budget = 0;             // evaluations of the search per device x language x data set
                                      // (0: the config's, or the quick default)
  bool skip_cpu = false;              // no serial/fast CPU timing (for tests of the device part)
  std::string cache_path;             // the tuner's resumable cache
  std::string worker_executable;
  std::string command;
  // As TuneOptions::progress; the CPU steps come with total 0.
  std::function<void(std::size_t done, std::size_t total, const std::string& what)> progress;
};

// Throws Error for bad options (unknown data-set key, no device matching).
PaperResult RunPaper(const PaperOptions& options);

}  // namespace skintune::internal
