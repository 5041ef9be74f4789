#include "report/overlay.hpp"

#include <algorithm>
#include <cmath>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace scenecal::report {

std::vector<ProjectedPoint> ProjectSwathe(const SceneSwathe& scene, const Eigen::Isometry3d& T_camera_lidar,
                                          bool visible_only) {
  std::vector<ProjectedPoint> points;
  scene.ForEachProjected(T_camera_lidar, visible_only,
                         [&](std::size_t, float reflectance01, float u, float v, float depth_m) {
                           points.push_back({u, v, reflectance01, depth_m});
                         });
  return points;
}

std::vector<ProjectedPoint> ProjectPoints(const CameraModel& camera, const Eigen::Isometry3d& T_camera_lidar,
                                          const std::vector<Eigen::Vector3d>& points_lidar,
                                          const std::vector<float>& values, double min_depth_m) {
  std::vector<ProjectedPoint> points;
  for (std::size_t i = 0; i < points_lidar.size(); ++i) {
    const Eigen::Vector3d p_camera = T_camera_lidar * points_lidar[i];
    Eigen::Vector2d pixel;
    if (!camera.Project(p_camera, &pixel, 0.0, min_depth_m)) continue;
    const float value = i < values.size() ? values[i] : 0.5f;
    points.push_back({static_cast<float>(pixel.x()), static_cast<float>(pixel.y()), value,
                      static_cast<float>(p_camera.z())});
  }
  return points;
}

cv::Mat GreyToBgr(const cv::Mat& grey, double contrast) {
  if (grey.empty()) return {};
  cv::Mat grey8;
  contrast = std::clamp(contrast, 0.0, 1.0);
  // value' = 0.5 + contrast * (value - 0.5), in 8 bits.
  if (grey.depth() == CV_8U) {
    grey.convertTo(grey8, CV_8U, contrast, 127.5 * (1.0 - contrast));
  } else {
    grey.convertTo(grey8, CV_8U, 255.0 * contrast, 127.5 * (1.0 - contrast));
  }
  if (grey8.channels() == 3) return grey8;
  cv::Mat bgr;
  cv::cvtColor(grey8, bgr, cv::COLOR_GRAY2BGR);
  return bgr;
}

double OverlayScale(int image_width_px, const OverlayOptions& options) {
  if (options.max_width_px <= 0 || image_width_px <= options.max_width_px) return 1.0;
  return static_cast<double>(options.max_width_px) / image_width_px;
}

cv::Mat ValueColormap() {
  static const cv::Mat lut = [] {
    cv::Mat ramp(256, 1, CV_8UC1);
    for (int i = 0; i < 256; ++i) ramp.at<unsigned char>(i) = static_cast<unsigned char>(i);
    cv::Mat colours;
    cv::applyColorMap(ramp, colours, cv::COLORMAP_TURBO);
    return colours;
  }();
  return lut;
}

namespace {

// Evenly strided subset so huge swathes stay readable and cheap to draw.
template <typename Draw>
void ForEachDrawn(const std::vector<ProjectedPoint>& points, const OverlayOptions& options, Draw&& draw) {
  const std::size_t limit = static_cast<std::size_t>(std::max(1, options.max_points));
  const std::size_t stride = points.size() > limit ? (points.size() + limit - 1) / limit : 1;
  for (std::size_t i = 0; i < points.size(); i += stride) draw(points[i]);
}

void DrawPoint(cv::Mat* bgr, const ProjectedPoint& point, double scale, const cv::Vec3b& colour, int radius) {
  // Pixel (0, 0) is the centre of the top-left pixel; scale about the pixel corner.
  const double x = (point.u + 0.5) * scale - 0.5, y = (point.v + 0.5) * scale - 0.5;
  const int cx = static_cast<int>(std::lround(x)), cy = static_cast<int>(std::lround(y));
  if (radius <= 0) {
    if (cx >= 0 && cy >= 0 && cx < bgr->cols && cy < bgr->rows) bgr->at<cv::Vec3b>(cy, cx) = colour;
    return;
  }
  cv::circle(*bgr, {cx, cy}, radius, cv::Scalar(colour[0], colour[1], colour[2]), cv::FILLED, cv::LINE_8);
}

cv::Mat Background(const cv::Mat& grey, const OverlayOptions& options, double* scale) {
  cv::Mat bgr = GreyToBgr(grey, options.background_contrast);
  *scale = OverlayScale(grey.cols, options);
  if (*scale < 1.0 && !bgr.empty()) {
    cv::Mat resized;
    cv::resize(bgr, resized, cv::Size(), *scale, *scale, cv::INTER_AREA);
    bgr = resized;
  }
  return bgr;
}

}  // namespace

