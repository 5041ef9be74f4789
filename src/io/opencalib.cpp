#include "io/opencalib.hpp"

#include <sstream>
#include <system_error>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "core/interrupt.hpp"
#include "io/dataset.hpp"
#include "io/pcd.hpp"
#include "io/staged_output.hpp"
#include "io/yaml_fields.hpp"

namespace scenecal::io {

namespace fs = std::filesystem;
using detail::Fail;

namespace {

}  // namespace

CameraModel OpenCalibCameraModel(const OpenCalibCalibration& calibration, int width, int height) {
  CameraModel model;
  model.width = width;
  model.height = height;
  model.kind = CameraModelKind::kRadTan;
  model.fx = calibration.fx;
  model.fy = calibration.fy;
  model.cx = calibration.cx;
  model.cy = calibration.cy;
  model.distortion = calibration.distortion;
  return model;
}

OpenCalibCalibration ReadOpenCalibCalibration(const fs::path& calib_txt) {
  return ParseOpenCalibCalibration(detail::ReadTextFile(calib_txt, 1 << 20), calib_txt.string());
}

OpenCalibCalibration ParseOpenCalibCalibration(const std::string& text, const std::string& file) {
  std::map<std::string, std::vector<double>> entries;
  std::istringstream lines(text);
  std::string line;
  int line_number = 0;
  while (std::getline(lines, line)) {
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    const std::size_t colon = line.find(':');
    const std::string where = fmt::format("line {}", line_number);
    if (colon == std::string::npos) Fail(file, where, "'" + line.substr(0, 40) + "'", "'K:', 'D:' or 'T:' followed by numbers");
    std::string key = line.substr(0, colon);
    key.erase(0, key.find_first_not_of(" \t"));
    key.erase(key.find_last_not_of(" \t") + 1);
    if (key != "K" && key != "D" && key != "T") Fail(file, where, "unknown key '" + key + "'", "K, D or T");
    if (entries.count(key) != 0) Fail(file, where + " " + key, "given twice", "each of K, D, T once");
    std::vector<double>& values = entries[key];
    std::istringstream numbers(line.substr(colon + 1));
    std::string token;
    while (numbers >> token) {
      double value = 0;
      if (!detail::ParseWholeToken(token, &value) || !std::isfinite(value)) {
        Fail(file, where + " " + key, "'" + token + "'", "finite numbers");
      }
      values.push_back(value);
    }
  }
  for (const auto& [key, description] : std::map<std::string, std::string>{
           {"K", "9 numbers (3x3 camera matrix, row-major)"},
           {"D", "4 or 5 radtan numbers k1 k2 p1 p2 [k3]"},
           {"T", "12 numbers ([R | t] row-major, lidar to camera)"}}) {
    if (entries.count(key) == 0) Fail(file, key, "missing", description);
    const std::size_t size = entries[key].size();
    const bool good = key == "K" ? size == 9 : key == "D" ? (size == 4 || size == 5) : size == 12;
    if (!good) Fail(file, key, fmt::format("{} numbers", size), description);
  }
  const std::vector<double>& k = entries["K"];
  if (k[1] != 0 || k[3] != 0 || k[6] != 0 || k[7] != 0 || k[8] != 1) {
    Fail(file, "K", "not of the form fx 0 cx 0 fy cy 0 0 1", "a pinhole camera matrix without skew");
  }
  OpenCalibCalibration calibration;
  calibration.fx = k[0];
  calibration.cx = k[2];
  calibration.fy = k[4];
  calibration.cy = k[5];
  calibration.distortion = entries["D"];
  const std::vector<double>& t = entries["T"];
  Eigen::Matrix4d matrix = Eigen::Matrix4d::Identity();
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 4; ++col) matrix(row, col) = t[static_cast<std::size_t>(row * 4 + col)];
  }
  // calib.txt prints about 6 significant digits, so R is orthonormal only to
  // ~1e-6; accept 1e-3 and snap to the nearest rotation (SVD).
  if (!IsRigid(matrix, 1e-3)) Fail(file, "T", "the 3x3 block is not a rotation", "[R | t] with R orthonormal, det +1");
  calibration.T_camera_lidar.linear() = NearestRotation(matrix.topLeftCorner<3, 3>());
  calibration.T_camera_lidar.translation() = matrix.topRightCorner<3, 1>();
  return calibration;
}

