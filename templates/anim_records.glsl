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

// ---------------------------------------------------------------- the hierarchy
// What the kernels that walk the hierarchy share (anim_records.clh says
// which, and palette.cl how): a work-group of ANIM_GROUP invocations over one
// instance, its nodes' rows in shared memory. They read the buffers `nodes`
// and `joints` by name.
#if (defined(ANIM_PALETTE_KERNEL) && ANIM_BAKED != 1 && ANIM_BAKED != 2) || (ANIM_FUSED && ANIM_BAKED >= 3)
Affine anim_multiply(Affine a, Affine b) {
  const vec4 unit_w = vec4(0.0, 0.0, 0.0, 1.0);
  Affine c;
  c.row0 = a.row0.x * b.row0 + a.row0.y * b.row1 + a.row0.z * b.row2 + a.row0.w * unit_w;
  c.row1 = a.row1.x * b.row0 + a.row1.y * b.row1 + a.row1.z * b.row2 + a.row1.w * unit_w;
  c.row2 = a.row2.x * b.row0 + a.row2.y * b.row1 + a.row2.z * b.row2 + a.row2.w * unit_w;
  return c;
}

#define ANIM_MAX_NODES 512  // fixed: the launch and the local memory the kernel is written for
// The local memory an instance's nodes take: the model's nodes (a define),
// at most ANIM_MAX_NODES, so that a small rig's groups leave the rest of it,
// and the L1 cache it shares, to others.
#if ANIM_NODE_COUNT < ANIM_MAX_NODES
#define ANIM_LOCAL_NODES ANIM_NODE_COUNT
#else
#define ANIM_LOCAL_NODES ANIM_MAX_NODES
#endif
#define ANIM_NODES_PER_ITEM ((ANIM_LOCAL_NODES + ANIM_GROUP - 1) / ANIM_GROUP)  // item, item + ANIM_GROUP, ...
// Node n's sampled translation, rotation and scale at rows 3n .. 3n + 2,
// then its local transform's rows there; and its parent (palette.cl).
shared vec4 local_rows[3 * ANIM_LOCAL_NODES];
shared int local_parent[ANIM_LOCAL_NODES];

// Each node's global transform by pointer jumping, ANIM_JUMPS rounds
// (anim_records.clh). Every invocation of the group calls it (it waits at
// barriers); `walk`, the same in every invocation, says whether there is work.
void anim_jump(bool walk, uint item) {
  for (uint round_ = 0u; round_ < uint(ANIM_JUMPS); ++round_) {
    Affine up[ANIM_NODES_PER_ITEM];
    int next[ANIM_NODES_PER_ITEM];
    for (uint k = 0u; k < uint(ANIM_NODES_PER_ITEM); ++k) {
      uint n = item + k * uint(ANIM_GROUP);
      next[k] = -2;  // no jump
      int p = walk && n < uint(ANIM_NODE_COUNT) ? local_parent[n] : -1;
      if (p >= 0) {
        up[k] = Affine(local_rows[3u * uint(p)], local_rows[3u * uint(p) + 1u], local_rows[3u * uint(p) + 2u]);
        next[k] = local_parent[p];
      }
    }
    memoryBarrierShared();
    barrier();
    for (uint k = 0u; k < uint(ANIM_NODES_PER_ITEM); ++k) {
      uint n = item + k * uint(ANIM_GROUP);
      if (next[k] == -2) continue;
      Affine m = anim_multiply(up[k], Affine(local_rows[3u * n], local_rows[3u * n + 1u], local_rows[3u * n + 2u]));
      local_rows[3u * n] = m.row0;
      local_rows[3u * n + 1u] = m.row1;
      local_rows[3u * n + 2u] = m.row2;
      local_parent[n] = next[k];
    }
    memoryBarrierShared();
    barrier();
  }
}

// A joint's palette entry once the walk is done: its node's global transform
// (joint0.x: the node) by its inverse bind (joint1..3: its rows).
Affine anim_joint_entry(vec4 joint0, vec4 joint1, vec4 joint2, vec4 joint3) {
  uint node = floatBitsToUint(joint0.x);
  return anim_multiply(Affine(local_rows[3u * node], local_rows[3u * node + 1u], local_rows[3u * node + 2u]),
                       Affine(joint1, joint2, joint3));
}