void DrawPointsByValue(cv::Mat* bgr, const std::vector<ProjectedPoint>& points, double scale,
                       const OverlayOptions& options) {
  if (bgr == nullptr || bgr->empty()) return;
  const cv::Mat lut = ValueColormap();
  ForEachDrawn(points, options, [&](const ProjectedPoint& point) {
    const float value = std::isfinite(point.value) ? std::clamp(point.value, 0.0f, 1.0f) : 0.0f;
    const int index = static_cast<int>(std::lround(value * 255.0f));
    DrawPoint(bgr, point, scale, lut.at<cv::Vec3b>(index), options.point_radius_px);
  });
}

void DrawPointsInColour(cv::Mat* bgr, const std::vector<ProjectedPoint>& points, const cv::Scalar& colour_bgr,
                        double scale, const OverlayOptions& options) {
  if (bgr == nullptr || bgr->empty()) return;
  const cv::Vec3b colour(cv::saturate_cast<unsigned char>(colour_bgr[0]),
                         cv::saturate_cast<unsigned char>(colour_bgr[1]),
                         cv::saturate_cast<unsigned char>(colour_bgr[2]));
  ForEachDrawn(points, options,
               [&](const ProjectedPoint& point) { DrawPoint(bgr, point, scale, colour, options.point_radius_px); });
}

cv::Mat RenderReflectanceOverlay(const cv::Mat& grey, const std::vector<ProjectedPoint>& points,
                                 const OverlayOptions& options) {
  double scale = 1.0;
  cv::Mat bgr = Background(grey, options, &scale);
  DrawPointsByValue(&bgr, points, scale, options);
  return bgr;
}

cv::Mat RenderComparisonOverlay(const cv::Mat& grey, const std::vector<ProjectedPoint>& initial,
                                const std::vector<ProjectedPoint>& result, const OverlayOptions& options) {
  double scale = 1.0;
  cv::Mat bgr = Background(grey, options, &scale);
  DrawPointsInColour(&bgr, initial, kInitialColourBgr, scale, options);
  DrawPointsInColour(&bgr, result, kResultColourBgr, scale, options);  // on top: the answer
  return bgr;
}

cv::Mat RenderReflectanceOverlay(const SceneSwathe& scene, const Eigen::Isometry3d& T_camera_lidar,
                                 const OverlayOptions& options) {
  return RenderReflectanceOverlay(scene.Image(), ProjectSwathe(scene, T_camera_lidar, options.visible_only), options);
}

cv::Mat RenderComparisonOverlay(const SceneSwathe& scene, const Eigen::Isometry3d& T_camera_lidar_initial,
                                const Eigen::Isometry3d& T_camera_lidar_result, const OverlayOptions& options) {
  return RenderComparisonOverlay(scene.Image(), ProjectSwathe(scene, T_camera_lidar_initial, options.visible_only),
                                 ProjectSwathe(scene, T_camera_lidar_result, options.visible_only), options);
}

std::string EncodePng(const cv::Mat& image) {
  if (image.empty()) return {};
  std::vector<unsigned char> buffer;
  if (!cv::imencode(".png", image, buffer)) return {};
  return std::string(buffer.begin(), buffer.end());
}

std::string Base64(std::string_view bytes) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned triple = (static_cast<unsigned char>(bytes[i]) << 16) |
                            (static_cast<unsigned char>(bytes[i + 1]) << 8) | static_cast<unsigned char>(bytes[i + 2]);
    out += kAlphabet[(triple >> 18) & 63];
    out += kAlphabet[(triple >> 12) & 63];
    out += kAlphabet[(triple >> 6) & 63];
    out += kAlphabet[triple & 63];
  }
  if (i < bytes.size()) {
    const bool two = i + 1 < bytes.size();
    const unsigned triple = (static_cast<unsigned char>(bytes[i]) << 16) |
                            (two ? static_cast<unsigned char>(bytes[i + 1]) << 8 : 0u);
    out += kAlphabet[(triple >> 18) & 63];
    out += kAlphabet[(triple >> 12) & 63];
    out += two ? kAlphabet[(triple >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

std::string PngDataUri(const cv::Mat& image) { return "data:image/png;base64," + Base64(EncodePng(image)); }

}  // namespace scenecal::report
