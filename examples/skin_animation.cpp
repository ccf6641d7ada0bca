// skintune example: play a model's animation on the best device with the tuned
// kernel and print frames per second and the bytes each frame uploads. Uses only
// <skintune/skintune.h> (and CLI11 for its options).
//
//   skin_animation MODEL.gltf|.glb|DATASET [MODEL...] [--db winners-db.json] [--device PATTERN]
//                  [--seconds S] [--readback] [--instances K] [--palette-buffers N] [--host-palettes]
//                  [--bake RATE [--bake-local | --bake-hybrid | --fuse-palette]]
//
// One model is animated on the device (Skinner::CreateAnimated, docs/ANIMATION.md):
// each frame uploads every character's clip and time, 16 bytes a character, and the
// device computes the palettes; with --host-palettes (and with several models) the
// host computes every palette (Model::Palette) and SetPalette uploads them.
// DATASET is a synthetic key such as 1600k-b4 (docs/DATA.md). PATTERN picks the
// device as Device::Open does ("cuda:", "gl:", "opencl:NVIDIA", "pocl"). Without --db the
// built-in default kernel runs; with --readback every frame is copied to host
// memory, otherwise it stays on the device (a renderer would draw from it). With
// --instances K one Skinner skins a crowd of K characters in one launch, each at its
// own phase of its clip (character k plays clip k modulo the model's clips); frames are
// SetAnimation (or SetPalette) + Skin without waiting between them.
// With several models, one Skinner skins them all in one launch (Skinner::CreateBatch:
// a scene of different characters, each playing its own animation), K times with
// --instances K. --palette-buffers N gives the Skinner a ring of N palette
// buffers (SkinnerOptions::palette_buffers: how many frames may be queued before
// SetPalette waits; 3 by default). --bake RATE bakes the model's clips at RATE frames a
// second when the Skinner is made (SkinnerOptions::bake_rate, docs/ANIMATION.md "Baked
// clips") and prints each clip's frames, bytes and largest error; --bake-local bakes
// each node's local transform instead (SkinnerOptions::bake_space, "Baked in local space"),
// --bake-hybrid both ("Hybrid records"); --fuse-palette makes the palettes from those records
// in the skin launch, one launch a frame (SkinnerOptions::fuse_palette, "The palette in the skin launch").
#include <CLI/CLI.hpp>
#include <skintune/skintune.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

using namespace skintune;

static int Fail(const Status& status) {
  std::fprintf(stderr, "skin_animation: %s\n", status.message().c_str());
  return 1;
}

