// skintune: the skinning both GLSL stages share, written once: bindings, the
// uniforms n and first (Vulkan: push constants), input loads, palette access, blending and
// skin_vertex() (loads one vertex and skins it: load_vertex(), then skin_loaded()). skin.comp and skin.vert
// include it after skin_params.h, with SKIN_COMPUTE_STAGE defined
// (templates/README.md, "Preludes"), and add how vertices are assigned to
// invocations and where the outputs go.

#ifndef SKIN_COMPUTE_STAGE
#error "define SKIN_COMPUTE_STAGE (1 compute shader, 0 vertex shader) before including skin_body.glsl"
#endif

// ---------------------------------------------------------------- bindings
//
// Buffers and the palette take consecutive bindings in argument order
// (scalars excluded): the sidecar's "binding" of each argument. The generator
// defines every one (BINDING_<ARGUMENT>, from the argument list); these are
// the defaults a template compiled alone takes (a fused kernel, ANIM_FUSED,
// binds frames, instances and clips where the palette was).
#if !defined(BINDING_PALETTE) && !defined(BINDING_FRAMES)
#if LAYOUT == 0
#define BINDING_RECORDS 0
#define BINDING_PALETTE 1
#define BINDING_OUT_POSITIONS 2
#define BINDING_OUT_NORMALS 3
#define BINDING_OUT_TANGENTS 4
#elif TANGENTS
#define BINDING_POSITIONS 0
#define BINDING_INDICES 1
#define BINDING_WEIGHTS 2
#define BINDING_NORMALS 3
#define BINDING_TANGENTS 4
#define BINDING_PALETTE 5
#define BINDING_OUT_POSITIONS 6
#define BINDING_OUT_NORMALS 7
#define BINDING_OUT_TANGENTS 8
#elif NORMALS
#define BINDING_POSITIONS 0
#define BINDING_INDICES 1
#define BINDING_WEIGHTS 2
#define BINDING_NORMALS 3
#define BINDING_PALETTE 4
#define BINDING_OUT_POSITIONS 5
#define BINDING_OUT_NORMALS 6
#else
#define BINDING_POSITIONS 0
#define BINDING_INDICES 1
#define BINDING_WEIGHTS 2
#define BINDING_PALETTE 3
#define BINDING_OUT_POSITIONS 4
#endif
#if MORPH
#error "MORPH: the generator defines the bindings of the morph targets' buffers (BINDING_MORPH_*)"
#endif
#endif

#ifdef VULKAN
// Vulkan (GL_KHR_vulkan_glsl predefines VULKAN; the language `vulkan`): no
// loose uniforms there, so the scalars are one push-constant block at byte
// offsets 0, 4, 8 (generator/emit.h PushConstantOffset); set 0 holds the
// bindings above. vertex_count is read by instanced kernels only.
layout(push_constant) uniform SkinScalars {
  uint n;
  uint first;
  uint vertex_count;
#if ANIM_FUSED
  float elapsed;  // byte 12
#endif
};
#else
uniform uint n;      // vertices of this launch
uniform uint first;  // index of its first vertex in the outputs (compute: written at first + v)
#if ANIM_FUSED
uniform float elapsed;  // seconds since the instances' upload, added to their clocks
#endif
#endif

#if INSTANCED
// The instance this invocation skins (docs/VARIANTS.md "Instancing"): the
// work-group's y (compute), the draw's instance (vertex). Its palette starts
// at joint INSTANCE * JOINTS (the K palettes one after another).
#if SKIN_COMPUTE_STAGE
#define INSTANCE gl_WorkGroupID.y
#else
#define INSTANCE uint(gl_InstanceID)
#endif
#endif

// ---------------------------------------------------------------- inputs
//
// float4 positions/normals are read as vec4 (one 16-byte load, like skin.cl's
// float4), packed float3 as three floats; index and weight arrays, and aos
// records, are 32-bit words. Records whose size is a multiple of 16 bytes are
// read through a uvec4 view, so 16-byte aligned fields are single loads.

