// The pair cost on a synthetic scene built here: a slanted, textured plane
// seen by a pinhole camera, lidar points on it whose reflectance is a
// monotone function of the albedo. The cost must be lowest at the true
// extrinsic, and the z-buffer must hide points behind a nearer surface.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "core/geometry.hpp"
#include "core/pair_cost.hpp"
#include "core/scene_information.hpp"

namespace scenecal {
namespace {

CameraModel TestCamera() {
  CameraModel camera;
  camera.width = 640;
  camera.height = 480;
  camera.kind = CameraModelKind::kPinhole;
  camera.fx = camera.fy = 600.0;
  camera.cx = 319.5;
  camera.cy = 239.5;
  return camera;
}

// Piecewise-constant random albedo in [0, 1] on 3 cm cells of the plane.
double Albedo(double a, double b) {
  const auto cell_a = static_cast<std::int64_t>(std::floor(a / 0.03));
  const auto cell_b = static_cast<std::int64_t>(std::floor(b / 0.03));
  std::uint64_t h = static_cast<std::uint64_t>(cell_a * 73856093) ^ static_cast<std::uint64_t>(cell_b * 19349663);
  h ^= h >> 33;
  h *= 0xff51afd7ed558ccdULL;
  h ^= h >> 33;
  return static_cast<double>(h % 1000) / 999.0;
}

// A plane in the camera frame: points p = origin + a * axis_a + b * axis_b.
struct Plane {
  Eigen::Vector3d origin, axis_a, axis_b;
  double half_a, half_b;  // extent, metres
  Eigen::Vector3d Normal() const { return axis_a.cross(axis_b).normalized(); }
  // Ray from the camera centre along d: plane coordinates of the hit, if within the extent.
  bool Hit(const Eigen::Vector3d& d, double* depth, double* a, double* b) const {
    const Eigen::Vector3d n = Normal();
    const double denominator = n.dot(d);
    if (std::abs(denominator) < 1e-9) return false;
    const double t = n.dot(origin) / denominator;
    if (t <= 0) return false;
    const Eigen::Vector3d p = t * d - origin;
    *a = p.dot(axis_a);
    *b = p.dot(axis_b);
    *depth = t * d.z();
    return std::abs(*a) <= half_a && std::abs(*b) <= half_b;
  }
};

Plane FarPlane() {
  // 4 m ahead, slanted 25 deg about the camera's y axis and 10 deg about x.
  const Eigen::Matrix3d r = RotationFromRollPitchYaw(RadiansFromDegrees(10), RadiansFromDegrees(25), 0);
  return {Eigen::Vector3d(0, 0, 4.0), r.col(0), r.col(1), 3.0, 2.5};
}

Plane NearPlane() {  // an occluder 2 m ahead, right of centre
  return {Eigen::Vector3d(0.3, 0.0, 2.0), Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), 0.15, 0.2};
}

struct Synthetic {
  CameraInfo camera;
  Eigen::Isometry3d T_camera_lidar;
  cv::Mat image;
  LidarScan scan;
  std::vector<bool> on_far_plane;  // per scan point
  std::vector<Eigen::Vector3d> p_camera;  // per scan point, camera frame
};

Synthetic MakeSynthetic(bool with_occluder) {
  Synthetic s;
  s.camera.name = "cam";
  s.camera.model = TestCamera();
  Vector6d tuple;
  tuple << 0.4, -0.3, 0.2, RadiansFromDegrees(-3), RadiansFromDegrees(4), RadiansFromDegrees(2);
  s.T_camera_lidar = TransformFromTuple(tuple);
  const Plane far = FarPlane(), near = NearPlane();

  s.image = cv::Mat(s.camera.model.height, s.camera.model.width, CV_32FC1, cv::Scalar(0.0f));
  for (int v = 0; v < s.image.rows; ++v) {
    for (int u = 0; u < s.image.cols; ++u) {
      const Eigen::Vector3d d = s.camera.model.Unproject(Eigen::Vector2d(u, v));
      double depth, a, b;
      float intensity = 0.5f;
      if (with_occluder && near.Hit(d, &depth, &a, &b)) {
        intensity = static_cast<float>(Albedo(a + 100.0, b));
      } else if (far.Hit(d, &depth, &a, &b)) {
        intensity = static_cast<float>(Albedo(a, b));
      }
      s.image.at<float>(v, u) = intensity;
    }
  }
  const Eigen::Isometry3d T_lidar_camera = s.T_camera_lidar.inverse();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const auto add_point = [&](const Plane& plane, double a, double b, double albedo, bool is_far) {
    const Eigen::Vector3d p = plane.origin + a * plane.axis_a + b * plane.axis_b;
    const Eigen::Vector3d q = T_lidar_camera * p;
    const double reflectance = 5.0 + 200.0 * std::pow(albedo, 1.5);  // monotone, not linear
    s.scan.points.push_back({static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()),
                             static_cast<float>(reflectance)});
    s.on_far_plane.push_back(is_far);
    s.p_camera.push_back(p);
  };
  for (int i = 0; i < 80000; ++i) {
    const double a = far.half_a * unit(rng), b = far.half_b * unit(rng);
    add_point(far, a, b, Albedo(a, b), true);
  }
  if (with_occluder) {
    for (double a = -near.half_a; a <= near.half_a; a += 0.01) {
      for (double b = -near.half_b; b <= near.half_b; b += 0.01) add_point(near, a, b, Albedo(a + 100.0, b), false);
    }
  }
  return s;
}

