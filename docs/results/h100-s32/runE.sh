#!/usr/bin/env bash
# session 32 call E (E2 with kcopy and direct): GL, a palette upload beside the kernel: one context, or a second shared one on its own thread
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
for m in 48 24; do timeout 100 build/bin/skintune_bench_glupload --mib $m --frames 2000 --repeat 3 >> "$S" 2>&1; echo "rc=$?" >> "$S"; done
cat "$S"
