#include "report/svg.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <fmt/format.h>

namespace scenecal::report {

namespace {

constexpr const char* kFont = "font-family=\"DejaVu Sans, Helvetica, Arial, sans-serif\"";
constexpr const char* kAxisColour = "#444";
constexpr const char* kGridColour = "#e4e4e4";

// Pixel coordinates with two decimals: compact, and always finite by construction.
std::string Px(double value) { return fmt::format("{:.2f}", value); }

struct Range {
  double low = std::numeric_limits<double>::infinity();
  double high = -std::numeric_limits<double>::infinity();
  void Include(double value) {
    if (!std::isfinite(value)) return;
    low = std::min(low, value);
    high = std::max(high, value);
  }
  bool Empty() const { return !(low <= high); }
};

// Maps data to pixels over [low, high] -> [pixel_low, pixel_high].
struct Scale {
  double low, high, pixel_low, pixel_high;
  double operator()(double value) const {
    return pixel_low + (value - low) / (high - low) * (pixel_high - pixel_low);
  }
};

double TickStep(const std::vector<double>& ticks) { return ticks.size() >= 2 ? ticks[1] - ticks[0] : 1.0; }

std::string SvgOpen(int width, int height) {
  return fmt::format(
      "<svg width=\"{0}\" height=\"{1}\" viewBox=\"0 0 {0} {1}\" {2} "
      "font-size=\"11\">\n<rect x=\"0\" y=\"0\" width=\"{0}\" height=\"{1}\" fill=\"#ffffff\"/>\n",
      width, height, kFont);
}

std::string Text(double x, double y, const std::string& text, const char* anchor = "middle", int size = 11,
                 const std::string& extra = "") {
  return fmt::format("<text x=\"{}\" y=\"{}\" text-anchor=\"{}\" font-size=\"{}\" fill=\"#222\"{}>{}</text>\n",
                     Px(x), Px(y), anchor, size, extra, EscapeXml(text));
}

// Frame, grid, ticks, tick labels and axis labels of a plot area.
std::string Axes(const Scale& sx, const std::vector<double>& x_ticks, const Scale& sy,
                 const std::vector<double>& y_ticks, const std::string& x_label, const std::string& y_label,
                 int height, bool x_tick_labels) {
  std::string out;
  const double left = sx.pixel_low, right = sx.pixel_high, bottom = sy.pixel_low, top = sy.pixel_high;
  const double y_step = TickStep(y_ticks), x_step = TickStep(x_ticks);
  for (double tick : y_ticks) {
    const double y = sy(tick);
    out += fmt::format("<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"{}\"/>\n", Px(left), Px(y), Px(right),
                       Px(y), kGridColour);
    out += Text(left - 5, y + 3.5, FormatTick(tick, y_step), "end", 10);
  }
  for (double tick : x_ticks) {
    const double x = sx(tick);
    out += fmt::format("<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"{}\"/>\n", Px(x), Px(top), Px(x),
                       Px(bottom), kGridColour);
    if (x_tick_labels) out += Text(x, bottom + 14, FormatTick(tick, x_step), "middle", 10);
  }
  out += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"{}\"/>\n", Px(left),
                     Px(top), Px(right - left), Px(bottom - top), kAxisColour);
  if (!x_label.empty()) out += Text(0.5 * (left + right), height - 6, x_label, "middle", 11);
  if (!y_label.empty()) {
    const double cx = 13, cy = 0.5 * (top + bottom);
    out += Text(cx, cy, y_label, "middle", 11, fmt::format(" transform=\"rotate(-90 {} {})\"", Px(cx), Px(cy)));
  }
  return out;
}

// The frame of a plot with categories along x (box and interval plots): its
// size and margins, the scales (y over `y_range`, x one unit per category),
// and the opening of its <svg> with the title and the axes.
struct CategoryFrame {
  int width = 0, height = 0;
  double left = 0, right = 0, top = 0, bottom = 0;
  std::vector<double> y_ticks;
  Scale sx{}, sy{};
  std::string open;  // <svg ...>, the title and the axes
};

CategoryFrame MakeCategoryFrame(int width_px, int height_px, const std::string& title, const std::string& y_label,
                                std::size_t categories, const Range& y_range) {
  CategoryFrame f;
  f.width = std::max(160, width_px);
  f.height = std::max(120, height_px);
  f.left = 62;
  f.right = f.width - 12.0;
  f.top = title.empty() ? 10.0 : 26.0;
  f.bottom = f.height - 40.0;  // room for the category labels
  f.y_ticks = NiceTicks(y_range.low, y_range.high, std::max(3, (f.height - 60) / 45));
  f.sy = {f.y_ticks.front(), f.y_ticks.back(), f.bottom, f.top};
  f.sx = {0.0, static_cast<double>(std::max<std::size_t>(1, categories)), f.left, f.right};
  f.open = SvgOpen(f.width, f.height);
  if (!title.empty()) f.open += Text(0.5 * (f.left + f.right), 17, title, "middle", 12, " font-weight=\"bold\"");
  f.open += Axes(f.sx, {}, f.sy, f.y_ticks, "", y_label, f.height, false);
  return f;
}

std::string MarkerShape(Marker marker, double x, double y, const std::string& colour) {
  switch (marker) {
    case Marker::kCircle:
      return fmt::format("<circle cx=\"{}\" cy=\"{}\" r=\"3\" fill=\"{}\" stroke=\"#fff\" stroke-width=\"0.6\"/>\n",
                         Px(x), Px(y), colour);
    case Marker::kSquare:
      return fmt::format("<rect x=\"{}\" y=\"{}\" width=\"6\" height=\"6\" fill=\"{}\" stroke=\"#fff\" "
                         "stroke-width=\"0.6\"/>\n",
                         Px(x - 3), Px(y - 3), colour);
    case Marker::kNone:
      break;
  }
  return {};
}

struct LegendEntry {
  std::string label, colour;
  Marker marker = Marker::kNone;
  bool line = true;
  std::string dash;
  bool box = false;
};

// Legend box in the top-right corner of the plot area.
std::string Legend(const std::vector<LegendEntry>& entries, double right, double top) {
  if (entries.empty()) return {};
  std::size_t longest = 0;
  for (const LegendEntry& entry : entries) longest = std::max(longest, entry.label.size());
  const double width = 34 + 6.2 * static_cast<double>(longest), row = 15;
  const double height = 6 + row * static_cast<double>(entries.size());
  const double x0 = right - width - 6, y0 = top + 6;
  std::string out = fmt::format(
      "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"#ffffff\" fill-opacity=\"0.85\" stroke=\"#bbb\"/>\n",
      Px(x0), Px(y0), Px(width), Px(height));
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const LegendEntry& entry = entries[i];
    const double y = y0 + 3 + row * (static_cast<double>(i) + 0.5);
    if (entry.box) {
      out += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"18\" height=\"9\" fill=\"{}\" fill-opacity=\"0.35\" "
                         "stroke=\"{}\"/>\n",
                         Px(x0 + 6), Px(y - 4.5), entry.colour, entry.colour);
    } else {
      if (entry.line)
        out += fmt::format("<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"{}\" stroke-width=\"2\"{}/>\n",
                           Px(x0 + 6), Px(y), Px(x0 + 24), Px(y), entry.colour,
                           entry.dash.empty() ? "" : fmt::format(" stroke-dasharray=\"{}\"", EscapeXml(entry.dash)));
      out += MarkerShape(entry.marker, x0 + 15, y, entry.colour);
    }
    out += Text(x0 + 30, y + 3.5, entry.label, "start", 10);
  }
  return out;
}

}  // namespace

