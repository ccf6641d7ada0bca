// skintune: the paper experiment's results (report/paper_result.h) shaped like the
// paper's own figures, and rendered for people.
//
// Summarise derives, from one or more PaperResults, plain tables of numbers:
//   - Fig. 1: speedups over the serial CPU baseline on the Fig. 1 data set
//     (100k-b2) for the CPU paths, every paper kernel and every tuned winner;
//   - Table 1: OpenCL's speed relative to CUDA and to GLSL on the same chip
//     (t_cuda / t_opencl, t_glsl / t_opencl) per data set;
//   - GB/s against vertex count per device, with the copy bandwidth as the
//     ceiling (how close a kernel is to the physical limit);
//   - the effect of each variant axis (best time with each value).
// The paper's published figures (PaperReported) are placed beside the
// matching rows and cells; where the paper's figure is missing the renderers
// say "not on record".
//
// RenderHtml writes one self-contained HTML5 page (inline CSS and SVG, no
// script, no external reference of any kind: it is meant to be committed,
// mailed and opened offline); RenderMarkdown a summary for a terminal or a
// README.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "generator/variant.h"
#include "reference/candy_wrapper.h"
#include "tuner/tuned_device.h"
#include "tuner/measurement.h"
#include "report/paper_result.h"
#include "tuner/report.h"

namespace skintune::internal {

// What the summary keeps of one input result (for headings and the devices
// section).
struct SummaryResult {
  std::string label;            // "" for a single result, else "run 1", "run 2", ...
  std::string created;
  std::string command;
  bool quick = false;
  std::string figure1_dataset;
  std::string config;           // the tuning's config and strategy
  std::string strategy;
  std::vector<std::pair<std::string, std::string>> machine;  // the tuning report's machine fields, as text
  HostInfo host;
  PaperReported reported;
  std::vector<PaperKernel> paper_kernels;
  std::vector<CpuResult> cpu;
  std::vector<DatasetInfo> datasets;
  std::vector<std::string> skipped;  // backends not present, with the reason
};

// One device of one result.
struct SummaryDevice {
  std::size_t result = 0;            // index into PaperSummary::results
  DeviceIdentity identity;
  std::string id;                    // identity.Id(), what measurements name
  PaperApi api = PaperApi::kOpenCl;  // from the backend (opencl, cuda, gl -> GLSL)
  std::vector<Lang> langs;           // the languages measured on it, in Lang order
  // Pairs the APIs that run on the same hardware: "host CPU" for a device of
  // type cpu (PoCL, llvmpipe: both are the result's host), else the lowercased
  // device name up to its first '/' and trimmed (GL's renderer string appends
  // "/PCIe/SSE2" to the name OpenCL and CUDA report).
  std::string chip;
  std::string label;                 // for headings: "run N: " (several results), name, API, platform
  double copy_bandwidth_gbps = 0.0;  // the device's copy kernel; 0: not measured
};

// One kernel's outcome on one device and data set.
struct KernelOutcome {
  std::string name;             // the paper kernel's name, or "tuned"
  std::string label;            // "OpenCL (optimised)", "OpenCL tuned (opencl)", ...
  bool measured = false;        // paper kernel: a measurement exists; tuned: a status-ok one exists
  Variant variant;              // paper kernel: with the data set's B; tuned: the winner's
  MeasureStatus status = MeasureStatus::kOk;  // measured only; a time is shown for ok only
  std::string detail;           // the measurement's detail (why it failed)
  double median_ms = 0.0;       // status ok only: the kernel time
  double frame_ms = 0.0;        // status ok only: the frame time (0: not measured)
  double gbps = 0.0;
  double copy_fraction = 0.0;   // gbps / the device's copy bandwidth; 0 when that is unknown
  double x_copy = 0.0;          // median_ms / the same-size copy's, timed the same way; 0 when unknown
  bool partly_cached = false;   // the rotation covered less than 2 x the chip's last-level cache
  double max_relative_error = 0.0;  // against the gold of its quantised weights (status ok)
  SourceError source_error;         // against the unquantised source (docs/TUNING.md "Precision")

