// PCD reader (ascii, binary, binary_compressed) and the OpenCalib importer,
// on synthetic files and on the three real OpenCalib frames.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "io/dataset.hpp"
#include "io/opencalib.hpp"
#include "io/pcd.hpp"
#include "io_test_support.hpp"

namespace scenecal {
namespace {

using namespace scenecal::testing;

const fs::path kOpenCalibDir = fs::path(SCENECAL_SHARED_DATA_DIR) / "opencalib";

void ExpectSamePoints(const io::PcdCloud& cloud, const std::vector<PcdTestPoint>& expected) {
  ASSERT_EQ(cloud.points.size(), expected.size());
  ASSERT_EQ(cloud.timestamps.size(), expected.size());
  EXPECT_TRUE(cloud.has_intensity);
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(cloud.points[i].x, expected[i].x) << i;
    EXPECT_EQ(cloud.points[i].y, expected[i].y) << i;
    EXPECT_EQ(cloud.points[i].z, expected[i].z) << i;
    EXPECT_EQ(cloud.points[i].reflectance, expected[i].intensity) << i;
    EXPECT_EQ(cloud.timestamps[i], expected[i].timestamp) << i;
  }
}

TEST(Pcd, RealOpenCalibFramesHaveTheDocumentedPointsAndPlausibleValues) {
  const std::vector<std::pair<std::string, std::size_t>> sets = {{"1", 101340}, {"2", 98805}, {"3", 85546}};
  for (const auto& [set, count] : sets) {
    SCOPED_TRACE("set " + set);
    const io::PcdCloud cloud = io::ReadPcd(kOpenCalibDir / set / "calib.pcd");
    EXPECT_EQ(cloud.data_encoding, "binary_compressed");
    EXPECT_EQ(cloud.points.size(), count);
    EXPECT_EQ(cloud.width * cloud.height, count);
    EXPECT_TRUE(cloud.has_intensity);
    EXPECT_EQ(cloud.timestamps.size(), count);
    std::size_t finite = 0, near_origin = 0;
    float max_range = 0, min_intensity = 1e30f, max_intensity = -1e30f;
    for (const LidarPoint& p : cloud.points) {
      if (!(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) && std::isfinite(p.reflectance))) continue;
      ++finite;
      const float range = std::sqrt(p.x * p.x + p.y * p.y + p.z * p.z);
      max_range = std::max(max_range, range);
      near_origin += range < 0.5f;
      min_intensity = std::min(min_intensity, p.reflectance);
      max_intensity = std::max(max_intensity, p.reflectance);
    }
    RecordProperty("max_range_m_set" + set, std::to_string(max_range));
    RecordProperty("intensity_range_set" + set, std::to_string(min_intensity) + ".." + std::to_string(max_intensity));
    EXPECT_EQ(finite, count);
    EXPECT_LT(max_range, 200.0f);
    EXPECT_GT(max_range, 20.0f);                 // a street scene, not a decoding of zeros
    EXPECT_LT(near_origin, count / 100);         // garbage decodes pile up near 0
    EXPECT_GE(min_intensity, 0.0f);
    EXPECT_LE(max_intensity, 255.0f);
    EXPECT_GT(max_intensity, min_intensity);
    // Per-point time: finite and spread over less than a second (one sweep).
    const auto [t_min, t_max] = std::minmax_element(cloud.timestamps.begin(), cloud.timestamps.end());
    EXPECT_TRUE(std::isfinite(*t_min) && std::isfinite(*t_max));
    EXPECT_LT(*t_max - *t_min, 1.0);
  }
}

TEST(Pcd, AsciiBinaryAndCompressedDecodeToTheSamePoints) {
  const std::vector<PcdTestPoint> points = PcdTestPoints(1000);
  ExpectSamePoints(io::ParsePcd(PcdAscii(points), "a.pcd"), points);
  ExpectSamePoints(io::ParsePcd(PcdBinary(points), "b.pcd"), points);
  ExpectSamePoints(io::ParsePcd(PcdBinaryCompressed(points), "c.pcd"), points);
  // An empty cloud is valid in every encoding.
  EXPECT_TRUE(io::ParsePcd(PcdBinaryCompressed({}), "e.pcd").points.empty());
  EXPECT_TRUE(io::ParsePcd(PcdAscii({}), "e.pcd").points.empty());
}

