// Camera models against OpenCV's reference implementations, round trips,
// validity rules, and the float fast path against the double one.
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include "core/camera.hpp"
#include "core/camera_kernel.hpp"
#include "core/geometry.hpp"

namespace scenecal {
namespace {

CameraModel MakeCamera(CameraModelKind kind, double fx, double cx, double fy, double cy,
                       std::vector<double> distortion, int width = 1920, int height = 1200) {
  CameraModel camera;
  camera.width = width;
  camera.height = height;
  camera.kind = kind;
  camera.fx = fx;
  camera.fy = fy;
  camera.cx = cx;
  camera.cy = cy;
  camera.distortion = std::move(distortion);
  return camera;
}

// The two real OpenCalib calibrations (calib.txt of rigs A and B), K given as
// fx cx fy cy.
CameraModel OpenCalibRigA() {
  return MakeCamera(CameraModelKind::kRadTan, 2152.8, 971.3, 2155.5, 605.9,
                    {-0.1192, 0.162, 0.00073985, 0.0014});
}
CameraModel OpenCalibRigB() {
  return MakeCamera(CameraModelKind::kRadTan, 2117.31, 924.681, 2113.29, 656.457,
                    {-0.102933, -0.040925, 0.00057951, -0.00419933, 0.429959});
}

// Random realistic intrinsics and distortion of the given kind (lenses from
// narrow to wide, distortions of the size calibration tools report).
CameraModel RandomCamera(CameraModelKind kind, std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const auto in = [&](double lo, double hi) { return lo + (hi - lo) * unit(rng); };
  const int width = static_cast<int>(in(640, 2048));
  const int height = static_cast<int>(in(480, 1536));
  const double f = in(0.4, 1.5) * width;
  std::vector<double> distortion;
  switch (kind) {
    case CameraModelKind::kPinhole:
      break;
    case CameraModelKind::kRadTan:
      distortion = {in(-0.4, 0.1), in(-0.1, 0.2), in(-2e-3, 2e-3), in(-2e-3, 2e-3)};
      if (unit(rng) < 0.5) distortion.push_back(in(-0.05, 0.3));
      break;
    case CameraModelKind::kEquidistant:
      distortion = {in(-0.05, 0.1), in(-0.05, 0.05), in(-0.02, 0.02), in(-0.01, 0.01)};
      break;
  }
  return MakeCamera(kind, f * in(0.98, 1.02), width * in(0.45, 0.55), f, height * in(0.45, 0.55),
                    distortion, width, height);
}

// Random points in front of the camera up to max_angle off the optical axis.
std::vector<Eigen::Vector3d> RandomPointsInFront(std::mt19937& rng, int count, double max_angle) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < count; ++i) {
    const double angle = max_angle * std::sqrt(unit(rng));
    const double azimuth = 2.0 * kPi * unit(rng);
    const double range = 0.5 + 60.0 * unit(rng);
    points.emplace_back(range * std::sin(angle) * std::cos(azimuth), range * std::sin(angle) * std::sin(azimuth),
                        range * std::cos(angle));
  }
  return points;
}

std::vector<cv::Point2d> OpenCvProject(const CameraModel& camera, const std::vector<Eigen::Vector3d>& points) {
  std::vector<cv::Point3d> object;
  for (const auto& p : points) object.emplace_back(p.x(), p.y(), p.z());
  const cv::Matx33d K(camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1);
  std::vector<cv::Point2d> image;
  if (camera.kind == CameraModelKind::kEquidistant) {
    cv::fisheye::projectPoints(object, image, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, camera.distortion);
  } else {
    cv::projectPoints(object, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, camera.distortion, image);
  }
  return image;
}

// Compares DistortAndScale/Project with OpenCV for points inside the model's
// monotonic range; returns how many points were compared.
int ExpectMatchesOpenCv(const CameraModel& camera, const std::vector<Eigen::Vector3d>& points) {
  const std::vector<cv::Point2d> expected = OpenCvProject(camera, points);
  const double limit = camera.MonotonicDistortionLimitSquared();
  int compared = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector2d normalised = points[i].head<2>() / points[i].z();
    const double s = camera.kind == CameraModelKind::kEquidistant ? std::pow(std::atan(normalised.norm()), 2)
                                                                  : normalised.squaredNorm();
    if (s >= limit) continue;
    Eigen::Vector2d pixel;
    const bool inside = camera.Project(points[i], &pixel);
    EXPECT_NEAR(pixel.x(), expected[i].x, 1e-6) << "point " << points[i].transpose();
    EXPECT_NEAR(pixel.y(), expected[i].y, 1e-6) << "point " << points[i].transpose();
    const bool expected_inside = expected[i].x >= -0.5 && expected[i].x < camera.width - 0.5 &&
                                 expected[i].y >= -0.5 && expected[i].y < camera.height - 0.5;
    EXPECT_EQ(inside, expected_inside) << "point " << points[i].transpose();
    ++compared;
  }
  return compared;
}

