#!/usr/bin/env bash
# session 33 call D: 64 GL Skinners (64 dispatches a frame) with and without the barrier after each
# Skin (experiment switch SKINTUNE_EXP_GL_BARRIER, never committed), CUDA and OpenCL beside
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
GV=glsl-compute.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals
CV=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals
OV=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals
run() {  # name bits device variant
  local name=$1 bits=$2 dev=$3 v=$4
  if [ "$bits" = all ]; then unset SKINTUNE_EXP_GL_BARRIER; else export SKINTUNE_EXP_GL_BARRIER=$bits; fi
  timeout 60 build/bin/skintune_bench_frame --device $dev --variant $v --benchmark_min_time=0.01 --frames 20 \
    --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter='(instanced|skinners)/skin-only' > /tmp/f.txt 2>&1
  echo "== $name rc=$? (bits $bits)" >> "$S"
  grep -E "median|throughput|rror" /tmp/f.txt | sed 's/  */ /g' | cut -c1-110 >> "$S"
  unset SKINTUNE_EXP_GL_BARRIER
}
run cuda all cuda: $CV
run opencl all opencl:nvidia $OV
for r in 1 2; do for b in all 0; do run gl-$b-$r $b gl: $GV; done; done
cat "$S"
