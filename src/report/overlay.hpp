// Overlays of lidar points projected into a camera image (the paper's Fig. 9),
// and PNG / base64 encoding for embedding them in a self-contained page.
//
// Points are culled exactly as the cost culls them: SceneSwathe's
// ForEachProjected (in front of the camera beyond the minimum depth, inside the
// image, and, by default, visible under the swathe's last z-buffer refresh), or
// CameraModel::Project for plain point lists.
//
// Typical use (given a PairCost `cost` and two estimates of T_camera_lidar):
//   const SceneSwathe& scene = cost.Scenes()[i];
//   cv::Mat fig9 = RenderComparisonOverlay(scene, T_initial, T_result);   // red vs blue
//   cv::Mat refl = RenderReflectanceOverlay(scene, T_result);             // colour = reflectance
//   std::string uri = PngDataUri(fig9);                                   // for <img src=...>
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "core/camera.hpp"
#include "core/swathe.hpp"

namespace scenecal::report {

// A point in the image: pixel (u, v) with (0, 0) the centre of the top-left
// pixel, a value in [0, 1] (normalised reflectance) and depth (m).
struct ProjectedPoint {
  float u = 0, v = 0;
  float value = 0;
  float depth_m = 0;
};

struct OverlayOptions {
  int point_radius_px = 1;     // in output pixels; 0 draws single pixels
  int max_width_px = 1280;     // larger images are scaled down (points scaled with them)
  bool visible_only = true;    // SceneSwathe: keep only points the z-buffer left visible
  double background_contrast = 0.8;  // grey background scaled towards mid-grey, so points stand out
  int max_points = 200000;     // draw at most this many per set (evenly strided)
};

// BGR colours (OpenCV order) of the paper's Fig. 9: red = initial guess, blue = result.
inline const cv::Scalar kInitialColourBgr{40, 40, 230};
inline const cv::Scalar kResultColourBgr{255, 120, 0};

// Points of the swathe that project under T_camera_lidar, as the cost sees them.
std::vector<ProjectedPoint> ProjectSwathe(const SceneSwathe& scene, const Eigen::Isometry3d& T_camera_lidar,
                                          bool visible_only = true);

// Points given in the lidar frame (metres) with values in [0, 1], projected
// with CameraModel::Project (in front beyond min_depth_m, inside the image).
std::vector<ProjectedPoint> ProjectPoints(const CameraModel& camera, const Eigen::Isometry3d& T_camera_lidar,
                                          const std::vector<Eigen::Vector3d>& points_lidar,
                                          const std::vector<float>& values, double min_depth_m = 0.2);

// Grey image (CV_32FC1 in [0, 1], or CV_8UC1) -> BGR CV_8UC3, contrast reduced
// towards mid-grey by `contrast` in [0, 1] (1 = unchanged).
cv::Mat GreyToBgr(const cv::Mat& grey, double contrast = 1.0);

// Output scale for an image of this width under options.max_width_px (<= 1).
double OverlayScale(int image_width_px, const OverlayOptions& options);

// Draws points onto a BGR image whose size is `scale` times the image the
// points were projected into. Colour by value through the turbo colormap,
// or in one fixed colour.
void DrawPointsByValue(cv::Mat* bgr, const std::vector<ProjectedPoint>& points, double scale,
                       const OverlayOptions& options = {});
void DrawPointsInColour(cv::Mat* bgr, const std::vector<ProjectedPoint>& points, const cv::Scalar& colour_bgr,
                        double scale, const OverlayOptions& options = {});

// The swathe under T_camera_lidar over its (normalised) image, points coloured
// by normalised reflectance (turbo colormap: blue low, red high).
cv::Mat RenderReflectanceOverlay(const SceneSwathe& scene, const Eigen::Isometry3d& T_camera_lidar,
                                 const OverlayOptions& options = {});
// Fig. 9: initial guess in red, result in blue, over the scene's image.
cv::Mat RenderComparisonOverlay(const SceneSwathe& scene, const Eigen::Isometry3d& T_camera_lidar_initial,
                                const Eigen::Isometry3d& T_camera_lidar_result, const OverlayOptions& options = {});
// Same from plain inputs: a grey image and two projected point sets.
cv::Mat RenderComparisonOverlay(const cv::Mat& grey, const std::vector<ProjectedPoint>& initial,
                                const std::vector<ProjectedPoint>& result, const OverlayOptions& options = {});
cv::Mat RenderReflectanceOverlay(const cv::Mat& grey, const std::vector<ProjectedPoint>& points,
                                 const OverlayOptions& options = {});

// BGR 256x1 lookup table of the colormap used for values (turbo).
cv::Mat ValueColormap();

// PNG bytes of an image (cv::imencode); empty string when encoding fails.
std::string EncodePng(const cv::Mat& image);
// Standard base64 (RFC 4648, with '=' padding).
std::string Base64(std::string_view bytes);
// "data:image/png;base64,..." for an <img src>.
std::string PngDataUri(const cv::Mat& image);

}  // namespace scenecal::report
