// A small, dependency-free SVG plotting kit for reports a person reads: line
// plots (several series, markers, legend), grouped box plots, and a grid of
// small multiples. Output is a standalone <svg> element (no XML prolog, no
// scripts, no external references) that can be inlined in HTML or saved as a
// .svg file. All text is XML-escaped; non-finite data values are skipped
// (a line breaks at them), so the output never contains "nan" or "inf".
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace scenecal::report {

// Escapes & < > " ' for XML/HTML text and attribute values.
std::string EscapeXml(std::string_view text);

// "Nice" tick positions (1, 2, 5 x 10^k steps) covering [low, high], about
// target_count of them. A degenerate range is widened around its value.
std::vector<double> NiceTicks(double low, double high, int target_count = 5);

// Formats a tick value with just enough decimals for the tick step.
std::string FormatTick(double value, double step);

// Colours as CSS strings ("#1f77b4").
const std::string& PaletteColour(std::size_t index);  // Tableau-10, cycles
// Light (t = 0) to dark (t = 1) blue, for sequences such as alternations.
std::string SequentialColour(double t);

enum class Marker { kNone, kCircle, kSquare };

struct Series {
  std::string label;
  std::vector<double> x, y;  // same length; non-finite pairs are skipped
  std::string colour = "#1f77b4";
  bool line = true;
  Marker marker = Marker::kNone;
  double line_width = 1.5;
  std::string dash;         // SVG stroke-dasharray, e.g. "4 3"; empty = solid
  bool in_legend = true;    // false hides the series from the legend
};

struct LinePlot {
  std::string title;
  std::string x_label;
  std::string y_label;
  std::vector<Series> series;
  // Horizontal reference line (e.g. 0 error, or the true value), dashed grey.
  std::optional<double> reference_y;
  std::optional<double> reference_x;  // vertical reference line
  int width_px = 420;
  int height_px = 280;
  bool legend = true;
};

std::string RenderLinePlot(const LinePlot& plot);

// Tukey box-plot statistics. Quartiles by linear interpolation between order
// statistics (R type 7 / numpy's default): q(p) at position p * (n - 1) of the
// sorted values. Whiskers reach the most extreme values within 1.5 IQR of the
// box; values beyond are outliers. Non-finite values are ignored.
struct BoxStatistics {
  std::size_t count = 0;
  double lower_whisker = 0, q1 = 0, median = 0, q3 = 0, upper_whisker = 0;
  std::vector<double> outliers;  // ascending
};
BoxStatistics ComputeBoxStatistics(std::vector<double> values);
// Linear-interpolation quantile of ascending, finite values (p in [0, 1]).
double SortedQuantile(const std::vector<double>& sorted, double p);

// A series of a grouped box plot: one sample set per category.
struct BoxSeries {
  std::string label;
  std::string colour = "#1f77b4";
  std::vector<std::vector<double>> values_per_category;  // size = categories.size()
};

struct BoxPlot {
  std::string title;
  std::string y_label;
  std::vector<std::string> categories;  // along x
  std::vector<BoxSeries> series;        // side by side within each category
  bool y_from_zero = true;              // errors: start the axis at 0
  int width_px = 520;
  int height_px = 300;
  bool legend = true;
};

std::string RenderBoxPlot(const BoxPlot& plot);

// Intervals per category (e.g. +-2 sigma per degree of freedom): a bar from
// low to high around a centre tick, an optional point (e.g. the error to the
// truth) and optional symmetric limits drawn as dashed lines at +-limit (e.g.
// what counts as good). Categories with non-finite bounds show "n/a".
struct IntervalCategory {
  std::string label;
  double low = 0.0, centre = 0.0, high = 0.0;
  std::optional<double> point;
};

struct IntervalPlot {
  std::string title;
  std::string y_label;
  std::vector<IntervalCategory> categories;
  std::string interval_label = "interval";
  std::string point_label = "point";
  std::optional<double> limit;  // dashed lines at +-limit
  std::string limit_label = "limit";
  std::string colour = "#1f77b4";
  int width_px = 360;
  int height_px = 260;
};

std::string RenderIntervalPlot(const IntervalPlot& plot);

// Lays out panels (each an <svg> from the functions above) in a grid of
// `columns`, left to right then top to bottom, as one <svg>. The cell size is
// the largest panel; an optional title runs across the top.
std::string SmallMultiples(const std::vector<std::string>& panels, int columns, const std::string& title = "");

// The element as a standalone .svg file: XML prolog and the SVG namespace.
std::string StandaloneSvg(const std::string& svg);

// Width and height attributes of an <svg> element string (0 when absent).
void SvgSize(const std::string& svg, int* width_px, int* height_px);

}  // namespace scenecal::report
