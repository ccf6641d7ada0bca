#!/usr/bin/env bash
# Session 31, call B: how long the palette pool's workers poll after a packing (20 us, the
# runtime's, against longer) in the frame model and in the real frame
# (SKINTUNE_PALETTE_SPIN_US, an experiment switch of this build only).
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
echo "== model" >> "$S"
timeout 200 build/bin/skintune_bench_upload --benchmark_min_time=0.2 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true \
  '--benchmark_filter=^(model/(pipelined|finish)(-pool)?/calls(:thread)?(/spin:[0-9]+)?|palette/pinned-wc/poses:2(/spinning:4)?)/real_time$' > /tmp/model.txt 2>&1
echo "rc=$?" >> "$S"
grep -E 'median|rror' /tmp/model.txt | sed 's/  */ /g' | cut -c1-220 >> "$S"
F="--benchmark_min_time=0.02 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter=instanced/(skin-only|set-skin-pipelined|set-skin-finish)"
for round in 1 2; do
for run in "cuda: 3" "cuda: 6 --submit-thread" "opencl:nvidia 3" "opencl:nvidia 6 --submit-thread" "gl: 3"; do
  set -- $run; dev=$1; buffers=$2; extra=${3:-}
  [ $round = 2 ] && [ $dev = gl: ] && continue
  case $dev in
    cuda:) V=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
    opencl:nvidia) V=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals ;;
    gl:) V=glsl-compute.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
  esac
  for spin in 20 500; do
    SKINTUNE_PALETTE_SPIN_US=$spin timeout 60 build/bin/skintune_bench_frame --device $dev --variant $V --palette-buffers $buffers $extra $F > /tmp/f.txt 2>&1
    echo "-- round $round $dev buffers $buffers $extra spin $spin rc=$?" >> "$S"
    grep -E 'median|rror' /tmp/f.txt | sed 's/  */ /g' | sed 's/frame\/instanced\///' | cut -c1-200 >> "$S"
  done
done
done
cat "$S"
