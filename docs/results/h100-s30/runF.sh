#!/usr/bin/env bash
# Session 30, call F: the packing on 1, 2 and 4 threads (helpers spinning between frames)
# graph:thread) against the caller making them, two rounds.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
for round in 1 2; do
echo "== round $round" >> "$S"
timeout 200 build/bin/skintune_bench_upload --benchmark_filter='palette/pinned-wc/poses:2|host/236544/pack-wc' --benchmark_min_time=0.2 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true > "$OUT/upload-$round.txt" 2>&1
echo "rc=$?" >> "$S"; grep -E 'median|rror' "$OUT/upload-$round.txt" | sed 's/  */ /g' >> "$S"
done
