#!/usr/bin/env bash
# Session 30, call B: the upload bench's frame model with host-time counters; GL read-back again.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
for round in 1 2; do
echo "== upload model, round $round" >> "$S"
timeout 200 build/bin/skintune_bench_upload --benchmark_filter='model/' --benchmark_min_time=0.2 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true > "$OUT/upload-model-$round.txt" 2>&1
echo "rc=$?" >> "$S"; grep -E 'median|rror' "$OUT/upload-model-$round.txt" | sed 's/  */ /g' >> "$S"
done
V=glsl-compute.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals
start=$(date +%s)
timeout 150 build/bin/skintune_bench_frame --device gl: --variant $V --benchmark_min_time=0.3 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_filter=read-back > "$OUT/gl-read.txt" 2>&1
echo "-- gl read-back rc=$? $(( $(date +%s) - start )) s" >> "$S"; grep -E 'median|mean|cv|rror' "$OUT/gl-read.txt" | sed 's/  */ /g' >> "$S"
