#include "reference/mesh_io.h"

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/error.h"
#include "base/input_file.h"
#include "base/memory_limit.h"
#include "reference/skinning.h"

namespace skintune::internal {

namespace {

constexpr char kMagic[4] = {'S', 'T', 'V', '1'};

void AppendU32(std::string& out, std::uint32_t value) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>((value >> (8 * i)) & 0xffu));
}

std::uint32_t ReadU32(const std::string& data, std::size_t offset) {
  std::uint32_t value = 0;
  for (int i = 0; i < 4; ++i) value |= std::uint32_t(static_cast<unsigned char>(data[offset + i])) << (8 * i);
  return value;
}

void AppendFloats(std::string& out, std::span<const glm::vec3> values) {
  static_assert(sizeof(glm::vec3) == 12);
  const std::size_t at = out.size();
  out.resize(at + values.size() * sizeof(glm::vec3));
  if (!values.empty()) std::memcpy(out.data() + at, values.data(), values.size() * sizeof(glm::vec3));
}

std::string EncodeObj(std::span<const glm::vec3> positions, std::span<const glm::vec3> normals) {
  std::string out;
  out.reserve(positions.size() * 40);
  char line[128];
  for (const glm::vec3& p : positions) {
    out.append(line, std::snprintf(line, sizeof line, "v %.9g %.9g %.9g\n", p.x, p.y, p.z));
  }
  for (const glm::vec3& n : normals) {
    out.append(line, std::snprintf(line, sizeof line, "vn %.9g %.9g %.9g\n", n.x, n.y, n.z));
  }
  return out;
}

std::string EncodeBinary(std::span<const glm::vec3> positions, std::span<const glm::vec3> normals,
                         std::span<const glm::vec4> tangents) {
  std::string out(kMagic, 4);
  AppendU32(out, static_cast<std::uint32_t>(positions.size()));
  AppendU32(out, (normals.empty() ? 0u : 1u) | (tangents.empty() ? 0u : 2u));
  AppendU32(out, 0u);
  AppendFloats(out, positions);
  AppendFloats(out, normals);
  static_assert(sizeof(glm::vec4) == 16);
  const std::size_t at = out.size();
  out.resize(at + tangents.size() * sizeof(glm::vec4));
  if (!tangents.empty()) std::memcpy(out.data() + at, tangents.data(), tangents.size() * sizeof(glm::vec4));
  return out;
}

SkinnedVertices DecodeObj(const std::string& path, const std::string& data) {
  SkinnedVertices result;
  std::istringstream in(data);
  std::string line;
  for (std::size_t number = 1; std::getline(in, line); ++number) {
    std::istringstream fields(line);
    std::string tag;
    glm::vec3 v;
    if (!(fields >> tag)) continue;
    if (tag != "v" && tag != "vn") continue;
    if (!(fields >> v.x >> v.y >> v.z)) throw Error(path + ": line " + std::to_string(number) + ": malformed '" + tag + "'");
    (tag == "v" ? result.positions : result.normals).push_back(v);
  }
  return result;
}

SkinnedVertices DecodeBinary(const std::string& path, const std::string& data) {
  if (data.size() < 16 || std::memcmp(data.data(), kMagic, 4) != 0) {
    throw Error(path + ": not a skintune vertex file (magic 'STV1' missing)");
  }
  const std::size_t n = ReadU32(data, 4);
  const std::uint32_t flags = ReadU32(data, 8);
  if ((flags & ~3u) != 0) throw Error(path + ": unknown flags " + std::to_string(flags) + " (bit 0 normals, bit 1 tangents)");
  const bool normals = (flags & 1u) != 0, tangents = (flags & 2u) != 0;
  const std::size_t expected =
      16 + n * sizeof(glm::vec3) * (normals ? 2 : 1) + (tangents ? n * sizeof(glm::vec4) : 0);
  if (data.size() != expected) {
    throw Error(path + ": size " + std::to_string(data.size()) + " bytes, expected " + std::to_string(expected) +
                " for " + std::to_string(n) + " vertices");
  }
  SkinnedVertices result;
  result.positions.resize(n);
  if (n) std::memcpy(result.positions.data(), data.data() + 16, n * sizeof(glm::vec3));
  if (normals) {
    result.normals.resize(n);
    if (n) std::memcpy(result.normals.data(), data.data() + 16 + n * sizeof(glm::vec3), n * sizeof(glm::vec3));
  }
  if (tangents) {
    result.tangents.resize(n);
    const std::size_t at = 16 + n * sizeof(glm::vec3) * (normals ? 2 : 1);
    if (n) std::memcpy(result.tangents.data(), data.data() + at, n * sizeof(glm::vec4));
  }
  return result;
}

}  // namespace