TEST(Camera, KindNamesRoundTrip) {
  for (CameraModelKind kind : {CameraModelKind::kPinhole, CameraModelKind::kRadTan, CameraModelKind::kEquidistant}) {
    CameraModelKind parsed = kind == CameraModelKind::kPinhole ? CameraModelKind::kRadTan : CameraModelKind::kPinhole;
    ASSERT_TRUE(ParseCameraModelKind(CameraModelKindName(kind), &parsed));
    EXPECT_EQ(parsed, kind);
  }
  CameraModelKind untouched = CameraModelKind::kRadTan;
  EXPECT_FALSE(ParseCameraModelKind("fisheye", &untouched));
  EXPECT_FALSE(ParseCameraModelKind("Pinhole", &untouched));
  EXPECT_FALSE(ParseCameraModelKind("", &untouched));
  EXPECT_EQ(untouched, CameraModelKind::kRadTan);
}

TEST(Camera, RadTanMatchesOpenCvOnOpenCalibIntrinsics) {
  std::mt19937 rng(11);
  for (const CameraModel& camera : {OpenCalibRigA(), OpenCalibRigB()}) {
    ASSERT_TRUE(camera.IsValid());
    // Both lenses cover about +-24 deg horizontally; go well past the image.
    const auto points = RandomPointsInFront(rng, 5000, RadiansFromDegrees(40));
    EXPECT_EQ(ExpectMatchesOpenCv(camera, points), 5000);  // no fold within 40 deg
  }
}

TEST(Camera, RadTanMatchesOpenCvOnRandomDistortions) {
  std::mt19937 rng(12);
  int compared = 0;
  for (int trial = 0; trial < 50; ++trial) {
    const CameraModel camera = RandomCamera(CameraModelKind::kRadTan, rng);
    ASSERT_TRUE(camera.IsValid());
    compared += ExpectMatchesOpenCv(camera, RandomPointsInFront(rng, 400, RadiansFromDegrees(60)));
  }
  EXPECT_GT(compared, 50 * 400 / 2);  // most points are inside the monotonic range
}

TEST(Camera, PinholeMatchesOpenCv) {
  std::mt19937 rng(13);
  for (int trial = 0; trial < 20; ++trial) {
    const CameraModel camera = RandomCamera(CameraModelKind::kPinhole, rng);
    EXPECT_EQ(ExpectMatchesOpenCv(camera, RandomPointsInFront(rng, 400, RadiansFromDegrees(70))), 400);
  }
}

TEST(Camera, EquidistantMatchesOpenCvFisheye) {
  std::mt19937 rng(14);
  int compared = 0;
  for (int trial = 0; trial < 50; ++trial) {
    CameraModel camera = RandomCamera(CameraModelKind::kEquidistant, rng);
    camera.fx *= 0.5;  // fisheye lenses: a wide field of view
    camera.fy *= 0.5;
    ASSERT_TRUE(camera.IsValid());
    compared += ExpectMatchesOpenCv(camera, RandomPointsInFront(rng, 400, RadiansFromDegrees(89)));
  }
  // Some random polynomials fold before 90 deg; those points are skipped.
  EXPECT_GT(compared, 50 * 400 * 3 / 4);
  // A real fisheye calibration (Kalibr-style equidistant, 190 deg lens class)
  // folds nowhere in the hemisphere.
  const CameraModel real = MakeCamera(CameraModelKind::kEquidistant, 380.7, 511.2, 380.4, 385.9,
                                      {-0.0135, 0.0034, -0.0056, 0.0011}, 1024, 768);
  EXPECT_EQ(ExpectMatchesOpenCv(real, RandomPointsInFront(rng, 4000, RadiansFromDegrees(89.9))), 4000);
}

