// The paper report: Summarise's arithmetic (speedups, Table 1 ratios,
// fractions of copy, axis effects), pairing APIs by chip, missing backends and
// failed kernels, the paper's figures beside the rows, and the HTML page's
// promises (escaped input, no script, no external reference, every id).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tests/report/sample_paper_result.h"
#include "tests/tuner/sample_report.h"
#include "report/paper_report.h"

namespace skintune::internal {
namespace {

using testing::PaperMeasurement;
using testing::SampleCpu;
using testing::SamplePaperKernels;
using testing::SamplePaperResult;

const char* kTunedOpenCl = "opencl.b2.padded.soa-split.float4.u8.unorm8.mat3x4.local.matrix.v1c.wg256.nonormals";
const char* kTunedCuda = "cuda.b2.padded.soa-split.float4.u8.unorm8.mat3x4.local.matrix.v1c.wg256.nonormals";

// One data set, OpenCL and CUDA on one GPU, round numbers:
//   serial 10 ms, fast 2 ms; OpenCL: unoptimised 2 ms, optimised 0.5 ms,
//   tuned 0.25 ms (and a "faster" failed one); CUDA: paper 0.6 ms, tuned 0.2 ms.
PaperResult Tiny() {
  PaperResult r;
  r.created = "2025-06-01T00:00:00Z";
  r.command = "skintune paper --tiny";
  r.host = {"Test CPU", 8, 50.0};
  r.paper_kernels = SamplePaperKernels();
  const DatasetInfo d{"100k-b2", 100000, 2, 77};
  r.tuning.datasets = {d};
  const DeviceIdentity gpu = testing::SampleOpenClGpu(), cuda = testing::SampleCudaGpu();
  r.tuning.devices = {gpu, cuda};
  r.tuning.copy_bandwidth_gbps = {{gpu.Id(), 1000.0}};
  std::vector<Measurement>& m = r.tuning.measurements;
  m.push_back(PaperMeasurement(gpu, d, r.paper_kernels[0].variant, 2.0));
  m.push_back(PaperMeasurement(gpu, d, r.paper_kernels[1].variant, 0.5));
  m.push_back(PaperMeasurement(gpu, d, ParseVariantKey(kTunedOpenCl), 0.25));
  Measurement failed = PaperMeasurement(gpu, d, ParseVariantKey("opencl.b2.soa.u16"), 0.01, MeasureStatus::kVerifyFailed, "off");
  failed.timing.median_ms = 0.01;  // a failure's time never counts, however small
  m.push_back(failed);
  m.push_back(PaperMeasurement(cuda, d, r.paper_kernels[2].variant, 0.6));
  m.push_back(PaperMeasurement(cuda, d, ParseVariantKey(kTunedCuda), 0.2));
  r.cpu = {SampleCpu(d, 10.0, 2.0, 8)};
  return r;
}

const Figure1Row* Row(const Figure1& f, const std::string& kind, const std::string& kernel,
                      std::optional<std::size_t> device) {
  for (const Figure1Row& row : f.rows) {
    if (row.kind == kind && row.kernel == kernel && row.device == device) return &row;
  }
  return nullptr;
}

std::size_t DeviceIndex(const PaperSummary& s, const DeviceIdentity& d, std::size_t result = 0) {
  for (std::size_t i = 0; i < s.devices.size(); ++i) {
    if (s.devices[i].id == d.Id() && s.devices[i].result == result) return i;
  }
  ADD_FAILURE() << "no device " << d.Id();
  return 0;
}

// What an offline, script-free page must not contain; each hit is named.
std::vector<std::string> ExternalReferences(const std::string& html) {
  std::vector<std::string> hits;
  for (const char* bad : {"<script", "http:", "https:", "//", "@import", "<link", "url(", "src=", "<iframe", "<object",
                          "<embed", "<img", "<base", "<meta http-equiv", "ftp:", "data:"}) {
    if (html.find(bad) != std::string::npos) hits.push_back(bad);
  }
  const std::regex href("href=\"([^\"]*)\"");
  for (auto it = std::sregex_iterator(html.begin(), html.end(), href); it != std::sregex_iterator(); ++it) {
    if ((*it)[1].str().rfind('#', 0) != 0) hits.push_back("href=\"" + (*it)[1].str() + "\"");
  }
  return hits;
}

bool HasId(const std::string& html, const std::string& id) {
  return html.find("id=\"" + id + "\"") != std::string::npos;
}

// The text of the section with `id` (up to its </section>).
std::string Section(const std::string& html, const std::string& id) {
  const std::size_t start = html.find("<section id=\"" + id + "\"");
  if (start == std::string::npos) return "";
  return html.substr(start, html.find("</section>", start) - start);
}

TEST(PaperSummary, SpeedupsAreTheSerialMedianOverEachImplementationsMedian) {
  const PaperResult r = Tiny();
  const PaperSummary s = Summarise({r});
  ASSERT_EQ(s.figure1.size(), 1u);
  const Figure1& f = s.figure1[0];
  EXPECT_EQ(f.dataset, "100k-b2");
  ASSERT_TRUE(f.serial_ms);
  EXPECT_DOUBLE_EQ(*f.serial_ms, 10.0);
  const std::size_t gpu = DeviceIndex(s, testing::SampleOpenClGpu()), cuda = DeviceIndex(s, testing::SampleCudaGpu());
  const Figure1Row* serial = Row(f, "serial", "", std::nullopt);
  const Figure1Row* fast = Row(f, "fast", "", std::nullopt);
  ASSERT_TRUE(serial && fast);
  EXPECT_DOUBLE_EQ(*serial->speedup, 1.0);
  EXPECT_DOUBLE_EQ(*fast->speedup, 5.0);
  EXPECT_NE(fast->label.find("8 threads"), std::string::npos) << fast->label;
  EXPECT_DOUBLE_EQ(*Row(f, "paper", "opencl-unoptimised", gpu)->speedup, 5.0);
  EXPECT_DOUBLE_EQ(*Row(f, "paper", "opencl-optimised", gpu)->speedup, 20.0);
  EXPECT_DOUBLE_EQ(*Row(f, "tuned", "", gpu)->speedup, 40.0);
  EXPECT_DOUBLE_EQ(*Row(f, "paper", "cuda", cuda)->speedup, 10.0 / 0.6);
  EXPECT_DOUBLE_EQ(*Row(f, "tuned", "", cuda)->speedup, 50.0);
  EXPECT_EQ(Row(f, "tuned", "", gpu)->label, "OpenCL tuned (opencl)");
  // The rows come in order: CPU, then each device's paper kernels and its tuned winner.
  ASSERT_EQ(f.rows.size(), 2u + 3u + 2u);
  EXPECT_EQ(f.rows[0].kind, "serial");
  EXPECT_EQ(f.rows[4].kind, "tuned");
  EXPECT_EQ(f.rows[4].device, gpu);
}

TEST(PaperSummary, TunedWinnerIsTheFastestOkMeasurementWithPaperKernelsAmongTheCandidates) {
  PaperResult r = Tiny();
  PaperSummary s = Summarise({r});
  const std::size_t gpu = DeviceIndex(s, testing::SampleOpenClGpu());
  const KernelResults* k = s.Kernels(gpu, "100k-b2");
  ASSERT_NE(k, nullptr);
  EXPECT_EQ(k->tuned.variant.Key(), ParseVariantKey(kTunedOpenCl).Key());  // not the failed 0.01 ms one
  EXPECT_DOUBLE_EQ(k->tuned.median_ms, 0.25);
  EXPECT_EQ(k->measurements, 4u);
  EXPECT_EQ(k->ok, 3u);
  // When the paper's kernel is the fastest, it is the tuned winner.
  for (Measurement& m : r.tuning.measurements) {
    if (m.variant == ParseVariantKey(kTunedOpenCl)) m.timing.median_ms = 0.9;
  }
  s = Summarise({r});
  k = s.Kernels(gpu, "100k-b2");
  EXPECT_EQ(k->tuned.variant, r.paper_kernels[1].variant);
  EXPECT_DOUBLE_EQ(k->tuned.median_ms, k->paper[1].median_ms);
}

TEST(PaperSummary, PaperKernelsAreLookedUpWithTheDataSetsInfluences) {
  const PaperResult r = SamplePaperResult();
  const PaperSummary s = Summarise({r});
  const std::size_t gpu = DeviceIndex(s, testing::SampleOpenClGpu());
  const KernelResults* b1 = s.Kernels(gpu, "25k-b1");
  ASSERT_NE(b1, nullptr);
  ASSERT_EQ(b1->paper.size(), 2u);  // the OpenCL kernels only
  EXPECT_EQ(b1->paper[1].name, "opencl-optimised");
  EXPECT_TRUE(b1->paper[1].Ok());
  EXPECT_EQ(b1->paper[1].variant.influences, 1);
  // Every tuned winner of the sample is faster than every paper kernel.
  for (const KernelResults& k : s.kernels) {
    for (const KernelOutcome& p : k.paper) {
      if (p.Ok()) {
        EXPECT_LT(k.tuned.median_ms, p.median_ms) << k.dataset << " " << p.name;
      }
    }
  }
}

TEST(PaperSummary, Table1RatiosAreTheOtherApisTimeOverOpenClsForTunedAndPaperKernels) {
  const PaperSummary s = Summarise({Tiny()});
  ASSERT_EQ(s.opencl_vs_cuda.size(), 1u);
  const Table1Grid& g = s.opencl_vs_cuda[0];
  EXPECT_EQ(g.chip, "nvidia h100 80gb hbm3");
  ASSERT_EQ(g.vertices, std::vector<std::size_t>{100000});
  ASSERT_EQ(g.influences, std::vector<int>{2});
  ASSERT_TRUE(g.cells[0][0]);
  const Table1Cell& cell = *g.cells[0][0];
  EXPECT_EQ(cell.dataset, "100k-b2");
  EXPECT_DOUBLE_EQ(*cell.tuned, 0.2 / 0.25);
  EXPECT_DOUBLE_EQ(*cell.paper, 0.6 / 0.5);
  EXPECT_FALSE(cell.reported);
  EXPECT_TRUE(s.opencl_vs_glsl.empty());
}

TEST(PaperSummary, Table1GridHasRowsPerVertexCountAndColumnsPerBOfTheDataSetsPresent) {
  const PaperSummary s = Summarise({SamplePaperResult()});
  ASSERT_EQ(s.opencl_vs_cuda.size(), 1u);
  const Table1Grid& g = s.opencl_vs_cuda[0];
  EXPECT_EQ(g.vertices, (std::vector<std::size_t>{25000, 100000, 400000}));
  EXPECT_EQ(g.influences, (std::vector<int>{1, 2}));
  EXPECT_EQ(g.cells[1][1]->dataset, "100k-b2");
  EXPECT_EQ(g.cells[2][0]->dataset, "400k-b1");
}

TEST(PaperSummary, PairsApisOnTheSameChipByNameUpToTheFirstSlashAndCpuDevicesAsTheHostCpu) {
  const PaperSummary s = Summarise({SamplePaperResult()});
  EXPECT_EQ(s.devices[DeviceIndex(s, testing::SampleOpenClGpu())].chip, "nvidia h100 80gb hbm3");
  EXPECT_EQ(s.devices[DeviceIndex(s, testing::SampleCudaGpu())].chip, "nvidia h100 80gb hbm3");
  EXPECT_EQ(s.devices[DeviceIndex(s, testing::SampleGlGpu())].chip, "nvidia h100 80gb hbm3");
  EXPECT_EQ(s.devices[DeviceIndex(s, testing::SampleOpenClCpu())].chip, "host CPU");
  EXPECT_EQ(s.devices[DeviceIndex(s, testing::SampleGlCpu())].chip, "host CPU");
  ASSERT_EQ(s.opencl_vs_cuda.size(), 1u);
  ASSERT_EQ(s.opencl_vs_glsl.size(), 2u);
  EXPECT_EQ(s.opencl_vs_glsl[0].chip, "nvidia h100 80gb hbm3");
  EXPECT_EQ(s.opencl_vs_glsl[0].other_device, DeviceIndex(s, testing::SampleGlGpu()));
  EXPECT_EQ(s.opencl_vs_glsl[1].chip, "host CPU");
  EXPECT_EQ(s.opencl_vs_glsl[1].opencl_device, DeviceIndex(s, testing::SampleOpenClCpu()));
  EXPECT_EQ(s.opencl_vs_glsl[1].other_device, DeviceIndex(s, testing::SampleGlCpu()));
  // The GL winner may be a compute shader: GLSL covers both GL languages.
  const KernelResults* gl = s.Kernels(DeviceIndex(s, testing::SampleGlGpu()), "100k-b2");
  EXPECT_EQ(gl->tuned.variant.lang, Lang::kGlslCompute);
  EXPECT_EQ(gl->tuned.label, "GLSL tuned (glsl-compute)");
  EXPECT_DOUBLE_EQ(*s.opencl_vs_glsl[0].cells[1][1]->paper, gl->paper[0].median_ms /
                   s.Kernels(DeviceIndex(s, testing::SampleOpenClGpu()), "100k-b2")->paper[1].median_ms);
}

TEST(PaperSummary, DevicesCountUnderTheirBackendsApiAndLanguagesUnderTheLanguageTablesApi) {
  const PaperSummary s = Summarise({SamplePaperResult()});
  EXPECT_EQ(s.devices[DeviceIndex(s, testing::SampleOpenClGpu())].api, PaperApi::kOpenCl);
  EXPECT_EQ(s.devices[DeviceIndex(s, testing::SampleCudaGpu())].api, PaperApi::kCuda);
  EXPECT_EQ(s.devices[DeviceIndex(s, testing::SampleGlGpu())].api, PaperApi::kGlsl);
  EXPECT_EQ(s.devices[DeviceIndex(s, testing::SampleOpenClCpu())].api, PaperApi::kOpenCl);
  EXPECT_EQ(s.devices[DeviceIndex(s, testing::SampleGlCpu())].api, PaperApi::kGlsl);
  // GLSL covers both GL stages; the names and titles the report has always shown.
  EXPECT_EQ(ApiOf(Lang::kOpenCl), PaperApi::kOpenCl);
  EXPECT_EQ(ApiOf(Lang::kCuda), PaperApi::kCuda);
  EXPECT_EQ(ApiOf(Lang::kGlslCompute), PaperApi::kGlsl);
  EXPECT_EQ(ApiOf(Lang::kGlslVertex), PaperApi::kGlsl);
  EXPECT_EQ(ApiOf(Lang::kVulkan), PaperApi::kVulkan);
  EXPECT_EQ(ApiOf(Lang::kCpu), PaperApi::kCpu);
  ASSERT_EQ(kPaperApiCount, 5);
  const char* names[] = {"opencl", "cuda", "glsl", "vulkan", "cpu"};
  const char* titles[] = {"OpenCL", "CUDA", "GLSL", "Vulkan", "CPU"};
  for (int i = 0; i < kPaperApiCount; ++i) {
    EXPECT_STREQ(Name(static_cast<PaperApi>(i)), names[i]);
    EXPECT_STREQ(DisplayName(static_cast<PaperApi>(i)), titles[i]);
  }
}

TEST(PaperSummary, ResultsAreNeverPairedAcrossRunsAndDevicesSayWhichRun) {
  const PaperSummary s = Summarise({SamplePaperResult(), SamplePaperResult()});
  EXPECT_EQ(s.devices.size(), 10u);
  EXPECT_EQ(s.figure1.size(), 2u);
  EXPECT_EQ(s.opencl_vs_cuda.size(), 2u);
  for (const Table1Grid& g : s.opencl_vs_cuda) {
    EXPECT_EQ(s.devices[g.opencl_device].result, g.result);
    EXPECT_EQ(s.devices[g.other_device].result, g.result);
  }
  EXPECT_EQ(s.devices[0].label.rfind("run 1: ", 0), 0u) << s.devices[0].label;
  EXPECT_EQ(s.devices[5].label.rfind("run 2: ", 0), 0u) << s.devices[5].label;
  EXPECT_EQ(Summarise({SamplePaperResult()}).devices[0].label.find("run"), std::string::npos);
}

TEST(PaperSummary, GbpsSeriesArePerLanguageAndBWithTheFractionOfTheDevicesCopy) {
  const PaperSummary s = Summarise({Tiny()});
  ASSERT_EQ(s.gbps.size(), 2u);
  const GbpsChart& gpu = s.gbps[0];
  EXPECT_DOUBLE_EQ(gpu.copy_bandwidth_gbps, 1000.0);
  ASSERT_EQ(gpu.series.size(), 1u);
  ASSERT_EQ(gpu.series[0].points.size(), 1u);
  const GbpsPoint& p = gpu.series[0].points[0];
  const double bytes = testing::SampleBytes(ParseVariantKey(kTunedOpenCl), 100000);
  EXPECT_DOUBLE_EQ(p.gbps, bytes / (0.25 * 1e6));
  EXPECT_DOUBLE_EQ(p.copy_fraction, p.gbps / 1000.0);
  EXPECT_DOUBLE_EQ(s.Kernels(0, "100k-b2")->tuned.copy_fraction, p.gbps / 1000.0);
  // No copy bandwidth recorded for the CUDA device: no fraction.
  EXPECT_DOUBLE_EQ(s.gbps[1].copy_bandwidth_gbps, 0.0);
  EXPECT_DOUBLE_EQ(s.gbps[1].series[0].points[0].copy_fraction, 0.0);

  const PaperSummary sample = Summarise({SamplePaperResult()});
  const GbpsChart& gl = sample.gbps[DeviceIndex(sample, testing::SampleGlGpu())];
  ASSERT_EQ(gl.series.size(), 4u);  // glsl-compute and glsl-vertex, B = 1 and 2
  EXPECT_EQ(gl.series[0].lang, Lang::kGlslCompute);
  EXPECT_EQ(gl.series[0].influences, 1);
  EXPECT_EQ(gl.series[0].points.size(), 3u);
  EXPECT_LT(gl.series[0].points[0].vertices, gl.series[0].points[2].vertices);
}

// A row of palettes made on the device is no plain row: it names its
// form, the palette kernel's own time and a baked form's clips (their bytes
// and largest error), in the HTML and the Markdown.
TEST(PaperSummary, AnAnimatedRowSaysItsPaletteKernelAndItsBakedClips) {
  PaperResult r = Tiny();
  const DeviceIdentity gpu = testing::SampleOpenClGpu();
  Variant baked = ParseVariantKey(kTunedOpenCl);
  baked.animation = Animation::kBaked240;
  Measurement m = PaperMeasurement(gpu, r.tuning.datasets[0], baked, 0.3);
  m.timing.palette_kernel_ms = 0.004;
  m.baked_clips = {{"animations[0] 'Walk'", 169, 1.5e6, 1.2e-4}, {"animations[1] 'Run'", 289, 0.84e6, 2.2e-4}};
  r.tuning.measurements.push_back(m);
  const PaperSummary s = Summarise({r});
  const RowWinner* animated = nullptr;
  for (const RowWinner& row : s.rows)
    if (row.variant == baked.Key()) animated = &row;
  ASSERT_NE(animated, nullptr);
  EXPECT_FALSE(animated->plain);
  EXPECT_EQ(animated->row, "100k animated");
  EXPECT_EQ(animated->animation, "baked240: palette kernel 0.00400 ms; 2 clips, 2.34 MB, largest error 2.20e-04");
  EXPECT_NE(Section(RenderHtml(s), "rows").find("2 clips, 2.34 MB, largest error 2.20e-04"), std::string::npos);
  EXPECT_NE(RenderMarkdown(s).find("100k animated (baked240: palette kernel"), std::string::npos);
}

// A row the user chooses (here normals written oct16) has its own winner,
// set against its plain row's on the same device, language and mesh; the
// GB/s chart keeps the plain row's winner.
TEST(PaperSummary, EveryRowsWinnerStandsAgainstItsPlainRow) {
  PaperResult r = Tiny();
  const DeviceIdentity gpu = testing::SampleOpenClGpu();
  Variant plain = ParseVariantKey(kTunedOpenCl), oct16 = plain;
  plain.normals = oct16.normals = Normals::kNormals;
  oct16.normal_format = NormalFormat::kOct16;
  r.tuning.measurements.push_back(PaperMeasurement(gpu, r.tuning.datasets[0], plain, 0.3));
  r.tuning.measurements.push_back(PaperMeasurement(gpu, r.tuning.datasets[0], oct16, 0.24));
  const PaperSummary s = Summarise({r});
  const RowWinner* packed = nullptr;
  const RowWinner* opencl_plain = nullptr;
  for (const RowWinner& row : s.rows) {
    if (row.lang != Lang::kOpenCl) continue;
    (row.plain ? opencl_plain : packed) = &row;
  }
  ASSERT_NE(packed, nullptr);
  ASSERT_NE(opencl_plain, nullptr);
  EXPECT_EQ(packed->row, "100k normals oct16");
  EXPECT_EQ(packed->variant, oct16.Key());
  EXPECT_DOUBLE_EQ(packed->vs_plain, 0.24 / 0.25);  // against the plain row's winner, the 0.25 ms nonormals kernel
  EXPECT_EQ(opencl_plain->row, "100k");
  EXPECT_DOUBLE_EQ(opencl_plain->vs_plain, 0.0);
  EXPECT_EQ(s.gbps[DeviceIndex(s, gpu)].series[0].points[0].variant.normal_format, NormalFormat::kF32);
  const std::string rows = Section(RenderHtml(s), "rows");
  EXPECT_NE(rows.find("100k normals oct16"), std::string::npos) << rows;
  EXPECT_NE(rows.find("0.960\xC3\x97"), std::string::npos) << rows;
  // Without such a row the section says every row is plain.
  EXPECT_NE(Section(RenderHtml(Summarise({Tiny()})), "rows").find("Every row is plain"), std::string::npos);
  // The Markdown summary lists the same row with its ratio; without one it has no such section.
  const std::string markdown = RenderMarkdown(s);
  EXPECT_NE(markdown.find("## Every row"), std::string::npos);
  EXPECT_NE(markdown.find("| 100k normals oct16 | 0.240 ms |"), std::string::npos) << markdown;
  EXPECT_NE(markdown.find("| 0.960 |"), std::string::npos) << markdown;
  EXPECT_EQ(RenderMarkdown(Summarise({Tiny()})).find("## Every row"), std::string::npos);
}

TEST(PaperSummary, AxisEffectsAreTheBestTimePerValueRelativeToTheBestOfAll) {
  const PaperSummary s = Summarise({Tiny()});
  ASSERT_EQ(s.axes.size(), 2u);
  const AxisChart& opencl = s.axes[0];
  EXPECT_EQ(opencl.lang, Lang::kOpenCl);
  EXPECT_EQ(opencl.dataset, "100k-b2");
  EXPECT_DOUBLE_EQ(opencl.best_ms, 0.25);
  EXPECT_EQ(opencl.measurements, 3u);
  std::vector<std::string> axes;
  for (const AxisEffect& a : opencl.axes) axes.push_back(a.axis);
  EXPECT_EQ(axes, (std::vector<std::string>{"layout", "position", "index", "weight", "palette", "storage", "blend",
                                            "vertices_per_item+assignment", "wg_size"}));
  const AxisEffect& layout = opencl.axes[0];
  ASSERT_EQ(layout.values.size(), 3u);
  EXPECT_EQ(layout.values[0].value, "aos");
  EXPECT_DOUBLE_EQ(layout.values[0].ratio, 8.0);
  EXPECT_EQ(layout.values[1].value, "soa");
  EXPECT_DOUBLE_EQ(layout.values[1].ratio, 2.0);
  EXPECT_EQ(layout.values[2].value, "soa-split");
  EXPECT_DOUBLE_EQ(layout.values[2].ratio, 1.0);
  const AxisEffect& index = opencl.axes[2];
  ASSERT_EQ(index.values.size(), 2u);  // i32 (twice), u8; the failed u16 variant does not count
  EXPECT_EQ(index.values[0].value, "i32");
  EXPECT_EQ(index.values[0].measurements, 2u);
  EXPECT_DOUBLE_EQ(index.values[0].best_ms, 0.5);
  EXPECT_EQ(opencl.axes[7].values[0].value, "1 contiguous");
}

TEST(PaperSummary, AxisChartUsesTheLargestDataSetMeasuredOnThatDevice) {
  PaperResult r = SamplePaperResult();
  const std::string gpu = testing::SampleOpenClGpu().Id();
  auto& m = r.tuning.measurements;
  // Nothing on the GPU's OpenCL at 400k-b2: its next largest is 400k-b1 (400k x 1 > 100k x 2).
  m.erase(std::remove_if(m.begin(), m.end(),
                         [&](const Measurement& x) { return x.device_id == gpu && x.dataset == "400k-b2"; }),
          m.end());
  const PaperSummary s = Summarise({r});
  const std::size_t device = DeviceIndex(s, testing::SampleOpenClGpu());
  auto size = [&](const std::string& key) {
    for (const DatasetInfo& d : r.tuning.datasets)
      if (d.key == key) return d.vertices * static_cast<std::size_t>(d.influences);
    return std::size_t{0};
  };
  for (const AxisChart& a : s.axes) {
    if (a.device == device && a.lang == Lang::kOpenCl) {
      EXPECT_EQ(a.dataset, "400k-b1");
    }
    // No data set with a verified time of this device and language is larger.
    for (const Measurement& x : m) {
      if (x.device_id != s.devices[a.device].id || x.variant.lang != a.lang || x.status != MeasureStatus::kOk) continue;
      EXPECT_LE(size(x.dataset), size(a.dataset)) << s.devices[a.device].label << " " << Name(a.lang) << ": " << x.dataset;
    }
  }
  EXPECT_EQ(s.axes.size(), 7u);  // OpenCL, CUDA, 2 x GL on the GPU; OpenCL, 2 x GL on the CPU
}

TEST(PaperSummary, FailedPaperKernelShowsItsStatusNeverATimeAndAMissingOneSaysNotMeasured) {
  const PaperResult r = SamplePaperResult();
  const PaperSummary s = Summarise({r});
  const std::size_t cpu = DeviceIndex(s, testing::SampleOpenClCpu());
  const Figure1Row* failed = Row(s.figure1[0], "paper", "opencl-unoptimised", cpu);
  ASSERT_NE(failed, nullptr);
  EXPECT_FALSE(failed->median_ms);
  EXPECT_FALSE(failed->speedup);
  EXPECT_EQ(failed->note, "verify_failed: vertex 17: position off by 0.5");
  const KernelResults* missing = s.Kernels(DeviceIndex(s, testing::SampleGlCpu()), "400k-b1");
  ASSERT_NE(missing, nullptr);
  ASSERT_EQ(missing->paper.size(), 1u);
  EXPECT_FALSE(missing->paper[0].measured);
  EXPECT_TRUE(missing->tuned.Ok());

  const std::string html = RenderHtml(s);
  EXPECT_NE(Section(html, "fig1").find("verify_failed&#58; vertex 17&#58; position off by 0.5"), std::string::npos);
  const std::string md = RenderMarkdown(s);
  EXPECT_NE(md.find("verify_failed: vertex 17: position off by 0.5"), std::string::npos);
  EXPECT_NE(md.find("GLSL (vertex shader): not measured"), std::string::npos);
}

TEST(PaperSummary, ReportedFiguresStandBesideTheMatchingRowsAndCells) {
  const PaperSummary s = Summarise({SamplePaperResult()});
  const Figure1& f = s.figure1[0];
  const std::size_t gpu = DeviceIndex(s, testing::SampleOpenClGpu()), cuda = DeviceIndex(s, testing::SampleCudaGpu()),
                    gl = DeviceIndex(s, testing::SampleGlGpu()), cpu = DeviceIndex(s, testing::SampleOpenClCpu()),
                    llvmpipe = DeviceIndex(s, testing::SampleGlCpu());
  EXPECT_EQ(*Row(f, "paper", "cuda", cuda)->reported, 20.0);
  EXPECT_EQ(*Row(f, "paper", "opencl-optimised", gpu)->reported, 18.0);
  EXPECT_EQ(*Row(f, "paper", "glsl-vertex", gl)->reported, 15.0);
  EXPECT_EQ(*Row(f, "paper", "opencl-optimised", cpu)->reported, 3.0);
  EXPECT_EQ(Row(f, "paper", "opencl-optimised", cpu)->series, "opencl-cpu");
  EXPECT_EQ(Row(f, "paper", "opencl-unoptimised", gpu)->series, "opencl-unoptimised");
  EXPECT_FALSE(Row(f, "paper", "opencl-unoptimised", gpu)->reported);  // not on record
  EXPECT_FALSE(Row(f, "paper", "glsl-vertex", llvmpipe)->reported);     // the paper's GLSL ran on a GPU
  EXPECT_FALSE(Row(f, "tuned", "", gpu)->reported);
  EXPECT_TRUE(f.unmatched.empty());
  EXPECT_EQ(*s.opencl_vs_cuda[0].cells[1][1]->reported, 0.9);
  EXPECT_EQ(*s.opencl_vs_cuda[0].cells[0][0]->reported, 0.8);
  EXPECT_FALSE(s.opencl_vs_cuda[0].cells[0][1]->reported);
  EXPECT_EQ(*s.opencl_vs_glsl[0].cells[1][1]->reported, 1.1);
  EXPECT_FALSE(s.opencl_vs_glsl[1].cells[1][1]->reported);  // the host CPU's grid: the paper's figures are a GPU's

  const std::string fig1 = Section(RenderHtml(s), "fig1");
  EXPECT_NE(fig1.find("paper 20.0\xC3\x97"), std::string::npos);
  EXPECT_NE(fig1.find("paper 3.00\xC3\x97"), std::string::npos);
  EXPECT_NE(fig1.find("paper: not on record"), std::string::npos);
  const std::string md = Figure1Markdown(s);
  EXPECT_NE(md.find("| 20.0\xC3\x97 |"), std::string::npos) << md;
  EXPECT_NE(Table1Markdown(s).find(" / 0.900 |"), std::string::npos) << Table1Markdown(s);
}

TEST(PaperSummary, WithoutReportedFiguresTheReportSaysNotOnRecord) {
  PaperResult r = SamplePaperResult();
  r.reported = {};
  r.reported.source = "Not on record: the paper's text was not available.";
  const PaperSummary s = Summarise({r});
  for (const Figure1Row& row : s.figure1[0].rows) EXPECT_FALSE(row.reported);
  const std::string html = RenderHtml(s);
  EXPECT_NE(Section(html, "fig1").find("The paper&#39;s figures: not on record"), std::string::npos);
  EXPECT_EQ(Section(html, "fig1").find("paper: not on record"), std::string::npos);  // said once, not per row
  EXPECT_NE(Section(html, "table1-opencl-vs-cuda").find("not on record"), std::string::npos);
  EXPECT_NE(Figure1Markdown(s).find("The paper's figures: not on record"), std::string::npos);
}

// The Markdown summary names where the paper's figures come from once, under
// Fig. 1; the Table 1 grids after it say only where none is on record.
TEST(PaperSummary, TheMarkdownNamesThePapersSourceOnce) {
  const PaperResult r = SamplePaperResult();
  ASSERT_FALSE(r.reported.source.empty());
  const std::string md = RenderMarkdown(Summarise({r}));
  const std::size_t first = md.find(r.reported.source);
  ASSERT_NE(first, std::string::npos);
  EXPECT_EQ(md.find(r.reported.source, first + 1), std::string::npos) << md;
  EXPECT_LT(first, md.find("## Table 1"));
}

TEST(PaperSummary, ReportedSeriesWithoutAMatchingDeviceIsListedApart) {
  PaperResult r = SamplePaperResult();
  const std::string cpu = testing::SampleOpenClCpu().Id();
  r.tuning.devices.erase(r.tuning.devices.begin() + 3);  // the CPU OpenCL device
  auto& m = r.tuning.measurements;
  m.erase(std::remove_if(m.begin(), m.end(), [&](const Measurement& x) { return x.device_id == cpu; }), m.end());
  const PaperSummary s = Summarise({r});
  ASSERT_EQ(s.figure1[0].unmatched.size(), 1u);
  EXPECT_EQ(s.figure1[0].unmatched[0].first, "opencl-cpu");
  EXPECT_EQ(s.figure1[0].unmatched[0].second, 3.0);
  EXPECT_NE(Section(RenderHtml(s), "fig1").find("opencl-cpu"), std::string::npos);
  EXPECT_EQ(s.opencl_vs_glsl.size(), 1u);  // llvmpipe has no OpenCL partner left
}

TEST(PaperSummary, MissingBackendLeavesItsComparisonEmptyAndTheReportSaysSo) {
  PaperResult r = SamplePaperResult();
  const std::string cuda = testing::SampleCudaGpu().Id();
  r.tuning.devices.erase(r.tuning.devices.begin() + 1);
  auto& m = r.tuning.measurements;
  m.erase(std::remove_if(m.begin(), m.end(), [&](const Measurement& x) { return x.device_id == cuda; }), m.end());
  r.tuning.skipped = {"cuda: skipped: libcuda.so.1 not found (sample)"};
  const PaperSummary s = Summarise({r});
  EXPECT_TRUE(s.opencl_vs_cuda.empty());
  EXPECT_EQ(s.opencl_vs_glsl.size(), 2u);
  for (const Figure1Row& row : s.figure1[0].rows) EXPECT_NE(row.kernel, "cuda");
  ASSERT_EQ(s.figure1[0].unmatched.size(), 1u);
  EXPECT_EQ(s.figure1[0].unmatched[0].first, "cuda");
  const std::string html = RenderHtml(s);
  EXPECT_NE(Section(html, "table1-opencl-vs-cuda").find("no chip with both APIs"), std::string::npos);
  EXPECT_EQ(Section(html, "table1-opencl-vs-glsl").find("no chip with both APIs"), std::string::npos);
  EXPECT_NE(Section(html, "devices").find("libcuda.so.1 not found"), std::string::npos);
  EXPECT_NE(Table1Markdown(s).find("No chip with both APIs (OpenCL and CUDA)"), std::string::npos);
  EXPECT_NE(RenderMarkdown(s).find("skipped: cuda: skipped: libcuda.so.1 not found (sample)"), std::string::npos);
}

TEST(PaperSummary, DeviceFoundButNeverMeasuredIsNotCompared) {
  PaperResult r = SamplePaperResult();
  const std::string cuda = testing::SampleCudaGpu().Id();
  auto& m = r.tuning.measurements;
  m.erase(std::remove_if(m.begin(), m.end(), [&](const Measurement& x) { return x.device_id == cuda; }), m.end());
  const PaperSummary s = Summarise({r});
  EXPECT_TRUE(s.opencl_vs_cuda.empty());
  const Figure1Row* row = Row(s.figure1[0], "paper", "cuda", DeviceIndex(s, testing::SampleCudaGpu()));
  ASSERT_NE(row, nullptr);
  EXPECT_EQ(row->note, "not measured");
  EXPECT_EQ(Row(s.figure1[0], "tuned", "", DeviceIndex(s, testing::SampleCudaGpu()))->note, "not measured");
}

TEST(PaperSummary, PlainTuningReportHasNoSerialBaselineAndSaysSo) {
  const PaperResult r = PaperResultFromReport(testing::SampleReport());
  EXPECT_TRUE(r.cpu.empty());
  EXPECT_TRUE(r.paper_kernels.empty());
  EXPECT_EQ(r.figure1_dataset, "100k-b4");  // no 100k-b2 in it: the one both devices were measured on
  EXPECT_EQ(r.host.cpu_model, "");          // the sample's machine has "cpu", not "cpu_model"
  EXPECT_EQ(r.command, "");                 // a tuning report does not record it
  const PaperSummary s = Summarise({r});
  EXPECT_FALSE(s.figure1[0].serial_ms);
  bool timed = false;
  for (const Figure1Row& row : s.figure1[0].rows) {
    EXPECT_FALSE(row.speedup);
    EXPECT_EQ(row.kind, "tuned");
    timed = timed || row.median_ms.has_value();
  }
  EXPECT_TRUE(timed);
  ASSERT_EQ(s.opencl_vs_cuda.size(), 1u);  // "Model GPU" through OpenCL and CUDA
  const std::string html = RenderHtml(s);
  EXPECT_NE(Section(html, "fig1").find("No serial baseline"), std::string::npos);
  EXPECT_NE(html.find("command not recorded"), std::string::npos);
  EXPECT_TRUE(HasId(html, "fig1-0"));
  EXPECT_NE(Figure1Markdown(s).find("No serial baseline"), std::string::npos);
  EXPECT_TRUE(ExternalReferences(html).empty());
}

TEST(PaperReportHtml, EscapesEveryTextFromTheInput) {
  PaperResult r = SamplePaperResult();
  const std::string evil = "Evil <GPU> & \"Co\" 'x'";
  for (DeviceIdentity& d : r.tuning.devices) {
    if (d.backend == "cuda") {
      const std::string old = d.Id();
      d.name = evil;
      for (Measurement& m : r.tuning.measurements) {
        if (m.device_id == old) m.device_id = d.Id();
      }
      r.tuning.copy_bandwidth_gbps[d.Id()] = r.tuning.copy_bandwidth_gbps[old];
    }
  }
  r.command = "skintune paper <script>alert(1)</script> --notes https://example.com//x";
  r.tuning.skipped = {"gl: <b>bold</b> & co"};
  r.reported.source = "see http://example.org/paper";
  const std::string html = RenderHtml(Summarise({r}));
  EXPECT_EQ(html.find(evil), std::string::npos);
  EXPECT_EQ(html.find("<GPU>"), std::string::npos);
  EXPECT_NE(html.find("Evil &lt;GPU&gt; &amp; &quot;Co&quot; &#39;x&#39;"), std::string::npos);
  EXPECT_EQ(html.find("<b>bold</b>"), std::string::npos);
  EXPECT_NE(html.find("&lt;b&gt;bold&lt;&#47;b&gt; &amp; co"), std::string::npos);
  EXPECT_TRUE(ExternalReferences(html).empty()) << ::testing::PrintToString(ExternalReferences(html));
}

TEST(PaperReportHtml, HasNoScriptAndNoExternalReference) {
  const std::string html = RenderHtml(Summarise({SamplePaperResult(), Tiny()}));
  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_TRUE(ExternalReferences(html).empty()) << ::testing::PrintToString(ExternalReferences(html));
  EXPECT_NE(html.find("font:15px/1.5 system-ui,sans-serif"), std::string::npos);
  // The checker itself finds each kind of reference.
  for (const char* bad : {"<script>x()</script>", "<img src=\"a.png\">", "<a href=\"https://example.com\">",
                          "<a href=\"page.html\">", "<style>@import 'x.css';</style>", "<link rel=\"stylesheet\">",
                          "<div style=\"background:url(x.png)\">", "//cdn.example.com"}) {
    EXPECT_FALSE(ExternalReferences(std::string("<p>ok</p>") + bad).empty()) << bad;
  }
}

TEST(PaperReportHtml, HasEverySectionAndOneChartPerFigure1DeviceAndDeviceLanguage) {
  const PaperSummary s = Summarise({SamplePaperResult()});
  const std::string html = RenderHtml(s);
  for (const char* id : {"fig1", "table1-opencl-vs-cuda", "table1-opencl-vs-glsl", "gbps", "axes", "rows", "devices",
                         "fig1-0", "candy-wrapper", "candy-wrapper-chart"}) {
    EXPECT_TRUE(HasId(html, id)) << id;
  }
  ASSERT_EQ(s.gbps.size(), 5u);
  for (std::size_t i = 0; i < 5; ++i) EXPECT_TRUE(HasId(html, "gbps-" + std::to_string(i))) << i;
  EXPECT_FALSE(HasId(html, "gbps-5"));
  ASSERT_EQ(s.axes.size(), 7u);
  for (std::size_t i = 0; i < 7; ++i) EXPECT_TRUE(HasId(html, "axes-" + std::to_string(i))) << i;
  EXPECT_FALSE(HasId(html, "axes-7"));
}

TEST(PaperReportHtml, Figure1LegendNamesTheCpuBaselinesThenEveryGpuApiInTableOrder) {
  const std::string fig1 = Section(RenderHtml(Summarise({SamplePaperResult()})), "fig1");
  std::size_t at = 0;
  for (const char* title : {"CPU", "OpenCL", "CUDA", "GLSL", "Vulkan", "the paper&#39;s kernel"}) {
    const std::size_t found = fig1.find(std::string("class=\"small\">") + title + "</text>", at);
    ASSERT_NE(found, std::string::npos) << title << " after position " << at;
    at = found;
  }
}

TEST(PaperReportHtml, EveryChartIsAnSvgWithClassRoleTitleViewBoxAndSize) {
  const std::string html = RenderHtml(Summarise({SamplePaperResult()}));
  const std::regex svg("<svg([^>]*)>(.{0,7})");
  std::size_t charts = 0;
  for (auto it = std::sregex_iterator(html.begin(), html.end(), svg); it != std::sregex_iterator(); ++it) {
    const std::string attributes = (*it)[1].str();
    ++charts;
    EXPECT_NE(attributes.find("class=\"chart\""), std::string::npos) << attributes;
    EXPECT_NE(attributes.find("role=\"img\""), std::string::npos) << attributes;
    EXPECT_TRUE(std::regex_search(attributes, std::regex("viewBox=\"0 0 [0-9.]+ [0-9.]+\""))) << attributes;
    EXPECT_TRUE(std::regex_search(attributes, std::regex(" width=\"[1-9][0-9.]*\""))) << attributes;
    EXPECT_TRUE(std::regex_search(attributes, std::regex(" height=\"[1-9][0-9.]*\""))) << attributes;
    EXPECT_EQ((*it)[2].str().substr(0, 6), "<title") << attributes;
  }
  EXPECT_EQ(charts, 1u + 5u + 7u + 1u);
}

// Linear blending's volume loss on a twisting joint against dual quaternions'.
TEST(PaperReportHtml, TheCandyWrapperShowsLinearBlendingCollapsingWhereDualQuaternionsDoNot) {
  const std::string candy = Section(RenderHtml(Summarise({SamplePaperResult()})), "candy-wrapper");
  EXPECT_NE(candy.find("<tr><td>90</td><td>0.707</td><td>1.000</td>"), std::string::npos) << candy;
  EXPECT_NE(candy.find("<tr><td>180</td><td>0.000</td><td>1.000</td>"), std::string::npos) << candy;
  EXPECT_NE(candy.find("linear blending"), std::string::npos);
  EXPECT_NE(candy.find("dual quaternions"), std::string::npos);
}

TEST(PaperReportHtml, NoResultsStillGivesEverySectionSayingSo) {
  const std::string html = RenderHtml(Summarise({}));
  for (const char* id : {"fig1", "table1-opencl-vs-cuda", "table1-opencl-vs-glsl", "gbps", "axes", "devices"}) {
    EXPECT_TRUE(HasId(html, id)) << id;
  }
  EXPECT_NE(html.find("No results were given."), std::string::npos);
  EXPECT_NE(Section(html, "table1-opencl-vs-cuda").find("no chip with both APIs"), std::string::npos);
  EXPECT_EQ(html.find("<svg"), std::string::npos);
  EXPECT_TRUE(ExternalReferences(html).empty());
  EXPECT_NE(RenderMarkdown(Summarise({})).find("No chip with both APIs"), std::string::npos);
}

TEST(PaperReportHtml, DevicesSectionListsIdentitiesHostKernelsAndCommand) {
  const PaperResult r = SamplePaperResult();
  const std::string devices = Section(RenderHtml(Summarise({r})), "devices");
  for (const std::string& text :
       {std::string("Portable Computing Language"), std::string("580.159.04 (CUDA 13.0)"), std::string("80.0 GiB"),
        std::string("50.0 MiB"), std::string("2756 GB/s"), std::string("Intel(R) Xeon(R) Processor (Sapphire Rapids)"),
        std::string("83.0 GB/s"), std::string("opencl.b2.padded.soa.float4.i32.f32.mat4.constant.matrix.v1c.wg128.nonormals"),
        std::string("section 4.1"), std::string("skintune paper --datasets"), std::string("2025-06-01T12&#58;00&#58;00Z"),
        std::string("No backend was skipped")}) {
    EXPECT_NE(devices.find(text), std::string::npos) << text;
  }
}

TEST(PaperReportMarkdown, HasFigure1Table1WinnersWithFractionOfCopyAndDevices) {
  const PaperSummary s = Summarise({Tiny()});
  const std::string md = RenderMarkdown(s);
  EXPECT_NE(md.find(Figure1Markdown(s)), std::string::npos);
  EXPECT_NE(md.find(Table1Markdown(s)), std::string::npos);
  EXPECT_NE(Figure1Markdown(s).find("| CPU (Test CPU) | CPU serial (1 thread, the paper's baseline) | 10.0 ms | "
                                    "1.00\xC3\x97 |"),
            std::string::npos)
      << Figure1Markdown(s);
  EXPECT_NE(Figure1Markdown(s).find("| OpenCL tuned (opencl) | 0.250 ms | 40.0\xC3\x97 |"), std::string::npos);
  // No Table 1 figure of the paper on record: the cells hold our two ratios only (no frame time measured: a dash).
  EXPECT_NE(Table1Markdown(s).find("| 100000 | 0.800 (—) / 1.20 |"), std::string::npos) << Table1Markdown(s);
  const double gbps = testing::SampleBytes(ParseVariantKey(kTunedOpenCl), 100000) / (0.25 * 1e6);
  EXPECT_NE(md.find(FormatMs(0.25) + " | " + FormatGbps(gbps) + " | " + FormatSignificant(1.25, 3) + " | " +
                    FormatSignificant(gbps / 1000.0, 2) + " |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| opencl | NVIDIA CUDA | NVIDIA H100 80GB HBM3 |"), std::string::npos);
  EXPECT_NE(md.find("host CPU Test CPU, 8 threads, copy 50.0 GB/s"), std::string::npos);
}

// Both errors of a tuned winner: against the quantised gold and against the source.
TEST(PaperReport, WinnersShowTheErrorAgainstTheSourceNextToTheQuantisedOne) {
  PaperResult r = Tiny();
  for (Measurement& m : r.tuning.measurements) {
    if (m.variant.Key() != ParseVariantKey(kTunedOpenCl).Key()) continue;
    m.max_relative_error = 2.5e-7;
    m.source_error = {true, 2.0, 8.4e-4, 4.2e-4, 0.0, 4.1e-4};
  }
  const PaperSummary s = Summarise({r});
  const std::string md = RenderMarkdown(s);
  EXPECT_NE(md.find("| vs quantised | vs source |"), std::string::npos) << md;
  EXPECT_NE(md.find("| 2.5e-07 | 4.2e-04 of the diagonal (weights 4.1e-04) |"), std::string::npos) << md;
  const std::string html = RenderHtml(s);
  EXPECT_NE(html.find("4.2e-04 of the diagonal (weights 4.1e-04)"), std::string::npos);
  EXPECT_NE(html.find(">vs source</th>"), std::string::npos);
  // A measurement from before the error was recorded says so.
  EXPECT_NE(RenderMarkdown(Summarise({Tiny()})).find("| not recorded |"), std::string::npos);
}

TEST(PaperReportFormat, ThreeSignificantDigitsWithoutAnExponent) {
  EXPECT_EQ(FormatSignificant(0.0234), "0.0234");
  EXPECT_EQ(FormatSignificant(7.85), "7.85");
  EXPECT_EQ(FormatSignificant(123.4), "123");
  EXPECT_EQ(FormatSignificant(1234.0), "1234");
  EXPECT_EQ(FormatSignificant(9.996), "10.0");
  EXPECT_EQ(FormatSignificant(0.0000123456), "0.0000123");
  EXPECT_EQ(FormatSignificant(0.0), "0");
  EXPECT_EQ(FormatMs(0.25), "0.250 ms");
  EXPECT_EQ(FormatSpeedup(16.6667), "16.7\xC3\x97");
  EXPECT_EQ(FormatGbps(2457.6), "2458 GB/s");
  EXPECT_EQ(FormatGbps(56.23), "56.2 GB/s");
}

// tests/data/paper/sample-result.json is SamplePaperResult() as JSON (the
// browser test renders it). SKINTUNE_UPDATE_FIXTURES=1 rewrites it.
TEST(PaperReportFixture, CommittedSampleResultIsTheSampleOfThisHeaderAndParses) {
  const std::filesystem::path path = std::filesystem::path(SKINTUNE_TEST_DATA_DIR) / "paper" / "sample-result.json";
  const nlohmann::json expected = PaperResultToJson(SamplePaperResult());
  const char* update = std::getenv("SKINTUNE_UPDATE_FIXTURES");
  if (update && std::string(update) == "1") {
    std::filesystem::create_directories(path.parent_path());
    std::ofstream(path) << expected.dump(1) << "\n";
  }
  std::ifstream in(path);
  ASSERT_TRUE(in) << path << " is missing; run this test with SKINTUNE_UPDATE_FIXTURES=1";
  const nlohmann::json committed = nlohmann::json::parse(in);
  EXPECT_EQ(committed, expected) << path << " differs from SamplePaperResult(); rerun with SKINTUNE_UPDATE_FIXTURES=1";
  const PaperResult parsed = PaperResultFromJson(committed, path.string());
  EXPECT_EQ(PaperResultToJson(parsed), expected);
}

}  // namespace
}  // namespace skintune::internal
