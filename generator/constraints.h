// skintune: which variants a device can run on a given mesh, and why not.
//
// Every constraint is expressed once, here, from the device's queried limits
// (DeviceLimits, filled by the backend that queried them) and the problem's
// shape. An invalid variant is reported with each constraint it breaks.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "generator/variant.h"
#include "model/mesh.h"

namespace skintune::internal {

struct DeviceLimits {
  std::size_t max_wg_size = 256;                   // CL_DEVICE_MAX_WORK_GROUP_SIZE, CUDA max threads/block,
                                                   // GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS
  std::uint64_t local_memory_bytes = 32768;        // __local / __shared__ / shared per work-group
  std::uint64_t constant_memory_bytes = 65536;     // __constant / __constant__ buffer
  std::uint64_t uniform_block_bytes = 16384;       // GL_MAX_UNIFORM_BLOCK_SIZE (GLSL "constant")
  bool image_support = true;                       // image1d_buffer / texture object / samplerBuffer
  std::uint64_t image_buffer_max_texels = 65536;   // CL_DEVICE_IMAGE_MAX_BUFFER_SIZE, GL_MAX_TEXTURE_BUFFER_SIZE
  bool vertex_shader_storage_blocks = true;        // GL_MAX_VERTEX_SHADER_STORAGE_BLOCKS > 0
  std::uint64_t max_grid_y = 65535;                // instances per launch: CUDA grid y, GL_MAX_COMPUTE_WORK_GROUP_COUNT[1]
                                                   // (not checked for OpenCL and glsl-vertex: no small limit)
};

struct ProblemShape {
  int joints = 77;            // palette entries
  int max_influences = 4;     // the largest per-vertex influence count of the mesh
  bool has_normals = false;
  int instances = 1;          // K instances skinned per launch, each with its own palette (docs/VARIANTS.md
                              // "Instancing"): constant and image storage hold all K palettes
  bool has_tangents = false;  // the mesh has tangents (then also normals)
  bool rigid_joints = false;  // every palette it is skinned with rotates and translates only
                              // (PackPalette's dualquat format holds it): dual quaternions may skin it
  int morph_targets = 0;      // the mesh's morph targets (0: none)
  // Every variant must apply them: WithMorphOf sets it for any mesh with
  // morph targets, as their weights may change any frame (a shape with
  // targets that no variant needs to apply exists for covering sets).
  bool morph_moves = false;
  // The scene's palettes are made on the device from its model's clips (a
  // scene key's "-anim", docs/ANIMATION.md): every variant animates on the device.
  bool animated = false;
};

// `shape` with the morph fields of a mesh's morph targets (any target: morph_moves).
ProblemShape WithMorphOf(ProblemShape shape, const MorphTargets& morph);

enum class Constraint {
  kInfluencesRange,       // B outside 1..8
  kInfluencesTooFew,      // B < the mesh's largest per-vertex count
  kVerticesPerItem,       // not 1, 2, 4 or 8
  kAssignmentRedundant,   // strided with 1 vertex per item is the same kernel as contiguous
  kWgSizeRange,           // not a multiple of 32 in 32..1024
  kWgSizeDevice,          // above the device's work-group limit
  kNoWorkGroups,          // glsl-vertex: one vertex per invocation, no work-groups (wg0, v1c required)
  kLocalMemory,           // palette larger than local memory, or local storage in a vertex shader
  kConstantMemory,        // palette larger than the constant buffer / uniform block
  kImageSupport,          // device without image support
  kImageSize,             // palette texels above the image buffer limit
  kStorageBlocks,         // vertex shader without storage blocks
  kIndexRange,            // joint count does not fit the index format
  kNormalsMissing,        // normals requested, mesh has none
  kTangentsMissing,       // tangents requested, mesh has none
  kTangentsFormat,        // tangents with float3 positions (tangents are float4: outputs share one stride)
  kInstanceCount,         // instances below 1, or more than one launch's grid can hold (CUDA, glsl-compute)
  kBlendPalette,          // blend dq without the dualquat palette, or the dualquat palette without blend dq
  kJointsNotRigid,        // blend dq on a mesh whose palettes scale, shear or mirror
  kMorphMissing,          // a morph value on a mesh without morph targets (not a variant of this data set)
  kMorphIgnored,          // morph none on a mesh whose morph targets move vertices (it would skin the wrong shape)
  kNormalFormatUnused,    // a packed normal format on a variant that skins no normals
  kAnimationMissing,      // palettes made on the device for a scene the host animates (not a variant of this data set)
  kAnimationIgnored,      // the host's palettes for a scene animated on the device (not a variant of this data set)
  kAnimationPalette,      // the palette kernel writes matrices (mat3x4, mat4): not the dualquat palette
  kAnimationMorph,        // an animated scene with morph targets (the Skinner animates them; the tuner does not)
  kAnimationFused,        // fused animation (each work-group makes its palette) without storage local
};

const char* Name(Constraint);

struct Violation {
  Constraint constraint;
  std::string message;  // e.g. "storage local: palette 77 x 64 B = 4928 B exceeds local memory 4096 B"
};

// Every constraint the variant breaks; empty when it can run.
std::vector<Violation> CheckVariant(const Variant& v, const DeviceLimits& device, const ProblemShape& shape);

// Whether the constraint only says the variant does not fit the data set's
// kind (its morph value): spaces are cut to the data set's values before
// they are enumerated (ForDataSet, generator/space.h), as a data set sets B.
constexpr bool NotOfThisDataSet(Constraint c) {
  return c == Constraint::kMorphMissing || c == Constraint::kMorphIgnored || c == Constraint::kAnimationMissing ||
         c == Constraint::kAnimationIgnored;
}

// Bytes one palette occupies in the variant's storage (an instanced launch
// reads `instances` of them; a work-group's local copy holds one).
std::uint64_t PaletteBytes(const Variant& v, int joints);

}  // namespace skintune::internal
