#!/bin/bash
# Final: every device and language at 1600k B=1..4 with the GL warm-up fix (issue 4 figures).
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export LD_LIBRARY_PATH=$PWD/.carry/lib:$LD_LIBRARY_PATH SKINTUNE_CACHE_DIR=/tmp/stc
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
B=.carry/bin
nvidia-smi --query-gpu=timestamp,clocks.sm --format=csv,noheader -lms 250 > $OUT/clocks.txt &
S=$!
date +%T
timeout 500 $B/skintune tune --config .carry/gpu-tune-b1-4.json --out $OUT/tune --quiet 2>&1 | tail -30
date +%T
kill $S
awk -F', ' '{print $2}' $OUT/clocks.txt | sort | uniq -c
rm -f $OUT/tune/cache.jsonl $OUT/tune/report.t4.json
