// skintune: the paper report as one self-contained HTML5 page.
//
// The page is meant to be committed next to the results, mailed and opened
// offline years later, so it depends on nothing: inline CSS, charts as inline
// SVG drawn here, no script, no web font, no link, no URL. Every text that
// comes from the input (device names, driver strings, details of failures,
// the command line) goes through Esc, which also writes '/' and ':' as
// character references so that no input text can form something that looks
// like a URL in the file ("https://", "//host").
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <string>
#include <string_view>

#include "report/paper_report.h"

namespace skintune::internal {

namespace {

std::string Esc(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      case '/': out += "&#47;"; break;
      case ':': out += "&#58;"; break;
      default: out += c;
    }
  }
  return out;
}

// At most `limit` characters (a failure's detail can be a whole build log).
std::string Cut(const std::string& text, std::size_t limit) {
  std::string one_line = text.substr(0, text.find('\n'));
  if (one_line.size() <= limit) return one_line;
  return one_line.substr(0, limit) + "\xE2\x80\xA6";
}

// The characters an escaped text shows (an entity is one), for laying out legends.
std::size_t Visible(std::string_view escaped) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < escaped.size(); ++i, ++n) {
    if (escaped[i] == '&') {
      const std::size_t end = escaped.find(';', i);
      if (end != std::string_view::npos) i = end;
    } else {
      while (i + 1 < escaped.size() && (static_cast<unsigned char>(escaped[i + 1]) & 0xC0) == 0x80) ++i;  // UTF-8
    }
  }
  return n;
}

// A coordinate for SVG.
std::string C(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f", v);
  return text;
}

// A switch, not a column of the language table: colours are the report's
// choice, and -Wswitch names an API that has none.
const char* ApiColour(PaperApi api) {
  switch (api) {
    case PaperApi::kOpenCl: return "#2563eb";
    case PaperApi::kCuda: return "#16a34a";
    case PaperApi::kGlsl: return "#ea580c";
    case PaperApi::kVulkan: return "#9333ea";
    case PaperApi::kCpu: return "#0f766e";  // the cpu device (the fast path's kernels), not the CPU baselines' grey
  }
  return "#6b7280";
}

constexpr const char* kCpuColour = "#6b7280";

// Colours of the lines per B in the GB/s charts (B = 1.. cycles).
constexpr const char* kBColours[] = {"#2563eb", "#16a34a", "#ea580c", "#9333ea",
                                     "#0891b2", "#be123c", "#4d7c0f", "#a16207"};

const char* BColour(int influences) { return kBColours[(std::max(influences, 1) - 1) % 8]; }

// "25k", "100k", "1.6M", "2500".
std::string Vertices(std::size_t n) {
  auto shortest = [](double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%.3g", v);
    return std::string(text);
  };
  if (n >= 1000000 && n % 10000 == 0) return shortest(static_cast<double>(n) / 1e6) + "M";
  if (n >= 1000 && n % 1000 == 0) return shortest(static_cast<double>(n) / 1e3) + "k";
  return std::to_string(n);
}

// A tick label: as short as it can be ("0.1", "2", "500", "1.25").
std::string Tick(double v) {
  if (v >= 1000.0 || (v > 0.0 && v < 0.001)) return FormatSignificant(v, 1);  // no "1e+03"
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", v);
  return text;
}

std::string Bytes(std::uint64_t bytes) {
  if (bytes == 0) return "unknown";
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double v = static_cast<double>(bytes);
  int u = 0;
  while (v >= 1024.0 && u < 4) {
    v /= 1024.0;
    ++u;
  }
  return FormatSignificant(v) + " " + units[u];
}

std::string Fraction(double f) { return FormatSignificant(f, 2); }

std::string Scientific(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1e", v);
  return text;
}

// Log-scale ticks 1, 2, 5 x 10^k within [lo, hi].
std::vector<double> LogTicks(double lo, double hi) {
  std::vector<double> ticks;
  for (int k = static_cast<int>(std::floor(std::log10(lo))); k <= static_cast<int>(std::ceil(std::log10(hi))); ++k) {
    for (double m : {1.0, 2.0, 5.0}) {
      const double v = m * std::pow(10.0, k);
      if (v >= lo * 0.999 && v <= hi * 1.001) ticks.push_back(v);
    }
  }
  return ticks;
}

// [lo, hi] widened to whole decades around every value.
// Only positive, finite values have a place on a log axis (the readers refuse
// any other time; this keeps a chart bounded whatever it is given).
std::pair<double, double> Decades(const std::vector<double>& all) {
  std::vector<double> values;
  for (double v : all)
    if (std::isfinite(v) && v > 0.0) values.push_back(v);
  if (values.empty()) values = {0.001, 1.0};
  double lo = *std::min_element(values.begin(), values.end());
  double hi = *std::max_element(values.begin(), values.end());
  lo = std::pow(10.0, std::floor(std::log10(lo)));
  hi = std::pow(10.0, std::ceil(std::log10(hi)));
  if (hi <= lo) hi = lo * 10.0;
  return {lo, hi};
}

struct LogScale {
  double lo, hi, x0, x1;
  double operator()(double v) const {
    const double t = (std::log10(std::clamp(v, lo, hi)) - std::log10(lo)) / (std::log10(hi) - std::log10(lo));
    return x0 + t * (x1 - x0);
  }
};

std::string SvgOpen(const std::string& id, double width, double height, const std::string& title) {
  return "<svg id=\"" + id + "\" class=\"chart\" role=\"img\" width=\"" + C(width) + "\" height=\"" + C(height) +
         "\" viewBox=\"0 0 " + C(width) + " " + C(height) + "\" aria-labelledby=\"" + id + "-title\"><title id=\"" +
         id + "-title\">" + title + "</title>";
}

std::string Text(double x, double y, const std::string& escaped, const std::string& attributes = "") {
  return "<text x=\"" + C(x) + "\" y=\"" + C(y) + "\"" + (attributes.empty() ? "" : " " + attributes) + ">" +
         escaped + "</text>";
}

std::string Line(double x1, double y1, double x2, double y2, const std::string& attributes) {
  return "<line x1=\"" + C(x1) + "\" y1=\"" + C(y1) + "\" x2=\"" + C(x2) + "\" y2=\"" + C(y2) + "\" " + attributes +
         "/>";
}

std::string Rect(double x, double y, double w, double h, const std::string& attributes) {
  return "<rect x=\"" + C(x) + "\" y=\"" + C(y) + "\" width=\"" + C(w) + "\" height=\"" + C(h) + "\" " +
         attributes + "/>";
}

