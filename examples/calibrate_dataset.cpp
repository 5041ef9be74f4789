// Calibrates a dataset (FORMAT.md) through the library, with default options:
//   example_calibrate_dataset DATASET [RESULT_YAML]
// Prints T_base_lidar of every lidar (and its error when the dataset has a ground truth) and writes the
// result file (default: calibration.yaml in the working folder). What `scenecal calibrate` does, without
// its command-line options, uncertainty estimate and report.
//
// The libraries never print: progress comes through a callback, a failure as a status with the reason
// (the core) or an exception naming the file (io::InputError); this program decides what to show.
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>

#include <Eigen/Geometry>

#include "core/calibrator.hpp"
#include "core/geometry.hpp"
#include "io/calibration_input.hpp"
#include "io/dataset.hpp"

namespace {

// "x y z (m), roll pitch yaw (deg)" of a transform, in the file's 6-tuple convention (core/geometry.hpp).
std::string DescribeTransform(const Eigen::Isometry3d& T) {
  const scenecal::Vector6d xyz_rpy = scenecal::TupleFromTransform(T);
  char text[160];
  std::snprintf(text, sizeof(text), "x %.4f y %.4f z %.4f m, roll %.3f pitch %.3f yaw %.3f deg", xyz_rpy[0],
                xyz_rpy[1], xyz_rpy[2], scenecal::DegreesFromRadians(xyz_rpy[3]),
                scenecal::DegreesFromRadians(xyz_rpy[4]), scenecal::DegreesFromRadians(xyz_rpy[5]));
  return text;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || argc > 3) {
    std::fprintf(stderr, "usage: %s DATASET [RESULT_YAML]\n", argv[0]);
    return 2;
  }
  const std::filesystem::path dataset_path = argv[1];
  const std::filesystem::path result_path = argc == 3 ? argv[2] : "calibration.yaml";
  try {
    // Metadata and file lists only; images and scans are read on demand.
    const scenecal::io::Dataset dataset = scenecal::io::OpenDataset(dataset_path);

    const scenecal::CalibrationOptions options;  // defaults (core/calibrate.hpp)
    scenecal::CalibrationInput input;
    input.rig = dataset.rig;  // its T_base_lidar are the initial guesses
    // The scenes selected from the file times, and only the images and scans they use.
    scenecal::io::LoadCalibrationInput(dataset, options.scenes, &input);
    std::fprintf(stderr, "%s\n", input.selection.Report().c_str());

    // The pipeline: the pair costs are built once here, and Solve runs options.scheme (alt by default).
    scenecal::Calibrator calibrator(
        input, options, [](const std::string& message) { std::fprintf(stderr, "%s\n", message.c_str()); });
    const scenecal::CalibrationOutcome outcome = calibrator.Solve();
    if (outcome.status != scenecal::CalibrationStatus::kSuccess) {
      std::fprintf(stderr, "cannot calibrate: %s\n", outcome.why.c_str());
      return 1;
    }

    std::printf("%s\n", outcome.result.termination.c_str());
    for (const scenecal::LidarCalibration& lidar : outcome.result.lidars) {
      std::printf("lidar %s T_base_lidar: %s\n", lidar.lidar.c_str(), DescribeTransform(lidar.T_base_lidar).c_str());
      if (dataset.ground_truth && dataset.ground_truth->T_base_lidar.contains(lidar.lidar)) {
        const Eigen::Isometry3d& T_base_lidar_true = dataset.ground_truth->T_base_lidar.at(lidar.lidar);
        std::printf("lidar %s error: translation %.4f m, rotation %.3f deg\n", lidar.lidar.c_str(),
                    scenecal::TranslationError(lidar.T_base_lidar, T_base_lidar_true),
                    scenecal::RotationErrorDegrees(lidar.T_base_lidar, T_base_lidar_true));
      }
    }
    for (const std::string& warning : outcome.result.warnings) std::printf("warning: %s\n", warning.c_str());

    scenecal::io::WriteCalibrationResult(result_path, outcome.result);
    std::printf("wrote %s\n", result_path.string().c_str());
  } catch (const std::exception& error) {  // io::InputError names the file and the field
    std::fprintf(stderr, "error: %s\n", error.what());
    return 1;
  }
  return 0;
}