#if LAYOUT == 0
#if AOS_RECORD_WORDS % 4 == 0
#define RECORD_VEC4S 1
layout(std430, binding = BINDING_RECORDS) readonly restrict buffer Records { uvec4 records[]; };
// Word w (a constant after unrolling) of vertex v's record.
#define RECORD_WORD(v, w) records[(v) * uint(AOS_RECORD_WORDS / 4) + ((w) >> 2u)][(w) & 3u]
#else
#define RECORD_VEC4S 0
layout(std430, binding = BINDING_RECORDS) readonly restrict buffer Records { uint records[]; };
#define RECORD_WORD(v, w) records[(v) * uint(AOS_RECORD_WORDS) + (w)]
#endif
#else
#if POSITION_FLOAT4
layout(std430, binding = BINDING_POSITIONS) readonly restrict buffer Positions { vec4 positions[]; };
#else
layout(std430, binding = BINDING_POSITIONS) readonly restrict buffer Positions { float positions[]; };
#endif
layout(std430, binding = BINDING_INDICES) readonly restrict buffer Indices { uint indices[]; };
layout(std430, binding = BINDING_WEIGHTS) readonly restrict buffer Weights { uint weights[]; };
#if NORMALS
#if POSITION_FLOAT4
layout(std430, binding = BINDING_NORMALS) readonly restrict buffer Normals { vec4 normals[]; };
#else
layout(std430, binding = BINDING_NORMALS) readonly restrict buffer Normals { float normals[]; };
#endif
#endif
#if TANGENTS
layout(std430, binding = BINDING_TANGENTS) readonly restrict buffer Tangents { vec4 tangents[]; };
#endif
#endif

#if MORPH
// The morph targets (docs/VARIANTS.md "Morph targets"): offsets as three
// floats, or binary16 x, y, z and a zero (one uvec2); the weights, T per instance.
#if MORPH_LAYOUT == 2
layout(std430, binding = BINDING_MORPH_OFFSETS) readonly restrict buffer MorphOffsets { uint morph_offsets[]; };
layout(std430, binding = BINDING_MORPH_TARGETS) readonly restrict buffer MorphTargets { uint morph_targets[]; };
#endif
#if MORPH_HALF
#define MORPH_T uvec2
vec3 half_offset(uvec2 h) { return vec3(unpackHalf2x16(h.x), unpackHalf2x16(h.y).x); }
#define MORPH_OFFSET(stream, e) half_offset(stream[e])
#else
#define MORPH_T float
#define MORPH_OFFSET(stream, e) vec3(stream[3u * (e)], stream[3u * (e) + 1u], stream[3u * (e) + 2u])
#endif
layout(std430, binding = BINDING_MORPH_POSITIONS) readonly restrict buffer MorphPositions { MORPH_T morph_positions[]; };
#if NORMALS
layout(std430, binding = BINDING_MORPH_NORMALS) readonly restrict buffer MorphNormals { MORPH_T morph_normals[]; };
#endif
#if TANGENTS
layout(std430, binding = BINDING_MORPH_TANGENTS) readonly restrict buffer MorphTangents { MORPH_T morph_tangents[]; };
#endif
layout(std430, binding = BINDING_MORPH_WEIGHTS) readonly restrict buffer MorphWeights { float morph_weights[]; };