PairCost MakeCost(const Synthetic& s, const PairCostOptions& options) {
  Scene scene;
  scene.camera = "cam";
  scene.lidar = "lidar";
  scene.scans.push_back({0, Eigen::Isometry3d::Identity()});
  std::vector<SceneSwathe> swathes;
  swathes.push_back(SceneSwathe::Build(scene, s.camera, s.image, {&s.scan}, options.swathe, NormalisationOptions{}));
  return PairCost(s.camera, "lidar", std::move(swathes), options);
}

void ExpectLowestAtTruth(const PairCostOptions& options) {
  const Synthetic s = MakeSynthetic(false);
  PairCost cost = MakeCost(s, options);
  ASSERT_EQ(cost.RefreshVisibility(s.T_camera_lidar), 1);
  const double at_truth = cost.Evaluate(s.T_camera_lidar);
  ASSERT_TRUE(std::isfinite(at_truth));
  for (int axis = 0; axis < 6; ++axis) {
    for (const double sign : {-1.0, 1.0}) {
      Vector6d delta = Vector6d::Zero();
      delta[axis] = sign * (axis < 3 ? 0.02 : RadiansFromDegrees(0.2));
      const double perturbed = cost.Evaluate(ExpSE3(delta) * s.T_camera_lidar);
      EXPECT_LT(at_truth, perturbed) << "axis " << axis << " sign " << sign << " metric "
                                     << MetricKindName(options.metric) << " binning "
                                     << BinningName(options.histogram.binning);
    }
  }
}

TEST(PairCost, NidLowestAtTruthHardBins) {
  PairCostOptions options;
  options.metric = MetricKind::kNid;
  ExpectLowestAtTruth(options);
}

TEST(PairCost, NidLowestAtTruthBSplineBins) {
  PairCostOptions options;
  options.metric = MetricKind::kNid;
  options.histogram.binning = Binning::kBSpline;
  ExpectLowestAtTruth(options);
}

TEST(PairCost, MiLowestAtTruth) {
  PairCostOptions options;
  options.metric = MetricKind::kMi;
  ExpectLowestAtTruth(options);
}

TEST(PairCost, CostIsMeanOfSceneCostsAndReportsCounts) {
  const Synthetic s = MakeSynthetic(false);
  PairCostOptions options;
  PairCost cost = MakeCost(s, options);
  cost.RefreshVisibility(s.T_camera_lidar);
  const std::vector<SceneEvaluation> scenes = cost.EvaluateScenes(s.T_camera_lidar);
  ASSERT_EQ(scenes.size(), 1u);
  EXPECT_NEAR(scenes[0].cost, cost.Evaluate(s.T_camera_lidar), 1e-12);
  EXPECT_EQ(scenes[0].projected_points, cost.ProjectedAtRefresh()[0]);
  // Every far-plane point is in front; most project inside the image.
  EXPECT_GT(scenes[0].projected_points, 40000u);
  EXPECT_LE(scenes[0].projected_points, s.scan.points.size());
  // NID on this strongly related pair is well below 1.
  EXPECT_LT(scenes[0].cost, 0.9);
}

