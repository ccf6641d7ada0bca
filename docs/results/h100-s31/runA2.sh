#!/usr/bin/env bash
cd "$(dirname "$0")/.."; OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt; nvidia-smi --query-gpu=name --format=csv,noheader >> $S
echo "== model" >> "$S"
timeout 200 build/bin/skintune_bench_upload --benchmark_min_time=0.2 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true \
  '--benchmark_filter=^(model/(skin-only|unpacked|pipelined|pipelined-pool|finish|finish-unpacked|finish-pool)/(calls|calls:same-stream|fetch)|palette/pinned-wc/poses:2|htod/236544/pinned-wc|sync/empty)/real_time$' > /tmp/model.txt 2>&1
echo "rc=$?" >> "$S"
grep -E 'median|rror' /tmp/model.txt | sed 's/  */ /g' | cut -c1-220 >> "$S"
cat $S
