// skintune tune: times and verifies the variants of a tuning space on every
// device found, each device in its own child process (skintune tune-worker),
// with a resumable measurement cache; writes the report, its T4 export and the
// winners database, and prints the winners.
#include <exception>
#include <iostream>
#include <memory>
#include <string>

#include "tools/commands.h"
#include "tools/progress.h"
#include "tools/tune_job.h"

namespace skintune::internal::tools {

namespace {

struct TuneCliOptions {
  TuneJobOptions job;
  std::string budget_text;  // checked by BudgetCheck
};

int RunTune(TuneCliOptions o, bool budget_given) {
  if (budget_given) o.job.budget = *ParseWholeNumber(o.budget_text, kMaxBudget);
  const TuneJobResult result = RunTuneJob(o.job);
  PrintWinners(result.report);
  if (!o.job.quiet) {
    std::string written;
    for (const auto& path : result.written) written += (written.empty() ? "" : ", ") + path.string();
    std::cerr << "skintune: tune: wrote " << written << " (cache " << result.cache.string() << ")\n";
  }
  return 0;
}

}  // namespace

double ParseMaxError(const std::string& text, const std::string& flag) {
  std::size_t used = 0;
  double value = 0.0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size())
    throw Error(flag + " '" + text + "': not a number (an error relative to the bounding-box diagonal, e.g. 1e-4)");
  if (const std::string bad = BadMaxError(value); !bad.empty()) throw Error(flag + " '" + text + "': " + bad);
  return value;
}

CLI::Validator BudgetCheck() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        if (ParseWholeNumber(text, kMaxBudget)) return "";
        return "must be a whole number from 0 to " + std::to_string(kMaxBudget) + " (got '" + text + "')";
      },
      "0.." + std::to_string(kMaxBudget));
}

Command RegisterTune(CLI::App& app) {
  auto o = std::make_shared<TuneCliOptions>();
  auto* sub = app.add_subcommand(
      "tune", "time and verify the variants of a tuning space on every device found; write the report and winners");
  AddTuneJobOptions(*sub, o->job);
  sub->add_option("--strategy", o->job.strategy, "search strategy (overrides the config's)")
      ->check(CLI::IsMember({"exhaustive", "random", "coordinate"}));
  auto* budget = sub->add_option("--budget", o->budget_text,
                                 "evaluations per device, language and dataset, 0 to " + std::to_string(kMaxBudget) +
                                     " (overrides the config's)")
                     ->check(BudgetCheck());
  return {sub, [o, budget] { return RunTune(*o, budget->count() > 0); }};
}

Command RegisterTuneWorker(CLI::App& app) {
  auto args = std::make_shared<TuneWorkerArgs>();
  auto* sub = app.add_subcommand("tune-worker", "measure variants for `skintune tune` (internal)");
  sub->group("");  // hidden: started by `skintune tune` only
  sub->add_option("--device-index", args->device_index, "the device's position in discovery order")->required();
  sub->add_option("--device-id", args->device_id, "the device's identity (takes precedence over the index)");
  sub->add_option("--host-lock", args->host_lock, "the lock file of the host's cores, shared with the other workers");
  sub->add_option("--chip-lock", args->chip_lock, "the lock file of the GPU, shared with its other APIs' workers");
  sub->add_option("--discover-only", args->discover_only, "the only API whose devices it looks for");
  sub->add_option("--cache-bytes", args->cache_bytes, "the device's last-level cache as the parent found it")
      ->check(CLI::PositiveNumber);
  sub->add_option("--cache-source", args->cache_source, "where the parent's cache figure came from");
  return {sub, [args] { return RunTuneWorker(*args); }};
}

}  // namespace skintune::internal::tools
