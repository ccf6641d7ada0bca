// skintune: the paper experiment's results as the paper's figures (Summarise)
// and the number formats of the reports. The renderers are in
// paper_report_html.cpp and paper_report_markdown.cpp.
#include "report/paper_report.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

#include <nlohmann/json.hpp>

#include "generator/axes.h"
#include "runtime/backend_table.h"
#include "runtime/winners_db.h"

namespace skintune::internal {

namespace {

// The API of a backend's languages (gl: glsl), from the table of APIs and
// the language table; `otherwise` for a backend this build does not know.
PaperApi ApiOfBackend(const std::string& backend, PaperApi otherwise) {
  const BackendEntry* entry = FindBackend(backend);
  return entry && !entry->languages.empty() ? ApiOf(entry->languages.front()) : otherwise;
}

std::string Trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) return "";
  return s.substr(first, s.find_last_not_of(" \t\r\n") - first + 1);
}

std::string ChipOf(const DeviceIdentity& d) {
  // Every CPU-type device of a result runs on that result's host (PoCL and
  // llvmpipe both name the CPU in their own way, so names cannot pair them).
  if (d.type == "cpu") return "host CPU";
  std::string name = d.name.substr(0, d.name.find('/'));
  std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return std::tolower(c); });
  return Trim(name);
}

std::string DeviceLabel(const DeviceIdentity& d, PaperApi api, const std::string& run) {
  std::string label = run.empty() ? "" : run + ": ";
  label += d.name + " \xC2\xB7 " + DisplayName(api);
  if (d.backend == "gl") {
    if (!d.platform.empty()) label += " on EGL " + d.platform;
  } else if (!d.platform.empty() && d.platform != DisplayName(api)) {
    label += " on " + d.platform;
  }
  return label;
}

std::string MachineValue(const nlohmann::json& v) { return v.is_string() ? v.get<std::string>() : v.dump(); }

double CopyFraction(double gbps, double copy) { return copy > 0.0 ? gbps / copy : 0.0; }

KernelOutcome OutcomeOf(const Measurement& m, double copy, std::uint64_t llc = 0) {
  KernelOutcome o;
  o.measured = true;
  o.variant = m.variant;
  o.status = m.status;
  o.detail = m.detail;
  if (m.status == MeasureStatus::kOk) {
    o.median_ms = m.timing.median_ms;
    o.frame_ms = m.timing.frame_ms;
    o.gbps = m.gbps;
    o.copy_fraction = CopyFraction(m.gbps, copy);
    o.x_copy = m.x_copy;
    // Timing version 5 flushes the cache before every sample: never partly cached.
    o.partly_cached = llc > 0 && m.timing.flush_bytes == 0.0 && m.timing.footprint_bytes > 0.0 &&
                      m.timing.footprint_bytes < 2.0 * static_cast<double>(llc);
    o.max_relative_error = m.max_relative_error;
    o.source_error = m.source_error;
  }
  return o;
}

// The series of the paper's Fig. 1 a paper kernel on a device stands for.
std::string SeriesOf(const PaperKernel& kernel, const SummaryDevice& device) {
  const bool gpu = device.identity.type == "gpu";
  if (gpu && kernel.name == "glsl-vertex") return "glsl";
  if (gpu && (kernel.name == "cuda" || kernel.name == "opencl-unoptimised" || kernel.name == "opencl-optimised")) {
    return kernel.name;
  }
  if (device.identity.type == "cpu" && device.api == PaperApi::kOpenCl && kernel.name == "opencl-optimised") {
    return "opencl-cpu";
  }
  return "";
}

std::string Note(const KernelOutcome& o, std::size_t measurements) {
  if (o.Ok()) return "";
  if (o.name == "tuned") {
    return measurements == 0 ? "not measured"
                             : "no variant passed (" + std::to_string(measurements) + " failed or invalid)";
  }
  if (!o.measured) return "not measured";
  return std::string(Name(o.status)) + (o.detail.empty() ? "" : ": " + o.detail);
}

