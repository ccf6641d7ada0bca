#!/usr/bin/env bash
# Session 30, call A: every GPU test binary of main (GL Finish by fence, ChunkCovering);
# the upload bench's frame model (calls vs graphs); the frame bench on CUDA, OpenCL, GL.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
echo "== tests" >> "$S"
ls build/bin | grep -E '^(runtime_.*|tuner_backend)_test$' | xargs -P6 -I{} sh -c 'timeout 300 build/bin/{} > '"$OUT"'/{}.log 2>&1; echo "{}: rc=$? $(grep -E "PASSED|FAILED|SKIPPED \]" '"$OUT"'/{}.log | tr "\n" " " | cut -c1-300)"' >> "$S"
echo "== upload model" >> "$S"
timeout 150 build/bin/skintune_bench_upload --benchmark_filter='model/' --benchmark_min_time=0.2 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true > "$OUT/upload-model.txt" 2>&1
echo "rc=$?" >> "$S"; grep -E 'median|rror' "$OUT/upload-model.txt" | sed 's/  */ /g' >> "$S"
F="--benchmark_min_time=0.1 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true"
for d in cuda::cuda opencl:nvidia:opencl gl::glsl-compute; do
  lang=${d##*:}; dev=${d%:*}
  V=$lang.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals
  [ $lang = opencl ] && V=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals
  start=$(date +%s)
  timeout 120 build/bin/skintune_bench_frame --device $dev --variant $V $F --benchmark_filter='instanced/(skin-only|set-skin-pipelined|set-skin-finish)|read-back' > "$OUT/frame-$lang.txt" 2>&1
  echo "-- $dev ($lang) rc=$? $(( $(date +%s) - start )) s" >> "$S"; grep -E 'median|rror' "$OUT/frame-$lang.txt" | sed 's/  */ /g' >> "$S"
done
