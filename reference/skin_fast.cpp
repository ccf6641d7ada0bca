// The fast CPU path: structure-of-arrays data made once (packed float3
// positions and normals, u16 joint and f32 weight slot arrays), skinned by
// the CPU kernel family (cpu_kernels/cpu_kernels.h: a kernel per influence
// count, the table of this CPU's instruction set) with streaming stores, all
// cores through a persistent ThreadPool. The cpu device (skintune tune)
// runs the same kernels on every format and layout of the variant space.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "cpu_kernels/cpu_kernels.h"
#include "base/error.h"
#include "reference/skinning.h"
#include "base/thread_pool.h"

namespace skintune::internal {

void CheckSkinningArguments(const SkinnedMesh& mesh, std::size_t palette_size, std::size_t out_positions,
                            std::size_t out_normals, const char* who);

struct FastSkinner::Impl {
  std::size_t n = 0;
  int b = 0;
  int joint_count = 0;
  std::vector<float> positions, normals;  // xyz per vertex
  std::vector<std::uint16_t> joints;      // [slot * n + vertex]
  std::vector<float> weights;             // [slot * n + vertex]
  std::vector<std::uint8_t> rows;         // the palette as float4 rows, 4 per joint (PackPalette's mat4 form)
  CpuPalette palette;
  CpuKernelFn kernel = nullptr;
  ThreadPool pool;
  explicit Impl(unsigned threads) : pool(threads) {}
};

FastSkinner::FastSkinner(const SkinnedMesh& mesh, unsigned threads) : impl_(std::make_unique<Impl>(threads)) {
  ThrowIfInvalid(mesh, "FastSkinner");
  RequireNoMorph(mesh, "FastSkinner");
  Impl& s = *impl_;
  s.n = mesh.vertex_count();
  s.b = mesh.influences;
  s.joint_count = mesh.joint_count;
  s.positions.resize(3 * s.n);
  std::memcpy(s.positions.data(), mesh.positions.data(), s.positions.size() * sizeof(float));
  if (mesh.has_normals()) {
    s.normals.resize(3 * s.n);
    std::memcpy(s.normals.data(), mesh.normals.data(), s.normals.size() * sizeof(float));
  }
  s.joints.resize(s.n * s.b);
  s.weights.resize(s.n * s.b);
  for (std::size_t v = 0; v < s.n; ++v) {
    for (int i = 0; i < s.b; ++i) {
      s.joints[i * s.n + v] = mesh.joints[v * s.b + i];
      s.weights[i * s.n + v] = mesh.weights[v * s.b + i];
    }
  }
  s.rows.resize(static_cast<std::size_t>(s.joint_count) * 64);
  s.kernel = FindCpuKernel({s.b, CpuIndex::kU16, CpuWeight::kF32, 4, false});
}

FastSkinner::~FastSkinner() = default;

unsigned FastSkinner::threads() const { return impl_->pool.size(); }
std::size_t FastSkinner::vertex_count() const { return impl_->n; }
int FastSkinner::influences() const { return impl_->b; }

std::size_t FastSkinner::BytesPerRun(bool with_normals) const {
  const Impl& s = *impl_;
  const std::size_t per_vertex_in = 3 * sizeof(float) + s.b * (sizeof(std::uint16_t) + sizeof(float));
  const std::size_t per_vertex_out = 3 * sizeof(float);
  const std::size_t normals = with_normals && !s.normals.empty() ? 2 * 3 * sizeof(float) : 0;
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
  static_assert(sizeof(glm::vec3) == 3 * sizeof(float));
  std::uint8_t* at = s.rows.data();
  for (const glm::mat4& m : palette)
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c, at += sizeof(float)) std::memcpy(at, &m[c][r], sizeof(float));
  LoadCpuPalette(s.rows, 4, s.palette);
  const bool normals = !out_normals.empty() && !s.normals.empty();
  CpuStreams streams;
  streams.positions = reinterpret_cast<const std::uint8_t*>(s.positions.data());
  streams.position_stride = 3 * sizeof(float);
  if (normals) {
    streams.normals = reinterpret_cast<const std::uint8_t*>(s.normals.data());
    streams.normal_stride = 3 * sizeof(float);
  }
  streams.indices = reinterpret_cast<const std::uint8_t*>(s.joints.data());
  streams.index_stride = sizeof(std::uint16_t);
  streams.index_slot = s.n * sizeof(std::uint16_t);
  streams.weights = reinterpret_cast<const std::uint8_t*>(s.weights.data());
  streams.weight_stride = sizeof(float);
  streams.weight_slot = s.n * sizeof(float);
  streams.out_positions = &out_positions[0].x;
  streams.out_normals = normals ? &out_normals[0].x : nullptr;
  streams.output_floats = 3;
  streams.stream_stores = true;  // skips the read-for-ownership of the outputs (docs/PERFORMANCE.md)
  // 16k-vertex chunks: large enough to amortise scheduling, small enough to
  // balance (the cpu device chooses its own per machine by measurement).
  constexpr std::size_t kGrain = 16384;
  RunCpuKernel(s.kernel, streams, s.palette, s.n, s.pool, kGrain);
}

}  // namespace skintune::internal