std::string EscapeXml(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += c;
    }
  }
  return out;
}

std::vector<double> NiceTicks(double low, double high, int target_count) {
  if (!std::isfinite(low) || !std::isfinite(high)) return {0.0, 1.0};
  if (high < low) std::swap(low, high);
  if (high - low <= 1e-12 * std::max(1.0, std::abs(high))) {
    const double pad = std::abs(low) > 0 ? 0.1 * std::abs(low) : 1.0;
    low -= pad;
    high += pad;
  }
  target_count = std::max(2, target_count);
  const double raw_step = (high - low) / (target_count - 1);
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw_step)));
  double step = magnitude;
  for (double factor : {1.0, 2.0, 2.5, 5.0, 10.0}) {
    step = factor * magnitude;
    if (step >= raw_step) break;
  }
  std::vector<double> ticks;
  const double first = std::floor(low / step + 1e-9) * step;
  for (double tick = first; tick <= high + step * (1 - 1e-9); tick += step) {
    // Snap to the step grid so 0.30000000000000004 prints and compares as 0.3.
    ticks.push_back(std::round(tick / step) * step);
    if (ticks.size() > 100) break;
  }
  return ticks;
}

std::string FormatTick(double value, double step) {
  step = std::abs(step);
  int decimals = 0;
  if (step > 0 && std::isfinite(step)) {
    decimals = std::max(0, static_cast<int>(std::ceil(-std::log10(step) - 1e-9)));
    // Steps like 2.5 x 10^k need one decimal more than 10^k.
    const double scaled = step * std::pow(10.0, decimals);
    if (std::abs(scaled - std::round(scaled)) > 1e-6) ++decimals;
  }
  decimals = std::min(decimals, 12);
  if (std::abs(value) < step * 1e-9) value = 0.0;  // no "-0"
  return fmt::format("{:.{}f}", value, decimals);
}

