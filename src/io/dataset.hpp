// FORMAT.md version 1: reading and writing datasets. Every reader validates
// fully and throws InputError naming the file and the field. The readers and
// writers of each file kind are in the headers included below; this header
// gathers them with the dataset as a whole.
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/calibration_result.hpp"
#include "core/rig.hpp"
#include "io/error.hpp"
#include "io/result_file.hpp"      // ground_truth.yaml, calibration result
#include "io/rig_file.hpp"         // rig.yaml
#include "io/sensor_files.hpp"     // sensor folders, images, scans
#include "io/trajectory_file.hpp"  // trajectory.csv

namespace scenecal::io {

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

// Writes rig.yaml, trajectory.csv and ground_truth.yaml (if given) and creates
// cameras/<name>/ and lidars/<name>/ folders; the caller writes images and scans.
void WriteDatasetSkeleton(const std::filesystem::path& root, const Rig& rig, const Trajectory& trajectory,
                          const std::optional<GroundTruth>& truth);

}  // namespace scenecal::io
