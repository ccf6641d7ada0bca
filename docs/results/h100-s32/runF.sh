#!/usr/bin/env bash
# session 32 call F: OpenCL uploads' device time (one queue or split over 2 or 4), and the frame with the
# upload split (experiment switch SKINTUNE_EXP_CL_SPLIT, never committed)
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
timeout 90 build/bin/skintune_bench_opencl_calls --platform NVIDIA --benchmark_min_time=0.05 --benchmark_filter='upload|frame' > "$OUT/calls.txt" 2>&1
echo "calls rc=$?" >> "$S"; grep manual_time "$OUT/calls.txt" | awk '{print $1, $2, $3}' >> "$S"
OV=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals
F='instanced/(skin-only|set-skin-pipelined|set-skin-finish)'
run() {  # name env args...
  local name=$1 e=$2; shift 2
  env $e timeout 40 build/bin/skintune_bench_frame --device opencl:nvidia --variant $OV --benchmark_min_time=0.02 \
    --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter="$F" "$@" > /tmp/f.txt 2>&1
  echo "== $name rc=$? ($e $*)" >> "$S"; grep -E "median" /tmp/f.txt | sed 's/  */ /g' | cut -c1-190 >> "$S"
}
for r in 1 2; do
  for sp in 1 2 4; do run thread6-split$sp-$r SKINTUNE_EXP_CL_SPLIT=$sp --submit-thread --palette-buffers 6; done
done
for sp in 1 2; do run default-split$sp SKINTUNE_EXP_CL_SPLIT=$sp; done
for t in runtime_opencl_runner_test runtime_skinner_opencl_test runtime_palette_ring_test runtime_skinner_misuse_test; do
  SKINTUNE_EXP_CL_SPLIT=2 SKINTUNE_TEST_OPENCL_DEVICE=NVIDIA timeout 60 build/bin/$t > /tmp/$t.log 2>&1
  echo "$t (split 2): rc=$? $(grep -E "^\[  (PASSED|FAILED) " /tmp/$t.log | tr "\n" " " | cut -c1-120)" >> "$S"
done
SKINTUNE_EXP_CL_SPLIT=2 timeout 60 build/bin/runtime_skinner_frames_test --gtest_filter='*opencl*' > /tmp/fr.log 2>&1
echo "runtime_skinner_frames_test opencl (split 2): rc=$? $(grep -E "^\[  (PASSED|FAILED) " /tmp/fr.log | tr "\n" " " | cut -c1-120)" >> "$S"
cat "$S"