#if ANIM_BAKED >= 3
// Each node's local transform from its records, mixed in local space, with
// its parent (anim_records.clh): the invocation's nodes item, item + ANIM_GROUP, ...
void anim_local_from_records(uvec4 in_, uint item) {
  float w = uintBitsToFloat(in_.w);
  for (uint n = item; n < uint(ANIM_NODE_COUNT); n += uint(ANIM_GROUP)) {
    Affine l;
    if (floatBitsToUint(nodes[4u * n].y) != 0u) {
      l = Affine(nodes[4u * n + 1u], nodes[4u * n + 2u], nodes[4u * n + 3u]);
    } else {
      Baked x = baked_sample(false, kBakedRows, kBakedItems, in_.x & 0xffffu, uintBitsToFloat(in_.y), n);
      if (w != 0.0) x = baked_mix(x, baked_sample(false, kBakedRows, kBakedItems, in_.x >> 16, uintBitsToFloat(in_.z), n), w);
#if ANIM_BAKED == 4
      l = anim_to_affine(Trs(vec4(x.ts.xyz, 0.0), x.q, x.s0));
#else
      l = anim_to_affine(Trs(vec4(x.ts.xyz, 0.0), x.q, vec4(x.ts.www, 0.0)));
#endif
    }
    local_rows[3u * n] = l.row0;
    local_rows[3u * n + 1u] = l.row1;
    local_rows[3u * n + 2u] = l.row2;
    local_parent[n] = floatBitsToInt(nodes[4u * n].x);
  }
}
#endif  // ANIM_BAKED >= 3
#endif  // the hierarchy

#if ANIM_FUSED
// Joint j's entry in the group's palette_local (PALETTE_ROWS vec4s a joint).
void anim_store_entry(uint j, Affine m) {
  palette_local[j * uint(PALETTE_ROWS)] = m.row0;
  palette_local[j * uint(PALETTE_ROWS) + 1u] = m.row1;
  palette_local[j * uint(PALETTE_ROWS) + 2u] = m.row2;
#if PALETTE_ROWS == 4
  palette_local[j * uint(PALETTE_ROWS) + 3u] = vec4(0.0, 0.0, 0.0, 1.0);
#endif
}

// An instance's palette in the group's palette_local (PALETTE_ROWS vec4s a
// joint), made by the group's invocations from its records at `state` (its
// clocks already advanced), ready for a barrier; NaN rows for a state that
// names clips there are not (anim_records.clh). Every invocation calls it.
void anim_fused_palette(uvec4 state) {
  uint item = gl_LocalInvocationID.x;
  bool valid = anim_state_valid(state);
#if ANIM_BAKED >= 3 && ANIM_STEADY
  bool walk = valid && uintBitsToFloat(state.w) != 0.0;  // one clip: palette records; a cross-fade walks
#elif ANIM_BAKED >= 3
  bool walk = valid;
#else
  bool walk = false;
#endif
  vec4 nan_row = vec4(uintBitsToFloat(0x7fc00000u));
  for (uint j = item; !walk && j < uint(JOINTS); j += uint(ANIM_GROUP)) {
    Affine m = Affine(nan_row, nan_row, nan_row);
#if ANIM_BAKED >= 3 && ANIM_STEADY
    if (valid) m = baked_affine(baked_instance(true, uint(ANIM_STEADY), uint(JOINTS), state, j), uint(ANIM_STEADY));
#elif ANIM_BAKED < 3
    if (valid) m = baked_affine(baked_instance(false, kBakedRows, uint(JOINTS), state, j), kBakedRows);
#endif
    anim_store_entry(j, m);
  }
#if ANIM_BAKED >= 3
  if (!walk) return;  // the same in every invocation: the whole group walks or none does (anim_records.clh)
  anim_local_from_records(state, item);
  memoryBarrierShared();
  barrier();
  anim_jump(true, item);
  for (uint j = item; j < uint(JOINTS); j += uint(ANIM_GROUP)) {
    Affine m = anim_joint_entry(joints[4u * j], joints[4u * j + 1u], joints[4u * j + 2u], joints[4u * j + 3u]);
    anim_store_entry(j, m);
  }
#endif  // ANIM_BAKED >= 3
}
#endif  // ANIM_FUSED
#endif  // ANIM_PALETTE_KERNEL || ANIM_FUSED
