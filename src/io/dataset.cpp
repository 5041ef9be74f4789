#include "io/dataset.hpp"

#include <set>
#include <system_error>

#include "io/yaml_fields.hpp"

namespace scenecal::io {

namespace fs = std::filesystem;
using detail::Fail;

namespace {

// ground_truth.yaml, whose sensors must all be sensors of the rig.
GroundTruth ReadGroundTruthOfRig(const fs::path& truth_path, const Rig& rig) {
  GroundTruth truth = ReadGroundTruth(truth_path);
  for (const auto& [name, transform] : truth.T_base_lidar) {
    if (rig.FindLidar(name) == nullptr) {
      Fail(truth_path.string(), "lidars." + name, "'" + name + "' is not a lidar of rig.yaml",
           "lidar names of rig.yaml");
    }
  }
  for (const auto& [name, transform] : truth.T_base_camera) {
    if (rig.FindCamera(name) == nullptr) {
      Fail(truth_path.string(), "cameras." + name, "'" + name + "' is not a camera of rig.yaml",
           "camera names of rig.yaml");
    }
  }
  return truth;
}

}  // namespace

Dataset OpenDataset(const fs::path& root) {
  std::error_code error;
  if (!fs::is_directory(root, error)) {
    Fail(root.string(), "dataset", "not a directory", "a dataset directory (FORMAT.md)");
  }
  Dataset dataset;
  dataset.root = root;
  dataset.rig = ReadRig(root / "rig.yaml");
  dataset.trajectory = ReadTrajectory(root / "trajectory.csv");
  const fs::path truth_path = root / "ground_truth.yaml";
  if (fs::exists(truth_path, error)) dataset.ground_truth = ReadGroundTruthOfRig(truth_path, dataset.rig);
  std::set<std::string> cameras, lidars;
  for (const CameraInfo& camera : dataset.rig.cameras) cameras.insert(camera.name);
  for (const LidarInfo& lidar : dataset.rig.lidars) lidars.insert(lidar.name);
  dataset.images = detail::ListSensorFolders(root, "cameras", cameras, true, "camera");
  dataset.scans = detail::ListSensorFolders(root, "lidars", lidars, false, "lidar");
  return dataset;
}

void WriteDatasetSkeleton(const fs::path& root, const Rig& rig, const Trajectory& trajectory,
                          const std::optional<GroundTruth>& truth) {
  fs::create_directories(root);
  WriteRig(root / "rig.yaml", rig);
  WriteTrajectory(root / "trajectory.csv", trajectory);
  if (truth) WriteGroundTruth(root / "ground_truth.yaml", *truth);
  for (const CameraInfo& camera : rig.cameras) fs::create_directories(root / "cameras" / camera.name);
  for (const LidarInfo& lidar : rig.lidars) fs::create_directories(root / "lidars" / lidar.name);
}

}  // namespace scenecal::io
