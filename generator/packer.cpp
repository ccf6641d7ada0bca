#include "generator/packer.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

#if defined(__SSE2__) || defined(__x86_64__)
#include <immintrin.h>
#endif

#include "base/error.h"
#include "templates/embedded_support.h"  // QuantiseVertex

namespace skintune::internal {
namespace {

std::size_t RoundUp(std::size_t x, std::size_t multiple) { return (x + multiple - 1) / multiple * multiple; }

std::string Context(const Variant& variant) { return "pack " + variant.Key(); }

[[noreturn]] void Fail(const Variant& variant, const std::string& message) {
  throw Error(Context(variant) + ": " + message);
}

// ------------------------------------------------------------ little-endian words

// Whole-word stores and loads on a little-endian host (a loop of byte stores
// made packing a 100k-vertex mesh 2-6 ms of every tuner measurement);
// byte by byte elsewhere.
void PutUint(std::uint8_t* at, std::uint32_t value, std::size_t bytes) {
  if constexpr (std::endian::native == std::endian::little) {
    switch (bytes) {
      case 1: *at = static_cast<std::uint8_t>(value); return;
      case 2: { const auto half = static_cast<std::uint16_t>(value); std::memcpy(at, &half, 2); return; }
      case 4: std::memcpy(at, &value, 4); return;
      default: break;
    }
  }
  for (std::size_t b = 0; b < bytes; ++b) at[b] = static_cast<std::uint8_t>(value >> (8 * b));
}

void PutFloat(std::uint8_t* at, float value) { PutUint(at, std::bit_cast<std::uint32_t>(value), 4); }

float GetFloat(const std::uint8_t* at) {
  std::uint32_t bits = 0;
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(&bits, at, 4);
  } else {
    for (int b = 0; b < 4; ++b) bits |= static_cast<std::uint32_t>(at[b]) << (8 * b);
  }
  return std::bit_cast<float>(bits);
}

// xyz, then w for float4 (1 for positions, 0 for normals).
void PutVector(std::uint8_t* at, const glm::vec3& v, PositionFormat format, float w) {
  PutFloat(at, v.x);
  PutFloat(at + 4, v.y);
  PutFloat(at + 8, v.z);
  if (format == PositionFormat::kFloat4) PutFloat(at + 12, w);
}

// A tangent's four floats: xyz, then w (the handedness).
void PutTangent(std::uint8_t* at, const glm::vec4& t) {
  for (int c = 0; c < 4; ++c) PutFloat(at + 4 * c, t[c]);
}

// ------------------------------------------------------------ weights

std::uint32_t UnormMax(WeightFormat format) { return format == WeightFormat::kUnorm16 ? 65535u : 255u; }

// The 32-bit value stored for every weight slot of the mesh: the float's bits
// for f32, the quantised integer for unorm16 / unorm8.
std::vector<std::uint32_t> WeightWords(const SkinnedMesh& mesh, WeightFormat format) {
  std::vector<std::uint32_t> words(mesh.weights.size());
  if (format == WeightFormat::kF32) {
    std::transform(mesh.weights.begin(), mesh.weights.end(), words.begin(),
                   [](float w) { return std::bit_cast<std::uint32_t>(w); });
    return words;
  }
  const auto b = static_cast<std::size_t>(mesh.influences);
  // The quantisation rule of docs/VARIANTS.md (the kernel contract's item 1)
  // is the generated header's own code: one implementation for skintune's
  // packer and every program that packs with the header's PackMesh.
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v)
    skintune_kernels::detail::QuantiseVertex(&mesh.weights[v * b], mesh.influences, UnormMax(format), &words[v * b]);
  return words;
}

// ------------------------------------------------------------ checks

