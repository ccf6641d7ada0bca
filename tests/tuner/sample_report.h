// A small tuning report (two devices, three datasets, ok and failed
// measurements of every kind) for the report and schema tests.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "tests/tuner/synthetic_model.h"
#include "tuner/report.h"

namespace skintune::internal::testing {

inline DeviceIdentity SampleGpu(const std::string& driver = "1.0") {
  DeviceIdentity d;
  d.backend = "opencl";
  d.index = 0;
  d.platform = "Synthetic";
  d.vendor = "Example";
  d.name = "Model GPU";
  d.driver_version = driver;
  d.api_version = "OpenCL 3.0";
  d.type = "gpu";
  d.compute_units = 132;
  d.global_memory_bytes = 80ull << 30;
  d.local_memory_bytes = 48 << 10;
  d.constant_memory_bytes = 64 << 10;
  d.last_level_cache_bytes = 50ull << 20;
  return d;
}

inline DeviceIdentity SampleCuda() {
  DeviceIdentity d;
  d.backend = "cuda";
  d.index = 1;
  d.platform = "CUDA";
  d.vendor = "NVIDIA";
  d.name = "Model GPU";
  d.driver_version = "12.4";
  d.api_version = "9.0";
  d.type = "gpu";
  d.compute_units = 132;
  d.global_memory_bytes = 80ull << 30;
  d.local_memory_bytes = 48 << 10;
  d.constant_memory_bytes = 64 << 10;
  return d;
}

inline Measurement WithStatus(Measurement m, MeasureStatus status, const std::string& detail) {
  m.status = status;
  m.detail = detail;
  if (status != MeasureStatus::kOk) {
    m.gbps = 0.0;
    m.timing = {};
  }
  return m;
}

// created: the report's `created`; ms_scale scales every time (to tell reports apart).
inline TuningReport SampleReport(const std::string& created = "2025-01-31T12:00:00Z", double ms_scale = 1.0,
                                 const std::string& driver = "1.0") {
  TuningReport r;
  r.created = created;
  r.config = "default";
  r.strategy = "exhaustive";
  r.machine = {{"hostname", "test-host"}, {"os", "Linux"}, {"cpu", "Example CPU"}, {"logical_cpus", 16},
               {"memory_bytes", 137438953472ull}};
  const DeviceIdentity gpu = SampleGpu(driver);
  const DeviceIdentity cuda = SampleCuda();
  r.devices = {gpu, cuda};
  r.copy_bandwidth_gbps = {{gpu.Id(), 2000.0}};  // none for the CUDA device: copy_fraction 0
  r.skipped = {"gl: skipped: no EGL display (test)"};
  r.datasets = {{"25k-b4", 25000, 4, 77}, {"100k-b4", 100000, 4, 77}, {"1600k-b1", 1600000, 1, 77}};
  const std::vector<Variant> candidates = SyntheticCandidates();
  auto add = [&](const Variant& v, const DeviceIdentity& d, const std::string& dataset, std::size_t vertices) {
    Measurement m = SyntheticMeasurement(v, d.Id(), dataset, vertices);
    if (m.status == MeasureStatus::kOk) {
      m.timing.median_ms *= ms_scale;
      m.timing.min_ms *= ms_scale;
      m.timing.max_ms *= ms_scale;
      m.gbps /= ms_scale;
    }
    m.timestamp = created;
    r.measurements.push_back(m);
    return m;
  };
  for (std::size_t i = 0; i < 40; ++i) {
    add(candidates[i * 97], gpu, "100k-b4", 100000);
    add(candidates[i * 89], gpu, "25k-b4", 25000);
    Variant c = candidates[i * 61];
    c.lang = Lang::kCuda;
    add(c, cuda, "100k-b4", 100000);
  }
  Variant b1;
  b1.influences = 1;
  add(b1, gpu, "1600k-b1", 1600000);
  // Failures of every kind, each "faster" than anything ok: never winners.
  Measurement fast = SyntheticMeasurement(candidates[3], gpu.Id(), "100k-b4");
  fast.timestamp = created;
  fast.timing = {1e-6, 1e-6, 1e-6, 3, 10, 4, 8};
  fast.gbps = 1e9;
  Variant v = candidates[5];
  for (MeasureStatus s : {MeasureStatus::kInvalid, MeasureStatus::kCompileFailed, MeasureStatus::kLaunchFailed, MeasureStatus::kVerifyFailed,
                   MeasureStatus::kTimeout}) {
    Measurement f = fast;
    f.variant = v;
    f.status = s;
    f.detail = std::string("synthetic ") + Name(s);
    if (s == MeasureStatus::kVerifyFailed) f.max_relative_error = std::numeric_limits<double>::infinity();
    r.measurements.push_back(f);
    v.wg_size = v.wg_size == 32 ? 64 : 32;
    v.blend = v.blend == Blend::kPoint ? Blend::kMatrix : Blend::kPoint;
  }
  // A bucket where everything failed: no winner for 1600k at B = 2.
  Variant b2;
  b2.influences = 2;
  Measurement failed = SyntheticMeasurement(b2, gpu.Id(), "1600k-b1", 1600000);
  failed.timestamp = created;
  r.measurements.push_back(WithStatus(failed, MeasureStatus::kVerifyFailed, "vertex 0 off"));
  return r;
}

}  // namespace skintune::internal::testing