// Pixel -> ray -> pixel, over the whole image including its corners.
void ExpectPixelRoundTrip(const CameraModel& camera, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-0.5 + 1e-6, camera.width - 0.5 - 1e-6);
  std::uniform_real_distribution<double> v(-0.5 + 1e-6, camera.height - 0.5 - 1e-6);
  // Corners inset by 1e-6 px: a pixel exactly on the edge may come back
  // 1e-13 px outside.
  std::vector<Eigen::Vector2d> pixels = {{-0.5 + 1e-6, -0.5 + 1e-6},
                                         {camera.width - 0.5 - 1e-6, -0.5 + 1e-6},
                                         {-0.5 + 1e-6, camera.height - 0.5 - 1e-6},
                                         {camera.width - 0.5 - 1e-6, camera.height - 0.5 - 1e-6},
                                         {camera.cx, camera.cy}};
  for (int i = 0; i < 1000; ++i) pixels.emplace_back(u(rng), v(rng));
  for (const auto& pixel : pixels) {
    const Eigen::Vector3d ray = camera.Unproject(pixel);
    ASSERT_DOUBLE_EQ(ray.z(), 1.0);
    for (double depth : {0.3, 7.0, 120.0}) {
      Eigen::Vector2d reprojected;
      EXPECT_TRUE(camera.Project(depth * ray, &reprojected)) << CameraModelKindName(camera.kind) << " pixel "
                                                             << pixel.transpose();
      EXPECT_LT((reprojected - pixel).norm(), 1e-10)
          << CameraModelKindName(camera.kind) << " pixel " << pixel.transpose();
    }
  }
}

// True when the edge of the distortion's monotonic range projects outside the
// image all round, so every pixel of the image has a preimage in that range.
bool WholeImageReachable(const CameraModel& camera) {
  const double limit = camera.MonotonicDistortionLimitSquared();
  const double r_edge = camera.kind == CameraModelKind::kEquidistant ? std::tan(0.999 * std::sqrt(limit))
                                                                     : std::sqrt(std::min(limit, 1e6)) * 0.999;
  for (int i = 0; i < 720; ++i) {
    const double azimuth = 2.0 * kPi * i / 720;
    const Eigen::Vector2d pixel = camera.DistortAndScale(r_edge * Eigen::Vector2d(std::cos(azimuth), std::sin(azimuth)));
    if (pixel.x() >= -0.5 && pixel.x() < camera.width - 0.5 && pixel.y() >= -0.5 && pixel.y() < camera.height - 0.5) {
      return false;
    }
  }
  return true;
}

TEST(Camera, UnprojectProjectRoundTrip) {
  std::mt19937 rng(15);
  ASSERT_TRUE(WholeImageReachable(OpenCalibRigA()));
  ASSERT_TRUE(WholeImageReachable(OpenCalibRigB()));
  ExpectPixelRoundTrip(OpenCalibRigA(), rng);
  ExpectPixelRoundTrip(OpenCalibRigB(), rng);
  int tested = 0;
  for (int trial = 0; trial < 20; ++trial) {
    for (CameraModelKind kind : {CameraModelKind::kPinhole, CameraModelKind::kRadTan, CameraModelKind::kEquidistant}) {
      const CameraModel camera = RandomCamera(kind, rng);
      if (!WholeImageReachable(camera)) continue;  // some pixels have no preimage
      ExpectPixelRoundTrip(camera, rng);
      ++tested;
    }
  }
  EXPECT_GT(tested, 40);
}

TEST(Camera, ProjectUnprojectRoundTripOfPoints) {
  std::mt19937 rng(16);
  for (const CameraModel& camera : {OpenCalibRigA(), OpenCalibRigB(),
                                    MakeCamera(CameraModelKind::kEquidistant, 400, 640, 400, 480,
                                               {0.02, -0.01, 0.004, -0.001}, 1280, 960)}) {
    for (const auto& point : RandomPointsInFront(rng, 3000, RadiansFromDegrees(80))) {
      Eigen::Vector2d pixel;
      if (!camera.Project(point, &pixel)) continue;
      const Eigen::Vector3d ray = camera.Unproject(pixel);
      EXPECT_LT((ray.normalized() - point.normalized()).norm(), 1e-12) << point.transpose();
    }
  }
}