const std::string& PaletteColour(std::size_t index) {
  static const std::array<std::string, 10> kPalette = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd",
                                                       "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};
  return kPalette[index % kPalette.size()];
}

std::string SequentialColour(double t) {
  t = std::clamp(std::isfinite(t) ? t : 0.0, 0.0, 1.0);
  // From #c6dbef (light blue) to #08306b (dark blue).
  const auto mix = [t](int a, int b) { return static_cast<int>(std::lround(a + (b - a) * t)); };
  return fmt::format("#{:02x}{:02x}{:02x}", mix(0xc6, 0x08), mix(0xdb, 0x30), mix(0xef, 0x6b));
}

std::string RenderLinePlot(const LinePlot& plot) {
  const int width = std::max(160, plot.width_px), height = std::max(120, plot.height_px);
  const double left = 62, right = width - 12.0, top = plot.title.empty() ? 10.0 : 26.0;
  const double bottom = height - (plot.x_label.empty() ? 24.0 : 38.0);

  Range x_range, y_range;
  for (const Series& series : plot.series) {
    const std::size_t n = std::min(series.x.size(), series.y.size());
    for (std::size_t i = 0; i < n; ++i) {
      if (!std::isfinite(series.x[i]) || !std::isfinite(series.y[i])) continue;
      x_range.Include(series.x[i]);
      y_range.Include(series.y[i]);
    }
  }
  if (plot.reference_y) y_range.Include(*plot.reference_y);
  if (plot.reference_x) x_range.Include(*plot.reference_x);
  if (x_range.Empty()) x_range = {0.0, 1.0};
  if (y_range.Empty()) y_range = {0.0, 1.0};
  const std::vector<double> x_ticks = NiceTicks(x_range.low, x_range.high, std::max(3, (width - 80) / 70));
  const std::vector<double> y_ticks = NiceTicks(y_range.low, y_range.high, std::max(3, (height - 60) / 45));
  const Scale sx{x_ticks.front(), x_ticks.back(), left, right};
  const Scale sy{y_ticks.front(), y_ticks.back(), bottom, top};

  std::string out = SvgOpen(width, height);
  if (!plot.title.empty()) out += Text(0.5 * (left + right), 17, plot.title, "middle", 12, " font-weight=\"bold\"");
  out += Axes(sx, x_ticks, sy, y_ticks, plot.x_label, plot.y_label, height, true);
  const auto reference = [&](double x1, double y1, double x2, double y2) {
    return fmt::format("<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"#888\" stroke-dasharray=\"5 4\"/>\n",
                       Px(x1), Px(y1), Px(x2), Px(y2));
  };
  if (plot.reference_y) out += reference(left, sy(*plot.reference_y), right, sy(*plot.reference_y));
  if (plot.reference_x) out += reference(sx(*plot.reference_x), top, sx(*plot.reference_x), bottom);

  std::vector<LegendEntry> legend;
  for (const Series& series : plot.series) {
    const std::size_t n = std::min(series.x.size(), series.y.size());
    const std::string colour = EscapeXml(series.colour);
    if (series.line) {
      // One polyline per run of finite points.
      std::string points;
      const auto flush = [&] {
        if (!points.empty())
          out += fmt::format("<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"{}\"{} "
                             "stroke-linejoin=\"round\"/>\n",
                             points, colour, Px(series.line_width),
                             series.dash.empty() ? "" : fmt::format(" stroke-dasharray=\"{}\"", EscapeXml(series.dash)));
        points.clear();
      };
      for (std::size_t i = 0; i < n; ++i) {
        if (!std::isfinite(series.x[i]) || !std::isfinite(series.y[i])) {
          flush();
          continue;
        }
        if (!points.empty()) points += ' ';
        points += Px(sx(series.x[i])) + "," + Px(sy(series.y[i]));
      }
      flush();
    }
    for (std::size_t i = 0; i < n; ++i)
      if (std::isfinite(series.x[i]) && std::isfinite(series.y[i]))
        out += MarkerShape(series.marker, sx(series.x[i]), sy(series.y[i]), colour);
    if (series.in_legend && !series.label.empty())
      legend.push_back({series.label, colour, series.marker, series.line, series.dash, false});
  }
  if (plot.legend) out += Legend(legend, right, top);
  out += "</svg>\n";
  return out;
}

