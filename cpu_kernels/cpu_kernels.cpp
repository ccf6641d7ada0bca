// The CPU kernels' selection (one table per instruction set), palettes,
// schedules and the threaded loop. The kernels: cpu_kernels.inc, compiled in
// slices by cpu_kernels_slice.cpp.
#include "cpu_kernels/cpu_kernels.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <optional>
#include <set>
#include <string>
#include <thread>

#include "cpu_kernels/cpu_kernel_table.h"
#include "base/error.h"
#include "base/thread_pool.h"

namespace skintune::internal {

namespace {

const char* const kIndexNames[] = {"u32", "u16", "u8"};
const char* const kWeightNames[] = {"f32", "unorm16", "unorm8"};
static_assert(std::size(kIndexNames) == cpu_detail::kIndexFormats);
static_assert(std::size(kWeightNames) == cpu_detail::kWeightFormats);

using cpu_detail::CpuIsa;

// Whether this CPU runs the table of `isa` (the -march of its slices,
// cpu_kernels/CMakeLists.txt).
bool Runs(CpuIsa isa) {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_cpu_init();
  switch (isa) {
    case CpuIsa::kAvx512:
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
             __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512dq");
    case CpuIsa::kAvx2:
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && __builtin_cpu_supports("bmi2");
    case CpuIsa::kBaseline: return true;
  }
  return false;
#else
  return isa == CpuIsa::kBaseline;
#endif
}

// The tables this build holds (SKINTUNE_CPU_ISAS, cpu_kernels/CMakeLists.txt),
// the fastest first.
constexpr struct {
  CpuIsa isa;
  const char* name;
  bool built;
} kIsas[] = {
    {CpuIsa::kAvx512, "avx512", SKINTUNE_CPU_ISA_AVX512},
    {CpuIsa::kAvx2, "avx2", SKINTUNE_CPU_ISA_AVX2},
    {CpuIsa::kBaseline, "baseline", SKINTUNE_CPU_ISA_BASELINE},
};

// The fastest table this build holds and this CPU runs (kIsas's index), or
// none.
std::optional<std::size_t> ThisCpu() {
  static const std::optional<std::size_t> chosen = []() -> std::optional<std::size_t> {
    for (std::size_t i = 0; i < std::size(kIsas); ++i)
      if (kIsas[i].built && Runs(kIsas[i].isa)) return i;
    return std::nullopt;
  }();
  return chosen;
}

// The table of kIsa, its 8 slices (B = 1..8) one after another.
template <CpuIsa kIsa, int... kB>
cpu_detail::CpuKernelTable AssembleTable(std::integer_sequence<int, kB...>) {
  cpu_detail::CpuKernelTable table{};
  const cpu_detail::CpuKernelSlice* slices[] = {&cpu_detail::CpuKernelSliceOf<kIsa, kB + 1>()...};
  static_assert(std::size(slices) == kCpuMaxInfluences);
  for (std::size_t b = 0; b < std::size(slices); ++b)
    std::copy(slices[b]->begin(), slices[b]->end(), table.begin() + b * cpu_detail::kSlotsPerInfluenceCount);
  return table;
}

template <CpuIsa kIsa>
const cpu_detail::CpuKernelTable& TableOf() {
  static const cpu_detail::CpuKernelTable table = AssembleTable<kIsa>(std::make_integer_sequence<int, kCpuMaxInfluences>{});
  return table;
}

const cpu_detail::CpuKernelTable& Table() {
  const std::optional<std::size_t> chosen = ThisCpu();
  if (!chosen) {
    std::string built;
    for (const auto& isa : kIsas)
      if (isa.built) built += std::string(built.empty() ? "" : ", ") + isa.name;
    throw Error("cpu kernel: this build holds the tables of " + built +
                " (SKINTUNE_CPU_ISAS), none of which this CPU runs: build with the default, which includes baseline");
  }
  switch (kIsas[*chosen].isa) {
#if SKINTUNE_CPU_ISA_AVX512
    case CpuIsa::kAvx512: return TableOf<CpuIsa::kAvx512>();
#endif
#if SKINTUNE_CPU_ISA_AVX2
    case CpuIsa::kAvx2: return TableOf<CpuIsa::kAvx2>();
#endif
#if SKINTUNE_CPU_ISA_BASELINE
    case CpuIsa::kBaseline: return TableOf<CpuIsa::kBaseline>();
#endif
    default: break;
  }
  throw Error("cpu kernel: no table");  // unreachable: ThisCpu() picks a built one
}

}  // namespace

std::string CpuKernelName(const CpuKernelKey& key) {
  const char* const palette = key.palette_rows == 2 ? "dualquat" : key.palette_rows == 3 ? "mat3x4" : "mat4";
  const char* const blend = key.dual_quaternion ? ".dq" : key.point_blend ? ".point" : ".matrix";
  return "b" + std::to_string(key.influences) + "." + kIndexNames[static_cast<int>(key.index)] + "." +
         kWeightNames[static_cast<int>(key.weight)] + "." + palette + blend;
}

void LoadCpuPalette(std::span<const std::uint8_t> packed_rows, int rows, CpuPalette& out) {
  if (rows < 2 || rows > 4)
    throw Error("cpu palette: " + std::to_string(rows) + " rows per joint (expected 4, 3 or 2)");
  const std::size_t joint_bytes = static_cast<std::size_t>(rows) * 4 * sizeof(float);
  if (packed_rows.size() % joint_bytes != 0) {
    throw Error("cpu palette: " + std::to_string(packed_rows.size()) + " bytes is not a whole number of " +
                std::to_string(rows) + "-row joints (" + std::to_string(joint_bytes) + " bytes each)");
  }
  out.rows = rows;
  out.joints.resize(packed_rows.size() / joint_bytes);
  const std::uint8_t* at = packed_rows.data();
  for (CpuJoint& j : out.joints) {
    std::memset(j.f, 0, sizeof j.f);
    if (rows == 2) {  // a dual quaternion: its two rows as they are, the real part first
      std::memcpy(j.f, at, joint_bytes);
      at += joint_bytes;
      continue;
    }
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < 4; ++c, at += sizeof(float)) std::memcpy(&j.f[rows * c + r], at, sizeof(float));
    }
  }
}

