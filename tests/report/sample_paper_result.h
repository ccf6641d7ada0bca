// A small paper result (report/paper_result.h) for the paper report tests and the
// committed fixture tests/data/paper/sample-result.json: a GPU seen through
// OpenCL, CUDA and GL, a CPU OpenCL device (PoCL) and llvmpipe GL (type cpu),
// six data sets (25k/100k/400k x B = 1, 2), the paper's kernels measured on
// every device with one of them failing verification and one never measured,
// tuned winners faster than the paper's kernels, and made-up "reported"
// figures (labelled as such) so the report places them.
//
// Times follow a simple model: bytes the variant's format moves per frame
// over the device's bandwidth times the variant's efficiency, plus a launch
// overhead; everything is deterministic, so the fixture can be compared with
// this header byte for byte.
#pragma once

#include <string>
#include <vector>

#include "generator/variant.h"
#include "report/paper_result.h"
#include "tuner/report.h"

namespace skintune::internal::testing {

inline DeviceIdentity PaperDevice(const std::string& backend, int index, const std::string& platform,
                                  const std::string& vendor, const std::string& name, const std::string& driver,
                                  const std::string& api_version, const std::string& type, std::uint32_t units,
                                  std::uint64_t memory, std::uint64_t llc) {
  DeviceIdentity d;
  d.backend = backend;
  d.index = index;
  d.platform = platform;
  d.vendor = vendor;
  d.name = name;
  d.driver_version = driver;
  d.api_version = api_version;
  d.type = type;
  d.compute_units = units;
  d.global_memory_bytes = memory;
  d.local_memory_bytes = 48 << 10;
  d.constant_memory_bytes = 64 << 10;
  d.last_level_cache_bytes = llc;
  return d;
}

inline DeviceIdentity SampleOpenClGpu() {
  return PaperDevice("opencl", 0, "NVIDIA CUDA", "NVIDIA Corporation", "NVIDIA H100 80GB HBM3", "580.159.04",
                     "OpenCL 3.0 CUDA", "gpu", 132, 80ull << 30, 50ull << 20);
}
inline DeviceIdentity SampleCudaGpu() {
  return PaperDevice("cuda", 0, "CUDA", "NVIDIA", "NVIDIA H100 80GB HBM3", "580.159.04 (CUDA 13.0)", "9.0", "gpu", 132,
                     80ull << 30, 50ull << 20);
}
inline DeviceIdentity SampleGlGpu() {
  return PaperDevice("gl", 0, "device", "NVIDIA Corporation", "NVIDIA H100 80GB HBM3/PCIe/SSE2",
                     "4.3.0 NVIDIA 580.159.04", "4.3.0 NVIDIA 580.159.04", "gpu", 0, 80ull << 30, 0);
}
inline DeviceIdentity SampleOpenClCpu() {
  return PaperDevice("opencl", 1, "Portable Computing Language", "GenuineIntel",
                     "cpu-skylake-avx512-Intel(R) Xeon(R) Processor", "5.0+debian", "OpenCL 3.0 PoCL", "cpu", 16,
                     128ull << 30, 32ull << 20);
}
inline DeviceIdentity SampleGlCpu() {
  return PaperDevice("gl", 1, "surfaceless", "Mesa", "llvmpipe (LLVM 15.0.6, 256 bits)", "4.5 (Core Profile) Mesa 22.3.6",
                     "4.5 (Core Profile) Mesa 22.3.6", "cpu", 0, 128ull << 30, 0);
}

// The paper's kernels as configs/paper.json lists them (copied, so the
// fixture does not change when that list is edited).
inline std::vector<PaperKernel> SamplePaperKernels() {
  auto kernel = [](const char* name, const char* label, const char* section, const char* key) {
    return PaperKernel{name, label, section, std::string("The ") + label + " kernel of the sample.",
                       ParseVariantKey(key)};
  };
  return {kernel("opencl-unoptimised", "OpenCL (not optimised)", "section 5.1",
                 "opencl.b2.padded.aos.float3.i32.f32.mat4.global.matrix.v1c.wg128.nonormals"),
          kernel("opencl-optimised", "OpenCL (optimised)", "section 5, its optimisations",
                 "opencl.b2.padded.soa.float4.i32.f32.mat4.constant.matrix.v1c.wg128.nonormals"),
          kernel("cuda", "CUDA", "section 4.1", "cuda.b2.padded.aos.float3.i32.f32.mat4.global.matrix.v1c.wg128.nonormals"),
          kernel("glsl-vertex", "GLSL (vertex shader)", "the paper's GLSL implementation",
                 "glsl-vertex.b2.padded.aos.float3.i32.f32.mat4.constant.matrix.v1c.wg0.nonormals")};
}

// Bytes a variant's format moves per frame (positions in and out, B indices
// and weights), as SyntheticMeasurement counts them.
inline double SampleBytes(const Variant& v, std::size_t vertices) {
  const double position = v.position == PositionFormat::kFloat4 ? 16.0 : 12.0;
  return static_cast<double>(vertices) *
         (2.0 * position + v.influences * static_cast<double>(BytesOf(v.index) + BytesOf(v.weight)));
}

// A measurement of `v` (B set to the data set's) taking `ms`, or failing with `status`.
inline Measurement PaperMeasurement(const DeviceIdentity& device, const DatasetInfo& dataset, Variant v, double ms,
                                    MeasureStatus status = MeasureStatus::kOk, const std::string& detail = "") {
  v.influences = dataset.influences;
  Measurement m;
  m.device_id = device.Id();
  m.dataset = dataset.key;
  m.variant = v;
  m.status = status;
  m.detail = detail;
  m.bytes_per_frame = SampleBytes(v, dataset.vertices);
  m.generator_version = "sample";
  m.timestamp = "2025-06-01T12:00:00Z";
  if (status == MeasureStatus::kOk) {
    m.timing = {ms, ms * 0.97, ms * 1.08, 5, 20, 8, 40, 2.0e8, ms / 1.25};  // 200 MB rotated: beyond 2 x 50 MiB
    m.gbps = m.bytes_per_frame / (ms * 1e6);
    m.x_copy = 1.25;  // the same-size copy takes 1/1.25 of the kernel's time
    m.max_relative_error = 3e-7;
  }
  return m;
}

// Serial and fast CPU timings of a data set (checked against the gold).
inline CpuResult SampleCpu(const DatasetInfo& d, double serial_ms, double fast_ms, unsigned threads) {
  auto timing = [&](double ms, unsigned t) {
    CpuTiming c;
    c.median_ms = ms;
    c.min_ms = ms * 0.98;
    c.max_ms = ms * 1.1;
    c.repetitions = 20;
    c.input_sets = 8;
    c.threads = t;
    c.bytes_per_frame = static_cast<double>(d.vertices) * (2.0 * 16.0 + d.influences * 8.0);
    c.gbps = c.bytes_per_frame / (ms * 1e6);
    c.max_relative_error = 1e-7;
    return c;
  };
  return {d.key, timing(serial_ms, 1), timing(fast_ms, threads)};
}

inline PaperResult SamplePaperResult() {
  PaperResult r;
  r.created = "2025-06-01T12:00:00Z";
  r.quick = false;
  r.command = "skintune paper --datasets 25k-b1,25k-b2,100k-b1,100k-b2,400k-b1,400k-b2 --out paper-sample";
  r.figure1_dataset = "100k-b2";
  r.host = {"Intel(R) Xeon(R) Processor (Sapphire Rapids)", 16, 83.0};
  r.reported.source =
      "Made-up figures of the test sample (tests/report/sample_paper_result.h), not the paper's: they only show "
      "where the report places the paper's figures.";
  r.reported.figure1 = {{"glsl", 15.0}, {"cuda", 20.0}, {"opencl-optimised", 18.0}, {"opencl-cpu", 3.0}};
  r.reported.opencl_vs_cuda = {{"25k-b1", 0.8}, {"100k-b2", 0.9}};
  r.reported.opencl_vs_glsl = {{"100k-b2", 1.1}};
  r.paper_kernels = SamplePaperKernels();

  TuningReport& t = r.tuning;
  t.created = r.created;
  t.config = "paper";
  t.strategy = "coordinate";
  t.machine = {{"hostname", "sample-host"}, {"os", "Linux 6.1.0 x86_64"}, {"cpu_model", r.host.cpu_model},
               {"logical_cpus", 16}, {"memory_bytes", 137438953472ull}};
  const DeviceIdentity opencl_gpu = SampleOpenClGpu(), cuda = SampleCudaGpu(), gl_gpu = SampleGlGpu(),
                       opencl_cpu = SampleOpenClCpu(), gl_cpu = SampleGlCpu();
  t.devices = {opencl_gpu, cuda, gl_gpu, opencl_cpu, gl_cpu};
  t.copy_bandwidth_gbps = {{opencl_gpu.Id(), 2756.0}, {cuda.Id(), 2966.0}, {gl_gpu.Id(), 2616.0},
                           {opencl_cpu.Id(), 56.0}, {gl_cpu.Id(), 21.0}};
  for (const char* size : {"25k", "100k", "400k"}) {
    const std::size_t vertices = std::string(size) == "25k" ? 25000 : std::string(size) == "100k" ? 100000 : 400000;
    for (int b = 1; b <= 2; ++b) t.datasets.push_back({std::string(size) + "-b" + std::to_string(b), vertices, b, 77});
  }

  // Efficiencies: the fraction of the device's bandwidth a variant reaches.
  struct Candidate {
    const char* key;  // B is set per data set
    double efficiency;
  };
  const std::vector<Candidate> opencl = {
      {"opencl.b2.padded.aos.float3.i32.f32.mat4.global.matrix.v1c.wg128.nonormals", 0.30},     // paper: unoptimised
      {"opencl.b2.padded.soa.float4.i32.f32.mat4.constant.matrix.v1c.wg128.nonormals", 0.55},   // paper: optimised
      {"opencl.b2.padded.soa-split.float4.u8.unorm8.mat3x4.local.matrix.v1c.wg256.nonormals", 0.90},
      {"opencl.b2.padded.soa-split.float4.u8.unorm8.mat3x4.global.matrix.v1c.wg256.nonormals", 0.85},
      {"opencl.b2.padded.soa.float4.u16.unorm16.mat3x4.constant.point.v2s.wg128.nonormals", 0.75},
      {"opencl.b2.padded.soa-split.float3.u8.f32.mat3x4.image.matrix.v4c.wg64.nonormals", 0.70},
  };
  const std::vector<Candidate> cuda_candidates = {
      {"cuda.b2.padded.aos.float3.i32.f32.mat4.global.matrix.v1c.wg128.nonormals", 0.35},  // paper
      {"cuda.b2.padded.soa-split.float4.u8.unorm8.mat3x4.local.matrix.v1c.wg256.nonormals", 0.88},
      {"cuda.b2.padded.soa-split.float4.u8.unorm8.mat3x4.global.matrix.v1c.wg256.nonormals", 0.86},
      {"cuda.b2.padded.soa.float4.u16.unorm16.mat3x4.constant.point.v2s.wg128.nonormals", 0.70},
  };
  const std::vector<Candidate> gl = {
      {"glsl-vertex.b2.padded.aos.float3.i32.f32.mat4.constant.matrix.v1c.wg0.nonormals", 0.05},  // paper
      {"glsl-vertex.b2.padded.soa-split.float4.u8.unorm8.mat3x4.global.matrix.v1c.wg0.nonormals", 0.08},
      {"glsl-compute.b2.padded.soa-split.float4.u8.unorm8.mat3x4.global.matrix.v1c.wg256.nonormals", 0.80},
      {"glsl-compute.b2.padded.soa-split.float4.u8.unorm8.mat3x4.constant.matrix.v1c.wg128.nonormals", 0.78},
  };
  auto measure = [&](const DeviceIdentity& device, const std::vector<Candidate>& candidates, double bandwidth_gbps,
                     double overhead_ms) {
    for (const DatasetInfo& d : t.datasets) {
      for (const Candidate& c : candidates) {
        Variant v = ParseVariantKey(c.key);
        v.influences = d.influences;
        const double ms = SampleBytes(v, d.vertices) / (bandwidth_gbps * c.efficiency * 1e6) + overhead_ms;
        const bool paper_unoptimised = v.layout == Layout::kAos && v.lang == Lang::kOpenCl;
        const bool image = v.storage == PaletteStorage::kImage;
        if (device.type == "cpu" && paper_unoptimised && d.key == "100k-b2") {
          // The failed paper kernel: shown with its status in Fig. 1, never with a time.
          t.measurements.push_back(
              PaperMeasurement(device, d, v, ms, MeasureStatus::kVerifyFailed, "vertex 17: position off by 0.5"));
        } else if (device.type == "cpu" && image) {
          t.measurements.push_back(
              PaperMeasurement(device, d, v, ms, MeasureStatus::kCompileFailed, "error: images are not supported"));
        } else if (device.type == "cpu" && v.lang == Lang::kGlslVertex && d.vertices == 400000) {
          // Never measured: the paper's GLSL kernel on llvmpipe at 400k is "not measured".
        } else {
          t.measurements.push_back(PaperMeasurement(device, d, v, ms));
        }
      }
    }
  };
  measure(opencl_gpu, opencl, 2756.0, 0.006);
  measure(cuda, cuda_candidates, 2966.0, 0.004);
  measure(gl_gpu, gl, 2616.0, 0.008);
  measure(opencl_cpu, opencl, 56.0, 0.02);
  measure(gl_cpu, gl, 21.0, 0.05);

  for (const DatasetInfo& d : t.datasets) {
    const double serial = static_cast<double>(d.vertices) * (4.0 + 3.0 * d.influences) * 1e-6;
    r.cpu.push_back(SampleCpu(d, serial, serial / 11.0 + 0.01, 16));
  }
  return r;
}

}  // namespace skintune::internal::testing
