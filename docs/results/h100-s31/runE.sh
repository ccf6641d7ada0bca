#!/usr/bin/env bash
# Session 31, call E: where SetPalette's host time goes in the real frame (SKINTUNE_TIMING_LOG's
# Skinner line, 61f9272: buffer wait, packing, upload hand-over), beside the frame model's
# pipelined rows on the same machine.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
echo "== model" >> "$S"
timeout 200 build/bin/skintune_bench_upload --benchmark_min_time=0.2 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true \
  '--benchmark_filter=^(model/(skin-only|pipelined|pipelined-pool)/(calls|calls:thread)(/spin:500)?|palette/pinned-wc/poses:2(/spinning:4|/chunks:4/pool:4)?)/real_time$' > /tmp/model.txt 2>&1
echo "rc=$?" >> "$S"
grep -E 'median|rror' /tmp/model.txt | sed 's/  */ /g' | cut -c1-220 >> "$S"
F="--benchmark_min_time=0.02 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter=instanced/(skin-only|set-skin-pipelined|set-skin-finish)"
for round in 1 2; do
for run in "cuda: 3" "cuda: 6 --submit-thread" "opencl:nvidia 3" "opencl:nvidia 6 --submit-thread"; do
  set -- $run; dev=$1; buffers=$2; extra=${3:-}
  case $dev in
    cuda:) V=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
    opencl:nvidia) V=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals ;;
  esac
  rm -f /tmp/tl.txt
  SKINTUNE_TIMING_LOG=/tmp/tl.txt timeout 60 build/bin/skintune_bench_frame --device $dev --variant $V --palette-buffers $buffers $extra $F > /tmp/f.txt 2>&1
  echo "-- round $round $dev buffers $buffers $extra rc=$?" >> "$S"
  grep -E 'median|rror' /tmp/f.txt | sed 's/  */ /g' | sed 's/frame\/instanced\///' | cut -c1-200 >> "$S"
  grep "skinner:" /tmp/tl.txt | cut -d' ' -f2- >> "$S"
done
done
cat "$S"
