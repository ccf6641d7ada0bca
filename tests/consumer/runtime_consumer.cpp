// Consumer of the installed skintune::runtime: skins CesiumMan's animation at
// one time on PoCL with the tuned kernel of the given database and writes the
// positions as a skintune .stv file (docs/FORMATS.md), for the test to check
// against the reference. A second Device with the same program cache must
// compile nothing.
//   consumer_runtime MODEL.gltf DB.json OUT.stv TIME CACHE_DIR
#include <skintune/skintune.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

namespace {

int Fail(const std::string& what, const skintune::Status& status) {
  std::fprintf(stderr, "consumer_runtime: %s: %s\n", what.c_str(), status.message().c_str());
  return 1;
}

bool WriteStv(const std::string& path, const std::vector<float>& xyz) {
  std::ofstream out(path, std::ios::binary);
  const std::uint32_t header[4] = {0x31565453u /* "STV1" */, static_cast<std::uint32_t>(xyz.size() / 3), 0, 0};
  out.write(reinterpret_cast<const char*>(header), sizeof header);
  out.write(reinterpret_cast<const char*>(xyz.data()), static_cast<std::streamsize>(xyz.size() * sizeof(float)));
  return static_cast<bool>(out);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 6) {
    std::fprintf(stderr, "usage: consumer_runtime MODEL DB OUT.stv TIME CACHE_DIR\n");
    return 2;
  }
  const double t = std::atof(argv[4]);
  skintune::DeviceOptions options;
  options.program_cache_dir = argv[5];
  skintune::Result<skintune::Model> model = skintune::Model::Load(argv[1]);
  if (!model) return Fail("model", model.status());
  skintune::Result<skintune::WinnersDb> db = skintune::WinnersDb::Load(argv[2]);
  if (!db) return Fail("database", db.status());
  std::vector<float> palette, positions(model->vertex_count() * 3);
  if (skintune::Status s = model->Palette(0, t, &palette); !s) return Fail("palette", s);

  int builds[2] = {0, 0};
  for (int start = 0; start < 2; ++start) {  // the second start must load every program from the cache
    skintune::Result<skintune::Device> device = skintune::Device::Open("Portable Computing Language", nullptr, options);
    if (!device) return Fail("device", device.status());
    skintune::Result<skintune::Skinner> skinner = skintune::Skinner::Create(*device, *db, model->mesh());
    if (!skinner) return Fail("skinner", skinner.status());
    skintune::Status s = skinner->SetPalette(palette.data(), palette.size());
    if (s) s = skinner->Skin();
    if (s) s = skinner->ReadPositions(positions.data(), positions.size());
    if (!s) return Fail("skinning", s);
    builds[start] = device->cache_stats().builds;
    if (start == 0)
      std::printf("device: %s\nvariant: %s\nlevel: %s (%s)\n", device->info().id.c_str(),
                  skinner->selection().variant.c_str(), skintune::MatchLevelName(skinner->selection().level),
                  skinner->selection().reason.c_str());
  }
  std::printf("builds: first start %d, second start %d\n", builds[0], builds[1]);
  if (builds[0] < 1 || builds[1] != 0) {
    std::fprintf(stderr, "consumer_runtime: the program cache did not spare the second start its builds\n");
    return 1;
  }
  if (!WriteStv(argv[3], positions)) {
    std::fprintf(stderr, "consumer_runtime: cannot write %s\n", argv[3]);
    return 1;
  }
  return 0;
}