void CheckFit(const SkinnedMesh& mesh, const Variant& variant) {
  ThrowIfInvalid(mesh, Context(variant));
  const int b = variant.influences;
  if (b < 1 || b > kMaxInfluences)
    Fail(variant, "influences " + std::to_string(b) + " outside 1.." + std::to_string(kMaxInfluences));
  if (mesh.vertex_count() > std::numeric_limits<std::uint32_t>::max())
    Fail(variant, std::to_string(mesh.vertex_count()) + " vertices do not fit 32-bit vertex indices");
  const std::size_t joint_limit =
      variant.index == IndexFormat::kU8 ? 256 : variant.index == IndexFormat::kU16 ? 65536 : 0x80000000u;
  if (static_cast<std::size_t>(mesh.joint_count) > joint_limit)
    Fail(variant, std::to_string(mesh.joint_count) + " joints do not fit " + Name(variant.index) +
                      " indices (at most " + std::to_string(joint_limit) + ")");
  if (SkinsNormals(variant) && !mesh.has_normals())
    Fail(variant, "normals requested but the mesh '" + mesh.name + "' has none");
  if (SkinsTangents(variant) && !mesh.has_tangents())
    Fail(variant, "tangents requested but the mesh '" + mesh.name + "' has none");
  if (SkinsTangents(variant) && variant.position != PositionFormat::kFloat4)
    Fail(variant, "tangents need the float4 position format (every output has the tangents' 16-byte stride)");
  if (SkinsMorph(variant) && !mesh.has_morph())
    Fail(variant, std::string("morph ") + Name(variant.morph) + " requested but the mesh '" + mesh.name +
                      "' has no morph targets");
  if (!SkinsMorph(variant) && mesh.morph.MovesVertices())
    Fail(variant, "the mesh '" + mesh.name + "' has morph targets that move its vertices, which a variant without "
                  "morph targets would ignore (use a morph value)");
  if (SkinsMorph(variant) &&
      3 * mesh.morph.count() * mesh.vertex_count() >= (std::uint64_t{1} << 32))
    Fail(variant, mesh.morph.where + ": " + std::to_string(mesh.morph.count()) + " targets x " +
                      std::to_string(mesh.vertex_count()) +
                      " vertices of offsets exceed the kernels' 32-bit element indices (3 floats each)");
  if (MorphHalf(variant))
    for (const auto* stream : {&mesh.morph.positions, &mesh.morph.normals, &mesh.morph.tangents})
      for (std::size_t t = 0; t < stream->size(); ++t)
        for (std::size_t v = 0; v < (*stream)[t].size(); ++v)
          for (int c = 0; c < 3; ++c)
            if (std::isinf(HalfValue(HalfBits((*stream)[t][v][c]))))
              Fail(variant, mesh.morph.where + ": target " + std::to_string(t) + " vertex " + std::to_string(v) +
                                ": offset component " + std::to_string((*stream)[t][v][c]) +
                                " rounds to infinity as a half (binary16 holds magnitudes below 65520; use float32 offsets)");
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const int count = mesh.InfluencesOf(v);
    if (count == 0) Fail(variant, "vertex " + std::to_string(v) + " has no non-zero weight");
    if (count > b)
      Fail(variant, "influences " + std::to_string(b) + " below the mesh's per-vertex count " +
                        std::to_string(count) + " (vertex " + std::to_string(v) + ")");
    if (variant.mixed != MixedCounts::kPadded) continue;
    for (int i = b; i < mesh.influences; ++i) {
      if (mesh.weights[v * mesh.influences + i] != 0.0f)
        Fail(variant, "vertex " + std::to_string(v) + " has a non-zero weight in slot " + std::to_string(i) +
                          ", beyond the variant's " + std::to_string(b) + " influences (padded keeps slots in place)");
    }
  }
}

// ------------------------------------------------------------ one launch

struct Slot {
  std::uint32_t joint = 0;
  std::uint32_t weight = 0;  // word as stored (float bits or quantised integer)
};

// The k slots of mesh vertex v as a launch with `k` influences reads them:
// padded keeps slot i in place (zeros beyond the mesh's slots); bucketed
// compacts the slots whose weight is non-zero in the mesh.
void GatherSlots(const SkinnedMesh& mesh, const std::vector<std::uint32_t>& words, MixedCounts mixed,
                 std::size_t v, int k, Slot* out) {
  const auto mb = static_cast<std::size_t>(mesh.influences);
  for (int i = 0; i < k; ++i) out[i] = Slot{};
  int next = 0;
  for (int i = 0; i < mesh.influences && next < k; ++i) {
    const std::size_t s = v * mb + static_cast<std::size_t>(i);
    if (mixed == MixedCounts::kBucketed && mesh.weights[s] == 0.0f) continue;
    out[next++] = Slot{mesh.joints[s], words[s]};
  }
}

