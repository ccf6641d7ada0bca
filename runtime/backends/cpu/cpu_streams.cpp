#include "runtime/backends/cpu/cpu_streams.h"

#include <cstring>

#include "base/error.h"

namespace skintune::internal {

CpuKernelKey CpuKeyOf(const Variant& variant, int influences) {
  CpuKernelKey key;
  key.influences = influences;
  switch (variant.index) {
    case IndexFormat::kI32: key.index = CpuIndex::kU32; break;  // joints are never negative
    case IndexFormat::kU16: key.index = CpuIndex::kU16; break;
    case IndexFormat::kU8: key.index = CpuIndex::kU8; break;
  }
  switch (variant.weight) {
    case WeightFormat::kF32: key.weight = CpuWeight::kF32; break;
    case WeightFormat::kUnorm16: key.weight = CpuWeight::kUnorm16; break;
    case WeightFormat::kUnorm8: key.weight = CpuWeight::kUnorm8; break;
  }
  key.palette_rows = static_cast<int>(BytesOf(variant.palette) / 16);
  key.point_blend = variant.blend == Blend::kPoint;
  key.dual_quaternion = variant.blend == Blend::kDualQuaternion;
  return key;
}

std::size_t CpuVertexInputCount(const Variant& variant) {
  return variant.layout == Layout::kAos ? 1 : 3 + (SkinsNormals(variant) ? 1 : 0) + (SkinsTangents(variant) ? 1 : 0);
}

CpuStreams CpuStreamsOf(const Variant& variant, int influences, std::size_t count,
                        std::span<const std::uint8_t* const> inputs, float* out_positions, float* out_normals,
                        float* out_tangents, bool stream_stores) {
  const std::size_t expected = CpuVertexInputCount(variant);
  if (inputs.size() != expected) {
    throw Error("cpu streams of " + variant.Key() + ": " + std::to_string(inputs.size()) + " input buffers, expected " +
                std::to_string(expected));
  }
  const std::size_t pb = BytesOf(variant.position), ib = BytesOf(variant.index), wb = BytesOf(variant.weight);
  const auto b = static_cast<std::size_t>(influences);
  CpuStreams s;
  s.output_floats = variant.position == PositionFormat::kFloat4 ? 4 : 3;
  s.out_positions = out_positions;
  s.out_normals = SkinsNormals(variant) ? out_normals : nullptr;
  s.out_tangents = SkinsTangents(variant) ? out_tangents : nullptr;
  s.stream_stores = stream_stores;
  switch (variant.layout) {
    case Layout::kAos: {
      const RecordLayout r = AosRecordLayout(variant, influences);
      s.positions = inputs[0] + r.position;
      s.position_stride = r.size;
      s.indices = inputs[0] + r.indices;
      s.index_stride = r.size;
      s.index_slot = ib;
      s.weights = inputs[0] + r.weights;
      s.weight_stride = r.size;
      s.weight_slot = wb;
      if (SkinsNormals(variant)) {
        s.normals = inputs[0] + r.normal;
        s.normal_stride = r.size;
      }
      if (SkinsTangents(variant)) {
        s.tangents = inputs[0] + r.tangent;
        s.tangent_stride = r.size;
      }
      return s;
    }
    case Layout::kSoa:
    case Layout::kSoaSplit: {
      const bool split = variant.layout == Layout::kSoaSplit;
      const std::size_t slot_stride = split ? SoaSplitSlotStride(static_cast<std::uint32_t>(count), variant) : 0;
      s.positions = inputs[0];
      s.position_stride = pb;
      s.indices = inputs[1];
      s.index_stride = split ? ib : b * ib;
      s.index_slot = split ? slot_stride * ib : ib;
      s.weights = inputs[2];
      s.weight_stride = split ? wb : b * wb;
      s.weight_slot = split ? slot_stride * wb : wb;
      if (SkinsNormals(variant)) {
        s.normals = inputs[3];
        s.normal_stride = pb;
      }
      if (SkinsTangents(variant)) {
        s.tangents = inputs[4];
        s.tangent_stride = kTangentBytes;
      }
      return s;
    }
  }
  throw Error("cpu streams of " + variant.Key() + ": unknown layout");
}

namespace {

float F32At(const std::uint8_t* p) {
  float f;
  std::memcpy(&f, p, sizeof f);
  return f;
}

// Offset e of a morph stream in the variant's format.
glm::vec3 OffsetAt(const std::uint8_t* stream, std::size_t e, bool half) {
  if (half) {
    std::uint16_t h[3];
    std::memcpy(h, stream + e * kMorphHalfOffsetBytes, sizeof h);
    return {HalfValue(h[0]), HalfValue(h[1]), HalfValue(h[2])};
  }
  const std::uint8_t* p = stream + e * kMorphF32OffsetBytes;
  return {F32At(p), F32At(p + 4), F32At(p + 8)};
}

}  // namespace

void MorphCpuStreams(const Variant& variant, std::size_t count, int targets,
                     std::span<const std::uint8_t* const> morph_inputs, const float* weights, const CpuStreams& s,
                     CpuMorphScratch& scratch, std::size_t begin, std::size_t end) {
  const bool sparse = MorphSparse(variant), half = MorphHalf(variant);
  const bool normals = s.normals != nullptr, tangents = s.tangents != nullptr;
  // The morph inputs in argument order: [offsets, targets,] positions[, normals[, tangents]].
  std::size_t next = 0;
  const std::uint32_t* offsets = sparse ? reinterpret_cast<const std::uint32_t*>(morph_inputs[next++]) : nullptr;
  const std::uint32_t* target_of = sparse ? reinterpret_cast<const std::uint32_t*>(morph_inputs[next++]) : nullptr;
  const std::uint8_t* d_positions = morph_inputs[next++];
  const std::uint8_t* d_normals = normals ? morph_inputs[next++] : nullptr;
  const std::uint8_t* d_tangents = tangents ? morph_inputs[next++] : nullptr;
  for (std::size_t v = begin; v < end; ++v) {
    const std::uint8_t* p = s.positions + v * s.position_stride;
    glm::vec3 position(F32At(p), F32At(p + 4), F32At(p + 8)), normal(0.0f), tangent(0.0f);
    if (normals) {
      const std::uint8_t* n = s.normals + v * s.normal_stride;
      normal = {F32At(n), F32At(n + 4), F32At(n + 8)};
    }
    if (tangents) {
      const std::uint8_t* t = s.tangents + v * s.tangent_stride;
      tangent = {F32At(t), F32At(t + 4), F32At(t + 8)};
    }
    // As the kernels: target order, weight 0 skipped, float32 sums.
    const auto apply = [&](std::size_t e, float w) {
      if (w == 0.0f) return;
      position += w * OffsetAt(d_positions, e, half);
      if (normals) normal += w * OffsetAt(d_normals, e, half);
      if (tangents) tangent += w * OffsetAt(d_tangents, e, half);
    };
    if (sparse) {
      for (std::uint32_t e = offsets[v]; e < offsets[v + 1]; ++e) apply(e, weights[target_of[e]]);
    } else {
      for (int t = 0; t < targets; ++t) apply(static_cast<std::size_t>(t) * count + v, weights[t]);
    }
    std::memcpy(&scratch.positions[3 * v], &position, sizeof position);
    if (normals) std::memcpy(&scratch.normals[3 * v], &normal, sizeof normal);
    if (tangents) {
      std::memcpy(&scratch.tangents[4 * v], &tangent, sizeof tangent);
      scratch.tangents[4 * v + 3] = F32At(s.tangents + v * s.tangent_stride + 12);
    }
  }
}

CpuStreams MorphedStreams(CpuStreams s, CpuMorphScratch& scratch, std::size_t count) {
  scratch.positions.resize(3 * count);
  s.positions = reinterpret_cast<const std::uint8_t*>(scratch.positions.data());
  s.position_stride = 3 * sizeof(float);
  if (s.normals) {
    scratch.normals.resize(3 * count);
    s.normals = reinterpret_cast<const std::uint8_t*>(scratch.normals.data());
    s.normal_stride = 3 * sizeof(float);
  }
  if (s.tangents) {
    scratch.tangents.resize(4 * count);
    s.tangents = reinterpret_cast<const std::uint8_t*>(scratch.tangents.data());
    s.tangent_stride = 4 * sizeof(float);
  }
  return s;
}

CpuStreams PackingStreams(CpuStreams s, CpuPackScratch& scratch, std::size_t count) {
  if (s.out_normals) {
    scratch.normals.resize(static_cast<std::size_t>(s.output_floats) * count);
    s.out_normals = scratch.normals.data();
  }
  if (s.out_tangents) {
    scratch.tangents.resize(4 * count);
    s.out_tangents = scratch.tangents.data();
  }
  s.stream_stores = false;  // the scratch is read right after
  return s;
}

void PackCpuOutputs(NormalFormat format, const CpuStreams& s, std::uint32_t* out_normals,
                    std::uint32_t* out_tangents, std::size_t begin, std::size_t end) {
  const auto floats = static_cast<std::size_t>(s.output_floats);
  for (std::size_t v = begin; v < end; ++v) {
    if (out_normals && s.out_normals) {
      const float* n = s.out_normals + v * floats;
      out_normals[v] = PackedNormalWord(format, glm::vec3(n[0], n[1], n[2]));
    }
    if (out_tangents && s.out_tangents) {
      const float* t = s.out_tangents + 4 * v;
      out_tangents[v] = PackedTangentWord(format, glm::vec4(t[0], t[1], t[2], t[3]));
    }
  }
}

}  // namespace skintune::internal
