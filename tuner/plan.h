// skintune: what a tuning run measures, built and checked before any device
// measures anything (the tuner's first step; tuner/schedule.h decides when
// each device runs, tuner/device_tuning.h runs one).
//
// A plan is every dataset loaded and checked (memory, finite palettes), the
// devices found (filtered by --device) with their limits and languages, and
// one task per device x language x dataset: the space's points with B = the
// dataset's influences, checked against the device's limits and the
// dataset's shape. An invalid point is recorded in its task (status invalid,
// every constraint it breaks; at most kMaxInvalidRecords per task); other B
// are not tried on that dataset: a larger B only pads with zero weights (the
// same output, more bytes), and winners are kept per B. A config that gives
// nothing to measure fails here, naming why.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "generator/constraints.h"
#include "generator/variant.h"
#include "runtime/device_identity.h"
#include "tuner/config.h"
#include "tuner/measurement.h"
#include "tuner/report.h"  // DatasetInfo

namespace skintune::internal {

inline constexpr std::size_t kMaxInvalidRecords = 10000;

struct PlannedDataset {
  DatasetInfo info;
  ProblemShape shape;  // the constraints' view: joints, widest vertex, normals, instances
};

struct PlannedDevice {
  DeviceIdentity identity;
  DeviceLimits limits;
  std::vector<Lang> languages;
};

// One device x language x dataset: its valid variants and its invalid points.
struct Task {
  std::size_t device = 0;   // into TuningPlan::devices
  Lang lang = Lang::kOpenCl;
  std::size_t dataset = 0;  // into TuningPlan::datasets
  std::vector<Variant> candidates;
  std::vector<Variant> baselines;     // measured before the search (TuneConfig::baselines)
  std::vector<Measurement> invalid;
  std::size_t planned = 0;  // evaluations expected (for progress)
};

struct TuningPlan {
  std::vector<PlannedDataset> datasets;
  std::vector<PlannedDevice> devices;
  std::vector<std::string> skipped;  // discovery's: APIs and devices not found, with the reason
  std::vector<Task> tasks;
  std::size_t total = 0;             // evaluations planned, over every task

  // Evaluations planned on device `d`.
  std::size_t PlannedOn(std::size_t d) const;
  // Whether device `d` has a task: reported, even with only invalid points.
  bool HasTasks(std::size_t d) const;
};

// Called with what the plan is doing ("loading dataset 5k-b4", "discovering devices").
using PlanProgress = std::function<void(const std::string& what)>;

// Throws Error for a run that cannot start: ValidateConfig's reasons, no
// worker executable.
void ValidateRun(const TuneConfig& config, const TuneOptions& options);

// The whole plan: the datasets (their errors name the config and element:
// "c.json: datasets[1]: ..."), the devices discovered and matching
// options.device_pattern, each dataset checked against each device's memory,
// then the tasks (PlanTasks). Throws Error for bad input: no device, none
// matching, a dataset that does not fit, nothing to measure.
TuningPlan PlanTuning(const TuneConfig& config, const TuneOptions& options, const std::string& created,
                      const PlanProgress& progress);

// One dataset loaded for the plan: the scene checked against this machine's
// memory before it is generated, every palette the workers start from finite.
PlannedDataset PlanDataset(const std::string& key);

// Of the devices `found`, those options.device_pattern matches (Error when
// none does); without a pattern all but software rasterizers
// (IsSoftwareRasterizer), each left out added to `skipped` with the reason,
// unless options.software_rasterizers asks for them or they are all there is.
std::vector<PlannedDevice> SelectDevices(std::vector<PlannedDevice> found, const TuneOptions& options,
                                         std::vector<std::string>& skipped);

// The tasks of `devices` x their languages (those of the space, and of
// `languages` when not empty) x `datasets`, in that order; invalid points
// recorded with timestamp `created`. Throws Error when no device offers a
// language of the space, or no task has a valid variant (naming the
// constraints that ruled the points out).
std::vector<Task> PlanTasks(const TuneConfig& config, const std::vector<Lang>& languages,
                            const std::vector<PlannedDataset>& datasets, const std::vector<PlannedDevice>& devices,
                            const std::string& created);

}  // namespace skintune::internal
