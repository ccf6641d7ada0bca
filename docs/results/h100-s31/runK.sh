#!/usr/bin/env bash
# Session 31, call K: main at c16331e (the crew on half the cores, 2 to 8 lanes; fence polled by the submit thread; 0.5 ms
# polls): the GPU tests that exercise SetPalette and the ring, then the frame on every API.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
echo "== tests" >> "$S"
for t in runtime_skinner_frames_test runtime_skinner_misuse_test runtime_palette_ring_test runtime_submit_thread_test runtime_host_work_test runtime_timing_log_test runtime_skinner_test runtime_skinner_batch_test; do [ -x build/bin/$t ] && echo $t; done | xargs -P4 -I{} sh -c 'timeout 300 build/bin/{} > /tmp/{}.log 2>&1; echo "{}: rc=$? $(grep -E "^\[  (PASSED|FAILED) " /tmp/{}.log | tr "\n" " " | cut -c1-200)"; grep -E "^\[  FAILED  \]" /tmp/{}.log | head -5' >> "$S"
F="--benchmark_min_time=0.02 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter=instanced/(skin-only|set-skin-pipelined|set-skin-finish)"
for run in "cuda: 6 --submit-thread" "cuda: 3" "opencl:nvidia 6 --submit-thread" "opencl:nvidia 3" "gl: 3" "cuda: 6 --submit-thread" "cuda: 3"; do
  set -- $run; dev=$1; buffers=$2; extra=${3:-}
  case $dev in
    cuda:) V=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
    opencl:nvidia) V=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals ;;
    gl:) V=glsl-compute.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
  esac
  rm -f /tmp/tl.txt
  SKINTUNE_TIMING_LOG=/tmp/tl.txt timeout 60 build/bin/skintune_bench_frame --device $dev --variant $V --palette-buffers $buffers $extra $F > /tmp/f.txt 2>&1
  echo "-- $dev buffers $buffers $extra rc=$?" >> "$S"
  grep -E 'median|rror' /tmp/f.txt | sed 's/  */ /g' | sed 's/frame\/instanced\///' | cut -c1-200 >> "$S"
  grep "skinner:" /tmp/tl.txt | cut -d' ' -f2- >> "$S"
done
cat "$S"