  bool Ok() const { return measured && status == MeasureStatus::kOk; }
};

// The paper kernels and the tuned winner of one device (one API) on one data set.
struct KernelResults {
  std::size_t device = 0;           // index into PaperSummary::devices
  PaperApi api = PaperApi::kOpenCl;
  std::string dataset;
  std::size_t vertices = 0;
  int influences = 0;
  // The result's paper kernels of this API (in the result's order), each the
  // measurement whose variant equals the kernel's with B = the data set's.
  std::vector<KernelOutcome> paper;
  // The fastest status-ok measurement of this device, API and data set, paper
  // kernels included (so it is never slower than a paper kernel).
  KernelOutcome tuned;
  std::size_t measurements = 0;     // of this device, API and data set
  std::size_t ok = 0;               // of which status ok
};

struct Figure1Row {
  std::string kind;                 // "serial", "fast", "paper", "tuned"
  std::string label;                // "CPU serial (1 thread)", "OpenCL (optimised)", "GLSL tuned (glsl-compute)"
  std::optional<std::size_t> device;  // none for the CPU rows
  PaperApi api = PaperApi::kOpenCl; // device rows
  std::string kernel;               // the paper kernel's name ("paper" rows)
  std::string variant;              // the measured variant's key (device rows with a measurement)
  std::optional<double> median_ms;  // a CPU timing or a status-ok measurement
  std::optional<double> speedup;    // serial median / median_ms; none without a baseline or a time
  std::string note;                 // why there is no time: "not measured", "verify_failed: ...", ...
  std::string series;               // the paper's Fig. 1 series of this row, "" if none
  std::optional<double> reported;   // the paper's figure for `series`, when on record
};

struct Figure1 {
  std::size_t result = 0;
  std::string dataset;
  std::size_t vertices = 0;         // 0 when the data set is not in the result
  int influences = 0;
  std::optional<double> serial_ms;  // the baseline; none: no serial CPU timing of the data set
  std::vector<Figure1Row> rows;     // the CPU rows, then per device its paper kernels and tuned winner
  // The paper's series with a figure on record but no row here (e.g.
  // "opencl-cpu" on a machine without a CPU OpenCL device), name -> figure.
  std::vector<std::pair<std::string, double>> unmatched;
};

struct Table1Cell {
  std::string dataset;
  std::optional<double> tuned;     // t_other / t_opencl of the tuned winners' kernel times
  std::optional<double> tuned_frame;  // the same of their frame times (Skin() back to back, host issue included)
  std::optional<double> paper;     // t_other / t_opencl of the paper kernels (opencl-optimised against
                                   // the other API's first paper kernel: cuda, glsl-vertex)
  std::optional<double> reported;  // the paper's figure for the data set (GPU chips only: the paper's
                                   // Table 1 is its GPU's)
};

// OpenCL against one other API on one chip of one result.
struct Table1Grid {
  PaperApi other = PaperApi::kCuda;  // kCuda, kGlsl or kVulkan
  std::size_t result = 0;
  std::string chip;
  std::size_t opencl_device = 0;     // indices into PaperSummary::devices
  std::size_t other_device = 0;
  std::vector<std::size_t> vertices;  // rows, ascending: the data sets' vertex counts
  std::vector<int> influences;        // columns, ascending
  std::vector<std::vector<std::optional<Table1Cell>>> cells;  // [row][column]; none: no such data set
};

struct GbpsPoint {
  std::string dataset;
  std::size_t vertices = 0;
  double gbps = 0.0;
  double median_ms = 0.0;
  double copy_fraction = 0.0;  // 0 when the copy bandwidth is unknown
  Variant variant;
  double x_copy = 0.0;         // the time / the same-size copy's; 0 when unknown
  double max_relative_error = 0.0;  // against the gold of its quantised weights
  SourceError source_error;         // against the unquantised source
  double low_ms = 0.0, high_ms = 0.0;  // the kernel time's 95% interval (0: not recorded)
  double frame_ms = 0.0;               // the frame time (0: not measured)
  std::size_t ties = 0;                // other candidates the tuner could not tell from it
  bool within_noise = false;           // every candidate of its key was within noise of it
};

// "4.2e-07 of the diagonal (unorm8 costs 1.6e-04)", or "not recorded": the
// error against the unquantised source, as both reports show it next to the
// error against the quantised gold.
std::string FormatSourceError(const SourceError& e);
// An error as both reports show it: "2.5e-07".
std::string FormatError(double error);

// The fastest status-ok variant of one language and B, per data set.
struct GbpsSeries {
  Lang lang = Lang::kOpenCl;
  int influences = 0;
  std::vector<GbpsPoint> points;  // ascending vertex count
};

struct GbpsChart {
  std::size_t device = 0;
  double copy_bandwidth_gbps = 0.0;
  std::vector<GbpsSeries> series;  // by language, then B
};

struct AxisValue {
  std::string value;               // "soa-split", "u8", "2 contiguous", "256", ...
  double best_ms = 0.0;            // the best median among status-ok measurements with this value
  double ratio = 1.0;              // best_ms / the best of all
  std::size_t measurements = 0;    // status-ok measurements with this value
};

struct AxisEffect {
  std::string axis;                // "layout", "position", ..., "vertices_per_item+assignment", "wg_size"
  std::vector<AxisValue> values;   // in the axis's natural order
};

// How much each axis value costs on one device, language and data set.
struct AxisChart {
  std::size_t device = 0;
  Lang lang = Lang::kOpenCl;
  std::string dataset;             // the largest measured (vertices x influences; ties: most ok measurements)
  double best_ms = 0.0;
  std::size_t measurements = 0;    // status-ok measurements on the data set
  std::vector<AxisEffect> axes;
};

// One row of the tuner's winners on a device (tuner/report.h BudgetWinners:
// every data set, language and row, the formats and morph targets a row of
// their own), with what it costs against its plain row's winner: the same
// device, language, B, vertex count and scene with f32 normals, no morph
// targets, linear blending and the host's palettes (an animated scene's row
// against its crowd's with uploaded palettes: what the palette kernel costs).
struct RowWinner {
  std::size_t device = 0;
  Lang lang = Lang::kOpenCl;
  std::string dataset;
  std::string row;      // runtime/winners_db.h RowName, " dq" added for dual quaternions
  std::string variant;  // its key
  double median_ms = 0.0, low_ms = 0.0, high_ms = 0.0;
  double gbps = 0.0, x_copy = 0.0;
  double position_rel = 0.0, normal_abs = 0.0;  // against the unquantised source (SourceError)
  bool plain = true;      // f32 normals, no morph targets, linear blending, the host's palettes
  double vs_plain = 0.0;  // median_ms / the plain row's winner's; 0: plain, or no plain row measured
  // Palettes made on the device: the palette kernel's form, its own time and
  // a baked form's clips ("baked240: palette kernel 0.0040 ms; 1 clip, 2.34 MB,
  // largest error 1.3e-04"); empty for the host's palettes.
  std::string animation;
};

struct PaperSummary {
  std::vector<SummaryResult> results;
  std::vector<SummaryDevice> devices;
  std::vector<KernelResults> kernels;      // per device x data set of its result
  std::vector<Figure1> figure1;            // one per result
  std::vector<Table1Grid> opencl_vs_cuda;  // per chip with both APIs measured
  std::vector<Table1Grid> opencl_vs_glsl;
  std::vector<Table1Grid> opencl_vs_vulkan;
  std::vector<GbpsChart> gbps;             // one per device
  std::vector<AxisChart> axes;             // per device x language with a status-ok measurement
  std::vector<RowWinner> rows;             // per device, every row's winner within the budget
  // Linear blending against dual quaternions on a twisting joint, every 15
  // degrees from 0 to 180 (reference/candy_wrapper.h): the algorithms' own
  // results, the same in every report with results (none without).
  std::vector<CandyWrapperPoint> candy_wrapper;

