// The paper experiment's data: its kernels are points of the variant space,
// its data-set lists, and the result JSON (round trip, errors naming the element).
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include <nlohmann/json.hpp>

#include "generator/constraints.h"
#include "base/error.h"
#include "tests/tuner/sample_report.h"
#include "report/paper_result.h"

namespace skintune::internal {
namespace {

std::string ErrorOf(const nlohmann::json& json) {
  try {
    PaperResultFromJson(json, "result.json");
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

PaperResult SampleResult() {
  PaperResult r;
  r.created = "2025-01-31T12:00:00Z";
  r.quick = true;
  r.command = "skintune paper --quick";
  r.figure1_dataset = "100k-b4";
  r.host = {"Example CPU", 16, 80.5};
  r.reported.source = "test";
  r.reported.figure1 = {{"cuda", 40.0}};
  r.reported.opencl_vs_cuda = {{"25k-b4", 1.1}};
  r.paper_kernels = PaperKernels();
  r.tuning = testing::SampleReport();
  CpuTiming serial{12.5, 12.0, 13.0, 9, 8, 1, 4.0e6, 0.32, 1e-7};
  CpuTiming fast{1.5, 1.4, 1.9, 9, 8, 16, 3.0e6, 2.0, 2e-7};
  r.cpu = {{"25k-b4", serial, fast}, {"100k-b4", serial, fast}};
  return r;
}

TEST(PaperKernels, AreTheFourKernelsOfThePaperWithTheirLanguages) {
  const std::vector<PaperKernel> kernels = PaperKernels();
  ASSERT_EQ(kernels.size(), 4u);
  EXPECT_EQ(kernels[0].name, "opencl-unoptimised");
  EXPECT_EQ(kernels[0].variant.lang, Lang::kOpenCl);
  EXPECT_EQ(kernels[1].name, "opencl-optimised");
  EXPECT_EQ(kernels[1].variant.lang, Lang::kOpenCl);
  EXPECT_EQ(kernels[2].name, "cuda");
  EXPECT_EQ(kernels[2].variant.lang, Lang::kCuda);
  EXPECT_EQ(kernels[3].name, "glsl-vertex");
  EXPECT_EQ(kernels[3].variant.lang, Lang::kGlslVertex);
  // The optimised kernel differs from the unoptimised one by exactly the
  // paper's three optimisations: float4 alignment, SoA, constant memory.
  Variant optimised = kernels[1].variant;
  EXPECT_EQ(optimised.position, PositionFormat::kFloat4);
  EXPECT_EQ(optimised.layout, Layout::kSoa);
  EXPECT_EQ(optimised.storage, PaletteStorage::kConstant);
  optimised.position = kernels[0].variant.position;
  optimised.layout = kernels[0].variant.layout;
  optimised.storage = kernels[0].variant.storage;
  EXPECT_EQ(optimised, kernels[0].variant);
  for (const PaperKernel& k : kernels) {
    EXPECT_FALSE(k.label.empty()) << k.name;
    EXPECT_FALSE(k.description.empty()) << k.name;
  }
}

TEST(PaperKernels, AreValidOnEveryPaperDataSetWithTheDefaultDeviceLimits) {
  for (const PaperKernel& k : PaperKernels()) {
    for (int b = 1; b <= 4; ++b) {
      Variant v = k.variant;
      v.influences = b;
      const std::vector<Violation> violations = CheckVariant(v, DeviceLimits{}, ProblemShape{77, b, false, 1});
      EXPECT_TRUE(violations.empty()) << v.Key() << ": " << (violations.empty() ? "" : violations[0].message);
    }
  }
}

TEST(PaperKernels, AMalformedListNamesTheElement) {
  nlohmann::json list = nlohmann::json::array(
      {{{"name", "a"}, {"label", "A"}, {"variant", "opencl.b2"}}, {{"name", "b"}, {"label", "B"}, {"variant", "opencl.bogus"}}});
  try {
    PaperKernelsFromJson(list, "paper.json");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("paper.json: paper_kernels[1]"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("bogus"), std::string::npos) << e.what();
  }
  list[1]["variant"] = "cuda.b2";
  list[1]["name"] = "a";
  EXPECT_THROW(PaperKernelsFromJson(list, "paper.json"), Error);  // a name used twice
}

TEST(PaperDatasets, AreThePapers16AndQuickKeepsFigure1sDataSet) {
  const std::vector<std::string> full = PaperDatasets(false);
  ASSERT_EQ(full.size(), 16u);
  EXPECT_EQ(full.front(), "25k-b1");
  EXPECT_EQ(full.back(), "1600k-b4");
  const std::vector<std::string> quick = PaperDatasets(true);
  EXPECT_EQ(quick.size(), 8u);
  EXPECT_NE(std::find(quick.begin(), quick.end(), "100k-b2"), quick.end());
  EXPECT_EQ(std::find(quick.begin(), quick.end(), "400k-b1"), quick.end());
}

TEST(PaperReported, TheBuiltInFiguresAreThePapersTable1AndSayWhereTheyComeFrom) {
  const PaperReported r = BuiltInPaperReported();
  EXPECT_NE(r.source.find("Liu, Chen, Ma, Han"), std::string::npos) << r.source;
  // Table 1 covers the 16 data sets in both grids (../shared/paper: ratio = 1 + percentage / 100).
  ASSERT_EQ(r.opencl_vs_cuda.size(), 16u);
  ASSERT_EQ(r.opencl_vs_glsl.size(), 16u);
  for (const std::string& key : PaperDatasets(false)) {
    EXPECT_EQ(r.opencl_vs_cuda.count(key), 1u) << key;
    EXPECT_EQ(r.opencl_vs_glsl.count(key), 1u) << key;
  }
  EXPECT_DOUBLE_EQ(r.opencl_vs_cuda.at("100k-b2"), 2.17);   // the text's "OpenCL is 2 times of CUDA"
  EXPECT_DOUBLE_EQ(r.opencl_vs_cuda.at("1600k-b1"), 2.72);  // +172%
  EXPECT_DOUBLE_EQ(r.opencl_vs_glsl.at("25k-b1"), 0.30);    // -70%
  EXPECT_DOUBLE_EQ(r.opencl_vs_glsl.at("100k-b4"), 1.00);   // 0%
  // Fig. 1 states relations, not a figure per bar: nothing is invented for it.
  EXPECT_TRUE(r.figure1.empty());
}

TEST(PaperReported, ANonPositiveFigureNamesItsPlace) {
  const nlohmann::json in = {{"source", "x"}, {"figure1", {{"cuda", -3}}}};
  try {
    PaperReportedFromJson(in, "paper.json");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("reported.figure1.cuda"), std::string::npos) << e.what();
  }
}

TEST(PaperResult, RoundTripsThroughJson) {
  const PaperResult r = SampleResult();
  const nlohmann::json json = PaperResultToJson(r);
  const PaperResult back = PaperResultFromJson(json, "result.json");
  EXPECT_EQ(PaperResultToJson(back), json);
  EXPECT_EQ(back.cpu.size(), 2u);
  EXPECT_EQ(back.cpu[1].fast.threads, 16u);
  EXPECT_EQ(back.paper_kernels.size(), 4u);
  EXPECT_EQ(back.tuning.measurements.size(), r.tuning.measurements.size());
  EXPECT_DOUBLE_EQ(back.reported.figure1.at("cuda"), 40.0);
}

TEST(PaperResult, MalformedElementsAreNamed) {
  const nlohmann::json good = PaperResultToJson(SampleResult());
  nlohmann::json j = good;
  j["kind"] = "skintune-report";
  EXPECT_NE(ErrorOf(j).find("kind is 'skintune-report', expected 'skintune-paper-result'"), std::string::npos) << ErrorOf(j);
  j = good;
  j["cpu"][1]["serial"].erase("median_ms");
  EXPECT_NE(ErrorOf(j).find("result.json: cpu[1]: serial: missing 'median_ms'"), std::string::npos) << ErrorOf(j);
  j = good;
  j["cpu"][0]["dataset"] = "400k-b3";
  EXPECT_NE(ErrorOf(j).find("cpu[0]: dataset '400k-b3' is not in tuning.datasets"), std::string::npos) << ErrorOf(j);
  j = good;
  j["paper_kernels"][2]["variant"] = "cuda.nonsense";
  EXPECT_NE(ErrorOf(j).find("paper_kernels[2]"), std::string::npos) << ErrorOf(j);
  j = good;
  j["tuning"]["measurements"][0].erase("status");
  EXPECT_NE(ErrorOf(j).find("result.json: tuning: measurements[0]"), std::string::npos) << ErrorOf(j);
  j = good;
  j["quick"] = "yes";
  EXPECT_NE(ErrorOf(j).find("quick: must be true or false"), std::string::npos) << ErrorOf(j);
}

}  // namespace
}  // namespace skintune::internal
