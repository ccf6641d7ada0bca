#!/usr/bin/env bash
# session 33 call C: GL's frame with the barrier after each Skin narrowed (experiment switch
# SKINTUNE_EXP_GL_BARRIER=<hex bits>, never committed; unset = GL_ALL_BARRIER_BITS), then the GL
# test binaries with the candidate bits
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
GV=glsl-compute.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals
CV=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals
F='instanced/(skin-only|set-skin-pipelined|set-skin-finish|skin-finish)'
run() {  # name bits device variant
  local name=$1 bits=$2 dev=$3 v=$4
  if [ "$bits" = all ]; then unset SKINTUNE_EXP_GL_BARRIER; else export SKINTUNE_EXP_GL_BARRIER=$bits; fi
  timeout 60 build/bin/skintune_bench_frame --device $dev --variant $v --benchmark_min_time=0.02 \
    --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter="$F" > /tmp/f.txt 2>&1
  echo "== $name rc=$? (bits $bits)" >> "$S"
  grep -E "median|throughput|us per frame|rror" /tmp/f.txt | sed 's/  */ /g' | cut -c1-150 >> "$S"
  unset SKINTUNE_EXP_GL_BARRIER
}
run cuda all cuda: $CV
for r in 1 2; do
  for b in all 2AAD 2201 2000 0; do run gl-$b-$r $b gl: $GV; done
done
export SKINTUNE_EXP_GL_BARRIER=2AAD
for t in runtime_gl_runner_test runtime_skinner_gl_test; do
  timeout 150 build/bin/$t > /tmp/$t.log 2>&1
  echo "$t (bits 2AAD): rc=$? $(grep -E "^\[  (PASSED|FAILED|SKIPPED) " /tmp/$t.log | tr "\n" " " | cut -c1-160)" >> "$S"
  grep -E "^\[  FAILED  \]" /tmp/$t.log | head -5 >> "$S"
done
timeout 100 build/bin/runtime_skinner_frames_test --gtest_filter='*/gl_*' > /tmp/fr.log 2>&1
echo "runtime_skinner_frames_test GL (bits 2AAD): rc=$? $(grep -E "^\[  (PASSED|FAILED) " /tmp/fr.log | tr "\n" " " | cut -c1-120)" >> "$S"
cat "$S"