// The charted axes of the table (generator/axes.h); an axis glued to the next
// one (vertices_per_item + assignment) is charted with it, as "2 strided".
std::vector<std::size_t> ChartedAxes() {
  std::vector<std::size_t> charted;
  for (std::size_t i = 0; i < kAxisCount; ++i)
    if (kAxes[i].chart == Chart::kYes && !kAxes[i].joins_previous) charted.push_back(i);
  return charted;
}

std::string ChartName(std::size_t i) {
  return std::string(kAxes[i].name) + (JoinsNext(i) ? std::string("+") + kAxes[i + 1].name : "");
}

// A variant's value on chart axis i: its label, and its order within the axis.
std::pair<std::string, int> ChartValue(std::size_t i, const Variant& v) {
  const int code = kAxes[i].Get(v);
  if (!JoinsNext(i)) return {ValueLabel(kAxes[i], code), code};
  const Axis& next = kAxes[i + 1];
  return {ValueLabel(kAxes[i], code) + " " + ValueLabel(next, next.Get(v)),
          code * static_cast<int>(next.values.size()) + next.Get(v)};
}

// Everything Summarise derives from one result, appended to `s`.
class ResultSummariser {
 public:
  ResultSummariser(const PaperResult& r, std::size_t index, bool several, PaperSummary& s)
      : r_(r), index_(index), s_(s) {
    SummaryResult info;
    info.label = several ? "run " + std::to_string(index + 1) : "";
    info.created = r.created;
    info.command = r.command;
    info.quick = r.quick;
    info.figure1_dataset = r.figure1_dataset;
    info.config = r.tuning.config;
    info.strategy = r.tuning.strategy;
    if (r.tuning.machine.is_object()) {
      for (const auto& [key, value] : r.tuning.machine.items()) info.machine.emplace_back(key, MachineValue(value));
    }
    info.host = r.host;
    info.reported = r.reported;
    info.paper_kernels = r.paper_kernels;
    info.cpu = r.cpu;
    info.datasets = r.tuning.datasets;
    info.skipped = r.tuning.skipped;
    s_.results.push_back(std::move(info));
    for (const Measurement& m : r.tuning.measurements) by_device_dataset_[{m.device_id, m.dataset}].push_back(&m);
  }

  void Run() {
    Devices();
    Kernels();
    Figure();
    Tables(PaperApi::kCuda, s_.opencl_vs_cuda);
    Tables(PaperApi::kGlsl, s_.opencl_vs_glsl);
    Tables(PaperApi::kVulkan, s_.opencl_vs_vulkan);
    for (std::size_t d = first_device_; d < s_.devices.size(); ++d) {
      Gbps(d);
      AxisCharts(d);
      Rows(d);
    }
  }

 private:
  const std::vector<const Measurement*>& Of(const std::string& device_id, const std::string& dataset) const {
    static const std::vector<const Measurement*> none;
    const auto it = by_device_dataset_.find({device_id, dataset});
    return it == by_device_dataset_.end() ? none : it->second;
  }

  void Devices() {
    first_device_ = s_.devices.size();
    for (const DeviceIdentity& identity : r_.tuning.devices) {
      SummaryDevice d;
      d.result = index_;
      d.identity = identity;
      d.id = identity.Id();
      std::set<Lang> langs;
      for (const Measurement& m : r_.tuning.measurements) {
        if (m.device_id == d.id) langs.insert(m.variant.lang);
      }
      d.langs.assign(langs.begin(), langs.end());
      d.api = ApiOfBackend(identity.backend, langs.empty() ? PaperApi::kOpenCl : ApiOf(*langs.begin()));
      d.chip = ChipOf(identity);
      d.label = DeviceLabel(identity, d.api, s_.results[index_].label);
      const auto copy = r_.tuning.copy_bandwidth_gbps.find(d.id);
      d.copy_bandwidth_gbps = copy == r_.tuning.copy_bandwidth_gbps.end() ? 0.0 : copy->second;
      s_.devices.push_back(std::move(d));
    }
  }

