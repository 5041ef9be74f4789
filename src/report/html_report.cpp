#include "report/html_report.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <numeric>

#include <fmt/format.h>

#include "core/geometry.hpp"
#include "core/uncertainty.hpp"
#include "io/error.hpp"
#include "report/svg.hpp"

namespace scenecal::report {

namespace {

constexpr const char* kTupleNames[6] = {"x", "y", "z", "roll", "pitch", "yaw"};
constexpr double kCm = 100.0;

// Display units of tuple component k: cm for translation, deg for rotation.
double TupleDisplay(const Vector6d& tuple, int k) {
  return k < 3 ? tuple[k] * kCm : DegreesFromRadians(tuple[k]);
}
const char* TupleUnit(int k) { return k < 3 ? "cm" : "deg"; }

std::string Num(double value, int decimals) {
  if (!std::isfinite(value)) return "n/a";
  if (std::abs(value) < 0.5 * std::pow(10.0, -decimals)) value = 0.0;  // no "-0.00"
  return fmt::format("{:.{}f}", value, decimals);
}
std::string Num(const std::optional<double>& value, int decimals) {
  return value ? Num(*value, decimals) : std::string("&ndash;");
}

std::string H(const std::string& text) { return EscapeXml(text); }

const char* kStyle = R"css(
body { font-family: "DejaVu Sans", Helvetica, Arial, sans-serif; margin: 0; color: #222; background: #f6f7f9; }
header { background: #20324a; color: #fff; padding: 18px 28px; }
header h1 { margin: 0 0 6px 0; font-size: 22px; }
header p { margin: 2px 0; font-size: 13px; color: #dfe6ee; }
nav { background: #e9edf2; padding: 8px 28px; font-size: 13px; }
nav a { margin-right: 16px; color: #20324a; }
main { padding: 8px 28px 40px 28px; }
section { background: #fff; border: 1px solid #dde2e8; border-radius: 6px; margin: 18px 0; padding: 12px 18px; }
h2 { font-size: 18px; margin: 4px 0 10px 0; color: #20324a; }
h3 { font-size: 15px; margin: 14px 0 6px 0; }
table { border-collapse: collapse; font-size: 12px; margin: 6px 0 12px 0; }
th, td { border: 1px solid #d4d9df; padding: 3px 7px; text-align: right; white-space: nowrap; }
th { background: #eef1f5; }
td.text, th.text { text-align: left; }
tr.truth td { color: #555; font-style: italic; }
.warnings { background: #fff4e0; border-left: 4px solid #e69a12; padding: 6px 12px; font-size: 13px; }
.ok { color: #1b7f2a; font-weight: bold; }
.bad { color: #b3261e; font-weight: bold; }
.note { font-size: 12px; color: #555; }
.figure { margin: 8px 0 16px 0; overflow-x: auto; }
.figure img { max-width: 100%; border: 1px solid #ccc; }
.caption { font-size: 12px; color: #444; margin-top: 4px; }
.swatch { display: inline-block; width: 12px; height: 12px; vertical-align: middle; margin: 0 4px 0 10px; }
details { font-size: 12px; margin: 6px 0; }
.wide { overflow-x: auto; }
)css";

std::string PageOpen(const std::string& title, const std::vector<std::string>& header_lines,
                     const std::vector<std::pair<std::string, std::string>>& nav) {
  std::string out = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  out += "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n";
  out += "<title>" + H(title) + "</title>\n<style>" + kStyle + "</style>\n</head>\n<body>\n";
  out += "<header><h1>" + H(title) + "</h1>\n";
  for (const std::string& line : header_lines) out += "<p>" + line + "</p>\n";
  out += "</header>\n<nav>";
  for (const auto& [id, name] : nav) out += "<a href=\"#" + H(id) + "\">" + H(name) + "</a>";
  out += "</nav>\n<main>\n";
  return out;
}

std::string PageClose() { return "</main>\n</body>\n</html>\n"; }

std::string TupleHeader(const std::string& first_columns, const std::string& suffix = "") {
  std::string out = first_columns;
  for (int k = 0; k < 6; ++k) out += fmt::format("<th>{}{} ({})</th>", kTupleNames[k], suffix, TupleUnit(k));
  return out;
}

std::string TupleCells(const Vector6d& tuple) {
  std::string out;
  for (int k = 0; k < 6; ++k) out += "<td>" + Num(TupleDisplay(tuple, k), k < 3 ? 2 : 3) + "</td>";
  return out;
}

std::string Figure(const std::string& svg, const std::string& caption = "") {
  std::string out = "<div class=\"figure\">\n" + svg;
  if (!caption.empty()) out += "<div class=\"caption\">" + caption + "</div>\n";
  return out + "</div>\n";
}

std::string OverlaySection(const std::vector<OverlayFigure>& overlays) {
  std::string out = "<section id=\"overlays\">\n<h2>Overlays: projected swathe (Fig. 9)</h2>\n";
  if (overlays.empty()) return out + "<p class=\"note\">No overlays were rendered for this report.</p>\n</section>\n";
  out += "<p class=\"note\">Lidar points projected into the camera image, culled as the cost culls them "
         "(in front of the camera, inside the image, visible under the z-buffer). "
         "<span class=\"swatch\" style=\"background:#e62828\"></span>initial guess "
         "<span class=\"swatch\" style=\"background:#0078ff\"></span>result; "
         "reflectance overlays use the turbo colormap (blue low, red high).</p>\n";
  for (const OverlayFigure& overlay : overlays) {
    out += "<div class=\"figure\">\n<h3>" + H(overlay.title) + "</h3>\n";
    if (overlay.bgr.empty()) {
      out += "<p class=\"note\">(empty image)</p>\n";
    } else {
      out += fmt::format("<img alt=\"{}\" width=\"{}\" height=\"{}\" src=\"{}\">\n", H(overlay.title),
                         overlay.bgr.cols, overlay.bgr.rows, PngDataUri(overlay.bgr));
    }
    std::string caption = H(overlay.caption);
    if (!overlay.file_name.empty())
      caption += (caption.empty() ? "" : " ") + std::string("Also saved as <code>") +
                 H(SafeFileName(overlay.file_name)) + "</code>.";
    if (!caption.empty()) out += "<div class=\"caption\">" + caption + "</div>\n";
    out += "</div>\n";
  }
  return out + "</section>\n";
}

std::vector<ReportFile> OverlayFiles(const std::vector<OverlayFigure>& overlays) {
  std::vector<ReportFile> files;
  for (const OverlayFigure& overlay : overlays) {
    if (overlay.bgr.empty() || overlay.file_name.empty()) continue;
    files.push_back({SafeFileName(overlay.file_name), EncodePng(overlay.bgr)});
  }
  return files;
}

std::string SettingsDetails(const std::map<std::string, std::string>& settings) {
  if (settings.empty()) return {};
  std::string out = "<details><summary>Settings (" + std::to_string(settings.size()) +
                    ")</summary>\n<table><tr><th class=\"text\">setting</th><th class=\"text\">value</th></tr>\n";
  for (const auto& [key, value] : settings)
    out += "<tr><td class=\"text\">" + H(key) + "</td><td class=\"text\">" + H(value) + "</td></tr>\n";
  return out + "</table></details>\n";
}

// --- Calibration sections ---------------------------------------------------

std::string LidarRowsTable(const std::vector<LidarRow>& lidars) {
  if (lidars.empty()) return "<p class=\"note\">No lidar result.</p>\n";
  std::string out = "<table>\n<tr>" + TupleHeader("<th class=\"text\">lidar</th><th class=\"text\">row</th>") +
                    "<th>|t err| (cm)</th><th>rot err (deg)</th></tr>\n";
  for (const LidarRow& row : lidars) {
    const std::string name = "<td class=\"text\">" + H(row.lidar) + "</td>";
    // One row per transform: its tuple and, with the truth, its errors (bold for the result).
    const auto transform_row = [&](const std::string& label, const Eigen::Isometry3d& T_base_lidar, bool bold) {
      const std::string open = bold ? "<td><b>" : "<td>";
      const std::string close = bold ? "</b></td>" : "</td>";
      std::string cells = "<tr>" + name + "<td class=\"text\">" + label + "</td>" +
                          TupleCells(TupleFromTransform(T_base_lidar));
      if (row.T_base_lidar_truth) {
        cells += open + Num(TranslationError(T_base_lidar, *row.T_base_lidar_truth) * kCm, 2) + close + open +
                 Num(RotationErrorDegrees(T_base_lidar, *row.T_base_lidar_truth), 3) + close;
      } else {
        cells += "<td></td><td></td>";
      }
      return cells + "</tr>\n";
    };
    out += transform_row("initial guess", row.T_base_lidar_initial, false);
    out += transform_row("<b>result</b>", row.T_base_lidar, true);
    if (row.sigma)
      out += "<tr>" + name + "<td class=\"text\">1-sigma</td>" + TupleCells(*row.sigma) + "<td></td><td></td></tr>\n";
    if (row.T_base_lidar_truth) {
      out += "<tr class=\"truth\">" + name + "<td class=\"text\">truth</td>" +
             TupleCells(TupleFromTransform(*row.T_base_lidar_truth)) + "<td></td><td></td></tr>\n";
      out += "<tr>" + name + "<td class=\"text\">error (result &minus; truth)</td>" +
             TupleCells(TupleError(row.T_base_lidar, *row.T_base_lidar_truth)) + "<td></td><td></td></tr>\n";
    }
  }
  return out + "</table>\n";
}

std::string PairRowsTables(const std::vector<PairRow>& pairs) {
  if (pairs.empty()) return "<p class=\"note\">No pair result.</p>\n";
  std::string out = "<div class=\"wide\"><table>\n<tr>" +
                    TupleHeader("<th class=\"text\">camera</th><th class=\"text\">lidar</th>") +
                    "<th>scenes used</th><th>initial cost</th><th>final cost</th></tr>\n";
  for (const PairRow& row : pairs)
    out += "<tr><td class=\"text\">" + H(row.camera) + "</td><td class=\"text\">" + H(row.lidar) + "</td>" +
           TupleCells(TupleFromTransform(row.T_camera_lidar)) +
           fmt::format("<td>{} / {}</td>", row.scenes_used, row.scenes) + "<td>" + Num(row.initial_cost, 5) +
           "</td><td>" + Num(row.final_cost, 5) + "</td></tr>\n";
  out += "</table></div>\n";
  const bool any_truth =
      std::any_of(pairs.begin(), pairs.end(), [](const PairRow& row) { return row.T_camera_lidar_truth.has_value(); });
  if (!any_truth) return out;
  out += "<h3>Pairs: error of T_camera_lidar to the truth (result &minus; truth)</h3>\n"
         "<div class=\"wide\"><table>\n<tr>" +
         TupleHeader("<th class=\"text\">camera</th><th class=\"text\">lidar</th>", " err") +
         "<th>|t err| (cm)</th><th>rot err (deg)</th></tr>\n";
  for (const PairRow& row : pairs) {
    if (!row.T_camera_lidar_truth) continue;
    out += "<tr><td class=\"text\">" + H(row.camera) + "</td><td class=\"text\">" + H(row.lidar) + "</td>" +
           TupleCells(TupleError(row.T_camera_lidar, *row.T_camera_lidar_truth)) + "<td>" +
           Num(TranslationError(row.T_camera_lidar, *row.T_camera_lidar_truth) * kCm, 2) + "</td><td>" +
           Num(RotationErrorDegrees(row.T_camera_lidar, *row.T_camera_lidar_truth), 3) + "</td></tr>\n";
  }
  return out + "</table></div>\n";
}

std::string OptimisationsAndTimings(const CalibrationReportData& data) {
  std::string out;
  if (!data.optimisations.empty()) {
    out += "<h3>Optimiser runs</h3>\n<table>\n<tr><th class=\"text\">problem</th><th>stages</th><th>iterations</th>"
           "<th>evaluations</th><th>time (s)</th><th class=\"text\">termination</th></tr>\n";
    for (const OptimisationRow& row : data.optimisations)
      out += fmt::format("<tr><td class=\"text\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>"
                         "<td class=\"text\">{}</td></tr>\n",
                         H(row.problem), row.stages, row.iterations, row.evaluations, Num(row.seconds, 2),
                         H(row.termination));
    out += "</table>\n";
  }
  if (!data.timings_s.empty()) {
    out += "<h3>Timings</h3>\n<table><tr><th class=\"text\">stage</th><th>seconds</th></tr>\n";
    for (const auto& [stage, seconds] : data.timings_s)
      out += "<tr><td class=\"text\">" + H(stage) + "</td><td>" + Num(seconds, 3) + "</td></tr>\n";
    out += "</table>\n";
  }
  return out;
}

std::string CalibrationSummary(const CalibrationReportData& data) {
  std::string out = "<section id=\"summary\">\n<h2>Summary</h2>\n";
  out += "<p>Termination: <b>" + H(data.termination.empty() ? std::string("(not given)") : data.termination) +
         "</b>";
  if (data.alternations > 0) out += fmt::format(" &middot; alternations: {}", data.alternations);
  out += "</p>\n";
  if (!data.warnings.empty()) {
    out += "<div class=\"warnings\"><b>Warnings</b><ul>\n";
    for (const std::string& warning : data.warnings) out += "<li>" + H(warning) + "</li>\n";
    out += "</ul></div>\n";
  }
  out += "<h3>Lidars: T_base_lidar</h3>\n" + LidarRowsTable(data.lidars);
  out += "<h3>Pairs: T_camera_lidar</h3>\n" + PairRowsTables(data.pairs);
  out += OptimisationsAndTimings(data);
  out += "<p class=\"note\">Tuples are [x, y, z, roll, pitch, yaw] with R = Rz(yaw) Ry(pitch) Rx(roll); "
         "per-axis errors are tuple(result) &minus; tuple(truth). T_camera_lidar maps lidar points into the "
         "camera frame (x right, y down, z forward).</p>\n";
  out += SettingsDetails(data.settings);
  return out + "</section>\n";
}

std::string UncertaintySection(const std::vector<LidarRow>& lidars) {
  std::string out = "<section id=\"uncertainty\">\n<h2>Uncertainty</h2>\n";
  const ErrorEstimateOptions good;  // the verdict's own limits
  const double good_cm = good.good_translation_m * kCm, good_deg = DegreesFromRadians(good.good_rotation_rad);
  const bool any = std::any_of(lidars.begin(), lidars.end(), [](const LidarRow& row) { return row.sigma.has_value(); });
  if (!any)
    return out + "<p class=\"note\">No uncertainty estimate (<code>--no-uncertainty</code>, too few scenes, or a "
                 "direction the data leave undetermined: see the warnings).</p>\n</section>\n";
  out += fmt::format(
      "<p class=\"note\">Per degree of freedom of T_base_lidar, the result &plusmn; 2 sigma (about 95 % of true errors "
      "lie within it), against what counts as good (dashed: &plusmn;{} cm, &plusmn;{} deg); with a ground truth, the "
      "error of the result (red dot).</p>\n",
      good_cm, good_deg);
  for (const LidarRow& row : lidars) {
    if (!row.sigma) continue;
    std::string verdict = row.verdict.empty() ? std::string("not judged") : H(row.verdict);
    if (row.verdict == "good") verdict = "<span class=\"ok\">good</span>";
    else if (!row.verdict.empty()) verdict = "<span class=\"bad\">" + H(row.verdict) + "</span>";
    out += "<h3>" + H(row.lidar) + ": " + verdict + "</h3>\n";
    if (!row.verdict_reason.empty()) out += "<p class=\"note\">" + H(row.verdict_reason) + "</p>\n";
    std::optional<Vector6d> error;
    if (row.T_base_lidar_truth) error = TupleError(row.T_base_lidar, *row.T_base_lidar_truth);
    std::vector<std::string> panels;
    for (int group = 0; group < 2; ++group) {
      IntervalPlot plot;
      plot.title = group == 0 ? "translation" : "rotation";
      plot.y_label = group == 0 ? "cm" : "deg";
      plot.interval_label = "result \u00b1 2 sigma";
      plot.point_label = "error to the truth";
      plot.limit = group == 0 ? good_cm : good_deg;
      plot.limit_label = "good";
      for (int k = 3 * group; k < 3 * group + 3; ++k) {
        const double two_sigma = 2.0 * TupleDisplay(*row.sigma, k);
        IntervalCategory category{kTupleNames[k], -two_sigma, 0.0, two_sigma, std::nullopt};
        if (error) category.point = TupleDisplay(*error, k);
        plot.categories.push_back(category);
      }
      panels.push_back(RenderIntervalPlot(plot));
    }
    out += "<div class=\"figure\">" + SmallMultiples(panels, 2) + "</div>\n";
  }
  return out + "</section>\n";
}

std::string ConvergenceSection(const std::vector<ConvergenceSeries>& convergence) {
  std::string out = "<section id=\"convergence\">\n<h2>Convergence per degree of freedom (Fig. 4)</h2>\n";
  if (convergence.empty())
    return out + "<p class=\"note\">No alternation history (the scheme is not <code>alt</code>, or it did not "
                 "run).</p>\n</section>\n";
  out += "<p class=\"note\">Lower-level solution (red) and upper-level solution (blue) of T_camera_lidar per "
         "alternation. With a ground truth the plots show the error (estimate &minus; truth), otherwise the value; "
         "the penalty tying the levels makes them meet in the limit.</p>\n";
  for (const ConvergenceSeries& series : convergence) {
    const bool truth = series.truth.has_value();
    std::vector<double> x(series.alternations.begin(), series.alternations.end());
    if (x.size() < std::max(series.lower.size(), series.upper.size()))
      for (std::size_t i = x.size(); i < std::max(series.lower.size(), series.upper.size()); ++i)
        x.push_back(static_cast<double>(i));
    const auto values = [&](const std::vector<Eigen::Isometry3d>& transforms, int k) {
      std::vector<double> v;
      for (const Eigen::Isometry3d& T : transforms)
        v.push_back(TupleDisplay(truth ? TupleError(T, *series.truth) : TupleFromTransform(T), k));
      return v;
    };
    std::vector<std::string> panels;
    for (int k = 0; k < 6; ++k) {
      LinePlot plot;
      plot.title = fmt::format("{} {} ({})", kTupleNames[k], truth ? "error" : "value", TupleUnit(k));
      plot.x_label = "alternation";
      plot.width_px = 330;
      plot.height_px = 220;
      plot.legend = k == 0;
      if (truth) plot.reference_y = 0.0;
      Series lower;
      lower.label = "lower";
      lower.x.assign(x.begin(), x.begin() + static_cast<long>(series.lower.size()));
      lower.y = values(series.lower, k);
      lower.colour = "#d62728";
      lower.marker = Marker::kCircle;
      Series upper;
      upper.label = "upper";
      upper.x.assign(x.begin(), x.begin() + static_cast<long>(series.upper.size()));
      upper.y = values(series.upper, k);
      upper.colour = "#1f77b4";
      upper.marker = Marker::kCircle;
      upper.dash = "4 3";
      plot.series = {lower, upper};
      panels.push_back(RenderLinePlot(plot));
    }
    out += "<h3>" + H(series.label) + "</h3>\n" + Figure(SmallMultiples(panels, 3));
    if (!series.lower_cost.empty()) {
      LinePlot cost;
      cost.title = "lower-level cost f_p at the lower solution";
      cost.x_label = "alternation";
      cost.y_label = "cost";
      cost.width_px = 500;
      cost.height_px = 220;
      cost.legend = false;
      Series s;
      s.label = "cost";
      s.x.assign(x.begin(), x.begin() + static_cast<long>(std::min(x.size(), series.lower_cost.size())));
      s.y = series.lower_cost;
      s.colour = "#2ca02c";
      s.marker = Marker::kSquare;
      cost.series = {s};
      out += Figure(RenderLinePlot(cost));
    }
  }
  return out + "</section>\n";
}

std::string CostSliceSection(const std::vector<CostSlicePanel>& panels_data) {
  std::string out = "<section id=\"cost-slices\">\n<h2>Cost slices (Fig. 6)</h2>\n";
  if (panels_data.empty()) return out + "<p class=\"note\">No cost slices were sampled.</p>\n</section>\n";
  const bool penalised = std::any_of(panels_data.begin(), panels_data.end(), [](const CostSlicePanel& panel) {
    return std::any_of(panel.sets.begin(), panel.sets.end(), [](const CostSliceSet& set) { return set.penalised; });
  });
  out += std::string("<p class=\"note\">") +
         (penalised ? "The lower-level objective (pair cost plus the alternation&rsquo;s penalty) "
                    : "The pair cost (without penalty) ") +
         "sampled along one degree of freedom at a time around the solution, "
         "T = Exp(&delta; e<sub>k</sub>) T<sub>centre</sub> (camera frame: x right, y down, z forward; rx, ry, rz "
         "rotations about those axes). Light to dark: successive alternations. A flat slice is a direction the "
         "data constrains weakly.</p>\n";
  for (const CostSlicePanel& panel : panels_data) {
    std::vector<std::string> panels;
    const std::size_t n = panel.sets.size();
    for (int k = 0; k < 6; ++k) {
      LinePlot plot;
      plot.title = std::string("along ") + TangentName(k);
      plot.x_label = std::string("offset (") + TupleUnit(k) + ")";
      plot.y_label = "cost";
      plot.width_px = 330;
      plot.height_px = 220;
      plot.legend = k == 0;
      plot.reference_x = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        const CostSliceSet& set = panel.sets[i];
        const CostSlice& slice = set.slices[static_cast<std::size_t>(k)];
        Series s;
        s.label = set.label.empty() ? fmt::format("set {}", i) : set.label;
        for (double offset : slice.offsets) s.x.push_back(k < 3 ? offset * kCm : DegreesFromRadians(offset));
        s.y = slice.costs;
        s.colour = n > 1 ? SequentialColour(static_cast<double>(i) / static_cast<double>(n - 1)) : "#1f77b4";
        s.line_width = 1.6;
        s.in_legend = n <= 4 || i == 0 || i + 1 == n;
        plot.series.push_back(std::move(s));
      }
      panels.push_back(RenderLinePlot(plot));
    }
    out += "<h3>" + H(panel.label) + "</h3>\n" + Figure(SmallMultiples(panels, 3));
  }
  return out + "</section>\n";
}

// --- Experiment sections ----------------------------------------------------

std::vector<std::string> MethodOrder(const ExperimentReportData& data) {
  std::vector<std::string> methods = data.methods;
  for (const ExperimentRun& run : data.runs)
    if (std::find(methods.begin(), methods.end(), run.method) == methods.end()) methods.push_back(run.method);
  return methods;
}

std::vector<double> Collect(const std::vector<ExperimentRun>& runs, const std::string& method,
                            double (*value)(const ExperimentRun&)) {
  std::vector<double> values;
  for (const ExperimentRun& run : runs)
    if (run.method == method && run.success) values.push_back(value(run));
  return values;
}

// Summary per method: runs, successes, error and time statistics; and the settings.
std::string ExperimentSummarySection(const ExperimentReportData& data, const std::vector<std::string>& methods) {
  std::string out = "<section id=\"summary\">\n<h2>Summary</h2>\n";
  if (!data.description.empty()) out += "<p>" + H(data.description) + "</p>\n";
  if (methods.empty()) out += "<p class=\"note\">No runs.</p>\n";
  else {
    out += "<table>\n<tr><th class=\"text\">method</th><th>runs</th><th>succeeded</th>"
           "<th>median |t err| (cm)</th><th>mean |t err| (cm)</th><th>max |t err| (cm)</th>"
           "<th>median rot err (deg)</th><th>mean rot err (deg)</th><th>max rot err (deg)</th>"
           "<th>median time (s)</th></tr>\n";
    for (const std::string& method : methods) {
      const std::vector<double> t =
          Collect(data.runs, method, [](const ExperimentRun& r) { return r.translation_error_m * kCm; });
      const std::vector<double> r =
          Collect(data.runs, method, [](const ExperimentRun& run) { return run.rotation_error_deg; });
      const std::vector<double> s = Collect(data.runs, method, [](const ExperimentRun& run) { return run.seconds; });
      const auto runs = std::count_if(data.runs.begin(), data.runs.end(),
                                      [&](const ExperimentRun& run) { return run.method == method; });
      const auto stat = [](const std::vector<double>& v, int which) {
        if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
        if (which == 0) return ComputeBoxStatistics(v).median;
        if (which == 1) return std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
        return *std::max_element(v.begin(), v.end());
      };
      out += fmt::format("<tr><td class=\"text\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>"
                         "<td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
                         H(method), runs, t.size(), Num(stat(t, 0), 2), Num(stat(t, 1), 2), Num(stat(t, 2), 2),
                         Num(stat(r, 0), 3), Num(stat(r, 1), 3), Num(stat(r, 2), 3), Num(stat(s, 0), 1));
    }
    out += "</table>\n<p class=\"note\">Errors are of T_base_lidar against the ground truth; failed runs are "
           "counted but left out of the statistics.</p>\n";
  }
  out += SettingsDetails(data.settings);
  out += "</section>\n";

  return out;
}

// Fig. 7: box plots of translation and rotation error per method.
std::string ErrorBoxPlotSection(const ExperimentReportData& data, const std::vector<std::string>& methods) {
  std::string out = "<section id=\"box-plots\">\n<h2>Translation and rotation error per method (Fig. 7)</h2>\n";
  if (methods.empty()) out += "<p class=\"note\">No runs.</p>\n";
  else {
    const int width = std::max(420, 90 * static_cast<int>(methods.size()) + 90);
    BoxPlot translation{"Translation error |t_est - t_true|", "error (cm)", methods, {}, true, width, 300, false};
    BoxPlot rotation{"Rotation error angle(R_est R_true^T)", "error (deg)", methods, {}, true, width, 300, false};
    BoxSeries t_series{"all", PaletteColour(0), {}}, r_series{"all", PaletteColour(1), {}};
    for (const std::string& method : methods) {
      t_series.values_per_category.push_back(
          Collect(data.runs, method, [](const ExperimentRun& r) { return r.translation_error_m * kCm; }));
      r_series.values_per_category.push_back(
          Collect(data.runs, method, [](const ExperimentRun& r) { return r.rotation_error_deg; }));
    }
    translation.series = {t_series};
    rotation.series = {r_series};
    out += Figure(SmallMultiples({RenderBoxPlot(translation), RenderBoxPlot(rotation)}, 2),
                  "Boxes span the 25th to 75th percentiles, the line is the median, whiskers reach the most "
                  "extreme runs within 1.5 IQR, circles are outliers.");
  }
  out += "</section>\n";

  return out;
}

// Fig. 8: absolute error per DoF, methods side by side.
std::string PerDofErrorSection(const ExperimentReportData& data, const std::vector<std::string>& methods) {
  std::string out = "<section id=\"per-dof-errors\">\n<h2>Absolute error per degree of freedom (Fig. 8)</h2>\n";
  std::vector<std::string> dof_methods;
  for (const std::string& method : data.per_dof_methods.empty() ? methods : data.per_dof_methods)
    if (std::find(methods.begin(), methods.end(), method) != methods.end()) dof_methods.push_back(method);
  if (dof_methods.empty()) out += "<p class=\"note\">No runs for the selected methods.</p>\n";
  else {
    std::vector<std::string> panels;
    for (int group = 0; group < 2; ++group) {
      BoxPlot plot;
      plot.title = group == 0 ? "Translation, per axis of T_base_lidar" : "Rotation, per angle of T_base_lidar";
      plot.y_label = group == 0 ? "|error| (cm)" : "|error| (deg)";
      plot.width_px = std::max(420, 60 * static_cast<int>(dof_methods.size()) * 3 + 120);
      plot.height_px = 300;
      for (int k = 3 * group; k < 3 * group + 3; ++k) plot.categories.push_back(kTupleNames[k]);
      for (std::size_t m = 0; m < dof_methods.size(); ++m) {
        BoxSeries series{dof_methods[m], PaletteColour(m), {}};
        for (int k = 3 * group; k < 3 * group + 3; ++k) {
          std::vector<double> values;
          for (const ExperimentRun& run : data.runs)
            if (run.method == dof_methods[m] && run.success) {
              Vector6d error = run.error;
              values.push_back(std::abs(TupleDisplay(error, k)));
            }
          series.values_per_category.push_back(std::move(values));
        }
        plot.series.push_back(std::move(series));
      }
      panels.push_back(RenderBoxPlot(plot));
    }
    out += Figure(SmallMultiples(panels, 2),
                  "Absolute per-axis error |tuple(estimate) &minus; tuple(truth)| of T_base_lidar, "
                  "x, y, z in the base frame; roll, pitch, yaw as in R = Rz Ry Rx.");
  }
  out += "</section>\n";

  return out;
}

// All runs, one table row each.
std::string RunsSection(const std::vector<ExperimentRun>& runs) {
  std::string out = "<section id=\"runs\">\n<h2>Runs</h2>\n";
  if (runs.empty()) out += "<p class=\"note\">No runs.</p>\n";
  else {
    out += "<details open><summary>" + std::to_string(runs.size()) + " runs</summary>\n<table>\n<tr>" +
           TupleHeader("<th class=\"text\">method</th><th class=\"text\">lidar</th><th>trial</th>", " err") +
           "<th>|t err| (cm)</th><th>rot err (deg)</th><th>time (s)</th><th class=\"text\">termination</th></tr>\n";
    for (const ExperimentRun& run : runs)
      out += fmt::format("<tr><td class=\"text\">{}</td><td class=\"text\">{}</td><td>{}</td>{}<td>{}</td><td>{}</td>"
                         "<td>{}</td><td class=\"text\"><span class=\"{}\">{}</span> {}</td></tr>\n",
                         H(run.method), H(run.lidar), run.trial, TupleCells(run.error),
                         Num(run.translation_error_m * kCm, 2), Num(run.rotation_error_deg, 3), Num(run.seconds, 1),
                         run.success ? "ok" : "bad", run.success ? "ok" : "failed", H(run.termination));
    out += "</table></details>\n";
  }
  out += "</section>\n";
  return out;
}

}  // namespace

Vector6d TupleError(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& truth) {
  Vector6d error = TupleFromTransform(estimate) - TupleFromTransform(truth);
  for (int k = 3; k < 6; ++k) error[k] = std::remainder(error[k], 2.0 * kPi);
  return error;
}

std::string SafeFileName(const std::string& name) {
  std::string out;
  for (char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
                    c == '_' || c == '-';
    out += ok ? c : '_';
  }
  if (out.empty() || out == "." || out == "..") out = "file";
  return out;
}

CalibrationReportData MakeCalibrationReportData(const CalibrationOutcome& outcome, const Rig& rig,
                                                const GroundTruth* truth) {
  CalibrationReportData data;
  const CalibrationResult& result = outcome.result;
  data.termination = result.termination;
  if (outcome.status != CalibrationStatus::kSuccess && !outcome.why.empty())
    data.termination += (data.termination.empty() ? "" : "; ") + outcome.why;
  data.warnings = result.warnings;
  data.settings = result.settings;
  data.timings_s = result.timings_s;
  if (auto it = result.settings.find("scheme"); it != result.settings.end()) data.scheme = it->second;
  if (auto it = result.settings.find("metric"); it != result.settings.end()) data.metric = it->second;

  const auto true_lidar = [&](const std::string& lidar) -> std::optional<Eigen::Isometry3d> {
    if (truth == nullptr) return std::nullopt;
    auto it = truth->T_base_lidar.find(lidar);
    if (it == truth->T_base_lidar.end()) return std::nullopt;
    return it->second;
  };
  for (const LidarCalibration& lidar : result.lidars) {
    LidarRow row;
    row.lidar = lidar.lidar;
    row.T_base_lidar = lidar.T_base_lidar;
    row.sigma = lidar.sigma;
    if (const LidarInfo* info = rig.FindLidar(lidar.lidar)) row.T_base_lidar_initial = info->T_base_lidar;
    row.T_base_lidar_truth = true_lidar(lidar.lidar);
    data.lidars.push_back(row);
  }
  for (const PairCalibration& pair : result.pairs) {
    PairRow row;
    row.camera = pair.camera;
    row.lidar = pair.lidar;
    row.T_camera_lidar = pair.T_camera_lidar;
    row.final_cost = pair.cost;
    const CameraInfo* camera = rig.FindCamera(pair.camera);
    const LidarInfo* lidar = rig.FindLidar(pair.lidar);
    if (camera && lidar) row.T_camera_lidar_initial = camera->T_camera_base() * lidar->T_base_lidar;
    for (const PairReport& report : outcome.pairs) {
      if (report.camera != pair.camera || report.lidar != pair.lidar) continue;
      row.initial_cost = report.initial_cost;
      row.final_cost = report.final_cost;
      row.scenes = report.scenes;
      row.scenes_used = report.scenes_used;
      row.T_camera_lidar_initial = report.T_camera_lidar_initial;
    }
    if (const auto T_base_lidar_truth = true_lidar(pair.lidar); T_base_lidar_truth && camera) {
      Eigen::Isometry3d T_base_camera = camera->T_base_camera;
      if (auto it = truth->T_base_camera.find(pair.camera); it != truth->T_base_camera.end())
        T_base_camera = it->second;
      row.T_camera_lidar_truth = T_base_camera.inverse() * *T_base_lidar_truth;
    }
    data.pairs.push_back(row);
  }
  for (const OptimisationReport& report : outcome.optimisations) {
    OptimisationRow row;
    row.problem = report.problem;
    // One run per stage (and restart), by the simplex or by L-BFGS.
    row.stages = static_cast<int>(report.stages.size() + report.gradient_runs.size());
    for (const NelderMeadSummary& stage : report.stages) row.iterations += stage.iterations;
    for (const GradientSolverSummary& run : report.gradient_runs) row.iterations += run.iterations;
    row.evaluations = report.evaluations;
    row.seconds = report.seconds;
    if (!report.stages.empty()) row.termination = report.stages.back().BriefReport();
    if (!report.gradient_runs.empty()) row.termination = report.gradient_runs.back().BriefReport();
    data.optimisations.push_back(row);
  }
  return data;
}

ConvergenceSeries ConvergenceFromHistory(const std::vector<AlternationRecord>& history, int pair,
                                         const std::string& label, const std::optional<Eigen::Isometry3d>& truth) {
  ConvergenceSeries series;
  series.label = label;
  series.truth = truth;
  if (pair < 0) return series;
  const std::size_t p = static_cast<std::size_t>(pair);
  for (const AlternationRecord& record : history) {
    if (p >= record.T_camera_lidar_lower.size() || p >= record.T_camera_lidar_upper.size()) continue;
    series.alternations.push_back(record.alternation);
    series.lower.push_back(record.T_camera_lidar_lower[p]);
    series.upper.push_back(record.T_camera_lidar_upper[p]);
    series.lower_cost.push_back(p < record.lower_cost.size() ? record.lower_cost[p]
                                                             : std::numeric_limits<double>::quiet_NaN());
  }
  return series;
}

std::vector<OverlayFigure> MakePairOverlays(const PairCost& cost, const Eigen::Isometry3d& T_camera_lidar_initial,
                                            const Eigen::Isometry3d& T_camera_lidar_result,
                                            const std::string& file_stem, int max_scenes,
                                            const OverlayOptions& options) {
  const std::vector<SceneSwathe>& scenes = cost.Scenes();
  std::vector<std::pair<std::size_t, std::size_t>> by_points;  // (projected points, scene)
  for (std::size_t s = 0; s < scenes.size(); ++s)
    by_points.emplace_back(scenes[s].CountProjected(T_camera_lidar_result), s);
  std::stable_sort(by_points.begin(), by_points.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<OverlayFigure> figures;
  const std::size_t count = std::min<std::size_t>(by_points.size(), static_cast<std::size_t>(std::max(0, max_scenes)));
  for (std::size_t i = 0; i < count; ++i) {
    const SceneSwathe& scene = scenes[by_points[i].second];
    const std::string where =
        fmt::format("{} / {}, image t = {} us", cost.Camera().name, cost.Lidar(), static_cast<long long>(scene.ImageTime()));
    OverlayFigure comparison;
    comparison.title = "Initial guess (red) vs result (blue): " + where;
    comparison.caption = fmt::format("{} scans, {} points projected at the result.", scene.ScanCount(),
                                     by_points[i].first);
    comparison.file_name = fmt::format("{}_{}_initial_vs_result.png", file_stem, i);
    comparison.bgr = RenderComparisonOverlay(scene, T_camera_lidar_initial, T_camera_lidar_result, options);
    figures.push_back(std::move(comparison));
    OverlayFigure reflectance;
    reflectance.title = "Result, coloured by reflectance: " + where;
    reflectance.file_name = fmt::format("{}_{}_reflectance.png", file_stem, i);
    reflectance.bgr = RenderReflectanceOverlay(scene, T_camera_lidar_result, options);
    figures.push_back(std::move(reflectance));
  }
  return figures;
}

std::string RenderCalibrationReport(const CalibrationReportData& data) {
  std::vector<std::string> header;
  if (!data.dataset.empty()) header.push_back("Dataset: " + H(data.dataset));
  std::string line;
  if (!data.scheme.empty()) line += "Scheme: <b>" + H(data.scheme) + "</b> ";
  if (!data.metric.empty()) line += "Metric: <b>" + H(data.metric) + "</b> ";
  line += fmt::format("&middot; {} lidar(s), {} pair(s)", data.lidars.size(), data.pairs.size());
  header.push_back(line);
  std::string out = PageOpen(data.title, header,
                             {{"summary", "Summary"},
                              {"convergence", "Convergence (Fig. 4)"},
                              {"uncertainty", "Uncertainty"},
                              {"cost-slices", "Cost slices (Fig. 6)"},
                              {"overlays", "Overlays (Fig. 9)"}});
  out += CalibrationSummary(data);
  out += UncertaintySection(data.lidars);
  out += ConvergenceSection(data.convergence);
  out += CostSliceSection(data.cost_slices);
  out += OverlaySection(data.overlays);
  return out + PageClose();
}

std::vector<ReportFile> CalibrationReportAttachments(const CalibrationReportData& data) {
  return OverlayFiles(data.overlays);
}

ExperimentRun MakeExperimentRun(const std::string& method, const std::string& lidar, int trial,
                                const Eigen::Isometry3d& T_base_lidar_estimate,
                                const Eigen::Isometry3d& T_base_lidar_truth, double seconds, bool success,
                                const std::string& termination) {
  ExperimentRun run;
  run.method = method;
  run.lidar = lidar;
  run.trial = trial;
  run.success = success;
  run.termination = termination;
  run.error = TupleError(T_base_lidar_estimate, T_base_lidar_truth);
  run.translation_error_m = TranslationError(T_base_lidar_estimate, T_base_lidar_truth);
  run.rotation_error_deg = RotationErrorDegrees(T_base_lidar_estimate, T_base_lidar_truth);
  run.seconds = seconds;
  return run;
}

std::string RenderExperimentReport(const ExperimentReportData& data) {
  const std::vector<std::string> methods = MethodOrder(data);
  std::vector<std::string> header;
  header.push_back(fmt::format("{} run(s), {} method(s)", data.runs.size(), methods.size()));
  std::string out = PageOpen(data.title, header,
                             {{"summary", "Summary"},
                              {"box-plots", "Errors per method (Fig. 7)"},
                              {"per-dof-errors", "Errors per DoF (Fig. 8)"},
                              {"runs", "Runs"},
                              {"overlays", "Overlays"}});
  out += ExperimentSummarySection(data, methods);
  out += ErrorBoxPlotSection(data, methods);
  out += PerDofErrorSection(data, methods);
  out += RunsSection(data.runs);
  out += OverlaySection(data.overlays);
  return out + PageClose();
}

std::vector<ReportFile> ExperimentReportAttachments(const ExperimentReportData& data) {
  return OverlayFiles(data.overlays);
}

void WriteReportDirectory(const std::string& directory, const std::string& html,
                          const std::vector<ReportFile>& attachments, const std::string& html_name) {
  const std::filesystem::path root(directory);
  std::filesystem::create_directories(root);
  for (const ReportFile& file : attachments) io::WriteFileAtomically((root / SafeFileName(file.name)).string(), file.content);
  io::WriteFileAtomically((root / SafeFileName(html_name)).string(), html);
}

}  // namespace scenecal::report
