// The one list of APIs (runtime/backend_table.h): its order is the public
// Backend enum's, its languages are the fallback chain's and the database's,
// and discovery through it finds what each API's own enumeration finds, with a
// skipped line for every API that has no device here. The device identity's
// JSON (runtime/device_identity.h) round-trips through the public DeviceInfo.
// The JSON schemas spell the backends as the table does.
#include "runtime/backend_table.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "runtime/backends/opencl/opencl_devices.h"
#include "runtime/device.h"
#include "runtime/selection.h"
#include "skintune/skintune.h"

namespace skintune::internal {
namespace {

TEST(BackendTable, ListsTheApisInTheOrderOfThePublicEnum) {
  const std::vector<BackendEntry>& table = Backends();
  ASSERT_EQ(table.size(), 5u);
  EXPECT_STREQ(BackendName(Backend::kOpenCl), "opencl");
  EXPECT_STREQ(BackendName(Backend::kCuda), "cuda");
  EXPECT_STREQ(BackendName(Backend::kGl), "gl");
  EXPECT_STREQ(BackendName(Backend::kVulkan), "vulkan");
  EXPECT_STREQ(BackendName(Backend::kCpu), "cpu");
  for (std::size_t i = 0; i < table.size(); ++i) {
    EXPECT_STREQ(BackendName(static_cast<Backend>(i)), table[i].name);
    EXPECT_EQ(FindBackend(table[i].name), &table[i]);
    EXPECT_EQ(LanguagesOf(static_cast<Backend>(i)), table[i].languages);
  }
  EXPECT_STREQ(BackendName(static_cast<Backend>(table.size())), "unknown");
  EXPECT_EQ(FindBackend("metal"), nullptr);
  EXPECT_EQ(JoinedBackendNames(), "opencl, cuda, gl, vulkan or cpu");
  EXPECT_EQ(JoinedBackendNames(true), "OpenCL, CUDA, GL, Vulkan or CPU");
}

TEST(BackendTable, EveryLanguageRunsOnExactlyOneBackend) {
  std::multiset<Lang> seen;
  for (const BackendEntry& b : Backends()) seen.insert(b.languages.begin(), b.languages.end());
  for (const Language& language : kLanguages) EXPECT_EQ(seen.count(language.lang), 1u) << language.name;
  EXPECT_EQ(seen.size(), kLangCount);
  EXPECT_EQ(LanguagesOf(Backend::kGl), (std::vector<Lang>{Lang::kGlslCompute, Lang::kGlslVertex}));
  EXPECT_EQ(LanguagesOf(Backend::kVulkan), (std::vector<Lang>{Lang::kVulkan}));
  EXPECT_EQ(LanguagesOf(Backend::kCpu), (std::vector<Lang>{Lang::kCpu}));
  EXPECT_EQ(LanguageNames(),
            (std::vector<std::string>{"opencl", "cuda", "glsl-compute", "glsl-vertex", "vulkan", "cpu"}));
}

// configs/*.schema.json are data: every "backend" enum and every device id
// pattern ("^(opencl|cuda|...):") must list this table's names, in its order.
int CheckBackendsInSchema(const nlohmann::json& schema, const nlohmann::json& node, const std::string& where) {
  std::vector<std::string> names;
  std::string pattern = "^(";
  for (const BackendEntry& b : Backends()) {
    names.push_back(b.name);
    pattern += std::string(names.size() > 1 ? "|" : "") + b.name;
  }
  pattern += "):";
  int found = 0;
  if (node.is_object() && node.contains("properties") && node["properties"].contains("backend")) {
    nlohmann::json backend = node["properties"]["backend"];
    if (backend.contains("$ref"))
      backend = schema.at(nlohmann::json::json_pointer(backend["$ref"].get<std::string>().substr(1)));
    EXPECT_EQ(backend.value("enum", nlohmann::json()), nlohmann::json(names)) << where << ".backend";
    ++found;
  }
  if (node.is_object() && node.contains("$defs") && node["$defs"].contains("device_id")) {
    EXPECT_EQ(node["$defs"]["device_id"].value("pattern", ""), pattern) << where << " $defs/device_id";
    ++found;
  }
  if (node.is_structured()) {
    for (const auto& [key, child] : node.items()) found += CheckBackendsInSchema(schema, child, where + "/" + key);
  }
  return found;
}

TEST(BackendTable, SchemasListTheTablesBackends) {
  std::map<std::string, int> found;
  for (const auto& entry : std::filesystem::directory_iterator(std::string(SKINTUNE_SOURCE_DIR) + "/configs")) {
    const std::string name = entry.path().filename().string();
    if (!name.ends_with(".schema.json")) continue;
    std::ifstream in(entry.path());
    const nlohmann::json schema = nlohmann::json::parse(in);
    found[name] = CheckBackendsInSchema(schema, schema, name);
  }
  // Not vacuous: the report's devices and measurements, the database's
  // entries, and both device id patterns were found and read.
  EXPECT_EQ(found["report.schema.json"], 3);
  EXPECT_EQ(found["winners-db.schema.json"], 2);
}

TEST(BackendTable, DiscoveryFindsEveryOpenClDeviceAndSaysWhyAnApiIsMissing) {
  const Discovered all = DiscoverDevices();
  std::set<std::string> with_devices;
  for (const FoundDevice& d : all.devices) {
    ASSERT_NE(FindBackend(d.identity.backend), nullptr) << d.identity.backend;
    with_devices.insert(d.identity.backend);
    EXPECT_EQ(d.identity.index, 0);
    EXPECT_TRUE(d.open) << d.identity.Id();
    if (d.identity.backend != "cpu") {  // cpu: no work-groups
      EXPECT_GT(d.limits.max_wg_size, 0u) << d.identity.Id();
    }
    // The public identity is the same device id.
    EXPECT_EQ(PublicInfo(d.identity).id, d.identity.Id());
    EXPECT_STREQ(BackendName(PublicInfo(d.identity).backend), d.identity.backend.c_str());
  }
  for (const BackendEntry& b : Backends()) {
    if (with_devices.count(b.name)) continue;
    bool said_why = false;
    for (const std::string& s : all.skipped) said_why = said_why || s.rfind(std::string(b.name) + ": ", 0) == 0;
    EXPECT_TRUE(said_why) << b.name << " has no device and no skipped line";
  }
  // Only one API: the others are not looked for.
  const Discovered opencl = DiscoverDevices("opencl");
  EXPECT_EQ(opencl.devices.size(), EnumerateOpenCl().devices.size());
  for (const FoundDevice& d : opencl.devices) EXPECT_EQ(d.identity.backend, "opencl");
  for (const std::string& s : opencl.skipped) EXPECT_EQ(s.rfind("opencl: ", 0), 0u) << s;
  EXPECT_TRUE(DiscoverDevices("metal").devices.empty());
}

TEST(BackendTable, AnOpenClDeviceOpensAsARunnerOfItsApi) {
  const Discovered opencl = DiscoverDevices("opencl");
  if (opencl.devices.empty()) GTEST_SKIP() << "no OpenCL device here";
  const std::unique_ptr<Runner> runner = opencl.devices.front().open();
  ASSERT_NE(runner, nullptr);
  EXPECT_STREQ(runner->api().name(), "OpenCL");
  EXPECT_EQ(runner->device_name(), opencl.devices.front().identity.name);
}

}  // namespace
}  // namespace skintune::internal
