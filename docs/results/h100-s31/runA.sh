#!/usr/bin/env bash
# Session 31, call A: session 30's call K (GPU tests of SkinnerOptions::palette_buffers; the frame
# with --palette-buffers 3 / 6, with and without the submit thread), then the frame model's
# waited-for frames: the upload on its own stream (calls), on the kernel's (calls:same-stream), or
# fetched by a kernel over PCIe (fetch); the packing on one thread or the pool.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
nproc >> "$S"
echo "== model" >> "$S"
timeout 200 build/bin/skintune_bench_upload --benchmark_min_time=0.2 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true \
  '--benchmark_filter=^(model/(skin-only|unpacked|pipelined|pipelined-pool|finish|finish-unpacked|finish-pool)/(calls|calls:same-stream|fetch)|palette/pinned-wc/poses:2|htod/236544/pinned-wc|sync/empty)/real_time$' > /tmp/model.txt 2>&1
echo "rc=$?" >> "$S"
grep -E 'median|rror' /tmp/model.txt | sed 's/  */ /g' | cut -c1-220 >> "$S"
echo "== tests" >> "$S"
for t in runtime_skinner_frames_test runtime_skinner_misuse_test runtime_palette_ring_test runtime_host_work_test; do echo $t; done | xargs -P4 -I{} sh -c 'timeout 300 build/bin/{} > /tmp/{}.log 2>&1; echo "{}: rc=$? $(grep -E "^\[  (PASSED|FAILED) " /tmp/{}.log | tr "\n" " " | cut -c1-200)"; grep -E "^\[  FAILED  \]" /tmp/{}.log | head -5' >> "$S"
F="--benchmark_min_time=0.02 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter=instanced/(skin-only|set-skin-pipelined|set-skin-finish)"
for run in "cuda: 3" "cuda: 6" "cuda: 3 --submit-thread" "cuda: 6 --submit-thread" "opencl:nvidia 6 --submit-thread" "gl: 6"; do
  set -- $run; dev=$1; buffers=$2; extra=${3:-}
  case $dev in
    cuda:) V=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
    opencl:nvidia) V=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals ;;
    gl:) V=glsl-compute.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
  esac
  timeout 60 build/bin/skintune_bench_frame --device $dev --variant $V --palette-buffers $buffers $extra $F > /tmp/f.txt 2>&1
  echo "-- $dev buffers $buffers $extra rc=$?" >> "$S"
  grep -E 'median|rror' /tmp/f.txt | sed 's/  */ /g' | sed 's/frame\/instanced\///' | cut -c1-200 >> "$S"
done
cat "$S"
