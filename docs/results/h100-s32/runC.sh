#!/usr/bin/env bash
# session 32 call C: OpenCL's pipelined frame with the submit thread, its spread: palette threads and the SetPalette split
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
OV=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals
F='instanced/(skin-only|set-skin-pipelined)'
run() {  # name args...
  local name=$1; shift
  SKINTUNE_TIMING_LOG=1 timeout 60 build/bin/skintune_bench_frame --device opencl:nvidia --variant $OV --benchmark_min_time=0.02 \
    --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter="$F" "$@" > /tmp/f.txt 2>&1
  echo "== $name rc=$? ($*)" | tee -a "$OUT/frames.txt" >> "$S"; cat /tmp/f.txt >> "$OUT/frames.txt"
  grep -E "median|skinner:" /tmp/f.txt | sed 's/  */ /g' | cut -c1-200 >> "$S"
}
for r in 1 2; do
  for t in 0 4 2; do run t$t-b6-$r --submit-thread --palette-buffers 6 --palette-threads $t; done
  run t0-b12-$r --submit-thread --palette-buffers 12
done
cat "$S"
