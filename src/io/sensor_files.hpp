// The sensor data of a dataset (FORMAT.md): the folders cameras/<camera>/ and
// lidars/<lidar>/ of files named by their timestamp, the images (PNG, JPEG)
// and the scans (.bin records of float32 x, y, z, reflectance). The readers
// validate fully and throw InputError naming the file and the problem.
#pragma once

#include <cstddef>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "core/camera.hpp"
#include "core/enum_names.hpp"
#include "core/rig.hpp"
#include "io/error.hpp"

namespace scenecal::io {

struct SensorFile {
  TimeUs t_us = 0;
  std::filesystem::path path;
};

// A data file's stem as an int64 timestamp (digits with an optional leading '-').
std::optional<TimeUs> ParseTimestamp(const std::string& text);

// The scans of one lidar of a dataset (lidars/<lidar>/, sorted by time),
// checked as OpenDataset checks them, without needing trajectory.csv (for
// building one: `scenecal odometry`). InputError when the folder is missing,
// empty or holds anything else.
std::vector<SensorFile> ListLidarScans(const std::filesystem::path& root, const std::string& lidar);

// ---- images ----

// What ReadImage makes of a (colour) image: its grey level, or the excess
// green 2G - R - B mapped from [-2, 2] to [0, 1]. Vegetation reflects the
// lidar's near infrared strongly but is dark in grey; excess green shows it
// bright (measured on the OpenCalib frames, BENCHMARK.md).
enum class ImageChannel { kGrey, kExcessGreen };
inline constexpr auto kImageChannelNames =
    MakeEnumNames<ImageChannel>({{ImageChannel::kGrey, "grey"}, {ImageChannel::kExcessGreen, "exg"}});
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

// ---- scans ----

LidarScan ReadScan(const SensorFile& file);
// Records in a scan file (file size / 16) without reading it; InputError when
// the size is not a multiple of 16.
std::size_t ScanRecordCount(const SensorFile& file);
// A scan file's bytes as read by ReadScan; `name` stands for the file in messages.
LidarScan ParseScan(const std::string& bytes, const std::string& name, TimeUs t_us);
void WriteScan(const std::filesystem::path& path, const std::vector<LidarPoint>& points);

namespace detail {

// Internal to io (OpenDataset, ListLidarScans). FORMAT.md's sensor-folder
// rule: every sensor named has its folder <root>/<folder>/<sensor>/ holding at
// least one data file (images or .bin scans named by timestamp), and nothing
// else is in <root>/<folder>/. The files of each sensor, sorted by time.
// sensor_word ("camera", "lidar") names the kind in messages.
std::map<std::string, std::vector<SensorFile>> ListSensorFolders(const std::filesystem::path& root,
                                                                 const std::string& folder,
                                                                 const std::set<std::string>& sensors, bool images,
                                                                 const std::string& sensor_word);

}  // namespace detail

}  // namespace scenecal::io
