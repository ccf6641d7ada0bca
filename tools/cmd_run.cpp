// skintune run: the main job on its built-in default. For now: list the
// devices, then skin the default dataset (the paper's Fig. 1 set-up: 100k
// vertices, 77 bones, 2 influences) with the three CPU implementations and
// check them against each other.
#include <algorithm>
#include <chrono>
#include <iomanip>
#include <iostream>

#include "reference/error.h"
#include "reference/skinning.h"
#include "reference/synthetic.h"
#include "runtime/backends/opencl/opencl_devices.h"
#include "tools/commands.h"

namespace skintune::tools {

namespace {

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

int RunDefault(const std::string& key) {
  const OpenClInventory inventory = EnumerateOpenCl();
  std::cout << "== devices\n";
  if (inventory.devices.empty()) std::cout << "OpenCL: skipped: " << inventory.status << "\n";
  for (const OpenClDeviceInfo& d : inventory.devices) {
    std::cout << "OpenCL " << d.platform_index << "." << d.device_index << ": " << d.name << " (" << d.platform_name
              << ", " << d.type << ", " << d.compute_units << " compute units)\n";
  }
  const SkinnedAsset asset = GenerateDataset(ParseDatasetKey(key));
  const SkinnedMesh& mesh = asset.mesh;
  const std::vector<glm::mat4> palette = asset.PaletteAt(0, 0.5);
  std::cout << "== CPU skinning of dataset " << asset.source << ": " << mesh.vertex_count() << " vertices, "
            << mesh.joint_count << " joints, " << mesh.influences << " influences, frame at t=0.5 s\n";
  const std::size_t n = mesh.vertex_count();
  std::vector<glm::vec3> serial(n), fast(n);
  GoldResult gold;
  FastSkinner skinner(mesh);
  const double gold_ms = MedianMs(3, [&] { gold = SkinGold(mesh, palette); });
  const double serial_ms = MedianMs(5, [&] { SkinSerial(mesh, palette, serial); });
  const double fast_ms = MedianMs(5, [&] { skinner.Run(palette, fast); });
  const GoldComparison serial_err = CompareToGold(gold.positions, serial);
  const GoldComparison fast_err = CompareToGold(gold.positions, fast);
  auto line = [&](const char* name, double ms, const GoldComparison* err) {
    std::cout << "  " << std::left << std::setw(7) << name << std::right << std::setw(9) << std::fixed
              << std::setprecision(3) << ms << " ms  " << std::setw(8) << std::setprecision(1) << n / ms / 1e3
              << " Mvertices/s";
    if (err) std::cout << "  max relative error vs gold " << std::scientific << std::setprecision(2) << err->max_relative;
    std::cout << std::defaultfloat << "\n";
  };
  line("gold", gold_ms, nullptr);
  line("serial", serial_ms, &serial_err);
  line("fast", fast_ms, &fast_err);
  std::cout << "  (median wall time of a few runs, informative only: bench/ has the measured figures; fast uses "
            << skinner.threads() << " threads)\n";
  constexpr double kTolerance = 1e-5;
  if (serial_err.max_relative > kTolerance || fast_err.max_relative > kTolerance) {
    throw Error("CPU implementations disagree with the gold beyond " + std::to_string(kTolerance));
  }
  std::cout << "ok: serial and fast agree with the float64 gold within 1e-5\n";
  return 0;
}

}  // namespace

Command RegisterRun(CLI::App& app) {
  auto key = std::make_shared<std::string>("default");
  auto* sub = app.add_subcommand("run", "the main job with built-in defaults: list devices, skin the default dataset");
  sub->add_option("--dataset", *key, "dataset key (default: 100k-b2, the paper's Fig. 1 data set)");
  return {sub, [key] { return RunDefault(*key); }};
}

}  // namespace skintune::tools
