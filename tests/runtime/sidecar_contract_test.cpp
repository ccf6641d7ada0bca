// The kernel contract (docs/VARIANTS.md "The kernel contract"): a program that
// knows only a kernel's sidecar JSON and the documented rules packs the mesh,
// launches the kernel (bucketed: one kernel per influence count) and gets the
// float64 gold. Everything below reads the sidecar; nothing calls the packer
// (Pack, PackPalette, QuantisedMesh, AosRecordLayout, SoaSplitSlotStride):
// the quantisation rule and the buffer layouts are written here from the
// document. Runs on the first OpenCL device (PoCL here). The bucketed kernels
// of the last tests are what the sidecars' commands write, run as written.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "generator/emit.h"
#include "generator/packer.h"  // the PackedMesh struct the runner takes, filled by hand
#include "model/gltf_import.h"
#include "reference/skinning.h"
#include "tests/common/scratch_dir.h"
#include "tests/runtime/first_opencl_runner.h"

namespace skintune::internal {
namespace {

using json = nlohmann::json;

std::size_t FormatBytes(const std::string& format) {
  if (format == "float4") return 16;
  if (format == "float3") return 12;
  if (format == "i32" || format == "f32") return 4;
  if (format == "u16" || format == "unorm16") return 2;
  if (format == "u8" || format == "unorm8") return 1;
  ADD_FAILURE() << "format " << format << " is not in the document";
  return 0;
}

void PutWord(std::vector<std::uint8_t>& bytes, std::size_t at, std::uint32_t value, std::size_t size) {
  for (std::size_t b = 0; b < size; ++b) bytes.at(at + b) = static_cast<std::uint8_t>(value >> (8 * b));
}
void PutVector(std::vector<std::uint8_t>& bytes, std::size_t at, const glm::vec3& v, std::size_t size, float w) {
  const float xyzw[4] = {v.x, v.y, v.z, w};
  for (std::size_t c = 0; c < size / 4; ++c) PutWord(bytes, at + 4 * c, std::bit_cast<std::uint32_t>(xyzw[c]), 4);
}
std::size_t Words(std::size_t bytes) { return (bytes + 3) / 4 * 4; }  // contract item 6

// Contract item 1, as the sidecar states it: floor, then the missing quanta
// to the largest remainders, ties to the earlier slot.
std::vector<std::uint32_t> Quantise(const float* w, int slots, std::uint32_t max) {
  double sum = 0.0;
  for (int i = 0; i < slots; ++i) sum += w[i];
  std::vector<double> remainder(slots);
  std::vector<std::uint32_t> q(slots);
  std::uint32_t total = 0;
  for (int i = 0; i < slots; ++i) {
    const double t = w[i] > 0.0f ? w[i] / sum * max : 0.0;
    q[i] = static_cast<std::uint32_t>(std::floor(t));
    remainder[i] = w[i] > 0.0f ? t - q[i] : -1.0;
    total += q[i];
  }
  for (; total < max; ++total) {
    const int best = static_cast<int>(std::max_element(remainder.begin(), remainder.end()) - remainder.begin());
    ++q[best];
    remainder[best] = -1.0;
  }
  return q;
}

struct Mesh {
  SkinnedAsset asset;
  std::vector<glm::mat4> palette;
};
const Mesh& CesiumMan() {
  static const Mesh mesh = [] {
    Mesh m;
    m.asset = ImportGltf(std::string(SKINTUNE_TEST_DATA_DIR) + "/CesiumMan.gltf").asset;
    m.palette = m.asset.PaletteAt(0, 0.5);
    return m;
  }();
  return mesh;
}

// One vertex's slots as a launch of `k` influences reads them: padded keeps
// slot i; bucketed compacts the non-zero ones (contract item 8).
struct Slots {
  std::vector<std::uint32_t> joints;
  std::vector<float> weights;
};
Slots SlotsOf(const SkinnedMesh& mesh, std::size_t v, int k, bool bucketed) {
  Slots s;
  for (int i = 0; i < mesh.influences; ++i) {
    const std::size_t at = v * mesh.influences + i;
    if (bucketed && mesh.weights[at] == 0.0f) continue;
    s.joints.push_back(mesh.joints[at]);
    s.weights.push_back(mesh.weights[at]);
  }
  s.joints.resize(k, 0);
  s.weights.resize(k, 0.0f);
  return s;
}

struct Built {
  PackedMesh packed;
  std::vector<KernelSource> kernels;
  std::vector<std::uint8_t> palette;
  SkinnedMesh skinned;  // the mesh with the weights the kernel reads (for the gold)
};

// The buffers of one launch of `k` influences over mesh vertices `vertices`, from `sidecar`.
Launch BuildLaunch(const json& sidecar, const SkinnedMesh& mesh, const std::vector<std::uint32_t>& vertices,
                   std::uint32_t first, int k, SkinnedMesh& skinned) {
  Launch launch;
  launch.first = first;
  launch.count = static_cast<std::uint32_t>(vertices.size());
  launch.influences = k;
  const std::size_t n = vertices.size();
  const json& weights = sidecar.at("weights");
  const bool quantised = weights.contains("max");
  const auto max = quantised ? weights.at("max").get<std::uint32_t>() : 0u;
  const bool bucketed = sidecar.contains("bucketed");
  std::size_t slot_stride = 0;
  if (sidecar.contains("slot_stride_multiple")) {
    const std::size_t m = sidecar.at("slot_stride_multiple");
    slot_stride = (std::max<std::size_t>(n, 1) + m - 1) / m * m;
    launch.slot_stride = static_cast<std::uint32_t>(slot_stride);
  }
  // The weight word of each slot, and the float the kernel then reads.
  auto slots_of = [&](std::size_t p, std::vector<std::uint32_t>& words) {
    const std::size_t v = vertices[p];
    Slots s = SlotsOf(mesh, v, k, bucketed);
    words.assign(k, 0);
    if (quantised) {
      words = Quantise(s.weights.data(), k, max);
      for (int i = 0; i < k; ++i) s.weights[i] = static_cast<float>(words[i]) / static_cast<float>(max);
    } else {
      for (int i = 0; i < k; ++i) words[i] = std::bit_cast<std::uint32_t>(s.weights[i]);
    }
    for (int i = 0; i < mesh.influences; ++i) {  // the gold's mesh: the same slots, kernel weights
      skinned.joints[v * mesh.influences + i] = i < k ? s.joints[i] : 0;
      skinned.weights[v * mesh.influences + i] = i < k ? s.weights[i] : 0.0f;
    }
    return s;
  };
  for (const json& arg : sidecar.at("arguments")) {
    if (arg.at("direction") != "in" || arg.at("kind") == "scalar" || arg.at("name") == "palette") continue;
    const std::string name = arg.at("name");
    const std::string indexing = arg.at("indexing");
    PackedBuffer buffer{name, {}};
    if (name == "records") {
      const json& r = sidecar.at("aos_record");
      const std::size_t size = r.at("size");
      const std::size_t pb = FormatBytes(sidecar.at("variant_axes").at("position"));
      const std::size_t ib = FormatBytes(sidecar.at("variant_axes").at("index"));
      const std::size_t wb = FormatBytes(sidecar.at("variant_axes").at("weight"));
      EXPECT_EQ(arg.at("stride_bytes"), size);
      buffer.bytes.assign(Words(n * size), 0);
      for (std::size_t p = 0; p < n; ++p) {
        std::vector<std::uint32_t> words;
        const Slots s = slots_of(p, words);
        std::size_t at = p * size;
        PutVector(buffer.bytes, at + r.at("position").get<std::size_t>(), mesh.positions[vertices[p]], pb, 1.0f);
        for (int i = 0; i < k; ++i) {
          PutWord(buffer.bytes, at + r.at("indices").get<std::size_t>() + i * ib, s.joints[i], ib);
          PutWord(buffer.bytes, at + r.at("weights").get<std::size_t>() + i * wb, words[i], wb);
        }
        if (r.at("holds_normal").get<bool>())
          PutVector(buffer.bytes, at + r.at("normal").get<std::size_t>(), mesh.normals[vertices[p]], pb, 0.0f);
      }
    } else if (name == "positions" || name == "normals") {
      const std::size_t eb = arg.at("element_bytes");
      EXPECT_EQ(indexing, "v");
      buffer.bytes.assign(Words(n * eb), 0);
      for (std::size_t p = 0; p < n; ++p) {
        const std::size_t v = vertices[p];
        PutVector(buffer.bytes, p * eb, name == "positions" ? mesh.positions[v] : mesh.normals[v], eb,
                  name == "positions" ? 1.0f : 0.0f);
      }
    } else {  // indices, weights: element of vertex p, slot i by `indexing`
      const std::size_t eb = arg.at("element_bytes");
      EXPECT_EQ(eb, FormatBytes(arg.at("format")));
      const bool split = indexing == "i*S+v";
      EXPECT_TRUE(split || indexing == "v*B+i") << indexing;
      const std::size_t elements = split ? k * slot_stride : k * n;
      buffer.bytes.assign(Words(elements * eb), 0);
      for (std::size_t p = 0; p < n; ++p) {
        std::vector<std::uint32_t> words;
        const Slots s = slots_of(p, words);
        for (int i = 0; i < k; ++i) {
          const std::size_t e = split ? i * slot_stride + p : p * k + i;
          PutWord(buffer.bytes, e * eb, name == "indices" ? s.joints[i] : words[i], eb);
        }
      }
    }
    launch.inputs.push_back(std::move(buffer));
  }
  return launch;
}

// Contract item 2: joints x R float4 rows, joint j row r at j*R + r.
std::vector<std::uint8_t> PaletteFromSidecar(const json& sidecar, const std::vector<glm::mat4>& matrices) {
  const json* palette = nullptr;
  for (const json& arg : sidecar.at("arguments"))
    if (arg.at("name") == "palette") palette = &arg;
  const int rows = palette->at("rows_per_joint");
  EXPECT_EQ(palette->at("elements"), static_cast<int>(matrices.size()) * rows);
  EXPECT_EQ(palette->at("stride_bytes"), 16 * rows);
  std::vector<std::uint8_t> bytes(Words(matrices.size() * rows * 16));
  for (std::size_t j = 0; j < matrices.size(); ++j)
    for (int r = 0; r < rows; ++r)
      for (int c = 0; c < 4; ++c)
        PutWord(bytes, ((j * rows + r) * 4 + c) * 4, std::bit_cast<std::uint32_t>(matrices[j][c][r]), 4);
  return bytes;
}

Built BuildFromSidecar(const std::string& key) {
  const Mesh& m = CesiumMan();
  const SkinnedMesh& mesh = m.asset.mesh;
  const Variant variant = ParseVariantKey(key);
  const int joints = mesh.joint_count;
  const json sidecar = SidecarJson(Emit(variant, 0, joints), variant);
  Built b;
  b.skinned = mesh;
  b.packed.variant = variant;
  b.packed.vertex_count = mesh.vertex_count();
  b.packed.palette_joints = static_cast<std::size_t>(joints);
  for (const json& arg : sidecar.at("arguments"))
    if (arg.at("name") == "out_positions") b.packed.output_stride_bytes = arg.at("stride_bytes");
  b.palette = PaletteFromSidecar(sidecar, m.palette);
  b.packed.palette = b.palette;
  const int influences = sidecar.at("influences");
  auto count_of = [&](std::size_t v) {
    int c = 0;
    for (int i = 0; i < mesh.influences; ++i) c += mesh.weights[v * mesh.influences + i] != 0.0f;
    return c;
  };
  std::vector<std::uint32_t> order(mesh.vertex_count());
  std::iota(order.begin(), order.end(), 0u);
  if (!sidecar.contains("bucketed")) {
    b.packed.order = order;
    b.packed.launches.push_back(BuildLaunch(sidecar, mesh, order, 0, influences, b.skinned));
    b.kernels.push_back(Emit(variant, 0, joints));
    return b;
  }
  // Contract item 8: stable ascending sort by count, one launch (and kernel) per count present.
  const json& bucketed = sidecar.at("bucketed");
  EXPECT_TRUE(bucketed.at("bucketed").get<bool>());
  std::stable_sort(order.begin(), order.end(),
                   [&](std::uint32_t a, std::uint32_t c) { return count_of(a) < count_of(c); });
  b.packed.order = order;
  for (std::size_t first = 0; first < order.size();) {
    const int k = count_of(order[first]);
    std::size_t end = first;
    while (end < order.size() && count_of(order[end]) == k) ++end;
    const std::vector<std::uint32_t> bucket(order.begin() + first, order.begin() + end);
    // The bucket's kernel, as the sidecar names it: `skintune emit --variant <key with b<k>>`.
    const json& entry = bucketed.at("kernels").at(k - 1);
    EXPECT_EQ(entry.at("influences"), k);
    const std::string emit = entry.at("emit");
    const std::size_t key_at = emit.find("--variant ") + 10;
    const std::string bucket_key = emit.substr(key_at, emit.find(' ', key_at) - key_at);
    const json bucket_sidecar = SidecarJson(Emit(ParseVariantKey(bucket_key), 0, joints), ParseVariantKey(bucket_key));
    b.packed.launches.push_back(
        BuildLaunch(bucket_sidecar, mesh, bucket, static_cast<std::uint32_t>(first), k, b.skinned));
    b.kernels.push_back(Emit(ParseVariantKey(bucket_key), 0, joints));
    first = end;
  }
  return b;
}

// A packed normal's word decoded by docs/VARIANTS.md "Packed normals and
// tangents", written here from the document (not the header's UnpackNormal).
glm::dvec3 DecodeAsDocumented(const std::string& format, std::uint32_t word) {
  glm::dvec3 n;
  if (format == "oct16") {
    double x = (word & 0xffffu) / 65535.0 * 2.0 - 1.0, y = (word >> 16) / 65535.0 * 2.0 - 1.0;
    const double z = 1.0 - std::abs(x) - std::abs(y), k = std::max(-z, 0.0);
    x -= (x >= 0.0 ? 1.0 : -1.0) * k;
    y -= (y >= 0.0 ? 1.0 : -1.0) * k;
    n = {x, y, z};
  } else {
    for (int c = 0; c < 3; ++c)
      n[c] = std::max(static_cast<std::int8_t>(static_cast<std::uint8_t>(word >> (8 * c))) / 127.0, -1.0);
  }
  return glm::normalize(n);
}

void ExpectMatchesGold(const std::string& key) {
  SCOPED_TRACE(key);
  std::string why;
  OpenClRunner* runner = testing::FirstOpenClRunner(why);
  if (!runner) GTEST_SKIP() << why;
  const Built b = BuildFromSidecar(key);
  const RunResult result = runner->Run(b.packed, b.kernels, b.palette);
  EXPECT_EQ(result.poisoned_vertices, 0u);
  const Variant variant = ParseVariantKey(key);
  const GoldResult gold = SkinGold(b.skinned, CesiumMan().palette, SkinsNormals(variant));
  // Output element p holds mesh vertex order[p] (read by the documented float layout, not Unpack).
  auto read = [&](const std::vector<std::uint8_t>& bytes) {
    std::vector<glm::vec3> out(b.packed.vertex_count);
    for (std::size_t p = 0; p < out.size(); ++p) {
      float xyz[3];
      std::memcpy(xyz, bytes.data() + p * b.packed.output_stride_bytes, sizeof xyz);
      out[b.packed.order[p]] = glm::vec3(xyz[0], xyz[1], xyz[2]);
    }
    return out;
  };
  const GoldComparison positions = CompareToGold(gold.positions, read(result.positions));
  EXPECT_EQ(positions.non_finite, 0u);
  EXPECT_LT(positions.max_relative, 1e-5) << "vertex " << positions.worst_vertex;
  if (SkinsNormals(variant) && !PacksNormals(variant)) {
    const GoldComparison normals = CompareToGold(gold.normals, read(result.normals));
    EXPECT_LT(normals.max_relative, 1e-5) << "vertex " << normals.worst_vertex;
  }
  if (PacksNormals(variant)) {  // one word a vertex, its stride and bound as the sidecar states them
    const json sidecar = SidecarJson(b.kernels.front(), variant);
    const json& format = sidecar.at("normal_format");
    std::size_t stride = 0;
    for (const json& a : sidecar.at("arguments"))
      if (a.at("name") == "out_normals") stride = a.at("stride_bytes").get<std::size_t>();
    ASSERT_EQ(stride, 4u);
    double worst = 0.0;
    for (std::size_t p = 0; p < b.packed.vertex_count; ++p) {
      std::uint32_t word;
      std::memcpy(&word, result.normals.data() + p * stride, 4);
      const glm::dvec3 n = DecodeAsDocumented(format.at("name"), word);
      worst = std::max(worst, glm::length(n - gold.normals[b.packed.order[p]]));
    }
    EXPECT_LT(worst, 1e-5 + format.at("max_error").get<double>());
    EXPECT_GT(worst, 1e-5) << "the words really are packed";
  }
  // The weights really were quantised: the gold of the source weights is further off.
  if (variant.weight != WeightFormat::kF32) {
    const GoldResult source = SkinGold(CesiumMan().asset.mesh, CesiumMan().palette);
    EXPECT_GT(MaxDistance(source.positions, gold.positions), 0.0);
  }
}

TEST(SidecarContract, PaddedSoaSplitImageUnorm8FromTheSidecarAloneMatchesTheGold) {
  ExpectMatchesGold("opencl.b4.padded.soa-split.float3.u16.unorm8.mat3x4.image.matrix.v2s.wg64.nonormals");
}

TEST(SidecarContract, BucketedAosWithNormalsUnorm16FromTheSidecarAloneMatchesTheGold) {
  ExpectMatchesGold("opencl.b4.bucketed.aos.float4.u8.unorm16.mat4.global.point.v1c.wg32.normals");
}

TEST(SidecarContract, PackedNormalsFromTheSidecarAloneDecodeToTheGoldWithinTheirStatedBound) {
  ExpectMatchesGold("opencl.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg64.normals.normals-oct16");
  ExpectMatchesGold("opencl.b4.bucketed.aos.float3.u8.f32.mat4.global.point.v2c.wg32.normals.normals-snorm8");
}

TEST(SidecarContract, PaddedSoaF32ConstantFromTheSidecarAloneMatchesTheGold) {
  ExpectMatchesGold("opencl.b4.padded.soa.float4.i32.f32.mat4.constant.matrix.v4c.wg128.normals");
}

// ------------------------------------------------------------ following the commands

namespace fs = std::filesystem;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in) << path;
  return std::string(std::istreambuf_iterator<char>(in), {});
}