// Vertex v's morph targets at their weights, in target order, added to its
// position, normal and tangent xyz.
void morph(uint v, inout vec3 position, inout vec3 normal, inout vec4 tangent) {
#if INSTANCED
  uint weights_first = INSTANCE * uint(MORPH_TARGETS);  // this instance's weights
#else
  uint weights_first = 0u;
#endif
#if MORPH_LAYOUT == 1
  for (uint t = 0u; t < uint(MORPH_TARGETS); ++t) {
    float w = morph_weights[weights_first + t];
    uint e = t * n + v;
#else
  uint morph_end = morph_offsets[v + 1u];
  for (uint e = morph_offsets[v]; e < morph_end; ++e) {
    float w = morph_weights[weights_first + morph_targets[e]];
#endif
    if (w == 0.0) continue;
    position += w * MORPH_OFFSET(morph_positions, e);
#if NORMALS
    normal += w * MORPH_OFFSET(morph_normals, e);
#endif
#if TANGENTS
    tangent.xyz += w * MORPH_OFFSET(morph_tangents, e);
#endif
  }
}
#endif

// The `bytes`-byte little-endian value at byte `byte_in_word` of `word`
// (elements are naturally aligned, so none straddles two words).
uint field(uint word, uint byte_in_word, uint bytes) {
  if (bytes == 4u) return word;
  return bitfieldExtract(word, int(byte_in_word * 8u), int(bytes * 8u));
}

// A run: one vertex's B values of `bytes` bytes each, adjacent, starting at
// byte `head` of a word (aos records; soa runs of whole words). Its words are
// read once each, then split: NVIDIA's GLSL compiler kept one load of the same
// word per value (its NVcp5.0 assembly of the crowd kernel: 11 loads a vertex
// where CUDA's has 5). RUN_CAPACITY words hold any run of values up to 4 bytes.
#define RUN_CAPACITY (INFLUENCES + 1)
uint run_words(uint head, uint bytes) { return (head + uint(INFLUENCES) * bytes + 3u) >> 2u; }
void split_run(uint words[RUN_CAPACITY], uint head, uint bytes, out uint values[INFLUENCES]) {
  for (uint i = 0u; i < uint(INFLUENCES); ++i) {
    uint byte = head + i * bytes;
    values[i] = field(words[byte >> 2u], byte & 3u, bytes);
  }
}

#if LAYOUT == 0
// xyz of the float4/float3 at byte `offset` of vertex v's record.
vec3 record_xyz(uint v, uint offset) {
#if RECORD_VEC4S
  if (offset % 16u == 0u) return uintBitsToFloat(records[v * uint(AOS_RECORD_WORDS / 4) + offset / 16u].xyz);
#endif
  uint w = offset / 4u;
  return uintBitsToFloat(uvec3(RECORD_WORD(v, w), RECORD_WORD(v, w + 1u), RECORD_WORD(v, w + 2u)));
}
vec3 load_position(uint v) { return record_xyz(v, uint(AOS_POSITION_OFFSET)); }
#if NORMALS
vec3 load_normal(uint v) { return record_xyz(v, uint(AOS_NORMAL_OFFSET)); }
#endif
#if TANGENTS
// The 4 floats (xyz and the handedness w) at the tangent's offset of vertex v's record.
vec4 load_tangent(uint v) {
#if RECORD_VEC4S
  if (uint(AOS_TANGENT_OFFSET) % 16u == 0u)
    return uintBitsToFloat(records[v * uint(AOS_RECORD_WORDS / 4) + uint(AOS_TANGENT_OFFSET) / 16u]);
#endif
  uint w = uint(AOS_TANGENT_OFFSET) / 4u;
  return uintBitsToFloat(uvec4(RECORD_WORD(v, w), RECORD_WORD(v, w + 1u), RECORD_WORD(v, w + 2u), RECORD_WORD(v, w + 3u)));
}
#endif
// The B values of `bytes` bytes each at byte `offset` of vertex v's record.
void load_record_run(uint v, uint offset, uint bytes, out uint values[INFLUENCES]) {
  uint words[RUN_CAPACITY];
  for (uint k = 0u; k < run_words(offset & 3u, bytes); ++k) words[k] = RECORD_WORD(v, (offset >> 2u) + k);
  split_run(words, offset & 3u, bytes, values);
}
void load_indices(uint v, uint slot_stride, out uint joint[INFLUENCES]) {
  load_record_run(v, uint(AOS_INDICES_OFFSET), uint(INDEX_BYTES), joint);
}
void load_raw_weights(uint v, uint slot_stride, out uint raw_weight[INFLUENCES]) {
  load_record_run(v, uint(AOS_WEIGHTS_OFFSET), uint(WEIGHT_BYTES), raw_weight);
}
#else
#if TANGENTS
vec4 load_tangent(uint v) { return tangents[v]; }
#endif
#if POSITION_FLOAT4
vec3 load_position(uint v) { return positions[v].xyz; }
#if NORMALS
vec3 load_normal(uint v) { return normals[v].xyz; }
#endif
#else
vec3 load_position(uint v) { return vec3(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]); }
#if NORMALS
vec3 load_normal(uint v) { return vec3(normals[3u * v], normals[3u * v + 1u], normals[3u * v + 2u]); }
#endif
#endif
#if LAYOUT == 1
// soa: vertex v's B values are adjacent, starting at element v*B. When a run
// is a whole number of words, its first word is v * (run / 4), each of its
// words is read once, and the word and shift of slot i are constants after
// unrolling; otherwise each value is read on its own.
void load_indices(uint v, uint slot_stride, out uint joint[INFLUENCES]) {
#if (INFLUENCES * INDEX_BYTES) % 4 == 0
  uint words[RUN_CAPACITY];
  for (uint k = 0u; k < uint(INFLUENCES * INDEX_BYTES / 4); ++k)
    words[k] = indices[v * uint(INFLUENCES * INDEX_BYTES / 4) + k];
  split_run(words, 0u, uint(INDEX_BYTES), joint);
#else
  for (uint i = 0u; i < uint(INFLUENCES); ++i) {
    uint byte = (v * uint(INFLUENCES) + i) * uint(INDEX_BYTES);
    joint[i] = field(indices[byte >> 2u], byte & 3u, uint(INDEX_BYTES));
  }
#endif
}
void load_raw_weights(uint v, uint slot_stride, out uint raw_weight[INFLUENCES]) {
#if (INFLUENCES * WEIGHT_BYTES) % 4 == 0
  uint words[RUN_CAPACITY];
  for (uint k = 0u; k < uint(INFLUENCES * WEIGHT_BYTES / 4); ++k)
    words[k] = weights[v * uint(INFLUENCES * WEIGHT_BYTES / 4) + k];
  split_run(words, 0u, uint(WEIGHT_BYTES), raw_weight);
#else
  for (uint i = 0u; i < uint(INFLUENCES); ++i) {
    uint byte = (v * uint(INFLUENCES) + i) * uint(WEIGHT_BYTES);
    raw_weight[i] = field(weights[byte >> 2u], byte & 3u, uint(WEIGHT_BYTES));
  }
#endif
}
#else
// soa-split: slot i of vertex v is element i*S + v.
void load_indices(uint v, uint slot_stride, out uint joint[INFLUENCES]) {
  for (uint i = 0u; i < uint(INFLUENCES); ++i) {
    uint byte = (i * slot_stride + v) * uint(INDEX_BYTES);
    joint[i] = field(indices[byte >> 2u], byte & 3u, uint(INDEX_BYTES));
  }
}
void load_raw_weights(uint v, uint slot_stride, out uint raw_weight[INFLUENCES]) {
  for (uint i = 0u; i < uint(INFLUENCES); ++i) {
    uint byte = (i * slot_stride + v) * uint(WEIGHT_BYTES);
    raw_weight[i] = field(weights[byte >> 2u], byte & 3u, uint(WEIGHT_BYTES));
  }
}
#endif
#endif

