// Round trips of every FORMAT.md file through the io writers and readers.
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>
#include <yaml-cpp/yaml.h>

#include "io/dataset.hpp"
#include "io/inspect.hpp"
#include "io/option_file.hpp"
#include "io/result_file.hpp"
#include "io_test_support.hpp"

namespace scenecal {
namespace {

using namespace scenecal::testing;

// Transforms are written as 6-tuples with 12 significant digits.
constexpr double kTransformTolerance = 1e-11;

double MatrixDistance(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff();
}

Rig ThreeModelRig() {
  Rig rig;
  rig.base_frame = "cam_front";
  CameraInfo front;
  front.name = "cam_front";
  front.model = {1280, 960, CameraModelKind::kPinhole, 983.044, 983.044, 643.647, 493.379, {}};
  CameraInfo side;
  side.name = "cam-side";
  side.model = {640, 480, CameraModelKind::kRadTan, 400.1, 401.2, 320.3, 240.4, {-0.1, 0.02, 0.001, -0.002, 0.003}};
  side.T_base_camera = TransformFromTuple((Vector6d() << 0.24, -0.01, 0.02, 0.1, -0.2, 1.3).finished());
  side.T_base_camera_sigma = (Vector6d() << 0.0005, 0.0005, 0.001, 0.001, 0.002, 0.0).finished();
  CameraInfo fisheye;
  fisheye.name = "Fish3";
  fisheye.model = {800, 800, CameraModelKind::kEquidistant, 300, 300, 399.5, 399.5, {0.01, -0.003, 0.0004, -0.00005}};
  fisheye.T_base_camera = TransformFromTuple((Vector6d() << -0.1, 0.2, 0.3, 3.1, 0.4, -2.9).finished());
  rig.cameras = {front, side, fisheye};
  LidarInfo rear;
  rear.name = "rear";
  rear.kind = LidarKind::k2d;
  rear.T_base_lidar = TransformFromTuple((Vector6d() << -2.6, 0.3, 1.1, -2.84, -1.51, -0.36).finished());
  LidarInfo top;
  top.name = "top";
  top.kind = LidarKind::k3d;
  top.T_base_lidar = TransformFromTuple((Vector6d() << 0.1, 0.2, 1.9, 0.001, 0.002, 1.5707).finished());
  rig.lidars = {rear, top};
  return rig;
}

TEST(DatasetIo, RigRoundTripWithAllModelsAndSigma) {
  const TempDir temp;
  const Rig rig = ThreeModelRig();
  io::WriteRig(temp.path() / "rig.yaml", rig);
  const Rig read = io::ReadRig(temp.path() / "rig.yaml");
  EXPECT_EQ(read.base_frame, rig.base_frame);
  ASSERT_EQ(read.cameras.size(), rig.cameras.size());
  for (std::size_t i = 0; i < rig.cameras.size(); ++i) {
    const CameraInfo& a = rig.cameras[i];
    const CameraInfo& b = read.cameras[i];
    EXPECT_EQ(b.name, a.name);
    EXPECT_EQ(b.model.kind, a.model.kind);
    EXPECT_EQ(b.model.width, a.model.width);
    EXPECT_EQ(b.model.height, a.model.height);
    EXPECT_EQ(b.model.fx, a.model.fx);  // shortest round-trip digits: exact
    EXPECT_EQ(b.model.fy, a.model.fy);
    EXPECT_EQ(b.model.cx, a.model.cx);
    EXPECT_EQ(b.model.cy, a.model.cy);
    EXPECT_EQ(b.model.distortion, a.model.distortion);
    EXPECT_LT(MatrixDistance(b.T_base_camera, a.T_base_camera), kTransformTolerance);
    ASSERT_EQ(b.T_base_camera_sigma.has_value(), a.T_base_camera_sigma.has_value());
    if (a.T_base_camera_sigma) {
      EXPECT_EQ(*b.T_base_camera_sigma, *a.T_base_camera_sigma);
    }
  }
  ASSERT_EQ(read.lidars.size(), rig.lidars.size());
  for (std::size_t i = 0; i < rig.lidars.size(); ++i) {
    EXPECT_EQ(read.lidars[i].name, rig.lidars[i].name);
    EXPECT_EQ(read.lidars[i].kind, rig.lidars[i].kind);
    EXPECT_LT(MatrixDistance(read.lidars[i].T_base_lidar, rig.lidars[i].T_base_lidar), kTransformTolerance);
  }
  // Writing what was read gives the same file: nothing is lost or re-rounded.
  io::WriteRig(temp.path() / "rig2.yaml", read);
  EXPECT_EQ(ReadFile(temp.path() / "rig2.yaml"), ReadFile(temp.path() / "rig.yaml"));
}

TEST(DatasetIo, RigAcceptsFourByFourTransformsAndExtra) {
  const TempDir temp;
  const Eigen::Isometry3d T_base_lidar =
      TransformFromTuple((Vector6d() << -2.6, 0.3, 1.1, -2.84, -1.51, -0.36).finished());
  std::string matrix = "[";
  for (int row = 0; row < 4; ++row) {
    matrix += row == 0 ? "[" : ", [";
    for (int col = 0; col < 4; ++col) matrix += fmt::format("{}{}", col == 0 ? "" : ", ", T_base_lidar.matrix()(row, col));
    matrix += "]";
  }
  matrix += "]";
  std::string rig_text = kValidRig;
  rig_text.replace(rig_text.find("[-2.6, 0.3, 1.1, -2.84, -1.51, -0.36]"), 37, matrix);
  WriteFile(temp.path() / "rig.yaml", rig_text);
  const Rig rig = io::ReadRig(temp.path() / "rig.yaml");
  ASSERT_EQ(rig.lidars.size(), 1u);
  EXPECT_LT(MatrixDistance(rig.lidars[0].T_base_lidar, T_base_lidar), 1e-15);
  // The valid rig has an `extra:` mapping with nested content; WriteRig with extra keeps it readable.
  YAML::Node extra;
  extra["source"] = "test";
  extra["list"].push_back(1.5);
  io::WriteRig(temp.path() / "rig_extra.yaml", rig, extra);
  EXPECT_NE(ReadFile(temp.path() / "rig_extra.yaml").find("source: test"), std::string::npos);
  EXPECT_NO_THROW(io::ReadRig(temp.path() / "rig_extra.yaml"));
}

// trajectory_source (FORMAT.md): optional, unknown when absent, written back
// when known, a value outside the list refused with the choices.
TEST(DatasetIo, RigTrajectorySourceIsReadWrittenAndChecked) {
  const TempDir temp;
  WriteFile(temp.path() / "rig.yaml", kValidRig);
  Rig rig = io::ReadRig(temp.path() / "rig.yaml");
  EXPECT_EQ(rig.trajectory_source, TrajectorySource::kUnknown);
  rig.trajectory_source = TrajectorySource::kVisualOdometry;
  io::WriteRig(temp.path() / "rig_vo.yaml", rig);
  EXPECT_NE(ReadFile(temp.path() / "rig_vo.yaml").find("trajectory_source: visual-odometry"), std::string::npos);
  EXPECT_EQ(io::ReadRig(temp.path() / "rig_vo.yaml").trajectory_source, TrajectorySource::kVisualOdometry);
  for (const char* name : {"exact", "ins", "lidar-odometry", "visual-odometry", "unknown"}) {
    TrajectorySource source = TrajectorySource::kUnknown;
    ASSERT_TRUE(ParseTrajectorySource(name, &source)) << name;
    EXPECT_STREQ(TrajectorySourceName(source), name);
  }
  WriteFile(temp.path() / "rig_bad.yaml", std::string(kValidRig) + "trajectory_source: gps\n");
  try {
    io::ReadRig(temp.path() / "rig_bad.yaml");
    ADD_FAILURE() << "a trajectory_source outside the list was accepted";
  } catch (const io::InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("trajectory_source"), std::string::npos) << message;
    EXPECT_NE(message.find("visual-odometry"), std::string::npos) << message;
  }
}

TEST(DatasetIo, TrajectoryRoundTripIsExact) {
  const TempDir temp;
  std::vector<TimeUs> times;
  std::vector<Eigen::Isometry3d> poses;
  for (int i = 0; i < 50; ++i) {
    times.push_back(1418381798086398 + i * 12345);
    poses.push_back(TransformFromTuple(
        (Vector6d() << 0.1 * i + 1e-7, -0.03 * i, 1.0 / 3.0, 0.01 * i, -0.02 * i, 0.05 * i - 1.0).finished()));
  }
  const Trajectory trajectory(times, poses);
  io::WriteTrajectory(temp.path() / "trajectory.csv", trajectory);
  const Trajectory read = io::ReadTrajectory(temp.path() / "trajectory.csv");
  ASSERT_EQ(read.size(), trajectory.size());
  EXPECT_EQ(read.times_us(), trajectory.times_us());
  for (std::size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read.poses()[i].translation(), trajectory.poses()[i].translation());
    EXPECT_LT(MatrixDistance(read.poses()[i], trajectory.poses()[i]), 1e-15);
  }
}

