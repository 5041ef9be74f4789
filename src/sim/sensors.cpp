#include "sim/sensors.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/geometry.hpp"
#include "core/interrupt.hpp"
#include "sim/noise.hpp"

namespace scenecal::sim {

double RayRadiance(const World& world, const Ray& ray, const RenderSettings& settings) {
  const auto hit = world.Intersect(ray, 400.0, 1e-4, /*with_reflectivity=*/false);
  if (!hit) {
    // Sky: brighter towards the horizon.
    return 1.25 - 0.4 * std::max(0.0, ray.direction.z());
  }
  const Eigen::Vector3d& sun = world.sun_direction();
  const double facing_sun = hit->normal.dot(sun);
  double direct = 0.0;
  if (facing_sun > 0.0) {
    direct = settings.sun_irradiance * facing_sun;
    if (settings.shadows && world.Occluded({hit->point + 2e-3 * hit->normal, sun}, 300.0)) direct = 0.0;
  }
  const double sky = settings.sky_irradiance * (0.55 + 0.45 * hit->normal.z());
  return hit->albedo * (direct + sky);
}

cv::Mat RenderImage(const World& world, const CameraModel& camera, const Eigen::Isometry3d& T_world_camera,
                    const RenderSettings& settings, std::uint64_t noise_key) {
  const int width = camera.width, height = camera.height;
  cv::Mat linear(height, width, CV_32F);
  const Eigen::Matrix3d R = T_world_camera.linear();
  const Eigen::Vector3d origin = T_world_camera.translation();
  const double corner_squared = std::pow(0.5 * width, 2) + std::pow(0.5 * height, 2);
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    for (int v = rows.begin(); v < rows.end(); ++v) {
      ThrowIfInterrupted();  // a full-size image takes seconds of ray casting
      auto* row = linear.ptr<float>(v);
      for (int u = 0; u < width; ++u) {
        const Eigen::Vector3d direction = (R * camera.Unproject(Eigen::Vector2d(u, v))).normalized();
        const double radiance = RayRadiance(world, {origin, direction}, settings);
        const double r2 = ((u - camera.cx) * (u - camera.cx) + (v - camera.cy) * (v - camera.cy)) / corner_squared;
        row[u] = static_cast<float>(radiance * settings.exposure * (1.0 - settings.vignetting * r2));
      }
    }
  });
  const double sigma = settings.blur_sigma_px * width / 1280.0;
  if (sigma > 0.2) cv::GaussianBlur(linear, linear, cv::Size(0, 0), sigma, sigma, cv::BORDER_REFLECT);

  // Gamma through a table (linear interpolation between 4096 steps).
  constexpr int kSteps = 4096;
  std::vector<double> gamma_table(kSteps + 2);
  for (int i = 0; i <= kSteps + 1; ++i) gamma_table[i] = std::pow(std::min(1.0, double(i) / kSteps), 1.0 / settings.gamma);
  cv::Mat image(height, width, CV_8U);
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    for (int v = rows.begin(); v < rows.end(); ++v) {
      const auto* in = linear.ptr<float>(v);
      auto* out = image.ptr<std::uint8_t>(v);
      for (int u = 0; u < width; ++u) {
        double x = std::max(0.0, static_cast<double>(in[u]));
        if (settings.noise) {
          const std::uint64_t key = HashKey(noise_key, static_cast<std::uint64_t>(v) * static_cast<std::uint64_t>(width) + u);
          x += std::sqrt(settings.read_noise * settings.read_noise + settings.shot_noise * x) * GaussianFromHash(key);
        }
        const double position = std::clamp(x, 0.0, 1.0) * kSteps;
        const auto step = static_cast<int>(position);
        const double encoded = gamma_table[step] + (gamma_table[step + 1] - gamma_table[step]) * (position - step);
        out[u] = static_cast<std::uint8_t>(std::lround(255.0 * encoded));
      }
    }
  });
  return image;
}

LidarModel LidarModel::PushBroom() {
  LidarModel model;
  model.kind = LidarKind::k2d;
  for (int i = 0; i < 541; ++i) {
    const double angle = RadiansFromDegrees(-135.0 + 0.5 * i);
    model.beam_directions.emplace_back(std::cos(angle), std::sin(angle), 0.0);
  }
  model.max_range_m = 50.0;
  return model;
}

LidarModel LidarModel::Spinning(double azimuth_step_deg) {
  LidarModel model;
  model.kind = LidarKind::k3d;
  const int azimuths = static_cast<int>(std::lround(360.0 / azimuth_step_deg));
  for (int a = 0; a < azimuths; ++a) {
    const double azimuth = RadiansFromDegrees(a * azimuth_step_deg);
    for (int b = 0; b < 32; ++b) {
      const double elevation = RadiansFromDegrees(-15.0 + 30.0 * b / 31.0);
      model.beam_directions.emplace_back(std::cos(elevation) * std::cos(azimuth),
                                         std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
    }
  }
  model.max_range_m = 100.0;
  model.range_noise_m = 0.02;
  model.reflectance_scale = 255.0;
  model.range_falloff_m = 60.0;
  return model;
}

std::vector<LidarPoint> ScanLidar(const World& world, const LidarModel& lidar, const Eigen::Isometry3d& T_world_lidar,
                                  std::uint64_t noise_key, ScanStatistics* statistics) {
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  std::vector<LidarPoint> points(lidar.beam_directions.size(), LidarPoint{kNaN, kNaN, kNaN, kNaN});
  const Eigen::Matrix3d R = T_world_lidar.linear();
  const Eigen::Vector3d origin = T_world_lidar.translation();
  std::size_t returns = 0;
  for (std::size_t b = 0; b < points.size(); ++b) {
    const Eigen::Vector3d& beam = lidar.beam_directions[b];
    const Eigen::Vector3d direction = R * beam;
    const auto hit = world.Intersect({origin, direction}, lidar.max_range_m, lidar.min_range_m);
    if (!hit) continue;  // sky or beyond the maximum range
    const double cos_incidence = std::abs(hit->normal.dot(direction));
    const double range_factor = 1.0 / (1.0 + std::pow(hit->distance / lidar.range_falloff_m, 2));
    const double signal = hit->reflectivity * std::pow(cos_incidence, lidar.incidence_exponent) * range_factor;
    const std::uint64_t key = HashKey(noise_key, b);
    // Weak returns (dark surfaces, grazing incidence, far away) are lost, with a soft threshold.
    if (signal < lidar.detection_threshold * (1.0 + 0.3 * GaussianFromHash(key ^ 1))) continue;
    const double range = hit->distance + lidar.range_noise_m * GaussianFromHash(key ^ 2);
    const double reflectance = std::max(
        0.0, lidar.reflectance_scale * signal * (1.0 + 0.05 * GaussianFromHash(key ^ 3)) +
                 0.004 * lidar.reflectance_scale * GaussianFromHash(key ^ 4));
    const Eigen::Vector3d p = range * beam;
    points[b] = {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()),
                 static_cast<float>(reflectance)};
    ++returns;
  }
  if (statistics) {
    statistics->returns += returns;
    statistics->no_returns += points.size() - returns;
  }
  return points;
}

}  // namespace scenecal::sim