CpuKernelFn FindCpuKernel(const CpuKernelKey& key) {
  if (key.influences < 1 || key.influences > kCpuMaxInfluences)
    throw Error("cpu kernel: " + std::to_string(key.influences) + " influences (expected 1..8)");
  if (key.palette_rows < 2 || key.palette_rows > 4)
    throw Error("cpu kernel: " + std::to_string(key.palette_rows) + " palette rows (expected 4, 3 or 2)");
  if (key.dual_quaternion && key.point_blend)
    throw Error("cpu kernel: dual-quaternion and point blending together (the key asks for both)");
  if (key.dual_quaternion && key.palette_rows != 2)
    throw Error("cpu kernel: dual-quaternion blending reads 2 palette rows a joint (a unit dual quaternion), not " +
                std::to_string(key.palette_rows));
  if (!key.dual_quaternion && key.palette_rows == 2)
    throw Error("cpu kernel: 2 palette rows (a unit dual quaternion) are read by dual-quaternion blending only, not " +
                std::string(key.point_blend ? "point" : "matrix") + " blending");
  return Table()[cpu_detail::SlotOf(key)];
}

std::vector<std::string> CpuKernelIsasBuilt() {
  std::vector<std::string> built;
  for (const auto& isa : kIsas)
    if (isa.built) built.push_back(isa.name);
  return built;
}

const char* CpuKernelIsa() {
  const std::optional<std::size_t> chosen = ThisCpu();
  return chosen ? kIsas[*chosen].name : "none";
}

std::vector<CpuKernelKey> AllCpuKernelKeys() {
  std::vector<CpuKernelKey> keys;
  for (std::size_t slot = 0; slot < cpu_detail::kCpuKernelCount; ++slot) keys.push_back(cpu_detail::KeyOfSlot(slot));
  return keys;
}