TEST(Pcd, GenericFieldSizesTypesAndCounts) {
  // x y z as float64, intensity as uint8, a 3-element float32 normal in between,
  // a signed 16-bit field; no timestamp.
  std::string text =
      "VERSION .7\nFIELDS x normal y z intensity label\nSIZE 8 4 8 8 1 2\nTYPE F F F F U I\nCOUNT 1 3 1 1 1 1\n"
      "WIDTH 2\nHEIGHT 2\nPOINTS 4\nDATA binary\n";
  for (int i = 0; i < 4; ++i) {
    AppendBytes(&text, 1.5 * i);
    for (int k = 0; k < 3; ++k) AppendBytes(&text, 9.0f);
    AppendBytes(&text, -2.0 * i);
    AppendBytes(&text, 0.25 + i);
    AppendBytes(&text, static_cast<std::uint8_t>(200 + i));
    AppendBytes(&text, static_cast<std::int16_t>(-7 * i));
  }
  const io::PcdCloud cloud = io::ParsePcd(text, "generic.pcd");
  ASSERT_EQ(cloud.points.size(), 4u);
  EXPECT_TRUE(cloud.timestamps.empty());
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(cloud.points[i].x, static_cast<float>(1.5 * i));
    EXPECT_EQ(cloud.points[i].y, static_cast<float>(-2.0 * i));
    EXPECT_EQ(cloud.points[i].z, static_cast<float>(0.25 + i));
    EXPECT_EQ(cloud.points[i].reflectance, static_cast<float>(200 + i));
  }
}

TEST(Pcd, TruncatedOrCorruptHeadersAreInputErrors) {
  const std::string good = PcdBinary(PcdTestPoints(20));
  const auto rejects = [](const std::string& text, const std::string& what) {
    try {
      io::ParsePcd(text, "bad.pcd");
      ADD_FAILURE() << what << ": accepted";
    } catch (const io::InputError& e) {
      EXPECT_NE(std::string(e.what()).find("bad.pcd"), std::string::npos) << e.what();
    }
  };
  rejects("", "empty file");
  rejects(good.substr(0, good.find("DATA")), "no DATA line");
  rejects(good.substr(0, good.size() - 1), "one byte short");
  std::string text = good;
  text.replace(text.find("SIZE 4 4 4 4 2 8"), 16, "SIZE 4 4 4 4 2");
  rejects(text, "SIZE count differs from FIELDS");
  text = good;
  text.replace(text.find("TYPE F F F F U F"), 16, "TYPE F F F F U Q");
  rejects(text, "unknown TYPE");
  text = good;
  text.replace(text.find("SIZE 4 4 4 4 2 8"), 16, "SIZE 4 4 4 4 3 8");
  rejects(text, "size 3");
  text = good;
  text.replace(text.find("FIELDS x y z"), 12, "FIELDS a b c");
  rejects(text, "no x y z");
  text = good;
  text.replace(text.find("DATA binary"), 11, "DATA zip");
  rejects(text, "unknown DATA");
  text = good;
  text.replace(text.find("HEIGHT 1"), 8, "HEIGHT 1099511627776");
  rejects(text, "huge HEIGHT");
  text = good;
  text.replace(text.find("COUNT 1 1 1 1 1 1"), 17, "COUNT 1 1 1 1 1 999999999");
  rejects(text, "huge COUNT");
  // Compressed: sizes claiming more than the file, or more than LZF can expand to.
  const std::string compressed = PcdBinaryCompressed(PcdTestPoints(20));
  rejects(compressed.substr(0, compressed.size() - 5), "truncated LZF stream");
  const std::size_t data = compressed.find("binary_compressed\n") + 18;
  rejects(compressed.substr(0, data + 6), "truncated size words");
}