double SortedQuantile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return std::numeric_limits<double>::quiet_NaN();
  const double position = std::clamp(p, 0.0, 1.0) * static_cast<double>(sorted.size() - 1);
  const std::size_t below = static_cast<std::size_t>(std::floor(position));
  const std::size_t above = std::min(below + 1, sorted.size() - 1);
  const double fraction = position - static_cast<double>(below);
  return sorted[below] + fraction * (sorted[above] - sorted[below]);
}

BoxStatistics ComputeBoxStatistics(std::vector<double> values) {
  values.erase(std::remove_if(values.begin(), values.end(), [](double v) { return !std::isfinite(v); }),
               values.end());
  std::sort(values.begin(), values.end());
  BoxStatistics stats;
  stats.count = values.size();
  if (values.empty()) return stats;
  stats.q1 = SortedQuantile(values, 0.25);
  stats.median = SortedQuantile(values, 0.5);
  stats.q3 = SortedQuantile(values, 0.75);
  const double iqr = stats.q3 - stats.q1;
  const double low_fence = stats.q1 - 1.5 * iqr, high_fence = stats.q3 + 1.5 * iqr;
  stats.lower_whisker = stats.q1;
  stats.upper_whisker = stats.q3;
  for (double v : values) {
    if (v < low_fence || v > high_fence) {
      stats.outliers.push_back(v);
    } else {
      stats.lower_whisker = std::min(stats.lower_whisker, v);
      stats.upper_whisker = std::max(stats.upper_whisker, v);
    }
  }
  return stats;
}

