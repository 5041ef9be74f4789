// The DGP importer on the real scene in ../shared/data/dgp/scene_01, its
// conventions checked against values computed by hand from the scene's JSON
// and point clouds, the NumPy readers, and malformed scenes.
#include <algorithm>
#include <cstring>
#include <functional>

#include <gtest/gtest.h>

#include "core/camera.hpp"
#include "core/geometry.hpp"
#include "io/dataset.hpp"
#include "io/dgp.hpp"
#include "io/npz.hpp"
#include "io_test_support.hpp"

namespace scenecal {
namespace {

using namespace scenecal::testing;

const fs::path kScene = fs::path(SCENECAL_SHARED_DATA_DIR) / "dgp" / "scene_01";
constexpr char kSceneJson[] = "scene_a8dc5ed1da0923563f85ea129f0e0a83e7fe1867.json";
constexpr char kCalibrationJson[] = "calibration/c0e1a6f1c439b282be0066d8dfcad9dd54782030.json";

double MatrixDistance(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff();
}

// A copy of the scene without its annotations, to break in one way.
fs::path CopyScene(const fs::path& destination) {
  fs::create_directories(destination);
  for (const char* part : {"rgb", "point_cloud", "calibration"}) {
    fs::copy(kScene / part, destination / part, fs::copy_options::recursive);
  }
  fs::copy_file(kScene / kSceneJson, destination / kSceneJson);
  for (const fs::directory_entry& entry : fs::recursive_directory_iterator(destination)) {
    fs::permissions(entry.path(), fs::perms::owner_write, fs::perm_options::add);  // shared/ is read-only
  }
  return destination;
}

TEST(DgpImport, SceneOneWithItsConventions) {
  ASSERT_TRUE(fs::exists(kScene / kSceneJson)) << "the DGP test scene is missing: " << kScene;
  const TempDir temp;
  const fs::path output = temp.path() / "dataset";
  const io::DgpImportSummary summary = io::ImportDgp(kScene, output, {});
  EXPECT_EQ(summary.frames, 3u);
  EXPECT_EQ(summary.cameras, (std::vector<std::string>{"CAMERA_01", "CAMERA_05", "CAMERA_06"}));
  EXPECT_EQ(summary.lidars, (std::vector<std::string>{"LIDAR"}));
  EXPECT_EQ(summary.base_frame, "CAMERA_01");
  EXPECT_EQ(summary.images, 9u);
  EXPECT_EQ(summary.scans, 3u);
  EXPECT_EQ(summary.points, 40733u + 40523u + 40239u);
  // Three camera times and three lidar times (the cameras of a frame fire together).
  EXPECT_EQ(summary.poses, 6u);
  // The file names count 100 ns; the RFC 3339 strings read them as microseconds.
  EXPECT_TRUE(summary.times_in_100ns);
  // Each camera's pose is the vehicle's pose times its extrinsic: the datums
  // of one time agree on the vehicle's pose when the conventions are right.
  EXPECT_LT(summary.pose_disagreement_m, 1e-6);
  EXPECT_LT(summary.pose_disagreement_deg, 1e-4);

  const io::Dataset dataset = io::OpenDataset(output);
  ASSERT_EQ(dataset.images.at("CAMERA_05").size(), 3u);
  EXPECT_EQ(dataset.images.at("CAMERA_05").front().t_us, 1556919593841523);  // 15569195938415230 x 100 ns
  ASSERT_EQ(dataset.scans.at("LIDAR").size(), 3u);
  EXPECT_EQ(dataset.scans.at("LIDAR").front().t_us, 1556919593820375);
  // Every image and scan lies on the trajectory.
  for (const auto* files : {&dataset.images.at("CAMERA_01"), &dataset.scans.at("LIDAR")}) {
    for (const io::SensorFile& file : *files) EXPECT_TRUE(dataset.trajectory.PoseAt(file.t_us).has_value());
  }
  ASSERT_TRUE(dataset.ground_truth.has_value());
  EXPECT_LT(MatrixDistance(dataset.ground_truth->T_base_lidar.at("LIDAR"), dataset.rig.lidars[0].T_base_lidar), 1e-12);

  // One lidar point of the first sweep per camera, projected by hand from the
  // calibration JSON (p_camera = R_ext^T (p_vehicle - t_ext), u = fx x/z + cx,
  // v = fy y/z + cy; the lidar's extrinsic is the identity): the point's index
  // in the sweep and its pixel.
  struct Expected {
    const char* camera;
    std::size_t point;
    double u, v;
  };
  const Expected expected[] = {{"CAMERA_01", 555, 35.15950623020592, 1168.734813865477},
                               {"CAMERA_05", 0, 1086.6353037961815, 1114.3620353959227},
                               {"CAMERA_06", 1143, 9.73759021172964, 516.8294724930668}};
  const LidarScan scan = io::ReadScan(dataset.scans.at("LIDAR").front());
  ASSERT_EQ(scan.points.size(), 40733u);
  for (const Expected& e : expected) {
    SCOPED_TRACE(e.camera);
    const CameraInfo& camera = *dataset.rig.FindCamera(e.camera);
    const Eigen::Isometry3d T_camera_lidar = camera.T_camera_base() * dataset.rig.lidars[0].T_base_lidar;
    const LidarPoint& p = scan.points[e.point];
    Eigen::Vector2d pixel;
    ASSERT_TRUE(camera.model.Project(T_camera_lidar * Eigen::Vector3d(p.x, p.y, p.z), &pixel));
    // The scan stores float32: ~1e-5 m at 57 m, far below 1e-3 px.
    EXPECT_NEAR(pixel.x(), e.u, 1e-3);
    EXPECT_NEAR(pixel.y(), e.v, 1e-3);
  }
}

TEST(DgpImport, CameraSubsetAndBaseCamera) {
  const TempDir temp;
  io::DgpImportOptions options;
  options.cameras = {"CAMERA_06", "CAMERA_05"};
  options.base_camera = "CAMERA_06";
  const io::DgpImportSummary summary = io::ImportDgp(kScene, temp.path() / "dataset", options);
  EXPECT_EQ(summary.base_frame, "CAMERA_06");
  EXPECT_EQ(summary.images, 6u);
  const io::Dataset dataset = io::OpenDataset(temp.path() / "dataset");
  ASSERT_EQ(dataset.rig.cameras.size(), 2u);
  EXPECT_EQ(dataset.rig.cameras[0].name, "CAMERA_06");  // the base camera first, the identity
  EXPECT_LT(MatrixDistance(dataset.rig.cameras[0].T_base_camera, Eigen::Isometry3d::Identity()), 1e-12);
  // The same physical transform whichever camera is the base.
  const io::Dataset all = io::OpenDataset([&] {
    io::ImportDgp(kScene, temp.path() / "all", {});
    return temp.path() / "all";
  }());
  const Eigen::Isometry3d T_cam6_cam5_subset = dataset.rig.FindCamera("CAMERA_05")->T_base_camera;
  const Eigen::Isometry3d T_cam6_cam5_all =
      all.rig.FindCamera("CAMERA_06")->T_camera_base() * all.rig.FindCamera("CAMERA_05")->T_base_camera;
  EXPECT_LT(MatrixDistance(T_cam6_cam5_subset, T_cam6_cam5_all), 1e-9);
  const Eigen::Isometry3d T_cam6_lidar_all =
      all.rig.FindCamera("CAMERA_06")->T_camera_base() * all.rig.lidars[0].T_base_lidar;
  EXPECT_LT(MatrixDistance(dataset.rig.lidars[0].T_base_lidar, T_cam6_lidar_all), 1e-9);
}

struct BadScene {
  std::string name;
  std::function<bool(const fs::path& scene)> wreck;
  std::string file, field;
  io::DgpImportOptions options = {};
};

TEST(DgpImport, MalformedScenesAreRefusedWithoutOutput) {
  const auto scene_json = [](const std::string& from, const std::string& to) {
    return [from, to](const fs::path& scene) { return ReplaceInFile(scene / kSceneJson, from, to); };
  };
  const auto calibration = [](const std::string& from, const std::string& to) {
    return [from, to](const fs::path& scene) { return ReplaceInFile(scene / kCalibrationJson, from, to); };
  };
  io::DgpImportOptions unknown_camera;
  unknown_camera.cameras = {"CAMERA_02"};
  io::DgpImportOptions bad_base;
  bad_base.cameras = {"CAMERA_01"};
  bad_base.base_camera = "CAMERA_05";
  const std::vector<BadScene> cases = {
      {"JSON syntax error", scene_json("\"samples\"", "\"samples\" ]"), "scene_", "byte"},
      // Found by fuzz_dgp_scene: a number beyond a double escaped as nlohmann's out_of_range.
      {"number beyond a double", scene_json("\"qw\": 0.28545389542589", "\"qw\": 66e411"), "scene_", "JSON"},
      {"calibration number beyond a double", calibration("\"fx\": 2167.6926048451924", "\"fx\": 0.6718e223863801"),
       "calibration", "JSON"},
      {"quaternion not of unit norm", scene_json("\"qw\": 0.28545389542589", "\"qw\": 0.58545389542589"), "scene_",
       "data[0].datum.point_cloud.pose.rotation"},
      {"timestamp not RFC 3339", scene_json("2463-05-15T00:38:58.203752Z", "2463-05-15 noon"), "scene_",
       "data[0].id.timestamp"},
      {"filename outside the scene", scene_json("point_cloud/LIDAR/15569195938203752.npz", "../x.npz"), "scene_",
       "data[0].datum.point_cloud.filename"},
      {"missing calibration",
       [](const fs::path& scene) { return fs::remove(scene / kCalibrationJson); }, "calibration", "file"},
      {"calibration without a camera", calibration("\"CAMERA_06\"", "\"CAMERA_07\""), "calibration", "names"},
      {"skewed camera", calibration("1056.7635782913833,\n      \"skew\": 0.0", "1056.7635782913833,\n      \"skew\": 3.0"),
       "calibration", "skew"},
      {"missing image",
       [](const fs::path& scene) { return fs::remove(scene / "rgb/CAMERA_05/15569195939415230.jpg"); },
       "15569195939415230.jpg", "file"},
      {"image of another size than its datum", scene_json("\"width\": 1936", "\"width\": 1920"), "CAMERA_0",
       "image size"},
      {"truncated point cloud",
       [](const fs::path& scene) {
         const fs::path cloud = scene / "point_cloud/LIDAR/15569195939203480.npz";
         fs::resize_file(cloud, fs::file_size(cloud) / 2);
         return true;
       },
       "15569195939203480.npz", "archive"},
      {"point cloud without intensity", scene_json("\"INTENSITY\"", "\"RANGE\""), "scene_", "point_format"},
      {"camera not in the scene", [](const fs::path&) { return true; }, "scene_", "--cameras", unknown_camera},
      {"base camera not imported", [](const fs::path&) { return true; }, "scene_", "--base-camera", bad_base},
  };
  const TempDir temp;
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const BadScene& bad = cases[i];
    SCOPED_TRACE(bad.name);
    const fs::path scene = CopyScene(temp.path() / ("scene" + std::to_string(i)));
    ASSERT_TRUE(bad.wreck(scene)) << "the edit did not apply";
    const fs::path output = temp.path() / ("out" + std::to_string(i));
    std::string message;
    try {
      io::ImportDgp(scene, output, bad.options);
      ADD_FAILURE() << "accepted";
    } catch (const io::InputError& e) {
      message = e.what();
    }
    EXPECT_NE(message.find(bad.file), std::string::npos) << message;
    EXPECT_NE(message.find(bad.field), std::string::npos) << message;
    EXPECT_NE(message.find("expected"), std::string::npos) << message;
    EXPECT_FALSE(fs::exists(output));
  }
  for (const fs::directory_entry& entry : fs::directory_iterator(temp.path())) {
    EXPECT_NE(entry.path().filename().string().front(), '.') << "a temporary folder was left: " << entry.path();
  }
}

TEST(DgpImport, CommandLine) {
  const TempDir temp;
  const fs::path output = temp.path() / "dataset";
  const CliRun run = RunCli("import dgp '" + kScene.string() + "' --output '" + output.string() +
                                "' --cameras CAMERA_05,CAMERA_01 --base-camera CAMERA_05",
                            temp.path());
  EXPECT_EQ(run.exit_code, 0) << run.stderr_text;
  EXPECT_NE(run.stderr_text.find("100 ns"), std::string::npos) << run.stderr_text;
  EXPECT_EQ(io::OpenDataset(output).rig.base_frame, "CAMERA_05");
  const CliRun kitti_only = RunCli("import dgp '" + kScene.string() + "' --output '" + (temp.path() / "b").string() +
                                       "' --first 1",
                                   temp.path());
  EXPECT_EQ(kitti_only.exit_code, 2) << kitti_only.stderr_text;
  const CliRun bad_list = RunCli("import dgp '" + kScene.string() + "' --output '" + (temp.path() / "c").string() +
                                     "' --cameras CAMERA_01,,CAMERA_05",
                                 temp.path());
  EXPECT_EQ(bad_list.exit_code, 2) << bad_list.stderr_text;
  EXPECT_FALSE(fs::exists(temp.path() / "b"));
  EXPECT_FALSE(fs::exists(temp.path() / "c"));
}

TEST(DgpTime, Rfc3339) {
  EXPECT_EQ(io::ParseRfc3339("1970-01-01T00:00:00Z"), 0);
  EXPECT_EQ(io::ParseRfc3339("2019-03-28T11:10:09.112358Z"), 1553771409112358);
  EXPECT_EQ(io::ParseRfc3339("2019-03-28T11:10:09.1123589Z"), 1553771409112358);  // finer digits dropped
  EXPECT_EQ(io::ParseRfc3339("2019-03-28T13:10:09.5+02:00"), 1553771409500000);
  EXPECT_EQ(io::ParseRfc3339("2019-03-28T11:10:09Z"), 1553771409000000);
  for (const char* bad : {"2019-03-28", "2019-02-30T00:00:00Z", "2019-03-28T25:00:00Z", "2019-03-28T11:10:09",
                          "x2019-03-28T11:10:09Z", "2019-03-28T11:10:09.Z", "2019-03-28T11:10:09+24:00"}) {
    EXPECT_FALSE(io::ParseRfc3339(bad).has_value()) << bad;
  }
}

// A .npy file: version 1 header padded to 64 bytes, then the raw elements.
std::string Npy(const std::string& descr, bool fortran, const std::string& shape, const std::string& payload) {
  std::string header =
      "{'descr': '" + descr + "', 'fortran_order': " + (fortran ? "True" : "False") + ", 'shape': " + shape + ", }";
  while ((10 + header.size() + 1) % 64 != 0) header += ' ';
  header += '\n';
  std::string bytes = "\x93NUMPY\x01";
  bytes += '\0';
  bytes += static_cast<char>(header.size() & 0xff);
  bytes += static_cast<char>(header.size() >> 8);
  return bytes + header + payload;
}

template <typename T>
std::string Raw(std::initializer_list<T> values, bool big_endian = false) {
  std::string bytes;
  for (const T value : values) {
    char element[sizeof(T)];
    std::memcpy(element, &value, sizeof(T));
    if (big_endian) std::reverse(element, element + sizeof(T));
    bytes.append(element, sizeof(T));
  }
  return bytes;
}

TEST(Npy, LayoutsAndTypes) {
  const io::NpyArray c_order = io::ParseNpy(Npy("<f8", false, "(2, 3)", Raw<double>({1, 2, 3, 4, 5, 6})), "c");
  ASSERT_EQ(c_order.rows, 2u);
  ASSERT_EQ(c_order.cols, 3u);
  EXPECT_EQ(c_order.At(1, 0), 4.0);
  const io::NpyArray fortran = io::ParseNpy(Npy("<f4", true, "(2, 3)", Raw<float>({1, 4, 2, 5, 3, 6})), "f");
  EXPECT_EQ(fortran.values, c_order.values);
  const io::NpyArray big = io::ParseNpy(Npy(">i2", false, "(3,)", Raw<std::int16_t>({-7, 300, 2}, true)), "b");
  EXPECT_EQ(big.rows, 3u);
  EXPECT_EQ(big.cols, 1u);
  EXPECT_EQ(big.values, (std::vector<double>{-7, 300, 2}));
  EXPECT_EQ(io::ParseNpy(Npy("|u1", false, "(0, 4)", ""), "empty").rows, 0u);
  // A huge dimension beside a zero one holds no element (fuzzing found it looping over the rows).
  const io::NpyArray tall_empty = io::ParseNpy(Npy("<f4", true, "(747771587, 0)", ""), "tall");
  EXPECT_EQ(tall_empty.rows, 747771587u);
  EXPECT_EQ(tall_empty.cols, 0u);
  EXPECT_TRUE(tall_empty.values.empty());
}

TEST(Npy, MalformedArraysAreRefusedBeforeAllocating) {
  struct Case {
    std::string bytes, field;
  };
  const std::string six = Raw<double>({1, 2, 3, 4, 5, 6});
  const std::vector<Case> cases = {
      {"not numpy at all", "magic"},
      {Npy("<f8", false, "(4, 3)", six), "data"},                           // fewer bytes than the shape
      {Npy("<f8", false, "(1000000000000, 1000000000)", six), "data"},     // absurd claim, no allocation
      {Npy("<f8", false, "(18446744073709551615, 2)", six), "data"},       // overflowing product
      {Npy("<c16", false, "(3,)", six), "descr"},                           // complex numbers
      {Npy("<U8", false, "(6,)", six), "descr"},                            // strings
      {Npy("<f8", false, "(1, 2, 3)", six), "shape"},                       // three dimensions
      {Npy("<f8", false, "(a, 3)", six), "shape"},
      {Npy("<f8", false, "(6,)", six).substr(0, 40), "header"},             // truncated header
  };
  for (const Case& bad : cases) {
    SCOPED_TRACE(bad.field);
    try {
      io::ParseNpy(bad.bytes, "array.npy");
      ADD_FAILURE() << "accepted";
    } catch (const io::InputError& e) {
      EXPECT_NE(std::string(e.what()).find(bad.field), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(io::ParseNpz("PK\x03\x04 broken", "cloud.npz", ""), io::InputError);
  EXPECT_THROW(io::ParseNpz("", "cloud.npz", ""), io::InputError);
}

}  // namespace
}  // namespace scenecal
