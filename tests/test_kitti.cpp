// KITTI raw importer (io/kitti.hpp) on a small synthetic drive written here:
// intrinsics, extrinsics and trajectory checked against values computed in
// this file straight from the KITTI devkit formulas (projection
// P_rect_0i * R_rect_00 * Tr_velo_to_cam, convertOxtsToPose), timestamps
// against hand-computed microseconds, file layout and options, and bad input.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include <Eigen/SVD>
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "io/dataset.hpp"
#include "io/kitti.hpp"
#include "io_test_support.hpp"

namespace scenecal {
namespace {

using namespace scenecal::testing;
using Matrix34d = Eigen::Matrix<double, 3, 4>;

constexpr double kPiTest = 3.14159265358979323846;
constexpr std::int64_t kMidnightUs = 1316995200LL * 1000000;  // 2011-09-26 00:00:00 UTC (date -u -d ... +%s)
constexpr std::int64_t kFirstImageNs = (13LL * 3600 + 2 * 60 + 25) * 1000000000LL + 964389445;  // 13:02:25.964389445
constexpr std::int64_t kFramePeriodNs = 103520117;                                              // ~10 Hz
const std::array<std::int64_t, 4> kCameraOffsetNs = {0, 51, 2077, 1333};  // image_00..03 trigger jitter
constexpr std::int64_t kVeloOffsetNs = -4713201;                          // velodyne: 4.7 ms before the cameras
constexpr std::int64_t kOxtsOffsetNs = -12345678;                         // OXTS: 12.3 ms before

// "2011-09-26 HH:MM:SS.nnnnnnnnn" for nanoseconds since midnight.
std::string KittiTime(std::int64_t ns_of_day) {
  const std::int64_t seconds = ns_of_day / 1000000000;
  return fmt::format("2011-09-26 {:02d}:{:02d}:{:02d}.{:09d}", seconds / 3600, seconds / 60 % 60, seconds % 60,
                     ns_of_day % 1000000000);
}
// The same instant in microseconds since the epoch, rounded to the nearest.
std::int64_t ExpectedUs(std::int64_t ns_of_day) { return kMidnightUs + (ns_of_day + 500) / 1000; }

Eigen::Matrix3d Snap(const Eigen::Matrix3d& m) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return svd.matrixU() * svd.matrixV().transpose();
}

std::string Numbers(const double* values, int count) {
  std::string text;
  for (int i = 0; i < count; ++i) text += fmt::format(" {:.17g}", values[i]);
  return text;
}
std::string RowMajor(const Eigen::MatrixXd& m) {
  std::vector<double> values;
  for (int r = 0; r < m.rows(); ++r) {
    for (int c = 0; c < m.cols(); ++c) values.push_back(m(r, c));
  }
  return Numbers(values.data(), static_cast<int>(values.size()));
}

Eigen::Matrix4d Rigid(const Eigen::Matrix3d& r, const Eigen::Vector3d& t) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = r;
  m.topRightCorner<3, 1>() = t;
  return m;
}

// What the synthetic drive holds, kept in full precision for expected values.
struct FakeDrive {
  fs::path date_dir, drive_dir;
  std::size_t frames = 0;
  std::array<Matrix34d, 4> P;
  Eigen::Matrix3d R_rect = Eigen::Matrix3d::Identity();
  Eigen::Matrix4d T_cam0_velo = Eigen::Matrix4d::Identity();  // Tr_velo_to_cam
  Eigen::Matrix4d T_velo_imu = Eigen::Matrix4d::Identity();   // Tr_imu_to_velo
  std::array<int, 4> width{}, height{};
  std::vector<std::array<double, 30>> oxts;
  std::array<std::vector<std::int64_t>, 4> camera_ns;  // ns of day per frame
  std::vector<std::int64_t> velo_ns, oxts_ns;
  std::vector<std::vector<Eigen::Vector3d>> points;  // per frame, velodyne frame (float-exact)

  Eigen::Vector3d T(int i) const {
    return P[static_cast<std::size_t>(i)].leftCols<3>().inverse() * P[static_cast<std::size_t>(i)].col(3);
  }
};