  void Kernels() {
    for (std::size_t d = first_device_; d < s_.devices.size(); ++d) {
      const SummaryDevice& device = s_.devices[d];
      for (const DatasetInfo& dataset : r_.tuning.datasets) {
        KernelResults k;
        k.device = d;
        k.api = device.api;
        k.dataset = dataset.key;
        k.vertices = dataset.vertices;
        k.influences = dataset.influences;
        const std::vector<const Measurement*>& measured = Of(device.id, dataset.key);
        for (const PaperKernel& kernel : r_.paper_kernels) {
          if (ApiOf(kernel.variant.lang) != device.api) continue;
          Variant wanted = kernel.variant;
          wanted.influences = dataset.influences;
          // A status-ok measurement if there is one (a resumed run may hold
          // the same variant twice), else the first.
          const Measurement* found = nullptr;
          for (const Measurement* m : measured) {
            if (m->variant != wanted) continue;
            if (found == nullptr || (found->status != MeasureStatus::kOk && m->status == MeasureStatus::kOk)) found = m;
          }
          KernelOutcome o = found ? OutcomeOf(*found, device.copy_bandwidth_gbps, device.identity.last_level_cache_bytes) : KernelOutcome{};
          if (!found) o.variant = wanted;
          o.name = kernel.name;
          o.label = kernel.label;
          k.paper.push_back(std::move(o));
        }
        const Measurement* best = nullptr;
        for (const Measurement* m : measured) {
          if (ApiOf(m->variant.lang) != device.api) continue;
          ++k.measurements;
          if (m->status != MeasureStatus::kOk) continue;
          ++k.ok;
          if (best == nullptr || m->timing.median_ms < best->timing.median_ms) best = m;
        }
        if (best) k.tuned = OutcomeOf(*best, device.copy_bandwidth_gbps, device.identity.last_level_cache_bytes);
        k.tuned.name = "tuned";
        k.tuned.label = std::string(DisplayName(device.api)) + " tuned" +
                        (best ? std::string(" (") + Name(best->variant.lang) + ")" : "");
        s_.kernels.push_back(std::move(k));
      }
    }
  }

  void Figure() {
    Figure1 f;
    f.result = index_;
    f.dataset = r_.figure1_dataset;
    for (const DatasetInfo& d : r_.tuning.datasets) {
      if (d.key == f.dataset) {
        f.vertices = d.vertices;
        f.influences = d.influences;
        break;
      }
    }
    for (const CpuResult& c : r_.cpu) {
      if (c.dataset != f.dataset) continue;
      f.serial_ms = c.serial.median_ms;
      Figure1Row serial;
      serial.kind = "serial";
      serial.label = "CPU serial (" + std::to_string(c.serial.threads) + " thread" +
                     (c.serial.threads == 1 ? "" : "s") + ", the paper's baseline)";
      serial.median_ms = c.serial.median_ms;
      serial.speedup = 1.0;
      f.rows.push_back(serial);
      Figure1Row fast;
      fast.kind = "fast";
      fast.label = "CPU fast (" + std::to_string(c.fast.threads) + " threads)";
      fast.median_ms = c.fast.median_ms;
      if (c.fast.median_ms > 0.0) fast.speedup = c.serial.median_ms / c.fast.median_ms;
      f.rows.push_back(fast);
      break;
    }
    std::set<std::string> matched;
    for (std::size_t d = first_device_; d < s_.devices.size(); ++d) {
      const SummaryDevice& device = s_.devices[d];
      const KernelResults* k = s_.Kernels(d, f.dataset);
      auto row_of = [&](const KernelOutcome& o, const std::string& kind, std::size_t measurements) {
        Figure1Row row;
        row.kind = kind;
        row.label = o.label;
        row.device = d;
        row.api = device.api;
        if (o.measured) row.variant = o.variant.Key();
        if (o.Ok()) {
          row.median_ms = o.median_ms;
          if (f.serial_ms && o.median_ms > 0.0) row.speedup = *f.serial_ms / o.median_ms;
        }
        row.note = Note(o, measurements);
        return row;
      };
      std::size_t p = 0;
      for (const PaperKernel& kernel : r_.paper_kernels) {
        if (ApiOf(kernel.variant.lang) != device.api) continue;
        KernelOutcome missing;
        missing.name = kernel.name;
        missing.label = kernel.label;
        Figure1Row r = row_of(k ? k->paper[p++] : missing, "paper", 0);
        r.kernel = kernel.name;
        r.series = SeriesOf(kernel, device);
        if (!r.series.empty()) {
          const auto it = r_.reported.figure1.find(r.series);
          if (it != r_.reported.figure1.end()) {
            r.reported = it->second;
            matched.insert(r.series);
          }
        }
        f.rows.push_back(std::move(r));
      }
      KernelOutcome no_tuned;
      no_tuned.name = "tuned";
      no_tuned.label = std::string(DisplayName(device.api)) + " tuned";
      f.rows.push_back(row_of(k ? k->tuned : no_tuned, "tuned", k ? k->measurements : 0));
    }
    for (const auto& [series, figure] : r_.reported.figure1) {
      if (!matched.count(series)) f.unmatched.emplace_back(series, figure);
    }
    s_.figure1.push_back(std::move(f));
  }

