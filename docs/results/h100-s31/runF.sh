#!/usr/bin/env bash
# Session 31, call F: the palette packed by lanes (each thread the same run every call, 4a-style
# commit "PackPaletteOnPool: each thread packs the same run") against runs taken as the pool hands
# them out (SKINTUNE_PALETTE_DYNAMIC=1, an experiment switch of this build only); the frame, with
# SKINTUNE_TIMING_LOG's SetPalette breakdown.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
F="--benchmark_min_time=0.02 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter=instanced/(skin-only|set-skin-pipelined|set-skin-finish)"
for round in 1 2; do
for run in "cuda: 3" "cuda: 6 --submit-thread" "opencl:nvidia 3" "opencl:nvidia 6 --submit-thread" "gl: 3"; do
  set -- $run; dev=$1; buffers=$2; extra=${3:-}
  case $dev in
    cuda:) V=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
    opencl:nvidia) V=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals ;;
    gl:) V=glsl-compute.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
  esac
  for dynamic in 1 0; do
    if [ $dynamic = 1 ]; then export SKINTUNE_PALETTE_DYNAMIC=1; else unset SKINTUNE_PALETTE_DYNAMIC; fi
    rm -f /tmp/tl.txt
    SKINTUNE_TIMING_LOG=/tmp/tl.txt timeout 60 build/bin/skintune_bench_frame --device $dev --variant $V --palette-buffers $buffers $extra $F > /tmp/f.txt 2>&1
    echo "-- round $round $dev buffers $buffers $extra dynamic=$dynamic rc=$?" >> "$S"
    grep -E 'median|rror' /tmp/f.txt | sed 's/  */ /g' | sed 's/frame\/instanced\///' | cut -c1-200 >> "$S"
    grep "skinner:" /tmp/tl.txt | cut -d' ' -f2- >> "$S"
  done
done
done
unset SKINTUNE_PALETTE_DYNAMIC
cat "$S"
