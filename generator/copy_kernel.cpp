#include "generator/copy_kernel.h"

#include <cstdint>
#include <algorithm>
#include <cstring>
#include <limits>
#include <numeric>
#include <string>

#include <glm/glm.hpp>

#include "base/error.h"

namespace skintune::internal {

namespace {

CopyKernel EmitCopyOrFlush(Lang lang, std::size_t bytes, bool flush) {
  CopyKernel copy;
  copy.items = bytes / 32 > 0 ? bytes / 32 : 1;
  if (copy.items > std::numeric_limits<std::uint32_t>::max())
    throw Error("copy of " + std::to_string(bytes) + " bytes: more than 2^32 - 1 items of 16 bytes");
  const std::size_t per_group_run = kCopyMaxGroups * static_cast<std::size_t>(kCopyWorkGroup);
  int per_item = 1;  // a power of two, as VERTICES_PER_ITEM must be (templates/skin_params.h)
  while (per_item < 8 && static_cast<std::size_t>(per_item) * per_group_run < copy.items) per_item *= 2;
  if (static_cast<std::size_t>(per_item) * per_group_run < copy.items)
    throw Error("copy of " + std::to_string(bytes) + " bytes: more than " + std::to_string(8 * per_group_run) +
                " items of 16 bytes");

  Variant variant;  // what the APIs read of a launch's variant: its language, a global palette, no normals
  const Language& language = LanguageOf(lang);  // its copy template and language: its API's
  variant.lang = language.copy_lang;
  variant.influences = 1;
  variant.storage = PaletteStorage::kGlobal;
  variant.wg_size = kCopyWorkGroup;
  variant.vertices_per_item = per_item;
  variant.assignment = Assignment::kStrided;
  variant.normals = Normals::kNone;

  KernelSource& k = copy.kernel;
  k.lang = variant.lang;
  k.entry_point = IsGlslText(variant.lang) ? "main" : "skintune_copy";
  k.influences = 1;
  k.defines = {{"WG_SIZE", kCopyWorkGroup}, {"VERTICES_PER_ITEM", per_item}};
  if (flush) k.defines.emplace_back("SKINTUNE_FLUSH", 1);
  const auto scalar = [](const char* name) {
    return KernelArgument{name, "u32", 4, 0, "", ArgumentDirection::kIn, ArgumentKind::kScalar};
  };
  k.arguments = {scalar("n"), scalar("first"),
                 {"copy_in", "uint4", 16, 16, "v", ArgumentDirection::kIn, ArgumentKind::kBuffer},
                 {"out_positions", "uint4", 16, 16, "first+v", ArgumentDirection::kOut, ArgumentKind::kBuffer}};
  k.launch.vertices_per_item = per_item;
  k.launch.strided = true;
  k.launch.wg_size = kCopyWorkGroup;
  k.launch.rule = "work items = ceil(n / " + std::to_string(per_item) + ") rounded up to a multiple of " +
                  std::to_string(kCopyWorkGroup) + "; item g copies g, g+G, .. below n (G = work items)";

  // The size is the argument n, not in the text: every copy and flush of one
  // language and VERTICES_PER_ITEM is one program, compiled once per process
  // (each packing's copy compiled anew cost NVIDIA's OpenCL ~80 ms a packing,
  // 2.5 s of a default run on the H200 machine, December 2026).
  const std::string heading = std::string(flush ? "the flush" : "the copy") + ": n items of 16 bytes";
  k.text = SpecialisedText(language.copy_template, heading, k.defines);
  k.source_hash = SourceHash(k.text);

  PackedMesh& mesh = copy.mesh;
  mesh.variant = variant;
  mesh.vertex_count = copy.items;
  Launch launch;
  launch.first = 0;
  launch.count = static_cast<std::uint32_t>(copy.items);
  launch.influences = 1;
  launch.inputs.push_back({"copy_in", std::vector<std::uint8_t>(copy.items * 16)});
  // A pattern no copy can elide or compress: each word a hash of its index
  // (murmur3's finalizer), in blocks the compiler vectorises. A serial LCG
  // took 2.3 s of CPU time for the 960 MB probe of a 480 MiB cache, this
  // 0.8 s with the pages' first touch (2-core machine, 2026-12-01).
  std::uint8_t* in = launch.inputs.back().bytes.data();
  constexpr std::size_t kBlock = 1024;
  std::uint32_t block[kBlock];
  for (std::size_t w0 = 0; w0 < copy.items * 4; w0 += kBlock) {
    const std::size_t n = std::min(kBlock, copy.items * 4 - w0);
    for (std::size_t i = 0; i < n; ++i) {
      std::uint32_t x = static_cast<std::uint32_t>(w0 + i) * 0x9e3779b9u + 0x7f4a7c15u;
      x ^= x >> 16;
      x *= 0x85ebca6bu;
      x ^= x >> 13;
      x *= 0xc2b2ae35u;
      block[i] = x ^ (x >> 16);
    }
    std::memcpy(in + w0 * 4, block, n * 4);
  }
  mesh.launches.push_back(std::move(launch));
  mesh.palette = PackPalette(std::vector<glm::mat4>{glm::mat4(1.0f)}, variant);
  mesh.palette_joints = 1;
  mesh.output_stride_bytes = 16;
  mesh.order.resize(copy.items);
  std::iota(mesh.order.begin(), mesh.order.end(), 0u);
  return copy;
}

}  // namespace

CopyKernel EmitCopy(Lang lang, std::size_t bytes) { return EmitCopyOrFlush(lang, bytes, false); }

CopyKernel EmitFlush(Lang lang, std::size_t read_bytes) { return EmitCopyOrFlush(lang, 2 * read_bytes, true); }

std::size_t FlushBytes(std::uint64_t llc_bytes, bool cpu) {
  const std::uint64_t llc = llc_bytes ? llc_bytes : kUnknownCacheBytes;
  const std::uint64_t bytes = std::max<std::uint64_t>(2 * llc, 8ull << 20);
  return static_cast<std::size_t>(cpu ? std::min(bytes, kCpuFlushCapBytes) : bytes);
}

}  // namespace skintune::internal
