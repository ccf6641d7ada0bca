// skintune example: play a model's animation on the best device with the tuned
// kernel and print frames per second. Uses only <skintune/skintune.h>.
//
//   skin_animation MODEL.gltf|.glb|DATASET [--db winners-db.json] [--device PATTERN]
//                  [--seconds S] [--readback]
//
// DATASET is a synthetic key such as 1600k-b4 (docs/DATA.md). PATTERN picks the
// device as Device::Open does ("cuda:", "gl:", "opencl:NVIDIA", "pocl"). Without --db the
// built-in default kernel runs; with --readback every frame is copied to host
// memory, otherwise it stays on the device (a renderer would draw from it).
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
    return std::fprintf(stderr, "usage: skin_animation MODEL|DATASET [--db F] [--device P] [--seconds S] [--readback]\n"), 2;
  std::string path = argv[1], db_path, pattern;
  double seconds = 3.0;
  bool readback = false;
  for (int i = 2; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "--db" && has_value) db_path = argv[++i];
    else if (arg == "--device" && has_value) pattern = argv[++i];
    else if (arg == "--seconds" && has_value) seconds = std::atof(argv[++i]);
    else if (arg == "--readback") readback = true;
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
  Result<Skinner> skinner = Skinner::Create(*device, *db, model->mesh());
  if (!skinner) return Fail(skinner.status());
  std::printf("%s: %zu vertices, %d influences, %d joints\ndevice: %s (%s)\nkernel: %s\n  %s: %s\n",
              model->source().c_str(), model->vertex_count(), model->influences(), model->joint_count(),
              device->info().name.c_str(), BackendName(device->info().backend), skinner->selection().variant.c_str(),
              MatchLevelName(skinner->selection().level), skinner->selection().reason.c_str());

  // One frame: the animation's palette at time t, skinned, read back or waited for.
  const int animation = model->animation_count() > 0 ? 0 : -1;
  std::vector<float> palette, positions(model->vertex_count() * 3), reference;
  auto frame = [&](double t, bool read) {
    Status status = model->Palette(animation, model->animation_start(animation) + t, &palette);
    if (status) status = skinner->SetPalette(palette.data(), palette.size());
    if (status) status = skinner->Skin();
    if (status) status = read ? skinner->ReadPositions(positions.data(), positions.size()) : skinner->Finish();
    return status;
  };
  // The first frame, checked against the float64 reference.
  Status status = frame(0.0, true);
  if (status) status = model->SkinReference(palette.data(), palette.size(), &reference);
  if (!status) return Fail(status);
  double error = 0.0, extent = 0.0;
  for (std::size_t i = 0; i < positions.size(); ++i) {
    error = std::max(error, std::abs(double(positions[i]) - reference[i]));
    extent = std::max(extent, std::abs(double(reference[i])));
  }
  std::printf("first frame: largest difference from the reference %.3g (%.2g of the model's extent)\n", error,
              error / extent);
  if (!(error <= 1e-3 * extent)) return Fail(Status(ErrorCode::kDeviceError, "the kernel's output is wrong"));

  int frames = 0;
  double elapsed = 0.0;
  const double duration = std::max(model->animation_duration(animation), 1e-9);
  const auto start = std::chrono::steady_clock::now();
  for (; elapsed < seconds; ++frames) {
    if (!(status = frame(std::fmod(elapsed, duration), readback))) return Fail(status);
    elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  std::printf("%d frames in %.2f s: %.1f frames/s, %.1f Mvertices/s (%s)\n", frames, elapsed, frames / elapsed,
              frames * double(model->vertex_count()) / elapsed * 1e-6,
              readback ? "read back every frame" : "left on the device");
  return 0;
}
