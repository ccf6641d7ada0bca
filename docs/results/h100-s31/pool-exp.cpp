#include <atomic>
#include <chrono>
#include <cstdio>
#include <thread>
#include <vector>
#include <cstdlib>
#include "generator/packer.h"
#include "reference/thread_pool.h"
using namespace skintune::internal;
using Clock = std::chrono::steady_clock;
int main(int argc, char** argv) {
  const unsigned threads = argc > 1 ? atoi(argv[1]) : 2;
  constexpr std::size_t kMatrices = 64 * 77;
  Variant variant; variant.palette = PaletteFormat::kMat3x4;
  std::vector<std::uint8_t> outv(kMatrices * 48 + 64);
  std::uint8_t* out = outv.data();
  std::vector<std::vector<float>> poses(2, std::vector<float>(kMatrices * 16));
  for (auto& p : poses) for (std::size_t i = 0; i < p.size(); ++i) p[i] = (i % 16 == 15) ? 1.f : 0.01f * (i % 7);
  const int N = 20000;
  // single
  auto t0 = Clock::now();
  for (int f = 0; f < N; ++f) PackPaletteInto(poses[f % 2].data(), kMatrices, variant, out);
  auto t1 = Clock::now();
  printf("single  %.2f us\n", std::chrono::duration<double, std::micro>(t1 - t0).count() / N);
  ThreadPool pool(threads, std::chrono::microseconds(500));
  const std::size_t grain = (kMatrices + threads - 1) / threads;
  t0 = Clock::now();
  for (int f = 0; f < N; ++f) {
    const float* in = poses[f % 2].data();
    pool.ParallelFor(kMatrices, grain, [&](std::size_t b, std::size_t e) { PackPaletteInto(in + 16 * b, e - b, variant, out + 48 * b); });
  }
  t1 = Clock::now();
  printf("pool    %.2f us\n", std::chrono::duration<double, std::micro>(t1 - t0).count() / N);
  {
    const auto caller = std::this_thread::get_id();
    std::atomic<long> by_caller{0};
    t0 = Clock::now();
    for (int f = 0; f < N; ++f) {
      const float* in = poses[f % 2].data();
      pool.ParallelFor(kMatrices, grain, [&](std::size_t b, std::size_t e) {
        if (std::this_thread::get_id() == caller) ++by_caller;
        PackPaletteInto(in + 16 * b, e - b, variant, out + 48 * b); });
    }
    t1 = Clock::now();
    printf("pool    %.2f us, chunks by the caller per loop %.2f of %u\n", std::chrono::duration<double, std::micro>(t1 - t0).count() / N, double(by_caller) / N, threads);
    // static: each thread packs the region of its own index (set on first use), whatever chunk it claimed
    std::atomic<int> next_id{0};
    t0 = Clock::now();
    for (int f = 0; f < N; ++f) {
      const float* in = poses[f % 2].data();
      pool.ParallelFor(kMatrices, grain, [&](std::size_t, std::size_t) {
        thread_local int id = -1; if (id < 0) id = next_id++ % (int)threads;
        const std::size_t b = std::min(kMatrices, id * grain), e = std::min(kMatrices, b + grain);
        PackPaletteInto(in + 16 * b, e - b, variant, out + 48 * b); });
    }
    t1 = Clock::now();
    printf("pool-static %.2f us\n", std::chrono::duration<double, std::micro>(t1 - t0).count() / N);
  }
  // spinning
  std::atomic<std::size_t> generation{0}, finished{0}; std::atomic<bool> stop{false};
  const std::size_t share = grain;
  auto pack = [&](std::size_t t, std::size_t frame) { const std::size_t b = std::min(kMatrices, t * share), e = std::min(kMatrices, b + share); PackPaletteInto(poses[frame % 2].data() + 16 * b, e - b, variant, out + 48 * b); };
  std::vector<std::thread> helpers;
  for (std::size_t t = 1; t < threads; ++t) helpers.emplace_back([&, t] { std::size_t seen = 0; for (;;) { std::size_t g; while ((g = generation.load()) == seen && !stop.load()) __builtin_ia32_pause(); if (stop) return; seen = g; pack(t, g); finished.fetch_add(1); } });
  t0 = Clock::now();
  for (int f = 1; f <= N; ++f) { finished.store(0); generation.store(f); pack(0, f); while (finished.load() != threads - 1) __builtin_ia32_pause(); }
  t1 = Clock::now();
  stop = true; for (auto& h : helpers) h.join();
  printf("spin    %.2f us\n", std::chrono::duration<double, std::micro>(t1 - t0).count() / N);
}