OpenCalibImportSummary ImportOpenCalib(const fs::path& source_dir, const fs::path& output, bool overwrite,
                                       std::int64_t t_us) {
  std::error_code error;
  if (!fs::is_directory(source_dir, error)) {
    Fail(source_dir.string(), "source", "not a directory", "a folder with calib.txt, calib.pcd and calib.jpg or calib.png");
  }
  const fs::path target = CheckOutputFolder(output, overwrite);
  // Everything is read and checked before anything is written.
  const OpenCalibCalibration calibration = ReadOpenCalibCalibration(source_dir / "calib.txt");
  fs::path image_path;
  for (const char* name : {"calib.jpg", "calib.jpeg", "calib.png"}) {
    if (fs::exists(source_dir / name, error)) {
      if (!image_path.empty()) {
        Fail((source_dir / name).string(), "image", "a second image beside " + image_path.filename().string(),
             "exactly one of calib.jpg or calib.png");
      }
      image_path = source_dir / name;
    }
  }
  if (image_path.empty()) Fail((source_dir / "calib.jpg").string(), "image", "missing", "calib.jpg or calib.png");
  const auto image_size = ImageFileSize(image_path);
  if (!image_size) Fail(image_path.string(), "image", "not a readable PNG or JPEG header", "a PNG or JPEG image");

  Rig rig;
  rig.base_frame = "camera";
  CameraInfo camera;
  camera.name = "camera";
  camera.model = OpenCalibCameraModel(calibration, image_size->first, image_size->second);
  std::string why;
  if (!camera.model.IsValid(&why)) Fail((source_dir / "calib.txt").string(), "K/D", "invalid camera: " + why, "a valid radtan camera");
  ReadImage({t_us, image_path}, camera.model);  // decodes it: a corrupt image fails here, not at calibration
  rig.cameras.push_back(camera);
  LidarInfo lidar;
  lidar.name = "lidar";
  lidar.kind = LidarKind::k3d;
  lidar.T_base_lidar = calibration.T_camera_lidar;  // base = camera
  rig.lidars.push_back(lidar);

  const PcdCloud cloud = ReadPcd(source_dir / "calib.pcd");
  if (!cloud.has_intensity) {
    Fail((source_dir / "calib.pcd").string(), "FIELDS", "no intensity field", "an intensity (or reflectance) field");
  }

  StagedOutput staged(target);
  const fs::path& root = staged.Staging();
  YAML::Node extra;
  extra["source"] = "opencalib";
  extra["source_dir"] = fs::absolute(source_dir).lexically_normal().string();
  extra["ground_truth"] =
      "ground_truth.yaml holds the data set's own reference extrinsic (calib.txt T), not exact truth; its accuracy "
      "is not stated";
  WriteRig(root / "rig.yaml", rig, extra);
  WriteTrajectory(root / "trajectory.csv", Trajectory({t_us}, {Eigen::Isometry3d::Identity()}));
  GroundTruth truth;
  truth.T_base_lidar["lidar"] = calibration.T_camera_lidar;
  WriteGroundTruth(root / "ground_truth.yaml", truth);
  fs::create_directories(root / "cameras" / "camera");
  fs::create_directories(root / "lidars" / "lidar");
  std::string extension = image_path.extension().string();
  fs::copy_file(image_path, root / "cameras" / "camera" / (std::to_string(t_us) + extension));
  WriteScan(root / "lidars" / "lidar" / (std::to_string(t_us) + ".bin"), cloud.points);
  OpenDataset(root);  // the result must read back as a valid dataset

  ThrowIfInterrupted();  // the last point at which the output can still be left as it was
  staged.Commit();

  OpenCalibImportSummary summary;
  summary.dataset = target;
  summary.image_width = image_size->first;
  summary.image_height = image_size->second;
  summary.points = cloud.points.size();
  for (const LidarPoint& p : cloud.points) {
    if (!(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) && std::isfinite(p.reflectance))) {
      ++summary.no_returns;
    }
  }
  return summary;
}

}  // namespace scenecal::io
