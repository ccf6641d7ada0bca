// skintune: the kernel parameters, their defaults and the values derived from
// them, written once for every kernel template (templates/README.md,
// "Preludes"). The generator prepends one #define per parameter; each has a
// default (the default Variant: b4 soa float4 u16 f32 mat3x4 global matrix v1c
// wg128 nonormals), so every template compiles alone. docs/VARIANTS.md says
// what each parameter means; a new one is added here, and only here.
//
// This text is OpenCL C, CUDA C++ and GLSL at once: preprocessor lines and
// comments only. An "item" is a work-item (OpenCL), a thread (CUDA) or an
// invocation (GLSL).

// ---------------------------------------------------------------- parameters

#ifndef INFLUENCES            // B: bone slots per vertex, 1..8
#define INFLUENCES 4
#endif
#ifndef LAYOUT                // 0 aos, 1 soa, 2 soa-split
#define LAYOUT 1
#endif
#ifndef POSITION_FLOAT4       // 1: float4 positions/normals/outputs; 0: packed float3
#define POSITION_FLOAT4 1
#endif
#ifndef INDEX_FORMAT          // 0 i32, 1 u16, 2 u8
#define INDEX_FORMAT 1
#endif
#ifndef WEIGHT_FORMAT         // 0 f32, 1 unorm16, 2 unorm8
#define WEIGHT_FORMAT 0
#endif
#ifndef PALETTE_ROWS          // float4 rows per joint: 4 mat4, 3 mat3x4, 2 a dual quaternion (BLEND 2)
#define PALETTE_ROWS 3
#endif
#ifndef STORAGE               // palette in 0 constant memory, 1 a local copy, 2 global memory, 3 an image
#define STORAGE 2
#endif
#ifndef JOINTS                // palette entries (sizes the local copy and CUDA's / GLSL's constant palette)
#define JOINTS 77
#endif
#ifndef BLEND                 // 0: blend matrices then transform; 1: transform per bone, blend points;
#define BLEND 0               // 2: blend unit dual quaternions (PALETTE_ROWS 2: real, dual part)
#endif
#ifndef VERTICES_PER_ITEM     // N: 1, 2, 4, 8
#define VERTICES_PER_ITEM 1
#endif
#ifndef STRIDED               // 0: contiguous vertices per item; 1: strided by the item count
#define STRIDED 0
#endif
#ifndef WG_SIZE               // work-group size (CUDA: threads per block); 0 for glsl-vertex
#define WG_SIZE 128
#endif
#ifndef NORMALS               // 1: also skin normals; 2: normals and tangents
#define NORMALS 0
#endif
#ifndef MORPH                 // morph targets before skinning: 0 none; bits 0-1 the layout (1 dense,
#define MORPH 0               // 2 sparse), bit 2 half offsets (docs/VARIANTS.md "Morph targets")
#endif
#ifndef MORPH_TARGETS         // MORPH: the mesh's morph targets (the weights' count per instance)
#define MORPH_TARGETS 1
#endif
#ifndef NORMAL_FORMAT         // skinned normals and tangents written as 0 float32, 1 octahedral 2 x unorm16,
#define NORMAL_FORMAT 0       // 2 4 x snorm8 (docs/VARIANTS.md "Packed normals and tangents")
#endif
#define MORPH_LAYOUT (MORPH & 3)
#define MORPH_HALF ((MORPH & 4) != 0)
#ifndef INSTANCED             // 1: K instances per launch, K palettes (docs/VARIANTS.md "Instancing")
#define INSTANCED 0
#endif
#ifndef PALETTE_INSTANCES     // INSTANCED constant storage in CUDA and GLSL: palettes the constant palette holds
#define PALETTE_INSTANCES 1
#endif

#if INDEX_FORMAT == 0
#define INDEX_BYTES 4
#elif INDEX_FORMAT == 1
#define INDEX_BYTES 2
#else
#define INDEX_BYTES 1
#endif

#if WEIGHT_FORMAT == 0
#define WEIGHT_BYTES 4
#elif WEIGHT_FORMAT == 1
#define WEIGHT_BYTES 2
#else
#define WEIGHT_BYTES 1
#endif

#if POSITION_FLOAT4
#define POSITION_BYTES 16
#define RECORD_ALIGN 16
#else
#define POSITION_BYTES 12
#define RECORD_ALIGN 4
#endif

// Tangents are 4 floats in every position format (xyz, then w: the
// handedness, +1 or -1), inputs and outputs alike.
#if NORMALS == 2
#define TANGENTS 1
#else
#define TANGENTS 0
#endif
#define TANGENT_BYTES 16

// (The GLSL preprocessor has no ?: operator: derived values use #if chains.)

// soa-split: slot i of vertex v at element i*S + v, S = n rounded up to this
// multiple (every slot array of both formats starts on a 256-byte boundary).
#ifndef SLOT_STRIDE_MULTIPLE
#if INDEX_BYTES == 1 || WEIGHT_BYTES == 1
#define SLOT_STRIDE_MULTIPLE 256
#elif INDEX_BYTES == 2 || WEIGHT_BYTES == 2
#define SLOT_STRIDE_MULTIPLE 128
#else
#define SLOT_STRIDE_MULTIPLE 64
#endif
#endif

