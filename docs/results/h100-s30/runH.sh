#!/usr/bin/env bash
# Session 30, call H: GPU tests of the pooled packing, the lock-free ThreadPool and the submit thread's
# ring waits; then the frame bench, this build against .carry/base (40b0607), on the APIs in $APIS.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/out}; mkdir -p "$OUT"; S=$OUT/summary.txt
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> "$S"
if [ -n "${TESTS:-}" ]; then
  echo "== tests" >> "$S"
  echo "$TESTS" | tr ' ' '\n' | xargs -P6 -I{} sh -c 'timeout 300 build/bin/{} > '"$OUT"'/{}.log 2>&1; echo "{}: rc=$? $(grep -E "PASSED|FAILED|SKIPPED \]" '"$OUT"'/{}.log | tr "\n" " " | cut -c1-300)"' >> "$S"
fi
F="--benchmark_min_time=0.1 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true"
for run in $RUNS; do   # api:binary[:submit]
  api=${run%%:*}; rest=${run#*:}; bin=${rest%%:*}; extra=""; [ "$rest" != "$bin" ] && extra=--submit-thread
  case $api in
    cuda) dev=cuda:; V=cuda.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
    opencl) dev=opencl:nvidia; V=opencl.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v2s.wg256.nonormals ;;
    gl) dev=gl:; V=glsl-compute.b4.padded.aos.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg256.nonormals ;;
  esac
  B=build/bin/skintune_bench_frame; [ $bin = base ] && B=.carry/base/skintune_bench_frame
  start=$(date +%s%N)
  timeout 110 $B --device $dev --variant $V $extra $F --benchmark_filter="instanced/(skin-only|set-skin-pipelined|set-skin-finish)" > "$OUT/frame-$api-$bin${extra:+-submit}.txt" 2>&1
  echo "-- $api $bin $extra rc=$? $(( ($(date +%s%N) - start) / 1000000 )) ms" >> "$S"
  grep -E 'median|rror' "$OUT/frame-$api-$bin${extra:+-submit}.txt" | sed 's/  */ /g' | sed 's/frame\/instanced\///' >> "$S"
done
