// skintune: reading a file from outside (docs/INPUTS.md, "Limits").
//
// Every reader of a file a user names (a config, a report, a paper result, a
// winners database, a measurement cache, a glTF model, skinned vertices, a
// program-cache entry) checks its kind and size before reading a byte: a
// directory, a FIFO (which would block the open or the read forever), a device
// such as /dev/zero (endless) or a file larger than its reader's cap is one
// error naming the file, never a hang or an allocation without bound. The
// checks are made on the open descriptor (opened without blocking), so the
// file read is the file checked.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace skintune::internal {

// The largest input each reader takes. A JSON document in memory is ~10x its
// text, so the JSON caps keep a parse within a few GiB; skintune writes files
// far smaller (a report of 100,000 measurements is ~100 MiB).
struct InputCap {
  const char* what;     // "a JSON file": said in the error
  std::uint64_t bytes;  // the largest size accepted
};
inline constexpr InputCap kJsonInput{"a JSON file", 256ull << 20};
inline constexpr InputCap kMeasurementCacheInput{"a measurement cache", 1ull << 30};
// glTF: a .glb's header counts its length in 32 bits; a .gltf's buffers are files of their own.
inline constexpr InputCap kGltfInput{"a glTF file or buffer", 4ull << 30};
// Skinned vertices (.stv, .obj) of up to 2^32 - 1 vertices with normals.
inline constexpr InputCap kSkinnedVerticesInput{"a skinned-vertex file", 256ull << 30};
inline constexpr InputCap kProgramCacheInput{"a program-cache file", 1ull << 30};

// The size of the regular file at `path`, checked as above; Error("<path>:
// cannot open file (No such file or directory)" / "is a directory, not a
// file" / "is a FIFO, not a regular file" / "is 8.0 GiB, more than the 256
// MiB a JSON file may have") otherwise.
std::uint64_t CheckInputFile(const std::string& path, const InputCap& cap);

// The whole regular file at `path` (CheckInputFile's checks, then read from
// the same descriptor); Error("<path>: cannot read file (...)") when a read
// fails (/proc/self/mem).
std::string ReadInputFile(const std::string& path, const InputCap& cap);
// The same as bytes (glTF buffers).
std::vector<unsigned char> ReadInputBytes(const std::string& path, const InputCap& cap);

// `text` parsed as JSON; Error("<name>: not valid JSON (...)") for any parse
// error, a number beyond double's range (1e400) included.
nlohmann::json ParseJson(const std::string& text, const std::string& name);

// ParseJson of ReadInputFile(path, kJsonInput).
nlohmann::json ReadJsonFile(const std::string& path);

}  // namespace skintune::internal
