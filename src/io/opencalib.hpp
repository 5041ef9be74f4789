// Importer for OpenCalib single-frame lidar-camera data (PJLab-ADG
// SensorsCalibration, lidar2camera): a folder with calib.txt, calib.pcd and
// calib.jpg or calib.png, turned into a native static dataset (FORMAT.md).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/camera.hpp"
#include "io/error.hpp"

namespace scenecal::io {

// calib.txt: "K:" 9 numbers (row-major 3x3), "D:" 4 or 5 radtan numbers
// (k1 k2 p1 p2 [k3]), "T:" 12 numbers, row-major [R | t] = T_camera_lidar.
struct OpenCalibCalibration {
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels
  std::vector<double> distortion;          // k1 k2 p1 p2 [k3]
  Eigen::Isometry3d T_camera_lidar = Eigen::Isometry3d::Identity();
};

OpenCalibCalibration ReadOpenCalibCalibration(const std::filesystem::path& calib_txt);
// The same on calib.txt's content in memory; `name` stands for the file in messages.
OpenCalibCalibration ParseOpenCalibCalibration(const std::string& text, const std::string& name);

// The radtan camera calib.txt describes, for an image of width x height pixels.
CameraModel OpenCalibCameraModel(const OpenCalibCalibration& calibration, int width, int height);

struct OpenCalibImportSummary {
  std::filesystem::path dataset;
  int image_width = 0, image_height = 0;  // pixels
  std::size_t points = 0;                 // records written to the scan (incl. no-returns)
  std::size_t no_returns = 0;             // records with a non-finite value
};

// Writes the dataset to output (a temporary folder beside it, renamed at the
// end, so no partial dataset is ever left). A non-empty output is refused
// (InputError) unless overwrite is set. The dataset has one camera "camera"
// (radtan, size of the image), one lidar "lidar" (3d), base_frame camera, a
// one-row identity trajectory at t_us, the image copied unchanged as
// cameras/camera/<t_us>.<ext>, the scan as lidars/lidar/<t_us>.bin, rig
// T_base_lidar = ground truth = calib.txt's T.
OpenCalibImportSummary ImportOpenCalib(const std::filesystem::path& source_dir, const std::filesystem::path& output,
                                       bool overwrite, std::int64_t t_us = 0);

}  // namespace scenecal::io
