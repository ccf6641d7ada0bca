#!/usr/bin/env bash
# The kernel-time and winner-stability checks on a GPU machine
# (docs/PERFORMANCE.md "Kernel time and frame time"), from the repository copy
# there after `eval "$(scripts/device-unpack)"`:
#
#   bench/kernel-time/run.sh ncu          five CUDA variants at 25k..6400k-b4: skintune's kernel time beside
#                                         Nsight Compute's gpu__time_duration (--cache-control all --clock-control none)
#   bench/kernel-time/run.sh runs N ARGS  N cold `skintune run ARGS` (every program cache emptied before each),
#                                         then compare.py on their reports (runs-summary.txt) and on
#                                         their timing logs (turns.txt: when each device's turn ran)
#   bench/kernel-time/run.sh twins        one variant in OpenCL, CUDA and Vulkan (and GLSL) at 100k..6400k-b4:
#                                         its kernel time, its context's launch start, the kernel beyond it and its frame time
#   bench/kernel-time/run.sh suite PART   the GPU suite's half PART (1 or 2): every test this machine can run
#                                         (suite-PART-summary.txt: the count, and every test failed or skipped)
#
# Writes under $OUT (default ./out); prints a short table last.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
out=${OUT:-$here/out}
bin="$here/build/bin"
mkdir -p "$out"
mode=${1:?usage: run.sh ncu|runs N ARGS|twins|suite PART}
shift
sizes=${SIZES:-"25k-b4 100k-b4 400k-b4 1600k-b4 6400k-b4"}
cuda_variants=(
  cuda.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg256.nonormals
  cuda.b4.padded.soa-split.float4.u8.unorm8.mat3x4.local.matrix.v1c.wg64.nonormals
  cuda.b4.padded.soa.float4.u8.f32.mat3x4.local.matrix.v1c.wg256.nonormals
  cuda.b4.padded.aos.float3.i32.f32.mat4.global.matrix.v1c.wg128.nonormals
  cuda.b4.padded.soa-split.float4.u16.unorm16.mat3x4.global.matrix.v1c.wg64.nonormals
)
case "$mode" in
  ncu)
    ncu=$(command -v ncu || ls /usr/local/cuda/bin/ncu 2>/dev/null || true)
    # The last variant also first: the process's first kernels are its warm-up
    # (compare.py shows that row and does not count it). Nsight Compute read the
    # variant that came first in its process 5% quicker than where it came last
    # (docs/PERFORMANCE.md "Nsight Compute").
    launches=10
    args=(--variant "${cuda_variants[-1]}")
    for v in "${cuda_variants[@]}"; do args+=(--variant "$v"); done
    for size in $sizes; do
      "$bin/skintune_bench_kernel_time" --device cuda: --dataset "$size" "${args[@]}" --json "$out/skintune-$size.jsonl" \
        > "$out/skintune-$size.txt" 2>&1 || cat "$out/skintune-$size.txt"
      [ -n "$ncu" ] || { echo "no ncu"; continue; }
      "$ncu" --cache-control all --clock-control none -k 'regex:^skin$' --metrics gpu__time_duration.sum --csv \
        --print-units base "$bin/skintune_bench_kernel_time" --device cuda: --dataset "$size" "${args[@]}" --launches "$launches" \
        > "$out/ncu-$size.csv" 2> "$out/ncu-$size.err" || tail -5 "$out/ncu-$size.err"
    done
    python3 "$here/bench/kernel-time/compare.py" ncu "$launches" "$out" $sizes | tee "$out/ncu-summary.txt"
    ;;
  runs)
    n=${1:?runs N}
    shift
    reports=()
    for i in $(seq 1 "$n"); do
      cache=$(mktemp -d)
      start=$(date +%s.%N)
      SKINTUNE_TIMING_LOG="$out/run$i.phases.log" \
      SKINTUNE_CACHE_DIR="$cache/skintune" POCL_CACHE_DIR="$cache/pocl" CUDA_CACHE_PATH="$cache/cuda" \
        __GL_SHADER_DISK_CACHE_PATH="$cache/gl" MESA_SHADER_CACHE_DIR="$cache/mesa" "$bin/skintune" run --out "$out/run$i" --quiet "$@" > "$out/run$i.txt" 2>&1 \
        || tail -5 "$out/run$i.txt"
      echo "run $i: $(python3 -c "import time,sys; print(round(time.time()-float(sys.argv[1]),1))" "$start") s" | tee -a "$out/runs-wall.txt"
      reports+=("$out/run$i/report.json")
      rm -rf "$cache"
    done
    python3 "$here/bench/kernel-time/compare.py" runs "${reports[@]}" | tee "$out/runs-summary.txt"
    python3 "$here/bench/kernel-time/compare.py" turns "$out"/run*.phases.log > "$out/turns.txt"
    ;;
  twins)
    for size in ${TWIN_SIZES:-100k-b4 400k-b4 1600k-b4 6400k-b4}; do
      for lang in opencl cuda vulkan glsl-compute; do
        case $lang in opencl) dev='opencl:NVIDIA';; cuda) dev='cuda:';; vulkan) dev='vulkan:';; glsl-compute) dev='gl:';; esac
        "$bin/skintune_bench_kernel_time" --device "$dev" --dataset "$size" --json "$out/twins-$lang-$size.jsonl" \
          --variant "$lang.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg256.nonormals" \
          > "$out/twins-$lang-$size.txt" 2>&1 || tail -3 "$out/twins-$lang-$size.txt"
      done
    done
    python3 "$here/bench/kernel-time/compare.py" twins "$out" | tee "$out/twins-summary.txt"
    ;;
  suite)
    # The GPU suite: every test but those that need this repository's toolchain (builds,
    # linters, the browser, the schema and paper tools) or wait out a timeout by design,
    # in two halves (PART 1 or 2) so that each fits one device call.
    part=${1:?suite PART (1 or 2)}
    total=$(ctest --test-dir "$here/build" -N | sed -n 's/^Total Tests: //p')
    half=$(( (total + 1) / 2 ))
    if [ "$part" = 1 ]; then range="1,$half"; else range="$((half + 1)),$total"; fi
    jobs=$(nproc); [ "$jobs" -le 12 ] || jobs=12  # the GPU machine's 16 cores ran it at 12
    ctest --test-dir "$here/build" -j "$jobs" --timeout 200 -I "$range" \
      -E 'InjectedHang|Schema|Consumer|^Build\.|Floors|Namespaces|FunctionLength|ReportBrowser|fuzz_build|Templates|PaperCli|Examples' \
      > "$out/suite-$part.txt" 2>&1 || true
    { echo "tests $range of $total"; grep -E "tests passed|tests failed|\(Failed\)|\(Timeout\)|\(Skipped\)" "$out/suite-$part.txt"; } \
      | tee "$out/suite-$part-summary.txt"
    ;;
  *) echo "unknown mode $mode" >&2; exit 2 ;;
esac
