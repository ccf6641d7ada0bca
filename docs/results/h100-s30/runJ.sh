#!/usr/bin/env bash
# Session 30, call J: the palette ring's depth (an experiment switch, SKINTUNE_EXP_PALETTE_SLOTS) in the
# pipelined frame, with the pooled packing: CUDA, CUDA with the submit thread, NVIDIA OpenCL.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
F="--benchmark_min_time=0.02 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter=instanced/(skin-only|set-skin-pipelined)"
for round in 1 2; do
for slots in 3 4 6; do
  for d in cuda:: cuda::--submit-thread opencl:nvidia:; do
    dev=${d%:*}; extra=${d##*:}
    V=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals
    [ "$dev" = opencl:nvidia ] && V=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals
    SKINTUNE_EXP_PALETTE_SLOTS=$slots timeout 60 build/bin/skintune_bench_frame --device $dev --variant $V $extra $F > /tmp/f.txt 2>&1
    echo "-- round $round slots $slots $dev $extra rc=$?" >> "$S"
    grep -E 'median|rror' /tmp/f.txt | sed 's/  */ /g' | sed 's/frame\/instanced\///' | cut -c1-200 >> "$S"
  done
done
done
