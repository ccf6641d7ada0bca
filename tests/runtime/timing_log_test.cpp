// SKINTUNE_TIMING_LOG (runtime/runner.h) from a Skinner: one line when it
// goes, saying how many SetPalette calls it took and where their host time
// went (the wait for a free palette buffer, the packing, the upload's
// hand-over); nothing for a Skinner that never took a palette. Its own
// executable: the log's path is read once per process, here set first.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "model/synthetic.h"
#include "skintune/skintune.h"
#include "tests/runtime/api_test_support.h"

namespace skintune::internal {
namespace {

using testing::CacheIn;
using testing::Floats;
using testing::TempDir;
using testing::View;

TEST(TimingLog, ASkinnerLogsWhereItsSetPaletteTimeWentWhenItGoes) {
  TempDir dir;
  const std::string log = dir.str() + "/timing.log";
  ASSERT_EQ(setenv("SKINTUNE_TIMING_LOG", log.c_str(), 1), 0);
  constexpr Backend kCpu = Backend::kCpu;
  Result<Device> device = Device::Open("", &kCpu, CacheIn(dir));
  ASSERT_TRUE(device.ok()) << device.status().message();
  const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("900-b4"));
  View view(asset.mesh);
  const std::vector<float> palette = Floats(asset.PaletteAt(0, 0.3));
  {
    Result<Skinner> unused = Skinner::Create(*device, WinnersDb::Empty(), view.mesh);
    ASSERT_TRUE(unused.ok()) << unused.status().message();
    Result<Skinner> skinner = Skinner::Create(*device, WinnersDb::Empty(), view.mesh);
    ASSERT_TRUE(skinner.ok()) << skinner.status().message();
    for (int f = 0; f < 5; ++f) {
      ASSERT_TRUE(skinner->SetPalette(palette.data(), palette.size()).ok());
      ASSERT_TRUE(skinner->Skin().ok());
    }
    std::vector<float> bad = palette;
    bad[7] = std::nanf("");
    EXPECT_FALSE(skinner->SetPalette(bad.data(), bad.size()).ok());  // rejected: not counted
    ASSERT_TRUE(skinner->Finish().ok());
  }
  std::ifstream in(log);
  ASSERT_TRUE(in) << log;
  std::stringstream text;
  text << in.rdbuf();
  const std::regex line(
      R"(^[0-9.]+ skinner: 5 SetPalette calls, host us per call: buffer wait [0-9.]+, packing [0-9.]+, upload hand-over [0-9.]+$)");
  int lines = 0;
  std::string l;
  while (std::getline(text, l))
    if (l.find("skinner:") != std::string::npos) {
      ++lines;
      EXPECT_TRUE(std::regex_match(l, line)) << l;
    }
  EXPECT_EQ(lines, 1) << text.str();
}

}  // namespace
}  // namespace skintune::internal
