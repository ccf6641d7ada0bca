// skintune: the paper report as Markdown (a terminal, a README, a commit
// message): Fig. 1 and Table 1 as tables, the tuned winners per device, the
// devices.
#include <algorithm>
#include <map>
#include <optional>
#include <string>

#include "report/paper_report.h"

namespace skintune::internal {

namespace {

constexpr const char* kDash = "\xE2\x80\x94";

// A table cell: one line, no column separator.
std::string Cell(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '|') {
      out += "\\|";
    } else if (c == '\n' || c == '\r') {
      out += ' ';
    } else {
      out += c;
    }
  }
  return out;
}

std::string Shortened(const std::string& text, std::size_t limit) {
  return text.size() <= limit ? text : text.substr(0, limit) + "\xE2\x80\xA6";
}

std::string Ratio(const std::optional<double>& v) { return v ? FormatSignificant(*v) : kDash; }

std::string Heading(const SummaryResult& r, const std::string& text) {
  return r.label.empty() ? text : r.label + ": " + text;
}

// Where the paper's figures come from, said once (under Fig. 1, the first
// table printed); the tables after it say only where none is on record.
std::string ReportedNote(const SummaryResult& r, bool any, bool with_source) {
  const std::string source = with_source && !r.reported.source.empty() ? Cell(r.reported.source) : "";
  if (any) return source.empty() ? "" : "The paper's figures: " + source + "\n\n";
  return "The paper's figures: not on record" + (source.empty() ? "." : " (" + source + ")") + "\n\n";
}

std::string Grids(const PaperSummary& s, PaperApi other, const std::vector<Table1Grid>& grids) {
  const std::string name = DisplayName(other);
  std::string out = "### Table 1: OpenCL relative to " + name + " (t_" + name +
                    " / t_OpenCL; above 1: OpenCL faster)\n\n";
  if (grids.empty()) return out + "No chip with both APIs (OpenCL and " + name + ") in these results.\n\n";
  for (const Table1Grid& g : grids) {
    const SummaryResult& r = s.results[g.result];
    const std::map<std::string, double>& reported = ReportedAgainst(r.reported, other);
    out += Cell(s.devices[g.opencl_device].label) + " vs " + Cell(s.devices[g.other_device].label) +
           "; each cell: the tuned winners' kernel time (their frame time) / the paper's kernels" +
           (reported.empty() ? std::string() : " / the paper's figure") + "\n\n";
    out += ReportedNote(r, !reported.empty(), /*with_source=*/false);
    out += "| vertices |";
    for (int b : g.influences) out += " B=" + std::to_string(b) + " |";
    out += "\n| --- |";
    for (std::size_t i = 0; i < g.influences.size(); ++i) out += " --- |";
    out += "\n";
    for (std::size_t row = 0; row < g.vertices.size(); ++row) {
      out += "| " + std::to_string(g.vertices[row]) + " |";
      for (const std::optional<Table1Cell>& cell : g.cells[row]) {
        if (!cell) {
          out += " no such data set |";
          continue;
        }
        out += " " + Ratio(cell->tuned) + " (" + Ratio(cell->tuned_frame) + ") / " + Ratio(cell->paper);
        if (!reported.empty()) {
          out += " / " + (cell->reported ? FormatSignificant(*cell->reported) : std::string("not on record"));
        }
        out += " |";
      }
      out += "\n";
    }
    out += "\n";
  }
  return out;
}

std::string GiBText(std::uint64_t bytes) {
  if (bytes == 0) return "unknown";
  return FormatSignificant(static_cast<double>(bytes) / (1024.0 * 1024.0 * 1024.0)) + " GiB";
}

}  // namespace