// KITTI-like numbers (2011_09_26) with the intrinsics scaled to 64x48 images:
// a nonzero R_rect_00, the grey stereo baseline 0.54 m in P_rect_01 and the
// colour cameras' offsets incl. a z term in P_rect_02. Written with 17
// significant digits so the expected values below use the very same numbers.
FakeDrive WriteFakeDrive(const fs::path& date_dir, std::size_t frames, bool calibration_in_drive = false) {
  FakeDrive drive;
  drive.date_dir = date_dir;
  drive.drive_dir = date_dir / "2011_09_26_drive_0005_sync";
  drive.frames = frames;
  const std::array<std::array<double, 4>, 4> intrinsics = {{{72.15377, 72.15377, 30.95593, 23.2854},
                                                            {72.15377, 72.15377, 30.95593, 23.2854},
                                                            {70.9012, 70.4137, 32.1106, 24.8151},
                                                            {70.9012, 70.4137, 32.1106, 24.8151}}};
  const std::array<Eigen::Vector3d, 4> offsets = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(-0.5371657, 0, 0),
                                                  Eigen::Vector3d(0.05984926, -0.001320, 0.002745884),
                                                  Eigen::Vector3d(-0.4731050, 0.005523, 0.002775)};
  drive.width = {64, 64, 66, 66};
  drive.height = {48, 48, 50, 50};
  for (std::size_t i = 0; i < 4; ++i) {
    Eigen::Matrix3d k;
    k << intrinsics[i][0], 0, intrinsics[i][2], 0, intrinsics[i][1], intrinsics[i][3], 0, 0, 1;
    drive.P[i].leftCols<3>() = k;
    drive.P[i].col(3) = k * offsets[i];  // as KITTI prints it: K * t
  }
  Eigen::Matrix3d r;
  r << 9.999239e-01, 9.837760e-03, -7.445048e-03, -9.869795e-03, 9.999421e-01, -4.278459e-03, 7.402527e-03,
      4.351614e-03, 9.999631e-01;
  drive.R_rect = Snap(r);
  r << 7.533745e-03, -9.999714e-01, -6.166020e-04, 1.480249e-02, 7.280733e-04, -9.998902e-01, 9.998621e-01,
      7.523790e-03, 1.480755e-02;
  drive.T_cam0_velo = Rigid(Snap(r), Eigen::Vector3d(-4.069766e-03, -7.631618e-02, -2.717806e-01));
  r << 9.999976e-01, 7.553071e-04, -2.035826e-03, -7.854027e-04, 9.998898e-01, -1.482298e-02, 2.024406e-03,
      1.482454e-02, 9.998881e-01;
  drive.T_velo_imu = Rigid(Snap(r), Eigen::Vector3d(-8.086759e-01, 3.195559e-01, -7.997231e-01));

  const fs::path calib_dir = calibration_in_drive ? drive.drive_dir : date_dir;
  std::string cam = "calib_time: 09-Jan-2012 13:57:47\ncorner_dist: 9.950000e-02\n";
  for (int i = 0; i < 4; ++i) {
    cam += fmt::format(
        "S_0{}: 1.392000e+03 5.120000e+02\nK_0{}: 9.842439e+02 0 6.9e+02 0 9.808141e+02 2.331966e+02 0 0 1\n"
        "D_0{}: -3.728755e-01 2.037299e-01 2.219027e-03 1.383707e-03 -7.233722e-02\n",
        i, i, i);
    if (i == 0)
      cam += "R_rect_00:" + RowMajor(drive.R_rect) + "\n";
    else
      cam += fmt::format(
          "R_rect_0{}: 9.996878e-01 -8.976826e-03 2.331651e-02 8.876121e-03 9.999508e-01 4.418952e-03 -2.335503e-02 "
          "-4.210612e-03 9.997184e-01\n",
          i);
    cam += fmt::format("S_rect_0{}: 1.242000e+03 3.750000e+02\n", i);
    cam += fmt::format("P_rect_0{}:", i) + RowMajor(drive.P[static_cast<std::size_t>(i)]) + "\n";
  }
  WriteFile(calib_dir / "calib_cam_to_cam.txt", cam);
  WriteFile(calib_dir / "calib_velo_to_cam.txt",
            "calib_time: 15-Mar-2012 11:37:16\nR:" + RowMajor(drive.T_cam0_velo.topLeftCorner<3, 3>()) +
                "\nT:" + RowMajor(drive.T_cam0_velo.topRightCorner<3, 1>().transpose()) +
                "\ndelta_f: 0.000000e+00 0.000000e+00\ndelta_c: 0.000000e+00 0.000000e+00\n");
  WriteFile(calib_dir / "calib_imu_to_velo.txt",
            "calib_time: 25-May-2012 16:47:16\nR:" + RowMajor(drive.T_velo_imu.topLeftCorner<3, 3>()) +
                "\nT:" + RowMajor(drive.T_velo_imu.topRightCorner<3, 1>().transpose()) + "\n");

  std::mt19937 random(7);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::array<std::string, 4> camera_stamps;
  std::string velo_stamps, oxts_stamps;
  for (std::size_t k = 0; k < frames; ++k) {
    const std::int64_t frame_ns = kFirstImageNs + static_cast<std::int64_t>(k) * kFramePeriodNs;
    const std::string name = fmt::format("{:010d}", k);
    for (std::size_t i = 0; i < 4; ++i) {
      drive.camera_ns[i].push_back(frame_ns + kCameraOffsetNs[i]);
      camera_stamps[i] += KittiTime(drive.camera_ns[i].back()) + "\n";
      const fs::path image = drive.drive_dir / fmt::format("image_0{}", i) / "data" / (name + ".png");
      fs::create_directories(image.parent_path());
      cv::imwrite(image.string(), TestPattern(drive.width[i], drive.height[i], i < 2 ? CV_8UC1 : CV_8UC3));
    }
    drive.velo_ns.push_back(frame_ns + kVeloOffsetNs);
    velo_stamps += KittiTime(drive.velo_ns.back()) + "\n";
    std::vector<float> records;
    std::vector<Eigen::Vector3d> points;
    for (int p = 0; p < 300; ++p) {
      const float x = static_cast<float>(4.0 + 30.0 * uniform(random));
      const float y = static_cast<float>(-6.0 + 12.0 * uniform(random));
      const float z = static_cast<float>(-1.7 + 2.5 * uniform(random));
      records.insert(records.end(), {x, y, z, static_cast<float>(uniform(random))});
      points.emplace_back(x, y, z);
    }
    drive.points.push_back(points);
    const fs::path scan = drive.drive_dir / "velodyne_points" / "data" / (name + ".bin");
    fs::create_directories(scan.parent_path());
    std::ofstream(scan, std::ios::binary)
        .write(reinterpret_cast<const char*>(records.data()), static_cast<std::streamsize>(records.size() * 4));
    drive.oxts_ns.push_back(frame_ns + kOxtsOffsetNs);
    oxts_stamps += KittiTime(drive.oxts_ns.back()) + "\n";
    const double t = static_cast<double>(k);
    std::array<double, 30> record{};
    record[0] = 49.015003823272 + 2.1e-5 * t + 3e-7 * t * t;  // lat (deg)
    record[1] = 8.4342971002335 + 3.4e-5 * t - 2e-7 * t * t;  // lon (deg)
    record[2] = 116.43032836914 + 0.12 * t;                   // alt (m)
    record[3] = 0.035752 - 0.011 * t;                         // roll (rad)
    record[4] = 0.00903 + 0.017 * t;                          // pitch (rad)
    record[5] = -2.6010136509629 + 0.09 * t;                  // yaw (rad)
    for (std::size_t v = 6; v < 25; ++v) record[v] = 0.1 * static_cast<double>(v) - 0.01 * t;
    record[25] = 4, record[26] = 10, record[27] = 4, record[28] = 4,
    record[29] = 0;  // navstat numsats posmode velmode orimode
    drive.oxts.push_back(record);
    WriteFile(drive.drive_dir / "oxts" / "data" / (name + ".txt"), Numbers(record.data(), 30).substr(1) + "\n");
  }
  for (std::size_t i = 0; i < 4; ++i) {
    WriteFile(drive.drive_dir / fmt::format("image_0{}", i) / "timestamps.txt", camera_stamps[i]);
  }
  WriteFile(drive.drive_dir / "velodyne_points" / "timestamps.txt", velo_stamps);
  WriteFile(drive.drive_dir / "velodyne_points" / "timestamps_start.txt", velo_stamps);  // ignored
  WriteFile(drive.drive_dir / "oxts" / "timestamps.txt", oxts_stamps);
  WriteFile(drive.drive_dir / "oxts" / "dataformat.txt", "lat: latitude of the oxts-unit (deg)\n");  // ignored
  return drive;
}