TEST(Camera, RejectsPointsBehindOrAtTheCamera) {
  const CameraModel camera = OpenCalibRigA();
  Eigen::Vector2d pixel(-7, -7);
  EXPECT_FALSE(camera.Project({0, 0, -1}, &pixel));
  EXPECT_FALSE(camera.Project({0.1, 0.1, 0}, &pixel));
  EXPECT_EQ(pixel, Eigen::Vector2d(-7, -7));  // not written behind the camera
  EXPECT_TRUE(camera.Project({0, 0, 1e-3}, &pixel));
  EXPECT_FALSE(camera.Project({0, 0, 1e-3}, &pixel, 0.0, /*min_depth=*/0.01));
  EXPECT_TRUE(camera.Project({0, 0, 0.02}, &pixel, 0.0, /*min_depth=*/0.01));
  // A point behind the camera whose perspective division would land in the
  // image (x/z, y/z near the centre).
  EXPECT_FALSE(camera.Project({-1e-3, -1e-3, -5}, &pixel));

  const CameraModel fisheye = MakeCamera(CameraModelKind::kEquidistant, 300, 640, 300, 480, {0, 0, 0, 0}, 1280, 960);
  // theta = 90 deg (z = 0) is rejected; 89.9 deg still projects inside.
  EXPECT_FALSE(fisheye.Project({1, 0, 0}, &pixel));
  const double theta = RadiansFromDegrees(89.9);
  EXPECT_TRUE(fisheye.Project({std::sin(theta), 0, std::cos(theta)}, &pixel));
  EXPECT_NEAR(pixel.x(), 640 + 300 * theta, 1e-9);
}

TEST(Camera, ImageBoundsAndMargin) {
  // Pinhole, so pixels are easy to place: u = 100 x/z + 50.
  const CameraModel camera = MakeCamera(CameraModelKind::kPinhole, 100, 50, 100, 40, {}, 100, 80);
  const auto point_at = [](double u, double v) { return Eigen::Vector3d((u - 50) / 100, (v - 40) / 100, 1); };
  Eigen::Vector2d pixel;
  // The image covers [-0.5, width - 0.5) x [-0.5, height - 0.5).
  EXPECT_TRUE(camera.Project(point_at(-0.5, -0.5), &pixel));
  EXPECT_FALSE(camera.Project(point_at(-0.5 - 1e-9, 10), &pixel));
  EXPECT_FALSE(camera.Project(point_at(10, -0.5 - 1e-9), &pixel));
  EXPECT_TRUE(camera.Project(point_at(99.5 - 1e-9, 79.5 - 1e-9), &pixel));
  EXPECT_FALSE(camera.Project(point_at(99.5, 10), &pixel));
  EXPECT_FALSE(camera.Project(point_at(10, 79.5), &pixel));
  // Pixel written even when outside, for callers to inspect.
  EXPECT_FALSE(camera.Project(point_at(150, 10), &pixel));
  EXPECT_NEAR(pixel.x(), 150, 1e-12);
  // Margin shrinks every side.
  EXPECT_TRUE(camera.Project(point_at(5, 40), &pixel, 5.0));
  EXPECT_FALSE(camera.Project(point_at(4, 40), &pixel, 5.0));
  EXPECT_FALSE(camera.Project(point_at(95, 40), &pixel, 5.0));
  EXPECT_TRUE(camera.Project(point_at(93, 40), &pixel, 5.0));
  EXPECT_FALSE(camera.Project(point_at(50, 4), &pixel, 5.0));
  EXPECT_FALSE(camera.Project(point_at(50, 75), &pixel, 5.0));
  EXPECT_TRUE(camera.Project(point_at(50, 73), &pixel, 5.0));
}