int main(int argc, char** argv) {
  std::vector<std::string> paths;
  std::string db_path, pattern;
  double seconds = 3.0;
  bool readback = false;
  SkinnerOptions options;
  CLI::App app{"skin_animation: play models' animations on one device with the tuned kernel"};
  // '' (an unset variable in a script) names no file: an error, never "no database".
  const CLI::Validator non_empty(
      [](std::string& value) { return value.empty() ? std::string("an empty path names no file") : std::string(); },
      "PATH");
  app.add_option("models", paths, "glTF files (.gltf, .glb) or synthetic dataset keys (1600k-b4)")
      ->required()
      ->check(non_empty);
  app.add_option("--db", db_path, "winners database (skintune tune's winners-db.json)")->check(non_empty);
  app.add_option("--device", pattern, "device pattern as Device::Open takes it (cuda:, gl:, opencl:NVIDIA, pocl)");
  // CLI::Range lets NaN through (every comparison with it is false).
  const CLI::Validator seconds_range(
      [](std::string& value) {
        double v = 0.0;
        if (CLI::detail::lexical_cast(value, v) && v >= 1e-3 && v <= 86400.0) return std::string();
        return "Value " + value + " not in range 0.001 to 86400";
      },
      "SECONDS");
  app.add_option("--seconds", seconds, "how long to play")->check(seconds_range);
  app.add_flag("--readback", readback, "read every frame back to host memory");
  app.add_option("--instances", options.instances, "characters per model, one launch")->check(CLI::Range(1, 1 << 20));
  app.add_option("--palette-buffers", options.palette_buffers, "SkinnerOptions::palette_buffers");
  bool host_palettes = false;
  app.add_flag("--host-palettes", host_palettes, "compute the palettes on the host and upload them (SetPalette)");
  CLI::Option* bake =
      app.add_option("--bake", options.bake_rate, "bake the clips at this many frames a second (SkinnerOptions::bake_rate)")
          ->check(CLI::Range(1e-3, kMaxBakeRate));
  bool bake_local = false;
  app.add_flag("--bake-local", bake_local,
               "bake each node's local transform, not each joint's palette entry (SkinnerOptions::bake_space)")
      ->needs(bake);
  bool bake_hybrid = false;
  app.add_flag("--bake-hybrid", bake_hybrid,
               "bake both: palette records for instances that play one clip, local ones for those that "
               "cross-fade (SkinnerOptions::bake_space kHybrid)")
      ->needs(bake)
      ->excludes("--bake-local");
  app.add_flag("--fuse-palette", options.fuse_palette,
               "make each palette from the baked records (palette, local or hybrid) in the skin launch: no palette "
               "kernel, one launch a frame (SkinnerOptions::fuse_palette)")
      ->needs(bake);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "skin_animation: %s (--help lists the options)\n", e.what());
    return 2;
  }
  if (bake_local) options.bake_space = BakeSpace::kLocal;
  if (bake_hybrid) options.bake_space = BakeSpace::kHybrid;
  std::vector<Model> models;
  std::vector<MeshView> meshes;
  for (const std::string& path : paths) {
    const std::string extension = path.substr(std::min(path.rfind('.'), path.size()));
    const bool gltf = extension == ".gltf" || extension == ".glb";
    Result<Model> model = gltf ? Model::Load(path) : Model::Synthetic(path);
    if (!model) return Fail(model.status());
    for (const std::string& warning : model->warnings()) std::fprintf(stderr, "warning: %s\n", warning.c_str());
    models.push_back(std::move(*model));
  }
  for (const Model& model : models) meshes.push_back(model.mesh());

  Result<Device> device = pattern.empty() ? Device::OpenBest() : Device::Open(pattern);
  if (!device) return Fail(device.status());
  Result<WinnersDb> db = db_path.empty() ? Result<WinnersDb>(WinnersDb::Empty()) : WinnersDb::Load(db_path);
  if (!db) return Fail(db.status());
  // One model with animations: animated on the device; else the host's palettes.
  const bool on_device = models.size() == 1 && !host_palettes && models[0].animation_count() > 0;
  Result<Skinner> skinner = on_device            ? Skinner::CreateAnimated(*device, *db, models[0], options)
                            : models.size() == 1 ? Skinner::Create(*device, *db, meshes[0], options)
                                                 : Skinner::CreateBatch(*device, *db, meshes.data(), meshes.size(), options);
  if (options.bake_rate > 0.0 && !on_device)
    return Fail(Status(ErrorCode::kInvalidArgument, "--bake bakes one model's clips animated on the device (not "
                                                    "with --host-palettes, several models or a model without clips)"));
  if (!skinner) return Fail(skinner.status());
  double baked_error = 0.0;  // the largest of the baked clips' stated errors, of the mesh's diagonal
  for (const BakedClip& clip : skinner->baked_clips()) {
    std::printf("baked clip '%s': %d frames, %zu bytes, largest error %.3g of the mesh's diagonal\n",
                clip.name.c_str(), clip.frames, clip.bytes, clip.max_error);
    baked_error = std::max(baked_error, clip.max_error);
  }
  for (std::size_t m = 0; m < models.size(); ++m)
    std::printf("%s: %d x %zu vertices, %d influences, %d joints\n", models[m].source().c_str(), options.instances,
                models[m].vertex_count(), models[m].influences(), models[m].joint_count());
  std::printf("device: %s (%s)\nkernel: %s (%s)\n  %s: %s\n", device->info().name.c_str(),
              BackendName(device->info().backend), skinner->selection().variant.c_str(),
              SceneShapeName(skinner->shape()), MatchLevelName(skinner->selection().level),
              skinner->selection().reason.c_str());

  // One frame: character k at time t + k/K of its clip (a batch: every model's clip 0, at its
  // place in the palette), skinned, read back or left queued on the device (the next
  // SetAnimation or SetPalette waits only when three frames are queued). The host's palettes
  // are computed for every frame without --host-palettes only for the first, to check it.
  const int k_count = options.instances;
  const std::size_t n = skinner->vertex_count(), joint_floats = std::size_t(skinner->joint_count()) * 16;
  std::vector<float> palette(k_count * joint_floats), one, positions(k_count * n * 3), reference;
  std::vector<AnimationState> states(static_cast<std::size_t>(k_count));
  double last_t = 0.0;  // the last frame's time (AdvanceAnimation moves the clocks by the difference)
  auto animation_of = [&](const Model& model, int k) {
    return model.animation_count() > 0 ? (on_device ? k % model.animation_count() : 0) : -1;
  };
  auto time_of = [&](const Model& model, int animation, double t, int k) {
    const double duration = std::max(model.animation_duration(animation), 1e-9);
    return model.animation_start(animation) + std::fmod(t + duration * k / k_count, duration);
  };
  auto host_palettes_at = [&](double t) {
    Status status;
    for (int k = 0; k < k_count && status; ++k) {
      for (std::size_t m = 0; m < models.size() && status; ++m) {
        const Model& model = models[m];
        const int animation = animation_of(model, k);
        if ((status = model.Palette(animation, time_of(model, animation, t, k), &one)))
          std::copy(one.begin(), one.end(), palette.begin() + k * joint_floats + skinner->joint_offset(m) * 16);
      }
    }
    return status;
  };
  auto frame = [&](double t, bool read) {
    Status status;
    if (on_device && t > 0.0) {  // the clocks advance on the device: nothing uploaded
      status = skinner->AdvanceAnimation(static_cast<float>(t - last_t));
    } else if (on_device) {  // the first frame: every character's clip and time
      for (int k = 0; k < k_count; ++k) {
        const int animation = animation_of(models[0], k);
        states[k] = {animation, static_cast<float>(time_of(models[0], animation, t, k))};
      }
      status = skinner->SetAnimation(states.data(), states.size());
    } else if ((status = host_palettes_at(t))) {
      status = skinner->SetPalette(palette.data(), palette.size());
    }
    if (status) status = skinner->Skin();
    if (status && read) status = skinner->ReadPositions(positions.data(), positions.size());
    last_t = t;
    return status;
  };
  // What a frame uploads: on the device, every character's clip and time once (16 bytes each),
  // then nothing; else every palette (48 bytes a joint in mat3x4, else 64).
  const bool rows3 = skinner->selection().variant.find(".mat3x4.") != std::string::npos;
  const std::size_t upload_bytes = on_device ? 0 : std::size_t(k_count) * skinner->joint_count() * (rows3 ? 48 : 64);
  std::printf("palettes: %s, %zu bytes uploaded per frame\n",
              !on_device ? "computed on the host (Model::Palette, SetPalette)"
              : options.fuse_palette
                  ? "made in the skin launch; the first frame uploads each character's clip and time (SetAnimation), "
                    "later ones pass the time since with the launch (AdvanceAnimation; the clocks go up again "
                    "every 16 s of it)"
                  : "computed on the device; the first frame uploads each character's clip and time "
                    "(SetAnimation), later ones advance the clocks there (AdvanceAnimation)",
              upload_bytes);
  Status status = frame(0.0, true);  // the first frame, every character checked against the reference
  if (status && on_device) status = host_palettes_at(0.0);
  double error = 0.0, extent = 0.0;
  for (int k = 0; k < k_count && status; ++k) {
    for (std::size_t m = 0; m < models.size() && status; ++m) {
      const std::size_t joints = std::size_t(models[m].joint_count()) * 16;
      status = models[m].SkinReference(palette.data() + k * joint_floats + skinner->joint_offset(m) * 16, joints,
                                       &reference);
      const std::size_t first = (k * n + skinner->vertex_offset(m)) * 3;
      for (std::size_t i = 0; i < reference.size(); ++i) {
        error = std::max(error, std::abs(double(positions[first + i]) - reference[i]));
        extent = std::max(extent, std::abs(double(reference[i])));
      }
    }
  }
  if (!status) return Fail(status);
  std::printf("first frame: largest difference from the reference %.3g (%.2g of the models' extent)\n", error,
              error / extent);
  // Baked clips may be off by their stated error (of the diagonal, at most 2 sqrt(3) x the extent).
  if (!(error <= (1e-3 + 1.25 * 2 * std::sqrt(3.0) * baked_error) * extent))
    return Fail(Status(ErrorCode::kDeviceError, "the kernel's output is wrong"));

  // Every frame at the wall clock's time since the start; each clip loops (on the host:
  // time_of; on the device: AdvanceAnimation's clocks loop in their clips).
  int frames = 0;
  double elapsed = 0.0;
  const auto start = std::chrono::steady_clock::now();
  for (; elapsed < seconds; ++frames) {
    if (!(status = frame(elapsed, readback))) return Fail(status);
    elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  if (!(status = skinner->Finish())) return Fail(status);  // the frames still queued count too
  elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("%d frames in %.2f s: %.1f frames/s, %.1f Mvertices/s (%s), %zu bytes uploaded per frame\n", frames,
              elapsed, frames / elapsed, frames * double(k_count * n) / elapsed * 1e-6,
              readback ? "read back every frame" : "left on the device", upload_bytes);
  return 0;
}