TEST(OpenCalib, ReadsCalibTxt) {
  const io::OpenCalibCalibration calibration = io::ReadOpenCalibCalibration(kOpenCalibDir / "3" / "calib.txt");
  EXPECT_DOUBLE_EQ(calibration.fx, 2117.31);
  EXPECT_DOUBLE_EQ(calibration.fy, 2113.29);
  EXPECT_DOUBLE_EQ(calibration.cx, 924.681);
  EXPECT_DOUBLE_EQ(calibration.cy, 656.457);
  ASSERT_EQ(calibration.distortion.size(), 5u);
  EXPECT_DOUBLE_EQ(calibration.distortion[4], 0.429959);
  const Eigen::Matrix3d r = calibration.T_camera_lidar.rotation();
  EXPECT_LT((r * r.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12);  // snapped to a rotation
  EXPECT_NEAR(r(0, 1), -0.999992, 1e-5);
  EXPECT_DOUBLE_EQ(calibration.T_camera_lidar.translation().z(), -0.551037);
}

TEST(OpenCalib, ImportOfSetOneReadsBackAndProjectsIntoTheImage) {
  const TempDir temp;
  const fs::path source = kOpenCalibDir / "1";
  const fs::path output = temp.path() / "set1";
  const io::OpenCalibImportSummary summary = io::ImportOpenCalib(source, output, false);
  EXPECT_EQ(summary.points, 101340u);
  EXPECT_EQ(summary.image_width, 1920);
  EXPECT_EQ(summary.image_height, 1200);

  const io::Dataset dataset = io::OpenDataset(output);
  const io::OpenCalibCalibration reference = io::ReadOpenCalibCalibration(source / "calib.txt");
  ASSERT_EQ(dataset.rig.cameras.size(), 1u);
  ASSERT_EQ(dataset.rig.lidars.size(), 1u);
  const CameraInfo& camera = dataset.rig.cameras[0];
  const LidarInfo& lidar = dataset.rig.lidars[0];
  EXPECT_EQ(dataset.rig.base_frame, "camera");
  EXPECT_EQ(camera.model.kind, CameraModelKind::kRadTan);
  EXPECT_EQ(camera.model.width, 1920);
  EXPECT_EQ(camera.model.height, 1200);
  EXPECT_EQ(camera.model.fx, reference.fx);
  EXPECT_EQ(camera.model.distortion, reference.distortion);
  EXPECT_EQ(lidar.kind, LidarKind::k3d);
  EXPECT_LT(TranslationError(lidar.T_base_lidar, reference.T_camera_lidar), 1e-12);
  EXPECT_LT(RotationErrorDegrees(lidar.T_base_lidar, reference.T_camera_lidar), 1e-9);
  ASSERT_TRUE(dataset.ground_truth.has_value());
  EXPECT_LT(TranslationError(dataset.ground_truth->T_base_lidar.at("lidar"), reference.T_camera_lidar), 1e-12);
  EXPECT_LT(RotationErrorDegrees(dataset.ground_truth->T_base_lidar.at("lidar"), reference.T_camera_lidar), 1e-9);
  EXPECT_EQ(dataset.trajectory.size(), 1u);
  ASSERT_EQ(dataset.images.at("camera").size(), 1u);
  ASSERT_EQ(dataset.scans.at("lidar").size(), 1u);
  EXPECT_EQ(dataset.images.at("camera")[0].t_us, dataset.trajectory.times_us()[0]);
  EXPECT_EQ(dataset.scans.at("lidar")[0].t_us, dataset.trajectory.times_us()[0]);
  // The image is copied unchanged.
  EXPECT_EQ(ReadFile(dataset.images.at("camera")[0].path), ReadFile(source / "calib.jpg"));
  EXPECT_NE(ReadFile(output / "rig.yaml").find("source: opencalib"), std::string::npos);

  // The reference extrinsic puts thousands of points into the image.
  const LidarScan scan = io::ReadScan(dataset.scans.at("lidar")[0]);
  EXPECT_EQ(scan.points.size() + scan.no_returns, 101340u);
  const GreyImage image = io::ReadImage(dataset.images.at("camera")[0], camera.model);
  EXPECT_EQ(image.intensity.cols, 1920);
  const Eigen::Isometry3d T_camera_lidar = camera.T_camera_base() * lidar.T_base_lidar;
  std::size_t inside = 0;
  for (const LidarPoint& p : scan.points) {
    Eigen::Vector2d pixel;
    if (camera.model.Project(T_camera_lidar * Eigen::Vector3d(p.x, p.y, p.z), &pixel)) ++inside;
  }
  RecordProperty("points_inside_image", static_cast<int>(inside));
  EXPECT_GT(inside, 5000u);
  EXPECT_LT(inside, scan.points.size() / 2);  // a camera sees a sector of a 360-degree sweep

  // Importing again over the dataset needs overwrite.
  EXPECT_THROW(io::ImportOpenCalib(source, output, false), io::InputError);
  EXPECT_NO_THROW(io::ImportOpenCalib(kOpenCalibDir / "3", output, true));
  EXPECT_EQ(io::OpenDataset(output).images.at("camera")[0].path.extension(), ".png");
}

}  // namespace
}  // namespace scenecal
