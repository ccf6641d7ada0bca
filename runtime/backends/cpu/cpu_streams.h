// skintune (internal): the CPU kernels (cpu_kernels/cpu_kernels.h) on the bytes
// the packer lays out for a variant (generator/packer.h), so that a cpu
// variant reads exactly what the GPU variants read: layouts aos / soa /
// soa-split, positions float4 / float3, indices i32 / u16 / u8, weights f32 /
// unorm16 / unorm8, palettes mat4 / mat3x4 / dualquat.
#pragma once

#include <cstdint>
#include <span>

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

}  // namespace skintune::internal