TEST(PairCost, TooFewPointsAndConstantImageAreIgnored) {
  Synthetic s = MakeSynthetic(false);
  PairCostOptions options;
  options.min_points_per_scene = 1'000'000;
  PairCost few = MakeCost(s, options);
  EXPECT_EQ(few.RefreshVisibility(s.T_camera_lidar), 0);
  EXPECT_EQ(few.CountState(SceneState::kTooFewPoints), 1);
  EXPECT_TRUE(std::isnan(few.Evaluate(s.T_camera_lidar)));

  s.image.setTo(cv::Scalar(0.3f));
  PairCost constant = MakeCost(s, PairCostOptions{});
  EXPECT_EQ(constant.RefreshVisibility(s.T_camera_lidar), 0);
  EXPECT_EQ(constant.CountState(SceneState::kConstantImage), 1);
}

TEST(PairCost, VisibilityHidesPointsBehindANearerSurface) {
  const Synthetic s = MakeSynthetic(true);
  PairCostOptions options;
  Scene scene;
  scene.camera = "cam";
  scene.lidar = "lidar";
  scene.scans.push_back({0, Eigen::Isometry3d::Identity()});
  SceneSwathe swathe =
      SceneSwathe::Build(scene, s.camera, s.image, {&s.scan}, options.swathe, NormalisationOptions{});
  ASSERT_EQ(swathe.PointCount(), s.scan.points.size());  // all within the range limits
  swathe.RefreshVisibility(s.T_camera_lidar, options.swathe);

  // Classify far-plane points by whether the camera ray to them hits the occluder
  // (with a border of two z-buffer cells, 16 px, left out on each side).
  const Plane near = NearPlane();
  std::vector<bool> visible(s.scan.points.size(), false);
  swathe.ForEachProjected(s.T_camera_lidar, true, [&](std::size_t i, float, float, float, float) { visible[i] = true; });
  int behind = 0, behind_hidden = 0, clear = 0, clear_hidden = 0, near_points = 0, near_hidden = 0;
  const CameraModel& model = s.camera.model;
  for (std::size_t i = 0; i < s.p_camera.size(); ++i) {
    Eigen::Vector2d pixel;
    if (!model.Project(s.p_camera[i], &pixel, 0.5)) continue;
    if (!s.on_far_plane[i]) {
      ++near_points;
      near_hidden += visible[i] ? 0 : 1;
      continue;
    }
    // The occluder spans u = 319.5 + 600 * [0.15, 0.45] / 2, v = 239.5 + 600 * [-0.2, 0.2] / 2.
    const double u0 = 319.5 + 300.0 * (near.origin.x() - near.half_a), u1 = 319.5 + 300.0 * (near.origin.x() + near.half_a);
    const double v0 = 239.5 - 300.0 * near.half_b, v1 = 239.5 + 300.0 * near.half_b;
    const bool inside = pixel.x() > u0 + 16 && pixel.x() < u1 - 16 && pixel.y() > v0 + 16 && pixel.y() < v1 - 16;
    const bool outside = pixel.x() < u0 - 16 || pixel.x() > u1 + 16 || pixel.y() < v0 - 16 || pixel.y() > v1 + 16;
    if (inside) {
      ++behind;
      behind_hidden += visible[i] ? 0 : 1;
    } else if (outside) {
      ++clear;
      clear_hidden += visible[i] ? 0 : 1;
    }
  }
  ASSERT_GT(behind, 500);
  ASSERT_GT(near_points, 500);
  EXPECT_GT(behind_hidden, 0.99 * behind) << behind_hidden << " of " << behind;
  EXPECT_LT(clear_hidden, 0.01 * clear) << clear_hidden << " of " << clear;
  EXPECT_EQ(near_hidden, 0);

  // With occlusion off nothing is hidden.
  SwatheOptions no_occlusion = options.swathe;
  no_occlusion.occlusion = false;
  swathe.RefreshVisibility(s.T_camera_lidar, no_occlusion);
  EXPECT_EQ(swathe.VisibleCount(), swathe.PointCount());
}

// The z-buffer compares a point with the nearest point of its cell, so on a
// surface seen at a grazing angle (the road ahead) the far part of every cell
// hides itself once the cell spans more depth than the margin. What the cell
// and margin options do, measured (docs/findings.md: on the spinning-lidar preset
// the translation error grows with the cell).
struct GrazingRoad {
  CameraInfo camera;
  LidarScan points;
  SceneSwathe swathe;
};