bool IsObjPath(const std::string& path) {
  if (path.size() < 4) return false;
  std::string ext = path.substr(path.size() - 4);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".obj";
}

void WriteFileAtomically(const std::string& path, const std::string& contents) {
  const std::string temp = path + ".tmp." + std::to_string(::getpid());
  {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    if (!out) throw Error(path + ": cannot write (" + std::strerror(errno) + ")");
    out.write(contents.data(), static_cast<std::streamsize>(contents.size()));
    out.flush();
    if (!out) {
      std::remove(temp.c_str());
      throw Error(path + ": write failed (" + std::strerror(errno) + ")");
    }
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    std::remove(temp.c_str());
    throw Error(path + ": cannot replace (" + std::strerror(err) + ")");
  }
}

void CheckWritable(const std::string& path) {
  struct stat info {};
  if (::stat(path.c_str(), &info) == 0 && S_ISDIR(info.st_mode))
    throw Error(path + ": is a folder, cannot be written as a file");
  const std::string temp = path + ".tmp." + std::to_string(::getpid());
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int err = errno;
    throw Error(path + ": cannot write (" + std::strerror(err) + ")");
  }
  ::close(fd);
  ::unlink(temp.c_str());
}

void WriteSkinnedVertices(const std::string& path, std::span<const glm::vec3> positions,
                          std::span<const glm::vec3> normals, std::span<const glm::vec4> tangents) {
  if (!normals.empty() && normals.size() != positions.size()) {
    throw Error(path + ": " + std::to_string(normals.size()) + " normals for " + std::to_string(positions.size()) +
                " positions");
  }
  if (!tangents.empty() && tangents.size() != positions.size()) {
    throw Error(path + ": " + std::to_string(tangents.size()) + " tangents for " + std::to_string(positions.size()) +
                " positions");
  }
  if (!tangents.empty() && IsObjPath(path))
    throw Error(path + ": a .obj file holds no tangents; nothing written (write skintune's binary format)");
  if (const std::size_t v = FirstNonFinite(tangents); v < tangents.size())
    throw Error(path + ": vertex " + std::to_string(v) + ": tangent is not finite; nothing written");
  // The last line of defence (callers name the origin first, CheckSkinnedOutput):
  // a NaN written as "-nan" is not even readable back.
  for (const auto& [values, what] : {std::pair{positions, "position"}, std::pair{normals, "normal"}}) {
    const std::size_t v = FirstNonFinite(values);
    if (v < values.size())
      throw Error(path + ": vertex " + std::to_string(v) + ": " + what + " is not finite; nothing written");
  }
  if (positions.size() > kMaxVertexCount)
    throw Error(path + ": " + std::to_string(positions.size()) + " vertices, more than the " +
                std::to_string(kMaxVertexCount) + " a vertex file can hold");
  WriteFileAtomically(path, IsObjPath(path) ? EncodeObj(positions, normals) : EncodeBinary(positions, normals, tangents));
}

SkinnedVertices ReadSkinnedVertices(const std::string& path) {
  const std::uint64_t size = CheckInputFile(path, kSkinnedVerticesInput);
  const MemoryAvailable available = HostMemoryAvailable();
  if (available.bytes > 0 && size > available.bytes)
    throw Error(path + ": is " + FormatBytes(size) + " but " + FormatBytes(available.bytes) +
                " of memory are available (" + available.from + ")");
  const std::string data = ReadInputFile(path, kSkinnedVerticesInput);
  return IsObjPath(path) ? DecodeObj(path, data) : DecodeBinary(path, data);
}

}  // namespace skintune::internal
