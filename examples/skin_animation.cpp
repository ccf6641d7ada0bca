// skintune example: play a model's animation on the best device with the tuned
// kernel and print frames per second. Uses only <skintune/skintune.h>.
//
//   skin_animation MODEL.gltf|.glb|DATASET [--db winners-db.json] [--device PATTERN]
//                  [--seconds S] [--readback] [--instances K]
//
// DATASET is a synthetic key such as 1600k-b4 (docs/DATA.md). PATTERN picks the
// device as Device::Open does ("cuda:", "gl:", "opencl:NVIDIA", "pocl"). Without --db the
// built-in default kernel runs; with --readback every frame is copied to host
// memory, otherwise it stays on the device (a renderer would draw from it). With
// --instances K one Skinner skins a crowd of K characters in one launch, each at its
// own phase of the animation; frames are SetPalette + Skin without waiting between them.
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
  if (argc < 2)
    return std::fprintf(stderr, "usage: skin_animation MODEL|DATASET [--db F] [--device P] [--seconds S] [--readback] "
                                "[--instances K]\n"), 2;
  std::string path = argv[1], db_path, pattern;
  double seconds = 3.0;
  bool readback = false;
  SkinnerOptions options;
  for (int i = 2; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "--db" && has_value) db_path = argv[++i];
    else if (arg == "--device" && has_value) pattern = argv[++i];
    else if (arg == "--seconds" && has_value) seconds = std::atof(argv[++i]);
    else if (arg == "--readback") readback = true;
    else if (arg == "--instances" && has_value) options.instances = std::atoi(argv[++i]);
    else return std::fprintf(stderr, "skin_animation: unknown or incomplete option '%s'\n", arg.c_str()), 2;
  }
  const std::string extension = path.substr(std::min(path.rfind('.'), path.size()));
  const bool gltf = extension == ".gltf" || extension == ".glb";
  Result<Model> model = gltf ? Model::Load(path) : Model::Synthetic(path);
  if (!model) return Fail(model.status());
  for (const std::string& warning : model->warnings()) std::fprintf(stderr, "warning: %s\n", warning.c_str());

  Result<Device> device = pattern.empty() ? Device::OpenBest() : Device::Open(pattern);
  if (!device) return Fail(device.status());
  Result<WinnersDb> db = db_path.empty() ? Result<WinnersDb>(WinnersDb::Empty()) : WinnersDb::Load(db_path);
  if (!db) return Fail(db.status());
  Result<Skinner> skinner = Skinner::Create(*device, *db, model->mesh(), options);
  if (!skinner) return Fail(skinner.status());
  std::printf("%s: %d x %zu vertices, %d influences, %d joints\ndevice: %s (%s)\nkernel: %s\n  %s: %s\n",
              model->source().c_str(), options.instances, model->vertex_count(), model->influences(),
              model->joint_count(),
              device->info().name.c_str(), BackendName(device->info().backend), skinner->selection().variant.c_str(),
              MatchLevelName(skinner->selection().level), skinner->selection().reason.c_str());

  // One frame: character k's palette at time t + k/K of the animation, skinned, read back or
  // left queued on the device (the next SetPalette waits only when three frames are queued).
  const int animation = model->animation_count() > 0 ? 0 : -1, k_count = options.instances;
  const std::size_t n = model->vertex_count(), joint_floats = std::size_t(model->joint_count()) * 16;
  const double duration = std::max(model->animation_duration(animation), 1e-9);
  std::vector<float> palette(k_count * joint_floats), one, positions(k_count * n * 3), reference;
  auto frame = [&](double t, bool read) {
    Status status;
    for (int k = 0; k < k_count && status; ++k) {
      const double at = model->animation_start(animation) + std::fmod(t + duration * k / k_count, duration);
      if ((status = model->Palette(animation, at, &one)))
        std::copy(one.begin(), one.end(), palette.begin() + k * joint_floats);
    }
    if (status) status = skinner->SetPalette(palette.data(), palette.size());
    if (status) status = skinner->Skin();
    if (status && read) status = skinner->ReadPositions(positions.data(), positions.size());
    return status;
  };
  Status status = frame(0.0, true);  // the first frame, every character checked against the reference
  double error = 0.0, extent = 0.0;
  for (int k = 0; k < k_count && status; ++k) {
    status = model->SkinReference(palette.data() + k * joint_floats, joint_floats, &reference);
    for (std::size_t i = 0; i < reference.size(); ++i) {
      error = std::max(error, std::abs(double(positions[k * n * 3 + i]) - reference[i]));
      extent = std::max(extent, std::abs(double(reference[i])));
    }
  }
  if (!status) return Fail(status);
  std::printf("first frame: largest difference from the reference %.3g (%.2g of the model's extent)\n", error,
              error / extent);
  if (!(error <= 1e-3 * extent)) return Fail(Status(ErrorCode::kDeviceError, "the kernel's output is wrong"));

  int frames = 0;
  double elapsed = 0.0;
  const auto start = std::chrono::steady_clock::now();
  for (; elapsed < seconds; ++frames) {
    if (!(status = frame(std::fmod(elapsed, duration), readback))) return Fail(status);
    elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  if (!(status = skinner->Finish())) return Fail(status);  // the frames still queued count too
  elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("%d frames in %.2f s: %.1f frames/s, %.1f Mvertices/s (%s)\n", frames, elapsed, frames / elapsed,
              frames * double(k_count * n) / elapsed * 1e-6,
              readback ? "read back every frame" : "left on the device");
  return 0;
}
