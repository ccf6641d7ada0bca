#!/usr/bin/env bash
# Session 31, call G: the packing of 64 x 77 mat3x4 into write-combined staging on the host's
# threads, taken apart: one thread, spinning helpers with fixed shares or shares handed out by a
# counter, a ThreadPool with fixed shares or chunks as claimed, and the runtime's PackPaletteOnPool.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
for round in 1 2; do
timeout 200 build/bin/skintune_bench_upload --benchmark_min_time=0.2 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true \
  '--benchmark_filter=^palette/pinned-wc/poses:2(/spinning:[24](/claims)?|/pool-fixed:[24]|/chunks:[24]/pool:[24]|/runtime)?/real_time$' > /tmp/p.txt 2>&1
echo "-- round $round rc=$?" >> "$S"
grep -E 'median|rror' /tmp/p.txt | sed 's/  */ /g' | cut -c1-160 >> "$S"
done
cat "$S"