std::string ShellQuoted(const std::string& text) {
  std::string quoted = "'";
  for (const char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

// Runs `command` as a shell would in `dir`, with the built skintune first on
// PATH; returns the sidecar of the files it printed (the .json one).
json RunEmitCommand(const std::string& command, const fs::path& dir) {
  const std::string shell = "cd " + ShellQuoted(dir.string()) + " && PATH=" +
                            ShellQuoted(std::string(SKINTUNE_BINARY_DIR) + "/bin") + ":\"$PATH\" " + command;
  FILE* pipe = ::popen(shell.c_str(), "r");
  EXPECT_NE(pipe, nullptr) << shell;
  if (pipe == nullptr) return json();
  std::string printed;
  char buffer[512];
  while (std::fgets(buffer, sizeof buffer, pipe)) printed += buffer;
  EXPECT_EQ(::pclose(pipe), 0) << "'" << command << "' failed; it printed: " << printed;
  for (std::size_t start = 0, end; (end = printed.find('\n', start)) != std::string::npos; start = end + 1) {
    const fs::path file = fs::path(dir) / printed.substr(start, end - start);
    if (file.extension() == ".json") return json::parse(ReadText(file));
  }
  ADD_FAILURE() << "'" << command << "' wrote no sidecar; it printed: " << printed;
  return json();
}

// The kernel as a program knows it from its sidecar and its source file.
KernelSource KernelFromSidecar(const json& sidecar, const fs::path& dir) {
  KernelSource k;
  k.lang = ParseVariantKey(sidecar.at("variant").get<std::string>()).lang;
  k.entry_point = sidecar.at("entry_point");
  k.text = ReadText(dir / sidecar.at("source_file").get<std::string>());
  k.influences = sidecar.at("influences");
  k.joints = sidecar.at("joints");
  k.instanced = sidecar.contains("instancing");
  if (k.instanced) k.max_instances = sidecar.at("instancing").at("max_instances");
  for (const json& a : sidecar.at("arguments")) {
    k.arguments.push_back({a.at("name"), a.at("format"), a.at("element_bytes"), a.at("stride_bytes"),
                           a.at("indexing"),
                           a.at("direction") == "out" ? ArgumentDirection::kOut : ArgumentDirection::kIn,
                           a.at("kind") == "scalar"  ? ArgumentKind::kScalar
                           : a.at("kind") == "image" ? ArgumentKind::kImage
                                                     : ArgumentKind::kBuffer});
  }
  const json& launch = sidecar.at("launch");
  k.launch.vertices_per_item = launch.at("vertices_per_item");
  k.launch.strided = launch.at("assignment") == "strided";
  k.launch.wg_size = launch.at("wg_size");
  k.launch.instanced = k.instanced;
  k.source_hash = sidecar.at("source_hash");
  return k;
}

// CesiumMan at B = 3 with its 19 joints spread over a palette of `joints`
// entries (joint j at 15j + 7), so a kernel sized for fewer joints reads
// entries it does not hold.
constexpr int kSpreadJoints = 300;
std::uint16_t Spread(std::uint16_t joint) { return static_cast<std::uint16_t>(15 * joint + 7); }

SkinnedMesh SpreadMesh() {
  SkinnedMesh mesh = CesiumMan().asset.mesh;
  CompactInfluences(mesh, 3);
  for (std::uint16_t& j : mesh.joints) j = Spread(j);
  mesh.joint_count = kSpreadJoints;
  return mesh;
}

// Instance i's palette: CesiumMan's pose at its own time on the spread
// joints, a scaling elsewhere (a read of a wrong entry shows).
std::vector<glm::mat4> SpreadPalette(int instance) {
  std::vector<glm::mat4> palette(kSpreadJoints, glm::mat4(7.0f));
  const std::vector<glm::mat4> pose = CesiumMan().asset.PaletteAt(0, 0.2 + 0.3 * instance);
  for (std::size_t j = 0; j < pose.size(); ++j) palette[Spread(static_cast<std::uint16_t>(j))] = pose[j];
  return palette;
}

// Contract item 8 to the letter: `skintune emit` of a bucketed variant, then
// each bucket's kernel from the command its sidecar gives, run as written;
// the buffers from the bucket kernels' sidecars (BuildLaunch), K palettes one
// after another, every instance against its own float64 gold.
void ExpectTheSidecarsCommandsGiveTheGold(const std::string& key, int instances) {
  SCOPED_TRACE(key + " x" + std::to_string(instances));
  std::string why;
  OpenClRunner* runner = testing::FirstOpenClRunner(why);
  if (!runner) GTEST_SKIP() << why;
  const fs::path dir = testing::ScratchDir("sidecar_commands");
  const std::string asked = "skintune emit --variant " + key + " --joints " + std::to_string(kSpreadJoints) +
                            (instances > 1 ? " --instances " + std::to_string(instances) : "") + " --out .";
  const json sidecar = RunEmitCommand(asked, dir);
  ASSERT_TRUE(sidecar.contains("bucketed")) << sidecar.dump(1);
  const SkinnedMesh mesh = SpreadMesh();
  const auto count_of = [&](std::uint32_t v) { return mesh.InfluencesOf(v); };
  Built b;
  b.skinned = mesh;
  b.packed.variant = ParseVariantKey(key);
  b.packed.vertex_count = mesh.vertex_count();
  b.packed.palette_joints = kSpreadJoints;
  b.packed.order.resize(mesh.vertex_count());
  std::iota(b.packed.order.begin(), b.packed.order.end(), 0u);
  std::stable_sort(b.packed.order.begin(), b.packed.order.end(),
                   [&](std::uint32_t a, std::uint32_t c) { return count_of(a) < count_of(c); });
  const std::vector<std::uint32_t>& order = b.packed.order;
  for (std::size_t first = 0; first < order.size();) {
    const int k = count_of(order[first]);
    std::size_t end = first;
    while (end < order.size() && count_of(order[end]) == k) ++end;
    const json bucket = RunEmitCommand(sidecar.at("bucketed").at("kernels").at(k - 1).at("emit"), dir);
    ASSERT_EQ(bucket.at("influences"), k);
    const std::vector<std::uint32_t> vertices(order.begin() + static_cast<std::ptrdiff_t>(first),
                                              order.begin() + static_cast<std::ptrdiff_t>(end));
    b.packed.launches.push_back(BuildLaunch(bucket, mesh, vertices, static_cast<std::uint32_t>(first), k, b.skinned));
    b.kernels.push_back(KernelFromSidecar(bucket, dir));
    for (const json& arg : bucket.at("arguments"))
      if (arg.at("name") == "out_positions") b.packed.output_stride_bytes = arg.at("stride_bytes");
    first = end;
  }
  ASSERT_GT(b.packed.launches.size(), 1u) << "the mesh has one influence count: no buckets to follow";
  std::vector<std::uint8_t> palettes;
  for (int i = 0; i < instances; ++i) {
    const std::vector<std::uint8_t> one = PaletteFromSidecar(sidecar, SpreadPalette(i));
    palettes.insert(palettes.end(), one.begin(), one.end());
  }
  const RunResult result = runner->Run(b.packed, b.kernels, palettes, instances);
  EXPECT_EQ(result.poisoned_vertices, 0u);
  const std::size_t n = b.packed.vertex_count;
  for (int i = 0; i < instances; ++i) {
    std::vector<glm::vec3> out(n);
    for (std::size_t p = 0; p < n; ++p) {
      float xyz[3];
      std::memcpy(xyz, result.positions.data() + (i * n + p) * b.packed.output_stride_bytes, sizeof xyz);
      out[order[p]] = glm::vec3(xyz[0], xyz[1], xyz[2]);
    }
    const GoldComparison c = CompareToGold(SkinGold(b.skinned, SpreadPalette(i)).positions, out);
    EXPECT_EQ(c.non_finite, 0u) << "instance " << i;
    EXPECT_LT(c.max_relative, 1e-5) << "instance " << i << " vertex " << c.worst_vertex;
  }
}

TEST(SidecarContract, BucketKernelsFromTheSidecarsCommandsMatchTheGoldAt300Joints) {
  ExpectTheSidecarsCommandsGiveTheGold("opencl.b3.bucketed.soa.float4.u16.f32.mat4.local.matrix.v1c.wg64.nonormals",
                                       1);
}

TEST(SidecarContract, InstancedBucketKernelsFromTheSidecarsCommandsMatchTheGoldOfEachInstance) {
  ExpectTheSidecarsCommandsGiveTheGold("opencl.b3.bucketed.soa.float4.u16.f32.mat4.local.matrix.v1c.wg64.nonormals",
                                       4);
  ExpectTheSidecarsCommandsGiveTheGold("opencl.b3.bucketed.aos.float3.u16.unorm8.mat3x4.image.point.v2s.wg32.nonormals",
                                       4);
}

}  // namespace
}  // namespace skintune::internal