float weight_of(uint raw) {
#if WEIGHT_FORMAT == 0
  return uintBitsToFloat(raw);
#elif WEIGHT_FORMAT == 1
  return float(raw) * (1.0 / 65535.0);
#else
  return float(raw) * (1.0 / 255.0);
#endif
}

// ---------------------------------------------------------------- palette
//
// Joint j's row r is vec4 number j*PALETTE_ROWS + r. Row 3 of mat4 (0 0 0 1
// for the affine palettes skinning uses) is never read: outputs are xyz.

#if STORAGE == 0 && INSTANCED
layout(std140, binding = BINDING_PALETTE) uniform Palette { vec4 palette_rows[PALETTE_INSTANCES * PALETTE_FLOAT4S]; };
#define ROW(k) palette_rows[k]
#elif STORAGE == 0
layout(std140, binding = BINDING_PALETTE) uniform Palette { vec4 palette_rows[PALETTE_FLOAT4S]; };
#define ROW(k) palette_rows[k]
#elif STORAGE == 1
#if !SKIN_COMPUTE_STAGE
#error "STORAGE 1 (local): a vertex shader has no shared memory"
#endif
#if ANIM_FUSED
// The records the local copy is made from (anim_records.glsl, skin.comp): palette
// records, or local ones with the nodes and joints they walk (ANIM_BAKED 3, 4) and
// hybrid records' palette records beside them (ANIM_STEADY).
#if ANIM_BAKED >= 3
layout(std430, binding = BINDING_NODES) readonly restrict buffer Nodes { vec4 nodes[]; };
#endif
layout(std430, binding = BINDING_FRAMES) readonly restrict buffer Frames { vec4 frames[]; };
#if ANIM_BAKED >= 3 && ANIM_STEADY
layout(std430, binding = BINDING_STEADY) readonly restrict buffer Steady { vec4 steady[]; };
#endif
#if ANIM_BAKED >= 3
layout(std430, binding = BINDING_JOINTS) readonly restrict buffer Joints { vec4 joints[]; };
#endif
layout(std430, binding = BINDING_INSTANCES) readonly restrict buffer Instances { uvec4 instances[]; };
layout(std430, binding = BINDING_CLIPS) readonly restrict buffer Clips { vec4 clips[]; };
#else
layout(std430, binding = BINDING_PALETTE) readonly restrict buffer Palette { vec4 palette_rows[]; };
#endif
shared vec4 palette_local[PALETTE_FLOAT4S];
#define ROW(k) palette_local[k]
#elif STORAGE == 2
layout(std430, binding = BINDING_PALETTE) readonly restrict buffer Palette { vec4 palette_rows[]; };
#define ROW(k) palette_rows[k]
#else
layout(binding = BINDING_PALETTE) uniform samplerBuffer palette_texels;
#define ROW(k) texelFetch(palette_texels, int(k))
#endif

