// skintune: writing (and reading back) skinned vertex output.
//
// Wavefront .obj: one "v x y z" line per vertex in the mesh's vertex order
// (then "vn x y z" lines when normals are given), nothing else.
//
// skintune binary vertex file (.stv), little-endian, documented in docs/FORMATS.md:
//   offset 0  char[4]  magic "STV1"
//   offset 4  uint32   vertex count N
//   offset 8  uint32   flags: bit 0 = normals present, bit 1 = tangents present
//   offset 12 uint32   reserved, 0
//   offset 16 float32  positions, N x (x, y, z)
//   then      float32  normals,   N x (x, y, z), when flag bit 0 is set
//   then      float32  tangents,  N x (x, y, z, w), when flag bit 1 is set
//
// Writes are atomic: data goes to a temporary file beside the target that is
// renamed over it only when complete, so a failure never truncates an existing file.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "model/mesh.h"  // kMaxVertexCount

namespace skintune::internal {

// Whether `path` names a .obj file (case-insensitive): the format WriteSkinnedVertices picks.
bool IsObjPath(const std::string& path);

// Chooses the format by extension: ".obj" (case-insensitive) -> obj, else binary.
// Throws Error("<path>: ...") when the file cannot be written, and without
// writing anything for a NaN or infinite value ("<path>: vertex V: position
// is not finite; nothing written") or more than kMaxVertexCount vertices.
// Tangents go to the binary format only (a .obj path with tangents is an error).
void WriteSkinnedVertices(const std::string& path, std::span<const glm::vec3> positions,
                          std::span<const glm::vec3> normals = {}, std::span<const glm::vec4> tangents = {});

struct SkinnedVertices {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;
  std::vector<glm::vec4> tangents;
};

// Reads either format back. Throws Error("<path>: ...") on malformed input.
SkinnedVertices ReadSkinnedVertices(const std::string& path);

// Writes `contents` to `path` atomically (temporary file + rename).
void WriteFileAtomically(const std::string& path, const std::string& contents);

// Throws Error("<path>: ...") unless WriteFileAtomically(path) can succeed as
// far as can be told before the work: `path` is not a folder and its folder
// takes a new file (the temporary file is created and removed; an existing
// `path` is not touched). Commands check every output first, so that a long
// run never ends in "cannot write".
void CheckWritable(const std::string& path);

}  // namespace skintune::internal