TEST(DatasetIo, TrajectoryNormalisesSlightlyOffQuaternions) {
  const TempDir temp;
  WriteFile(temp.path() / "trajectory.csv", "timestamp_us,x,y,z,qx,qy,qz,qw\r\n5,1,2,3,0,0,0,1.0009\r\n");
  const Trajectory read = io::ReadTrajectory(temp.path() / "trajectory.csv");
  ASSERT_EQ(read.size(), 1u);
  EXPECT_LT((read.poses()[0].rotation() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_EQ(read.poses()[0].translation(), Eigen::Vector3d(1, 2, 3));
}

TEST(DatasetIo, GroundTruthRoundTrip) {
  const TempDir temp;
  GroundTruth truth;
  truth.T_base_lidar["rear"] = TransformFromTuple((Vector6d() << -2.6, 0.3, 1.1, -2.84, -1.51, -0.36).finished());
  truth.T_base_camera["right"] = TransformFromTuple((Vector6d() << 0.24, 0.001, 0, 0.002, 0, 0).finished());
  io::WriteGroundTruth(temp.path() / "gt.yaml", truth);
  const GroundTruth read = io::ReadGroundTruth(temp.path() / "gt.yaml");
  ASSERT_EQ(read.T_base_lidar.size(), 1u);
  ASSERT_EQ(read.T_base_camera.size(), 1u);
  EXPECT_LT(MatrixDistance(read.T_base_lidar.at("rear"), truth.T_base_lidar.at("rear")), kTransformTolerance);
  EXPECT_LT(MatrixDistance(read.T_base_camera.at("right"), truth.T_base_camera.at("right")), kTransformTolerance);
}

// The 40 x 30 camera the image tests read their images with.
CameraModel SmallCamera() {
  CameraModel camera;
  camera.width = 40;
  camera.height = 30;
  camera.fx = camera.fy = 50;
  return camera;
}

TEST(DatasetIo, ImagesRoundTripGreyColour8And16Bit) {
  const TempDir temp;
  const CameraModel camera = SmallCamera();
  // 8-bit grey through WriteImage: exact values / 255.
  const cv::Mat grey8 = TestPattern(40, 30, CV_8UC1);
  io::WriteImage(temp.path() / "10.png", grey8);
  const GreyImage a = io::ReadImage({10, temp.path() / "10.png"}, camera);
  EXPECT_EQ(a.t_us, 10);
  ASSERT_EQ(a.intensity.type(), CV_32F);
  EXPECT_FLOAT_EQ(a.intensity.at<float>(7, 9), grey8.at<std::uint8_t>(7, 9) / 255.0f);
  // 16-bit grey: / 65535.
  const cv::Mat grey16 = TestPattern(40, 30, CV_16UC1);
  io::WriteImage(temp.path() / "11.png", grey16);
  const GreyImage b = io::ReadImage({11, temp.path() / "11.png"}, camera);
  EXPECT_FLOAT_EQ(b.intensity.at<float>(20, 3), grey16.at<std::uint16_t>(20, 3) / 65535.0f);
  double min = 0, max = 0;
  cv::minMaxLoc(b.intensity, &min, &max);
  EXPECT_GE(min, 0.0);
  EXPECT_LE(max, 1.0);
  // Colour (BGR) and BGRA: the grey conversion of OpenCV, scaled.
  for (const int type : {CV_8UC3, CV_8UC4, CV_16UC3}) {
    const cv::Mat colour = TestPattern(40, 30, type);
    const fs::path path = temp.path() / "12.png";
    ASSERT_TRUE(cv::imwrite(path.string(), colour));
    cv::Mat expected;
    cv::cvtColor(colour, expected, colour.channels() == 3 ? cv::COLOR_BGR2GRAY : cv::COLOR_BGRA2GRAY);
    const double scale = colour.depth() == CV_16U ? 1.0 / 65535.0 : 1.0 / 255.0;
    const GreyImage c = io::ReadImage({12, path}, camera);
    const double expected_value = colour.depth() == CV_16U ? expected.at<std::uint16_t>(5, 6) * scale
                                                           : expected.at<std::uint8_t>(5, 6) * scale;
    EXPECT_NEAR(c.intensity.at<float>(5, 6), expected_value, 1e-6) << "type " << type;
  }
  // JPEG by extension (lossy: values close, size right).
  const cv::Mat smooth(30, 40, CV_8UC1, cv::Scalar(100));
  io::WriteImage(temp.path() / "13.jpg", smooth);
  const GreyImage d = io::ReadImage({13, temp.path() / "13.jpg"}, camera);
  EXPECT_NEAR(d.intensity.at<float>(15, 20), 100.0 / 255.0, 2.0 / 255.0);
  EXPECT_EQ(io::ImageFileSize(temp.path() / "13.jpg"), std::make_pair(40, 30));
  EXPECT_EQ(io::ImageFileSize(temp.path() / "11.png"), std::make_pair(40, 30));
}

TEST(DatasetIo, ExcessGreenChannelOfColourImagesAndGreyRefused) {
  const TempDir temp;
  const CameraModel camera = SmallCamera();
  io::ImageChannel channel = io::ImageChannel::kGrey;
  ASSERT_TRUE(io::ParseImageChannel("exg", &channel));
  EXPECT_EQ(channel, io::ImageChannel::kExcessGreen);
  EXPECT_STREQ(io::ImageChannelName(channel), "exg");
  EXPECT_FALSE(io::ParseImageChannel("green", &channel));
  // (2G - R - B + 2) / 4 of the channels scaled to [0, 1], for 8- and 16-bit BGR and BGRA.
  for (const int type : {CV_8UC3, CV_8UC4, CV_16UC3}) {
    const cv::Mat colour = TestPattern(40, 30, type);
    const fs::path path = temp.path() / "20.png";
    ASSERT_TRUE(cv::imwrite(path.string(), colour));
    const double scale = colour.depth() == CV_16U ? 1.0 / 65535.0 : 1.0 / 255.0;
    const GreyImage image = io::ReadImage({20, path}, camera, io::ImageChannel::kExcessGreen);
    ASSERT_EQ(image.intensity.type(), CV_32F);
    for (const auto& [row, col] : {std::pair{5, 6}, std::pair{17, 31}}) {
      cv::Mat pixel = colour(cv::Rect(col, row, 1, 1));
      pixel.convertTo(pixel, CV_64F, scale);
      const double* bgr = pixel.ptr<double>(0);
      const double expected = (2.0 * bgr[1] - bgr[2] - bgr[0] + 2.0) / 4.0;
      EXPECT_NEAR(image.intensity.at<float>(row, col), expected, 1e-6) << "type " << type;
    }
  }
  // A pure green pixel is the brightest (1), magenta the darkest (0).
  cv::Mat two(30, 40, CV_8UC3, cv::Scalar(0, 255, 0));
  two(cv::Rect(0, 0, 20, 30)).setTo(cv::Scalar(255, 0, 255));
  ASSERT_TRUE(cv::imwrite((temp.path() / "21.png").string(), two));
  const GreyImage extremes = io::ReadImage({21, temp.path() / "21.png"}, camera, io::ImageChannel::kExcessGreen);
  EXPECT_FLOAT_EQ(extremes.intensity.at<float>(10, 30), 1.0f);
  EXPECT_FLOAT_EQ(extremes.intensity.at<float>(10, 5), 0.0f);
  // A grey image has no excess green: refused, naming the file and the field.
  io::WriteImage(temp.path() / "22.png", TestPattern(40, 30, CV_8UC1));
  try {
    io::ReadImage({22, temp.path() / "22.png"}, camera, io::ImageChannel::kExcessGreen);
    ADD_FAILURE() << "a grey image was accepted for the excess-green channel";
  } catch (const io::InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("22.png"), std::string::npos) << message;
    EXPECT_NE(message.find("image channels"), std::string::npos) << message;
    EXPECT_NE(message.find("exg"), std::string::npos) << message;
  }
}

TEST(DatasetIo, ScansRoundTripAndCountNoReturns) {
  const TempDir temp;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const std::vector<LidarPoint> points = {
      {1, 2, 3, 4}, {nan, 0, 0, 1}, {-1.5f, 2.25f, 0, 0}, {0, inf, 0, 1}, {0, 0, 0, nan}, {7, 8, 9, 10}};
  io::WriteScan(temp.path() / "42.bin", points);
  EXPECT_EQ(fs::file_size(temp.path() / "42.bin"), 16u * points.size());
  const LidarScan scan = io::ReadScan({42, temp.path() / "42.bin"});
  EXPECT_EQ(scan.t_us, 42);
  EXPECT_EQ(scan.no_returns, 3u);
  ASSERT_EQ(scan.points.size(), 3u);
  EXPECT_EQ(scan.points[0].x, 1.0f);
  EXPECT_EQ(scan.points[1].y, 2.25f);
  EXPECT_EQ(scan.points[2].reflectance, 10.0f);
  EXPECT_EQ(io::ScanRecordCount({42, temp.path() / "42.bin"}), points.size());
  io::WriteScan(temp.path() / "43.bin", {});
  EXPECT_TRUE(io::ReadScan({43, temp.path() / "43.bin"}).points.empty());
}

TEST(DatasetIo, CalibrationResultRoundTripWithExtraKeys) {
  const TempDir temp;
  CalibrationResult result;
  LidarCalibration lidar;
  lidar.lidar = "rear";
  lidar.T_base_lidar = TransformFromTuple((Vector6d() << -2.6, 0.3, 1.1, -2.84, -1.51, -0.36).finished());
  lidar.sigma = (Vector6d() << 0.01, 0.02, 0.03, 0.001, 0.002, 0.003).finished();
  LidarCalibration other;
  other.lidar = "top";
  result.lidars = {lidar, other};
  PairCalibration pair;
  pair.camera = "left";
  pair.lidar = "rear";
  pair.T_camera_lidar = TransformFromTuple((Vector6d() << 1, 2, 3, 0.1, 0.2, 0.3).finished());
  pair.cost = 0.912345678901234;
  result.pairs = {pair};
  result.termination = "converged: change below 1e-4: after 7 iterations";
  result.settings = {{"metric", "nid"}, {"scheme", "alt"}, {"bins", "32"}, {"flag", "true"}};
  result.timings_s = {{"total", 12.5}, {"lower", 1.0 / 3.0}};
  result.warnings = {"rotation about x: weakly constrained", "no: colon: issues"};
  YAML::Node extra;
  YAML::Node iteration;
  iteration["iteration"] = 1;
  iteration["cost"] = 0.95;
  extra["history"].push_back(iteration);
  const fs::path path = temp.path() / "calibration.yaml";
  io::WriteCalibrationResult(path, result, extra);
  const std::string text = ReadFile(path);
  EXPECT_EQ(text.rfind("format: scenecal-calibration/1", 0), 0u) << text;
  EXPECT_NE(text.find("history:"), std::string::npos);
  const CalibrationResult read = io::ReadCalibrationResult(path);
  ASSERT_EQ(read.lidars.size(), 2u);
  EXPECT_EQ(read.lidars[0].lidar, "rear");
  EXPECT_LT(MatrixDistance(read.lidars[0].T_base_lidar, lidar.T_base_lidar), kTransformTolerance);
  ASSERT_TRUE(read.lidars[0].sigma.has_value());
  EXPECT_EQ(*read.lidars[0].sigma, *lidar.sigma);
  EXPECT_FALSE(read.lidars[1].sigma.has_value());
  ASSERT_EQ(read.pairs.size(), 1u);
  EXPECT_EQ(read.pairs[0].camera, "left");
  EXPECT_EQ(read.pairs[0].lidar, "rear");
  EXPECT_EQ(read.pairs[0].cost, pair.cost);
  EXPECT_LT(MatrixDistance(read.pairs[0].T_camera_lidar, pair.T_camera_lidar), kTransformTolerance);
  EXPECT_EQ(read.termination, result.termination);
  EXPECT_EQ(read.settings, result.settings);
  EXPECT_EQ(read.timings_s, result.timings_s);
  EXPECT_EQ(read.warnings, result.warnings);
  // A standard key cannot be overridden through the extra keys.
  YAML::Node clash;
  clash["pairs"] = 1;
  EXPECT_THROW(io::WriteCalibrationResult(path, result, clash), std::invalid_argument);
  EXPECT_EQ(ReadFile(path), text);  // the earlier file is untouched
}

TEST(DatasetIo, DatasetSkeletonAndOpen) {
  const TempDir temp;
  const fs::path root = temp.path() / "sim";
  const Rig rig = ThreeModelRig();
  const Trajectory trajectory({100, 200, 300}, {Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity(),
                                                Eigen::Isometry3d(Eigen::Translation3d(1, 0, 0))});
  GroundTruth truth;
  truth.T_base_lidar["top"] = rig.lidars[1].T_base_lidar;
  io::WriteDatasetSkeleton(root, rig, trajectory, truth);
  io::WriteImage(root / "cameras" / "cam_front" / "200.png", cv::Mat(960, 1280, CV_8UC1, cv::Scalar(3)));
  io::WriteImage(root / "cameras" / "cam_front" / "100.png", cv::Mat(960, 1280, CV_8UC1, cv::Scalar(3)));
  io::WriteScan(root / "lidars" / "top" / "250.bin", TestPoints(4, 0));
  // The skeleton alone is not a dataset: every sensor needs a data file (FORMAT.md).
  EXPECT_THROW(io::OpenDataset(root), io::InputError);
  io::WriteImage(root / "cameras" / "cam-side" / "300.png", cv::Mat(480, 640, CV_8UC1, cv::Scalar(3)));
  io::WriteImage(root / "cameras" / "Fish3" / "300.png", cv::Mat(800, 800, CV_8UC1, cv::Scalar(3)));
  io::WriteScan(root / "lidars" / "rear" / "150.bin", TestPoints(4, 0));
  const io::Dataset dataset = io::OpenDataset(root);
  ASSERT_EQ(dataset.images.at("cam_front").size(), 2u);
  EXPECT_EQ(dataset.images.at("cam_front")[0].t_us, 100);  // sorted by time
  EXPECT_EQ(dataset.images.at("cam_front")[1].t_us, 200);
  EXPECT_EQ(dataset.images.at("cam-side").size(), 1u);
  EXPECT_EQ(dataset.scans.at("top").size(), 1u);
  EXPECT_EQ(dataset.scans.at("rear").size(), 1u);
  ASSERT_TRUE(dataset.ground_truth.has_value());
  EXPECT_EQ(dataset.ground_truth->T_base_lidar.count("top"), 1u);
}

TEST(DatasetIo, SummaryOfTheSmallDataset) {
  const TempDir temp;
  const fs::path root = temp.path() / "dataset";
  WriteValidDataset(root);
  const io::Dataset dataset = io::OpenDataset(root);
  std::size_t progress_calls = 0;
  const io::DatasetSummary summary =
      io::SummariseDataset(dataset, {}, [&](std::size_t done, std::size_t total) {
        ++progress_calls;
        EXPECT_LE(done, total);
      });
  EXPECT_EQ(progress_calls, 6u);  // 3 images + 3 scans
  ASSERT_EQ(summary.cameras.size(), 2u);
  EXPECT_EQ(summary.cameras[0].images, 2u);
  EXPECT_NEAR(summary.cameras[0].rate_hz, 1.0 / 0.2, 1e-9);
  EXPECT_EQ(summary.cameras[0].with_scans_nearby, 2u);
  ASSERT_EQ(summary.lidars.size(), 1u);
  EXPECT_EQ(summary.lidars[0].points_min, 10u);
  EXPECT_EQ(summary.lidars[0].points_median, 12u);
  EXPECT_EQ(summary.lidars[0].points_max, 14u);
  EXPECT_NEAR(summary.distance_m, 0.5, 1e-12);
  EXPECT_NEAR(summary.mean_speed_m_s, 1.0, 1e-9);
  EXPECT_TRUE(summary.ground_truth);
  EXPECT_TRUE(summary.can_calibrate);
  const std::string text = io::FormatDatasetSummary(dataset, summary);
  EXPECT_NE(text.find("verdict: can be calibrated"), std::string::npos) << text;
  // Quick mode reads sizes only and reaches the same verdict.
  io::SummaryOptions quick;
  quick.read_contents = false;
  const io::DatasetSummary quick_summary = io::SummariseDataset(dataset, quick);
  EXPECT_TRUE(quick_summary.can_calibrate);
  EXPECT_EQ(quick_summary.lidars[0].points_max, 14u);
}

// Found by fuzz_scan: an empty scan copied 0 bytes from a null pointer
// (undefined behaviour; UBSan builds report it).
TEST(DatasetIo, EmptyScanFileHasNoPoints) {
  const LidarScan scan = io::ParseScan("", "0.bin", 7);
  EXPECT_TRUE(scan.points.empty());
  EXPECT_EQ(scan.no_returns, 0u);
  EXPECT_EQ(scan.t_us, 7);
}

// Found by fuzz_calibration_result: a byte that is not UTF-8 was read as it
// is but written back as U+FFFD, so a file did not survive a round trip. YAML
// is Unicode text: such bytes are refused, naming the line.
TEST(DatasetIo, YamlFilesMustBeUtf8) {
  const std::string result = "format: scenecal-calibration/1\nlidars: {}\npairs: []\nwarnings:\n  - \"caf\xe9\"\n";
  try {
    io::ParseCalibrationResult(result, "result.yaml");
    ADD_FAILURE() << "accepted";
  } catch (const io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("result.yaml: line 5"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("not UTF-8"), std::string::npos) << e.what();
  }
  for (const char* bad : {"\xc0\xaf", "\xed\xa0\x80", "\xf4\x90\x80\x80", "\xe2\x82"}) {  // overlong, surrogate, > U+10FFFF, cut
    EXPECT_THROW(io::ParseRig(std::string(kValidRig) + "  x: \"" + bad + "\"\n", "rig.yaml"), io::InputError) << bad;
  }
  // yaml-cpp decodes the escapes \_ and \N to lone Latin-1 bytes, which would
  // not survive being written back (found by fuzz_calibration_result): refused,
  // in a value and in a settings key, naming the field.
  const std::pair<const char*, const char*> escapes[] = {{"termination: \"a\\_b\"\n", "result.yaml: termination (line 4)"},
                                                         {"warnings: [\"a\\Nb\"]\n", "result.yaml: warnings[0] (line 4)"},
                                                         {"settings:\n  \"a\\_b\": x\n", "result.yaml: a key of settings (line 5)"}};
  for (const auto& [bad, where] : escapes) {
    try {
      io::ParseCalibrationResult(std::string("format: scenecal-calibration/1\nlidars: {}\npairs: []\n") + bad,
                                 "result.yaml");
      ADD_FAILURE() << "accepted " << bad;
    } catch (const io::InputError& e) {
      EXPECT_NE(std::string(e.what()).find(where), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("not UTF-8 (from an escape)"), std::string::npos) << e.what();
    }
  }
  // Well-formed UTF-8 (2, 3 and 4 bytes) is text like any other.
  const std::string good = "format: scenecal-calibration/1\nlidars: {}\npairs: []\nwarnings: [\"caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x99\x82\"]\n";
  EXPECT_EQ(io::ParseCalibrationResult(good, "result.yaml").warnings.at(0), "caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x99\x82");
}

// A settings or timings key with an escaped control character ("\r", found by
// fuzz_calibration_result) is written quoted and escaped, so it reads back the same.
TEST(DatasetIo, ResultKeysWithEscapesSurviveARoundTrip) {
  const std::string text =
      "format: scenecal-calibration/1\nlidars: {}\npairs: []\nsettings:\n  \"sch\\rm1Neme\": alt\n"
      "timings_s:\n  \"lo\\tad\": 1.5\n";
  const CalibrationResult result = io::ParseCalibrationResult(text, "result.yaml");
  ASSERT_EQ(result.settings.count("sch\rm1Neme"), 1u);
  const CalibrationResult again = io::ParseCalibrationResult(io::CalibrationResultToYaml(result), "again.yaml");
  EXPECT_EQ(again.settings, result.settings);
  EXPECT_EQ(again.timings_s.count("lo\tad"), 1u);
}

// FORMAT.md's covariance: written as 6 rows of 6 and read back exactly; a
// matrix that is not 6x6, not symmetric or has a negative variance is refused
// with its field.
TEST(DatasetIo, ResultCovarianceRoundTripsAndBadOnesAreRefused) {
  CalibrationResult result;
  LidarCalibration lidar;
  lidar.lidar = "rear";
  Matrix6d covariance = Matrix6d::Identity() * 1e-4;
  covariance(0, 4) = covariance(4, 0) = 3.25e-6;
  lidar.sigma = covariance.diagonal().cwiseSqrt();
  lidar.covariance = covariance;
  result.lidars.push_back(lidar);
  const CalibrationResult again = io::ParseCalibrationResult(io::CalibrationResultToYaml(result), "result.yaml");
  ASSERT_TRUE(again.lidars.at(0).covariance.has_value());
  EXPECT_EQ(*again.lidars.at(0).covariance, covariance);
  const std::string head = "format: scenecal-calibration/1\npairs: []\nlidars:\n  rear:\n    T_base_lidar: [0, 0, 0, 0, 0, 0]\n"
                           "    covariance: ";
  const std::string row = "[1, 0, 0, 0, 0, 0]";
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"[" + row + "]", "lidars.rear.covariance"},
      {"[[1, 2, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0], [0, 0, 1, 0, 0, 0], [0, 0, 0, 1, 0, 0], [0, 0, 0, 0, 1, 0], "
       "[0, 0, 0, 0, 0, 1]]",
       "lidars.rear.covariance[1][0]"},
      {"[[-1, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0], [0, 0, 1, 0, 0, 0], [0, 0, 0, 1, 0, 0], [0, 0, 0, 0, 1, 0], "
       "[0, 0, 0, 0, 0, 1]]",
       "lidars.rear.covariance[0][0]"},
  };
  for (const auto& [matrix, field] : bad) {
    try {
      io::ParseCalibrationResult(head + matrix + "\n", "result.yaml");
      ADD_FAILURE() << "accepted " << matrix;
    } catch (const io::InputError& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  }
}

