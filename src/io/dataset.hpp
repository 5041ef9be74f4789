// FORMAT.md version 1: reading and writing datasets. Every reader validates
// fully and throws InputError naming the file and the field.
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/calibration_result.hpp"
#include "core/rig.hpp"
#include "io/error.hpp"

namespace scenecal::io {

struct SensorFile {
  TimeUs t_us = 0;
  std::filesystem::path path;
};

// An opened dataset: metadata parsed and checked, file lists indexed by time.
// Image and scan contents are read on demand (ReadImage, ReadScan).
struct Dataset {
  std::filesystem::path root;
  Rig rig;
  Trajectory trajectory;
  std::map<std::string, std::vector<SensorFile>> images;  // by camera name, sorted by time
  std::map<std::string, std::vector<SensorFile>> scans;   // by lidar name, sorted by time
  std::optional<GroundTruth> ground_truth;
};

// Reads rig.yaml, trajectory.csv, ground_truth.yaml (if present) and lists
// cameras/<camera>/ and lidars/<lidar>/ (file names must be timestamps).
Dataset OpenDataset(const std::filesystem::path& root);

Rig ReadRig(const std::filesystem::path& path);
void WriteRig(const std::filesystem::path& path, const Rig& rig);
Trajectory ReadTrajectory(const std::filesystem::path& path);
void WriteTrajectory(const std::filesystem::path& path, const Trajectory& trajectory);
GroundTruth ReadGroundTruth(const std::filesystem::path& path);
void WriteGroundTruth(const std::filesystem::path& path, const GroundTruth& truth);

// Decodes an image, checks its size against the camera, converts colour to
// grey and scales to [0, 1] (8- and 16-bit).
GreyImage ReadImage(const SensorFile& file, const CameraModel& camera);
// Writes an 8-bit or 16-bit single-channel image as PNG (or JPEG by extension).
void WriteImage(const std::filesystem::path& path, const cv::Mat& grey);

LidarScan ReadScan(const SensorFile& file);
void WriteScan(const std::filesystem::path& path, const std::vector<LidarPoint>& points);

// Result file (FORMAT.md "Calibration result"), written atomically.
void WriteCalibrationResult(const std::filesystem::path& path, const CalibrationResult& result);
CalibrationResult ReadCalibrationResult(const std::filesystem::path& path);

// Writes rig.yaml, trajectory.csv and ground_truth.yaml (if given) and creates
// cameras/<name>/ and lidars/<name>/ folders; the caller writes images and scans.
void WriteDatasetSkeleton(const std::filesystem::path& root, const Rig& rig, const Trajectory& trajectory,
                          const std::optional<GroundTruth>& truth);

}  // namespace scenecal::io
