// Tests of the report kit: SVG plots, box-plot statistics, overlays, cost
// slices and the self-contained HTML pages.
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>
#include <opencv2/imgcodecs.hpp>

#include "core/camera.hpp"
#include "core/geometry.hpp"
#include "core/scenes.hpp"
#include "core/swathe.hpp"
#include "core/upper_level.hpp"
#include "report/cost_slices.hpp"
#include "report/html_report.hpp"
#include "report/overlay.hpp"
#include "report/svg.hpp"

namespace scenecal::report {
namespace {

const std::set<std::string> kVoidHtmlElements = {"meta", "img", "br", "hr", "input", "link", "area", "base",
                                                 "col", "embed", "source", "track", "wbr"};

// A simple well-formedness check: every opening tag is closed in order
// (self-closing "/>" and HTML void elements excepted), no stray '<' in text.
// Returns an empty string when balanced, else what went wrong.
std::string TagBalanceProblem(const std::string& text) {
  std::vector<std::string> stack;
  std::size_t pos = 0;
  while ((pos = text.find('<', pos)) != std::string::npos) {
    const std::size_t end = text.find('>', pos);
    if (end == std::string::npos) return "unterminated tag at " + std::to_string(pos);
    const std::string tag = text.substr(pos + 1, end - pos - 1);
    pos = end + 1;
    if (tag.empty()) return "empty tag";
    if (tag[0] == '!' || tag[0] == '?') continue;  // doctype, prolog
    if (tag.find('<') != std::string::npos) return "'<' inside a tag: " + tag;
    if (tag[0] == '/') {
      const std::string name = tag.substr(1);
      if (stack.empty() || stack.back() != name)
        return "closing </" + name + "> does not match <" + (stack.empty() ? std::string("none") : stack.back()) + ">";
      stack.pop_back();
      continue;
    }
    if (tag.back() == '/') continue;  // self-closing
    const std::string name = tag.substr(0, tag.find_first_of(" \n\t"));
    if (kVoidHtmlElements.count(name)) continue;
    stack.push_back(name);
  }
  if (!stack.empty()) return "unclosed <" + stack.back() + ">";
  return {};
}

// Every numeric attribute value (x="..", points="..", etc.) parses as finite.
void ExpectFiniteNumbers(const std::string& svg) {
  EXPECT_EQ(svg.find("nan"), std::string::npos);
  EXPECT_EQ(svg.find("inf"), std::string::npos);
  const std::regex attribute(R"re(\s(x|y|x1|x2|y1|y2|cx|cy|r|width|height)="([^"]*)")re");
  int checked = 0;
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), attribute); it != std::sregex_iterator(); ++it) {
    const std::string value = (*it)[2];
    char* end = nullptr;
    const double number = std::strtod(value.c_str(), &end);
    EXPECT_TRUE(end != value.c_str() && *end == '\0' && std::isfinite(number))
        << (*it)[1] << "=\"" << value << "\"";
    ++checked;
  }
  EXPECT_GT(checked, 10);
}

TEST(Svg, EscapesMarkupCharacters) {
  EXPECT_EQ(EscapeXml("a<b & \"c\" > 'd'"), "a&lt;b &amp; &quot;c&quot; &gt; &#39;d&#39;");
  EXPECT_EQ(EscapeXml("plain"), "plain");
}

TEST(Svg, NiceTicksCoverTheRangeWithRoundSteps) {
  for (const auto& [low, high] : std::vector<std::pair<double, double>>{{0.0, 1.0}, {-0.0312, 0.047}, {3.0, 3.0},
                                                                       {0.8813, 0.9342}, {-250.0, 1700.0}}) {
    const std::vector<double> ticks = NiceTicks(low, high, 5);
    ASSERT_GE(ticks.size(), 2u) << low << " " << high;
    EXPECT_LE(ticks.front(), low);
    EXPECT_GE(ticks.back(), high);
    const double step = ticks[1] - ticks[0];
    const double mantissa = step / std::pow(10.0, std::floor(std::log10(step)));
    EXPECT_TRUE(std::abs(mantissa - 1) < 1e-9 || std::abs(mantissa - 2) < 1e-9 || std::abs(mantissa - 2.5) < 1e-9 ||
                std::abs(mantissa - 5) < 1e-9)
        << "step " << step;
    EXPECT_LE(ticks.size(), 12u);
  }
  EXPECT_EQ(FormatTick(0.30000000000000004, 0.1), "0.3");
  EXPECT_EQ(FormatTick(-1e-17, 0.5), "0.0");
  EXPECT_EQ(FormatTick(1.25, 0.25), "1.25");
  EXPECT_EQ(FormatTick(1500, 500), "1500");
}

TEST(Svg, LinePlotIsBalancedFiniteAndEscaped) {
  LinePlot plot;
  plot.title = "cost <NID> & more";
  plot.x_label = "alternation";
  plot.y_label = "x error (cm)";
  plot.reference_y = 0.0;
  Series a;
  a.label = "lower <a>";
  a.x = {0, 1, 2, 3, 4};
  a.y = {1.0, std::nan(""), 0.5, std::numeric_limits<double>::infinity(), 0.1};
  a.marker = Marker::kCircle;
  Series b;
  b.label = "upper";
  b.x = {0, 1, 2, 3, 4};
  b.y = {2.0, 1.0, 0.4, 0.2, 0.1};
  b.marker = Marker::kSquare;
  b.dash = "4 3";
  plot.series = {a, b};
  const std::string svg = RenderLinePlot(plot);
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  EXPECT_EQ(TagBalanceProblem(svg), "");
  ExpectFiniteNumbers(svg);
  EXPECT_NE(svg.find("cost &lt;NID&gt; &amp; more"), std::string::npos);
  EXPECT_NE(svg.find("lower &lt;a&gt;"), std::string::npos);
  EXPECT_EQ(svg.find("<NID>"), std::string::npos);
  // The NaN and the infinity break series a into three polylines; b is one.
  std::size_t polylines = 0;
  for (std::size_t at = svg.find("<polyline"); at != std::string::npos; at = svg.find("<polyline", at + 1)) ++polylines;
  EXPECT_EQ(polylines, 4u);
  // 3 finite circles of a (+1 in the legend), 5 squares of b (+1 legend).
  std::size_t circles = 0;
  for (std::size_t at = svg.find("<circle"); at != std::string::npos; at = svg.find("<circle", at + 1)) ++circles;
  EXPECT_EQ(circles, 4u);
}

TEST(Svg, EmptyPlotsStillRender) {
  const std::string line = RenderLinePlot(LinePlot{});
  EXPECT_EQ(TagBalanceProblem(line), "");
  BoxPlot box;
  box.categories = {"a"};
  box.series = {BoxSeries{"s", "#000", {{}}}};
  const std::string boxes = RenderBoxPlot(box);
  EXPECT_EQ(TagBalanceProblem(boxes), "");
  EXPECT_NE(boxes.find("n/a"), std::string::npos);
}

TEST(BoxStatistics, MatchHandComputedQuartilesWhiskersAndOutliers) {
  // Sorted: 1..9, 100. Positions p (n - 1): q1 at 2.25 -> 3 + 0.25 = 3.25;
  // median at 4.5 -> 5.5; q3 at 6.75 -> 7.75. IQR 4.5: fences -3.5 and 14.5,
  // so 100 is an outlier and the whiskers end at 1 and 9.
  const BoxStatistics stats = ComputeBoxStatistics({9, 2, 100, 4, 1, 7, 3, 8, 5, 6});
  EXPECT_EQ(stats.count, 10u);
  EXPECT_DOUBLE_EQ(stats.q1, 3.25);
  EXPECT_DOUBLE_EQ(stats.median, 5.5);
  EXPECT_DOUBLE_EQ(stats.q3, 7.75);
  EXPECT_DOUBLE_EQ(stats.lower_whisker, 1.0);
  EXPECT_DOUBLE_EQ(stats.upper_whisker, 9.0);
  ASSERT_EQ(stats.outliers.size(), 1u);
  EXPECT_DOUBLE_EQ(stats.outliers[0], 100.0);

  // Odd count, NaN ignored: 1 2 3 -> 1.5, 2, 2.5; no outliers.
  const BoxStatistics odd = ComputeBoxStatistics({3, std::nan(""), 1, 2});
  EXPECT_EQ(odd.count, 3u);
  EXPECT_DOUBLE_EQ(odd.q1, 1.5);
  EXPECT_DOUBLE_EQ(odd.median, 2.0);
  EXPECT_DOUBLE_EQ(odd.q3, 2.5);
  EXPECT_TRUE(odd.outliers.empty());

  // A low outlier: -20, 1, 2, 3, 4 -> q1 1, q3 3, fences -2 and 6.
  const BoxStatistics low = ComputeBoxStatistics({1, 2, 3, 4, -20});
  EXPECT_DOUBLE_EQ(low.q1, 1.0);
  EXPECT_DOUBLE_EQ(low.q3, 3.0);
  EXPECT_DOUBLE_EQ(low.lower_whisker, 1.0);
  EXPECT_DOUBLE_EQ(low.upper_whisker, 4.0);
  ASSERT_EQ(low.outliers.size(), 1u);
  EXPECT_DOUBLE_EQ(low.outliers[0], -20.0);

  EXPECT_EQ(ComputeBoxStatistics({}).count, 0u);
}

TEST(Svg, BoxPlotDrawsOneBoxPerSeriesAndCategory) {
  BoxPlot plot;
  plot.title = "errors";
  plot.y_label = "cm";
  plot.categories = {"x", "y", "z"};
  plot.series = {BoxSeries{"alt-nid", "#1f77b4", {{1, 2, 3, 4}, {1, 1, 2}, {5, 6, 7, 50}}},
                 BoxSeries{"mi <joint>", "#d62728", {{2, 3}, {4}, {0.5, 0.7, 0.9}}}};
  const std::string svg = RenderBoxPlot(plot);
  EXPECT_EQ(TagBalanceProblem(svg), "");
  ExpectFiniteNumbers(svg);
  std::size_t boxes = 0;
  for (std::size_t at = svg.find("class=\"box\""); at != std::string::npos; at = svg.find("class=\"box\"", at + 1))
    ++boxes;
  EXPECT_EQ(boxes, 6u);
  EXPECT_NE(svg.find("mi &lt;joint&gt;"), std::string::npos);
}

TEST(Svg, SmallMultiplesPlacesEveryPanel) {
  std::vector<std::string> panels;
  for (int k = 0; k < 6; ++k) {
    LinePlot plot;
    plot.title = "panel " + std::to_string(k);
    plot.width_px = 200;
    plot.height_px = 150;
    Series s;
    s.x = {0, 1};
    s.y = {static_cast<double>(k), k + 1.0};
    plot.series = {s};
    panels.push_back(RenderLinePlot(plot));
  }
  const std::string grid = SmallMultiples(panels, 3, "six panels");
  EXPECT_EQ(TagBalanceProblem(grid), "");
  int width = 0, height = 0;
  SvgSize(grid, &width, &height);
  EXPECT_EQ(width, 600);
  EXPECT_EQ(height, 24 + 2 * 150);
  EXPECT_NE(grid.find("<svg x=\"400\" y=\"174\""), std::string::npos);  // the sixth panel
  for (int k = 0; k < 6; ++k) EXPECT_NE(grid.find("panel " + std::to_string(k)), std::string::npos);
  const std::string file = StandaloneSvg(grid);
  EXPECT_EQ(file.rfind("<?xml", 0), 0u);
  EXPECT_NE(file.find("xmlns=\"http://www.w3.org/2000/svg\""), std::string::npos);
}

TEST(Overlay, Base64MatchesRfc4648Vectors) {
  EXPECT_EQ(Base64(""), "");
  EXPECT_EQ(Base64("f"), "Zg==");
  EXPECT_EQ(Base64("fo"), "Zm8=");
  EXPECT_EQ(Base64("foo"), "Zm9v");
  EXPECT_EQ(Base64("foob"), "Zm9vYg==");
  EXPECT_EQ(Base64("fooba"), "Zm9vYmE=");
  EXPECT_EQ(Base64("foobar"), "Zm9vYmFy");
  EXPECT_EQ(Base64(std::string("\xff\x00\x80", 3)), "/wCA");
}

CameraModel SmallCamera() {
  CameraModel camera;
  camera.width = 64;
  camera.height = 48;
  camera.fx = camera.fy = 50.0;
  camera.cx = 31.5;
  camera.cy = 23.5;
  return camera;
}

TEST(Overlay, ColoursThePixelsWhereKnownPointsProject) {
  const CameraModel camera = SmallCamera();
  const cv::Mat grey(48, 64, CV_32FC1, cv::Scalar(0.5));
  // Lidar frame = camera frame shifted: T_camera_lidar translates by +1 m in z.
  const Eigen::Isometry3d T_camera_lidar = TransformFromTuple((Vector6d() << 0, 0, 1, 0, 0, 0).finished());
  // Camera-frame points (x, y, 2): pixel u = 31.5 + 25 x, v = 23.5 + 25 y.
  const std::vector<Eigen::Vector3d> points_lidar = {
      {0.5 / 25, 0.5 / 25, 1.0},   // -> pixel (32, 24)
      {-0.7, -0.5, 1.0},           // -> (14, 11)
      {0.0, 0.0, -3.0},            // behind the camera: culled
      {10.0, 0.0, 1.0}};           // far outside the image: culled
  const std::vector<ProjectedPoint> projected = ProjectPoints(camera, T_camera_lidar, points_lidar, {0.0f, 1.0f, 1.0f, 1.0f});
  ASSERT_EQ(projected.size(), 2u);
  EXPECT_NEAR(projected[0].u, 32.0, 1e-4);
  EXPECT_NEAR(projected[0].v, 24.0, 1e-4);
  EXPECT_NEAR(projected[1].u, 14.0, 1e-4);
  EXPECT_NEAR(projected[1].v, 11.0, 1e-4);

  OverlayOptions options;
  options.point_radius_px = 0;
  options.background_contrast = 1.0;
  // Fig. 9 style: the first point as "initial", the second as "result".
  const cv::Mat comparison = RenderComparisonOverlay(grey, {projected[0]}, {projected[1]}, options);
  ASSERT_EQ(comparison.type(), CV_8UC3);
  ASSERT_EQ(comparison.size(), cv::Size(64, 48));
  EXPECT_EQ(comparison.at<cv::Vec3b>(24, 32), cv::Vec3b(40, 40, 230));  // red (BGR)
  EXPECT_EQ(comparison.at<cv::Vec3b>(11, 14), cv::Vec3b(255, 120, 0));  // blue
  EXPECT_EQ(comparison.at<cv::Vec3b>(0, 0), cv::Vec3b(128, 128, 128));  // untouched grey background
  int coloured = 0;
  for (int v = 0; v < 48; ++v)
    for (int u = 0; u < 64; ++u) {
      const cv::Vec3b c = comparison.at<cv::Vec3b>(v, u);
      coloured += !(c[0] == c[1] && c[1] == c[2]);
    }
  EXPECT_EQ(coloured, 2);

  // By value: reflectance 0 and 1 take the two ends of the colormap.
  const cv::Mat by_value = RenderReflectanceOverlay(grey, projected, options);
  const cv::Mat lut = ValueColormap();
  EXPECT_EQ(by_value.at<cv::Vec3b>(24, 32), lut.at<cv::Vec3b>(0));
  EXPECT_EQ(by_value.at<cv::Vec3b>(11, 14), lut.at<cv::Vec3b>(255));
  EXPECT_NE(lut.at<cv::Vec3b>(0), lut.at<cv::Vec3b>(255));

  // Scaled down: the point lands at the scaled pixel.
  options.max_width_px = 32;
  const cv::Mat half = RenderComparisonOverlay(grey, {}, {projected[1]}, options);
  ASSERT_EQ(half.size(), cv::Size(32, 24));
  EXPECT_EQ(half.at<cv::Vec3b>(5, 7), cv::Vec3b(255, 120, 0));  // (14 + 0.5) / 2 - 0.5 = 6.75 -> 7

  // PNG round trip of the overlay.
  const std::string png = EncodePng(comparison);
  const cv::Mat decoded = cv::imdecode(std::vector<unsigned char>(png.begin(), png.end()), cv::IMREAD_COLOR);
  ASSERT_FALSE(decoded.empty());
  EXPECT_EQ(cv::norm(decoded, comparison, cv::NORM_INF), 0.0);
  EXPECT_EQ(PngDataUri(comparison).rfind("data:image/png;base64,iVBORw0KGgo", 0), 0u);
}

TEST(Overlay, SwatheOverlayCullsAsTheCostDoes) {
  CameraInfo camera;
  camera.name = "front";
  camera.model = SmallCamera();
  Scene scene;
  scene.camera = "front";
  scene.lidar = "lidar";
  scene.image_t_us = 1000;
  scene.scans.push_back({1000, Eigen::Isometry3d::Identity()});
  LidarScan scan;
  scan.t_us = 1000;
  // Lidar = camera frame here. In view, behind, and outside the image; reflectances vary.
  scan.points = {{0.02f, 0.02f, 2.0f, 10.0f}, {-0.56f, -0.4f, 2.0f, 50.0f}, {0.0f, 0.0f, -5.0f, 30.0f},
                 {20.0f, 0.0f, 2.0f, 40.0f}, {0.3f, 0.3f, 3.0f, 20.0f}};
  cv::Mat intensity(48, 64, CV_32FC1);
  for (int v = 0; v < 48; ++v)
    for (int u = 0; u < 64; ++u) intensity.at<float>(v, u) = static_cast<float>(u) / 63.0f;
  SwatheOptions swathe_options;
  swathe_options.occlusion = false;
  const SceneSwathe swathe =
      SceneSwathe::Build(scene, camera, intensity, {&scan}, swathe_options, NormalisationOptions{});
  ASSERT_EQ(swathe.PointCount(), 5u);
  const std::vector<ProjectedPoint> points = ProjectSwathe(swathe, Eigen::Isometry3d::Identity());
  ASSERT_EQ(points.size(), 3u);
  EXPECT_EQ(points.size(), swathe.CountProjected(Eigen::Isometry3d::Identity()));
  OverlayOptions options;
  options.point_radius_px = 0;
  const cv::Mat overlay = RenderComparisonOverlay(swathe, Eigen::Isometry3d::Identity(),
                                                  Eigen::Isometry3d::Identity(), options);
  for (const ProjectedPoint& point : points)
    EXPECT_EQ(overlay.at<cv::Vec3b>(static_cast<int>(std::lround(point.v)), static_cast<int>(std::lround(point.u))),
              cv::Vec3b(255, 120, 0));
  EXPECT_EQ(overlay.at<cv::Vec3b>(static_cast<int>(std::lround(23.5 + 25 * 0.01)), static_cast<int>(std::lround(31.5 + 25 * 0.01))),
            cv::Vec3b(255, 120, 0));
  const cv::Mat coloured = RenderReflectanceOverlay(swathe, Eigen::Isometry3d::Identity(), options);
  EXPECT_EQ(coloured.size(), cv::Size(64, 48));
}

TEST(CostSlices, SampleEachDofAroundTheCentre) {
  const Eigen::Isometry3d minimum = TransformFromTuple((Vector6d() << 0.1, -0.2, 0.3, 0.05, -0.1, 0.2).finished());
  const Vector6d weights = (Vector6d() << 1, 2, 3, 40, 50, 60).finished();
  const TransformCost cost = [&](const Eigen::Isometry3d& T) {
    const Vector6d d = LogSE3(T * minimum.inverse());
    return 1.0 + d.dot(weights.asDiagonal() * d);
  };
  CostSliceOptions options;
  options.samples = 10;  // made odd: 11
  const CostSliceSet set = SampleCostSlices(cost, minimum, options);
  for (int k = 0; k < 6; ++k) {
    const CostSlice& slice = set.slices[static_cast<std::size_t>(k)];
    ASSERT_EQ(slice.offsets.size(), 11u);
    ASSERT_EQ(slice.costs.size(), 11u);
    const double half = k < 3 ? options.half_range_translation_m : options.half_range_rotation_rad;
    EXPECT_DOUBLE_EQ(slice.offsets.front(), -half);
    EXPECT_DOUBLE_EQ(slice.offsets.back(), half);
    EXPECT_NEAR(slice.offsets[5], 0.0, 1e-15);
    EXPECT_NEAR(slice.costs[5], 1.0, 1e-12);  // the centre is the minimum
    for (std::size_t s = 0; s < 11; ++s) {
      const double expected = 1.0 + weights[k] * slice.offsets[s] * slice.offsets[s];
      EXPECT_NEAR(slice.costs[s], expected, 1e-9) << "dof " << k << " sample " << s;
    }
  }
  EXPECT_STREQ(TangentName(3), "rx");
  std::string why;
  EXPECT_TRUE(options.IsValid(&why)) << why;
  options.samples = 1;
  EXPECT_FALSE(options.IsValid(&why));
}

TEST(CostSlices, AlternationSlicesUseTheHeldUpperEstimateAndPenalty) {
  EXPECT_EQ(SlicedAlternations(20, 8).size(), 8u);
  EXPECT_EQ(SlicedAlternations(20, 8).front(), 0);
  EXPECT_EQ(SlicedAlternations(20, 8).back(), 19);
  EXPECT_EQ(SlicedAlternations(3, 8), (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(SlicedAlternations(5, 1), (std::vector<int>{4}));
  EXPECT_TRUE(SlicedAlternations(0, 4).empty());

  const Eigen::Isometry3d initial = TransformFromTuple((Vector6d() << 0.2, 0, 0, 0, 0, 0).finished());
  std::vector<AlternationRecord> history(3);
  for (int i = 0; i < 3; ++i) {
    history[i].alternation = i;
    history[i].sigma_translation_m = 0.1 / (i + 1);
    history[i].sigma_rotation_rad = 0.05 / (i + 1);
    history[i].T_camera_lidar_lower = {TransformFromTuple((Vector6d() << 0.1 / (i + 1), 0, 0, 0, 0, 0).finished())};
    history[i].T_camera_lidar_upper = {TransformFromTuple((Vector6d() << 0.12 / (i + 1), 0, 0, 0, 0, 0).finished())};
  }
  const TransformCost zero = [](const Eigen::Isometry3d&) { return 0.0; };
  CostSliceOptions options;
  options.samples = 5;
  options.include_penalty = true;
  const std::vector<CostSliceSet> sets = SampleAlternationSlices(zero, history, 0, initial, options);
  ASSERT_EQ(sets.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(sets[i].alternation, i);
    EXPECT_TRUE(sets[i].penalised);
    EXPECT_TRUE(sets[i].centre.isApprox(history[i].T_camera_lidar_lower[0]));
    // The cost is zero, so the centre sample is the penalty to the upper estimate held at i.
    const Eigen::Isometry3d held = i == 0 ? initial : history[i - 1].T_camera_lidar_upper[0];
    const Vector6d d = DifferenceLog(history[i].T_camera_lidar_lower[0], held);
    const double expected = d.dot(PairPenaltyInformation(history[i].sigma_translation_m, history[i].sigma_rotation_rad,
                                                         options.penalty_frame, held) *
                                  d);
    EXPECT_NEAR(sets[i].slices[0].costs[2], expected, 1e-12);
    EXPECT_GT(expected, 0.0);
  }
  options.include_penalty = false;
  const std::vector<CostSliceSet> plain = SampleAlternationSlices(zero, history, 0, initial, options);
  ASSERT_EQ(plain.size(), 3u);
  EXPECT_FALSE(plain[0].penalised);
  EXPECT_EQ(plain[0].slices[0].costs[2], 0.0);
  EXPECT_TRUE(SampleAlternationSlices(zero, history, 5, initial, options).empty());  // no such pair
}

void ExpectSelfContained(const std::string& html) {
  EXPECT_EQ(html.find("http://"), std::string::npos);
  EXPECT_EQ(html.find("https://"), std::string::npos);
  EXPECT_EQ(html.find("src=\"//"), std::string::npos);
  EXPECT_EQ(html.find("url("), std::string::npos);
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_EQ(html.find("<link"), std::string::npos);
  EXPECT_EQ(TagBalanceProblem(html), "");
}

CalibrationReportData SampleCalibrationData() {
  CalibrationReportData data;
  data.title = "report of <rig> & co";
  data.dataset = "/data/<odd>";
  data.scheme = "alt";
  data.metric = "nid";
  data.termination = "max alternations";
  data.warnings = {"weak <x> axis"};
  data.settings = {{"bins<", "32"}};
  const Eigen::Isometry3d truth = TransformFromTuple((Vector6d() << 0.1, 0.2, -1.5, 0.1, 0.02, -0.03).finished());
  const Eigen::Isometry3d result = ExpSE3((Vector6d() << 0.01, 0, 0, 0, 0.002, 0).finished()) * truth;
  data.lidars.push_back({"<lidar>", truth, result, std::nullopt, truth, "", ""});
  PairRow pair;
  pair.camera = "cam<0>";
  pair.lidar = "<lidar>";
  pair.T_camera_lidar = result;
  pair.T_camera_lidar_truth = truth;
  pair.final_cost = 0.9;
  data.pairs.push_back(pair);
  std::vector<AlternationRecord> history(4);
  for (int i = 0; i < 4; ++i) {
    history[i].alternation = i;
    history[i].sigma_translation_m = history[i].sigma_rotation_rad = 1.0 / (i + 1);
    history[i].T_camera_lidar_lower = {ExpSE3(Vector6d::Constant(0.01 / (i + 1))) * truth};
    history[i].T_camera_lidar_upper = {ExpSE3(Vector6d::Constant(0.012 / (i + 1))) * truth};
    history[i].lower_cost = {0.95 - 0.01 * i};
  }
  data.convergence.push_back(ConvergenceFromHistory(history, 0, "cam<0> / <lidar>", truth));
  const TransformCost cost = [&](const Eigen::Isometry3d& T) { return LogSE3(T * truth.inverse()).squaredNorm(); };
  data.cost_slices.push_back({"cam<0> / <lidar>", SampleAlternationSlices(cost, history, 0, truth)});
  OverlayFigure overlay;
  overlay.title = "overlay <0>";
  overlay.file_name = "cam<0>/overlay.png";
  overlay.bgr = cv::Mat(24, 32, CV_8UC3, cv::Scalar(10, 200, 30));
  data.overlays.push_back(overlay);
  return data;
}

TEST(HtmlReport, CalibrationPageIsSelfContainedEscapedAndComplete) {
  const CalibrationReportData data = SampleCalibrationData();
  const std::string html = RenderCalibrationReport(data);
  ExpectSelfContained(html);
  for (const char* id : {"summary", "uncertainty", "convergence", "cost-slices", "overlays"})
    EXPECT_NE(html.find(std::string("<section id=\"") + id + "\""), std::string::npos) << id;
  EXPECT_NE(html.find("No uncertainty estimate"), std::string::npos);
  EXPECT_EQ(html.find("<rig>"), std::string::npos);
  EXPECT_EQ(html.find("<lidar>"), std::string::npos);
  EXPECT_EQ(html.find("cam<0>"), std::string::npos);
  EXPECT_NE(html.find("report of &lt;rig&gt; &amp; co"), std::string::npos);
  EXPECT_NE(html.find("cam&lt;0&gt; / &lt;lidar&gt;"), std::string::npos);
  EXPECT_NE(html.find("weak &lt;x&gt; axis"), std::string::npos);
  EXPECT_NE(html.find("src=\"data:image/png;base64,"), std::string::npos);
  // 6 DoF panels + cost plot of Fig. 4, 6 panels of Fig. 6, each nested in a grid <svg> or standalone.
  std::size_t svgs = 0;
  for (std::size_t at = html.find("<svg"); at != std::string::npos; at = html.find("<svg", at + 1)) ++svgs;
  EXPECT_EQ(svgs, (1 + 6) + 1 + (1 + 6));
  // The x error of the result (1 cm along x of the log, about 1 cm in the tuple) is in the table.
  const Vector6d error = TupleError(data.pairs[0].T_camera_lidar, *data.pairs[0].T_camera_lidar_truth);
  EXPECT_NE(html.find(fmt::format("<td>{:.2f}</td>", error[0] * 100)), std::string::npos);

  const std::vector<ReportFile> files = CalibrationReportAttachments(data);
  ASSERT_EQ(files.size(), 1u);
  EXPECT_EQ(files[0].name, "cam_0__overlay.png");
  EXPECT_EQ(files[0].content.substr(1, 3), "PNG");
  EXPECT_NE(html.find("cam_0__overlay.png"), std::string::npos);
}

TEST(HtmlReport, UncertaintySectionPlotsTwoSigmaPerDofAgainstTheGoodLimits) {
  CalibrationReportData data;
  const Eigen::Isometry3d truth = TransformFromTuple((Vector6d() << 0.1, 0, -1.5, 0, 0, 0).finished());
  // The result is 0.5 cm off in x and 0.05 deg in yaw; sigma 1 cm / 0.1 deg on every axis.
  const Eigen::Isometry3d result =
      TransformFromTuple(TupleFromTransform(truth) + (Vector6d() << 0.005, 0, 0, 0, 0, 0.05 * M_PI / 180).finished());
  LidarRow row{"<lidar>", truth, result, std::nullopt, truth, "", ""};
  row.sigma = (Vector6d() << 0.01, 0.01, 0.01, 0.1 * M_PI / 180, 0.1 * M_PI / 180, 0.1 * M_PI / 180).finished();
  row.verdict = "weak";
  row.verdict_reason = "2 sigma along <x> exceeds 1 cm";
  data.lidars.push_back(row);
  LidarRow unjudged{"other", truth, result, std::nullopt, std::nullopt, "", ""};
  data.lidars.push_back(unjudged);  // no sigma: no plot
  const std::string html = RenderCalibrationReport(data);
  ExpectSelfContained(html);
  const std::size_t section = html.find("<section id=\"uncertainty\">");
  ASSERT_NE(section, std::string::npos);
  const std::string body = html.substr(section, html.find("</section>", section) - section);
  EXPECT_NE(body.find("&lt;lidar&gt;: <span class=\"bad\">weak</span>"), std::string::npos) << body;
  EXPECT_NE(body.find("along &lt;x&gt; exceeds"), std::string::npos);
  EXPECT_EQ(body.find("<h3>other"), std::string::npos);
  // One interval per DoF: 2 sigma is 2 cm and 0.2 deg; the truth's error as a point.
  std::size_t intervals = 0;
  for (std::size_t at = body.find("class=\"interval\""); at != std::string::npos;
       at = body.find("class=\"interval\"", at + 1))
    ++intervals;
  EXPECT_EQ(intervals, 6u);
  EXPECT_NE(body.find("x: result \u00b1 2 sigma [-2, 2]; error to the truth 0.5"), std::string::npos) << body;
  EXPECT_NE(body.find("yaw: result \u00b1 2 sigma [-0.2, 0.2]; error to the truth 0.05"), std::string::npos);
  EXPECT_NE(body.find("stroke-dasharray=\"5 4\""), std::string::npos);  // the good limits
}

TEST(HtmlReport, EmptyCalibrationDataStillRenders) {
  const std::string html = RenderCalibrationReport(CalibrationReportData{});
  ExpectSelfContained(html);
  EXPECT_NE(html.find("No alternation history"), std::string::npos);
  EXPECT_NE(html.find("No overlays"), std::string::npos);
}

TEST(HtmlReport, ExperimentPageHasBoxPlotsPerMethodAndPerDof) {
  ExperimentReportData data;
  data.description = "a <test>";
  data.methods = {"once-nid", "alt-nid"};
  data.per_dof_methods = {"alt-nid", "once-mi"};
  const Eigen::Isometry3d truth = TransformFromTuple((Vector6d() << 0, 0, -1, 0.2, 0, 0).finished());
  for (const std::string method : {"once-nid", "alt-nid", "once-mi"})
    for (int trial = 0; trial < 5; ++trial) {
      const Eigen::Isometry3d estimate =
          TransformFromTuple(TupleFromTransform(truth) + Vector6d::Constant(0.001 * (trial + 1)));
      data.runs.push_back(MakeExperimentRun(method, "rear", trial, estimate, truth, 3.0, trial != 4, "done"));
    }
  EXPECT_NEAR(data.runs[0].error[0], 0.001, 1e-12);
  EXPECT_NEAR(data.runs[0].translation_error_m, std::sqrt(3.0) * 0.001, 1e-9);
  const std::string html = RenderExperimentReport(data);
  ExpectSelfContained(html);
  for (const char* id : {"summary", "box-plots", "per-dof-errors", "runs"})
    EXPECT_NE(html.find(std::string("<section id=\"") + id + "\""), std::string::npos) << id;
  EXPECT_NE(html.find("a &lt;test&gt;"), std::string::npos);
  // Fig. 7: 3 methods x 2 plots; Fig. 8: 2 methods x 6 DoF.
  std::size_t boxes = 0;
  for (std::size_t at = html.find("class=\"box\""); at != std::string::npos; at = html.find("class=\"box\"", at + 1))
    ++boxes;
  EXPECT_EQ(boxes, 3u * 2u + 2u * 6u);
  // The failed run is listed but left out of the statistics (4 of 5 succeeded).
  EXPECT_NE(html.find("<td class=\"text\">once-nid</td><td>5</td><td>4</td>"), std::string::npos);
  EXPECT_NE(html.find("failed"), std::string::npos);
}

TEST(HtmlReport, MakeCalibrationReportDataDerivesPairTruthFromTheRig) {
  Rig rig;
  rig.base_frame = "left";
  CameraInfo left;
  left.name = "left";
  CameraInfo right;
  right.name = "right";
  right.T_base_camera = TransformFromTuple((Vector6d() << 0.24, 0, 0, 0, 0, 0).finished());
  rig.cameras = {left, right};
  LidarInfo lidar;
  lidar.name = "rear";
  lidar.T_base_lidar = TransformFromTuple((Vector6d() << 0, 0, -1.5, 0.1, 0, 0).finished());
  rig.lidars = {lidar};
  GroundTruth truth;
  truth.T_base_lidar["rear"] = TransformFromTuple((Vector6d() << 0.01, 0, -1.5, 0.1, 0.01, 0).finished());

  CalibrationOutcome outcome;
  outcome.result.termination = "converged";
  outcome.result.warnings = {"w"};
  outcome.result.settings = {{"scheme", "joint"}, {"metric", "mi"}};
  outcome.result.lidars.push_back({"rear", truth.T_base_lidar["rear"], std::nullopt, std::nullopt});
  outcome.result.pairs.push_back({"right", "rear", right.T_camera_base() * truth.T_base_lidar["rear"], 0.8});
  PairReport report;
  report.camera = "right";
  report.lidar = "rear";
  report.scenes = 10;
  report.scenes_used = 9;
  report.initial_cost = 0.95;
  report.final_cost = 0.8;
  outcome.pairs.push_back(report);
  OptimisationReport optimisation;
  optimisation.problem = "joint rear";
  optimisation.stages = {NelderMeadSummary{100, 150, 0.95, 0.85, NelderMeadTermination::kMaxIterations},
                         NelderMeadSummary{50, 80, 0.85, 0.8, NelderMeadTermination::kMaxIterations}};
  optimisation.evaluations = 230;
  outcome.optimisations.push_back(optimisation);

  const CalibrationReportData data = MakeCalibrationReportData(outcome, rig, &truth);
  EXPECT_EQ(data.scheme, "joint");
  EXPECT_EQ(data.metric, "mi");
  ASSERT_EQ(data.lidars.size(), 1u);
  EXPECT_TRUE(data.lidars[0].T_base_lidar_initial.isApprox(lidar.T_base_lidar));
  ASSERT_TRUE(data.lidars[0].T_base_lidar_truth.has_value());
  ASSERT_EQ(data.pairs.size(), 1u);
  EXPECT_EQ(data.pairs[0].scenes_used, 9);
  EXPECT_DOUBLE_EQ(*data.pairs[0].initial_cost, 0.95);
  ASSERT_TRUE(data.pairs[0].T_camera_lidar_truth.has_value());
  // The pair's result equals its truth here, so the error is zero.
  EXPECT_LT(TupleError(data.pairs[0].T_camera_lidar, *data.pairs[0].T_camera_lidar_truth).norm(), 1e-12);
  ASSERT_EQ(data.optimisations.size(), 1u);
  EXPECT_EQ(data.optimisations[0].iterations, 150);
  EXPECT_EQ(data.optimisations[0].stages, 2);
  ExpectSelfContained(RenderCalibrationReport(data));
}

TEST(HtmlReport, TupleErrorWrapsAngles) {
  const Eigen::Isometry3d a = TransformFromTuple((Vector6d() << 0, 0, 0, kPi - 0.01, 0, 0).finished());
  const Eigen::Isometry3d b = TransformFromTuple((Vector6d() << 0, 0, 0, -kPi + 0.01, 0, 0).finished());
  EXPECT_NEAR(TupleError(a, b)[3], -0.02, 1e-9);
}

TEST(HtmlReport, WriteReportDirectoryWritesPageAndAttachments) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("scenecal_report_test_" + std::to_string(::getpid())) / "nested";
  WriteReportDirectory(dir.string(), "<html></html>", {{"a.png", std::string("\x89PNG", 4)}, {"../b c.png", "x"}});
  std::ifstream page(dir / "report.html");
  std::stringstream content;
  content << page.rdbuf();
  EXPECT_EQ(content.str(), "<html></html>");
  EXPECT_TRUE(std::filesystem::exists(dir / "a.png"));
  EXPECT_TRUE(std::filesystem::exists(dir / ".._b_c.png"));  // made safe: stays inside the directory
  EXPECT_EQ(SafeFileName(""), "file");
  EXPECT_EQ(SafeFileName(".."), "file");
  std::filesystem::remove_all(dir.parent_path());
}

}  // namespace
}  // namespace scenecal::report