// (x, y, z, 1) by the three rows.
vec3 transform_point(vec4 r0, vec4 r1, vec4 r2, vec3 p) {
  vec4 h = vec4(p, 1.0);
  return vec3(dot(r0, h), dot(r1, h), dot(r2, h));
}

// The normal matrix's product (reference/skinning.h NormalMatrix): sign(det A)
// * cofactor(A) * d, for A's rows a0..a2 (xyz): the direction of the inverse
// transpose's, right under non-uniform scale and shear.
vec3 transform_normal(vec4 a0, vec4 a1, vec4 a2, vec3 d) {
  vec3 c0 = cross(a1.xyz, a2.xyz);
  vec3 n = vec3(dot(c0, d), dot(cross(a2.xyz, a0.xyz), d), dot(cross(a0.xyz, a1.xyz), d));
  return dot(a0.xyz, c0) < 0.0 ? -n : n;
}

// The tangent's product: A * t.xyz, and t.w flipped where A mirrors (det A < 0).
vec4 transform_tangent(vec4 a0, vec4 a1, vec4 a2, vec4 t) {
  float det = dot(a0.xyz, cross(a1.xyz, a2.xyz));
  return vec4(dot(a0.xyz, t.xyz), dot(a1.xyz, t.xyz), dot(a2.xyz, t.xyz), det < 0.0 ? -t.w : t.w);
}

