#!/usr/bin/env bash
# session 33 call A: does NVIDIA OpenCL's upload overlap the kernel before it (the frame model's
# orders), the waited-for frame without a palette (instanced/skin-finish) in every API, and
# OpenCL's pipelined spread across processes with the SetPalette split (SKINTUNE_TIMING_LOG=-)
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
for r in 1 2 3; do
  timeout 100 build/bin/skintune_bench_opencl_calls --platform NVIDIA --benchmark_min_time=0.05 --benchmark_repetitions=3 \
    --benchmark_report_aggregates_only=true --benchmark_filter='frame|upload/write-mapped/queues:1' > /tmp/calls$r.txt 2>&1
  echo "== opencl_calls process $r rc=$?" >> "$S"; grep -E "median|ERROR" /tmp/calls$r.txt | awk '{print $1, $2, $3, $4, $5}' >> "$S"
done
OV=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals
CV=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals
GV=glsl-compute.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals
run() {  # name device variant filter reps args...
  local name=$1 dev=$2 v=$3 f=$4 reps=$5; shift 5
  timeout 90 build/bin/skintune_bench_frame --device $dev --variant $v --benchmark_min_time=0.02 \
    --benchmark_repetitions=$reps --benchmark_report_aggregates_only=true --benchmark_filter="$f" "$@" > /tmp/f.txt 2>&1
  echo "== $name rc=$? ($dev $*)" >> "$S"
  grep -E "median|skinner:|throughput|us per frame|rror" /tmp/f.txt | sed 's/  */ /g' | cut -c1-200 >> "$S"
}
FIN='instanced/(skin-only|set-skin-pipelined|set-skin-finish|skin-finish)'
run cuda-default cuda: $CV "$FIN" 3
run ocl-default opencl:nvidia $OV "$FIN" 3
run gl-default gl: $GV "$FIN" 3
run cuda-thread6 cuda: $CV "$FIN" 3 --submit-thread --palette-buffers 6
PIPE='instanced/(skin-only|set-skin-pipelined)'
export SKINTUNE_TIMING_LOG=-
for r in 1 2 3 4; do
  run ocl-thread6-log-$r opencl:nvidia $OV "$PIPE" 5 --submit-thread --palette-buffers 6
done
for r in 1 2; do
  run ocl-default-log-$r opencl:nvidia $OV "$PIPE" 5
done
cat "$S"