// Option files: values and lists in the file's order, a preset's own keys, a
// result's options block; what is not an option file is refused with its line.
TEST(DatasetIo, OptionFilesReadValuesListsAndAResultsOptionsBlock) {
  const io::OptionFile file = io::ParseOptionText(
      "# a comment\ndescription: test preset\nrequires: push-broom-drive\nthin: 2\nmotion-correction: [turn, "
      "drive-scale]\nrefresh-border: 3.75%\n",
      "preset.yaml");
  EXPECT_EQ(file.description, "test preset");
  EXPECT_EQ(file.requires_data, io::kRequiresPushBroomDrive);
  ASSERT_EQ(file.options.size(), 3u);
  EXPECT_EQ(file.options[0].name, "thin");
  EXPECT_EQ(file.options[0].values, std::vector<std::string>{"2"});
  EXPECT_EQ(file.options[0].line, 4);
  EXPECT_EQ(file.options[1].values, (std::vector<std::string>{"turn", "drive-scale"}));
  EXPECT_EQ(file.options[2].values, std::vector<std::string>{"3.75%"});
  // What OptionsYaml writes reads back the same.
  YAML::Emitter out;
  out << io::OptionsYaml(file.options);
  const io::OptionFile again = io::ParseOptionText(out.c_str(), "again.yaml");
  ASSERT_EQ(again.options.size(), file.options.size());
  for (std::size_t i = 0; i < again.options.size(); ++i) {
    EXPECT_EQ(again.options[i].name, file.options[i].name);
    EXPECT_EQ(again.options[i].values, file.options[i].values);
  }
  // A result file: its options block, the rest ignored.
  const io::OptionFile result = io::ParseOptionText(
      "format: scenecal-calibration/1\nlidars: {}\noptions:\n  scenes: 4\n  stages: 1,0.3\n", "result.yaml");
  ASSERT_EQ(result.options.size(), 2u);
  EXPECT_EQ(result.options[1].values, std::vector<std::string>{"1,0.3"});
  const auto message = [](const std::string& text) {
    try {
      io::ParseOptionText(text, "bad.yaml");
    } catch (const io::InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message("thin: 2\nthin: 3\n").find("duplicate"), std::string::npos);
  EXPECT_NE(message("thin: {a: 1}\n").find("thin"), std::string::npos);
  EXPECT_NE(message("thin: []\n").find("non-empty list"), std::string::npos);
  EXPECT_NE(message("thin:\n").find("thin"), std::string::npos);
  EXPECT_NE(message("--thin: 2\n").find("without its leading --"), std::string::npos);
  EXPECT_NE(message("- thin\n").find("a mapping"), std::string::npos);
  EXPECT_NE(message("requires: anything\n").find("push-broom-drive"), std::string::npos);
  EXPECT_NE(message("format: scenecal-calibration/1\nlidars: {}\n").find("without an options block"),
            std::string::npos);
  EXPECT_NE(message("thin: [2\n").find("line"), std::string::npos);
  // A control character would not survive being written back (found by fuzz_option_file).
  EXPECT_NE(message("thin: \"2\\x03\"\n").find("control character (0x03)"), std::string::npos);
  EXPECT_NE(message("\"th\\x00in\": 2\n").find("control character (0x00)"), std::string::npos);
  EXPECT_NE(message(std::string("thin: 2\0N\n", 10)).find("control character"), std::string::npos);
  EXPECT_EQ(message("thin: \"\\uD800\"\n").find("accepted"), std::string::npos);  // a lone surrogate
  // A CR ends a line only before an LF; alone it stayed inside a name (found by fuzz_calibration_result).
  EXPECT_NE(message("thin: 2\r\r\nscenes: 4\n").find("(0x0D) is a control character"), std::string::npos);
  EXPECT_NE(message("thin: 2\r\nscenes: 4\r\n").find("accepted"), std::string::npos);
  try {
    io::ParseCalibrationResult("format: scenecal-calibration/1\nlidars: {}\npairs:\n  - camera: right0.5]\r\r\n"
                               "    lidar: front\n    T_camera_lidar: [0, 0, 0, 0, 0, 0]\n",
                               "result.yaml");
    ADD_FAILURE() << "a camera name with a lone CR was accepted";
  } catch (const io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("line 4: byte 70 (0x0D)"), std::string::npos) << e.what();
  }
  EXPECT_NE(message("thin: 2\n").find("accepted"), std::string::npos);
}

}  // namespace
}  // namespace scenecal
