#!/usr/bin/env bash
# For session 32's first call (not run in session 31: no device time left): every test binary of
# the build on the GPU machine, four at a time, each with its pass/fail line, the failures listed.
# Pack with `scripts/device-pack` (all of build/bin: check the 64 MiB carry; else SKINTUNE_PACK_BIN
# with the runtime_*, tuner_*, tools_* and reference_thread_pool tests), carry [".carry", ".gl"]:
#   eval "$(scripts/device-unpack)"; for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig;
#   export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json; OUT=$OUT .carry/runN.sh
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
ls build/bin | grep -E '_test$' | xargs -P4 -I{} sh -c 'timeout 500 build/bin/{} > /tmp/{}.log 2>&1; echo "{}: rc=$? $(grep -E "^\[  (PASSED|FAILED|SKIPPED) " /tmp/{}.log | tr "\n" " " | cut -c1-200)"; grep -E "^\[  FAILED  \]" /tmp/{}.log | head -5' | sort >> "$S"
cat "$S"
