#!/usr/bin/env bash
# Session 30, call C: the frame model's packing: with and without the upload beside it, into
# write-combined or ordinary page-locked staging; the packing alone for reference.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
lscpu | grep -E 'Model name|^CPU\(s\)|Thread|L2|L3' >> "$S"
for round in 1 2; do
echo "== round $round" >> "$S"
timeout 200 build/bin/skintune_bench_upload --benchmark_filter='model/[a-z-]+/(calls|graph:alternating)/|palette/pinned(-wc)?/poses:2|host/236544/' --benchmark_min_time=0.2 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true > "$OUT/upload-$round.txt" 2>&1
echo "rc=$?" >> "$S"; grep -E 'median|rror' "$OUT/upload-$round.txt" | sed 's/  */ /g' >> "$S"
done
