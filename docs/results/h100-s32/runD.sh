#!/usr/bin/env bash
# session 32 call D: OpenCL uploads on the frames' (now plain) queue, an experiment switch (SKINTUNE_EXP_CL_SAMEQ, never committed)
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
OV=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals
F='instanced/(skin-only|set-skin-pipelined|set-skin-finish)'
run() {  # name env -- args...
  local name=$1 e=$2; shift 2
  env $e timeout 60 build/bin/skintune_bench_frame --device opencl:nvidia --variant $OV --benchmark_min_time=0.02 \
    --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter="$F" "$@" > /tmp/f.txt 2>&1
  echo "== $name rc=$? ($e $*)" | tee -a "$OUT/frames.txt" >> "$S"; cat /tmp/f.txt >> "$OUT/frames.txt"
  grep -E "median" /tmp/f.txt | sed 's/  */ /g' | cut -c1-200 >> "$S"
}
for r in 1 2; do
  run default-base-$r X=1; run default-sameq-$r SKINTUNE_EXP_CL_SAMEQ=1
  run thread6-base-$r X=1 --submit-thread --palette-buffers 6; run thread6-sameq-$r SKINTUNE_EXP_CL_SAMEQ=1 --submit-thread --palette-buffers 6
done
cat "$S"