// ---- expected values, straight from the devkit formulas ----------------------------

// Rectified camera i from cam0: T_cami_cam0 = [I | K_i^-1 * P_rect_0i(:, 3)].
Eigen::Matrix4d ExpectedCamFromCam0(const FakeDrive& d, int i) { return Rigid(Eigen::Matrix3d::Identity(), d.T(i)); }

// R_rect_00 * Tr_velo_to_cam as a 4x4.
Eigen::Matrix4d ExpectedCam0RectFromVelo(const FakeDrive& d) {
  return Rigid(d.R_rect, Eigen::Vector3d::Zero()) * d.T_cam0_velo;
}

// KITTI's projection of a velodyne point into rectified camera i (pixels).
Eigen::Vector2d KittiPixel(const FakeDrive& d, int i, const Eigen::Vector3d& x) {
  const Eigen::Vector3d h = d.P[static_cast<std::size_t>(i)] * (ExpectedCam0RectFromVelo(d) * x.homogeneous());
  return h.head<2>() / h.z();
}

// convertOxtsToPose without the normalisation by the first pose: T_world_imu.
Eigen::Matrix4d DevkitImuPose(const FakeDrive& d, std::size_t k) {
  const double er = 6378137.0;
  const double scale = std::cos(d.oxts[0][0] * kPiTest / 180.0);
  const std::array<double, 30>& o = d.oxts[k];
  const double tx = scale * o[1] * kPiTest * er / 180.0;
  const double ty = scale * er * std::log(std::tan((90.0 + o[0]) * kPiTest / 360.0));
  const double rx = o[3], ry = o[4], rz = o[5];
  Eigen::Matrix3d Rx, Ry, Rz;
  Rx << 1, 0, 0, 0, std::cos(rx), -std::sin(rx), 0, std::sin(rx), std::cos(rx);
  Ry << std::cos(ry), 0, std::sin(ry), 0, 1, 0, -std::sin(ry), 0, std::cos(ry);
  Rz << std::cos(rz), -std::sin(rz), 0, std::sin(rz), std::cos(rz), 0, 0, 0, 1;
  return Rigid(Rz * Ry * Rx, Eigen::Vector3d(tx, ty, o[2]));
}

Eigen::Matrix4d Matrix(const Eigen::Isometry3d& t) { return t.matrix(); }

const Eigen::Isometry3d& PoseAtTime(const io::Dataset& dataset, TimeUs t_us) {
  const std::vector<TimeUs>& times = dataset.trajectory.times_us();
  const auto it = std::find(times.begin(), times.end(), t_us);
  if (it == times.end()) throw std::runtime_error(fmt::format("no trajectory row at {}", t_us));
  return dataset.trajectory.poses()[static_cast<std::size_t>(it - times.begin())];
}

