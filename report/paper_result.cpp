// skintune: the paper experiment's data: its kernels, the paper's published
// figures, and the versioned result JSON (configs/paper-result.schema.json).
#include <cmath>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "runtime/json_fields.h"
#include "runtime/recorded_time.h"
#include "report/paper_result.h"
#include "tuner/tune.h"  // EmbeddedConfig

namespace skintune::internal {

namespace {

using namespace json_fields;

const nlohmann::json& PaperConfig() {
  static const nlohmann::json config = nlohmann::json::parse(EmbeddedConfig("paper"));
  return config;
}

std::map<std::string, double> Figures(const nlohmann::json& in, const std::string& where) {
  std::map<std::string, double> out;
  if (!in.is_object()) throw Error(where + ": expected an object of name -> number");
  for (const auto& [name, value] : in.items()) {
    if (!value.is_number() || !std::isfinite(value.get<double>()) || value.get<double>() <= 0.0) {
      throw Error(where + "." + name + ": expected a positive number (got " + value.dump() + ")");
    }
    out[name] = value.get<double>();
  }
  return out;
}

nlohmann::json CpuTimingJson(const CpuTiming& t) {
  return {{"median_ms", t.median_ms},
          {"min_ms", t.min_ms},
          {"max_ms", t.max_ms},
          {"repetitions", t.repetitions},
          {"input_sets", t.input_sets},
          {"threads", t.threads},
          {"bytes_per_frame", t.bytes_per_frame},
          {"gbps", t.gbps},
          {"max_relative_error", t.max_relative_error}};
}

CpuTiming CpuTimingFromJson(const nlohmann::json& in) {
  if (!in.is_object()) throw Error("expected an object");
  CpuTiming t;
  t.median_ms = Number(in, "median_ms");
  t.min_ms = Number(in, "min_ms");
  t.max_ms = Number(in, "max_ms");
  t.repetitions = static_cast<int>(Integer(in, "repetitions"));
  t.input_sets = static_cast<int>(Integer(in, "input_sets"));
  const std::int64_t threads = Integer(in, "threads");
  if (threads < 1) throw Error("'threads' must be >= 1");
  t.threads = static_cast<unsigned>(threads);
  t.bytes_per_frame = Number(in, "bytes_per_frame");
  t.gbps = Number(in, "gbps");
  t.max_relative_error = Number(in, "max_relative_error");
  RecordedTime time;
  time.median_ms = t.median_ms;
  time.min_ms = t.min_ms;
  time.max_ms = t.max_ms;
  time.bytes_per_frame = t.bytes_per_frame;
  time.gbps = t.gbps;
  std::string problem = ImpossibleTime(time);
  if (problem.empty() && t.repetitions < 1)
    problem = "'repetitions' is " + std::to_string(t.repetitions) + ": a median needs at least one timed run";
  if (problem.empty()) problem = NotFiniteNonNegative("max_relative_error", t.max_relative_error);
  if (!problem.empty()) throw Error("impossible figures: " + problem);
  return t;
}

nlohmann::json ReportedJson(const PaperReported& r) {
  nlohmann::json out = {{"source", r.source}};
  out["figure1"] = nlohmann::json::object();
  for (const auto& [k, v] : r.figure1) out["figure1"][k] = v;
  out["opencl_vs_cuda"] = nlohmann::json::object();
  for (const auto& [k, v] : r.opencl_vs_cuda) out["opencl_vs_cuda"][k] = v;
  out["opencl_vs_glsl"] = nlohmann::json::object();
  for (const auto& [k, v] : r.opencl_vs_glsl) out["opencl_vs_glsl"][k] = v;
  return out;
}

}  // namespace

const char* Name(PaperApi api) { return ApiRow(static_cast<std::size_t>(api)).api; }

const char* DisplayName(PaperApi api) { return ApiRow(static_cast<std::size_t>(api)).api_title; }

const std::map<std::string, double>& ReportedAgainst(const PaperReported& reported, PaperApi other) {
  static const std::map<std::string, double> none;
  if (other == PaperApi::kCuda) return reported.opencl_vs_cuda;
  if (other == PaperApi::kGlsl) return reported.opencl_vs_glsl;
  return none;
}

std::vector<PaperKernel> PaperKernelsFromJson(const nlohmann::json& list, const std::string& context) {
  if (!list.is_array() || list.empty()) throw Error(context + ": paper_kernels: expected a non-empty list");
  std::vector<PaperKernel> out;
  for (std::size_t i = 0; i < list.size(); ++i) {
    out.push_back(At(context, "paper_kernels[" + std::to_string(i) + "]", [&] {
      const nlohmann::json& k = list[i];
      if (!k.is_object()) throw Error("expected an object");
      PaperKernel kernel;
      kernel.name = String(k, "name");
      kernel.label = String(k, "label");
      kernel.section = OptionalString(k, "section");
      kernel.description = OptionalString(k, "description");
      kernel.variant = ParseVariantKey(String(k, "variant"));
      for (const PaperKernel& other : out) {
        if (other.name == kernel.name) throw Error("the name '" + kernel.name + "' is used twice");
      }
      return kernel;
    }));
  }
  return out;
}

std::vector<PaperKernel> PaperKernels() {
  return PaperKernelsFromJson(PaperConfig().at("paper_kernels"), "configs/paper.json");
}

PaperReported PaperReportedFromJson(const nlohmann::json& in, const std::string& context) {
  const std::string where = context + ": reported";
  if (!in.is_object()) throw Error(where + ": expected an object");
  PaperReported r;
  r.source = At(where, "source", [&] { return OptionalString(in, "source"); });
  if (in.contains("figure1")) r.figure1 = Figures(in["figure1"], where + ".figure1");
  if (in.contains("opencl_vs_cuda")) r.opencl_vs_cuda = Figures(in["opencl_vs_cuda"], where + ".opencl_vs_cuda");
  if (in.contains("opencl_vs_glsl")) r.opencl_vs_glsl = Figures(in["opencl_vs_glsl"], where + ".opencl_vs_glsl");
  return r;
}

PaperReported BuiltInPaperReported() { return PaperReportedFromJson(PaperConfig().at("reported"), "configs/paper.json"); }

std::vector<std::string> PaperDatasets(bool quick) {
  std::vector<std::string> keys;
  const std::vector<std::string> sizes =
      quick ? std::vector<std::string>{"25k", "100k"} : std::vector<std::string>{"25k", "100k", "400k", "1600k"};
  for (const std::string& size : sizes) {
    for (int b = 1; b <= 4; ++b) keys.push_back(size + "-b" + std::to_string(b));
  }
  return keys;
}

nlohmann::json PaperResultToJson(const PaperResult& result) {
  nlohmann::json out;
  out["schema_version"] = kPaperResultSchemaVersion;
  out["kind"] = kPaperResultKind;
  out["created"] = result.created;
  out["quick"] = result.quick;
  out["command"] = result.command;
  out["figure1_dataset"] = result.figure1_dataset;
  out["host"] = {{"cpu_model", result.host.cpu_model},
                 {"threads", result.host.threads},
                 {"copy_bandwidth_gbps", result.host.copy_bandwidth_gbps}};
  out["reported"] = ReportedJson(result.reported);
  out["paper_kernels"] = nlohmann::json::array();
  for (const PaperKernel& k : result.paper_kernels) {
    out["paper_kernels"].push_back({{"name", k.name},
                                    {"label", k.label},
                                    {"section", k.section},
                                    {"description", k.description},
                                    {"variant", k.variant.Key()}});
  }
  out["cpu"] = nlohmann::json::array();
  for (const CpuResult& c : result.cpu) {
    out["cpu"].push_back({{"dataset", c.dataset}, {"serial", CpuTimingJson(c.serial)}, {"fast", CpuTimingJson(c.fast)}});
  }
  out["tuning"] = ReportToJson(result.tuning);
  return out;
}

PaperResult PaperResultFromJson(const nlohmann::json& json, const std::string& context) {
  CheckHeader(json, context, kPaperResultKind, kPaperResultSchemaVersion);
  PaperResult r;
  r.created = At(context, "created", [&] { return String(json, "created"); });
  r.quick = At(context, "quick", [&] {
    const nlohmann::json& q = Field(json, "quick");
    if (!q.is_boolean()) throw Error("must be true or false");
    return q.get<bool>();
  });
  r.command = At(context, "command", [&] { return OptionalString(json, "command"); });
  r.figure1_dataset = At(context, "figure1_dataset", [&] { return String(json, "figure1_dataset"); });
  r.host = At(context, "host", [&] {
    const nlohmann::json& h = Field(json, "host");
    if (!h.is_object()) throw Error("expected an object");
    HostInfo host;
    host.cpu_model = String(h, "cpu_model");
    const std::int64_t threads = Integer(h, "threads");
    if (threads < 0) throw Error("'threads' must not be negative");
    host.threads = static_cast<unsigned>(threads);
    host.copy_bandwidth_gbps = Number(h, "copy_bandwidth_gbps");  // 0: not measured (--no-cpu)
    if (const std::string problem = NotFiniteNonNegative("copy_bandwidth_gbps", host.copy_bandwidth_gbps);
        !problem.empty())
      throw Error("impossible figures: " + problem);
    return host;
  });
  r.reported = PaperReportedFromJson(At(context, "reported", [&]() -> const nlohmann::json& { return Field(json, "reported"); }),
                                     context);
  r.paper_kernels =
      PaperKernelsFromJson(At(context, "paper_kernels", [&]() -> const nlohmann::json& { return Field(json, "paper_kernels"); }),
                           context);
  r.tuning = ReportFromJson(At(context, "tuning", [&]() -> const nlohmann::json& { return Field(json, "tuning"); }),
                            context + ": tuning");
  const nlohmann::json& cpu = At(context, "cpu", [&]() -> const nlohmann::json& { return Array(json, "cpu"); });
  for (std::size_t i = 0; i < cpu.size(); ++i) {
    r.cpu.push_back(At(context, "cpu[" + std::to_string(i) + "]", [&] {
      const nlohmann::json& c = cpu[i];
      if (!c.is_object()) throw Error("expected an object");
      CpuResult out;
      out.dataset = String(c, "dataset");
      bool known = false;
      for (const DatasetInfo& d : r.tuning.datasets) known = known || d.key == out.dataset;
      if (!known) throw Error("dataset '" + out.dataset + "' is not in tuning.datasets");
      for (const char* name : {"serial", "fast"}) {
        try {
          (std::string(name) == "serial" ? out.serial : out.fast) = CpuTimingFromJson(Field(c, name));
        } catch (const Error& e) {
          throw Error(std::string(name) + ": " + e.what());
        }
      }
      return out;
    }));
  }
  return r;
}

}  // namespace skintune::internal
