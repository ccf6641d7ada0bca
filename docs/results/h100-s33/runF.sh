#!/usr/bin/env bash
# session 33 call F (after the device-lost change): TuneCli.InjectedHang under load (three GPU test binaries beside it), its log kept;
# skin_animation (options now parsed with CLI11) on every GPU API
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt; L=$OUT/logs.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
for v in "cuda:" "opencl:NVIDIA" "gl:" "vulkan:"; do
  timeout 60 build/bin/skin_animation 25k-b4 --instances 64 --seconds 1 --device "$v" > /tmp/a.txt 2>&1
  echo "skin_animation 25k-b4 --instances 64 --device $v: rc=$?" >> "$S"; grep -E "device:|kernel:|first frame|frames/s|rror|skin_animation:" /tmp/a.txt >> "$S"
done
timeout 60 build/bin/skin_animation tests/data/CesiumMan.gltf tests/data/Fox.gltf --instances 8 --seconds 1 --device cuda: > /tmp/a.txt 2>&1
echo "skin_animation batch on cuda: rc=$?" >> "$S"; grep -E "kernel:|first frame|frames/s|rror" /tmp/a.txt >> "$S"
timeout 10 build/bin/skin_animation 25k-b4 --instances abc > /tmp/a.txt 2>&1; echo "bad --instances: rc=$? $(cat /tmp/a.txt)" >> "$S"
# the load: three GPU binaries beside the hang test, as session 32's call 0 ran them
for t in runtime_cuda_test runtime_gl_runner_test runtime_opencl_runner_test; do
  SKINTUNE_TEST_OPENCL_DEVICE=NVIDIA timeout 280 build/bin/$t > /tmp/$t.log 2>&1 &
done
sleep 2
start=$(date +%s)
timeout 250 build/bin/tuner_tune_cli_test --gtest_filter='*InjectedHang*' --gtest_repeat=4 > /tmp/hang.log 2>&1
echo "InjectedHang x4 under load: rc=$? in $(( $(date +%s) - start )) s" >> "$S"
grep -E "^\[ *(OK|FAILED) " /tmp/hang.log >> "$S"
wait
for t in runtime_cuda_test runtime_gl_runner_test runtime_opencl_runner_test; do
  echo "$t (beside): $(grep -E "^\[  (PASSED|FAILED) " /tmp/$t.log | tr "\n" " " | cut -c1-120)" >> "$S"
done
for t in runtime_skinner_gl_test tuner_backend_test; do
  timeout 200 build/bin/$t > /tmp/$t.log 2>&1
  echo "$t (alone): rc=$? $(grep -E "^\[  (PASSED|FAILED|SKIPPED) " /tmp/$t.log | tr "\n" " " | cut -c1-200)" >> "$S"
done
timeout 100 build/bin/runtime_skinner_frames_test --gtest_filter='*/gl_*' > /tmp/fr.log 2>&1
echo "runtime_skinner_frames_test GL: rc=$? $(grep -E "^\[  (PASSED|FAILED) " /tmp/fr.log | tr "\n" " " | cut -c1-120)" >> "$S"
grep -E "\[ hang|Which is" /tmp/hang.log | head -20 >> "$S"
{ echo "==== hang.log (failures)"; grep -B2 -A30 "Failure" /tmp/hang.log | head -150; } > "$L"
cat "$S"
