#!/usr/bin/env bash
# session 32 call A: OpenCL's launch cost taken apart, and two runtime switches (experiment build)
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
timeout 150 build/bin/skintune_bench_opencl_calls --platform NVIDIA --benchmark_min_time=0.05 > "$OUT/calls.txt" 2>&1; echo "calls rc=$?" >> "$S"
grep -E "manual_time|NVIDIA" "$OUT/calls.txt" | awk '{print $1, $2, $3}' >> "$S"
V=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals
F='instanced/(skin-only|set-skin-pipelined|set-skin-finish)'
run() {  # name env... -- args
  local name=$1; shift
  env "$@" timeout 60 build/bin/skintune_bench_frame --device opencl:nvidia --variant $V --benchmark_min_time=0.02 \
    --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter="$F" $EXTRA > "$OUT/frame-$name.txt" 2>&1
  echo "== $name rc=$? ($EXTRA)" >> "$S"; grep -E "median|throughput|minus" "$OUT/frame-$name.txt" | awk '{print $1, $2, $3}' >> "$S"
}
for round in 1 2; do
  EXTRA="--submit-thread --palette-buffers 6"
  run base$round X=1; run plain$round SKINTUNE_EXP_CL_PLAIN=1; run noevent$round SKINTUNE_EXP_CL_NOEVENT=1
  run both$round SKINTUNE_EXP_CL_PLAIN=1 SKINTUNE_EXP_CL_NOEVENT=1
done
EXTRA=""
run default-base X=1; run default-both SKINTUNE_EXP_CL_PLAIN=1 SKINTUNE_EXP_CL_NOEVENT=1
cat "$S"