  void Tables(PaperApi other, std::vector<Table1Grid>& out) {
    std::vector<std::size_t> vertices;
    std::vector<int> influences;
    for (const DatasetInfo& d : r_.tuning.datasets) {
      if (std::find(vertices.begin(), vertices.end(), d.vertices) == vertices.end()) vertices.push_back(d.vertices);
      if (std::find(influences.begin(), influences.end(), d.influences) == influences.end()) {
        influences.push_back(d.influences);
      }
    }
    std::sort(vertices.begin(), vertices.end());
    std::sort(influences.begin(), influences.end());
    // The paper kernels compared: the optimised OpenCL kernel (the paper's
    // best OpenCL) against the other API's own kernel.
    int opencl_kernel = -1, other_kernel = -1;
    int api_index[kPaperApiCount] = {};
    for (const PaperKernel& kernel : r_.paper_kernels) {
      const PaperApi api = ApiOf(kernel.variant.lang);
      const int position = api_index[static_cast<int>(api)]++;
      if (api == PaperApi::kOpenCl && kernel.name == "opencl-optimised") opencl_kernel = position;
      if (api == other && other_kernel < 0) other_kernel = position;
    }
    // A device found but never measured (e.g. a run with --lang opencl) has
    // nothing to compare: no grid of dashes for it.
    for (std::size_t o = first_device_; o < s_.devices.size(); ++o) {
      if (s_.devices[o].api != PaperApi::kOpenCl || s_.devices[o].langs.empty()) continue;
      for (std::size_t x = first_device_; x < s_.devices.size(); ++x) {
        if (s_.devices[x].api != other || s_.devices[x].chip != s_.devices[o].chip || s_.devices[x].langs.empty()) {
          continue;
        }
        Table1Grid g;
        g.other = other;
        g.result = index_;
        g.chip = s_.devices[o].chip;
        g.opencl_device = o;
        g.other_device = x;
        g.vertices = vertices;
        g.influences = influences;
        g.cells.assign(vertices.size(), std::vector<std::optional<Table1Cell>>(influences.size()));
        const std::map<std::string, double>& reported = ReportedAgainst(r_.reported, other);
        for (const DatasetInfo& d : r_.tuning.datasets) {
          const std::size_t row = std::find(vertices.begin(), vertices.end(), d.vertices) - vertices.begin();
          const std::size_t column = std::find(influences.begin(), influences.end(), d.influences) - influences.begin();
          if (g.cells[row][column]) continue;  // the first data set of that size and B
          Table1Cell cell;
          cell.dataset = d.key;
          const KernelResults* ko = s_.Kernels(o, d.key);
          const KernelResults* kx = s_.Kernels(x, d.key);
          if (ko && kx && ko->tuned.Ok() && kx->tuned.Ok()) {
            cell.tuned = kx->tuned.median_ms / ko->tuned.median_ms;
            if (kx->tuned.frame_ms > 0.0 && ko->tuned.frame_ms > 0.0) cell.tuned_frame = kx->tuned.frame_ms / ko->tuned.frame_ms;
          }
          if (ko && kx && opencl_kernel >= 0 && other_kernel >= 0 && ko->paper[opencl_kernel].Ok() &&
              kx->paper[other_kernel].Ok()) {
            cell.paper = kx->paper[other_kernel].median_ms / ko->paper[opencl_kernel].median_ms;
          }
          // The paper's Table 1 is its GPU's: its figures stand beside GPU chips only.
          const auto it = reported.find(d.key);
          if (it != reported.end() && g.chip != "host CPU") cell.reported = it->second;
          g.cells[row][column] = std::move(cell);
        }
        out.push_back(std::move(g));
      }
    }
  }