TEST(Camera, RadTanFoldBackIsRejected) {
  // r_d = r (1 - 0.4 r^2) rises until r^2 = 1 / 1.2 and then falls back
  // through the image centre.
  const CameraModel camera = MakeCamera(CameraModelKind::kRadTan, 500, 640, 500, 480, {-0.4, 0, 0, 0}, 1280, 960);
  EXPECT_NEAR(camera.MonotonicDistortionLimitSquared(), 1.0 / 1.2, 1e-12);
  Eigen::Vector2d pixel;
  const Eigen::Vector3d folded(1.6, 0.0, 1.0);  // r_d = 1.6 (1 - 0.4 * 2.56) = -0.038
  EXPECT_FALSE(camera.Project(folded, &pixel));
  EXPECT_GE(pixel.x(), 0);  // ... although the folded pixel lies in the image
  EXPECT_LT(pixel.x(), 1280);
  EXPECT_NEAR(pixel.x(), 640 + 500 * 1.6 * (1 - 0.4 * 2.56), 1e-9);
  // Just inside the limit the point projects (the pixel is in the image too).
  const double r_inside = std::sqrt(1.0 / 1.2) * 0.999;
  EXPECT_TRUE(camera.Project({0, r_inside, 1}, &pixel));
  const double r_outside = std::sqrt(1.0 / 1.2) * 1.001;
  EXPECT_FALSE(camera.Project({0, r_outside, 1}, &pixel));

  // The limit is where d r_d / d r changes sign, for random distortions too.
  std::mt19937 rng(17);
  int folding = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const CameraModel random = RandomCamera(CameraModelKind::kRadTan, rng);
    const double limit = random.MonotonicDistortionLimitSquared();
    const double k1 = random.distortion[0], k2 = random.distortion[1];
    const double k3 = random.distortion.size() == 5 ? random.distortion[4] : 0.0;
    const auto slope = [&](double s) { return 1 + 3 * k1 * s + 5 * k2 * s * s + 7 * k3 * s * s * s; };
    if (!std::isfinite(limit)) {
      for (double s = 0; s < 1e4; s += 0.01) ASSERT_GT(slope(s), 0.0) << s;
      continue;
    }
    ++folding;
    EXPECT_NEAR(slope(limit), 0.0, 1e-9);
    for (double s = 0; s < limit; s += limit / 1000) ASSERT_GT(slope(s), 0.0) << s;
  }
  EXPECT_GT(folding, 10);
}

TEST(Camera, EquidistantFoldBackIsRejected) {
  // theta_d = theta (1 - 0.3 theta^2) rises until theta^2 = 1 / 0.9.
  const CameraModel camera =
      MakeCamera(CameraModelKind::kEquidistant, 300, 640, 300, 480, {-0.3, 0, 0, 0}, 1280, 960);
  EXPECT_NEAR(camera.MonotonicDistortionLimitSquared(), 1.0 / 0.9, 1e-12);
  Eigen::Vector2d pixel;
  const double theta_limit = std::sqrt(1.0 / 0.9);
  for (double theta : {0.99 * theta_limit, 1.01 * theta_limit, RadiansFromDegrees(85)}) {
    const bool inside = camera.Project({std::sin(theta), 0, std::cos(theta)}, &pixel);
    EXPECT_EQ(inside, theta < theta_limit) << theta;
    EXPECT_GT(pixel.x(), 640);  // in the image either way
    EXPECT_LT(pixel.x(), 1279);
  }
  // Without distortion the limit is the hemisphere.
  const CameraModel plain = MakeCamera(CameraModelKind::kEquidistant, 300, 640, 300, 480, {0, 0, 0, 0}, 1280, 960);
  EXPECT_DOUBLE_EQ(plain.MonotonicDistortionLimitSquared(), kPi * kPi / 4);
}

TEST(Camera, IsValidReportsTheProblem) {
  std::string why;
  EXPECT_TRUE(OpenCalibRigA().IsValid(&why));
  EXPECT_TRUE(OpenCalibRigB().IsValid(&why));
  EXPECT_TRUE(MakeCamera(CameraModelKind::kPinhole, 500, 320, 500, 240, {}).IsValid(&why));
  EXPECT_TRUE(MakeCamera(CameraModelKind::kEquidistant, 500, 320, 500, 240, {0.1, 0, 0, 0}).IsValid(&why));

  const auto expect_invalid = [&](const CameraModel& camera, const std::string& mention) {
    std::string message;
    EXPECT_FALSE(camera.IsValid(&message));
    EXPECT_NE(message.find(mention), std::string::npos) << "message: " << message;
    EXPECT_FALSE(camera.IsValid());  // no message pointer is fine
  };
  CameraModel camera = OpenCalibRigA();
  camera.width = 0;
  expect_invalid(camera, "image size");
  camera = OpenCalibRigA();
  camera.height = -3;
  expect_invalid(camera, "image size");
  camera = OpenCalibRigA();
  camera.fx = 0;
  expect_invalid(camera, "focal");
  camera = OpenCalibRigA();
  camera.fy = -1;
  expect_invalid(camera, "focal");
  camera = OpenCalibRigA();
  camera.fx = std::numeric_limits<double>::quiet_NaN();
  expect_invalid(camera, "focal");
  camera = OpenCalibRigA();
  camera.fy = std::numeric_limits<double>::infinity();
  expect_invalid(camera, "focal");
  camera = OpenCalibRigA();
  camera.cx = std::numeric_limits<double>::infinity();
  expect_invalid(camera, "principal point");
  camera = OpenCalibRigA();
  camera.cy = std::numeric_limits<double>::quiet_NaN();
  expect_invalid(camera, "principal point");
  camera = OpenCalibRigA();
  camera.distortion = {0.1, 0.2, 0.3};
  expect_invalid(camera, "radtan takes 4 or 5");
  camera.distortion = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6};
  expect_invalid(camera, "radtan takes 4 or 5");
  camera.distortion = {0.1, std::numeric_limits<double>::quiet_NaN(), 0, 0};
  expect_invalid(camera, "coefficient 1");
  camera = MakeCamera(CameraModelKind::kPinhole, 500, 320, 500, 240, {0.1});
  expect_invalid(camera, "pinhole");
  camera = MakeCamera(CameraModelKind::kEquidistant, 500, 320, 500, 240, {0.1, 0, 0, 0, 0});
  expect_invalid(camera, "equidistant takes 4");
  camera = MakeCamera(CameraModelKind::kEquidistant, 500, 320, 500, 240, {0.1, 0, 0, -std::numeric_limits<double>::infinity()});
  expect_invalid(camera, "coefficient 3");
}

