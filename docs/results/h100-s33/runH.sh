#!/usr/bin/env bash
# session 33 call H: the CUDA and Vulkan binaries after stage "lost" (9eaeeac)
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
for t in runtime_cuda_test runtime_skinner_cuda_test runtime_vulkan_runner_test runtime_skinner_vulkan_test tuner_backend_test; do
  timeout 200 build/bin/$t > /tmp/$t.log 2>&1
  echo "$t: rc=$? $(grep -E "^\[  (PASSED|FAILED|SKIPPED) " /tmp/$t.log | tr "\n" " " | cut -c1-200)" >> "$S"
  grep -E "^\[  FAILED  \]" /tmp/$t.log | head -5 >> "$S"
done
cat "$S"
