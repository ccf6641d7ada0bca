#!/usr/bin/env bash
# session 32 call B: main with the OpenCL frames' queue without profiling: its GPU tests on NVIDIA, then the frame
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
for t in runtime_opencl_runner_test runtime_skinner_opencl_test runtime_skinner_frames_test runtime_skinner_misuse_test runtime_palette_ring_test tuner_backend_test; do
  SKINTUNE_TEST_OPENCL_DEVICE=NVIDIA timeout 200 build/bin/$t > /tmp/$t.log 2>&1
  echo "$t: rc=$? $(grep -E "^\[  (PASSED|FAILED|SKIPPED) " /tmp/$t.log | tr "\n" " " | cut -c1-160)" >> "$S"
  grep -E "^\[  FAILED  \]" /tmp/$t.log | head -5 >> "$S"
done
cp /tmp/runtime_opencl_runner_test.log "$OUT/" 2>/dev/null
F='instanced/(skin-only|set-skin-pipelined|set-skin-finish)'
run() {  # name device variant args...
  local name=$1 dev=$2 v=$3; shift 3
  timeout 60 build/bin/skintune_bench_frame --device $dev --variant $v --benchmark_min_time=0.02 \
    --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter="$F" "$@" > "$OUT/frame-$name.txt" 2>&1
  echo "== $name rc=$? ($dev $*)" >> "$S"; grep -E "median" "$OUT/frame-$name.txt" | awk '{print $1, $2, $3}' >> "$S"
}
OV=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals
CV=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals
GV=glsl-compute.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals
for r in 1 2 3; do run ocl-thread6-$r opencl:nvidia $OV --submit-thread --palette-buffers 6; done
for r in 1 2; do run ocl-default-$r opencl:nvidia $OV; done
run cuda-thread6 cuda: $CV --submit-thread --palette-buffers 6
run cuda-default cuda: $CV
run gl-default gl: $GV
cat "$S"
