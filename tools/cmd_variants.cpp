// skintune variants: the kernel variant space, its size, and what a device
// and mesh allow of it (each invalid point counted under the constraint it breaks).
#include <algorithm>
#include <fstream>
#include <iostream>

#include <nlohmann/json.hpp>

#include "generator/axes.h"
#include "generator/space.h"
#include "base/error.h"
#include "model/scene.h"
#include "runtime/backends/opencl/opencl_devices.h"
#include "tools/commands.h"
#include "tuner/datasets.h"  // AllRigid, PalettesRigid
#include "tools/tune_job.h"  // LoadConfigJson
#include "tuner/tune.h"

namespace skintune::internal::tools {

namespace {

struct VariantsOptions {
  std::string device;
  std::string config;
  std::vector<std::string> langs;
  MeshSource source;
  bool list = false;
  bool json = false;
};

TuningSpace LoadSpace(const VariantsOptions& o) {
  nlohmann::json space = nlohmann::json::object();
  if (!o.config.empty()) {
    const nlohmann::json config = LoadConfigJson(o.config);  // a file, or a built-in name as `tune` takes it
    ConfigFromJson(config, o.config);  // a tuning config as `tune` takes it (42, null, [] are not)
    space = config["space"];
  }
  if (!o.langs.empty()) space["lang"] = o.langs;
  return SpaceFromJson(space, o.config.empty() ? "--lang" : o.config);
}

int RunVariants(const VariantsOptions& o) {
  const TuningSpace space = LoadSpace(o);
  DeviceLimits limits;
  std::string device_name = "generic limits (no --device)";
  if (!o.device.empty()) {
    const std::vector<OpenClDeviceInfo> matches = MatchDevices(EnumerateOpenCl(), o.device);
    if (matches.empty()) throw Error("--device '" + o.device + "': no OpenCL device matches (see skintune devices)");
    limits = LimitsOf(matches.front());
    device_name = matches.front().platform_name + " / " + matches.front().name;
  }
  ProblemShape shape{77, 1, true, 1, false, true};
  std::string mesh_name = "the paper's rig (77 joints, any influence count, normals available, rigid palettes)";
  const auto widest_of = [](const SkinnedMesh& mesh) {
    int widest = 1;
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) widest = std::max(widest, mesh.InfluencesOf(v));
    return widest;
  };
  if (!o.source.dataset.empty()) {
    // A scene key as `tune` and `run` take it (5k-b4-x16, a+b batches):
    // the instances count toward the constant and image storage limits.
    const SkinnedScene scene = LoadScene(ParseSceneKey(o.source.dataset));
    shape = WithMorphOf({scene.mesh().joint_count, widest_of(scene.mesh()), scene.mesh().has_normals(),
                         scene.spec.instances, scene.mesh().has_normals() && scene.mesh().has_tangents(),
                         tuner_internal::PalettesRigid(scene)},
                        scene.mesh().morph);
    shape.animated = scene.spec.animated;
    mesh_name = "scene '" + scene.spec.key + "'";
  } else if (!o.source.mesh_file.empty()) {
    const SkinnedAsset asset = LoadAsset(o.source);
    const std::vector<glm::mat4> palette =
        asset.animations.empty() ? asset.PaletteAt(-1, 0.0) : asset.PaletteAt(0, asset.animations.front().start);
    shape = WithMorphOf({asset.mesh.joint_count, widest_of(asset.mesh), asset.mesh.has_normals(), 1,
                         asset.mesh.has_normals() && asset.mesh.has_tangents(), tuner_internal::AllRigid(palette)},
                        asset.mesh.morph);
    mesh_name = asset.source;
  }
  std::vector<std::string> keys;
  const SpaceCount count = Enumerate(space, limits, shape, [&](const Variant& v) {
    if (o.list) keys.push_back(v.Key());
  });
  if (o.json) {
    nlohmann::json out = {{"space", space}, {"device", device_name}, {"mesh", mesh_name},
                          {"total", count.total}, {"valid", count.valid}};
    for (const auto& [constraint, n] : count.invalid_by) out["invalid_by"][Name(constraint)] = n;
    if (o.list) out["variants"] = keys;
    std::cout << out.dump(2) << "\n";
    return 0;
  }
  std::cout << "space: " << count.total << " variants\n"
            << "device: " << device_name << "\nmesh: " << mesh_name << "\n"
            << "valid: " << count.valid << "\n";
  for (const auto& [constraint, n] : count.invalid_by) {
    std::cout << "invalid (" << Name(constraint) << "): " << n << "\n";
  }
  for (const std::string& key : keys) std::cout << key << "\n";
  return 0;
}

}  // namespace

Command RegisterVariants(CLI::App& app) {
  auto o = std::make_shared<VariantsOptions>();
  auto* sub = app.add_subcommand("variants", "list the kernel variant space, its size and what a device allows");
  sub->add_option("--device", o->device,
                  "OpenCL device whose limits apply: a case-insensitive substring of its id "
                  "'<backend>:<platform>/<name>/<driver>', vendor, type or platform short name (pocl), as every "
                  "--device");
  sub->add_option("--config", o->config, "tuning config whose \"space\" restricts the axes: a JSON file, or a built-in name as tune takes it (default: every value)")
      ->check(NonEmptyPath());
  sub->add_option("--lang", o->langs, "restrict to these languages: " + Choices(AxisOf<&Variant::lang>()));
  AddMeshSourceOptions(*sub, o->source);
  sub->add_flag("--list", o->list, "print the key of every valid variant");
  sub->add_flag("--json", o->json, "print JSON");
  return {sub, [o] { return RunVariants(*o); }};
}

}  // namespace skintune::internal::tools
