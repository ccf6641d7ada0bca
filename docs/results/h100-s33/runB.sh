#!/usr/bin/env bash
# session 33 call B: tools_paper_cli_test to its end on the GPU machine, then the injected hang alone
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
start=$(date +%s)
timeout 330 build/bin/tools_paper_cli_test > /tmp/paper.log 2>&1
echo "tools_paper_cli_test rc=$? in $(( $(date +%s) - start )) s" >> "$S"
grep -E "^\[ *(RUN|OK|PASSED|FAILED|SKIPPED) " /tmp/paper.log | cut -c1-160 >> "$S"
start=$(date +%s)
timeout 90 build/bin/tuner_tune_cli_test --gtest_filter='*InjectedHang*' > /tmp/hang.log 2>&1
echo "tuner_tune_cli_test InjectedHang* rc=$? in $(( $(date +%s) - start )) s" >> "$S"
grep -E "^\[ *(OK|PASSED|FAILED|SKIPPED) |Failure|Expected|Which is" /tmp/hang.log | cut -c1-200 | head -30 >> "$S"
tail -c 20000 /tmp/paper.log > "$OUT/paper-tail.log"
timeout 60 build/bin/skintune_bench_opencl_calls --platform NVIDIA --benchmark_min_time=0.01 --benchmark_repetitions=3 \
  --benchmark_report_aggregates_only=true --benchmark_filter='frame/(kernel-only|copy-buffer/queues:1|write-pageable/queues:1)|upload/(copy-buffer|write-pageable)/queues:1' > /tmp/calls.txt 2>&1
echo "== opencl_calls rc=$?" >> "$S"; grep -E "median|ERROR" /tmp/calls.txt | awk '{print $1, $2, $3}' >> "$S"
OV=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals
export SKINTUNE_TIMING_LOG=-
for r in 1 2 3; do
  timeout 30 build/bin/skintune_bench_frame --device opencl:nvidia --variant $OV --benchmark_min_time=0.01 --benchmark_repetitions=3 \
    --benchmark_report_aggregates_only=true --benchmark_filter='instanced/(skin-only|set-skin-pipelined)' --submit-thread --palette-buffers 6 > /tmp/f.txt 2>&1
  echo "== ocl-thread6-log-$r rc=$?" >> "$S"; grep -E "median|skinner:|throughput" /tmp/f.txt | sed 's/  */ /g' | cut -c1-200 >> "$S"
done
cat "$S"