  void Gbps(std::size_t d) {
    const SummaryDevice& device = s_.devices[d];
    GbpsChart chart;
    chart.device = d;
    chart.copy_bandwidth_gbps = device.copy_bandwidth_gbps;
    std::map<std::pair<Lang, int>, GbpsSeries> series;
    for (const DatasetInfo& dataset : r_.tuning.datasets) {
      std::map<Lang, const Measurement*> best;
      std::map<Lang, const Winner*> winner_of;
      for (const Winner& w : chosen_)
        if (w.device_id == device.id && w.dataset == dataset.key && Plain(w)) winner_of[w.lang] = &w;
      for (const Measurement* m : Of(device.id, dataset.key)) {
        if (m->status != MeasureStatus::kOk) continue;
        const auto w = winner_of.find(m->variant.lang);
        if (w != winner_of.end() && w->second->variant.Key() == m->variant.Key()) best[m->variant.lang] = m;
      }
      for (const auto& [lang, m] : best) {
        GbpsSeries& s = series[{lang, dataset.influences}];
        s.lang = lang;
        s.influences = dataset.influences;
        // One point per vertex count: the first data set of that size and B.
        if (std::any_of(s.points.begin(), s.points.end(),
                        [&](const GbpsPoint& p) { return p.vertices == dataset.vertices; })) {
          continue;
        }
        const Winner& w = *winner_of.at(lang);
        s.points.push_back({dataset.key, dataset.vertices, m->gbps, w.median_ms,
                            CopyFraction(m->gbps, device.copy_bandwidth_gbps), m->variant, m->x_copy,
                            m->max_relative_error, m->source_error, w.low_ms, w.high_ms, w.frame_ms,
                            w.tie_set.empty() ? 0 : w.tie_set.size() - 1, w.within_noise});
      }
    }
    for (auto& [key, s] : series) {
      std::sort(s.points.begin(), s.points.end(),
                [](const GbpsPoint& a, const GbpsPoint& b) { return a.vertices < b.vertices; });
      chart.series.push_back(std::move(s));
    }
    s_.gbps.push_back(std::move(chart));
  }

  // RowWinner::animation of `w`, from its measurement.
  std::string AnimationOf(const Winner& w) const {
    if (!AnimatesOnDevice(w.variant)) return "";
    const std::string key = w.variant.Key();
    for (const Measurement* m : Of(w.device_id, w.dataset)) {
      if (m->variant.Key() != key) continue;
      std::string text = std::string(Name(w.variant.animation)) +
                         (FusesPalette(w.variant.animation) ? ": palettes made in the skin launch"
                                                            : ": palette kernel " + FormatMs(m->timing.palette_kernel_ms));
      if (m->baked_clips.empty()) return text;
      double bytes = 0.0, error = 0.0;
      for (const BakedClipRecord& c : m->baked_clips) {
        bytes += c.bytes;
        error = std::max(error, c.max_error);
      }
      std::ostringstream tail;
      tail.precision(2);
      tail << "; " << m->baked_clips.size() << (m->baked_clips.size() == 1 ? " clip, " : " clips, ") << std::fixed
           << bytes / 1e6 << " MB, largest error " << std::scientific << error;
      return text + tail.str();
    }
    return Name(w.variant.animation);
  }

  static bool Plain(const Winner& w) {
    return w.morph_targets == 0 && w.variant.normal_format == NormalFormat::kF32 &&
           w.variant.blend != Blend::kDualQuaternion && !AnimatesOnDevice(w.variant);
  }