TEST(CameraKernel, ProjectFastAgreesWithProject) {
  std::mt19937 rng(18);
  std::vector<CameraModel> cameras = {OpenCalibRigA(), OpenCalibRigB(),
                                      MakeCamera(CameraModelKind::kRadTan, 500, 320, 500, 240, {-0.4, 0, 0, 0}, 640, 480),
                                      MakeCamera(CameraModelKind::kEquidistant, 300, 640, 300, 480, {-0.3, 0, 0, 0}, 1280, 960)};
  for (int trial = 0; trial < 10; ++trial) {
    for (CameraModelKind kind : {CameraModelKind::kPinhole, CameraModelKind::kRadTan, CameraModelKind::kEquidistant}) {
      cameras.push_back(RandomCamera(kind, rng));
    }
  }
  int accepted = 0, rejected = 0;
  for (const CameraModel& camera : cameras) {
    for (double margin : {0.0, 12.0}) {
      const ProjectionParams params = MakeProjectionParams(camera, margin);
      const double limit = camera.MonotonicDistortionLimitSquared();
      auto points = RandomPointsInFront(rng, 2000, RadiansFromDegrees(85));
      points.emplace_back(0, 0, -1);
      points.emplace_back(0, 0, 0);
      for (const auto& point : points) {
        Eigen::Vector2d pixel;
        const bool inside = camera.Project(point, &pixel, margin);
        float u = 0, v = 0;
        const bool fast_inside = ProjectFast(params, static_cast<float>(point.x()), static_cast<float>(point.y()),
                                             static_cast<float>(point.z()), &u, &v);
        if (!(point.z() > 1e-6)) {
          EXPECT_FALSE(fast_inside);
          continue;
        }
        // Points within float precision of a decision boundary may go either way.
        const Eigen::Vector2d normalised = point.head<2>() / point.z();
        const double s = camera.kind == CameraModelKind::kEquidistant ? std::pow(std::atan(normalised.norm()), 2)
                                                                      : normalised.squaredNorm();
        const double to_edge = std::min({std::abs(pixel.x() - (-0.5 + margin)),
                                         std::abs(pixel.x() - (camera.width - 0.5 - margin)),
                                         std::abs(pixel.y() - (-0.5 + margin)),
                                         std::abs(pixel.y() - (camera.height - 0.5 - margin))});
        const bool near_boundary = to_edge < 1e-2 || std::abs(s - limit) < 1e-5 * std::max(1.0, limit);
        if (!near_boundary) {
          EXPECT_EQ(fast_inside, inside) << point.transpose();
        }
        if (inside) {
          EXPECT_NEAR(u, pixel.x(), 1e-3) << CameraModelKindName(camera.kind) << " " << point.transpose();
          EXPECT_NEAR(v, pixel.y(), 1e-3) << CameraModelKindName(camera.kind) << " " << point.transpose();
          ++accepted;
        } else {
          ++rejected;
        }
      }
    }
  }
  EXPECT_GT(accepted, 10000);
  EXPECT_GT(rejected, 10000);
}

}  // namespace
}  // namespace scenecal
