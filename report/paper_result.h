// skintune: the result of the seed paper's experiment, as report/ renders it.
//
// "GPGPU Acceleration for Skeletal Animation — Comparing OpenCL with CUDA and
// GLSL" measured a serial CPU baseline against GLSL, CUDA and OpenCL kernels
// (its Fig. 1: speedups on 100k vertices, 2 influences, 77 bones) and
// OpenCL's speed relative to CUDA and to GLSL on 16 data sets (its Table 1:
// 25k/100k/400k/1600k vertices x 1..4 influences). The experiment that repeats
// it on the present machine is tools/experiments/paper.h (RunPaper); what it
// finds is a PaperResult:
//   - the CPU: the paper's serial baseline (SkinSerial, one thread) and the
//     fast multi-core path (FastSkinner), both checked against the gold;
//   - every device and language: the paper's own kernels, which are points of
//     skintune's variant space (PaperKernels(), configs/paper.json
//     "paper_kernels"), and the tuned winner of a search over the space;
//   - every device's copy bandwidth (a plain copy kernel) and the host's, so
//     every GB/s figure can be read as a fraction of the physical limit;
//   - the figures the paper published (PaperReported), to stand beside them.
// The result is versioned JSON (configs/paper-result.schema.json);
// report/paper_report.h turns one or more results into the Fig. 1- and
// Table 1-shaped tables, an HTML report and a Markdown summary.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "generator/variant.h"
#include "tuner/report.h"

namespace skintune::internal {

inline constexpr const char* kPaperResultSchemaVersion = "1.0.0";
inline constexpr const char* kPaperResultKind = "skintune-paper-result";

// The paper compares three APIs; GLSL covers both GL languages (the paper's
// form is the vertex shader, the tuned winner may be a compute shader).
// Vulkan (compute, SPIR-V) is skintune's fourth API: Table 1 compares it
// with OpenCL on the same chip too, with no figure of the paper's.
// The APIs are the language table's (generator/languages.h: a language's
// `api` column), in its order: each enumerator is the API of a language, so
// which API a language counts under is the table's word, not the report's.
enum class PaperApi {
  kOpenCl = ApiIndex(Lang::kOpenCl),
  kCuda = ApiIndex(Lang::kCuda),
  kGlsl = ApiIndex(Lang::kGlslCompute),  // and glsl-vertex
  kVulkan = ApiIndex(Lang::kVulkan),
  kCpu = ApiIndex(Lang::kCpu),
};
inline constexpr int kPaperApiCount = static_cast<int>(kApiCount);
static_assert(kPaperApiCount == static_cast<int>(PaperApi::kCpu) + 1,
              "a new API in generator/languages.h: name it in PaperApi (last) and give it a colour (ApiColour)");
const char* Name(PaperApi);                // the table's api: "opencl", "cuda", "glsl", "vulkan", "cpu"
const char* DisplayName(PaperApi);         // its api_title: "OpenCL", "CUDA", "GLSL", "Vulkan", "CPU"
constexpr PaperApi ApiOf(Lang lang) { return static_cast<PaperApi>(ApiIndex(lang)); }

// One of the paper's kernels as a point of our space. `variant` has the
// influences of the Fig. 1 data set; the experiment sets B per data set.
struct PaperKernel {
  std::string name;         // "opencl-unoptimised", "opencl-optimised", "cuda", "glsl-vertex"
  std::string label;        // for tables: "OpenCL (not optimised)", ...
  std::string section;      // where the paper describes it, e.g. "section 5.1"
  std::string description;  // what of the paper's text the axis values encode
  Variant variant;
};

// The kernels of configs/paper.json "paper_kernels". Throws Error naming the
// element for a malformed list (an unknown key token, a missing field).
std::vector<PaperKernel> PaperKernelsFromJson(const nlohmann::json& list, const std::string& context);
// The built-in list (from the embedded configs/paper.json).
std::vector<PaperKernel> PaperKernels();

// The figures the paper published, from configs/paper.json "reported". Every
// figure is optional: a missing one is shown as "not on record".
struct PaperReported {
  std::string source;                              // citation, or why figures are missing
  std::map<std::string, double> figure1;           // series -> speedup over the serial CPU
                                                   // ("glsl", "cuda", "opencl-unoptimised",
                                                   //  "opencl-optimised", "opencl-cpu")
  std::map<std::string, double> opencl_vs_cuda;    // dataset key -> t_cuda / t_opencl
  std::map<std::string, double> opencl_vs_glsl;    // dataset key -> t_glsl / t_opencl
};
PaperReported PaperReportedFromJson(const nlohmann::json& in, const std::string& context);
// The paper's Table 1 figures of OpenCL against `other` (none for Vulkan).
const std::map<std::string, double>& ReportedAgainst(const PaperReported& reported, PaperApi other);
PaperReported BuiltInPaperReported();

// A CPU implementation timed on one data set: the median of `repetitions`
// frames, each on the next of `input_sets` copies of the mesh and a different
// palette, after a warm-up; checked against the gold.
struct CpuTiming {
  double median_ms = 0.0;
  double min_ms = 0.0;
  double max_ms = 0.0;
  int repetitions = 0;
  int input_sets = 0;
  unsigned threads = 1;
  double bytes_per_frame = 0.0;     // the implementation's inputs read + outputs written
  double gbps = 0.0;
  double max_relative_error = 0.0;  // against the gold
};

struct CpuResult {
  std::string dataset;
  CpuTiming serial;  // the paper's serial baseline (the denominator of every speedup)
  CpuTiming fast;    // FastSkinner on every core
};

struct HostInfo {
  std::string cpu_model;
  unsigned threads = 0;
  double copy_bandwidth_gbps = 0.0;  // multi-threaded copy, bytes read + written
};

struct PaperResult {
  std::string created;      // UTC ISO 8601, when the run finished
  bool quick = false;       // the reduced data-set list
  std::string command;      // the command line that produced it
  std::string figure1_dataset = "100k-b2";
  HostInfo host;
  PaperReported reported;
  std::vector<PaperKernel> paper_kernels;
  std::vector<CpuResult> cpu;   // one per data set, in tuning.datasets order
  TuningReport tuning;          // devices, copy bandwidths, every measurement (paper kernels included)
                                // but the invalid points of the space (an invalid paper kernel stays)
};

nlohmann::json PaperResultToJson(const PaperResult& result);
// Throws Error("<context>: <element>: ...") for a malformed result.
PaperResult PaperResultFromJson(const nlohmann::json& json, const std::string& context);

// The data sets of the full experiment (the paper's 16) and of --quick.
std::vector<std::string> PaperDatasets(bool quick);

}  // namespace skintune::internal