#if BLEND == 2
// The rigid map of a unit dual quaternion (skin.cl's dual_quaternion_rows).
void dual_quaternion_rows(vec4 r, vec4 d, out vec4 m0, out vec4 m1, out vec4 m2) {
  vec3 t = 2.0 * (r.w * d.xyz - d.w * r.xyz + cross(r.xyz, d.xyz));
  float x = r.x, y = r.y, z = r.z, w = r.w;
  m0 = vec4(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y), t.x);
  m1 = vec4(2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x), t.y);
  m2 = vec4(2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y), t.z);
}
#endif

// Skins one vertex's position given its joints and weights, and gives the
// blended matrix's rows (a0..a2) that normals and tangents are turned by
// (dead code without NORMALS). BLEND 2: the blended dual quaternion's rigid
// map, each influence on the side of the first's (skin.cl's blend).
void blend(uint joint[INFLUENCES], float weight[INFLUENCES], vec3 position, out vec3 out_p,
           out vec4 a0, out vec4 a1, out vec4 a2) {
#if BLEND == 2
  uint k0 = joint[0] * uint(PALETTE_ROWS);
  vec4 q0 = ROW(k0);
  vec4 r = weight[0] * q0, d = weight[0] * ROW(k0 + 1u);
  for (uint i = 1u; i < uint(INFLUENCES); ++i) {
    uint k = joint[i] * uint(PALETTE_ROWS);
    vec4 q = ROW(k);
    float w = dot(q0, q) < 0.0 ? -weight[i] : weight[i];
    r += w * q;
    d += w * ROW(k + 1u);
  }
  float inverse_length = inversesqrt(dot(r, r));
  dual_quaternion_rows(inverse_length * r, inverse_length * d, a0, a1, a2);
  out_p = transform_point(a0, a1, a2, position);
#elif BLEND == 1
  uint k = joint[0] * uint(PALETTE_ROWS);
  vec4 r0 = ROW(k), r1 = ROW(k + 1u), r2 = ROW(k + 2u);
  vec3 p = weight[0] * transform_point(r0, r1, r2, position);
  a0 = weight[0] * r0;
  a1 = weight[0] * r1;
  a2 = weight[0] * r2;
  for (uint i = 1u; i < uint(INFLUENCES); ++i) {
    k = joint[i] * uint(PALETTE_ROWS);
    r0 = ROW(k);
    r1 = ROW(k + 1u);
    r2 = ROW(k + 2u);
    p += weight[i] * transform_point(r0, r1, r2, position);
    a0 += weight[i] * r0;
    a1 += weight[i] * r1;
    a2 += weight[i] * r2;
  }
  out_p = p;
#else
  uint k0 = joint[0] * uint(PALETTE_ROWS);
  a0 = weight[0] * ROW(k0);
  a1 = weight[0] * ROW(k0 + 1u);
  a2 = weight[0] * ROW(k0 + 2u);
  for (uint i = 1u; i < uint(INFLUENCES); ++i) {
    uint k = joint[i] * uint(PALETTE_ROWS);
    a0 += weight[i] * ROW(k);
    a1 += weight[i] * ROW(k + 1u);
    a2 += weight[i] * ROW(k + 2u);
  }
  out_p = transform_point(a0, a1, a2, position);
#endif
}

// Loads vertex v of the launch and skins it: the position, the normal and the
// tangent (xyz not normalised yet; zero without NORMALS / TANGENTS).
// One vertex's inputs, loaded (and morphed): what skin_loaded() skins.
struct VertexIn {
  vec3 position;
  vec3 normal;
  vec4 tangent;
  uint joint[INFLUENCES];
  uint raw_weight[INFLUENCES];
};

