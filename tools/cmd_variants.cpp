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

// The space to count, and the data sets of the config it came from (none
// without --config).
struct LoadedSpace {
  TuningSpace space;
  std::vector<std::string> datasets;
};

LoadedSpace LoadSpace(const VariantsOptions& o) {
  nlohmann::json space = nlohmann::json::object();
  std::vector<std::string> datasets;
  if (!o.config.empty()) {
    const nlohmann::json config = LoadConfigJson(o.config);  // a file, or a built-in name as `tune` takes it
    datasets = ConfigFromJson(config, o.config).datasets;  // a tuning config as `tune` takes it (42, null, [] are not)
    space = config["space"];
  }
  if (!o.langs.empty()) space["lang"] = o.langs;
  return {SpaceFromJson(space, o.config.empty() ? "--lang" : o.config), datasets};
}

// A mesh the space is counted on: the problem it poses and how it is named;
// for a config's data set, its B, the one influence count `tune` measures it at.
struct CountedMesh {
  ProblemShape shape;
  std::string name;
  int tuned_influences = 0;
};

int WidestOf(const SkinnedMesh& mesh) {
  int widest = 1;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) widest = std::max(widest, mesh.InfluencesOf(v));
  return widest;
}

// A scene key as `tune` and `run` take it (5k-b4-x16, a+b batches, a glTF
// file): the instances count toward the constant and image storage limits.
// `at_its_b`: counted at the scene's B only, as `tune` plans a data set.
CountedMesh SceneMesh(const std::string& key, bool at_its_b) {
  const SkinnedScene scene = LoadScene(ParseSceneKey(key));
  ProblemShape shape = WithMorphOf({scene.mesh().joint_count, WidestOf(scene.mesh()), scene.mesh().has_normals(),
                                    scene.spec.instances, scene.mesh().has_normals() && scene.mesh().has_tangents(),
                                    tuner_internal::PalettesRigid(scene)},
                                   scene.mesh().morph);
  shape.animated = scene.spec.animated;
  return {shape, "scene '" + scene.spec.key + "'", at_its_b ? scene.mesh().influences : 0};
}

CountedMesh AssetMesh(const MeshSource& source) {
  const SkinnedAsset asset = LoadAsset(source);
  const std::vector<glm::mat4> palette =
      asset.animations.empty() ? asset.PaletteAt(-1, 0.0) : asset.PaletteAt(0, asset.animations.front().start);
  return {WithMorphOf({asset.mesh.joint_count, WidestOf(asset.mesh), asset.mesh.has_normals(), 1,
                       asset.mesh.has_normals() && asset.mesh.has_tangents(), tuner_internal::AllRigid(palette)},
                      asset.mesh.morph),
          asset.source, 0};
}

// What the space is counted on: --dataset or --mesh; else the config's data
// sets, each as `tune` would measure it (an animated crowd's forms, a mesh's
// morph targets: values the paper's rig would cut from the space); else the
// paper's rig.
std::vector<CountedMesh> MeshesOf(const VariantsOptions& o, const std::vector<std::string>& config_datasets) {
  if (!o.source.dataset.empty()) return {SceneMesh(o.source.dataset, false)};  // every B that can skin it
  if (!o.source.mesh_file.empty()) return {AssetMesh(o.source)};
  std::vector<CountedMesh> out;
  for (const std::string& key : config_datasets) {
    out.push_back(SceneMesh(key, true));
    out.back().name +=
        " (a data set of " + o.config + ", at its B " + std::to_string(out.back().tuned_influences) + " as tune takes it)";
  }
  if (out.empty())
    out.push_back({ProblemShape{77, 1, true, 1, false, true},
                   "the paper's rig (77 joints, any influence count, normals available, rigid palettes)"});
  return out;
}

int RunVariants(const VariantsOptions& o) {
  const LoadedSpace loaded = LoadSpace(o);
  const TuningSpace& space = loaded.space;
  DeviceLimits limits;
  std::string device_name = "generic limits (no --device)";
  if (!o.device.empty()) {
    const std::vector<OpenClDeviceInfo> matches = MatchDevices(EnumerateOpenCl(), o.device);
    if (matches.empty()) throw Error("--device '" + o.device + "': no OpenCL device matches (see skintune devices)");
    limits = LimitsOf(matches.front());
    device_name = matches.front().platform_name + " / " + matches.front().name;
  }
  const std::vector<CountedMesh> meshes = MeshesOf(o, loaded.datasets);
  nlohmann::json all = nlohmann::json::array();
  for (std::size_t i = 0; i < meshes.size(); ++i) {
    std::vector<std::string> keys;
    TuningSpace counted = space;
    if (meshes[i].tuned_influences > 0)  // tune measures a data set at its B only, if the space holds it
      std::erase_if(counted.influences, [&](int b) { return b != meshes[i].tuned_influences; });
    const SpaceCount count = Enumerate(counted, limits, meshes[i].shape, [&](const Variant& v) {
      if (o.list) keys.push_back(v.Key());
    });
    if (o.json) {
      nlohmann::json out = {{"space", counted}, {"device", device_name}, {"mesh", meshes[i].name},
                            {"total", count.total}, {"valid", count.valid}};
      for (const auto& [constraint, n] : count.invalid_by) out["invalid_by"][Name(constraint)] = n;
      if (o.list) out["variants"] = keys;
      all.push_back(std::move(out));
      continue;
    }
    if (i > 0) std::cout << "\n";
    std::cout << "space: " << count.total << " variants\n"
              << "device: " << device_name << "\nmesh: " << meshes[i].name << "\n"
              << "valid: " << count.valid << "\n";
    for (const auto& [constraint, n] : count.invalid_by) {
      std::cout << "invalid (" << Name(constraint) << "): " << n << "\n";
    }
    for (const std::string& key : keys) std::cout << key << "\n";
  }
  // One mesh: its object, as before; the config's data sets: one each.
  if (o.json) std::cout << (all.size() == 1 ? all[0] : all).dump(2) << "\n";
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
  sub->add_option("--config", o->config, "tuning config whose \"space\" restricts the axes: a JSON file, or a built-in name as tune takes it (default: every value); without --dataset or --mesh, counted on each of its data sets")
      ->check(NonEmptyPath());
  sub->add_option("--lang", o->langs, "restrict to these languages: " + Choices(AxisOf<&Variant::lang>()));
  AddMeshSourceOptions(*sub, o->source);
  sub->add_flag("--list", o->list, "print the key of every valid variant");
  sub->add_flag("--json", o->json, "print JSON");
  return {sub, [o] { return RunVariants(*o); }};
}

}  // namespace skintune::internal::tools
