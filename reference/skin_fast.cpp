// The fast CPU path: structure-of-arrays data made once, a loop per influence
// count written so the compiler vectorises it across vertices (gathers of the
// palette rows), function clones for AVX-512 / AVX2 picked at run time by the
// loader (target_clones), all cores through a persistent ThreadPool.
#include <algorithm>
#include <cmath>

#include "reference/error.h"
#include "reference/skinning.h"
#include "reference/thread_pool.h"

namespace skintune {

void CheckSkinningArguments(const SkinnedMesh& mesh, std::size_t palette_size, std::size_t out_positions,
                            std::size_t out_normals, const char* who);

namespace {

// Palette rows of a 3x4 affine matrix, 12 floats per joint: rows 0..2 of the
// 4x4 (the last row of an affine matrix is 0 0 0 1 and is not read).
constexpr int kRowFloats = 12;

struct FastArgs {
  const float* px;
  const float* py;
  const float* pz;
  const float* nx;
  const float* ny;
  const float* nz;
  const std::uint16_t* joints;         // [slot * n + vertex]
  const float* weights;                // [slot * n + vertex]
  std::size_t n;                       // slot stride
  const float* palette;                // joint * 12
  float* out_positions;                // xyz interleaved, as glm::vec3
  float* out_normals;                  // xyz interleaved, or null
};

// Restrict-qualified parameters: without them the compiler must assume the
// outputs alias the inputs and does not vectorise across vertices.
template <int B, bool kNormals>
[[gnu::always_inline]] inline void SkinLoop(const float* __restrict px, const float* __restrict py,
                                            const float* __restrict pz, const float* __restrict nx,
                                            const float* __restrict ny, const float* __restrict nz,
                                            const std::uint16_t* __restrict joints,
                                            const float* __restrict weights, const float* __restrict palette,
                                            float* __restrict out, float* __restrict out_n, std::size_t n,
                                            std::size_t begin, std::size_t end) {
  for (std::size_t v = begin; v < end; ++v) {
    float m[kRowFloats] = {};
#pragma GCC unroll 8
    for (int i = 0; i < B; ++i) {
      const float w = weights[i * n + v];
      const float* row = palette + std::size_t(joints[i * n + v]) * kRowFloats;
#pragma GCC unroll 12
      for (int k = 0; k < kRowFloats; ++k) m[k] += w * row[k];
    }
    const float x = px[v], y = py[v], z = pz[v];
    out[3 * v + 0] = m[0] * x + m[1] * y + m[2] * z + m[3];
    out[3 * v + 1] = m[4] * x + m[5] * y + m[6] * z + m[7];
    out[3 * v + 2] = m[8] * x + m[9] * y + m[10] * z + m[11];
    if constexpr (kNormals) {
      const float ox = m[0] * nx[v] + m[1] * ny[v] + m[2] * nz[v];
      const float oy = m[4] * nx[v] + m[5] * ny[v] + m[6] * nz[v];
      const float oz = m[8] * nx[v] + m[9] * ny[v] + m[10] * nz[v];
      // Branch-free so the loop still vectorises; a zero normal stays zero.
      const float inv = 1.0f / std::sqrt(std::max(ox * ox + oy * oy + oz * oz, 1e-30f));
      out_n[3 * v + 0] = ox * inv;
      out_n[3 * v + 1] = oy * inv;
      out_n[3 * v + 2] = oz * inv;
    }
  }
}

template <int B, bool kNormals>
[[gnu::always_inline]] inline void SkinRange(const FastArgs& a, std::size_t begin, std::size_t end) {
  SkinLoop<B, kNormals>(a.px, a.py, a.pz, a.nx, a.ny, a.nz, a.joints, a.weights, a.palette, a.out_positions,
                        a.out_normals, a.n, begin, end);
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
  std::vector<float> palette;
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
  s.palette.resize(std::size_t(s.joint_count) * kRowFloats);
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
  for (std::size_t j = 0; j < palette.size(); ++j) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) s.palette[j * kRowFloats + r * 4 + c] = palette[j][c][r];
  }
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
