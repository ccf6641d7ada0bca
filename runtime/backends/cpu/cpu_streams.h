// skintune (internal): the CPU kernels (cpu_kernels/cpu_kernels.h) on the bytes
// the packer lays out for a variant (generator/packer.h), so that a cpu
// variant reads exactly what the GPU variants read: layouts aos / soa /
// soa-split, positions float4 / float3, indices i32 / u16 / u8, weights f32 /
// unorm16 / unorm8, palettes mat4 / mat3x4 / dualquat.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "generator/packer.h"
#include "cpu_kernels/cpu_kernels.h"

namespace skintune::internal {

// The kernel of `variant` for a launch of `influences` (its formats, palette rows and blend).
CpuKernelKey CpuKeyOf(const Variant& variant, int influences);

// The streams of one launch of `count` vertices and `influences` slots:
// `inputs` are its buffers in argument order (aos: records; soa, soa-split:
// positions, indices, weights[, normals[, tangents]]); the outputs (null: not
// written) point at the launch's first output vertex. Throws Error for the wrong number of inputs.
CpuStreams CpuStreamsOf(const Variant& variant, int influences, std::size_t count,
                        std::span<const std::uint8_t* const> inputs, float* out_positions, float* out_normals,
                        float* out_tangents, bool stream_stores);

// The number of a launch's inputs CpuStreamsOf reads (the vertex streams);
// a morph variant's morph-target buffers follow them.
std::size_t CpuVertexInputCount(const Variant& variant);

// A morph variant's streams with the morph targets applied (docs/VARIANTS.md
// "Morph targets"): vertices [begin, end) of `s`'s positions (normals,
// tangents) plus the offsets at `weights` (MORPH_TARGETS of them, this
// instance's), written as float32 x, y, z (tangents x, y, z, w) into
// `scratch`, which the returned streams read instead. `morph_inputs`: the
// launch's morph-target buffers in argument order (after the vertex
// streams, without morph_weights). The cpu device's kernels are the table's
// (cpu_kernels/), so the morph pass runs before them on the same threads.
struct CpuMorphScratch {
  std::vector<float> positions, normals, tangents;  // 3, 3, 4 floats a vertex of the launch
};
void MorphCpuStreams(const Variant& variant, std::size_t count, int targets,
                     std::span<const std::uint8_t* const> morph_inputs, const float* weights, const CpuStreams& s,
                     CpuMorphScratch& scratch, std::size_t begin, std::size_t end);
// `s` reading `scratch` (sized for `count` vertices) for what MorphCpuStreams wrote.
CpuStreams MorphedStreams(CpuStreams s, CpuMorphScratch& scratch, std::size_t count);

// A packed normal_format (docs/VARIANTS.md "Packed normals and tangents"):
// the table's kernels write float32 normals and tangents into `scratch`
// (PackingStreams: `s` with its normal and tangent outputs there, sized for
// `count` vertices), then PackCpuOutputs packs vertices [begin, end) of them
// into one word each, by the rule every kernel runs (generator/packer.h
// PackedNormalWord), at `out_normals` / `out_tangents` (null: not written).
struct CpuPackScratch {
  std::vector<float> normals, tangents;  // output_floats and 4 floats a vertex of the launch
};
CpuStreams PackingStreams(CpuStreams s, CpuPackScratch& scratch, std::size_t count);
void PackCpuOutputs(NormalFormat format, const CpuStreams& s, std::uint32_t* out_normals,
                    std::uint32_t* out_tangents, std::size_t begin, std::size_t end);

}  // namespace skintune::internal
