// FORMAT.md version 1: reading and writing datasets. Every reader validates
// fully and throws InputError naming the file and the field.
#pragma once

#include <cstddef>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/calibration_result.hpp"
#include "core/rig.hpp"
#include "io/error.hpp"

namespace YAML {
class Node;  // yaml-cpp; include <yaml-cpp/yaml.h> to build one
}

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
// As WriteRig, plus a top-level `extra:` mapping (free for users, ignored by ReadRig).
void WriteRig(const std::filesystem::path& path, const Rig& rig, const YAML::Node& extra);
Trajectory ReadTrajectory(const std::filesystem::path& path);
void WriteTrajectory(const std::filesystem::path& path, const Trajectory& trajectory);
GroundTruth ReadGroundTruth(const std::filesystem::path& path);
void WriteGroundTruth(const std::filesystem::path& path, const GroundTruth& truth);

// The readers above on a file's content already in memory (the Read*
// functions read the file and call these); `name` stands for the file in
// messages.
Rig ParseRig(const std::string& text, const std::string& name);
Trajectory ParseTrajectory(const std::string& text, const std::string& name);
GroundTruth ParseGroundTruth(const std::string& text, const std::string& name);

// Most sensors a rig.yaml may name, per kind: far above any real rig, low
// enough that a corrupt or hostile file cannot make every later stage
// (folder listing, pairs, costs) explode.
inline constexpr std::size_t kMaxRigCameras = 64;
inline constexpr std::size_t kMaxRigLidars = 64;

// What ReadImage makes of a (colour) image: its grey level, or the excess
// green 2G - R - B mapped from [-2, 2] to [0, 1]. Vegetation reflects the
// lidar's near infrared strongly but is dark in grey; excess green shows it
// bright (measured on the OpenCalib frames, BENCHMARK.md).
enum class ImageChannel { kGrey, kExcessGreen };
bool ParseImageChannel(const std::string& name, ImageChannel* channel);  // "grey" | "exg"
const char* ImageChannelName(ImageChannel channel);

// Decodes an image, checks its size against the camera, converts it to the
// channel (colour to grey, or excess green: a grey image is then refused)
// and scales to [0, 1] (8- and 16-bit).
GreyImage ReadImage(const SensorFile& file, const CameraModel& camera, ImageChannel channel = ImageChannel::kGrey);
// Writes an 8-bit or 16-bit image (grey, or BGR/BGRA) as PNG, or 8-bit as JPEG
// (by extension). Scans and images are plain writes (no fsync: simulations write thousands).
void WriteImage(const std::filesystem::path& path, const cv::Mat& grey);

// (width, height) of a PNG or JPEG from its header only, without decoding
// (`inspect --quick`); nullopt when the header cannot be read.
std::optional<std::pair<int, int>> ImageFileSize(const std::filesystem::path& path);  // (width, height)

LidarScan ReadScan(const SensorFile& file);
// Records in a scan file (file size / 16) without reading it; InputError when
// the size is not a multiple of 16.
std::size_t ScanRecordCount(const SensorFile& file);
// A scan file's bytes as read by ReadScan; `name` stands for the file in messages.
LidarScan ParseScan(const std::string& bytes, const std::string& name, TimeUs t_us);
void WriteScan(const std::filesystem::path& path, const std::vector<LidarPoint>& points);

// Result file (FORMAT.md "Calibration result"), written atomically.
void WriteCalibrationResult(const std::filesystem::path& path, const CalibrationResult& result);
// As above, with more top-level keys appended after the standard ones (e.g. a
// per-iteration `history`). extra_keys must be a mapping (or null) whose keys
// do not repeat a standard key; std::invalid_argument otherwise.
void WriteCalibrationResult(const std::filesystem::path& path, const CalibrationResult& result,
                            const YAML::Node& extra_keys);
// The YAML text WriteCalibrationResult writes (extra_keys may be null).
std::string CalibrationResultToYaml(const CalibrationResult& result, const YAML::Node* extra_keys = nullptr);
CalibrationResult ReadCalibrationResult(const std::filesystem::path& path);
CalibrationResult ParseCalibrationResult(const std::string& text, const std::string& name);  // content in memory

// Sensor names: [A-Za-z0-9_-]+.
bool IsValidSensorName(const std::string& name);
// A data file's stem as an int64 timestamp (digits with an optional leading '-').
std::optional<TimeUs> ParseTimestamp(const std::string& text);

// Writes rig.yaml, trajectory.csv and ground_truth.yaml (if given) and creates
// cameras/<name>/ and lidars/<name>/ folders; the caller writes images and scans.
void WriteDatasetSkeleton(const std::filesystem::path& root, const Rig& rig, const Trajectory& trajectory,
                          const std::optional<GroundTruth>& truth);

// The scans of one lidar of a dataset (lidars/<lidar>/, sorted by time),
// checked as OpenDataset checks them, without needing trajectory.csv (for
// building one: `scenecal odometry`). InputError when the folder is missing,
// empty or holds anything else.
std::vector<SensorFile> ListLidarScans(const std::filesystem::path& root, const std::string& lidar);

}  // namespace scenecal::io
