// skintune: what the GLSL palette kernel (palette.comp) and a compute skin
// kernel that makes its palette itself (ANIM_FUSED, skin.comp) share: affine
// rows from translation, rotation and scale, the clips' clocks, and the baked
// records' reads and mixes (docs/ANIMATION.md "Baked clips"; palette.cl says
// how). It reads the buffers `clips` and `frames` (and, hybrid records,
// `steady`) by name: the including file declares them first. A prelude
// (templates/README.md): its text is in every GLSL compute skin kernel, and
// compiled only in the palette kernel (ANIM_PALETTE_KERNEL) and a fused one.
#if defined(ANIM_PALETTE_KERNEL) || ANIM_FUSED
const uint kRestPose = 0xffffu;

struct Affine {
  vec4 row0, row1, row2;  // an affine transform's rows (x, y, z | translation)
};

struct Trs {
  vec4 t, r, s;  // translation, rotation (x, y, z, w), scale
};

vec4 anim_normalize_quat(vec4 q) {
  float length = sqrt(dot(q, q));
  return length > 0.0 ? q / length : q;
}

// T * R * S as rows, from a normalised (x, y, z, w) rotation.
Affine anim_to_affine(Trs x) {
  vec4 q = x.r;
  float xx = q.x * q.x, yy = q.y * q.y, zz = q.z * q.z;
  float xy = q.x * q.y, xz = q.x * q.z, yz = q.y * q.z, wx = q.w * q.x, wy = q.w * q.y, wz = q.w * q.z;
  Affine m;
  m.row0 = vec4((1.0 - 2.0 * (yy + zz)) * x.s.x, 2.0 * (xy - wz) * x.s.y, 2.0 * (xz + wy) * x.s.z, x.t.x);
  m.row1 = vec4(2.0 * (xy + wz) * x.s.x, (1.0 - 2.0 * (xx + zz)) * x.s.y, 2.0 * (yz - wx) * x.s.z, x.t.y);
  m.row2 = vec4(2.0 * (xz - wy) * x.s.x, 2.0 * (yz + wx) * x.s.y, (1.0 - 2.0 * (xx + yy)) * x.s.z, x.t.z);
  return m;
}

bool anim_clip_valid(uint clip) { return clip == kRestPose || clip < uint(ANIM_CLIP_COUNT); }

// Whether an instance's state names clips there are: its clip, and its second where it blends.
bool anim_state_valid(uvec4 s) {
  return anim_clip_valid(s.x & 0xffffu) && (uintBitsToFloat(s.w) == 0.0 || anim_clip_valid(s.x >> 16));
}

// Time t moved into [start, end] of its clip, looping (palette.cl).
float anim_loop_time(float t, vec4 range) {
  float length = range.y - range.x;
  if (!(length > 0.0)) return range.x;
  float u = t - range.x;
  u = min(max(u - length * floor(u / length), 0.0), length);
  return range.x + u;
}

// An instance's state advanced by `step` seconds on its clips' clocks (palette.cl).
uvec4 anim_advance(uvec4 s, float step) {
  uint c1 = s.x & 0xffffu, c2 = s.x >> 16;
  if (c1 != kRestPose && c1 < uint(ANIM_CLIP_COUNT)) s.y = floatBitsToUint(anim_loop_time(uintBitsToFloat(s.y) + step, clips[c1]));
  if (c2 != kRestPose && c2 < uint(ANIM_CLIP_COUNT)) s.z = floatBitsToUint(anim_loop_time(uintBitsToFloat(s.z) + step, clips[c2]));
  return s;
}

#if ANIM_BAKED
// Baked clips: palette.cl's baked kernel (docs/ANIMATION.md "Baked clips").
// Records of ANIM_BAKED_ROWS vec4s, of joints or (local space, ANIM_BAKED
// 3 and 4) nodes (palette.cl says which).
#if ANIM_BAKED == 2
const uint kBakedRows = 4u;
#elif ANIM_BAKED == 4
const uint kBakedRows = 3u;
#else
const uint kBakedRows = 2u;
#endif
#if ANIM_BAKED >= 3
const uint kBakedItems = uint(ANIM_NODE_COUNT);
#else
const uint kBakedItems = uint(ANIM_JOINT_COUNT);
#endif