  // The kernel results of a device on a data set, or null.
  const KernelResults* Kernels(std::size_t device, const std::string& dataset) const;
};

PaperSummary Summarise(const std::vector<PaperResult>& results);

// A plain tuning report as a PaperResult with no CPU timings and no paper
// kernels (the figures then say there is no serial baseline). The Fig. 1 data
// set is 100k-b2 when the report has it, else the one measured on the most
// devices (the first of those).
PaperResult PaperResultFromReport(const TuningReport& report);

// One self-contained HTML5 page: sections fig1, table1-opencl-vs-cuda,
// table1-opencl-vs-glsl, gbps (charts gbps-0, gbps-1, ...), axes (charts
// axes-0, ...), candy-wrapper (chart candy-wrapper-chart) and devices; every chart an <svg class="chart" role="img">
// with a <title>. Every text from the input is escaped.
std::string RenderHtml(const PaperSummary& summary);
// The Fig. 1 and Table 1 tables, per device its tuned winners (ms, GB/s,
// fraction of copy), and the devices.
std::string RenderMarkdown(const PaperSummary& summary);
std::string Figure1Markdown(const PaperSummary& summary);
std::string Table1Markdown(const PaperSummary& summary);

// Number formats of the reports: 3 significant digits without an exponent,
// whole numbers with all their digits ("0.0234", "7.85", "123", "1234").
std::string FormatSignificant(double value, int digits = 3);
std::string FormatMs(double ms);           // "0.0234 ms"
std::string FormatSpeedup(double factor);  // "12.3×"
std::string FormatGbps(double gbps);       // "2458 GB/s", "56.2 GB/s"

}  // namespace skintune::internal
