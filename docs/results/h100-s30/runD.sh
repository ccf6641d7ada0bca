#!/usr/bin/env bash
# Session 30, call D: the frame model with the driver calls on a thread of their own (calls:thread,
# graph:thread) against the caller making them, two rounds.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
for round in 1 2; do
echo "== round $round" >> "$S"
timeout 200 build/bin/skintune_bench_upload --benchmark_filter='model/(skin-only|pipelined|unpacked)/(calls|calls:thread|graph:alternating|graph:thread)/|palette/pinned-wc/poses:2' --benchmark_min_time=0.2 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true > "$OUT/upload-$round.txt" 2>&1
echo "rc=$?" >> "$S"; grep -E 'median|rror' "$OUT/upload-$round.txt" | sed 's/  */ /g' >> "$S"
done
