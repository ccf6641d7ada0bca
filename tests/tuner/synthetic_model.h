// A synthetic, deterministic cost model of the OpenCL variant space, for the
// strategy, replay, report and schema tests: no device needed.
//
// time = streamed bytes / effective bandwidth, where the effective bandwidth
// depends on the layout and how vertices are assigned to items, times factors
// for the palette storage and format, the blend, the work-group size (with a
// per-group copy for local storage), interactions between axes (register
// pressure, narrow loads, occupancy), plus a launch overhead per bucket, times
// a fixed per-variant "noise" of +-3%. About 3% of the variants fail
// (compile, launch, verification or timeout, chosen by the variant's hash).
#pragma once

#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "generator/space.h"
#include "generator/variant.h"
#include "tuner/measurement.h"

namespace skintune::internal::testing {

// The OpenCL space of a 100k-vertex, 4-influence, 77-joint mesh without
// normals, with influences fixed at 4 (about 48k valid variants).
inline std::vector<Variant> SyntheticCandidates(std::size_t max_wg = 256) {
  TuningSpace space = TuningSpace::Full();
  space.langs = {Lang::kOpenCl};
  space.influences = {4};
  space.normals = {Normals::kNone};
  space.morphs = {Morph::kNone};
  space.normal_formats = {NormalFormat::kF32};
  DeviceLimits limits;
  limits.max_wg_size = max_wg;
  std::vector<Variant> out;
  Enumerate(space, limits, ProblemShape{77, 4, false}, [&](const Variant& v) { out.push_back(v); });
  return out;
}

// A value in [-1, 1) fixed per variant and salt.
inline double HashUnit(const Variant& v, std::uint64_t salt) {
  std::uint64_t h = static_cast<std::uint64_t>(v.Hash()) ^ (salt * 0x9E3779B97F4A7C15ull);
  h ^= h >> 33;
  h *= 0xFF51AFD7ED558CCDull;
  h ^= h >> 33;
  return static_cast<double>(h >> 11) / static_cast<double>(1ull << 52) - 1.0;
}

inline double SyntheticTimeMs(const Variant& v, std::size_t vertices = 100000) {
  const double b = v.influences;
  const double position = v.position == PositionFormat::kFloat4 ? 16.0 : 12.0;
  const double bytes =
      static_cast<double>(vertices) * (2.0 * position + b * (static_cast<double>(BytesOf(v.index)) +
                                                             static_cast<double>(BytesOf(v.weight))));
  double efficiency = v.layout == Layout::kAos ? 0.62 : v.layout == Layout::kSoa ? 0.86 : 1.0;
  const double steps = std::log2(static_cast<double>(v.vertices_per_item));
  if (v.assignment == Assignment::kContiguous) {
    efficiency /= 1.0 + (v.layout == Layout::kSoaSplit ? 0.18 : 0.08) * steps;
  } else {
    efficiency *= 1.0 + 0.03 * steps;  // more loads in flight, still coalesced
  }
  if (v.position == PositionFormat::kFloat3) efficiency *= 0.95;
  const double bandwidth_gbps = 400.0 * efficiency;
  double ms = bytes / (bandwidth_gbps * 1e6);
  switch (v.storage) {
    case PaletteStorage::kConstant: ms *= 1.30; break;  // divergent reads serialise
    case PaletteStorage::kLocal: ms *= 1.0 + 2.0 / v.wg_size; break;  // the per-group copy
    case PaletteStorage::kGlobal: ms *= 1.04; break;
    case PaletteStorage::kImage: ms *= 1.02; break;
  }
  if (v.palette == PaletteFormat::kMat4) ms *= 1.04;
  if (v.blend == Blend::kPoint) ms *= 1.03;
  switch (v.wg_size) {
    case 32: ms *= 1.15; break;
    case 64: ms *= 1.03; break;
    case 256: ms *= 1.01; break;
    default: break;
  }
  // Interactions (what makes the space not separable):
  if (v.blend == Blend::kPoint && v.vertices_per_item >= 4) ms *= 1.25;  // register pressure
  if (v.palette == PaletteFormat::kMat4 && v.vertices_per_item == 8) ms *= 1.15;
  if (v.layout == Layout::kSoaSplit && BytesOf(v.index) == 1 && BytesOf(v.weight) == 1) ms *= 1.08;  // narrow slot loads
  if (v.layout == Layout::kAos && v.position == PositionFormat::kFloat3) ms *= 0.97;  // smaller records
  if (v.wg_size * v.vertices_per_item >= 1024) ms *= 1.06;  // too few groups to fill the device
  if (v.storage == PaletteStorage::kConstant && v.index == IndexFormat::kU8) ms *= 0.9;  // fewer distinct bones per warp
  ms += v.mixed == MixedCounts::kBucketed ? 0.004 : 0.0;  // extra launches
  return ms * (1.0 + 0.03 * HashUnit(v, 1));
}

inline MeasureStatus SyntheticStatus(const Variant& v) {
  const double u = HashUnit(v, 2);  // uniform in [-1, 1)
  if (u < -0.985) return MeasureStatus::kCompileFailed;
  if (u < -0.975) return MeasureStatus::kLaunchFailed;
  if (u < -0.97) return MeasureStatus::kVerifyFailed;
  if (u < -0.968) return MeasureStatus::kTimeout;
  return MeasureStatus::kOk;
}

inline Measurement SyntheticMeasurement(const Variant& v, const std::string& device_id, const std::string& dataset,
                                        std::size_t vertices = 100000) {
  Measurement m;
  m.device_id = device_id;
  m.dataset = dataset;
  m.variant = v;
  m.status = SyntheticStatus(v);
  m.generator_version = "test";
  m.timestamp = "2025-01-31T12:00:00Z";
  const double position = v.position == PositionFormat::kFloat4 ? 16.0 : 12.0;
  m.bytes_per_frame = static_cast<double>(vertices) *
                      (2.0 * position + v.influences * static_cast<double>(BytesOf(v.index) + BytesOf(v.weight)));
  switch (m.status) {
    case MeasureStatus::kOk: {
      const double t = SyntheticTimeMs(v, vertices);
      m.timing = {t, t * 0.98, t * 1.05, 3, 10, 4, 8};  // 8 frames a burst
      m.gbps = m.bytes_per_frame / (t * 1e6);
      m.max_relative_error = 2e-7;
      break;
    }
    case MeasureStatus::kCompileFailed: m.detail = "error: synthetic build failure"; break;
    case MeasureStatus::kLaunchFailed: m.detail = "CL_OUT_OF_RESOURCES"; break;
    case MeasureStatus::kVerifyFailed:
      m.detail = "vertex 17: position off by 0.5";
      m.max_relative_error = 0.5;
      break;
    case MeasureStatus::kTimeout: m.detail = "exceeded 60 s"; break;
    case MeasureStatus::kInvalid: break;
    case MeasureStatus::kTooImprecise: break;  // never drawn: the model has no weight-format error
  }
  return m;
}

// The model as an evaluator: the median of status-ok variants, nullopt otherwise.
inline std::optional<double> SyntheticEvaluate(const Variant& v) {
  if (SyntheticStatus(v) != MeasureStatus::kOk) return std::nullopt;
  return SyntheticTimeMs(v);
}

}  // namespace skintune::internal::testing