// A flat road 1.5 m below a level camera (y down), 4 to 40 m ahead, 6 m wide,
// sampled every 5 cm across and every 10 cm along: nothing occludes it.
GrazingRoad MakeGrazingRoad() {
  GrazingRoad road;
  road.camera.name = "cam";
  road.camera.model.width = 640;
  road.camera.model.height = 480;
  road.camera.model.fx = road.camera.model.fy = 500.0;
  road.camera.model.cx = 319.5;
  road.camera.model.cy = 239.5;
  cv::Mat image(480, 640, CV_32FC1);
  cv::randu(image, 0.0f, 1.0f);
  for (double z = 4.0; z <= 40.0; z += 0.1) {
    for (double x = -3.0; x <= 3.0; x += 0.05)
      road.points.points.push_back({float(x), 1.5f, float(z), float(100.0 + 50.0 * x)});
  }
  Scene scene;
  scene.camera = "cam";
  scene.lidar = "lidar";
  scene.scans.push_back({0, Eigen::Isometry3d::Identity()});
  road.swathe =
      SceneSwathe::Build(scene, road.camera, image, {&road.points}, SwatheOptions{}, NormalisationOptions{});
  return road;
}

std::size_t HiddenCount(SceneSwathe& swathe, int cell_px, double relative, double absolute_m) {
  SwatheOptions options;
  options.occlusion_cell_px = cell_px;
  options.occlusion_relative_margin = relative;
  options.occlusion_absolute_margin_m = absolute_m;
  EXPECT_GT(swathe.RefreshVisibility(Eigen::Isometry3d::Identity(), options), 40000u);
  return swathe.PointCount() - swathe.VisibleCount();
}

TEST(PairCost, ZBufferCellHidesAGrazingRoadFromItself) {
  GrazingRoad road = MakeGrazingRoad();
  // Default margins (20 % + 0.3 m): nothing hidden with cells up to 4 px, then
  // a share that grows with the cell (measured: 16 % at 8 px, 48 % at 16 px).
  EXPECT_EQ(HiddenCount(road.swathe, 1, 0.2, 0.3), 0u);
  EXPECT_EQ(HiddenCount(road.swathe, 4, 0.2, 0.3), 0u);
  std::size_t previous_default = 0, previous_tight = 0;
  for (int cell : {8, 16, 32, 64}) {
    const std::size_t with_default = HiddenCount(road.swathe, cell, 0.2, 0.3);
    const std::size_t with_tight = HiddenCount(road.swathe, cell, 0.05, 0.1);
    EXPECT_GT(with_default, previous_default) << "cell " << cell;
    EXPECT_GT(with_tight, with_default) << "cell " << cell;
    EXPECT_GT(with_tight, previous_tight) << "cell " << cell;
    EXPECT_LT(with_tight, road.swathe.PointCount()) << "cell " << cell;  // the nearest row of every cell stays
    previous_default = with_default;
    previous_tight = with_tight;
  }
  EXPECT_EQ(HiddenCount(road.swathe, 0, 0.2, 0.3), HiddenCount(road.swathe, 8, 0.2, 0.3));  // 640 / 80
}