std::string Diamond(double x, double y, double r, const std::string& attributes) {
  return "<path d=\"M" + C(x) + " " + C(y - r) + "L" + C(x + r) + " " + C(y) + "L" + C(x) + " " + C(y + r) + "L" +
         C(x - r) + " " + C(y) + "Z\" " + attributes + "/>";
}

const char* kCss = R"css(
*{box-sizing:border-box}
body{margin:0;background:#eef0f3;color:#1f2328;font:15px/1.5 system-ui,sans-serif}
main{max-width:1200px;margin:0 auto;padding:24px 32px 56px;background:#fff;min-height:100vh}
h1{font-size:26px;line-height:1.25;margin:0 0 6px}
h2{font-size:20px;margin:40px 0 8px;padding-bottom:4px;border-bottom:2px solid #e5e7eb}
h3{font-size:16px;margin:24px 0 4px}
p{margin:6px 0 10px;max-width:980px}
.lead{color:#57606a}
nav{margin:12px 0 0;padding:8px 0;border-top:1px solid #e5e7eb;border-bottom:1px solid #e5e7eb}
nav a{margin-right:18px;color:#0b5cad;text-decoration:none;font-weight:600}
.note{color:#57606a;font-size:14px}
.warn{background:#fff8e6;border-left:4px solid #e3a008;padding:6px 12px;max-width:980px}
table{border-collapse:collapse;margin:8px 0 18px;font-size:14px;display:block;max-width:100%;overflow-x:auto}
td code{word-break:break-all}
th,td{border:1px solid #d8dee4;padding:4px 8px;text-align:left;vertical-align:top}
th{background:#f3f4f6;font-weight:600}
td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
table.grid td{min-width:170px;font-variant-numeric:tabular-nums}
table.grid td.faster{background:#e7f5ec}
table.grid td.slower{background:#fdeceb}
table.grid td.even{background:#f6f8fa}
table.grid td.none{background:#fafafa;color:#8c959f}
.gt{color:#1a7f37;font-weight:600}
.lt{color:#b42318;font-weight:600}
.eq{color:#57606a;font-weight:600}
.muted{color:#8c959f}
svg.chart{display:block;margin:6px 0 18px;max-width:100%;height:auto;background:#fff}
svg.chart text{font-family:system-ui,sans-serif;fill:#1f2328}
svg.chart .small{font-size:11px}
svg.chart .label{font-size:12.5px}
svg.chart .head{font-size:13px;font-weight:600}
svg.chart .value{font-size:12px;font-variant-numeric:tabular-nums}
svg.chart .missing{font-size:12px;font-style:italic;fill:#8c959f}
.charts{display:grid;grid-template-columns:repeat(auto-fill,minmax(520px,1fr));gap:4px 24px}
figure{margin:0}
figcaption{font-size:14px;color:#57606a;margin-top:14px}
code{font:12.5px ui-monospace,monospace;background:#f3f4f6;padding:1px 4px;border-radius:3px;word-break:break-all}
footer{margin-top:40px;color:#8c959f;font-size:13px}
)css";

class Renderer {
 public:
  explicit Renderer(const PaperSummary& s) : s_(s) {}

  std::string Render() {
    out_ += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
            "<title>skintune: the paper&#39;s experiment, Fig. 1 and Table 1 reproduced</title>\n<style>";
    out_ += kCss;
    out_ += "</style>\n</head>\n<body>\n<main>\n";
    Header();
    Figure1Section();
    Table1Section(PaperApi::kCuda, s_.opencl_vs_cuda, "table1-opencl-vs-cuda");
    Table1Section(PaperApi::kGlsl, s_.opencl_vs_glsl, "table1-opencl-vs-glsl");
    Table1Section(PaperApi::kVulkan, s_.opencl_vs_vulkan, "table1-opencl-vs-vulkan");
    GbpsSection();
    AxesSection();
    RowsSection();
    CandyWrapperSection();
    DevicesSection();
    out_ += "<footer>Written by <code>skintune report</code>. Self-contained: no script, no external resource.</footer>\n";
    out_ += "</main>\n</body>\n</html>\n";
    return std::move(out_);
  }

 private:
  const std::string& Label(std::size_t device) const { return s_.devices[device].label; }

  void Header() {
    out_ += "<h1>GPGPU Acceleration for Skeletal Animation, reproduced</h1>\n";
    out_ += "<p class=\"lead\">The paper <em>GPGPU Acceleration for Skeletal Animation \xE2\x80\x94 Comparing OpenCL "
            "with CUDA and GLSL</em> measured hand-written skinning kernels against a serial CPU loop. skintune "
            "repeats the experiment on the machines below: the paper&#39;s kernels are points of its variant space, "
            "measured beside the fastest variant its tuner found (every time verified against a float64 "
            "reference).</p>\n";
    for (const SummaryResult& r : s_.results) {
      out_ += "<p class=\"note\">" + (r.label.empty() ? std::string() : "<strong>" + Esc(r.label) + "</strong>: ") +
              "created " + Esc(r.created) + (r.quick ? " (quick: the reduced data-set list)" : "") + "; host " +
              Esc(r.host.cpu_model.empty() ? "unknown" : r.host.cpu_model) + "; " +
              (r.command.empty() ? std::string("command not recorded") : "command <code>" + Esc(r.command) + "</code>") +
              "</p>\n";
    }
    if (s_.results.empty()) out_ += "<p class=\"warn\">No results were given.</p>\n";
    out_ += "<nav><a href=\"#fig1\">Fig. 1</a><a href=\"#table1-opencl-vs-cuda\">Table 1: OpenCL vs CUDA</a>"
            "<a href=\"#table1-opencl-vs-glsl\">Table 1: OpenCL vs GLSL</a><a href=\"#gbps\">GB/s</a>"
            "<a href=\"#axes\">Variant axes</a><a href=\"#rows\">Rows</a><a href=\"#devices\">Devices</a></nav>\n";
  }

  // ---- Fig. 1 ------------------------------------------------------------

  void Figure1Section() {
    out_ += "<section id=\"fig1\">\n<h2>Fig. 1: speedup over the serial CPU</h2>\n";
    out_ += "<p>As in the paper&#39;s Fig. 1: the time per frame of the serial CPU loop (the paper&#39;s baseline) "
            "over each implementation&#39;s, on one data set. Light bars are the paper&#39;s kernels as written "
            "in the paper, solid bars the tuned winner of the same API on the same device; a \xE2\x97\x86 marks "
            "the figure the paper published for that series.</p>\n";
    if (s_.figure1.empty()) out_ += "<p class=\"warn\">No results.</p>\n";
    for (std::size_t i = 0; i < s_.figure1.size(); ++i) Figure1Chart(s_.figure1[i], i);
    out_ += "</section>\n";
  }

  void Figure1Chart(const Figure1& f, std::size_t index) {
    const SummaryResult& r = s_.results[f.result];
    out_ += "<h3>" + (r.label.empty() ? std::string() : Esc(r.label) + ": ") + "data set " + Esc(f.dataset) +
            (f.vertices ? " (" + Esc(std::to_string(f.vertices)) + " vertices, " + std::to_string(f.influences) +
                              " influences per vertex)"
                        : " (not in this result)") +
            "</h3>\n";
    if (!f.serial_ms) {
      out_ += "<p class=\"warn\">No serial baseline: this result has no serial CPU timing of " + Esc(f.dataset) +
              ", so no speedup can be computed. The chart shows the median times instead (shorter is "
              "faster).</p>\n";
    }
    ReportedSource(r, !r.reported.figure1.empty());
    for (const auto& [series, figure] : f.unmatched) {
      out_ += "<p class=\"note\">The paper&#39;s figure for <strong>" + Esc(series) + "</strong>: " +
              FormatSpeedup(figure) + ", no matching device here.</p>\n";
    }

    const bool speedups = f.serial_ms.has_value();
    std::vector<double> values;
    for (const Figure1Row& row : f.rows) {
      if (speedups && row.speedup) values.push_back(*row.speedup);
      if (!speedups && row.median_ms) values.push_back(*row.median_ms);
      if (speedups && row.reported) values.push_back(*row.reported);
    }
    if (speedups) values.push_back(1.0);
    if (values.empty()) values = {0.001, 1.0};
    const auto [lo, hi] = Decades(values);
    const double width = 1120, x0 = 380, x1 = 810;
    const LogScale x{lo, hi, x0, x1};
    const double row_h = 22, head_h = 30, top = 46;
    // A heading row before the CPU rows and before each device's rows.
    std::size_t groups = 0;
    for (std::size_t i = 0; i < f.rows.size(); ++i) groups += i == 0 || f.rows[i].device != f.rows[i - 1].device;
    const double height =
        top + static_cast<double>(groups) * head_h + static_cast<double>(f.rows.size()) * row_h + 56;
    const std::string title = std::string("Fig. 1, ") + Esc(f.dataset) + ": " +
                              (speedups ? "speedup over the serial CPU per implementation, log scale"
                                        : "median time per frame per implementation (no serial baseline), log scale");
    out_ += SvgOpen("fig1-" + std::to_string(index), width, height, title);
    Figure1Legend(speedups);
    const double plot_top = top, plot_bottom = height - 50;
    // 1-2-5 grid lines; labels on each when there is room, else on the decades only.
    const bool crowded = (x1 - x0) / std::log10(hi / lo) < 120;
    for (double t : LogTicks(lo, hi)) {
      const bool major = std::fabs(std::log10(t) - std::round(std::log10(t))) < 1e-9;
      out_ += Line(x(t), plot_top, x(t), plot_bottom,
                   std::string("stroke=\"") + (major ? "#c9d1d9" : "#eef1f4") + "\" stroke-width=\"1\"");
      if (major || !crowded) {
        out_ += Text(x(t), plot_bottom + 16, Tick(t) + (speedups ? "\xC3\x97" : ""),
                     std::string("class=\"small\" text-anchor=\"middle\"") + (major ? " font-weight=\"600\"" : ""));
      }
    }
    if (speedups) out_ += Line(x(1.0), plot_top, x(1.0), plot_bottom, "stroke=\"#57606a\" stroke-width=\"1.5\"");
    out_ += Text((x0 + x1) / 2, plot_bottom + 36,
                 speedups ? "speedup over the serial CPU (log scale; right of 1\xC3\x97 is faster)"
                          : "median time per frame, ms (log scale; shorter is faster)",
                 "class=\"label\" text-anchor=\"middle\"");
    out_ += Text(x1 + 12, plot_top - 8, speedups ? "speedup \xC2\xB7 time" : "time", "class=\"small\"");
    if (!r.reported.figure1.empty()) out_ += Text(x1 + 170, plot_top - 8, "the paper", "class=\"small\"");

    double y = top;
    for (std::size_t i = 0; i < f.rows.size(); ++i) {
      const Figure1Row& row = f.rows[i];
      if (i == 0 || row.device != f.rows[i - 1].device) {
        const std::string heading = row.device ? Label(*row.device) : std::string("CPU (host: ") +
                                                                          (r.host.cpu_model.empty() ? "unknown" : r.host.cpu_model) + ")";
        out_ += Text(12, y + 21, Esc(heading), "class=\"head\"");
        out_ += Line(12, y + 26, width - 12, y + 26, "stroke=\"#e5e7eb\"");
        y += head_h;
      }
      Figure1Bar(f, row, x, y, row_h, speedups);
      y += row_h;
    }
    out_ += "</svg>\n";
  }

  void Figure1Legend(bool speedups) {
    double lx = 12;
    const double ly = 14;
    auto swatch = [&](const std::string& colour, double opacity, const std::string& text) {
      out_ += Rect(lx, ly - 9, 14, 10,
                   "fill=\"" + colour + "\" fill-opacity=\"" + C(opacity) + "\" stroke=\"" + colour + "\"");
      out_ += Text(lx + 19, ly, text, "class=\"small\"");
      lx += 34 + 6.6 * static_cast<double>(Visible(text));
    };
    swatch(kCpuColour, 1.0, "CPU");
    // Every API in the language table's order but the cpu device, whose title
    // (CPU) the baselines' swatch already shows in grey.
    for (int i = 0; i < kPaperApiCount; ++i) {
      const auto api = static_cast<PaperApi>(i);
      if (api != PaperApi::kCpu) swatch(ApiColour(api), 1.0, DisplayName(api));
    }
    swatch("#57606a", 0.3, "the paper&#39;s kernel");
    swatch("#57606a", 1.0, "tuned winner");
    if (speedups) {
      out_ += Diamond(lx + 6, ly - 4, 5, "fill=\"#111\"");
      out_ += Text(lx + 16, ly, "the paper&#39;s published figure", "class=\"small\"");
    }
  }

  void Figure1Bar(const Figure1& f, const Figure1Row& row, const LogScale& x, double y, double h, bool speedups) {
    const SummaryResult& r = s_.results[f.result];
    const std::string colour = row.device ? ApiColour(row.api) : kCpuColour;
    const double mid = y + h / 2;
    std::string tip = row.label;
    if (!row.variant.empty()) tip += "\n" + row.variant;
    if (!row.note.empty()) tip += "\n" + row.note;
    out_ += "<g><title>" + Esc(tip) + "</title>";
    out_ += Text(x.x0 - 10, mid + 4, Esc(row.label), "class=\"label\" text-anchor=\"end\"");
    const std::optional<double> value = speedups ? row.speedup : row.median_ms;
    if (value) {
      const double from = speedups ? x(1.0) : x.x0;
      const double to = x(*value);
      const double left = std::min(from, to);
      const double bar = std::max(std::fabs(to - from), 2.0);
      const bool paper = row.kind == "paper";
      out_ += Rect(left, y + 4, bar, h - 8,
                   "rx=\"2\" fill=\"" + colour + "\" fill-opacity=\"" + (paper ? "0.3" : "1") + "\" stroke=\"" +
                       colour + "\"");
      out_ += Text(x.x1 + 12, mid + 4,
                   speedups ? FormatSpeedup(*value) + " \xC2\xB7 " + FormatMs(*row.median_ms) : FormatMs(*value),
                   "class=\"value\"");
    } else {
      out_ += Text(x.x0 + 6, mid + 4, Esc(Cut(row.note.empty() ? "no time" : row.note, 64)), "class=\"missing\"");
    }
    // The paper's figure in a column of its own, so it lines up down the chart.
    if (row.reported) {
      out_ += Text(x.x1 + 170, mid + 4, "paper " + FormatSpeedup(*row.reported), "class=\"value\" font-weight=\"600\"");
    } else if (!row.series.empty() && !r.reported.figure1.empty()) {
      out_ += Text(x.x1 + 170, mid + 4, "paper: not on record", "class=\"missing\"");
    }
    if (row.reported && speedups) out_ += Diamond(x(*row.reported), mid, 6, "fill=\"#111\" stroke=\"#fff\"");
    out_ += "</g>";
  }

  void ReportedSource(const SummaryResult& r, bool any) {
    if (any) {
      if (!r.reported.source.empty()) {
        out_ += "<p class=\"note\">The paper&#39;s figures: " + Esc(r.reported.source) + "</p>\n";
      }
    } else {
      out_ += "<p class=\"note\">The paper&#39;s figures: not on record" +
              (r.reported.source.empty() ? std::string(".") : " (" + Esc(r.reported.source) + ")") + "</p>\n";
    }
  }

  // ---- Table 1 -------------------------------------------------------------

  static std::string RatioSpan(const std::optional<double>& v) {
    if (!v) return "<span class=\"muted\">\xE2\x80\x94</span>";
    const char* cls = *v > 1.02 ? "gt" : *v < 0.98 ? "lt" : "eq";
    return std::string("<span class=\"") + cls + "\">" + FormatSignificant(*v) + "</span>";
  }

  void Table1Section(PaperApi other, const std::vector<Table1Grid>& grids, const char* id) {
    const std::string name = DisplayName(other);
    out_ += std::string("<section id=\"") + id + "\">\n<h2>Table 1: OpenCL relative to " + name + "</h2>\n";
    out_ += "<p>OpenCL&#39;s speed relative to " + name + " on the same chip: t<sub>" + name +
            "</sub> / t<sub>OpenCL</sub> per data set (rows: vertices, columns: influences per vertex B). "
            "<span class=\"gt\">Above 1</span> OpenCL is faster, <span class=\"lt\">below 1</span> slower. "
            "Each cell gives the tuned winners of both APIs, the paper&#39;s kernels (OpenCL optimised against " +
            (other == PaperApi::kCuda   ? std::string("the CUDA kernel")
             : other == PaperApi::kGlsl ? std::string("the GLSL vertex shader")
                                        : std::string("no kernel: the paper has no Vulkan")) +
            ") and the paper&#39;s published figure.</p>\n";
    if (grids.empty()) {
      out_ += "<p class=\"warn\">No comparison: no chip with both APIs (OpenCL and " + name +
              ") in these results.</p>\n";
    }
    for (const Table1Grid& g : grids) {
      const SummaryResult& r = s_.results[g.result];
      out_ += "<h3>" + Esc(Label(g.opencl_device)) + " vs " + Esc(Label(g.other_device)) + "</h3>\n";
      const std::map<std::string, double>& reported = ReportedAgainst(r.reported, other);
      ReportedSource(r, !reported.empty());
      out_ += "<table class=\"grid\"><thead><tr><th>vertices \\ B</th>";
      for (int b : g.influences) out_ += "<th>B = " + std::to_string(b) + "</th>";
      out_ += "</tr></thead><tbody>\n";
      for (std::size_t row = 0; row < g.vertices.size(); ++row) {
        out_ += "<tr><th>" + Esc(Vertices(g.vertices[row])) + "</th>";
        for (std::size_t column = 0; column < g.influences.size(); ++column) {
          const std::optional<Table1Cell>& cell = g.cells[row][column];
          if (!cell) {
            out_ += "<td class=\"none\">no such data set</td>";
            continue;
          }
          const std::optional<double>& lead = cell->tuned ? cell->tuned : cell->paper;
          const char* cls = !lead ? "none" : *lead > 1.02 ? "faster" : *lead < 0.98 ? "slower" : "even";
          out_ += std::string("<td class=\"") + cls + "\">tuned " + RatioSpan(cell->tuned) + "<br>per frame " +
                  RatioSpan(cell->tuned_frame) + "<br>paper&#39;s kernels " +
                  RatioSpan(cell->paper);
          if (!reported.empty()) {  // none on record at all: said once above the grid
            out_ += "<br>paper&#39;s figure " +
                    (cell->reported ? FormatSignificant(*cell->reported)
                                    : std::string("<span class=\"muted\">not on record</span>"));
          }
          out_ += "</td>";
        }
        out_ += "</tr>\n";
      }
      out_ += "</tbody></table>\n";
    }
    out_ += "</section>\n";
  }

  // ---- GB/s ------------------------------------------------------------------

  void GbpsSection() {
    out_ += "<section id=\"gbps\">\n<h2>GB/s against vertex count</h2>\n";
    out_ += "<p>Per device the fastest verified variant of each language and B on each data set, as bytes the "
            "variant&#39;s format must move per frame (inputs read + outputs written) over its median time. The "
            "dashed line is the device&#39;s own copy kernel (bytes read + written per second): the physical "
            "ceiling of a memory-bound kernel.</p>\n";
    if (s_.gbps.empty()) out_ += "<p class=\"warn\">No devices.</p>\n";
    for (std::size_t i = 0; i < s_.gbps.size(); ++i) GbpsChartHtml(s_.gbps[i], i);
    out_ += "</section>\n";
  }

  void GbpsChartHtml(const GbpsChart& chart, std::size_t index) {
    const SummaryDevice& device = s_.devices[chart.device];
    out_ += "<figure>\n<h3>" + Esc(device.label) + "</h3>\n";
    const double width = 1120, height = 400, x0 = 84, x1 = 800, y0 = 24, y1 = 330;
    out_ += SvgOpen("gbps-" + std::to_string(index), width, height,
                    "GB/s of the tuned winners against vertex count on " + Esc(device.label));
    std::vector<double> vertices;
    double top = chart.copy_bandwidth_gbps;
    for (const GbpsSeries& s : chart.series) {
      for (const GbpsPoint& p : s.points) {
        vertices.push_back(static_cast<double>(p.vertices));
        top = std::max(top, p.gbps);
      }
    }
    if (vertices.empty()) {
      out_ += Rect(x0, y0, x1 - x0, y1 - y0, "fill=\"#fafafa\" stroke=\"#d8dee4\"");
      out_ += Text((x0 + x1) / 2, (y0 + y1) / 2, "no status-ok measurement on this device",
                   "class=\"missing\" text-anchor=\"middle\"");
      out_ += "</svg>\n</figure>\n";
      return;
    }
    const double vmin = *std::min_element(vertices.begin(), vertices.end());
    const double vmax = *std::max_element(vertices.begin(), vertices.end());
    const LogScale x{vmin / 1.6, vmax * 1.6, x0, x1};
    // A "nice" step: 1, 2 or 5 x 10^k, about five of them.
    const double raw = top * 1.12 / 5.0;
    const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
    const double step = raw / magnitude <= 1 ? magnitude : raw / magnitude <= 2 ? 2 * magnitude
                                                       : raw / magnitude <= 5 ? 5 * magnitude
                                                                              : 10 * magnitude;
    const double ymax = std::ceil(top * 1.12 / step) * step;
    auto y = [&](double v) { return y1 - v / ymax * (y1 - y0); };
    for (double v = 0; v <= ymax * 1.0001; v += step) {
      out_ += Line(x0, y(v), x1, y(v), "stroke=\"#eaeef2\"");
      out_ += Text(x0 - 8, y(v) + 4, Tick(v), "class=\"small\" text-anchor=\"end\"");
    }
    std::set<double> ticks(vertices.begin(), vertices.end());
    for (double v : ticks) {
      out_ += Line(x(v), y0, x(v), y1, "stroke=\"#eaeef2\"");
      out_ += Text(x(v), y1 + 18, Vertices(static_cast<std::size_t>(v)), "class=\"small\" text-anchor=\"middle\"");
    }
    out_ += Rect(x0, y0, x1 - x0, y1 - y0, "fill=\"none\" stroke=\"#8c959f\"");
    out_ += Text((x0 + x1) / 2, y1 + 44, "vertices (log scale)", "class=\"label\" text-anchor=\"middle\"");
    out_ += Text(22, (y0 + y1) / 2, "GB/s",
                 "class=\"label\" text-anchor=\"middle\" transform=\"rotate(-90 22 " + C((y0 + y1) / 2) + ")\"");
    if (chart.copy_bandwidth_gbps > 0.0) {
      out_ += Line(x0, y(chart.copy_bandwidth_gbps), x1, y(chart.copy_bandwidth_gbps),
                   "stroke=\"#111\" stroke-width=\"1.5\" stroke-dasharray=\"7 5\"");
      out_ += Text(x1 - 6, y(chart.copy_bandwidth_gbps) - 7, "copy kernel: " + FormatGbps(chart.copy_bandwidth_gbps),
                   "class=\"label\" text-anchor=\"end\" font-weight=\"600\"");
    } else {
      out_ += Text(x1 - 6, y0 + 16, "copy bandwidth not measured", "class=\"missing\" text-anchor=\"end\"");
    }
    double ly = y0 + 8;
    out_ += Text(x1 + 24, ly, "language, B (best of copy)", "class=\"head\"");
    ly += 20;
    for (const GbpsSeries& s : chart.series) {
      const std::string colour = BColour(s.influences);
      const std::string dash = s.lang == Lang::kGlslVertex ? " stroke-dasharray=\"6 4\"" : "";
      std::string points;
      for (const GbpsPoint& p : s.points) points += C(x(static_cast<double>(p.vertices))) + "," + C(y(p.gbps)) + " ";
      out_ += "<polyline points=\"" + points + "\" fill=\"none\" stroke=\"" + colour + "\" stroke-width=\"2.2\"" +
              dash + "/>";
      double best_fraction = 0.0;
      for (const GbpsPoint& p : s.points) {
        best_fraction = std::max(best_fraction, p.copy_fraction);
        std::string tip = p.dataset + ": " + FormatGbps(p.gbps) + ", " + FormatMs(p.median_ms);
        if (p.copy_fraction > 0.0) tip += ", " + Fraction(p.copy_fraction) + " of copy";
        tip += "\n" + p.variant.Key();
        out_ += "<circle cx=\"" + C(x(static_cast<double>(p.vertices))) + "\" cy=\"" + C(y(p.gbps)) +
                "\" r=\"4\" fill=\"" + colour + "\" stroke=\"#fff\"><title>" + Esc(tip) + "</title></circle>";
      }
      out_ += Line(x1 + 24, ly - 4, x1 + 54, ly - 4, "stroke=\"" + colour + "\" stroke-width=\"2.2\"" + dash);
      out_ += Text(x1 + 62, ly, Esc(Name(s.lang)) + " B=" + std::to_string(s.influences) +
                                    (best_fraction > 0.0 ? " (" + Fraction(best_fraction) + ")" : ""),
                   "class=\"label\"");
      ly += 20;
    }
    out_ += "</svg>\n";
    WinnersTable(chart);
    out_ += "</figure>\n";
  }

  // The points of a GB/s chart as a table: per data set and language the
  // winner's time, GB/s, its time over the same-size copy's, fraction of the
  // device's large copy and variant.
  void WinnersTable(const GbpsChart& chart) {
    std::map<std::string, std::vector<std::pair<Lang, const GbpsPoint*>>> by_dataset;
    for (const GbpsSeries& s : chart.series) {
      for (const GbpsPoint& p : s.points) by_dataset[p.dataset].emplace_back(s.lang, &p);
    }
    out_ += "<table><thead><tr><th>data set</th><th>language</th><th title=\"the kernel's own device time from a "
            "flushed cache: median and 95% interval\">kernel time</th><th title=\"Skin() issued back to back, host "
            "issue included\">frame time</th><th title=\"other candidates within the tie margin of the fastest, plus the spread between "
            "processes; the winner moves the fewest bytes, then has the lowest error, then the palette storage with "
            "the fewest limits\">ties</th><th>GB/s</th><th title=\"time / the "
            "time of a copy of the same bytes, timed the same way\">\xC3\x97 same-size copy</th><th>of large copy</th>"
            "<th title=\"largest relative error against the float64 gold of the variant's quantised weights\">vs "
            "quantised</th><th title=\"largest error against the float64 gold of the unquantised source, of the "
            "bounding-box diagonal, and what the weight format alone costs\">vs source</th>"
            "<th>tuned winner</th></tr></thead><tbody>\n";
    for (const DatasetInfo& d : s_.results[s_.devices[chart.device].result].datasets) {
      const auto it = by_dataset.find(d.key);
      if (it == by_dataset.end()) continue;
      for (const auto& [lang, p] : it->second) {
        const std::string interval =
            p->high_ms > p->low_ms ? " [" + FormatSignificant(p->low_ms, 3) + ", " + FormatSignificant(p->high_ms, 3) + "]" : "";
        out_ += "<tr><td>" + Esc(d.key) + "</td><td>" + Esc(Name(lang)) + "</td><td class=\"num\">" +
                FormatMs(p->median_ms) + Esc(interval) + "</td><td class=\"num\">" +
                (p->frame_ms > 0.0 ? FormatMs(p->frame_ms) : std::string("not measured")) + "</td><td class=\"num\">" +
                std::to_string(p->ties) + (p->within_noise ? " (all within noise)" : "") + "</td><td class=\"num\">" +
                FormatGbps(p->gbps) + "</td><td class=\"num\">" +
                (p->x_copy > 0.0 ? FormatSignificant(p->x_copy, 3) : std::string("not measured")) +
                "</td><td class=\"num\">" + (p->copy_fraction > 0.0 ? Fraction(p->copy_fraction) : std::string("copy unknown")) +
                "</td><td class=\"num\">" + Esc(FormatError(p->max_relative_error)) +
                "</td><td class=\"num\">" + Esc(FormatSourceError(p->source_error)) + "</td><td><code>" +
                Esc(p->variant.Key()) + "</code></td></tr>\n";
      }
    }
    out_ += "</tbody></table>\n";
  }

  // ---- Axes ---------------------------------------------------------------------

  void AxesSection() {
    out_ += "<section id=\"axes\">\n<h2>What each variant axis costs</h2>\n";
    out_ += "<p>Per device and language, on the largest data set measured (vertices \xC3\x97 influences: small "
            "ones are bound by launch overhead on a GPU): for each value of each axis, the best median time among "
            "the verified variants with that "
            "value, relative to the best of all (1\xC3\x97). A long bar is a value the device punishes; values "
            "never measured are absent.</p>\n";
    if (s_.axes.empty()) out_ += "<p class=\"warn\">No status-ok measurement on any device.</p>\n";
    out_ += "<div class=\"charts\">\n";
    for (std::size_t i = 0; i < s_.axes.size(); ++i) AxisChartHtml(s_.axes[i], i);
    out_ += "</div>\n</section>\n";
  }

  void AxisChartHtml(const AxisChart& chart, std::size_t index) {
    const SummaryDevice& device = s_.devices[chart.device];
    out_ += "<figure><figcaption><strong>" + Esc(device.label) + "</strong>, " + Esc(Name(chart.lang)) + ", " +
            Esc(chart.dataset) + ": best " + FormatMs(chart.best_ms) + " over " +
            std::to_string(chart.measurements) + " verified variant" + (chart.measurements == 1 ? "" : "s") +
            "</figcaption>\n";
    std::size_t rows = 0;
    double worst = 1.0;
    for (const AxisEffect& a : chart.axes) {
      rows += a.values.size();
      for (const AxisValue& v : a.values) worst = std::max(worst, v.ratio);
    }
    const double width = 560, x0 = 200, x1 = 420, top = 30, axis_h = 20, row_h = 17;
    const double height = top + static_cast<double>(chart.axes.size()) * axis_h + static_cast<double>(rows) * row_h + 44;
    const double hi = std::max(1.25, worst * 1.08);
    const LogScale x{1.0, hi, x0, x1};
    out_ += SvgOpen("axes-" + std::to_string(index), width, height,
                    "Best time per axis value relative to the best, " + Esc(device.label) + ", " +
                        Esc(Name(chart.lang)) + ", " + Esc(chart.dataset));
    std::vector<double> ticks;
    for (double t : {1.0, 1.1, 1.25, 1.5, 2.0, 3.0, 5.0, 10.0, 20.0, 50.0, 100.0, 1000.0, 10000.0}) {
      if (t <= hi) ticks.push_back(t);
    }
    const double bottom = height - 40;
    double last_label = -1e9;
    for (double t : ticks) {
      out_ += Line(x(t), top - 6, x(t), bottom, "stroke=\"#eaeef2\"");
      if (x(t) - last_label < 36) continue;  // no overlapping labels
      out_ += Text(x(t), bottom + 14, Tick(t) + "\xC3\x97", "class=\"small\" text-anchor=\"middle\"");
      last_label = x(t);
    }
    out_ += Text((x0 + x1) / 2, bottom + 32, "best time with the value / the best (log scale)",
                 "class=\"small\" text-anchor=\"middle\"");
    out_ += Text(x1 + 8, top - 12, "relative \xC2\xB7 best time", "class=\"small\"");
    const std::string colour = ApiColour(ApiOf(chart.lang));
    double y = top;
    for (const AxisEffect& a : chart.axes) {
      out_ += Text(10, y + 13, Esc(a.axis), "class=\"head\"");
      y += axis_h;
      for (const AxisValue& v : a.values) {
        const double mid = y + row_h / 2;
        const bool best = v.ratio <= 1.0 + 1e-12;
        out_ += "<g><title>" +
                Esc(a.axis + " = " + v.value + ": best " + FormatMs(v.best_ms) + ", " + FormatSignificant(v.ratio) +
                    "\xC3\x97 the best, " + std::to_string(v.measurements) + " verified variant" +
                    (v.measurements == 1 ? "" : "s")) +
                "</title>";
        out_ += Text(x0 - 10, mid + 4, Esc(v.value), "class=\"label\" text-anchor=\"end\"");
        out_ += Rect(x0, y + 3, std::max(x(v.ratio) - x0, 2.0), row_h - 6,
                     "rx=\"2\" fill=\"" + colour + "\" fill-opacity=\"" + (best ? "1" : "0.45") + "\"");
        out_ += Text(x1 + 8, mid + 4, FormatSignificant(v.ratio) + "\xC3\x97 \xC2\xB7 " + FormatMs(v.best_ms),
                     std::string("class=\"value\"") + (best ? " font-weight=\"600\"" : ""));
        out_ += "</g>";
        y += row_h;
      }
    }
    out_ += "</svg>\n</figure>\n";
  }

  // ---- Rows ---------------------------------------------------------------------

  // Every row's winner, the formats, morph targets and blends each a row of
  // their own, with what it costs against its plain row.
  void RowsSection() {
    out_ += "<section id=\"rows\">\n<h2>Every row: formats, morph targets, blends and animation</h2>\n";
    out_ += "<p>The user chooses a row: the format the normals and tangents are written in, the mesh&#39;s morph "
            "targets, linear or dual-quaternion blending, palettes made on the device (an animated scene, whose "
            "kernel time holds the palette kernel). Each is tuned as a row of its own, and its winner within "
            "the error budget is set here against its plain row&#39;s (f32 normals, no morph targets, linear "
            "blending, the host&#39;s palettes; the same device, language, B, vertex count and scene): what that "
            "choice costs, or saves.</p>\n";
    bool any = false;
    for (const RowWinner& r : s_.rows) any = any || !r.plain;
    if (!any) {
      out_ += "<p class=\"note\">Every row is plain in these results.</p>\n</section>\n";
      return;
    }
    out_ += "<table><thead><tr><th>device</th><th>language</th><th>data set</th><th>row</th><th title=\"the "
            "kernel's own device time: median and 95% interval\">kernel time</th><th>GB/s</th><th title=\"time / "
            "the time of a copy of the same bytes\">\xC3\x97 same-size copy</th><th title=\"positions against the "
            "unquantised source's float64 gold, of the bounding-box diagonal; normals as unit vectors\">error: "
            "positions, normals</th><th title=\"kernel time / the plain row's winner's\">\xC3\x97 plain row</th>"
            "<th>tuned winner</th></tr></thead><tbody>\n";
    for (const RowWinner& r : s_.rows) {
      const std::string interval =
          r.high_ms > r.low_ms ? " [" + FormatSignificant(r.low_ms, 3) + ", " + FormatSignificant(r.high_ms, 3) + "]" : "";
      out_ += "<tr><td>" + Esc(s_.devices[r.device].label) + "</td><td>" + Esc(Name(r.lang)) + "</td><td>" +
              Esc(r.dataset) + "</td><td>" + Esc(r.row) + (r.animation.empty() ? "" : "<br><small>" + Esc(r.animation) + "</small>") +
              "</td><td class=\"num\">" + FormatMs(r.median_ms) +
              Esc(interval) + "</td><td class=\"num\">" + FormatGbps(r.gbps) + "</td><td class=\"num\">" +
              (r.x_copy > 0.0 ? FormatSignificant(r.x_copy, 3) : std::string("not measured")) +
              "</td><td class=\"num\">" + Scientific(r.position_rel) + ", " + Scientific(r.normal_abs) +
              "</td><td class=\"num\">" +
              (r.plain ? std::string("plain") : r.vs_plain > 0.0 ? FormatSpeedup(r.vs_plain) : "no plain row") +
              "</td><td><code>" + Esc(r.variant) + "</code></td></tr>\n";
    }
    out_ += "</tbody></table>\n</section>\n";
  }

  // ---- Devices --------------------------------------------------------------------

  // Why blend dq exists: a joint twisting about its own axis, the middle
  // ring's radius and the blend region's volume under each method.
  void CandyWrapperSection() {
    out_ += "<section id=\"candy-wrapper\">\n<h2>Dual quaternions: the candy wrapper</h2>\n";
    out_ += "<p>A tube bound to two joints, the second twisting about the tube&#39;s own axis, the weights "
            "crossing from one joint to the other over the middle half (docs/VARIANTS.md &quot;Dual "
            "quaternions&quot;). Linear blending (<code>matrix</code>, <code>point</code>) averages the two "
            "joints&#39; matrices, so the ring between them shrinks to |cos(twist / 2)| of its radius and "
            "collapses at 180 degrees; dual quaternions (<code>dq</code>) blend the rigid motions and keep its "
            "volume. The float64 golds of both methods, not a measurement.</p>\n";
    if (s_.candy_wrapper.empty()) {
      out_ += "</section>\n";
      return;
    }
    const double width = 760, height = 320, x0 = 70, x1 = 560, y0 = 20, y1 = 260;
    out_ += SvgOpen("candy-wrapper-chart", width, height,
                    "The middle ring&#39;s radius against the joint&#39;s twist, linear blending and dual quaternions");
    const double top = s_.candy_wrapper.back().twist_degrees;
    auto x = [&](double degrees) { return x0 + degrees / top * (x1 - x0); };
    auto y = [&](double ratio) { return y1 - ratio / 1.1 * (y1 - y0); };
    for (double v = 0.0; v <= 1.0001; v += 0.25) {
      out_ += Line(x0, y(v), x1, y(v), "stroke=\"#eaeef2\"");
      out_ += Text(x0 - 8, y(v) + 4, C(v), "class=\"small\" text-anchor=\"end\"");
    }
    for (const CandyWrapperPoint& p : s_.candy_wrapper) {
      if (static_cast<int>(p.twist_degrees) % 45 != 0) continue;
      out_ += Text(x(p.twist_degrees), y1 + 18, C(p.twist_degrees), "class=\"small\" text-anchor=\"middle\"");
    }
    out_ += Rect(x0, y0, x1 - x0, y1 - y0, "fill=\"none\" stroke=\"#8c959f\"");
    out_ += Text((x0 + x1) / 2, y1 + 42, "twist (degrees)", "class=\"label\" text-anchor=\"middle\"");
    out_ += Text(20, (y0 + y1) / 2, "radius / rest",
                 "class=\"label\" text-anchor=\"middle\" transform=\"rotate(-90 20 " + C((y0 + y1) / 2) + ")\"");
    const struct {
      const char* label;
      const char* colour;
      double CandyWrapperPoint::*radius;
    } methods[] = {{"linear blending", "#cf222e", &CandyWrapperPoint::linear_radius},
                   {"dual quaternions", "#0969da", &CandyWrapperPoint::dual_quaternion_radius}};
    double ly = y0 + 10;
    for (const auto& m : methods) {
      std::string points;
      for (const CandyWrapperPoint& p : s_.candy_wrapper) points += C(x(p.twist_degrees)) + "," + C(y(p.*m.radius)) + " ";
      out_ += "<polyline points=\"" + points + "\" fill=\"none\" stroke=\"" + m.colour + "\" stroke-width=\"2.2\"/>";
      out_ += Line(x1 + 20, ly - 4, x1 + 50, ly - 4, "stroke=\"" + std::string(m.colour) + "\" stroke-width=\"2.2\"");
      out_ += Text(x1 + 58, ly, m.label, "class=\"label\"");
      ly += 20;
    }
    out_ += "</svg>\n<table>\n<tr><th>twist (degrees)</th><th>radius, linear</th><th>radius, dual quaternions</th>"
            "<th>volume, linear</th><th>volume, dual quaternions</th></tr>\n";
    for (const CandyWrapperPoint& p : s_.candy_wrapper) {
      if (static_cast<int>(p.twist_degrees) % 45 != 0) continue;
      char row[256];
      std::snprintf(row, sizeof row, "<tr><td>%.0f</td><td>%.3f</td><td>%.3f</td><td>%.3f</td><td>%.3f</td></tr>\n",
                    p.twist_degrees, p.linear_radius, p.dual_quaternion_radius, p.linear_volume,
                    p.dual_quaternion_volume);
      out_ += row;
    }
    out_ += "</table>\n</section>\n";
  }

  void DevicesSection() {
    out_ += "<section id=\"devices\">\n<h2>Devices, host and kernels</h2>\n";
    for (std::size_t ri = 0; ri < s_.results.size(); ++ri) {
      const SummaryResult& r = s_.results[ri];
      if (!r.label.empty()) out_ += "<h3>" + Esc(r.label) + "</h3>\n";
      out_ += "<p>" +
              (r.command.empty() ? std::string("Command not recorded") : "Command <code>" + Esc(r.command) + "</code>") +
              ", finished " +
              Esc(r.created) + (r.quick ? " (quick)" : "") + "; tuning config " + Esc(r.config) + ", strategy " +
              Esc(r.strategy) + ".</p>\n";
      out_ += "<table><thead><tr><th>backend</th><th>platform</th><th>name</th><th>vendor</th><th>driver</th>"
              "<th>API version</th><th>type</th><th>compute units</th><th>memory</th><th>last-level cache</th>"
              "<th>copy</th><th>paired as</th></tr></thead><tbody>\n";
      for (const SummaryDevice& d : s_.devices) {
        if (d.result != ri) continue;
        const DeviceIdentity& i = d.identity;
        out_ += "<tr><td>" + Esc(i.backend) + "</td><td>" + Esc(i.platform) + "</td><td>" + Esc(i.name) + "</td><td>" +
                Esc(i.vendor) + "</td><td>" + Esc(i.driver_version) + "</td><td>" + Esc(i.api_version) + "</td><td>" +
                Esc(i.type) + "</td><td class=\"num\">" +
                (i.compute_units ? std::to_string(i.compute_units) : std::string("unknown")) +
                "</td><td class=\"num\">" + Bytes(i.global_memory_bytes) + "</td><td class=\"num\" title=\"" +
                Esc(i.last_level_cache_source) + "\">" + Bytes(i.last_level_cache_bytes) + "</td><td class=\"num\">" +
                (d.copy_bandwidth_gbps > 0.0 ? FormatGbps(d.copy_bandwidth_gbps) : std::string("not measured")) +
                "</td><td>" + Esc(d.chip) + "</td></tr>\n";
      }
      out_ += "</tbody></table>\n";
      if (r.skipped.empty()) {
        out_ += "<p class=\"note\">No backend was skipped.</p>\n";
      } else {
        out_ += "<p class=\"note\">Skipped backends:</p><ul>\n";
        for (const std::string& s : r.skipped) out_ += "<li>" + Esc(s) + "</li>\n";
        out_ += "</ul>\n";
      }
      out_ += "<p><strong>Host CPU</strong>: " + Esc(r.host.cpu_model.empty() ? "unknown" : r.host.cpu_model) + ", " +
              std::to_string(r.host.threads) + " threads, copy " +
              (r.host.copy_bandwidth_gbps > 0.0 ? FormatGbps(r.host.copy_bandwidth_gbps) : std::string("not measured")) +
              ".";
      if (!r.machine.empty()) {
        out_ += " Machine:";
        for (const auto& [key, value] : r.machine) out_ += " " + Esc(key) + " <code>" + Esc(value) + "</code>";
      }
      out_ += "</p>\n";
      CpuTable(r);
      KernelTable(r);
    }
    out_ += "</section>\n";
  }

  void CpuTable(const SummaryResult& r) {
    if (r.cpu.empty()) {
      out_ += "<p class=\"note\">No CPU timings (no serial baseline).</p>\n";
      return;
    }
    out_ += "<table><thead><tr><th>data set</th><th>serial (threads)</th><th>serial GB/s</th><th>fast (threads)</th>"
            "<th>fast GB/s</th><th>fast over serial</th><th>max relative error</th></tr></thead><tbody>\n";
    for (const CpuResult& c : r.cpu) {
      out_ += "<tr><td>" + Esc(c.dataset) + "</td><td class=\"num\">" + FormatMs(c.serial.median_ms) + " (" +
              std::to_string(c.serial.threads) + ")</td><td class=\"num\">" + FormatGbps(c.serial.gbps) +
              "</td><td class=\"num\">" + FormatMs(c.fast.median_ms) + " (" + std::to_string(c.fast.threads) +
              ")</td><td class=\"num\">" + FormatGbps(c.fast.gbps) + "</td><td class=\"num\">" +
              (c.fast.median_ms > 0.0 ? FormatSpeedup(c.serial.median_ms / c.fast.median_ms) : std::string("\xE2\x80\x94")) +
              "</td><td class=\"num\">" + Scientific(std::max(c.serial.max_relative_error, c.fast.max_relative_error)) +
              "</td></tr>\n";
    }
    out_ += "</tbody></table>\n";
  }

  void KernelTable(const SummaryResult& r) {
    if (r.paper_kernels.empty()) {
      out_ += "<p class=\"note\">No paper kernels in this result.</p>\n";
      return;
    }
    out_ += "<p>The paper&#39;s kernels as variants of skintune&#39;s space (shown with the Fig. 1 data set&#39;s B; "
            "each data set is measured with its own B):</p>\n";
    out_ += "<table><thead><tr><th>kernel</th><th>where in the paper</th><th>variant</th><th>what it encodes</th>"
            "</tr></thead><tbody>\n";
    for (const PaperKernel& k : r.paper_kernels) {
      out_ += "<tr><td>" + Esc(k.label) + "<br><span class=\"muted\">" + Esc(k.name) + "</span></td><td>" +
              Esc(k.section) + "</td><td><code>" + Esc(k.variant.Key()) + "</code></td><td>" + Esc(k.description) +
              "</td></tr>\n";
    }
    out_ += "</tbody></table>\n";
  }

  const PaperSummary& s_;
  std::string out_;
};

}  // namespace

std::string RenderHtml(const PaperSummary& summary) { return Renderer(summary).Render(); }

}  // namespace skintune::internal
