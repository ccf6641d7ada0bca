#!/bin/bash
# One device call: tune every GPU backend, then PoCL, merge, FPS of the example per backend, CL-GL interop.
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export LD_LIBRARY_PATH=$PWD/.carry/lib:$LD_LIBRARY_PATH SKINTUNE_CACHE_DIR=/tmp/stc
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
B=.carry/bin
nvidia-smi -L
$B/skintune devices > $OUT/devices.txt 2>&1
date
timeout 250 $B/skintune tune --config .carry/gpu-runtime.json --device NVIDIA --lang opencl cuda glsl-compute --out $OUT/gpu --quiet 2>&1 | tail -30
date
timeout 120 $B/skintune tune --config .carry/gpu-runtime.json --device "Portable Computing" --out $OUT/pocl --quiet 2>&1 | tail -12
date
$B/skintune db merge $OUT/gpu/winners-db.json $OUT/pocl/winners-db.json -o $OUT/db.json || cp $OUT/gpu/winners-db.json $OUT/db.json
rm -f $OUT/gpu/cache.jsonl $OUT/pocl/cache.jsonl $OUT/gpu/report.t4.json $OUT/pocl/report.t4.json $OUT/pocl/report.json
for dev in "cuda:" "opencl:NVIDIA" "gl:" "Portable Computing"; do
  for m in tests/data/CesiumMan.gltf 1600k-b4; do
    for rb in "" --readback; do
      echo "== $dev $m $rb"; timeout 30 $B/skin_animation $m --device "$dev" --db $OUT/db.json --seconds 2 $rb 2>&1 | grep -v warning
    done
  done
done > $OUT/fps.txt 2>&1
date
timeout 60 $B/runtime_skinner_gl_test --gtest_filter='OpenClGlInterop*:GlDevice*:GlSkinner*' > $OUT/interop.txt 2>&1
tail -5 $OUT/interop.txt; grep -c "^== " $OUT/fps.txt; grep "frames/s" $OUT/fps.txt