Launch PackLaunch(const SkinnedMesh& mesh, const Variant& variant, const std::vector<std::uint32_t>& words,
                  const std::vector<std::uint32_t>& order, std::uint32_t first, std::uint32_t count, int k) {
  Launch launch;
  launch.first = first;
  launch.count = count;
  launch.influences = k;
  const std::size_t n = count;
  const std::size_t pb = BytesOf(variant.position);
  const std::size_t ib = BytesOf(variant.index);
  const std::size_t wb = BytesOf(variant.weight);
  const auto kk = static_cast<std::size_t>(k);
  Slot slots[kMaxInfluences];

  if (variant.layout == Layout::kAos) {
    const RecordLayout r = AosRecordLayout(variant, k);
    PackedBuffer records{"records", std::vector<std::uint8_t>(n * r.size, 0)};
    for (std::size_t p = 0; p < n; ++p) {
      const std::uint32_t v = order[first + p];
      std::uint8_t* rec = records.bytes.data() + p * r.size;
      PutVector(rec + r.position, mesh.positions[v], variant.position, 1.0f);
      GatherSlots(mesh, words, variant.mixed, v, k, slots);
      for (std::size_t i = 0; i < kk; ++i) {
        PutUint(rec + r.indices + i * ib, slots[i].joint, ib);
        PutUint(rec + r.weights + i * wb, slots[i].weight, wb);
      }
      if (SkinsNormals(variant)) PutVector(rec + r.normal, mesh.normals[v], variant.position, 0.0f);
      if (SkinsTangents(variant)) PutTangent(rec + r.tangent, mesh.tangents[v]);
    }
    launch.inputs.push_back(std::move(records));
    return launch;
  }

  const bool split = variant.layout == Layout::kSoaSplit;
  const std::size_t stride = split ? SoaSplitSlotStride(count, variant) : 0;
  launch.slot_stride = static_cast<std::uint32_t>(stride);
  const std::size_t elements = split ? kk * stride : kk * n;
  PackedBuffer positions{"positions", std::vector<std::uint8_t>(n * pb, 0)};
  PackedBuffer indices{"indices", std::vector<std::uint8_t>(RoundUp(elements * ib, 4), 0)};
  PackedBuffer weights{"weights", std::vector<std::uint8_t>(RoundUp(elements * wb, 4), 0)};
  PackedBuffer normals{"normals", std::vector<std::uint8_t>(SkinsNormals(variant) ? n * pb : 0, 0)};
  PackedBuffer tangents{"tangents", std::vector<std::uint8_t>(SkinsTangents(variant) ? n * kTangentBytes : 0, 0)};
  for (std::size_t p = 0; p < n; ++p) {
    const std::uint32_t v = order[first + p];
    PutVector(positions.bytes.data() + p * pb, mesh.positions[v], variant.position, 1.0f);
    if (SkinsNormals(variant)) PutVector(normals.bytes.data() + p * pb, mesh.normals[v], variant.position, 0.0f);
    if (SkinsTangents(variant)) PutTangent(tangents.bytes.data() + p * kTangentBytes, mesh.tangents[v]);
    GatherSlots(mesh, words, variant.mixed, v, k, slots);
    for (std::size_t i = 0; i < kk; ++i) {
      const std::size_t e = split ? i * stride + p : p * kk + i;
      PutUint(indices.bytes.data() + e * ib, slots[i].joint, ib);
      PutUint(weights.bytes.data() + e * wb, slots[i].weight, wb);
    }
  }
  launch.inputs.push_back(std::move(positions));
  launch.inputs.push_back(std::move(indices));
  launch.inputs.push_back(std::move(weights));
  if (SkinsNormals(variant)) launch.inputs.push_back(std::move(normals));
  if (SkinsTangents(variant)) launch.inputs.push_back(std::move(tangents));
  return launch;
}

// One morph offset in the variant's format: float32 x, y, z, or binary16 x, y, z, 0.
void PutOffset(std::uint8_t* at, const glm::vec3& d, bool half) {
  for (int c = 0; c < 3; ++c) {
    if (half) {
      PutUint(at + 2 * c, HalfBits(d[c]), 2);
    } else {
      PutFloat(at + 4 * c, d[c]);
    }
  }
  if (half) PutUint(at + 6, 0, 2);
}

// The morph streams of one launch (docs/VARIANTS.md "Morph targets"), after
// the vertex streams, in argument order. Dense: target t's offset of packed
// vertex p at t*count+p. Sparse: per packed vertex the targets with a
// non-zero offset in any stream, in target order. Every buffer holds at
// least one element (a launch no target moves still binds them).
void PackMorph(const SkinnedMesh& mesh, const Variant& variant, const std::vector<std::uint32_t>& order, Launch& launch) {
  if (!SkinsMorph(variant)) return;
  const MorphTargets& m = mesh.morph;
  const bool half = MorphHalf(variant);
  const std::size_t ob = half ? kMorphHalfOffsetBytes : kMorphF32OffsetBytes;
  struct Stream {
    const char* name;
    const std::vector<std::vector<glm::vec3>>* offsets;  // empty: zeros
  };
  std::vector<Stream> streams = {{"morph_positions", &m.positions}};
  if (SkinsNormals(variant)) streams.push_back({"morph_normals", &m.normals});
  if (SkinsTangents(variant)) streams.push_back({"morph_tangents", &m.tangents});
  const auto offset = [&](const Stream& s, std::size_t t, std::uint32_t v) {
    return t < s.offsets->size() ? (*s.offsets)[t][v] : glm::vec3(0.0f);
  };
  const std::size_t n = launch.count, targets = m.count();
  std::vector<std::pair<std::uint32_t, std::uint32_t>> entries;  // (packed vertex, target), sparse
  std::vector<std::uint32_t> starts;
  if (MorphSparse(variant)) {
    starts.reserve(n + 1);
    for (std::size_t p = 0; p < n; ++p) {
      starts.push_back(static_cast<std::uint32_t>(entries.size()));
      const std::uint32_t v = order[launch.first + p];
      for (std::size_t t = 0; t < targets; ++t)
        if (std::any_of(streams.begin(), streams.end(), [&](const Stream& s) { return offset(s, t, v) != glm::vec3(0.0f); }))
          entries.emplace_back(static_cast<std::uint32_t>(p), static_cast<std::uint32_t>(t));
    }
    starts.push_back(static_cast<std::uint32_t>(entries.size()));
    PackedBuffer offsets{"morph_offsets", std::vector<std::uint8_t>(starts.size() * 4)};
    for (std::size_t i = 0; i < starts.size(); ++i) PutUint(offsets.bytes.data() + 4 * i, starts[i], 4);
    PackedBuffer target_of{"morph_targets", std::vector<std::uint8_t>(std::max<std::size_t>(entries.size(), 1) * 4, 0)};
    for (std::size_t e = 0; e < entries.size(); ++e) PutUint(target_of.bytes.data() + 4 * e, entries[e].second, 4);
    launch.inputs.push_back(std::move(offsets));
    launch.inputs.push_back(std::move(target_of));
  }
  for (const Stream& s : streams) {
    const std::size_t elements = MorphSparse(variant) ? entries.size() : targets * n;
    PackedBuffer out{s.name, std::vector<std::uint8_t>(RoundUp(std::max<std::size_t>(elements, 1) * ob, 4), 0)};
    if (MorphSparse(variant)) {
      for (std::size_t e = 0; e < entries.size(); ++e)
        PutOffset(out.bytes.data() + e * ob, offset(s, entries[e].second, order[launch.first + entries[e].first]), half);
    } else {
      for (std::size_t t = 0; t < targets; ++t)
        for (std::size_t p = 0; p < n; ++p)
          PutOffset(out.bytes.data() + (t * n + p) * ob, offset(s, t, order[launch.first + p]), half);
    }
    launch.inputs.push_back(std::move(out));
  }
}

}  // namespace