VertexIn load_vertex(uint v, uint slot_stride) {
  VertexIn x;
  x.position = load_position(v);
  x.normal = vec3(0.0);
  x.tangent = vec4(0.0);
#if NORMALS
  x.normal = load_normal(v);
#endif
#if TANGENTS
  x.tangent = load_tangent(v);
#endif
#if MORPH
  morph(v, x.position, x.normal, x.tangent);
#endif
  load_indices(v, slot_stride, x.joint);
  load_raw_weights(v, slot_stride, x.raw_weight);
  return x;
}

void skin_loaded(VertexIn x, out vec3 skinned_position, out vec3 skinned_normal, out vec4 skinned_tangent) {
#if INSTANCED && STORAGE != 1
  for (uint i = 0u; i < uint(INFLUENCES); ++i) x.joint[i] += INSTANCE * uint(JOINTS);  // this instance's palette
#endif
  float weight[INFLUENCES];
  for (uint i = 0u; i < uint(INFLUENCES); ++i) weight[i] = weight_of(x.raw_weight[i]);
  vec4 a0, a1, a2;
  blend(x.joint, weight, x.position, skinned_position, a0, a1, a2);
  skinned_normal = vec3(0.0);
  skinned_tangent = vec4(0.0);
#if NORMALS
  skinned_normal = transform_normal(a0, a1, a2, x.normal);
#endif
#if TANGENTS
  skinned_tangent = transform_tangent(a0, a1, a2, x.tangent);
#endif
}

void skin_vertex(uint v, uint slot_stride, out vec3 skinned_position, out vec3 skinned_normal,
                 out vec4 skinned_tangent) {
  skin_loaded(load_vertex(v, slot_stride), skinned_position, skinned_normal, skinned_tangent);
}

// The slot stride S of soa-split for a launch of n vertices (0 otherwise).
uint slot_stride_of(uint count) {
#if LAYOUT == 2
  return ROUND_UP(max(count, 1u), uint(SLOT_STRIDE_MULTIPLE));
#else
  return 0u;
#endif
}

// Normals and tangents packed into one word each (NORMAL_FORMAT 1, 2;
// docs/VARIANTS.md "Packed normals and tangents": the rule skintune's packer
// and the emitted header's PackNormal run too).
#if NORMAL_FORMAT == 1
float sign_not_zero(float v) { return v >= 0.0 ? 1.0 : -1.0; }
uint unorm16(float v) { return uint(floor(clamp(v, 0.0, 1.0) * 65535.0 + 0.5)); }
// The octahedral coordinates of a unit vector, each in [0, 1].
vec2 octahedral(vec3 n) {
  float s = abs(n.x) + abs(n.y) + abs(n.z);
  float u = n.x / s, v = n.y / s;
  if (n.z < 0.0) {
    float fu = (1.0 - abs(v)) * sign_not_zero(u);
    v = (1.0 - abs(u)) * sign_not_zero(v);
    u = fu;
  }
  return vec2(u * 0.5 + 0.5, v * 0.5 + 0.5);
}
uint pack_normal(vec3 n) {
  vec2 o = octahedral(n);
  return unorm16(o.x) | (unorm16(o.y) << 16);
}
// y keeps the handedness: at least 1/2 for +1, below for -1.
uint pack_tangent(vec4 t) {
  vec2 o = octahedral(t.xyz);
  float y = max(o.y, 1.0 / 32767.0) * 0.5 + 0.5;
  if (t.w < 0.0) y = 1.0 - y;
  uint x16 = unorm16(o.x);
  uint y16 = unorm16(y);
  if (x16 == 0u && y16 == 65535u) x16 = 65535u;
  return x16 | (y16 << 16);
}
#elif NORMAL_FORMAT == 2
uint snorm8(float v) { return uint(int(floor(clamp(v, -1.0, 1.0) * 127.0 + 0.5))) & 0xffu; }
uint pack_tangent(vec4 t) { return snorm8(t.x) | (snorm8(t.y) << 8) | (snorm8(t.z) << 16) | (snorm8(t.w) << 24); }
uint pack_normal(vec3 n) { return pack_tangent(vec4(n, 0.0)); }
#endif