std::string RenderBoxPlot(const BoxPlot& plot) {
  const std::size_t categories = std::max<std::size_t>(1, plot.categories.size());
  const std::size_t series_count = std::max<std::size_t>(1, plot.series.size());

  std::vector<std::vector<BoxStatistics>> stats(plot.series.size());
  Range y_range;
  if (plot.y_from_zero) y_range.Include(0.0);
  for (std::size_t s = 0; s < plot.series.size(); ++s) {
    for (std::size_t c = 0; c < plot.categories.size(); ++c) {
      const std::vector<double> empty;
      const std::vector<double>& values =
          c < plot.series[s].values_per_category.size() ? plot.series[s].values_per_category[c] : empty;
      stats[s].push_back(ComputeBoxStatistics(values));
      const BoxStatistics& b = stats[s].back();
      if (b.count == 0) continue;
      y_range.Include(b.lower_whisker);
      y_range.Include(b.upper_whisker);
      for (double o : b.outliers) y_range.Include(o);
    }
  }
  if (y_range.Empty()) y_range = {0.0, 1.0};
  const CategoryFrame frame =
      MakeCategoryFrame(plot.width_px, plot.height_px, plot.title, plot.y_label, plot.categories.size(), y_range);
  const double right = frame.right, top = frame.top, bottom = frame.bottom;
  const Scale &sx = frame.sx, &sy = frame.sy;
  std::string out = frame.open;
  const double category_px = (right - frame.left) / static_cast<double>(categories);
  const double box_px = std::min(40.0, 0.75 * category_px / static_cast<double>(series_count));
  for (std::size_t c = 0; c < plot.categories.size(); ++c) {
    const double centre = sx(static_cast<double>(c) + 0.5);
    out += Text(centre, bottom + 14, plot.categories[c], "middle", 10);
    if (c > 0)
      out += fmt::format("<line x1=\"{0}\" y1=\"{1}\" x2=\"{0}\" y2=\"{2}\" stroke=\"{3}\"/>\n",
                         Px(sx(static_cast<double>(c))), Px(top), Px(bottom), kGridColour);
    for (std::size_t s = 0; s < plot.series.size(); ++s) {
      const BoxStatistics& b = stats[s][c];
      const std::string colour = EscapeXml(plot.series[s].colour);
      const double x = centre + (static_cast<double>(s) - 0.5 * static_cast<double>(series_count - 1)) * box_px * 1.15;
      const double half = 0.5 * box_px;
      if (b.count == 0) {
        out += Text(x, bottom - 4, "n/a", "middle", 9);
        continue;
      }
      out += fmt::format("<g><title>{}</title>\n",
                         EscapeXml(fmt::format("{} / {}: n={}, median {:.4g}, IQR [{:.4g}, {:.4g}]",
                                               plot.categories[c], plot.series[s].label, b.count, b.median, b.q1,
                                               b.q3)));
      // Whiskers, box (quartiles), median line, outliers.
      out += fmt::format("<line x1=\"{0}\" y1=\"{1}\" x2=\"{0}\" y2=\"{2}\" stroke=\"{3}\"/>\n", Px(x),
                         Px(sy(b.lower_whisker)), Px(sy(b.q1)), colour);
      out += fmt::format("<line x1=\"{0}\" y1=\"{1}\" x2=\"{0}\" y2=\"{2}\" stroke=\"{3}\"/>\n", Px(x),
                         Px(sy(b.q3)), Px(sy(b.upper_whisker)), colour);
      for (double w : {b.lower_whisker, b.upper_whisker})
        out += fmt::format("<line x1=\"{0}\" y1=\"{2}\" x2=\"{1}\" y2=\"{2}\" stroke=\"{3}\"/>\n", Px(x - 0.5 * half),
                           Px(x + 0.5 * half), Px(sy(w)), colour);
      out += fmt::format("<rect class=\"box\" x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\" "
                         "fill-opacity=\"0.35\" stroke=\"{}\"/>\n",
                         Px(x - half), Px(sy(b.q3)), Px(box_px), Px(std::max(0.5, sy(b.q1) - sy(b.q3))), colour,
                         colour);
      out += fmt::format("<line x1=\"{0}\" y1=\"{2}\" x2=\"{1}\" y2=\"{2}\" stroke=\"{3}\" stroke-width=\"2\"/>\n",
                         Px(x - half), Px(x + half), Px(sy(b.median)), colour);
      for (double o : b.outliers)
        out += fmt::format("<circle cx=\"{}\" cy=\"{}\" r=\"2.5\" fill=\"none\" stroke=\"{}\"/>\n", Px(x),
                           Px(sy(o)), colour);
      out += "</g>\n";
    }
  }
  if (plot.legend && plot.series.size() > 1) {
    std::vector<LegendEntry> legend;
    for (const BoxSeries& series : plot.series)
      legend.push_back({series.label, EscapeXml(series.colour), Marker::kNone, false, "", true});
    out += Legend(legend, right, top);
  }
  out += "</svg>\n";
  return out;
}