std::vector<std::string> FileNames(const fs::path& folder) {
  std::vector<std::string> names;
  if (!fs::is_directory(folder)) return names;
  for (const fs::directory_entry& entry : fs::directory_iterator(folder))
    names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// ---- timestamps ----------------------------------------------------------------------

TEST(KittiTimestamp, ConvertsToMicrosecondsSinceTheEpochAsUtc) {
  // 2011-09-26 13:02:25 UTC = 1317042145 s (date -u -d '2011-09-26 13:02:25' +%s); .964389445 s -> 964389 us.
  EXPECT_EQ(io::ParseKittiTimestamp("2011-09-26 13:02:25.964389445"), std::optional<TimeUs>(1317042145964389));
  EXPECT_EQ(io::ParseKittiTimestamp("2011-09-26 13:02:25.964389500"),
            std::optional<TimeUs>(1317042145964390));  // nearest
  EXPECT_EQ(io::ParseKittiTimestamp("2011-09-26 13:02:25"), std::optional<TimeUs>(1317042145000000));
  EXPECT_EQ(io::ParseKittiTimestamp("2011-09-26 13:02:25.5"), std::optional<TimeUs>(1317042145500000));
  EXPECT_EQ(io::ParseKittiTimestamp("2011-09-26 23:59:59.9999996"),
            std::optional<TimeUs>(1317081600000000));  // carries into the next day
  EXPECT_EQ(io::ParseKittiTimestamp("1970-01-01 00:00:00.000001"), std::optional<TimeUs>(1));
  EXPECT_EQ(io::ParseKittiTimestamp("2012-02-29 00:00:00"), std::optional<TimeUs>(1330473600000000));  // leap day
  for (const char* bad :
       {"", "2011-09-26", "2011-09-26 13:02:2x.964389445", "2011-09-26T13:02:25.964389445", "2011-09-26 13:02:25.",
        "2011-09-26 13:02:25.9643894451", "2011-02-30 00:00:00", "2011-13-01 00:00:00", "2011-09-26 24:00:00",
        "2011-09-26 13:60:00", "11-09-26 13:02:25", "1969-12-31 23:59:59", "2011-09-26 13:02:25 +0100"}) {
    EXPECT_FALSE(io::ParseKittiTimestamp(bad).has_value()) << bad;
  }
}

// ---- import --------------------------------------------------------------------------

class KittiImport : public ::testing::Test {
 protected:
  void SetUp() override { drive_ = WriteFakeDrive(temp_.path() / "2011_09_26", 5); }

  io::Dataset Import(const io::KittiImportOptions& options, const std::string& name = "out") {
    io::ImportKitti(drive_.drive_dir, temp_.path() / name, options);
    return io::OpenDataset(temp_.path() / name);
  }

  TempDir temp_;
  FakeDrive drive_;
};

TEST_F(KittiImport, CamerasHaveTheRectifiedIntrinsicsAndTranslations) {
  const io::Dataset dataset = Import({});
  ASSERT_EQ(dataset.rig.cameras.size(), 4u);
  EXPECT_EQ(dataset.rig.base_frame, "image_00");
  for (int i = 0; i < 4; ++i) {
    SCOPED_TRACE(i);
    const CameraInfo* camera = dataset.rig.FindCamera(fmt::format("image_0{}", i));
    ASSERT_NE(camera, nullptr);
    const Matrix34d& p = drive_.P[static_cast<std::size_t>(i)];
    EXPECT_EQ(camera->model.kind, CameraModelKind::kPinhole);
    EXPECT_TRUE(camera->model.distortion.empty());
    EXPECT_DOUBLE_EQ(camera->model.fx, p(0, 0));
    EXPECT_DOUBLE_EQ(camera->model.fy, p(1, 1));
    EXPECT_DOUBLE_EQ(camera->model.cx, p(0, 2));
    EXPECT_DOUBLE_EQ(camera->model.cy, p(1, 2));
    EXPECT_EQ(camera->model.width, drive_.width[static_cast<std::size_t>(i)]);
    EXPECT_EQ(camera->model.height, drive_.height[static_cast<std::size_t>(i)]);
    // T_base_cami = T_cam0_cami (base = rectified image_00, whose P has no offset).
    const Eigen::Matrix4d expected = ExpectedCamFromCam0(drive_, i).inverse();
    EXPECT_LT((Matrix(camera->T_base_camera) - expected).cwiseAbs().maxCoeff(), 1e-9) << Matrix(camera->T_base_camera);
  }
  // The stereo baseline: image_01 sits 0.537 m to the right (+x) of image_00.
  EXPECT_NEAR(dataset.rig.FindCamera("image_01")->T_base_camera.translation().x(), 0.5371657, 1e-9);
}

TEST_F(KittiImport, LidarPointsProjectToKittisPixels) {
  const io::Dataset dataset = Import({});
  ASSERT_EQ(dataset.rig.lidars.size(), 1u);
  const LidarInfo& lidar = dataset.rig.lidars[0];
  EXPECT_EQ(lidar.name, "velodyne");
  EXPECT_EQ(lidar.kind, LidarKind::k3d);
  EXPECT_EQ(dataset.rig.trajectory_source, TrajectorySource::kIns);  // from oxts/
  ASSERT_TRUE(dataset.ground_truth.has_value());
  const Eigen::Isometry3d& truth = dataset.ground_truth->T_base_lidar.at("velodyne");
  EXPECT_LT((Matrix(truth) - Matrix(lidar.T_base_lidar)).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((Matrix(lidar.T_base_lidar) - ExpectedCam0RectFromVelo(drive_)).cwiseAbs().maxCoeff(), 1e-10);
  int inside = 0;
  for (const int i : {0, 1, 2, 3}) {
    const CameraInfo& camera = *dataset.rig.FindCamera(fmt::format("image_0{}", i));
    const Eigen::Isometry3d T_camera_lidar = camera.T_camera_base() * lidar.T_base_lidar;
    for (const Eigen::Vector3d& x : drive_.points[0]) {
      Eigen::Vector2d pixel;
      inside += camera.model.Project(T_camera_lidar * x, &pixel);
      const Eigen::Vector2d kitti = KittiPixel(drive_, i, x);
      ASSERT_LT((pixel - kitti).norm(), 1e-6) << "camera " << i << " point " << x.transpose() << ": "
                                              << pixel.transpose() << " vs KITTI " << kitti.transpose();
    }
  }
  EXPECT_GT(inside, 100);  // the points are in view, so the comparison is over real pixels
}

TEST_F(KittiImport, TrajectoryMatchesTheDevkitMotionInTheBaseFrame) {
  const io::Dataset dataset = Import({});
  ASSERT_EQ(dataset.trajectory.size(), 5u);
  for (std::size_t k = 0; k < 5; ++k) EXPECT_EQ(dataset.trajectory.times_us()[k], ExpectedUs(drive_.oxts_ns[k]));
  // T_base_imu = T_cam0rect_velo * T_velo_imu (base = rectified image_00).
  const Eigen::Matrix4d T_base_imu = ExpectedCam0RectFromVelo(drive_) * drive_.T_velo_imu;
  for (const auto& [a, b] : std::vector<std::pair<std::size_t, std::size_t>>{{0, 1}, {1, 4}, {0, 4}}) {
    SCOPED_TRACE(fmt::format("frames {} -> {}", a, b));
    const Eigen::Matrix4d expected =
        T_base_imu * DevkitImuPose(drive_, a).inverse() * DevkitImuPose(drive_, b) * T_base_imu.inverse();
    const Eigen::Matrix4d imported = Matrix(PoseAtTime(dataset, ExpectedUs(drive_.oxts_ns[a])).inverse() *
                                            PoseAtTime(dataset, ExpectedUs(drive_.oxts_ns[b])));
    EXPECT_LT((imported - expected).cwiseAbs().maxCoeff(), 1e-6) << imported << "\nvs\n" << expected;
    EXPECT_GT((expected.topRightCorner<3, 1>().norm()), 0.5);  // the vehicle moved: not a trivial identity
  }
  // Gravity stays along world z: the base's absolute rotation is the devkit's too.
  const Eigen::Matrix4d world_base0 = DevkitImuPose(drive_, 2) * T_base_imu.inverse();
  const Eigen::Matrix3d imported_rotation = PoseAtTime(dataset, ExpectedUs(drive_.oxts_ns[2])).rotation();
  EXPECT_LT((imported_rotation - world_base0.topLeftCorner<3, 3>()).cwiseAbs().maxCoeff(), 1e-9);
  // Small numbers: the origin is the first record's position, not 1e6 m of Mercator.
  EXPECT_LT(dataset.trajectory.poses()[0].translation().norm(), 5.0);
}

TEST_F(KittiImport, FilesAreNamedByTheirMicrosecondsAndCopiedUnchanged) {
  const io::Dataset dataset = Import({});
  const fs::path out = temp_.path() / "out";
  // The first image_00 time, by hand: 1317042145 s + 0.964389445 s.
  EXPECT_TRUE(fs::exists(out / "cameras" / "image_00" / "1317042145964389.png"));
  for (std::size_t i = 0; i < 4; ++i) {
    const std::string name = fmt::format("image_0{}", i);
    std::vector<std::string> expected;
    for (const std::int64_t ns : drive_.camera_ns[i]) expected.push_back(fmt::format("{}.png", ExpectedUs(ns)));
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(FileNames(out / "cameras" / name), expected) << name;
    EXPECT_EQ(ReadFile(out / "cameras" / name / expected[2]),
              ReadFile(drive_.drive_dir / name / "data" / fmt::format("{:010d}.png", 2)));
  }
  ASSERT_EQ(dataset.scans.at("velodyne").size(), 5u);
  for (std::size_t k = 0; k < 5; ++k) {
    const io::SensorFile& scan = dataset.scans.at("velodyne")[k];
    EXPECT_EQ(scan.t_us, ExpectedUs(drive_.velo_ns[k]));
    EXPECT_EQ(ReadFile(scan.path),
              ReadFile(drive_.drive_dir / "velodyne_points" / "data" / fmt::format("{:010d}.bin", k)));
  }
  const LidarScan scan = io::ReadScan(dataset.scans.at("velodyne")[3]);
  ASSERT_EQ(scan.points.size(), 300u);
  EXPECT_EQ(scan.points[7].x, static_cast<float>(drive_.points[3][7].x()));
  EXPECT_NE(ReadFile(out / "rig.yaml").find("source: kitti"), std::string::npos);
  EXPECT_EQ(FileNames(temp_.path()), std::vector<std::string>({"2011_09_26", "out"}));  // no temporary left
}

TEST_F(KittiImport, CamerasAndFrameRangeAreHonoured) {
  io::KittiImportOptions options;
  options.cameras = {3, 2};
  options.first = 1;
  options.count = 2;
  std::size_t last_done = 0, calls = 0, total = 0;
  options.progress = [&](std::size_t done, std::size_t all) {
    ++calls;
    last_done = done;
    total = all;
  };
  const io::KittiImportSummary summary = io::ImportKitti(drive_.drive_dir, temp_.path() / "colour", options);
  EXPECT_EQ(summary.images, 4u);
  EXPECT_EQ(summary.scans, 2u);
  EXPECT_EQ(calls, 6u);
  EXPECT_EQ(last_done, 6u);
  EXPECT_EQ(total, 6u);
  const io::Dataset dataset = io::OpenDataset(temp_.path() / "colour");
  ASSERT_EQ(dataset.rig.cameras.size(), 2u);
  EXPECT_EQ(dataset.rig.base_frame, "image_02");
  EXPECT_EQ(FileNames(temp_.path() / "colour" / "cameras"), std::vector<std::string>({"image_02", "image_03"}));
  EXPECT_EQ(dataset.images.at("image_02").size(), 2u);
  EXPECT_EQ(dataset.images.at("image_02")[0].t_us, ExpectedUs(drive_.camera_ns[2][1]));
  EXPECT_EQ(dataset.images.at("image_03")[1].t_us, ExpectedUs(drive_.camera_ns[3][2]));
  ASSERT_EQ(dataset.scans.at("velodyne").size(), 2u);
  EXPECT_EQ(dataset.scans.at("velodyne")[0].t_us, ExpectedUs(drive_.velo_ns[1]));
  // Rows for frames 0..3: the range plus one record on each side.
  ASSERT_EQ(dataset.trajectory.size(), 4u);
  EXPECT_EQ(dataset.trajectory.times_us().front(), ExpectedUs(drive_.oxts_ns[0]));
  EXPECT_EQ(dataset.trajectory.times_us().back(), ExpectedUs(drive_.oxts_ns[3]));

  // Base = rectified image_02: the same KITTI pixels through the other base.
  const CameraInfo& base = *dataset.rig.FindCamera("image_02");
  EXPECT_LT((Matrix(base.T_base_camera) - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff(), 1e-15);
  const Eigen::Matrix4d expected_03 = ExpectedCamFromCam0(drive_, 2) * ExpectedCamFromCam0(drive_, 3).inverse();
  EXPECT_LT((Matrix(dataset.rig.FindCamera("image_03")->T_base_camera) - expected_03).cwiseAbs().maxCoeff(), 1e-9);
  const LidarInfo& lidar = dataset.rig.lidars[0];
  for (const int i : {2, 3}) {
    const CameraInfo& camera = *dataset.rig.FindCamera(fmt::format("image_0{}", i));
    for (std::size_t p = 0; p < 50; ++p) {
      const Eigen::Vector3d& x = drive_.points[1][p];
      Eigen::Vector2d pixel;
      camera.model.Project(camera.T_camera_base() * lidar.T_base_lidar * x, &pixel);
      ASSERT_LT((pixel - KittiPixel(drive_, i, x)).norm(), 1e-6) << "camera " << i;
    }
  }
  // And the motion, in the image_02 frame.
  const Eigen::Matrix4d T_base_imu =
      ExpectedCamFromCam0(drive_, 2) * ExpectedCam0RectFromVelo(drive_) * drive_.T_velo_imu;
  const Eigen::Matrix4d expected =
      T_base_imu * DevkitImuPose(drive_, 0).inverse() * DevkitImuPose(drive_, 3) * T_base_imu.inverse();
  const Eigen::Matrix4d imported = Matrix(dataset.trajectory.poses()[0].inverse() * dataset.trajectory.poses()[3]);
  EXPECT_LT((imported - expected).cwiseAbs().maxCoeff(), 1e-6);
}

TEST_F(KittiImport, CalibrationInsideTheDriveFolderIsAccepted) {
  const TempDir other;
  const FakeDrive inside = WriteFakeDrive(other.path() / "date", 2, /*calibration_in_drive=*/true);
  EXPECT_FALSE(fs::exists(other.path() / "date" / "calib_cam_to_cam.txt"));
  io::KittiImportOptions options;
  options.cameras = {0};
  const io::KittiImportSummary summary = io::ImportKitti(inside.drive_dir, other.path() / "out", options);
  EXPECT_EQ(summary.calibration_dir, inside.drive_dir);
  const io::Dataset dataset = io::OpenDataset(other.path() / "out");
  EXPECT_LT((Matrix(dataset.rig.lidars[0].T_base_lidar) - ExpectedCam0RectFromVelo(inside)).cwiseAbs().maxCoeff(),
            1e-10);
}

TEST_F(KittiImport, AcceptsKittisPrintedPrecisionBySnappingRotations) {
  // The real 2011_09_26 lines, 7 significant digits: R is orthonormal to ~1e-6 only.
  WriteFile(drive_.date_dir / "calib_velo_to_cam.txt",
            "calib_time: 15-Mar-2012 11:37:16\n"
            "R: 7.533745e-03 -9.999714e-01 -6.166020e-04 1.480249e-02 7.280733e-04 -9.998902e-01 9.998621e-01 "
            "7.523790e-03 1.480755e-02\nT: -4.069766e-03 -7.631618e-02 -2.717806e-01\n");
  const io::Dataset dataset = Import({});
  const Eigen::Matrix3d r = dataset.rig.lidars[0].T_base_lidar.rotation();
  EXPECT_LT((r * r.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((Matrix(dataset.rig.lidars[0].T_base_lidar) - ExpectedCam0RectFromVelo(drive_)).cwiseAbs().maxCoeff(),
            1e-5);
}

TEST_F(KittiImport, LostFramesAreSkipped) {
  // KITTI marks a lost velodyne frame with an empty timestamps.txt line and no file.
  const fs::path velo = drive_.drive_dir / "velodyne_points";
  ASSERT_TRUE(ReplaceInFile(velo / "timestamps.txt", KittiTime(drive_.velo_ns[2]), ""));
  ASSERT_TRUE(fs::remove(velo / "data" / "0000000002.bin"));
  const io::KittiImportSummary summary = io::ImportKitti(drive_.drive_dir, temp_.path() / "out", {});
  EXPECT_EQ(summary.lost, 1u);
  const io::Dataset dataset = io::OpenDataset(temp_.path() / "out");
  ASSERT_EQ(dataset.scans.at("velodyne").size(), 4u);
  EXPECT_EQ(dataset.scans.at("velodyne")[2].t_us, ExpectedUs(drive_.velo_ns[3]));  // frame 3 keeps its own time
  EXPECT_EQ(dataset.images.at("image_00").size(), 5u);
}

// Published snippets hold only the images and the velodyne: without
// timestamps.txt every sensor's frame k is at k x 100 ms, without oxts/ the
// trajectory is the caller's (lidar odometry in the CLI).
TEST_F(KittiImport, SnippetWithoutOxtsAndTimestamps) {
  fs::remove_all(drive_.drive_dir / "oxts");
  for (const char* folder : {"image_00", "image_01", "image_02", "image_03", "velodyne_points"}) {
    ASSERT_TRUE(fs::remove(drive_.drive_dir / folder / "timestamps.txt"));
  }
  ASSERT_TRUE(fs::remove(drive_.drive_dir / "velodyne_points" / "data" / "0000000002.bin"));  // a lost scan
  // Without a way to make the trajectory, the drive is refused naming oxts/.
  try {
    io::ImportKitti(drive_.drive_dir, temp_.path() / "refused", {});
    ADD_FAILURE() << "accepted without oxts/";
  } catch (const io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("oxts"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(temp_.path() / "refused"));

  io::KittiImportOptions options;
  std::vector<TimeUs> scan_times_seen;
  options.trajectory_from_scans = [&](const std::vector<io::SensorFile>& scans, const Eigen::Isometry3d& T_base_velo) {
    EXPECT_LT((T_base_velo.matrix() - ExpectedCam0RectFromVelo(drive_)).cwiseAbs().maxCoeff(), 1e-5);
    std::vector<Eigen::Isometry3d> poses;
    for (const io::SensorFile& scan : scans) {
      scan_times_seen.push_back(scan.t_us);
      Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
      pose.translation().z() = 1e-6 * static_cast<double>(scan.t_us);  // 1 m/s forward
      poses.push_back(pose);
    }
    std::vector<TimeUs> times = scan_times_seen;
    return Trajectory(times, poses);
  };
  const io::KittiImportSummary summary = io::ImportKitti(drive_.drive_dir, temp_.path() / "out", options);
  EXPECT_TRUE(summary.trajectory_from_scans);
  EXPECT_EQ(summary.without_timestamps.size(), 5u);
  EXPECT_EQ(summary.lost, 1u);
  EXPECT_EQ(scan_times_seen, (std::vector<TimeUs>{0, 100'000, 300'000, 400'000}));
  const io::Dataset dataset = io::OpenDataset(temp_.path() / "out");
  ASSERT_EQ(dataset.images.at("image_02").size(), 5u);
  for (std::size_t k = 0; k < 5; ++k) EXPECT_EQ(dataset.images.at("image_02")[k].t_us, static_cast<TimeUs>(k) * 100'000);
  ASSERT_EQ(dataset.trajectory.size(), 4u);
  EXPECT_NEAR(dataset.trajectory.poses().back().translation().z(), 0.4, 1e-12);
  EXPECT_EQ(dataset.rig.trajectory_source, TrajectorySource::kLidarOdometry);

  // The command line makes the trajectory by lidar odometry and says so.
  const CliRun run = RunCli("import kitti '" + drive_.drive_dir.string() + "' --output '" +
                                (temp_.path() / "cli").string() + "'",
                            temp_.path());
  EXPECT_EQ(run.exit_code, 0) << run.stderr_text;
  EXPECT_NE(run.stderr_text.find("lidar odometry"), std::string::npos) << run.stderr_text;
  EXPECT_NE(run.stderr_text.find("10 Hz"), std::string::npos) << run.stderr_text;
  EXPECT_EQ(io::OpenDataset(temp_.path() / "cli").trajectory.size(), 4u);
}

// ---- bad input ---------------------------------------------------------------------

struct BadCase {
  std::string name;
  std::function<bool(const FakeDrive&)> wreck;  // false: the edit did not apply (a broken test)
  std::vector<std::string> expected;            // substrings of the message (file, field, what)
  std::string cli_options = "";                 // extra CLI options
};

std::vector<BadCase> BadCases() {
  const auto file_of = [](const FakeDrive& d, const std::string& relative) { return d.drive_dir / relative; };
  const auto replace_line = [](std::string relative_to_date, std::string from, std::string to) {
    return [=](const FakeDrive& d) { return ReplaceInFile(d.date_dir / relative_to_date, from, to); };
  };
  return {
      {"missing calibration file",
       [](const FakeDrive& d) { return fs::remove(d.date_dir / "calib_velo_to_cam.txt"); },
       {"calib_velo_to_cam.txt", "missing"}},
      {"P_rect_02 with 11 numbers",
       [](const FakeDrive& d) {
         std::string text = ReadFile(d.date_dir / "calib_cam_to_cam.txt");
         const std::size_t at = text.find("P_rect_02:");
         const std::size_t end = text.find('\n', at);
         text.erase(text.rfind(' ', end), end - text.rfind(' ', end));  // drop the last number
         WriteFile(d.date_dir / "calib_cam_to_cam.txt", text);
         return at != std::string::npos;
       },
       {"calib_cam_to_cam.txt", "P_rect_02", "11 numbers", "12 numbers"}},
      {"missing key R_rect_00",
       replace_line("calib_cam_to_cam.txt", "R_rect_00:", "R_rect_0x:"),
       {"calib_cam_to_cam.txt", "R_rect_00", "missing"}},
      {"non-numeric T",
       replace_line("calib_imu_to_velo.txt", "T: ", "T: 0.1x "),
       {"calib_imu_to_velo.txt", "T", "'0.1x'"}},
      {"R not a rotation",
       replace_line("calib_imu_to_velo.txt", "R: 0", "R: 5"),
       {"calib_imu_to_velo.txt", "line 2 R", "not a rotation matrix"}},
      {"line without a colon",
       replace_line("calib_velo_to_cam.txt", "delta_f:", "delta_f"),
       {"calib_velo_to_cam.txt", "line 4"}},
      {"timestamp count != data file count",
       [file_of](const FakeDrive& d) { return fs::remove(file_of(d, "velodyne_points/data/0000000004.bin")); },
       {"velodyne_points/data", "4 .bin files for 5 timestamps"}},
      {"data file named off its line",
       [file_of](const FakeDrive& d) {
         fs::rename(file_of(d, "image_01/data/0000000004.png"), file_of(d, "image_01/data/0000000007.png"));
         return true;
       },
       {"image_01/data/0000000004.png", "missing"}},
      {"bad timestamp",
       [file_of](const FakeDrive& d) {
         return ReplaceInFile(file_of(d, "image_01/timestamps.txt"), KittiTime(d.camera_ns[1][2]),
                              "2011-09-26 13:02:2x.964389445");
       },
       {"image_01/timestamps.txt", "line 3", "13:02:2x"}},
      {"non-increasing timestamps",
       [file_of](const FakeDrive& d) {
         return ReplaceInFile(file_of(d, "oxts/timestamps.txt"), KittiTime(d.oxts_ns[3]), KittiTime(d.oxts_ns[1]));
       },
       {"oxts/timestamps.txt", "line 4", "not after line 3"}},
      {"missing data folder",
       [file_of](const FakeDrive& d) { return fs::remove_all(file_of(d, "oxts/data")) > 0; },
       {"oxts/data", "missing"}},
      {"OXTS record with 29 numbers",
       [file_of](const FakeDrive& d) {
         WriteFile(file_of(d, "oxts/data/0000000002.txt"), Numbers(d.oxts[2].data(), 29) + "\n");
         return true;
       },
       {"oxts/data/0000000002.txt", "29 numbers", "30 numbers"}},
      {"OXTS non-numeric yaw",
       [file_of](const FakeDrive& d) {
         const std::string path = file_of(d, "oxts/data/0000000001.txt").string();
         std::string text = ReadFile(path);
         const std::size_t at = text.find(fmt::format("{:.17g}", d.oxts[1][5]));
         if (at == std::string::npos) return false;
         text.replace(at, 1, "y");
         WriteFile(path, text);
         return true;
       },
       {"oxts/data/0000000001.txt", "value 6 (yaw)"}},
      {"sensors with different frame counts",
       [file_of](const FakeDrive& d) {
         std::string text = ReadFile(file_of(d, "image_03/timestamps.txt"));
         WriteFile(file_of(d, "image_03/timestamps.txt"), text + KittiTime(d.camera_ns[3][4] + 100000000) + "\n");
         cv::imwrite(file_of(d, "image_03/data/0000000005.png").string(), TestPattern(66, 50, CV_8UC3));
         return true;
       },
       {"image_03/timestamps.txt", "6 lines", "has 5"}},
      {"empty drive",
       [file_of](const FakeDrive& d) {
         for (const char* folder : {"image_00", "image_01", "image_02", "image_03", "oxts", "velodyne_points"}) {
           WriteFile(file_of(d, std::string(folder) + "/timestamps.txt"), "");
           fs::remove_all(file_of(d, std::string(folder) + "/data"));
           fs::create_directories(file_of(d, std::string(folder) + "/data"));
         }
         return true;
       },
       {"oxts/timestamps.txt", "empty"}},
      {"image of another size",
       [file_of](const FakeDrive& d) {
         return cv::imwrite(file_of(d, "image_02/data/0000000003.png").string(), TestPattern(60, 50, CV_8UC3));
       },
       {"image_02/data/0000000003.png", "60 x 50"}},
      {"scan size not a multiple of 16",
       [file_of](const FakeDrive& d) {
         std::ofstream(file_of(d, "velodyne_points/data/0000000001.bin"), std::ios::app | std::ios::binary) << "abc";
         return true;
       },
       {"velodyne_points/data/0000000001.bin", "multiple of 16"}},
      {"frame range beyond the drive",
       [](const FakeDrive&) { return true; },
       {"--first/--count", "0..4"},
       "--first 3 --count 3"},
  };
}

TEST(KittiBadInput, EveryCaseIsRejectedNamingTheFileWithoutOutput) {
  ASSERT_TRUE(fs::exists(SCENECAL_CLI_PATH)) << "build the scenecal target first";
  const std::vector<BadCase> cases = BadCases();
  const TempDir temp;
  for (std::size_t c = 0; c < cases.size(); ++c) {
    const BadCase& bad = cases[c];
    SCOPED_TRACE(bad.name);
    const FakeDrive drive = WriteFakeDrive(temp.path() / fmt::format("date{}", c), 5);
    ASSERT_TRUE(bad.wreck(drive)) << "the edit did not apply";
    const fs::path output = temp.path() / fmt::format("out{}", c);
    io::KittiImportOptions options;
    if (!bad.cli_options.empty()) {
      options.first = 3;
      options.count = 3;
    }
    std::string message;
    try {
      io::ImportKitti(drive.drive_dir, output, options);
      ADD_FAILURE() << "accepted";
    } catch (const io::InputError& e) {
      message = e.what();
    }
    for (const std::string& part : bad.expected)
      EXPECT_NE(message.find(part), std::string::npos) << part << " in: " << message;
    EXPECT_NE(message.find("expected"), std::string::npos) << message;
    EXPECT_FALSE(fs::exists(output));
    const CliRun run =
        RunCli("import kitti '" + drive.drive_dir.string() + "' --output '" + output.string() + "' " + bad.cli_options,
               temp.path());
    EXPECT_TRUE(run.exited);
    EXPECT_EQ(run.exit_code, 2) << run.stderr_text;
    EXPECT_NE(run.stderr_text.find(bad.expected.front()), std::string::npos) << run.stderr_text;
    EXPECT_FALSE(fs::exists(output)) << "a failed import left its output";
  }
  for (const fs::directory_entry& entry : fs::directory_iterator(temp.path())) {
    EXPECT_NE(entry.path().filename().string().front(), '.') << "temporary left: " << entry.path();
  }
}

TEST(KittiCli, ImportsAndRejectsBadOptions) {
  ASSERT_TRUE(fs::exists(SCENECAL_CLI_PATH)) << "build the scenecal target first";
  const TempDir temp;
  const FakeDrive drive = WriteFakeDrive(temp.path() / "2011_09_26", 4);
  const fs::path output = temp.path() / "out";
  const std::string source = "import kitti '" + drive.drive_dir.string() + "' --output '" + output.string() + "'";
  const CliRun ok = RunCli(source + " --cameras 0,1 --first 1 --count 2", temp.path());
  ASSERT_EQ(ok.exit_code, 0) << ok.stderr_text;
  EXPECT_NE(ok.stderr_text.find("copied 6/6"), std::string::npos) << ok.stderr_text;  // progress on stderr
  const io::Dataset dataset = io::OpenDataset(output);
  EXPECT_EQ(dataset.rig.cameras.size(), 2u);
  EXPECT_EQ(dataset.images.at("image_01").size(), 2u);
  // A second import into the non-empty folder needs --force.
  EXPECT_EQ(RunCli(source, temp.path()).exit_code, 2);
  EXPECT_EQ(dataset.images.at("image_01").size(), io::OpenDataset(output).images.at("image_01").size());
  const CliRun forced = RunCli(source + " --force", temp.path());
  EXPECT_EQ(forced.exit_code, 0) << forced.stderr_text;
  EXPECT_EQ(io::OpenDataset(output).rig.cameras.size(), 4u);
  for (const char* options : {"--cameras 4", "--cameras 0,0", "--cameras x", "--count 0"}) {
    const CliRun run = RunCli("import kitti '" + drive.drive_dir.string() + "' --output '" +
                                  (temp.path() / "never").string() + "' " + options,
                              temp.path());
    EXPECT_EQ(run.exit_code, 2) << options << ": " << run.stderr_text;
    EXPECT_FALSE(fs::exists(temp.path() / "never")) << options;
  }
  // KITTI options do not apply to opencalib.
  EXPECT_EQ(RunCli("import opencalib '" + drive.drive_dir.string() + "' --output '" + (temp.path() / "never").string() +
                       "' --first 2",
                   temp.path())
                .exit_code,
            2);
}

}  // namespace
}  // namespace scenecal
