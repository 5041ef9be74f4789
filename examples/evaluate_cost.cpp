// Evaluates the pair cost (NID by default) of one (camera, lidar) pair of a dataset at a few extrinsics:
//   example_evaluate_cost DATASET [CAMERA LIDAR]
// (default: the rig's first camera and first lidar). The extrinsics: the rig's initial guess, that guess
// moved by 1 cm along and turned by 0.1 deg about each camera axis, and the ground truth when the dataset
// has one. A lower cost means the lidar's reflectance and the image intensity agree better.
#include <cmath>
#include <cstdio>
#include <exception>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "core/calibrate.hpp"
#include "core/geometry.hpp"
#include "core/pair_cost.hpp"
#include "io/calibration_input.hpp"
#include "io/dataset.hpp"

int main(int argc, char** argv) {
  if (argc != 2 && argc != 4) {
    std::fprintf(stderr, "usage: %s DATASET [CAMERA LIDAR]\n", argv[0]);
    return 2;
  }
  try {
    const scenecal::io::Dataset dataset = scenecal::io::OpenDataset(argv[1]);
    const scenecal::Rig& rig = dataset.rig;
    const std::string camera_name = argc == 4 ? argv[2] : rig.cameras.empty() ? "" : rig.cameras.front().name;
    const std::string lidar_name = argc == 4 ? argv[3] : rig.lidars.empty() ? "" : rig.lidars.front().name;
    const scenecal::CameraInfo* camera = rig.FindCamera(camera_name);
    const scenecal::LidarInfo* lidar = rig.FindLidar(lidar_name);
    if (camera == nullptr || lidar == nullptr) {
      std::fprintf(stderr, "error: the rig has no camera '%s' or no lidar '%s'\n", camera_name.c_str(),
                   lidar_name.c_str());
      return 2;
    }

    // The pair's scenes only, and the images and scans they use.
    const scenecal::CalibrationOptions options;  // cost, scene and swathe settings as a calibration uses them
    scenecal::CalibrationInput input;
    input.rig = rig;
    scenecal::io::LoadCalibrationInput(dataset, options.scenes, &input);
    std::erase_if(input.selection.scenes, [&](const scenecal::Scene& scene) {
      return scene.camera != camera->name || scene.lidar != lidar->name;
    });

    // The cost is a function of T_camera_lidar = T_base_camera^-1 * T_base_lidar (known camera transform).
    scenecal::PairCost cost = scenecal::BuildPairCost(input, *camera, lidar->name, options);
    const Eigen::Isometry3d T_camera_lidar_guess = camera->T_camera_base() * lidar->T_base_lidar;
    // Which points are visible (occlusion) and which scenes count are fixed at the guess, as an optimiser
    // fixes them between its runs: every cost below compares the same points.
    const int scenes_used = cost.RefreshVisibility(T_camera_lidar_guess);
    std::printf("pair %s/%s (%s): %d of %d scenes used\n", camera->name.c_str(), lidar->name.c_str(),
                scenecal::MetricKindName(options.cost.metric), scenes_used, cost.SceneCount());

    std::vector<std::pair<std::string, Eigen::Isometry3d>> extrinsics = {{"initial guess", T_camera_lidar_guess}};
    const char* axes[] = {"x", "y", "z"};
    for (int axis = 0; axis < 3; ++axis) {
      Eigen::Isometry3d moved = T_camera_lidar_guess;
      moved.translation() += 0.01 * Eigen::Vector3d::Unit(axis);  // 1 cm, camera frame
      extrinsics.emplace_back(std::string("guess moved 1 cm along camera ") + axes[axis], moved);
    }
    for (int axis = 0; axis < 3; ++axis) {
      // 0.1 deg about the camera axis through the lidar's origin.
      Eigen::Isometry3d turned = T_camera_lidar_guess;
      turned.linear() = scenecal::ExpSO3(scenecal::RadiansFromDegrees(0.1) * Eigen::Vector3d::Unit(axis)) *
                        T_camera_lidar_guess.linear();
      extrinsics.emplace_back(std::string("guess turned 0.1 deg about camera ") + axes[axis], turned);
    }
    if (dataset.ground_truth && dataset.ground_truth->T_base_lidar.contains(lidar->name)) {
      extrinsics.emplace_back("ground truth",
                              camera->T_camera_base() * dataset.ground_truth->T_base_lidar.at(lidar->name));
    }

    for (const auto& [name, T_camera_lidar] : extrinsics) {
      const double value = cost.Evaluate(T_camera_lidar);  // NaN when no scene is used
      if (!std::isfinite(value)) {
        std::fprintf(stderr, "error: no scene of the pair carries information at the %s\n", name.c_str());
        return 1;
      }
      std::printf("%-42s cost %.6f\n", name.c_str(), value);
    }
  } catch (const std::exception& error) {  // io::InputError names the file and the field
    std::fprintf(stderr, "error: %s\n", error.what());
    return 1;
  }
  return 0;
}
