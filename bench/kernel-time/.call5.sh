for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
eval "$(scripts/device-unpack)"
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
R=$OUT/r; mkdir -p $R; export OUT=$R
build/bin/skintune devices > $R/devices.txt 2>&1; grep -E "^\s+(opencl|cuda|gl|vulkan|cpu)" $R/devices.txt | head
timeout 150 build/bin/runtime_kernel_time_test > $R/kernel_time_test.txt 2>&1; tail -4 $R/kernel_time_test.txt
timeout 120 bench/kernel-time/run.sh ncu > $R/ncu.log 2>&1; tail -28 $R/ncu.log
TWIN_SIZES="100k-b4 400k-b4 1600k-b4 6400k-b4" timeout 90 bench/kernel-time/run.sh twins > $R/twins.log 2>&1; tail -6 $R/twins.log
timeout 240 bench/kernel-time/run.sh runs 3 > $R/runs.log 2>&1; tail -25 $R/runs.log
cd $R/.. && tar czf call5.tgz r && rm -rf r
