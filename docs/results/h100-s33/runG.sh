#!/usr/bin/env bash
# session 33 call G: the injected GL hang under load with the test's new expectation, and alone
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
for t in runtime_cuda_test runtime_gl_runner_test runtime_opencl_runner_test; do
  SKINTUNE_TEST_OPENCL_DEVICE=NVIDIA timeout 200 build/bin/$t > /tmp/$t.log 2>&1 &
done
sleep 2
timeout 150 build/bin/tuner_tune_cli_test --gtest_filter='*InjectedHang*' --gtest_repeat=3 > /tmp/hang.log 2>&1
echo "InjectedHang x3 under load: rc=$?" >> "$S"; grep -E "^\[ *(OK|FAILED) |\[ hang" /tmp/hang.log >> "$S"
wait
for t in runtime_cuda_test runtime_gl_runner_test runtime_opencl_runner_test; do
  echo "$t (beside): $(grep -E "^\[  (PASSED|FAILED) " /tmp/$t.log | tr "\n" " " | cut -c1-120)" >> "$S"
done
timeout 60 build/bin/tuner_tune_cli_test --gtest_filter='*InjectedHang*' > /tmp/hang1.log 2>&1
echo "InjectedHang alone: rc=$?" >> "$S"; grep -E "^\[ *(OK|FAILED) |\[ hang" /tmp/hang1.log >> "$S"
cat "$S"