std::string RenderIntervalPlot(const IntervalPlot& plot) {
  const std::size_t categories = std::max<std::size_t>(1, plot.categories.size());
  const auto finite = [](const IntervalCategory& c) {
    return std::isfinite(c.low) && std::isfinite(c.high) && std::isfinite(c.centre);
  };

  Range y_range;
  y_range.Include(0.0);
  for (const IntervalCategory& c : plot.categories) {
    if (finite(c)) {
      y_range.Include(c.low);
      y_range.Include(c.high);
    }
    if (c.point) y_range.Include(*c.point);
  }
  if (plot.limit && std::isfinite(*plot.limit)) {
    y_range.Include(*plot.limit);
    y_range.Include(-*plot.limit);
  }
  if (y_range.Empty() || y_range.low == y_range.high) y_range = {-1.0, 1.0};
  y_range.Include(y_range.high + 0.5 * (y_range.high - y_range.low));  // room for the legend above the bars
  const CategoryFrame frame =
      MakeCategoryFrame(plot.width_px, plot.height_px, plot.title, plot.y_label, plot.categories.size(), y_range);
  const double left = frame.left, right = frame.right, top = frame.top, bottom = frame.bottom;
  const Scale &sx = frame.sx, &sy = frame.sy;
  std::string out = frame.open;
  const std::string colour = EscapeXml(plot.colour);
  const bool any_point = std::any_of(plot.categories.begin(), plot.categories.end(),
                                     [](const IntervalCategory& c) { return c.point.has_value(); });
  if (plot.limit && std::isfinite(*plot.limit)) {
    for (double y : {*plot.limit, -*plot.limit})
      out += fmt::format("<line x1=\"{0}\" y1=\"{2}\" x2=\"{1}\" y2=\"{2}\" stroke=\"#2ca02c\" "
                         "stroke-dasharray=\"5 4\"/>\n",
                         Px(left), Px(right), Px(sy(y)));
  }
  const double category_px = (right - left) / static_cast<double>(categories);
  const double half = std::min(14.0, 0.25 * category_px);
  for (std::size_t i = 0; i < plot.categories.size(); ++i) {
    const IntervalCategory& c = plot.categories[i];
    const double x = sx(static_cast<double>(i) + 0.5);
    out += Text(x, bottom + 14, c.label, "middle", 10);
    if (!finite(c)) {
      out += Text(x, bottom - 4, "n/a", "middle", 9);
      continue;
    }
    out += fmt::format("<g><title>{}</title>\n",
                       EscapeXml(fmt::format("{}: {} [{:.4g}, {:.4g}]{}", c.label, plot.interval_label, c.low,
                                             c.high,
                                             c.point ? fmt::format("; {} {:.4g}", plot.point_label, *c.point) : "")));
    out += fmt::format("<rect class=\"interval\" x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\" "
                       "fill-opacity=\"0.3\" stroke=\"{}\"/>\n",
                       Px(x - half), Px(sy(c.high)), Px(2 * half), Px(std::max(0.5, sy(c.low) - sy(c.high))), colour,
                       colour);
    out += fmt::format("<line x1=\"{0}\" y1=\"{2}\" x2=\"{1}\" y2=\"{2}\" stroke=\"{3}\" stroke-width=\"2\"/>\n",
                       Px(x - half), Px(x + half), Px(sy(c.centre)), colour);
    if (c.point) out += MarkerShape(Marker::kCircle, x, sy(*c.point), "#d62728");
    out += "</g>\n";
  }
  std::vector<LegendEntry> legend{{plot.interval_label, colour, Marker::kNone, false, "", true}};
  if (any_point) legend.push_back({plot.point_label, "#d62728", Marker::kCircle, false, "", false});
  if (plot.limit && std::isfinite(*plot.limit)) legend.push_back({plot.limit_label, "#2ca02c", Marker::kNone, true, "5 4", false});
  out += Legend(legend, right, top);
  out += "</svg>\n";
  return out;
}

std::string StandaloneSvg(const std::string& svg) {
  if (svg.rfind("<svg", 0) != 0) return svg;
  return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\"" + svg.substr(4);
}

void SvgSize(const std::string& svg, int* width_px, int* height_px) {
  const auto attribute = [&](const char* name) {
    const std::string key = std::string(" ") + name + "=\"";
    const std::size_t open_end = svg.find('>');
    const std::size_t at = svg.find(key);
    if (at == std::string::npos || at > open_end) return 0;
    return std::atoi(svg.c_str() + at + key.size());
  };
  if (width_px) *width_px = attribute("width");
  if (height_px) *height_px = attribute("height");
}

std::string SmallMultiples(const std::vector<std::string>& panels, int columns, const std::string& title) {
  columns = std::max(1, std::min<int>(columns, static_cast<int>(std::max<std::size_t>(1, panels.size()))));
  int cell_width = 1, cell_height = 1;
  for (const std::string& panel : panels) {
    int w = 0, h = 0;
    SvgSize(panel, &w, &h);
    cell_width = std::max(cell_width, w);
    cell_height = std::max(cell_height, h);
  }
  const int rows = (static_cast<int>(panels.size()) + columns - 1) / columns;
  const int title_px = title.empty() ? 0 : 24;
  const int width = columns * cell_width, height = title_px + std::max(1, rows) * cell_height;
  std::string out = SvgOpen(width, height);
  if (!title.empty()) out += Text(0.5 * width, 17, title, "middle", 13, " font-weight=\"bold\"");
  for (std::size_t i = 0; i < panels.size(); ++i) {
    const std::string& panel = panels[i];
    const int x = static_cast<int>(i % static_cast<std::size_t>(columns)) * cell_width;
    const int y = title_px + static_cast<int>(i / static_cast<std::size_t>(columns)) * cell_height;
    // A nested <svg> is placed by its x and y attributes.
    if (panel.rfind("<svg", 0) == 0)
      out += fmt::format("<svg x=\"{}\" y=\"{}\"{}", x, y, std::string_view(panel).substr(4));
  }
  out += "</svg>\n";
  return out;
}

}  // namespace scenecal::report
