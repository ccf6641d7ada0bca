// Fuzz target for the glTF importer: ImportGltf reads untrusted files, so for
// any input bytes it must either return or throw Error whose message
// starts with the file name. Anything else (another exception, a crash, a
// sanitizer report, a hang, runaway memory, an anonymous message) is a bug.
// Built two ways (tests/fuzz/CMakeLists.txt): as a libFuzzer target
// (gltf_import_fuzz, clang, -DSKINTUNE_FUZZ=ON) and, with any compiler, into
// gltf_import_fuzz_replay, which runs a corpus through it (replay_main.cpp).
//
// ImportGltf takes a path, so the bytes go to a file in a folder of this
// process's own (relative buffer URIs resolve against that folder only); it is
// rewritten for every input and removed at exit.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <system_error>

#include "base/error.h"
#include "model/gltf_import.h"

using namespace skintune::internal;  // the readers under test and fuzz_support.h's helpers

namespace {

namespace fs = std::filesystem;

[[noreturn]] void Die(const std::string& what) {
  std::fprintf(stderr, "gltf_import_fuzz: %s\n", what.c_str());
  std::abort();
}

fs::path& Folder() {
  static fs::path folder;
  return folder;
}

void RemoveFolder() {
  std::error_code ec;
  fs::remove_all(Folder(), ec);
}

// <temp>/skintune_gltf_fuzz_<pid>/input.gltf, created on first use.
const std::string& InputPath() {
  static const std::string path = [] {
    std::error_code ec;
    fs::path folder = fs::temp_directory_path(ec);
    if (ec) folder = "/tmp";
    folder /= "skintune_gltf_fuzz_" + std::to_string(::getpid());
    fs::create_directories(folder, ec);
    if (ec) Die("cannot create " + folder.string() + ": " + ec.message());
    Folder() = folder;
    std::atexit(RemoveFolder);
    return (folder / "input.gltf").string();
  }();
  return path;
}

void WriteInput(const std::string& path, const std::uint8_t* data, std::size_t size) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (size > 0) out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  out.close();
  if (!out) Die("cannot write " + path);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string& path = InputPath();
  WriteInput(path, data, size);
  for (const bool strict : {false, true}) {
    GltfImportOptions options;
    options.strict = strict;
    try {
      const GltfImportResult result = ImportGltf(path, options);
      // A successful import is a validated asset: touch it so nothing is optimised away.
      if (result.asset.mesh.vertex_count() == 0) Die("imported a mesh without vertices");
    } catch (const Error& e) {
      // Malformed input, reported as gltf_import.h promises: the message starts with the file name.
      if (std::string_view(e.what()).substr(0, path.size() + 2) != path + ": ")
        Die("error message without the file name: " + std::string(e.what()));
    }
  }
  return 0;
}