  void Rows(std::size_t d) {
    const SummaryDevice& device = s_.devices[d];
    for (const Winner& w : chosen_) {
      if (w.device_id != device.id || !w.within_budget) continue;
      RowWinner r;
      r.device = d;
      r.lang = w.lang;
      r.dataset = w.dataset;
      r.row = RowName(w) + (w.variant.blend == Blend::kDualQuaternion ? " dq" : "");
      r.variant = w.variant.Key();
      r.median_ms = w.median_ms;
      r.low_ms = w.low_ms;
      r.high_ms = w.high_ms;
      r.gbps = w.gbps;
      r.x_copy = w.x_copy;
      r.position_rel = w.source_error.position_rel;
      r.normal_abs = w.source_error.normal_abs;
      r.plain = Plain(w);
      r.animation = AnimationOf(w);
      for (const Winner& p : chosen_) {  // the plain row of the same mesh size and scene
        if (r.plain || !Plain(p) || !p.within_budget || p.device_id != w.device_id || p.lang != w.lang ||
            p.influences != w.influences || p.vertices != w.vertices || p.shape != w.shape ||
            p.instances != w.instances || p.meshes != w.meshes || !(p.median_ms > 0.0))
          continue;
        r.vs_plain = w.median_ms / p.median_ms;
      }
      s_.rows.push_back(std::move(r));
    }
  }

  void AxisCharts(std::size_t d) {
    const SummaryDevice& device = s_.devices[d];
    for (Lang lang : device.langs) {
      // The data set: the largest measured (vertices x influences; ties: the
      // one with most status-ok measurements). Small data sets are bound by
      // launch overhead on a GPU, where no axis shows its cost.
      const DatasetInfo* chosen = nullptr;
      std::size_t chosen_ok = 0;
      auto size = [](const DatasetInfo& info) { return info.vertices * static_cast<std::size_t>(std::max(info.influences, 1)); };
      for (const DatasetInfo& dataset : r_.tuning.datasets) {
        std::size_t ok = 0;
        for (const Measurement* m : Of(device.id, dataset.key)) ok += m->variant.lang == lang && m->status == MeasureStatus::kOk;
        if (ok == 0) continue;
        if (chosen == nullptr || size(dataset) > size(*chosen) ||
            (size(dataset) == size(*chosen) && ok > chosen_ok)) {
          chosen = &dataset;
          chosen_ok = ok;
        }
      }
      if (chosen == nullptr) continue;
      AxisChart chart;
      chart.device = d;
      chart.lang = lang;
      chart.dataset = chosen->key;
      chart.measurements = chosen_ok;
      chart.best_ms = std::numeric_limits<double>::infinity();
      std::vector<const Measurement*> ok;
      for (const Measurement* m : Of(device.id, chosen->key)) {
        if (m->variant.lang != lang || m->status != MeasureStatus::kOk) continue;
        ok.push_back(m);
        chart.best_ms = std::min(chart.best_ms, m->timing.median_ms);
      }
      for (std::size_t axis : ChartedAxes()) {
        std::map<int, AxisValue> values;
        for (const Measurement* m : ok) {
          const auto [label, order] = ChartValue(axis, m->variant);
          auto [it, fresh] = values.try_emplace(order);
          AxisValue& v = it->second;
          if (fresh) {
            v.value = label;
            v.best_ms = m->timing.median_ms;
          }
          v.best_ms = std::min(v.best_ms, m->timing.median_ms);
          ++v.measurements;
        }
        AxisEffect effect;
        effect.axis = ChartName(axis);
        for (auto& [order, v] : values) {
          v.ratio = chart.best_ms > 0.0 ? v.best_ms / chart.best_ms : 1.0;
          effect.values.push_back(std::move(v));
        }
        chart.axes.push_back(std::move(effect));
      }
      s_.axes.push_back(std::move(chart));
    }
  }

  const PaperResult& r_;
  std::size_t index_;
  PaperSummary& s_;
  // The tuner's own choice of each row (the winner among the ties at the
  // run's budget: tuner/report.h BudgetWinners), made once per result.
  const std::vector<Winner> chosen_ = BudgetWinners(ComputeWinners(r_.tuning), r_.tuning.tie_margin);
  std::size_t first_device_ = 0;
  std::map<std::pair<std::string, std::string>, std::vector<const Measurement*>> by_device_dataset_;
};

}  // namespace