// refresh_border_px scores only the points that project at least that many
// pixels inside the image at the refresh; the others stay out wherever the
// estimate then moves them, until the next refresh.
TEST(PairCost, RefreshBorderFixesThePointSetAwayFromTheImageBorder) {
  GrazingRoad road = MakeGrazingRoad();
  const CameraModel& model = road.camera.model;
  SwatheOptions options;
  options.occlusion = false;
  options.refresh_border_px = 40.0;
  road.swathe.RefreshVisibility(Eigen::Isometry3d::Identity(), options);
  // Points within 0.01 px of a limit may fall either way (float projection in the swathe).
  std::size_t surely_visible = 0, maybe_visible = 0, inside_image = 0;
  for (const LidarPoint& p : road.points.points) {
    Eigen::Vector2d pixel;
    if (!model.Project(Eigen::Vector3d(p.x, p.y, p.z), &pixel, 0.5)) continue;  // the mask does not concern it
    ++inside_image;
    const double distance_to_limit = std::min({pixel.x() - 40.0, pixel.y() - 40.0, 599.0 - pixel.x(), 439.0 - pixel.y()});
    if (distance_to_limit > 0.01) ++surely_visible;
    else if (distance_to_limit > -0.01) ++maybe_visible;
  }
  ASSERT_GT(inside_image, 20000u);
  // Everything else is out, including the points outside the image now.
  const std::size_t hidden = road.swathe.PointCount() - road.swathe.VisibleCount();
  EXPECT_GE(hidden, road.swathe.PointCount() - surely_visible - maybe_visible);
  EXPECT_LE(hidden, road.swathe.PointCount() - surely_visible);
  EXPECT_GT(hidden - (road.swathe.PointCount() - inside_image), 100u);
  // Turned by 20 px at the centre (up to 30 px at the edges), the set of scored points is the same.
  Eigen::Isometry3d shifted = Eigen::Isometry3d::Identity();
  shifted.linear() = Eigen::AngleAxisd(-20.0 / 500.0, Eigen::Vector3d::UnitY())
                         .toRotationMatrix();
  std::size_t scored_at_refresh = 0, scored_shifted = 0;
  road.swathe.ForEachProjected(Eigen::Isometry3d::Identity(), true,
                               [&](std::size_t, float, float, float, float) { ++scored_at_refresh; });
  road.swathe.ForEachProjected(shifted, true, [&](std::size_t, float, float, float, float) { ++scored_shifted; });
  EXPECT_EQ(scored_shifted, scored_at_refresh);
  // Without the border, points enter or leave the image under the same move.
  options.refresh_border_px = 0.0;
  road.swathe.RefreshVisibility(Eigen::Isometry3d::Identity(), options);
  std::size_t all_at_refresh = 0, all_shifted = 0;
  road.swathe.ForEachProjected(Eigen::Isometry3d::Identity(), true,
                               [&](std::size_t, float, float, float, float) { ++all_at_refresh; });
  road.swathe.ForEachProjected(shifted, true, [&](std::size_t, float, float, float, float) { ++all_shifted; });
  EXPECT_NE(all_shifted, all_at_refresh);
}

TEST(PairCost, SwatheOptionsRefuseBadOcclusionAndBorderSettings) {
  std::string why;
  EXPECT_TRUE(SwatheOptions{}.IsValid(&why)) << why;
  const auto refused = [](auto&& change, const std::string& expected) {
    SwatheOptions options;
    change(options);
    std::string message;
    EXPECT_FALSE(options.IsValid(&message));
    EXPECT_NE(message.find(expected), std::string::npos) << message;
  };
  const double inf = std::numeric_limits<double>::infinity();
  refused([](SwatheOptions& o) { o.occlusion_cell_px = -1; }, "occlusion_cell_px");
  refused([](SwatheOptions& o) { o.occlusion_relative_margin = -0.1; }, "occlusion margins");
  refused([&](SwatheOptions& o) { o.occlusion_relative_margin = inf; }, "occlusion margins");
  refused([](SwatheOptions& o) { o.occlusion_absolute_margin_m = std::nan(""); }, "occlusion margins");
  refused([](SwatheOptions& o) { o.refresh_border_px = -1.0; }, "refresh_border_px");
  refused([&](SwatheOptions& o) { o.refresh_border_px = inf; }, "refresh_border_px");
}