std::string Describe(const CpuSchedule& schedule) {
  return std::to_string(schedule.threads) + (schedule.threads == 1 ? " thread x " : " threads x ") +
         std::to_string(schedule.chunk) + "-vertex chunks";
}

std::vector<CpuSchedule> CpuScheduleCandidates(std::size_t vertices, unsigned max_threads) {
  if (max_threads == 0) max_threads = std::max(1u, std::thread::hardware_concurrency());
  std::vector<unsigned> threads;
  for (unsigned t = 1; t < max_threads; t *= 2) threads.push_back(t);
  threads.push_back(max_threads);
  std::vector<CpuSchedule> out;
  const auto round64 = [](std::size_t n) { return std::max<std::size_t>(64, (n + 63) / 64 * 64); };
  for (unsigned t : threads) {
    std::vector<std::size_t> chunks;
    for (std::size_t c : {std::size_t(4096), std::size_t(16384), std::size_t(65536)})
      if (c <= vertices) chunks.push_back(c);
    const std::size_t per_thread = round64((vertices + t - 1) / t);
    if (std::find(chunks.begin(), chunks.end(), per_thread) == chunks.end()) chunks.push_back(per_thread);
    for (std::size_t c : chunks) out.push_back({t, c});
  }
  return out;
}

std::size_t FastestCandidate(std::size_t candidates, const std::function<double(std::size_t)>& frame_ms,
                             int samples, const std::function<std::size_t(std::size_t)>& warm_group) {
  if (candidates == 0) throw Error("cpu schedule: no candidates");
  samples = std::max(samples, 1);
  // Untimed: first touch, the pool's start; once per warm group where given.
  std::set<std::size_t> warmed;
  for (std::size_t i = 0; i < candidates; ++i)
    if (!warm_group || warmed.insert(warm_group(i)).second) frame_ms(i);
  // Rounds of one call per candidate: a drift of the host's load falls on
  // every candidate alike rather than on those timed during it. After the
  // first round only those within kFastestCandidateCut of its quickest go on.
  std::vector<std::vector<double>> t(candidates);
  std::vector<bool> racing(candidates, true);
  for (int k = 0; k < samples; ++k) {
    for (std::size_t i = 0; i < candidates; ++i)
      if (racing[i]) t[i].push_back(frame_ms(i));
    if (k > 0) continue;
    double quickest = t[0][0];
    for (std::size_t i = 1; i < candidates; ++i) quickest = std::min(quickest, t[i][0]);
    for (std::size_t i = 0; i < candidates; ++i) racing[i] = t[i][0] <= kFastestCandidateCut * quickest;
  }
  std::size_t best = candidates;
  double best_ms = 0.0;
  for (std::size_t i = 0; i < candidates; ++i) {
    if (!racing[i]) continue;
    const double quickest = *std::min_element(t[i].begin(), t[i].end());
    if (best == candidates || quickest < best_ms) {
      best = i;
      best_ms = quickest;
    }
  }
  return best;
}

void RunCpuKernel(CpuKernelFn kernel, const CpuStreams& s, const CpuPalette& palette, std::size_t count,
                  ThreadPool& pool, std::size_t chunk) {
  if (chunk == 0) throw Error("cpu kernel: chunk of 0 vertices");
  if (pool.size() == 1 || count <= chunk) {
    kernel(s, palette, 0, count);
    return;
  }
  pool.ParallelFor(count, chunk, [&](std::size_t begin, std::size_t end) { kernel(s, palette, begin, end); });
}

CpuPools::CpuPools() = default;
CpuPools::~CpuPools() = default;

ThreadPool& CpuPools::Get(unsigned threads) {
  threads = std::max(threads, 1u);
  if (pools_.size() < threads) pools_.resize(threads);
  auto& slot = pools_[threads - 1];
  if (!slot) slot = std::make_unique<ThreadPool>(threads, kCpuPoolSpin);
  return *slot;
}

}  // namespace skintune::internal