std::string Figure1Markdown(const PaperSummary& s) {
  std::string out;
  for (const Figure1& f : s.figure1) {
    const SummaryResult& r = s.results[f.result];
    out += "### " + Cell(Heading(r, "Fig. 1: speedup over the serial CPU, " + f.dataset)) +
           (f.vertices ? " (" + std::to_string(f.vertices) + " vertices, B = " + std::to_string(f.influences) + ")"
                       : " (not in this result)") +
           "\n\n";
    if (!f.serial_ms) {
      out += "No serial baseline: no serial CPU timing of " + Cell(f.dataset) + " in this result, so no speedups.\n\n";
    }
    out += ReportedNote(r, !r.reported.figure1.empty(), /*with_source=*/true);
    out += "| device | implementation | time | speedup | the paper |\n| --- | --- | ---: | ---: | ---: |\n";
    for (const Figure1Row& row : f.rows) {
      const std::string device =
          row.device ? s.devices[*row.device].label : "CPU (" + (r.host.cpu_model.empty() ? "host" : r.host.cpu_model) + ")";
      std::string paper;
      if (row.reported) {
        paper = FormatSpeedup(*row.reported);
      } else if (!row.series.empty()) {
        paper = "not on record";
      }
      out += "| " + Cell(device) + " | " + Cell(row.label) + " | " +
             (row.median_ms ? FormatMs(*row.median_ms) : Cell(Shortened(row.note, 60))) + " | " +
             (row.speedup ? FormatSpeedup(*row.speedup) : std::string(kDash)) + " | " + paper + " |\n";
    }
    for (const auto& [series, figure] : f.unmatched) {
      out += "\nThe paper's figure for " + Cell(series) + ": " + FormatSpeedup(figure) + ", no matching device here.";
    }
    out += "\n";
  }
  return out;
}

std::string Table1Markdown(const PaperSummary& s) {
  return Grids(s, PaperApi::kCuda, s.opencl_vs_cuda) + Grids(s, PaperApi::kGlsl, s.opencl_vs_glsl) +
         Grids(s, PaperApi::kVulkan, s.opencl_vs_vulkan);
}

