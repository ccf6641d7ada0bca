#!/usr/bin/env bash
# Session 31, call J: the palette crew with 4 lanes (7e88aa7) against 6 and 8
# (SKINTUNE_PALETTE_LANES, an experiment switch of this build only; runs of 512 matrices above 4
# lanes): the bare packing, then the frame with SKINTUNE_TIMING_LOG's SetPalette breakdown.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
for lanes in 4 6 8; do
  SKINTUNE_PALETTE_LANES=$lanes timeout 100 build/bin/skintune_bench_upload --benchmark_min_time=0.2 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true \
    '--benchmark_filter=^palette/pinned-wc/poses:2(/spinning:4|/runtime)?/real_time$' > /tmp/p.txt 2>&1
  echo "-- bare lanes=$lanes rc=$?" >> "$S"
  grep -E 'median|rror' /tmp/p.txt | sed 's/  */ /g' | cut -c1-160 >> "$S"
done
F="--benchmark_min_time=0.02 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter=instanced/(skin-only|set-skin-pipelined|set-skin-finish)"
for round in 1 2; do
for run in "cuda: 6 --submit-thread" "cuda: 3" "opencl:nvidia 6 --submit-thread"; do
  set -- $run; dev=$1; buffers=$2; extra=${3:-}
  case $dev in
    cuda:) V=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
    opencl:nvidia) V=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals ;;
  esac
  for lanes in 4 8; do
    [ $round = 2 ] && [ $dev = opencl:nvidia ] && continue
    rm -f /tmp/tl.txt
    SKINTUNE_PALETTE_LANES=$lanes SKINTUNE_TIMING_LOG=/tmp/tl.txt timeout 60 build/bin/skintune_bench_frame --device $dev --variant $V --palette-buffers $buffers $extra $F > /tmp/f.txt 2>&1
    echo "-- round $round $dev buffers $buffers $extra lanes=$lanes rc=$?" >> "$S"
    grep -E 'median|rror' /tmp/f.txt | sed 's/  */ /g' | sed 's/frame\/instanced\///' | cut -c1-200 >> "$S"
    grep "skinner:" /tmp/tl.txt | cut -d' ' -f2- >> "$S"
  done
done
done
cat "$S"
