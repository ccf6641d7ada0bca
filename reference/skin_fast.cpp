// The fast CPU path: structure-of-arrays data made once, a loop per influence
// count over 16-float matrix vectors, function clones for AVX-512 / AVX2
// picked at run time by the loader (target_clones), all cores through a
// persistent ThreadPool.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "reference/error.h"
#include "reference/skinning.h"
#include "reference/thread_pool.h"

namespace skintune {

void CheckSkinningArguments(const SkinnedMesh& mesh, std::size_t palette_size, std::size_t out_positions,
                            std::size_t out_normals, const char* who);

namespace {

// The whole 4x4 palette matrix fits one 16-float vector (a zmm register with
// AVX-512; GCC splits it into narrower registers on other targets). Blending
// B matrices is then B loads and B fused multiply-adds per vertex, with no
// gathers (slow on many cores, e.g. AMD Zen 4).
typedef float V16 __attribute__((vector_size(64)));
typedef float V4 __attribute__((vector_size(16)));
constexpr int kMatrixFloats = 16;

struct FastArgs {
  const float* px;
  const float* py;
  const float* pz;
  const float* nx;
  const float* ny;
  const float* nz;
  const std::uint16_t* joints;  // [slot * n + vertex]
  const float* weights;         // [slot * n + vertex]
  std::size_t n;                // slot stride
  const V16* palette;           // one column-major 4x4 per joint, 64-byte aligned
  float* out_positions;         // xyz interleaved, as glm::vec3
  float* out_normals;           // xyz interleaved, or null
};

template <int C>
[[gnu::always_inline]] inline V4 Column(const V16& m) {
  return __builtin_shufflevector(m, m, 4 * C, 4 * C + 1, 4 * C + 2, 4 * C + 3);
}

template <int B, bool kNormals>
[[gnu::always_inline]] inline void SkinRange(const FastArgs& a, std::size_t begin, std::size_t end) {
  const std::size_t n = a.n;
  for (std::size_t v = begin; v < end; ++v) {
    V16 m = a.weights[v] * a.palette[a.joints[v]];
#pragma GCC unroll 8
    for (int i = 1; i < B; ++i) m += a.weights[i * n + v] * a.palette[a.joints[i * n + v]];
    const V4 c0 = Column<0>(m), c1 = Column<1>(m), c2 = Column<2>(m);
    const V4 p = c0 * a.px[v] + c1 * a.py[v] + c2 * a.pz[v] + Column<3>(m);
    float* out = a.out_positions + 3 * v;
    out[0] = p[0];
    out[1] = p[1];
    out[2] = p[2];
    if constexpr (kNormals) {
      const V4 q = c0 * a.nx[v] + c1 * a.ny[v] + c2 * a.nz[v];
      const float len2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
      const float inv = len2 > 0.0f ? 1.0f / std::sqrt(len2) : 0.0f;
      float* out_n = a.out_normals + 3 * v;
      out_n[0] = q[0] * inv;
      out_n[1] = q[1] * inv;
      out_n[2] = q[2] * inv;
    }
  }
}

template <bool kNormals>
[[gnu::always_inline]] inline void Dispatch(int b, const FastArgs& a, std::size_t begin, std::size_t end) {
  switch (b) {
    case 1: return SkinRange<1, kNormals>(a, begin, end);
    case 2: return SkinRange<2, kNormals>(a, begin, end);
    case 3: return SkinRange<3, kNormals>(a, begin, end);
    case 4: return SkinRange<4, kNormals>(a, begin, end);
    case 5: return SkinRange<5, kNormals>(a, begin, end);
    case 6: return SkinRange<6, kNormals>(a, begin, end);
    case 7: return SkinRange<7, kNormals>(a, begin, end);
    default: return SkinRange<8, kNormals>(a, begin, end);
  }
}

[[gnu::target_clones("arch=skylake-avx512", "arch=haswell", "default")]]
void SkinChunk(int b, bool normals, const FastArgs& a, std::size_t begin, std::size_t end) {
  if (normals) {
    Dispatch<true>(b, a, begin, end);
  } else {
    Dispatch<false>(b, a, begin, end);
  }
}

}  // namespace

struct FastSkinner::Impl {
  std::size_t n = 0;
  int b = 0;
  int joint_count = 0;
  std::vector<float> px, py, pz, nx, ny, nz;
  std::vector<std::uint16_t> joints;  // [slot * n + vertex]
  std::vector<float> weights;         // [slot * n + vertex]
  std::vector<V16> palette;  // std::vector honours the 64-byte alignment (C++17)
  ThreadPool pool;
  explicit Impl(unsigned threads) : pool(threads) {}
};

FastSkinner::FastSkinner(const SkinnedMesh& mesh, unsigned threads) : impl_(std::make_unique<Impl>(threads)) {
  ThrowIfInvalid(mesh, "FastSkinner");
  Impl& s = *impl_;
  s.n = mesh.vertex_count();
  s.b = mesh.influences;
  s.joint_count = mesh.joint_count;
  s.px.resize(s.n);
  s.py.resize(s.n);
  s.pz.resize(s.n);
  for (std::size_t v = 0; v < s.n; ++v) {
    s.px[v] = mesh.positions[v].x;
    s.py[v] = mesh.positions[v].y;
    s.pz[v] = mesh.positions[v].z;
  }
  if (mesh.has_normals()) {
    s.nx.resize(s.n);
    s.ny.resize(s.n);
    s.nz.resize(s.n);
    for (std::size_t v = 0; v < s.n; ++v) {
      s.nx[v] = mesh.normals[v].x;
      s.ny[v] = mesh.normals[v].y;
      s.nz[v] = mesh.normals[v].z;
    }
  }
  s.joints.resize(s.n * s.b);
  s.weights.resize(s.n * s.b);
  for (std::size_t v = 0; v < s.n; ++v) {
    for (int i = 0; i < s.b; ++i) {
      s.joints[i * s.n + v] = mesh.joints[v * s.b + i];
      s.weights[i * s.n + v] = mesh.weights[v * s.b + i];
    }
  }
  s.palette.resize(s.joint_count);
}

FastSkinner::~FastSkinner() = default;

unsigned FastSkinner::threads() const { return impl_->pool.size(); }
std::size_t FastSkinner::vertex_count() const { return impl_->n; }
int FastSkinner::influences() const { return impl_->b; }

std::size_t FastSkinner::BytesPerRun(bool with_normals) const {
  const Impl& s = *impl_;
  const std::size_t per_vertex_in = 3 * sizeof(float) + s.b * (sizeof(std::uint16_t) + sizeof(float));
  const std::size_t per_vertex_out = 3 * sizeof(float);
  const std::size_t normals = with_normals && !s.nx.empty() ? 2 * 3 * sizeof(float) : 0;
  return s.n * (per_vertex_in + per_vertex_out + normals);
}

void FastSkinner::Run(std::span<const glm::mat4> palette, std::span<glm::vec3> out_positions,
                      std::span<glm::vec3> out_normals) {
  Impl& s = *impl_;
  if (palette.size() != static_cast<std::size_t>(s.joint_count)) {
    throw Error("FastSkinner: palette has " + std::to_string(palette.size()) + " matrices, mesh has " +
                std::to_string(s.joint_count) + " joints");
  }
  if (out_positions.size() != s.n || (!out_normals.empty() && out_normals.size() != s.n)) {
    throw Error("FastSkinner: output spans must hold " + std::to_string(s.n) + " vertices");
  }
  static_assert(sizeof(glm::mat4) == sizeof(V16));
  for (std::size_t j = 0; j < palette.size(); ++j) std::memcpy(&s.palette[j], &palette[j], sizeof(V16));
  const bool normals = !out_normals.empty() && !s.nx.empty();
  const FastArgs args{s.px.data(),          s.py.data(),          s.pz.data(),
                      s.nx.data(),          s.ny.data(),          s.nz.data(),
                      s.joints.data(),      s.weights.data(),     s.n,
                      s.palette.data(),
                      &out_positions[0].x,  normals ? &out_normals[0].x : nullptr};
  // 16k-vertex chunks: large enough to amortise scheduling, small enough to balance.
  constexpr std::size_t kGrain = 16384;
  const int b = s.b;
  s.pool.ParallelFor(s.n, kGrain, [&](std::size_t begin, std::size_t end) {
    SkinChunk(b, normals, args, begin, end);
  });
}

}  // namespace skintune
