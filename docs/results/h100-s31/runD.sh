#!/usr/bin/env bash
# Session 31, call D: the fence queried once by the caller, then polled by the submit thread (6cc1fb7) on NVIDIA: the
# GPU tests of the ring and the frames, then the frame with the submit thread, the thread polling
# (new) against the caller waiting in the driver (SKINTUNE_CALLER_WAITS=1, an experiment switch of
# this build only), both with the 0.5 ms palette pool poll of b73148c.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
echo "== tests" >> "$S"
for t in runtime_skinner_frames_test runtime_skinner_misuse_test runtime_palette_ring_test runtime_submit_thread_test; do echo $t; done | xargs -P4 -I{} sh -c 'timeout 300 build/bin/{} > /tmp/{}.log 2>&1; echo "{}: rc=$? $(grep -E "^\[  (PASSED|FAILED) " /tmp/{}.log | tr "\n" " " | cut -c1-200)"; grep -E "^\[  FAILED  \]" /tmp/{}.log | head -5' >> "$S"
F="--benchmark_min_time=0.02 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter=instanced/(skin-only|set-skin-pipelined|set-skin-finish)"
for round in 1 2; do
for run in "cuda: 3" "cuda: 6" "opencl:nvidia 3" "opencl:nvidia 6"; do
  set -- $run; dev=$1; buffers=$2
  case $dev in
    cuda:) V=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
    opencl:nvidia) V=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals ;;
  esac
  for waits in 1 0; do
    if [ $waits = 1 ]; then export SKINTUNE_CALLER_WAITS=1; else unset SKINTUNE_CALLER_WAITS; fi
    timeout 60 build/bin/skintune_bench_frame --device $dev --variant $V --palette-buffers $buffers --submit-thread $F > /tmp/f.txt 2>&1
    echo "-- round $round $dev buffers $buffers submit-thread caller-waits=$waits rc=$?" >> "$S"
    grep -E 'median|rror' /tmp/f.txt | sed 's/  */ /g' | sed 's/frame\/instanced\///' | cut -c1-200 >> "$S"
  done
done
done
unset SKINTUNE_CALLER_WAITS
for run in "cuda: 3" "opencl:nvidia 3" "gl: 3"; do
  set -- $run; dev=$1; buffers=$2
  case $dev in
    cuda:) V=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
    opencl:nvidia) V=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals ;;
    gl:) V=glsl-compute.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
  esac
  timeout 60 build/bin/skintune_bench_frame --device $dev --variant $V --palette-buffers $buffers $F > /tmp/f.txt 2>&1
  echo "-- default options $dev buffers $buffers rc=$?" >> "$S"
  grep -E 'median|rror' /tmp/f.txt | sed 's/  */ /g' | sed 's/frame\/instanced\///' | cut -c1-200 >> "$S"
done
cat "$S"
