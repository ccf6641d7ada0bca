#!/usr/bin/env bash
# Session 31, call H: the palette packed by the LaneCrew (baa9719) against the ThreadPool before it
# (SKINTUNE_PALETTE_THREADPOOL=1, an experiment switch of this build only): the bare packing rows,
# then the frame with SKINTUNE_TIMING_LOG's SetPalette breakdown, two rounds.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
for pool in 1 0; do
  if [ $pool = 1 ]; then export SKINTUNE_PALETTE_THREADPOOL=1; else unset SKINTUNE_PALETTE_THREADPOOL; fi
  timeout 100 build/bin/skintune_bench_upload --benchmark_min_time=0.2 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true \
    '--benchmark_filter=^palette/pinned-wc/poses:2(/spinning:4|/pool-fixed:4|/runtime)?/real_time$' > /tmp/p.txt 2>&1
  echo "-- bare threadpool=$pool rc=$?" >> "$S"
  grep -E 'median|rror' /tmp/p.txt | sed 's/  */ /g' | cut -c1-160 >> "$S"
done
F="--benchmark_min_time=0.02 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter=instanced/(skin-only|set-skin-pipelined|set-skin-finish)"
for round in 1 2; do
for run in "cuda: 3" "cuda: 6 --submit-thread" "opencl:nvidia 3" "opencl:nvidia 6 --submit-thread" "gl: 3"; do
  set -- $run; dev=$1; buffers=$2; extra=${3:-}
  case $dev in
    cuda:) V=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
    opencl:nvidia) V=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals ;;
    gl:) V=glsl-compute.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
  esac
  for pool in 1 0; do
    [ $round = 2 ] && [ $dev = gl: ] && continue
    if [ $pool = 1 ]; then export SKINTUNE_PALETTE_THREADPOOL=1; else unset SKINTUNE_PALETTE_THREADPOOL; fi
    rm -f /tmp/tl.txt
    SKINTUNE_TIMING_LOG=/tmp/tl.txt timeout 60 build/bin/skintune_bench_frame --device $dev --variant $V --palette-buffers $buffers $extra $F > /tmp/f.txt 2>&1
    echo "-- round $round $dev buffers $buffers $extra threadpool=$pool rc=$?" >> "$S"
    grep -E 'median|rror' /tmp/f.txt | sed 's/  */ /g' | sed 's/frame\/instanced\///' | cut -c1-200 >> "$S"
    grep "skinner:" /tmp/tl.txt | cut -d' ' -f2- >> "$S"
  done
done
done
unset SKINTUNE_PALETTE_THREADPOOL
cat "$S"
