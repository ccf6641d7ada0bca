// skintune skin: the CPU reference on a dataset or glTF model, rest pose or
// an animation sampled at a time, written as .obj or skintune's binary format.
#include <chrono>
#include <cmath>
#include <iostream>

#include "reference/error.h"
#include "reference/mesh_io.h"
#include "reference/skinning.h"
#include "tools/commands.h"

namespace skintune::tools {

namespace {

struct SkinOptions {
  MeshSource source;
  std::string animation;
  double time = 0.0;
  bool time_given = false;
  std::string out;
  std::string implementation = "gold";
};

std::vector<glm::vec3> ToFloat(const std::vector<glm::dvec3>& values) {
  return std::vector<glm::vec3>(values.begin(), values.end());
}

int RunSkin(const SkinOptions& o) {
  if (!std::isfinite(o.time)) throw Error("--time must be a finite number of seconds");
  const SkinnedAsset asset = LoadAsset(o.source);
  int clip = -1;
  if (!o.animation.empty()) {
    clip = asset.FindAnimation(o.animation);
  } else if (o.time_given) {
    if (asset.animations.empty()) throw Error(asset.source + ": --time given but it has no animations");
    clip = 0;
  }
  const double t = o.time_given || clip < 0 ? o.time : asset.animations[clip].start;
  const std::vector<glm::mat4> palette = asset.PaletteAt(clip, t);
  const SkinnedMesh& mesh = asset.mesh;
  const std::size_t n = mesh.vertex_count();
  std::vector<glm::vec3> positions(n), normals(o.source.normals && mesh.has_normals() ? n : 0);
  const auto start = std::chrono::steady_clock::now();
  if (o.implementation == "gold") {
    const GoldResult gold = SkinGold(mesh, palette, !normals.empty());
    positions = ToFloat(gold.positions);
    normals = ToFloat(gold.normals);
  } else if (o.implementation == "serial") {
    ThrowIfInvalid(mesh, asset.source);
    SkinSerial(mesh, palette, positions, normals);
  } else {
    FastSkinner(mesh).Run(palette, positions, normals);
  }
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  WriteSkinnedVertices(o.out, positions, normals);
  std::cout << "skinned " << n << " vertices (" << mesh.influences << " influences, " << mesh.joint_count
            << " joints) of " << asset.source << " at "
            << (clip < 0 ? std::string("rest pose") : "t=" + std::to_string(t) + " s of animation " +
                                                          std::to_string(clip))
            << " with " << o.implementation << " in " << ms << " ms -> " << o.out << "\n";
  return 0;
}

}  // namespace

Command RegisterSkin(CLI::App& app) {
  auto o = std::make_shared<SkinOptions>();
  auto* sub = app.add_subcommand("skin", "skin a dataset or glTF model on the CPU and write the positions");
  AddMeshSourceOptions(*sub, o->source);
  sub->add_option("--animation", o->animation, "animation name or index (default: rest pose)");
  sub->add_option("--time", o->time, "time in seconds within the animation (default: its start)")
      ->check(CLI::NonNegativeNumber)
      ->each([o](const std::string&) { o->time_given = true; });
  sub->add_option("--out", o->out, "output file: .obj (v x y z lines) or skintune binary (docs/FORMATS.md)")
      ->required();
  sub->add_flag("--normals", o->source.normals, "also skin and write normals (when the mesh has them)");
  sub->add_option("--impl", o->implementation, "CPU implementation: gold (float64), serial (paper baseline), fast")
      ->check(CLI::IsMember({"gold", "serial", "fast"}));
  return {sub, [o] {
            if (o->source.dataset.empty() && o->source.mesh_file.empty())
              throw Error("skin: give --dataset NAME or --mesh FILE");
            return RunSkin(*o);
          }};
}

}  // namespace skintune::tools