RecordLayout AosRecordLayout(const Variant& variant, int influences) {
  const std::size_t b = static_cast<std::size_t>(std::max(influences, 0));
  const std::size_t align = variant.position == PositionFormat::kFloat4 ? 16 : 4;
  RecordLayout r;
  r.position = 0;
  r.indices = BytesOf(variant.position);
  const std::size_t wb = BytesOf(variant.weight);
  r.weights = RoundUp(r.indices + b * BytesOf(variant.index), wb);
  std::size_t end = r.weights + b * wb;
  if (SkinsNormals(variant)) {
    r.normal = RoundUp(end, align);
    end = r.normal + BytesOf(variant.position);
  }
  if (SkinsTangents(variant)) {
    r.tangent = RoundUp(end, align);
    end = r.tangent + kTangentBytes;
  }
  r.size = RoundUp(end, align);
  return r;
}

std::uint32_t SoaSplitSlotStride(std::uint32_t count, const Variant& variant) {
  const std::size_t narrowest = std::min(BytesOf(variant.index), BytesOf(variant.weight));
  const std::size_t multiple = std::max<std::size_t>(64, 256 / narrowest);
  return static_cast<std::uint32_t>(RoundUp(std::max<std::size_t>(count, 1), multiple));
}

PackedMesh Pack(const SkinnedMesh& mesh, const Variant& variant) {
  CheckFit(mesh, variant);
  const std::vector<std::uint32_t> words = WeightWords(mesh, variant.weight);
  const auto n = static_cast<std::uint32_t>(mesh.vertex_count());

  PackedMesh packed;
  packed.variant = variant;
  packed.vertex_count = n;
  packed.output_stride_bytes = BytesOf(variant.position);
  packed.palette_joints = static_cast<std::size_t>(mesh.joint_count);
  packed.order.resize(n);
  for (std::uint32_t v = 0; v < n; ++v) packed.order[v] = v;

  if (variant.mixed == MixedCounts::kPadded) {
    packed.launches.push_back(PackLaunch(mesh, variant, words, packed.order, 0, n, variant.influences));
  } else {
    std::vector<int> counts(n);
    for (std::uint32_t v = 0; v < n; ++v) counts[v] = mesh.InfluencesOf(v);
    std::stable_sort(packed.order.begin(), packed.order.end(),
                     [&counts](std::uint32_t a, std::uint32_t b) { return counts[a] < counts[b]; });
    for (std::uint32_t first = 0; first < n;) {
      const int k = counts[packed.order[first]];
      std::uint32_t end = first;
      while (end < n && counts[packed.order[end]] == k) ++end;
      packed.launches.push_back(PackLaunch(mesh, variant, words, packed.order, first, end - first, k));
      first = end;
    }
  }
  for (Launch& launch : packed.launches) PackMorph(mesh, variant, packed.order, launch);
  if (SkinsMorph(variant)) {
    packed.morph_targets = static_cast<int>(mesh.morph.count());
    packed.morph_weights = PackMorphWeights(mesh.morph.weights);
  }
  // The rest pose (identity for every joint): a palette of the right size to
  // bind until the first PackPalette of a frame replaces it.
  packed.palette = PackPalette(std::vector<glm::mat4>(packed.palette_joints, glm::mat4(1.0f)), variant);
  return packed;
}