const KernelResults* PaperSummary::Kernels(std::size_t device, const std::string& dataset) const {
  for (const KernelResults& k : kernels) {
    if (k.device == device && k.dataset == dataset) return &k;
  }
  return nullptr;
}

PaperSummary Summarise(const std::vector<PaperResult>& results) {
  PaperSummary s;
  for (std::size_t i = 0; i < results.size(); ++i) ResultSummariser(results[i], i, results.size() > 1, s).Run();
  std::vector<double> twists;
  for (int degrees = 0; degrees <= 180; degrees += 15) twists.push_back(degrees);
  if (!results.empty()) s.candy_wrapper = CandyWrapper(twists);
  return s;
}

PaperResult PaperResultFromReport(const TuningReport& report) {
  PaperResult r;
  r.created = report.created;
  // r.command stays empty: a tuning report does not record its command line.
  r.tuning = report;
  r.reported.source = "not a paper result: a plain tuning report, without the paper's kernels or CPU timings";
  const bool has_fig1 = std::any_of(report.datasets.begin(), report.datasets.end(),
                                    [&](const DatasetInfo& d) { return d.key == r.figure1_dataset; });
  if (!has_fig1 && !report.datasets.empty()) {
    // The data set the most devices were measured on, so Fig. 1 compares them.
    std::size_t best = 0;
    r.figure1_dataset = report.datasets.front().key;
    for (const DatasetInfo& d : report.datasets) {
      std::set<std::string> devices;
      for (const Measurement& m : report.measurements) {
        if (m.dataset == d.key) devices.insert(m.device_id);
      }
      if (devices.size() > best) {
        best = devices.size();
        r.figure1_dataset = d.key;
      }
    }
  }
  if (report.machine.is_object()) {
    const nlohmann::json& cpu = report.machine.contains("cpu_model") ? report.machine["cpu_model"] : nlohmann::json();
    if (cpu.is_string()) r.host.cpu_model = cpu.get<std::string>();
    const nlohmann::json& threads =
        report.machine.contains("logical_cpus") ? report.machine["logical_cpus"] : nlohmann::json();
    if (threads.is_number_integer() && threads.get<std::int64_t>() > 0) {
      r.host.threads = static_cast<unsigned>(threads.get<std::int64_t>());
    }
  }
  return r;
}

std::string FormatSignificant(double value, int digits) {
  if (!std::isfinite(value)) return "\xE2\x80\x94";  // an em dash
  if (value == 0.0) return "0";
  const double magnitude = std::fabs(value);
  char text[64];
  // Whole numbers of more digits keep them: "1234", not "1230".
  if (magnitude >= std::pow(10.0, digits - 1)) {
    std::snprintf(text, sizeof text, "%.0f", value);
    return text;
  }
  int exponent = static_cast<int>(std::floor(std::log10(magnitude)));
  const double scale = std::pow(10.0, digits - 1 - exponent);
  const double rounded = std::round(magnitude * scale) / scale;
  exponent = static_cast<int>(std::floor(std::log10(rounded)));  // 9.996 rounds to 10.0
  const int decimals = std::max(0, digits - 1 - exponent);
  std::snprintf(text, sizeof text, "%.*f", decimals, value < 0 ? -rounded : rounded);
  return text;
}

std::string FormatMs(double ms) { return FormatSignificant(ms) + " ms"; }

std::string FormatSpeedup(double factor) { return FormatSignificant(factor) + "\xC3\x97"; }

std::string FormatError(double error) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1e", error);
  return text;
}

std::string FormatSourceError(const SourceError& e) {
  if (!e.known) return "not recorded";
  return FormatError(e.position_rel) + " of the diagonal (weights " + FormatError(e.quantisation_rel) + ")";
}

std::string FormatGbps(double gbps) {
  if (gbps >= 100.0) {
    char text[64];
    std::snprintf(text, sizeof text, "%.0f GB/s", gbps);
    return text;
  }
  return FormatSignificant(gbps) + " GB/s";
}

}  // namespace skintune::internal