struct Baked {
  vec4 q, ts, s0, s1;  // rotation (x, y, z, w); translation (and s); the stretch
};

// Float4 k of `frames`, or (hybrid records) of `steady` (GLSL has no
// pointers to pass the buffer).
vec4 record_row(bool from_steady, uint k) {
#if ANIM_STEADY
  if (from_steady) return steady[k];
#endif
  return frames[k];
}

// Item j's record of `rows` vec4s at `frame`, of `items` a frame (palette.cl).
Baked baked_record(bool from_steady, uint rows_, uint items, uint frame, uint j) {
  uint at = rows_ * (frame * items + j);
  return Baked(record_row(from_steady, at), record_row(from_steady, at + 1u),
               rows_ >= 3u ? record_row(from_steady, at + 2u) : vec4(0.0),
               rows_ == 4u ? record_row(from_steady, at + 3u) : vec4(0.0));
}

Baked baked_mix(Baked x, Baked y, float u) {
  vec4 q2 = dot(x.q, y.q) < 0.0 ? -y.q : y.q;
  return Baked(anim_normalize_quat(x.q + u * (q2 - x.q)), x.ts + u * (y.ts - x.ts), x.s0 + u * (y.s0 - x.s0),
               x.s1 + u * (y.s1 - x.s1));
}

Baked baked_sample(bool from_steady, uint rows_, uint items, uint clip, float t, uint j) {
  if (clip == kRestPose) return baked_record(from_steady, rows_, items, 0u, j);
  vec4 range = clips[clip];
  uint count = floatBitsToUint(range.z), first = floatBitsToUint(range.w);
  if (count < 2u) return baked_record(from_steady, rows_, items, first, j);
  float length = range.y - range.x;
  float u = length > 0.0 ? min(max((t - range.x) / length, 0.0), 1.0) * float(count - 1u) : 0.0;
  uint k = min(uint(u), count - 2u);
  return baked_mix(baked_record(from_steady, rows_, items, first + k, j),
                   baked_record(from_steady, rows_, items, first + k + 1u, j), u - float(k));
}

// The rows of R(q) S | t of a palette record of `rows_` vec4s (2: a
// similarity, S = s I).
Affine baked_affine(Baked x, uint rows_) {
  if (rows_ != 4u) return anim_to_affine(Trs(vec4(x.ts.xyz, 0.0), x.q, vec4(x.ts.www, 0.0)));
  Affine r = anim_to_affine(Trs(vec4(0.0), x.q, vec4(1.0, 1.0, 1.0, 0.0)));
  vec4 s_row0 = vec4(x.s0.x, x.s0.w, x.s1.x, 0.0), s_row1 = vec4(x.s0.w, x.s0.y, x.s1.y, 0.0);
  vec4 s_row2 = vec4(x.s1.x, x.s1.y, x.s0.z, 0.0);
  Affine m;
  m.row0 = r.row0.x * s_row0 + r.row0.y * s_row1 + r.row0.z * s_row2 + vec4(0.0, 0.0, 0.0, x.ts.x);
  m.row1 = r.row1.x * s_row0 + r.row1.y * s_row1 + r.row1.z * s_row2 + vec4(0.0, 0.0, 0.0, x.ts.y);
  m.row2 = r.row2.x * s_row0 + r.row2.y * s_row1 + r.row2.z * s_row2 + vec4(0.0, 0.0, 0.0, x.ts.z);
  return m;
}

// Joint (or node) j of an instance (in_: clips, time, time2, weight) from its
// records: its clip's sample, mixed towards its second clip's by the weight.
Baked baked_instance(bool from_steady, uint rows_, uint items, uvec4 in_, uint j) {
  float w = uintBitsToFloat(in_.w);
  Baked x = baked_sample(from_steady, rows_, items, in_.x & 0xffffu, uintBitsToFloat(in_.y), j);
  if (w == 0.0) return x;
  return baked_mix(x, baked_sample(from_steady, rows_, items, in_.x >> 16, uintBitsToFloat(in_.z), j), w);
}
#endif  // ANIM_BAKED
#endif  // ANIM_PALETTE_KERNEL || ANIM_FUSED
