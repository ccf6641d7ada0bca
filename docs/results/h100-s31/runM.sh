#!/usr/bin/env bash
# Session 31, call M: the crew waking only the helpers a packing needs: host_work_test under
# ThreadSanitizer on the 8-lane host (packings on 1-8 threads in turn), the GPU tests of SetPalette,
# then the CUDA frame at 1, 2, 4 and 0 palette threads.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
echo "== tsan" >> "$S"
LD_LIBRARY_PATH=.carry/tsan:${LD_LIBRARY_PATH:-} setarch -R .carry/tsan/hw_tsan --gtest_repeat=5 > /tmp/tsan.log 2>&1; echo "rc=$?" >> "$S"
grep -E "WARNING|PASSED|FAILED" /tmp/tsan.log | sort | uniq -c >> "$S"
echo "== tests" >> "$S"
for t in runtime_skinner_frames_test runtime_skinner_misuse_test runtime_host_work_test; do echo $t; done | xargs -P3 -I{} sh -c 'timeout 300 build/bin/{} > /tmp/{}.log 2>&1; echo "{}: rc=$? $(grep -E "^\[  (PASSED|FAILED) " /tmp/{}.log | tr "\n" " " | cut -c1-200)"; grep -E "^\[  FAILED  \]" /tmp/{}.log | head -5' >> "$S"
F="--benchmark_min_time=0.02 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter=instanced/(skin-only|set-skin-pipelined|set-skin-finish)"
V=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals
for threads in 0 1 2 4 0; do
  rm -f /tmp/tl.txt
  SKINTUNE_TIMING_LOG=/tmp/tl.txt timeout 60 build/bin/skintune_bench_frame --device cuda: --variant $V --palette-buffers 6 --submit-thread --palette-threads $threads $F > /tmp/f.txt 2>&1
  echo "-- cuda: buffers 6 --submit-thread --palette-threads $threads rc=$?" >> "$S"
  grep -E 'median|rror' /tmp/f.txt | sed 's/  */ /g' | sed 's/frame\/instanced\///' | cut -c1-200 >> "$S"
  grep "skinner:" /tmp/tl.txt | cut -d' ' -f2- >> "$S"
done
cat "$S"
