// Golden tests: the emitted source and sidecar of a few fixed variants are
// pinned in tests/generator/golden/. After an intended change to templates/ or
// generator/, regenerate them with scripts/update-golden and review the diff.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "generator/emit.h"

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;
const fs::path kGolden = fs::path(SKINTUNE_SOURCE_DIR) / "tests/generator/golden";
constexpr int kGoldenMorphTargets = 4;  // scripts/update-golden's --morph-targets

std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  EXPECT_TRUE(in) << "missing golden file " << p << " (run scripts/update-golden)";
  return std::string(std::istreambuf_iterator<char>(in), {});
}

std::vector<std::string> GoldenKeys() {
  std::ifstream in(kGolden / "VARIANTS.txt");
  std::vector<std::string> keys;
  for (std::string line; std::getline(in, line);)
    if (!line.empty() && line[0] != '#') keys.push_back(line);
  return keys;
}

TEST(GoldenEmit, ThereArePinnedVariants) { EXPECT_GE(GoldenKeys().size(), 3u); }

TEST(GoldenEmit, EmittedSourceAndSidecarMatchThePinnedFiles) {
  for (const std::string& key : GoldenKeys()) {
    const Variant v = ParseVariantKey(key);
    ASSERT_EQ(v.Key(), key) << "VARIANTS.txt must list canonical keys";
    const KernelSource source = Emit(v, 0, 77, EmitOptions{.morph_targets = SkinsMorph(v) ? kGoldenMorphTargets : 0});
    EXPECT_EQ(source.text, Slurp(kGolden / (key + LanguageOf(v.lang).extension)))
        << key << ": emitted source changed; if intended, run scripts/update-golden and review the diff";
    nlohmann::json sidecar = SidecarJson(source, v);
    sidecar["source_file"] = key + LanguageOf(v.lang).extension;
    if (v.lang == Lang::kVulkan) sidecar["spirv_file"] = key + ".spv";  // emit's SPIR-V (not pinned: glslang's)
    EXPECT_EQ(sidecar, nlohmann::json::parse(Slurp(kGolden / (key + ".json"))))
        << key << ": sidecar changed; if intended, run scripts/update-golden";
  }
}

}  // namespace
}  // namespace skintune::internal
