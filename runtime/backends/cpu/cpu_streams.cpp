#include "runtime/backends/cpu/cpu_streams.h"

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

CpuStreams CpuStreamsOf(const Variant& variant, int influences, std::size_t count,
                        std::span<const std::uint8_t* const> inputs, float* out_positions, float* out_normals,
                        float* out_tangents, bool stream_stores) {
  const std::size_t expected =
      variant.layout == Layout::kAos ? 1 : 3 + (SkinsNormals(variant) ? 1 : 0) + (SkinsTangents(variant) ? 1 : 0);
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

}  // namespace skintune::internal