std::size_t PaletteMatrixBytes(const Variant& variant) { return BytesOf(variant.palette); }

std::vector<std::uint8_t> PackMorphWeights(std::span<const double> weights) {
  std::vector<std::uint8_t> bytes(weights.size() * 4);
  for (std::size_t t = 0; t < weights.size(); ++t) PutFloat(bytes.data() + 4 * t, static_cast<float>(weights[t]));
  return bytes;
}

// The emitted header's rule (plain C++17), so that the header and the packer
// cannot drift apart; EmbedHeader.HalfBitsIsTheIeeeConversionToBinary16
// checks it against the compiler's own conversion.
std::uint16_t HalfBits(float value) { return skintune_kernels::detail::HalfBits(value); }
float HalfValue(std::uint16_t bits) { return static_cast<float>(std::bit_cast<_Float16>(bits)); }

std::vector<std::uint8_t> PackPalette(std::span<const glm::mat4> palette, const Variant& variant) {
  std::vector<std::uint8_t> bytes(palette.size() * PaletteMatrixBytes(variant));
  static_assert(sizeof(glm::mat4) == 16 * sizeof(float), "glm::mat4 is 16 contiguous floats, column after column");
  if (palette.empty()) return bytes;
  const std::size_t bad = PackPaletteInto(&palette.front()[0][0], palette.size(), variant, bytes.data());
  if (bad < palette.size() && variant.palette == PaletteFormat::kDualQuaternion) throw Error(NotRigid(palette[bad], bad));
  return bytes;
}

std::string NotRigid(const glm::mat4& matrix, std::size_t entry) {
  float unused[8];
  double deviation = 0.0;
  skintune_kernels::DualQuaternionOf(&matrix[0][0], unused, &deviation);
  std::ostringstream s;
  s << "palette entry " << entry << " is not a rigid transform: ";
  if (std::isinf(deviation)) {
    s << "it is not finite, or it mirrors (det <= 0)";
  } else {
    s << "max |(A^T A - I)_ij| of its 3x3 A is " << deviation << ", above " << skintune_kernels::kRigidTolerance
      << " (it scales or shears)";
  }
  s << "; dual-quaternion skinning takes rotations and translations only: use matrix blending for this rig";
  return s.str();
}