std::string RenderMarkdown(const PaperSummary& s) {
  std::string out = "# The paper's experiment (GPGPU Acceleration for Skeletal Animation) " +
                    std::string(s.results.size() > 1 ? "on " + std::to_string(s.results.size()) + " runs" : "on one machine") +
                    "\n\n";
  for (const SummaryResult& r : s.results) {
    out += "- " + (r.label.empty() ? std::string() : r.label + ": ") + Cell(r.created) +
           (r.quick ? " (quick)" : "") + ", host " + Cell(r.host.cpu_model.empty() ? "unknown" : r.host.cpu_model) +
           (r.command.empty() ? std::string(", command not recorded") : ", `" + Cell(r.command) + "`") + "\n";
  }
  out += "\n## Fig. 1\n\n" + Figure1Markdown(s) + "## Table 1\n\n" + Table1Markdown(s);
  out += "## Tuned winners per device\n\n"
         "The fastest verified variant per data set; GB/s = bytes the format moves / median time (a crowd's: K "
         "copies of its mesh, which its launch reads once, so it may pass the device's bandwidth); \"x copy\" = "
         "the time over a copy of the same bytes timed the same way (docs/TUNING.md \"Timing\"; * partly from cache: the "
         "rotation covered less than twice the chip's last-level cache); \"of copy\" = GB/s over the device's large "
         "copy; \"vs quantised\" = the largest relative error against the float64 gold of the variant's quantised "
         "weights (the correctness check); \"vs source\" = the largest error against the gold of the unquantised "
         "source, of the bounding-box diagonal, and what the weight format alone costs.\n\n";
  for (std::size_t d = 0; d < s.devices.size(); ++d) {
    const SummaryDevice& device = s.devices[d];
    out += "### " + Cell(device.label) + " (copy " +
           (device.copy_bandwidth_gbps > 0.0 ? FormatGbps(device.copy_bandwidth_gbps) : std::string("not measured")) +
           ")\n\n| data set | tuned winner | time | GB/s | x copy | of copy | vs quantised | vs source | the paper's kernels |\n"
           "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |\n";
    for (const KernelResults& k : s.kernels) {
      if (k.device != d) continue;
      std::string paper;
      for (const KernelOutcome& o : k.paper) {
        if (!paper.empty()) paper += "; ";
        paper += o.label + ": " +
                 (o.Ok() ? FormatMs(o.median_ms) : !o.measured ? std::string("not measured")
                                                               : Shortened(std::string(Name(o.status)) + (o.detail.empty() ? "" : " (" + o.detail + ")"), 60));
      }
      if (k.tuned.Ok()) {
        out += "| " + Cell(k.dataset) + " | " + Cell(k.tuned.label) + " `" + Cell(k.tuned.variant.Key()) + "` | " +
               FormatMs(k.tuned.median_ms) + " | " + FormatGbps(k.tuned.gbps) + " | " +
               (k.tuned.x_copy > 0.0 ? FormatSignificant(k.tuned.x_copy, 3) + (k.tuned.partly_cached ? "*" : "")
                                     : std::string(kDash)) +
               " | " + (k.tuned.copy_fraction > 0.0 ? FormatSignificant(k.tuned.copy_fraction, 2) : std::string(kDash)) +
               " | " + FormatError(k.tuned.max_relative_error) + " | " +
               Cell(FormatSourceError(k.tuned.source_error)) + " | " + Cell(paper) + " |\n";
      } else {
        out += "| " + Cell(k.dataset) + " | " +
               (k.measurements == 0 ? std::string("not measured")
                                    : "no variant passed (" + std::to_string(k.measurements) + " failed or invalid)") +
               " | " + kDash + " | " + kDash + " | " + kDash + " | " + kDash + " | " + kDash + " | " + kDash + " | " +
               Cell(paper) + " |\n";
      }
    }
    out += "\n";
  }
  // Every row the user chooses beside its plain row (PaperSummary::rows), as the HTML's "Every row".
  std::string rows;
  for (const RowWinner& r : s.rows) {
    if (r.plain) continue;
    rows += "| " + Cell(s.devices[r.device].label) + " | " + Name(r.lang) + " | " + Cell(r.dataset) + " | " +
            Cell(r.row + (r.animation.empty() ? "" : " (" + r.animation + ")")) + " | " + FormatMs(r.median_ms) + " | " +
            (r.x_copy > 0.0 ? FormatSignificant(r.x_copy, 3) : std::string(kDash)) + " | " +
            FormatError(r.position_rel) + ", " + FormatError(r.normal_abs) + " | " +
            (r.vs_plain > 0.0 ? FormatSignificant(r.vs_plain, 3) : std::string("no plain row")) + " | `" +
            Cell(r.variant) + "` |\n";
  }
  if (!rows.empty())
    out += "## Every row\n\nEach row the user chooses (normals written packed, morph targets, dual quaternions, "
           "palettes made on the device) "
           "beside its plain row's winner on the same device, language and mesh: x plain = its time over that "
           "winner's; error = positions against the unquantised source (of the diagonal), normals (unit "
           "vectors).\n\n| device | language | data set | row | time | x copy | error | x plain | tuned winner |\n"
           "| --- | --- | --- | --- | ---: | ---: | ---: | ---: | --- |\n" +
           rows + "\n";
  out += "## Devices\n\n| backend | platform | name | vendor | driver | API version | type | compute units | memory | "
         "last-level cache | copy |\n| --- | --- | --- | --- | --- | --- | --- | ---: | ---: | ---: | ---: |\n";
  for (const SummaryDevice& d : s.devices) {
    const DeviceIdentity& i = d.identity;
    out += "| " + Cell(i.backend) + " | " + Cell(i.platform) + " | " + Cell(i.name) + " | " + Cell(i.vendor) + " | " +
           Cell(i.driver_version) + " | " + Cell(i.api_version) + " | " + Cell(i.type) + " | " +
           std::to_string(i.compute_units) + " | " + GiBText(i.global_memory_bytes) + " | " +
           (i.last_level_cache_bytes ? FormatSignificant(static_cast<double>(i.last_level_cache_bytes) / 1048576.0) + " MiB" +
                                           (i.last_level_cache_source.empty() ? "" : " (" + Cell(i.last_level_cache_source) + ")")
                                     : std::string("unknown")) +
           " | " + (d.copy_bandwidth_gbps > 0.0 ? FormatGbps(d.copy_bandwidth_gbps) : std::string("not measured")) +
           " |\n";
  }
  out += "\n";
  for (const SummaryResult& r : s.results) {
    out += "- " + (r.label.empty() ? std::string() : r.label + ": ") + "host CPU " +
           Cell(r.host.cpu_model.empty() ? "unknown" : r.host.cpu_model) + ", " + std::to_string(r.host.threads) +
           " threads, copy " +
           (r.host.copy_bandwidth_gbps > 0.0 ? FormatGbps(r.host.copy_bandwidth_gbps) : std::string("not measured")) +
           "\n";
    for (const std::string& skipped : r.skipped) out += "- skipped: " + Cell(skipped) + "\n";
  }
  return out;
}

}  // namespace skintune::internal
