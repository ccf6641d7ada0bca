// skintune emit: one variant's kernel file plus a sidecar JSON describing its
// interface (arguments, formats, strides, launch geometry), so another program
// can bind and launch it without reading skintune's code.
#include <algorithm>
#include <filesystem>
#include <iostream>

#include <nlohmann/json.hpp>

#include "generator/constraints.h"
#include "generator/emit.h"
#include "reference/error.h"
#include "reference/mesh_io.h"
#include "tools/commands.h"

namespace skintune::tools {

namespace {

struct EmitArgs {
  std::string variant;
  std::string out;
  int joints = 77;
  int instances = 0;  // 0: the plain kernel; K >= 1: instanced, for up to K instances per launch
};

const char* Extension(Lang lang) {
  switch (lang) {
    case Lang::kOpenCl: return ".cl";
    case Lang::kCuda: return ".cu";
    case Lang::kGlslCompute: return ".comp";
    case Lang::kGlslVertex: return ".vert";
  }
  return ".txt";
}

int RunEmit(const EmitArgs& o) {
  const Variant variant = ParseVariantKey(o.variant);
  // Only the variant's own constraints: device limits are the tuner's business.
  const ProblemShape shape{o.joints, 1, true, std::max(o.instances, 1)};
  DeviceLimits unlimited;
  unlimited.max_wg_size = 1024;
  unlimited.local_memory_bytes = unlimited.constant_memory_bytes = unlimited.uniform_block_bytes = 1u << 30;
  unlimited.image_buffer_max_texels = 1u << 30;
  const std::vector<Violation> broken = CheckVariant(variant, unlimited, shape);
  if (!broken.empty()) {
    throw Error("variant '" + variant.Key() + "' is invalid: " + broken.front().message + " (constraint " +
                Name(broken.front().constraint) + ")");
  }
  EmitOptions options;
  options.instanced = o.instances > 0;
  options.max_instances = o.instances;
  const KernelSource source = Emit(variant, 0, o.joints, options);
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec || !fs::is_directory(o.out)) throw Error(o.out + ": cannot create output folder (" + ec.message() + ")");
  const std::string base = (fs::path(o.out) / (variant.Key() + (options.instanced ? ".instanced" : ""))).string();
  const std::string kernel_file = base + Extension(variant.lang);
  nlohmann::json sidecar = SidecarJson(source, variant);
  sidecar["source_file"] = fs::path(kernel_file).filename().string();
  WriteFileAtomically(kernel_file, source.text);
  WriteFileAtomically(base + ".json", sidecar.dump(2) + "\n");
  std::cout << kernel_file << "\n" << base << ".json\n";
  return 0;
}

}  // namespace

Command RegisterEmit(CLI::App& app) {
  auto o = std::make_shared<EmitArgs>();
  auto* sub = app.add_subcommand("emit", "write one variant's kernel source and its interface (sidecar JSON)");
  sub->add_option("--variant", o->variant, "variant key (see skintune variants --list and docs/VARIANTS.md)")
      ->required();
  sub->add_option("--out", o->out, "output folder (created if missing)")->required();
  sub->add_option("--joints", o->joints, "palette size the kernel is specialised for (default 77)")
      ->check(CLI::Range(1, 65536));
  sub->add_option("--instances", o->instances,
                  "emit the instanced kernel for up to K instances per launch (docs/VARIANTS.md \"Instancing\"); "
                  "files are named <key>.instanced.*")
      ->check(CLI::Range(1, 1 << 20));
  return {sub, [o] { return RunEmit(*o); }};
}

}  // namespace skintune::tools