// Rows of the transposed matrix (the kernels read a row as a float4); the
// finiteness test looks at the exponent bits, a branch per matrix only. Each
// matrix is transposed in registers and stored whole (48 or 64 bytes, wide
// stores): the runtime packs straight into write-combined page-locked
// staging, where byte stores cost about a nanosecond each (byte stores made
// a 64 x 77-joint SetPalette cost 300 us on the H100 machine's host, 2026-11).
namespace {

// The dual-quaternion palette (skintune_kernels::DualQuaternionOf, 32 bytes a
// matrix); the first matrix that is not finite or not rigid stops it.
// `largest`: the largest |element| of the matrices packed (a rotation's are
// at most 1), the runtime's bound on the outputs as for the matrix rows.
std::size_t PackDualQuaternions(const float* column_major, std::size_t matrices, std::uint8_t* out, float& largest) {
  for (std::size_t j = 0; j < matrices; ++j, out += 32) {
    float dq[8];
    if (!skintune_kernels::DualQuaternionOf(column_major + 16 * j, dq)) return j;
    std::memcpy(out, dq, sizeof dq);
    largest = std::max({largest, 1.0f, std::fabs(column_major[16 * j + 12]), std::fabs(column_major[16 * j + 13]),
                        std::fabs(column_major[16 * j + 14])});
  }
  return matrices;
}

template <std::size_t kRows>
std::size_t PackRows(const float* column_major, std::size_t matrices, std::uint8_t* out, float& largest) {
  static_assert(std::endian::native == std::endian::little, "packed buffers are little-endian, as the devices read them");
  std::size_t first_special = matrices;
#if defined(__SSE2__)
  // Four columns in, a 4x4 transpose in registers, kRows rows out; the
  // exponent test on all 16 words at once, and the magnitudes' maximum.
  const __m128i exponent = _mm_set1_epi32(0x7f800000);
  const __m128 magnitude = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  __m128 top = _mm_setzero_ps();
  for (std::size_t j = 0; j < matrices; ++j, out += kRows * 16) {
    const float* m = column_major + 16 * j;
    __m128 c0 = _mm_loadu_ps(m), c1 = _mm_loadu_ps(m + 4), c2 = _mm_loadu_ps(m + 8), c3 = _mm_loadu_ps(m + 12);
    const auto special = [&](__m128 c) {
      return _mm_cmpeq_epi32(_mm_and_si128(_mm_castps_si128(c), exponent), exponent);
    };
    const __m128i any = _mm_or_si128(_mm_or_si128(special(c0), special(c1)), _mm_or_si128(special(c2), special(c3)));
    top = _mm_max_ps(top, _mm_max_ps(_mm_max_ps(_mm_and_ps(c0, magnitude), _mm_and_ps(c1, magnitude)),
                                     _mm_max_ps(_mm_and_ps(c2, magnitude), _mm_and_ps(c3, magnitude))));
    _MM_TRANSPOSE4_PS(c0, c1, c2, c3);
    auto* rows = reinterpret_cast<float*>(out);
    _mm_storeu_ps(rows, c0);
    _mm_storeu_ps(rows + 4, c1);
    _mm_storeu_ps(rows + 8, c2);
    if constexpr (kRows == 4) _mm_storeu_ps(rows + 12, c3);
    if (_mm_movemask_epi8(any) != 0 && first_special == matrices) first_special = j;
  }
  float lanes[4];
  _mm_storeu_ps(lanes, top);
  largest = std::max(std::max(lanes[0], lanes[1]), std::max(lanes[2], lanes[3]));
#else
  for (std::size_t j = 0; j < matrices; ++j, out += kRows * 16) {
    std::uint32_t words[16];
    std::memcpy(words, column_major + 16 * j, sizeof words);
    std::uint32_t special = 0;
    std::uint32_t rows[kRows * 4];
    for (std::size_t i = 0; i < 16; ++i) special |= (words[i] & 0x7f800000u) == 0x7f800000u ? 1u : 0u;
    for (std::size_t i = 0; i < 16; ++i) largest = std::max(largest, std::fabs(column_major[16 * j + i]));
    for (std::size_t r = 0; r < kRows; ++r)
      for (std::size_t c = 0; c < 4; ++c) rows[r * 4 + c] = words[c * 4 + r];
    std::memcpy(out, rows, sizeof rows);
    if (special && first_special == matrices) first_special = j;
  }
#endif
  return first_special;
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define SKINTUNE_PACK_AVX512 1
// One matrix per 512-bit register: the transpose is one permute, the rows
// one 64-byte store, the exponent test one compare into a mask. Three rows
// go four matrices at a time (below); for the last few each store's fourth
// row lands on the next matrix's first, which the next store overwrites:
// every store is a plain one, in order, as write-combined staging wants;
// only the last matrix's is masked (nothing written past the end). Built
// for AVX-512F whatever the compiler's target;
// called only where the CPU has it (PackIsaAvailable).
__attribute__((target("avx512f"))) std::size_t PackRowsAvx512(const float* column_major, std::size_t matrices,
                                                                std::uint8_t* out, std::size_t rows, float& largest) {
  // Output word k (row k / 4, column k % 4) is input word (k % 4) * 4 + k / 4.
  const __m512i transpose = _mm512_set_epi32(15, 11, 7, 3, 14, 10, 6, 2, 13, 9, 5, 1, 12, 8, 4, 0);
  const __m512i exponent = _mm512_set1_epi32(0x7f800000);
  const __mmask16 kept = rows == 4 ? 0xFFFF : 0x0FFF;
  auto* rows_out = reinterpret_cast<float*>(out);
  std::size_t first_special = matrices;
  std::size_t j = 0;
  __m512 top = _mm512_setzero_ps();  // the magnitudes' maximum, per lane (maskz: GCC 12 warns on the plain max's undefined source)
  if (rows == 3) {
    // Four matrices' rows are 192 bytes: three whole 64-byte stores, each
    // gathered from two matrices by one two-source permute (index bit 4
    // picks the second), so no store straddles a cache line where `out` is
    // 64-byte aligned (page-locked staging is) and none writes a byte twice.
    // Output word k of a matrix is input word (k % 4) * 4 + k / 4.
    constexpr auto word = [](int k, int from_second) { return from_second * 16 + (k % 4) * 4 + k / 4; };
    const __m512i first = _mm512_set_epi32(word(3, 1), word(2, 1), word(1, 1), word(0, 1), word(11, 0), word(10, 0),
                                           word(9, 0), word(8, 0), word(7, 0), word(6, 0), word(5, 0), word(4, 0),
                                           word(3, 0), word(2, 0), word(1, 0), word(0, 0));
    const __m512i second = _mm512_set_epi32(word(7, 1), word(6, 1), word(5, 1), word(4, 1), word(3, 1), word(2, 1),
                                            word(1, 1), word(0, 1), word(11, 0), word(10, 0), word(9, 0), word(8, 0),
                                            word(7, 0), word(6, 0), word(5, 0), word(4, 0));
    const __m512i third = _mm512_set_epi32(word(11, 1), word(10, 1), word(9, 1), word(8, 1), word(7, 1), word(6, 1),
                                           word(5, 1), word(4, 1), word(3, 1), word(2, 1), word(1, 1), word(0, 1),
                                           word(11, 0), word(10, 0), word(9, 0), word(8, 0));
    for (; j + 4 <= matrices; j += 4) {
      const float* m = column_major + 16 * j;
      const __m512 m0 = _mm512_loadu_ps(m), m1 = _mm512_loadu_ps(m + 16), m2 = _mm512_loadu_ps(m + 32),
                   m3 = _mm512_loadu_ps(m + 48);
      float* o = rows_out + 12 * j;
      _mm512_storeu_ps(o, _mm512_permutex2var_ps(m0, first, m1));
      _mm512_storeu_ps(o + 16, _mm512_permutex2var_ps(m1, second, m2));
      _mm512_storeu_ps(o + 32, _mm512_permutex2var_ps(m2, third, m3));
      top = _mm512_maskz_max_ps(0xFFFF, top,
                                _mm512_maskz_max_ps(0xFFFF, _mm512_maskz_max_ps(0xFFFF, _mm512_abs_ps(m0), _mm512_abs_ps(m1)),
                                                    _mm512_maskz_max_ps(0xFFFF, _mm512_abs_ps(m2), _mm512_abs_ps(m3))));
      if (first_special != matrices) continue;
      // (Written out: a lambda would not inherit this function's AVX-512 target.)
      const __mmask16 s0 = _mm512_cmpeq_epi32_mask(_mm512_and_si512(_mm512_castps_si512(m0), exponent), exponent);
      const __mmask16 s1 = _mm512_cmpeq_epi32_mask(_mm512_and_si512(_mm512_castps_si512(m1), exponent), exponent);
      const __mmask16 s2 = _mm512_cmpeq_epi32_mask(_mm512_and_si512(_mm512_castps_si512(m2), exponent), exponent);
      const __mmask16 s3 = _mm512_cmpeq_epi32_mask(_mm512_and_si512(_mm512_castps_si512(m3), exponent), exponent);
      if (s0 != 0) first_special = j;
      else if (s1 != 0) first_special = j + 1;
      else if (s2 != 0) first_special = j + 2;
      else if (s3 != 0) first_special = j + 3;
    }
  }
  for (; j < matrices; ++j) {
    const __m512 m = _mm512_loadu_ps(column_major + 16 * j);
    const __mmask16 special =
        _mm512_cmpeq_epi32_mask(_mm512_and_si512(_mm512_castps_si512(m), exponent), exponent);
    // maskz with every lane kept is the plain permute; GCC 12 warns on
    // _mm512_permutexvar_ps's own undefined source operand.
    const __m512 t = _mm512_maskz_permutexvar_ps(0xFFFF, transpose, m);
    top = _mm512_maskz_max_ps(0xFFFF, top, _mm512_abs_ps(m));
    if (rows == 4 || j + 1 < matrices) {
      _mm512_storeu_ps(rows_out + 4 * rows * j, t);
    } else {
      _mm512_mask_storeu_ps(rows_out + 4 * rows * j, kept, t);
    }
    if (special != 0 && first_special == matrices) first_special = j;
  }
  float lanes[16];
  _mm512_storeu_ps(lanes, top);
  largest = *std::max_element(lanes, lanes + 16);
  return first_special;
}
#endif
}  // namespace

bool PackIsaAvailable(PackIsa isa) {
  switch (isa) {
    case PackIsa::kAuto:
    case PackIsa::kBaseline:
      return true;
    case PackIsa::kAvx512:
#if defined(SKINTUNE_PACK_AVX512)
      return __builtin_cpu_supports("avx512f");
#else
      return false;
#endif
  }
  return false;
}

std::size_t PackPaletteInto(const float* column_major, std::size_t matrices, const Variant& variant, std::uint8_t* out,
                            PackIsa isa, float* largest_magnitude) {
  const std::size_t rows = PaletteMatrixBytes(variant) / 16;
  float unused = 0.0f;
  float& largest = largest_magnitude ? *largest_magnitude : unused;
  largest = 0.0f;
  if (variant.palette == PaletteFormat::kDualQuaternion) return PackDualQuaternions(column_major, matrices, out, largest);
#if defined(SKINTUNE_PACK_AVX512)
  static const bool avx512 = PackIsaAvailable(PackIsa::kAvx512);
  if (isa == PackIsa::kAvx512 && !avx512) throw Error("PackPaletteInto: this CPU has no AVX-512F");
  if (isa == PackIsa::kAvx512 || (isa == PackIsa::kAuto && avx512))
    return PackRowsAvx512(column_major, matrices, out, rows, largest);
#else
  if (isa == PackIsa::kAvx512) throw Error("PackPaletteInto: built without the AVX-512 path");
#endif
  return rows == 4 ? PackRows<4>(column_major, matrices, out, largest) : PackRows<3>(column_major, matrices, out, largest);
}

namespace {

// Calls put(mesh vertex, bytes of its output) for each packed output vertex,
// after checking the output's size.
template <typename Put>
void ForEachOutput(const PackedMesh& packed, Output which, std::span<const std::uint8_t> output, Put put) {
  const std::size_t stride = OutputStrideBytes(packed.variant, which);
  const std::size_t expected = packed.vertex_count * stride;
  if (output.size() != expected || packed.order.size() != packed.vertex_count) {
    std::ostringstream s;
    s << "unpack " << packed.variant.Key() << ": " << SpecOf(which).what << " output has " << output.size()
      << " bytes, expected " << packed.vertex_count << " vertices x " << stride << " bytes = " << expected;
    throw Error(s.str());
  }
  for (std::size_t p = 0; p < packed.vertex_count; ++p) put(packed.order[p], output.data() + p * stride);
}

std::uint32_t GetWord(const std::uint8_t* at) {
  std::uint32_t word;
  std::memcpy(&word, at, 4);
  return word;
}

skintune_kernels::NormalFormat EmbeddedFormat(NormalFormat format) {
  return static_cast<skintune_kernels::NormalFormat>(static_cast<int>(format));
}
static_assert(static_cast<int>(skintune_kernels::NormalFormat::kSnorm8) == static_cast<int>(NormalFormat::kSnorm8));

}  // namespace

std::uint32_t PackedNormalWord(NormalFormat format, const glm::vec3& normal) {
  return skintune_kernels::PackNormal(EmbeddedFormat(format), &normal.x);
}
std::uint32_t PackedTangentWord(NormalFormat format, const glm::vec4& tangent) {
  return skintune_kernels::PackTangent(EmbeddedFormat(format), &tangent.x);
}
glm::vec3 UnpackedNormal(NormalFormat format, std::uint32_t word) {
  glm::vec3 n;
  skintune_kernels::UnpackNormal(EmbeddedFormat(format), word, &n.x);
  return n;
}
glm::vec4 UnpackedTangent(NormalFormat format, std::uint32_t word) {
  glm::vec4 t;
  skintune_kernels::UnpackTangent(EmbeddedFormat(format), word, &t.x);
  return t;
}

std::vector<glm::vec3> Unpack(const PackedMesh& packed, std::span<const std::uint8_t> output) {
  std::vector<glm::vec3> out(packed.vertex_count);
  ForEachOutput(packed, Output::kPositions, output, [&](std::uint32_t v, const std::uint8_t* at) {
    out[v] = glm::vec3(GetFloat(at), GetFloat(at + 4), GetFloat(at + 8));
  });
  return out;
}

std::vector<glm::vec3> UnpackNormals(const PackedMesh& packed, std::span<const std::uint8_t> output) {
  std::vector<glm::vec3> out(packed.vertex_count);
  const NormalFormat format = packed.variant.normal_format;
  ForEachOutput(packed, Output::kNormals, output, [&](std::uint32_t v, const std::uint8_t* at) {
    out[v] = format == NormalFormat::kF32 ? glm::vec3(GetFloat(at), GetFloat(at + 4), GetFloat(at + 8))
                                          : UnpackedNormal(format, GetWord(at));
  });
  return out;
}

std::vector<glm::vec4> UnpackTangents(const PackedMesh& packed, std::span<const std::uint8_t> output) {
  std::vector<glm::vec4> out(packed.vertex_count);
  const NormalFormat format = packed.variant.normal_format;
  ForEachOutput(packed, Output::kTangents, output, [&](std::uint32_t v, const std::uint8_t* at) {
    out[v] = format == NormalFormat::kF32 ? glm::vec4(GetFloat(at), GetFloat(at + 4), GetFloat(at + 8), GetFloat(at + 12))
                                          : UnpackedTangent(format, GetWord(at));
  });
  return out;
}

SkinnedMesh QuantisedMesh(const SkinnedMesh& mesh, const Variant& variant) {
  ThrowIfInvalid(mesh, "quantise " + variant.Key());
  SkinnedMesh out = mesh;
  if (SkinsMorph(variant)) {
    if (MorphHalf(variant))
      for (auto* stream : {&out.morph.positions, &out.morph.normals, &out.morph.tangents})
        for (std::vector<glm::vec3>& target : *stream)
          for (glm::vec3& d : target)
            for (int c = 0; c < 3; ++c) d[c] = HalfValue(HalfBits(d[c]));
  }
  if (variant.weight == WeightFormat::kF32) return out;
  const std::vector<std::uint32_t> words = WeightWords(mesh, variant.weight);
  const auto max = static_cast<float>(UnormMax(variant.weight));
  for (std::size_t s = 0; s < words.size(); ++s) out.weights[s] = static_cast<float>(words[s]) / max;
  return out;
}

bool HoldsWeightsExactly(const SkinnedMesh& mesh, WeightFormat format) {
  Variant variant;
  variant.weight = format;
  return QuantisedMesh(mesh, variant).weights == mesh.weights;
}

}  // namespace skintune::internal