// aos record: byte offsets of its fields and its size, as the packer lays them
// out (generator/packer.h AosRecordLayout: natural alignment, size rounded up
// to 16 bytes for float4 and 4 for float3). The defaults follow that rule.
#define ROUND_UP(x, m) (((x) + (m) - 1) / (m) * (m))
#ifndef AOS_POSITION_OFFSET
#define AOS_POSITION_OFFSET 0
#endif
#ifndef AOS_INDICES_OFFSET
#define AOS_INDICES_OFFSET POSITION_BYTES
#endif
#ifndef AOS_WEIGHTS_OFFSET
#define AOS_WEIGHTS_OFFSET ROUND_UP(AOS_INDICES_OFFSET + INFLUENCES * INDEX_BYTES, WEIGHT_BYTES)
#endif
#ifndef AOS_NORMAL_OFFSET
#define AOS_NORMAL_OFFSET ROUND_UP(AOS_WEIGHTS_OFFSET + INFLUENCES * WEIGHT_BYTES, RECORD_ALIGN)
#endif
#ifndef AOS_TANGENT_OFFSET
#define AOS_TANGENT_OFFSET ROUND_UP(AOS_NORMAL_OFFSET + POSITION_BYTES, RECORD_ALIGN)
#endif
#ifndef AOS_RECORD_WORDS
#if TANGENTS
#define AOS_RECORD_WORDS (ROUND_UP(AOS_TANGENT_OFFSET + TANGENT_BYTES, RECORD_ALIGN) / 4)
#elif NORMALS
#define AOS_RECORD_WORDS (ROUND_UP(AOS_NORMAL_OFFSET + POSITION_BYTES, RECORD_ALIGN) / 4)
#else
#define AOS_RECORD_WORDS (ROUND_UP(AOS_WEIGHTS_OFFSET + INFLUENCES * WEIGHT_BYTES, RECORD_ALIGN) / 4)
#endif
#endif
#define AOS_RECORD_BYTES (AOS_RECORD_WORDS * 4)

// The palette kernel's (templates/palette.*, generator/palette_kernel.h): it
// is specialised per model, as the skin kernel is per mesh.
#ifndef ANIM_NODE_COUNT       // nodes of the skeleton, 1..512
#define ANIM_NODE_COUNT 1
#endif
#ifndef ANIM_JOINT_COUNT      // joints of the skin (palette entries per instance)
#define ANIM_JOINT_COUNT 1
#endif
#ifndef ANIM_CLIP_COUNT       // clips packed
#define ANIM_CLIP_COUNT 1
#endif
#ifndef ANIM_PALETTE_ROWS     // float4 rows written per joint: 3 mat3x4, 4 mat4 (a last row 0 0 0 1)
#define ANIM_PALETTE_ROWS 3
#endif
#ifndef ANIM_BAKED            // 1, 2: the palette kernel reads baked palette records of 2 or 4 float4s (frames,
#define ANIM_BAKED 0          // instances, palette, clips, states; docs/ANIMATION.md "Baked clips"); 3, 4: local
#endif                        // records of 2 or 3 float4s (nodes, frames, joints, ...); 0: it samples
#ifndef ANIM_STEADY           // with ANIM_BAKED 3, 4: the float4s (2 or 4) of the same frames' palette records
#define ANIM_STEADY 0         // beside the local ones (buffer steady, after frames; docs/ANIMATION.md "Hybrid
#endif                        // records"), which an instance that plays one clip reads; 0: none
#ifndef ANIM_JUMPS            // the hierarchy kernels' rounds of pointer jumping: ceil(log2(depth + 1)) for the
#define ANIM_JUMPS 9          // deepest node's ancestors (generator/palette_kernel.h); 9 reaches any of 512 nodes
#endif
#ifndef ANIM_FUSED            // 1: a skin kernel (STORAGE local) that makes its instance's palette from
#define ANIM_FUSED 0          // records (ANIM_BAKED 1..4) in its local copy, instead of reading the palette
#endif                        // (buffers: EmitFused; docs/ANIMATION.md "The palette in the skin launch")
#ifndef ANIM_GROUP            // the palette kernel's work-group: 3 x ANIM_NODE_COUNT rounded up to a multiple
#define ANIM_GROUP 256        // of 32, from 64 to 256 (every sample in one round: generator/palette_kernel.h);
#endif                        // a fused skin kernel's: WG_SIZE

#if INFLUENCES < 1 || INFLUENCES > 8
#error "INFLUENCES must be 1..8"
#endif
#if VERTICES_PER_ITEM != 1 && VERTICES_PER_ITEM != 2 && VERTICES_PER_ITEM != 4 && VERTICES_PER_ITEM != 8
#error "VERTICES_PER_ITEM must be 1, 2, 4 or 8"
#endif
#if NORMALS < 0 || NORMALS > 2
#error "NORMALS must be 0 (none), 1 (normals) or 2 (normals and tangents)"
#endif
#if STORAGE < 0 || STORAGE > 3
#error "STORAGE must be 0 (constant), 1 (local), 2 (global) or 3 (image)"
#endif

#if ANIM_FUSED && (STORAGE != 1 || BLEND == 2 || ANIM_BAKED < 1 || ANIM_BAKED > 4)
#error "ANIM_FUSED needs STORAGE 1 (local), matrix blending and baked records (ANIM_BAKED 1..4)"
#endif
#if ANIM_FUSED && ANIM_GROUP != WG_SIZE
#error "ANIM_FUSED: the records are read by the skin kernel's work-group (ANIM_GROUP WG_SIZE)"
#endif

#define PALETTE_FLOAT4S (JOINTS * PALETTE_ROWS)