TEST(InformativeScenes, ChoiceCoversTheWeakDirectionsBeforeRepeatingAStrongOne) {
  const InformativeChoiceOptions options;
  Vector6d unit;  // metres / radians per unit
  unit << Eigen::Vector3d::Constant(options.unit_translation_m), Eigen::Vector3d::Constant(options.unit_rotation_rad);
  // Information in units, converted to metres / radians: H = S^-1 H_units S^-1.
  const auto scene = [&](int axis, double strength) {
    Matrix6d in_units = Matrix6d::Zero();
    in_units(axis, axis) = strength;
    return Matrix6d(unit.cwiseInverse().asDiagonal() * in_units * unit.cwiseInverse().asDiagonal());
  };
  std::vector<Matrix6d> pool;
  for (int i = 0; i < 4; ++i) pool.push_back(scene(0, 100.0));  // 0..3: x only, strongly
  for (int axis = 0; axis < 6; ++axis) pool.push_back(scene(axis, 1.0));  // 4..9: one direction each, weakly
  pool.push_back(Matrix6d::Zero());  // 10: nothing
  InformativeChoiceOptions plain = options;
  plain.separate_neighbours = false;
  const InformativeChoice choice = ChooseInformativeScenes(pool, 6, plain);
  // One strong x scene (the first of the tie), then every other direction; not the weak x or a second strong x.
  EXPECT_EQ(choice.chosen, (std::vector<std::size_t>{0, 5, 6, 7, 8, 9}));
  EXPECT_GE(choice.predicted_variance_chosen, choice.predicted_variance_pool);
  EXPECT_LT(choice.predicted_variance_chosen, 1.1 * choice.predicted_variance_pool);
  // Evenly spread picks (every third) leave directions unconstrained: far worse.
  Matrix6d spread = Matrix6d::Zero();
  for (const std::size_t s : {0, 3, 6, 9}) spread += unit.asDiagonal() * pool[s] * unit.asDiagonal();
  EXPECT_LT(spread.fullPivLu().rank(), 6);
  // By default no two chosen scenes are neighbours in the pool while others are left: 0, then 5 (not 1 or 4),
  // then 7 and 9 (6 and 8 sit beside 5 and 7), then the strong x at 2 or 3 before a neighbour of a chosen one.
  const InformativeChoice apart = ChooseInformativeScenes(pool, 5, options);
  EXPECT_EQ(apart.chosen, (std::vector<std::size_t>{0, 2, 5, 7, 9}));
  const InformativeChoice packed = ChooseInformativeScenes(pool, 8, options);  // more than fit apart: neighbours too
  EXPECT_EQ(packed.chosen.size(), 8u);
  // All of a pool when asked for more; the empty scene last.
  const InformativeChoice all = ChooseInformativeScenes(pool, 50, options);
  EXPECT_EQ(all.chosen.size(), pool.size());
  const InformativeChoice ten = ChooseInformativeScenes(pool, 10, options);
  EXPECT_EQ(std::count(ten.chosen.begin(), ten.chosen.end(), std::size_t{10}), 0);
  EXPECT_TRUE(ChooseInformativeScenes({}, 3, options).chosen.empty());
}

TEST(InformativeScenes, PairKeepsTheFramesThatInformAndDropsFlatOnes) {
  const Synthetic s = MakeSynthetic(false);
  PairCostOptions options;
  const cv::Mat flat(s.image.size(), s.image.type(), cv::Scalar(0.5));
  std::vector<SceneSwathe> swathes;
  for (int frame = 0; frame < 5; ++frame) {
    Scene scene;
    scene.camera = "cam";
    scene.lidar = "lidar";
    scene.image_t_us = 1000 * frame;
    scene.scans.push_back({scene.image_t_us, Eigen::Isometry3d::Identity()});
    // Frames 1 and 3 textured, the others a uniform grey (no edge to align).
    swathes.push_back(SceneSwathe::Build(scene, s.camera, frame % 2 == 1 ? s.image : flat, {&s.scan}, options.swathe,
                                         NormalisationOptions{}));
  }
  PairCost cost(s.camera, "lidar", std::move(swathes), options);
  ASSERT_EQ(cost.RefreshVisibility(s.T_camera_lidar), 2);  // the flat frames are not used
  ASSERT_EQ(cost.FrameCount(), 5);
  const Matrix6d information = cost.Scenes()[1].AlignmentInformation(s.T_camera_lidar);
  EXPECT_TRUE(information.isApprox(information.transpose()));
  EXPECT_GT(information.trace(), 0.0);
  EXPECT_EQ(cost.Scenes()[0].AlignmentInformation(s.T_camera_lidar).norm(), 0.0);  // uniform image: nothing
  const InformativeChoice choice = cost.KeepMostInformative(s.T_camera_lidar, 2);
  EXPECT_EQ(choice.chosen, (std::vector<std::size_t>{1, 3}));
  ASSERT_EQ(cost.SceneCount(), 2);
  EXPECT_EQ(cost.Scenes()[0].ImageTime(), 1000);
  EXPECT_EQ(cost.Scenes()[1].ImageTime(), 3000);
  EXPECT_EQ(cost.RefreshVisibility(s.T_camera_lidar), 2);
  EXPECT_TRUE(std::isfinite(cost.Evaluate(s.T_camera_lidar)));
}

}  // namespace
}  // namespace scenecal
