#include "io/kitti.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <yaml-cpp/yaml.h>

#include "core/geometry.hpp"
#include "core/interrupt.hpp"
#include "io/dataset.hpp"
#include "io/staged_output.hpp"
#include "io/yaml_fields.hpp"

namespace scenecal::io {

namespace fs = std::filesystem;
using detail::Fail;

namespace {

constexpr const char* kCamToCam = "calib_cam_to_cam.txt";
constexpr const char* kVeloToCam = "calib_velo_to_cam.txt";
constexpr const char* kImuToVelo = "calib_imu_to_velo.txt";
constexpr const char* kLidarName = "velodyne";
constexpr std::size_t kOxtsValues = 30;     // lat lon alt roll pitch yaw vn ve vf vl vu ax ... (devkit dataformat.txt)
constexpr double kEarthRadius = 6378137.0;  // m, the devkit's Mercator sphere (WGS84 equatorial radius)
constexpr std::size_t kMaxTextBytes = 64u << 20;
// Without timestamps.txt: frame k at k x 100 ms (KITTI's nominal 10 Hz).
constexpr TimeUs kSyntheticFramePeriodUs = 100'000;
constexpr std::size_t kMaxFramesWithoutTimestamps = 10'000'000;

std::string Trim(std::string_view text) {
  const std::size_t begin = text.find_first_not_of(" \t\r\n");
  if (begin == std::string_view::npos) return {};
  const std::size_t end = text.find_last_not_of(" \t\r\n");
  return std::string(text.substr(begin, end - begin + 1));
}

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream stream(text);
  for (std::string line; std::getline(stream, line);) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    lines.push_back(std::move(line));
  }
  return lines;
}

std::string Shorten(const std::string& text) { return text.size() > 40 ? text.substr(0, 40) + "..." : text; }

bool ParseDouble(const std::string& token, double* value) {
  return detail::ParseWholeToken(token, value) && std::isfinite(*value);
}

// ---- calibration files: "KEY: values" lines ---------------------------------

struct KeyLine {
  int line = 0;
  std::string values;
};

class KeyValueFile {
 public:
  explicit KeyValueFile(const fs::path& path) : KeyValueFile(detail::ReadTextFile(path, 1 << 20), path.string()) {}

  KeyValueFile(const std::string& text, std::string name) : file_(std::move(name)) {
    const std::vector<std::string> lines = Lines(text);
    for (std::size_t i = 0; i < lines.size(); ++i) {
      const int number = static_cast<int>(i) + 1;
      if (Trim(lines[i]).empty()) continue;
      const std::size_t colon = lines[i].find(':');
      const std::string where = fmt::format("line {}", number);
      if (colon == std::string::npos) Fail(file_, where, "'" + Shorten(lines[i]) + "'", "'KEY: values'");
      const std::string key = Trim(std::string_view(lines[i]).substr(0, colon));
      if (key.empty()) Fail(file_, where, "no key before ':'", "'KEY: values'");
      if (entries_.count(key) != 0) {
        Fail(file_, where + " " + key, fmt::format("given twice (also line {})", entries_[key].line), "each key once");
      }
      entries_[key] = {number, lines[i].substr(colon + 1)};
    }
  }

  const std::string& file() const { return file_; }

  // The `count` numbers of `key` (description: what they are).
  std::vector<double> Numbers(const std::string& key, std::size_t count, const std::string& description) const {
    const std::string expected = fmt::format("{} numbers ({})", count, description);
    const auto entry = entries_.find(key);
    if (entry == entries_.end()) Fail(file_, key, "missing", "a line '" + key + ": ' with " + expected);
    const std::string where = fmt::format("line {} {}", entry->second.line, key);
    std::vector<double> values;
    std::istringstream tokens(entry->second.values);
    for (std::string token; tokens >> token;) {
      double value = 0;
      if (!ParseDouble(token, &value)) Fail(file_, where, "'" + Shorten(token) + "'", "finite numbers: " + expected);
      values.push_back(value);
    }
    if (values.size() != count) Fail(file_, where, fmt::format("{} numbers", values.size()), expected);
    return values;
  }

  // A 3x3 rotation from 9 row-major numbers. KITTI prints about 7 significant
  // digits, so R is orthonormal only to ~1e-6: accept 1e-3 and snap to the
  // nearest rotation (SVD), as the OpenCalib importer does.
  Eigen::Matrix3d Rotation(const std::string& key, const std::string& description) const {
    const std::vector<double> values = Numbers(key, 9, description);
    Eigen::Matrix4d matrix = Eigen::Matrix4d::Identity();
    for (int row = 0; row < 3; ++row) {
      for (int col = 0; col < 3; ++col) matrix(row, col) = values[static_cast<std::size_t>(row * 3 + col)];
    }
    if (!IsRigid(matrix, 1e-3)) {
      Fail(file_, fmt::format("line {} {}", entries_.at(key).line, key), "not a rotation matrix",
           "a row-major 3x3 rotation (orthonormal, det +1)");
    }
    return NearestRotation(matrix.topLeftCorner<3, 3>());
  }

  int Line(const std::string& key) const { return entries_.at(key).line; }

 private:
  std::string file_;
  std::map<std::string, KeyLine> entries_;
};

// calib_*.txt lives in the date folder (the drive's parent); also accepted in the drive folder.
fs::path FindCalibrationFile(const fs::path& drive_dir, const char* name) {
  std::error_code error;
  const fs::path beside = drive_dir.parent_path() / name;
  if (fs::is_regular_file(beside, error)) return beside;
  const fs::path inside = drive_dir / name;
  if (fs::is_regular_file(inside, error)) return inside;
  Fail(beside.string(), "calibration", fmt::format("missing (nor in the drive folder {})", drive_dir.string()),
       std::string(name) + " in the date folder above the drive (or in the drive folder)");
}

Eigen::Isometry3d ReadRigidTransform(const fs::path& path, const std::string& what) {
  return ParseKittiRigidTransform(detail::ReadTextFile(path, 1 << 20), path.string(), what);
}

// ---- sensor folders: timestamps.txt + data/<10 digits>.<ext> ------------------

struct SensorSeries {
  std::string folder;     // e.g. image_02, velodyne_points, oxts
  std::string extension;  // .png, .bin, .txt
  fs::path directory;     // drive/folder
  fs::path timestamps_file;
  std::vector<std::optional<TimeUs>> times;  // per frame; nullopt: an empty line (data lost)
  bool without_timestamps = false;            // no timestamps.txt: times by frame index at 10 Hz

  fs::path DataFile(std::size_t frame) const { return directory / "data" / fmt::format("{:010d}{}", frame, extension); }
};

SensorSeries ReadSensorSeries(const fs::path& drive_dir, const std::string& folder, const std::string& extension,
                              const std::string& content) {
  SensorSeries series;
  series.folder = folder;
  series.extension = extension;
  series.directory = drive_dir / folder;
  series.timestamps_file = series.directory / "timestamps.txt";
  std::error_code error;
  const std::string layout =
      folder + "/timestamps.txt and " + folder + "/data/0000000000" + extension + " ... (" + content + ")";
  if (!fs::is_directory(series.directory, error)) Fail(series.directory.string(), "folder", "missing", layout);
  const fs::path data_dir = series.directory / "data";
  if (!fs::is_directory(data_dir, error)) Fail(data_dir.string(), "folder", "missing", layout);

  const std::string file = series.timestamps_file.string();
  if (!fs::exists(series.timestamps_file, error)) {
    // Frames by the data files' indices, at KITTI's nominal 10 Hz.
    series.without_timestamps = true;
    for (const fs::directory_entry& entry : fs::directory_iterator(data_dir)) {
      ThrowIfInterrupted();
      const std::string stem = entry.path().stem().string();
      std::size_t index = 0;
      if (!entry.is_regular_file(error) || entry.path().extension() != extension || stem.size() != 10 ||
          !detail::ParseWholeToken(stem, &index) || index > kMaxFramesWithoutTimestamps) {
        Fail(entry.path().string(), "data file", "'" + entry.path().filename().string() + "'",
             fmt::format("data files named by frame index, 0000000000{} ... (no timestamps.txt)", extension));
      }
      if (index >= series.times.size()) series.times.resize(index + 1);
      series.times[index] = static_cast<TimeUs>(index) * kSyntheticFramePeriodUs;
    }
    return series;
  }
  series.times = ParseKittiTimestamps(detail::ReadTextFile(series.timestamps_file, kMaxTextBytes), file);
  const std::size_t with_time = static_cast<std::size_t>(
      std::count_if(series.times.begin(), series.times.end(), [](const auto& t) { return t.has_value(); }));

  // Every line with a time has its data file, and there are no others.
  std::size_t files = 0;
  for (const fs::directory_entry& entry : fs::directory_iterator(data_dir)) {
    if (entry.is_regular_file(error) && entry.path().extension() == extension) ++files;
  }
  if (files != with_time) {
    Fail(data_dir.string(), "data files",
         fmt::format("{} {} files for {} timestamps ({} lines in {})", files, extension, with_time,
                     series.times.size(), file),
         "one data file per non-empty line of timestamps.txt");
  }
  for (std::size_t i = 0; i < series.times.size(); ++i) {
    if (series.times[i] && !fs::is_regular_file(series.DataFile(i), error)) {
      Fail(series.DataFile(i).string(), "data file", fmt::format("missing (line {} of {} has a time)", i + 1, file),
           fmt::format("data files named by frame index, {:010d}{} for line {}", i, extension, i + 1));
    }
  }
  return series;
}

// ---- OXTS -------------------------------------------------------------------------

using OxtsRecord = KittiOxtsRecord;

OxtsRecord ReadOxts(const fs::path& path) { return ParseKittiOxts(detail::ReadTextFile(path, 1 << 20), path.string()); }

// The devkit's conversion (convertOxtsToPose): Mercator with the scale of
// latitude lat0 (degrees), rotation Rz(yaw) * Ry(pitch) * Rx(roll). Returns
// T_world_imu (world x east, y north, z up; metres) before the origin shift.
Eigen::Isometry3d ImuPoseFromOxts(const OxtsRecord& record, double lat0) {
  const double scale = std::cos(lat0 * kPi / 180.0);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() =
      Eigen::Vector3d(scale * kEarthRadius * record.lon * kPi / 180.0,
                      scale * kEarthRadius * std::log(std::tan((90.0 + record.lat) * kPi / 360.0)), record.alt);
  pose.linear() = RotationFromRollPitchYaw(record.roll, record.pitch, record.yaw);
  return pose;
}

std::string CameraName(int index) { return fmt::format("image_{:02d}", index); }

}  // namespace

// ---- the drive's text files, in memory ------------------------------------------------

Eigen::Isometry3d ParseKittiRigidTransform(const std::string& text, const std::string& name, const std::string& what) {
  const KeyValueFile file(text, name);
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  transform.linear() = file.Rotation("R", "row-major rotation, " + what);
  const std::vector<double> t = file.Numbers("T", 3, "translation in metres, " + what);
  transform.translation() = Eigen::Vector3d(t[0], t[1], t[2]);
  return transform;
}

KittiOxtsRecord ParseKittiOxts(const std::string& text, const std::string& file) {
  static const char* const kNames[] = {"lat", "lon", "alt", "roll", "pitch", "yaw"};
  std::istringstream tokens(text);
  std::vector<double> values;


  for (std::string token; tokens >> token;) {
    double value = 0;
    const std::string field = values.size() < 6 ? fmt::format("value {} ({})", values.size() + 1, kNames[values.size()])
                                                : fmt::format("value {}", values.size() + 1);
    if (!ParseDouble(token, &value)) Fail(file, field, "'" + Shorten(token) + "'", "a finite number");
    values.push_back(value);
  }
  if (values.size() != kOxtsValues) {
    Fail(file, "record", fmt::format("{} numbers", values.size()),
         fmt::format("{} numbers (lat lon alt roll pitch yaw ... of the KITTI OXTS format)", kOxtsValues));
  }
  KittiOxtsRecord record{values[0], values[1], values[2], values[3], values[4], values[5]};
  if (!(std::abs(record.lat) < 90.0))
    Fail(file, "value 1 (lat)", fmt::format("{}", record.lat), "a latitude in (-90, 90) degrees");
  if (!(std::abs(record.lon) <= 180.0))
    Fail(file, "value 2 (lon)", fmt::format("{}", record.lon), "a longitude in [-180, 180] degrees");
  return record;
}

std::vector<std::optional<TimeUs>> ParseKittiTimestamps(const std::string& text, const std::string& file) {
  const std::vector<std::string> lines = Lines(text);
  std::vector<std::optional<TimeUs>> times;
  std::optional<std::size_t> previous;  // index of the last line with a time
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const std::string line = Trim(lines[i]);
    if (line.empty()) {
      times.push_back(std::nullopt);
      continue;
    }
    const std::optional<TimeUs> t_us = ParseKittiTimestamp(line);
    const std::string where = fmt::format("line {}", i + 1);
    if (!t_us) {
      Fail(file, where, "'" + Shorten(line) + "'",
           "a time 'YYYY-MM-DD HH:MM:SS.fffffffff' (UTC, year 1970..2200) or an empty line for a lost frame");
    }
    if (previous && *t_us <= *times[*previous]) {
      Fail(file, where, fmt::format("time {} us is not after line {} ({} us)", *t_us, *previous + 1, *times[*previous]),
           "strictly increasing times (microseconds)");
    }
    previous = i;
    times.push_back(t_us);
  }
  return times;
}

// ---- timestamps ---------------------------------------------------------------------

std::optional<TimeUs> ParseKittiTimestamp(std::string_view text) {
  // YYYY-MM-DD HH:MM:SS[.f{1,9}]
  if (text.size() < 19 || text.size() == 20 || text.size() > 29) return std::nullopt;
  const auto digits = [&](std::size_t at, std::size_t count, int* value) {
    *value = 0;
    for (std::size_t i = at; i < at + count; ++i) {
      if (text[i] < '0' || text[i] > '9') return false;
      *value = *value * 10 + (text[i] - '0');
    }
    return true;
  };
  int year = 0, month = 0, day = 0, hour = 0, minute = 0, second = 0;
  if (!digits(0, 4, &year) || text[4] != '-' || !digits(5, 2, &month) || text[7] != '-' || !digits(8, 2, &day) ||
      text[10] != ' ' || !digits(11, 2, &hour) || text[13] != ':' || !digits(14, 2, &minute) || text[16] != ':' ||
      !digits(17, 2, &second)) {
    return std::nullopt;
  }
  std::int64_t fraction_ns = 0;
  if (text.size() > 19) {
    if (text[19] != '.') return std::nullopt;
    int digit = 0;
    std::int64_t scale = 100000000;
    for (std::size_t i = 20; i < text.size(); ++i, scale /= 10) {
      if (!digits(i, 1, &digit)) return std::nullopt;
      fraction_ns += digit * scale;
    }
  }
  // Years 1970..2200 keep nanoseconds since the epoch positive and inside int64.
  if (year < 1970 || year > 2200 || hour > 23 || minute > 59 || second > 59) return std::nullopt;
  const std::chrono::year_month_day date{std::chrono::year{year}, std::chrono::month{static_cast<unsigned>(month)},
                                         std::chrono::day{static_cast<unsigned>(day)}};
  if (!date.ok()) return std::nullopt;
  const std::int64_t days = std::chrono::sys_days(date).time_since_epoch().count();
  const std::int64_t seconds = ((days * 24 + hour) * 60 + minute) * 60 + second;
  const std::int64_t ns = seconds * 1000000000 + fraction_ns;
  return (ns + 500) / 1000;  // nearest microsecond
}

// ---- calibration ----------------------------------------------------------------------

KittiCalibration ReadKittiCalibration(const fs::path& drive_dir_in, const std::vector<int>& cameras) {
  for (const int index : cameras) {
    if (index < 0 || index > 3) throw std::invalid_argument(fmt::format("KITTI camera index {} is not 0..3", index));
  }
  fs::path drive_dir = fs::absolute(drive_dir_in).lexically_normal();
  if (!drive_dir.has_filename()) drive_dir = drive_dir.parent_path();  // "drive/": its parent is the date folder
  KittiCalibration calibration;
  const fs::path cam_to_cam = FindCalibrationFile(drive_dir, kCamToCam);
  const fs::path velo_to_cam = FindCalibrationFile(drive_dir, kVeloToCam);
  const fs::path imu_to_velo = FindCalibrationFile(drive_dir, kImuToVelo);
  calibration.directory = cam_to_cam.parent_path();
  ParseKittiCamToCam(detail::ReadTextFile(cam_to_cam, 1 << 20), cam_to_cam.string(), cameras, &calibration);
  calibration.T_cam0_velo = ReadRigidTransform(velo_to_cam, "velodyne to unrectified camera 0");
  calibration.T_velo_imu = ReadRigidTransform(imu_to_velo, "IMU (OXTS) to velodyne");
  return calibration;
}

void ParseKittiCamToCam(const std::string& text, const std::string& name, const std::vector<int>& cameras,
                        KittiCalibration* calibration) {
  for (const int index : cameras) {
    if (index < 0 || index > 3) throw std::invalid_argument(fmt::format("KITTI camera index {} is not 0..3", index));
  }
  const KeyValueFile cams(text, name);
  calibration->R_rect_00 = cams.Rotation("R_rect_00", "row-major rotation, unrectified to rectified camera 0");
  for (const int index : cameras) {
    const std::string key = fmt::format("P_rect_{:02d}", index);
    const std::vector<double> p =
        cams.Numbers(key, 12, "row-major 3x4 projection of rectified camera " + CameraName(index));
    Eigen::Matrix<double, 3, 4> matrix;
    for (int row = 0; row < 3; ++row) {
      for (int col = 0; col < 4; ++col) matrix(row, col) = p[static_cast<std::size_t>(row * 4 + col)];
    }
    // Rectified cameras share one image plane: the left 3x3 block is a camera
    // matrix K without skew; anything else is not a KITTI rectified projection.
    if (matrix(0, 1) != 0 || matrix(1, 0) != 0 || matrix(2, 0) != 0 || matrix(2, 1) != 0 || matrix(2, 2) != 1 ||
        !(matrix(0, 0) > 0) || !(matrix(1, 1) > 0)) {
      Fail(cams.file(), fmt::format("line {} {}", cams.Line(key), key),
           "left 3x3 block not of the form fx 0 cx; 0 fy cy; 0 0 1",
           "a rectified projection [K | K t] with K = [fx 0 cx; 0 fy cy; 0 0 1], fx, fy > 0");
    }
    calibration->P_rect[static_cast<std::size_t>(index)] = matrix;
  }
}

bool KittiImportOptions::IsValid(std::string* why) const {
  const auto fail = [why](const std::string& reason) {
    if (why != nullptr) *why = reason;
    return false;
  };
  std::set<int> seen;
  for (const int index : cameras) {
    if (index < 0 || index > 3) return fail(fmt::format("camera index {} is not 0..3 (image_00..image_03)", index));
    if (!seen.insert(index).second) return fail(fmt::format("camera index {} given twice", index));
  }
  if (count && *count == 0) return fail("frame count 0: at least one frame is needed");
  return true;
}

// ---- import ---------------------------------------------------------------------------

namespace {

// The cameras to import (indices 0..3): as asked, or every image_0i folder present; sorted.
std::vector<int> ChooseCameras(const fs::path& drive_dir, std::vector<int> cameras, const std::string& layout_hint) {
  std::error_code error;
  if (cameras.empty()) {
    for (int index = 0; index < 4; ++index) {
      if (fs::is_directory(drive_dir / CameraName(index), error)) cameras.push_back(index);
    }
    if (cameras.empty()) {
      // A common slip: the date folder given instead of the drive inside it.
      std::string what = "no image_00 .. image_03 folder";
      for (const fs::directory_entry& entry : fs::directory_iterator(drive_dir, error)) {
        const std::string name = entry.path().filename().string();
        if (entry.is_directory(error) && name.size() > 5 && name.ends_with("_sync")) {
          what += " (a date folder? it holds the drive " + name + ")";
          break;
        }
      }
      Fail(drive_dir.string(), "cameras", what, layout_hint);
    }
  }
  std::sort(cameras.begin(), cameras.end());
  return cameras;
}

// The drive's sensor folders, on one clock and with one entry per frame each.
struct DriveSeries {
  std::optional<SensorSeries> oxts;  // none: no oxts/, the trajectory comes from the scans
  SensorSeries velodyne;
  std::vector<SensorSeries> images;  // one per imported camera, in the order of the camera indices
  bool synthetic_times = false;      // a folder lacks timestamps.txt: every sensor at 10 Hz by frame index
  std::size_t frames = 0;            // frames of the drive
};

DriveSeries ReadDriveSeries(const fs::path& drive_dir, const std::vector<int>& cameras,
                            const KittiImportOptions& options, std::vector<std::string>* without_timestamps) {
  std::error_code error;
  // Without oxts/ the trajectory comes from the scans (options.trajectory_from_scans).
  const bool have_oxts = fs::exists(drive_dir / "oxts", error);
  if (!have_oxts && !options.trajectory_from_scans) {
    Fail((drive_dir / "oxts").string(), "folder", "missing", "oxts/ with the GPS/IMU records (the trajectory)");
  }
  DriveSeries drive;
  if (have_oxts) drive.oxts = ReadSensorSeries(drive_dir, "oxts", ".txt", "OXTS GPS/IMU records");
  drive.velodyne = ReadSensorSeries(drive_dir, "velodyne_points", ".bin", "velodyne scans");
  for (const int index : cameras) {
    drive.images.push_back(ReadSensorSeries(drive_dir, CameraName(index), ".png", "rectified PNG images"));
  }
  std::vector<SensorSeries*> all{&drive.velodyne};
  if (drive.oxts) all.push_back(&*drive.oxts);
  for (SensorSeries& camera : drive.images) all.push_back(&camera);
  // One clock for all: if any folder lacks timestamps.txt, every sensor takes
  // its frame index at 10 Hz (a lost frame, an empty line, stays lost).
  drive.synthetic_times =
      std::any_of(all.begin(), all.end(), [](const SensorSeries* series) { return series->without_timestamps; });
  for (SensorSeries* series : all) {
    if (series->without_timestamps) without_timestamps->push_back(series->folder);
    if (!drive.synthetic_times) continue;
    for (std::size_t k = 0; k < series->times.size(); ++k) {
      if (series->times[k]) series->times[k] = static_cast<TimeUs>(k) * kSyntheticFramePeriodUs;
    }
  }
  // A synced drive numbers the frames of every sensor alike (a lost frame
  // keeps its empty line), so the line counts agree. Without timestamps.txt a
  // folder's count is its highest frame index (a lost last frame cannot show).
  const SensorSeries& reference = drive.oxts ? *drive.oxts : drive.velodyne;
  drive.frames = reference.times.size();
  if (drive.frames == 0) {
    Fail(reference.timestamps_file.string(), "frames", "none (empty file)", "at least one frame: an empty drive");
  }
  for (SensorSeries* series : all) {
    const bool may_be_short = series->without_timestamps && series->times.size() < drive.frames;
    if (series->times.size() != drive.frames && !may_be_short) {
      Fail(series->timestamps_file.string(), "lines",
           fmt::format("{} lines, but {} has {}", series->times.size(), reference.timestamps_file.string(),
                       drive.frames),
           "as many lines as every other sensor of the synced drive (one per frame)");
    }
    series->times.resize(drive.frames);
  }
  return drive;
}

// The frames imported: [first, end).
struct FrameRange {
  std::size_t first = 0;
  std::size_t end = 0;  // one past the last frame imported
};

FrameRange SelectFrames(const fs::path& drive_dir, const KittiImportOptions& options, std::size_t frames) {
  const std::size_t first = options.first;
  const std::size_t count = options.count.value_or(first < frames ? frames - first : 0);
  if (first >= frames || count > frames - first) {
    Fail(drive_dir.string(), "--first/--count",
         fmt::format("frames {}..{} asked for", first, first + std::max<std::size_t>(count, 1) - 1),
         fmt::format("frames within 0..{} (the drive has {})", frames - 1, frames));
  }
  return {first, first + count};
}

// The rig's extrinsics from the calibration files (the conventions of ImportKitti, kitti.hpp).
struct DriveExtrinsics {
  std::array<Eigen::Vector3d, 4> t_cami_cam0;  // metres, by camera index (the imported cameras only)
  Eigen::Isometry3d T_base_velo;
  Eigen::Isometry3d T_imu_base;
};

DriveExtrinsics ComputeExtrinsics(const KittiCalibration& calibration, const std::vector<int>& cameras) {
  DriveExtrinsics extrinsics;
  // Rectified camera i: T_cami_cam0 = [I | K_i^-1 * P_rect_0i(:, 3)].
  for (const int index : cameras) {
    const Eigen::Matrix<double, 3, 4>& p = *calibration.P_rect[static_cast<std::size_t>(index)];
    extrinsics.t_cami_cam0[static_cast<std::size_t>(index)] = p.leftCols<3>().inverse() * p.col(3);
  }
  const int base_index = cameras.front();
  Eigen::Isometry3d T_base_cam0rect = Eigen::Isometry3d::Identity();
  T_base_cam0rect.translation() = extrinsics.t_cami_cam0[static_cast<std::size_t>(base_index)];
  Eigen::Isometry3d R_rect = Eigen::Isometry3d::Identity();  // unrectified -> rectified camera 0
  R_rect.linear() = calibration.R_rect_00;
  const Eigen::Isometry3d T_cam0rect_velo = R_rect * calibration.T_cam0_velo;
  extrinsics.T_base_velo = T_base_cam0rect * T_cam0rect_velo;
  extrinsics.T_imu_base = (extrinsics.T_base_velo * calibration.T_velo_imu).inverse();
  return extrinsics;
}

// Camera image_0i of the rig, and its image files in the frame range (frames
// without a time are counted in *lost). The first image is decoded and every
// other one's header must give the same size.
CameraInfo ImportCamera(const SensorSeries& series, int index, int base_index, const KittiCalibration& calibration,
                        const DriveExtrinsics& extrinsics, FrameRange range, std::vector<SensorFile>* files,
                        std::size_t* lost) {
  for (std::size_t frame = range.first; frame < range.end; ++frame) {
    if (series.times[frame])
      files->push_back({*series.times[frame], series.DataFile(frame)});
    else
      ++*lost;
  }
  if (files->empty()) {
    Fail(series.timestamps_file.string(), "frames",
         fmt::format("no image in frames {}..{}", range.first, range.end - 1), "at least one image per camera");
  }
  const fs::path& first_image = files->front().path;
  const auto size = ImageFileSize(first_image);
  if (!size) Fail(first_image.string(), "image", "not a readable PNG header", "a PNG image");
  CameraInfo camera;
  camera.name = CameraName(index);
  const Eigen::Matrix<double, 3, 4>& p = *calibration.P_rect[static_cast<std::size_t>(index)];
  camera.model.width = size->first;
  camera.model.height = size->second;
  camera.model.kind = CameraModelKind::kPinhole;  // rectified: no distortion
  camera.model.fx = p(0, 0);
  camera.model.fy = p(1, 1);
  camera.model.cx = p(0, 2);
  camera.model.cy = p(1, 2);
  std::string why;
  if (!camera.model.IsValid(&why)) {
    Fail((calibration.directory / kCamToCam).string(), fmt::format("P_rect_{:02d}", index), "invalid camera: " + why,
         "a valid pinhole camera");
  }
  // T_base_cami = T_camb_cam0 * T_cami_cam0^-1: translations only.
  camera.T_base_camera.translation() = extrinsics.t_cami_cam0[static_cast<std::size_t>(base_index)] -
                                       extrinsics.t_cami_cam0[static_cast<std::size_t>(index)];
  ReadImage(files->front(), camera.model);  // decodes it: a corrupt image fails here
  for (const SensorFile& file : *files) {   // headers only: sizes must agree
    ThrowIfInterrupted();
    const auto other = ImageFileSize(file.path);
    if (!other) Fail(file.path.string(), "image", "not a readable PNG header", "a PNG image");
    if (*other != *size) {
      Fail(file.path.string(), "image size", fmt::format("{} x {} pixels", other->first, other->second),
           fmt::format("{} x {} pixels as the first image {}", size->first, size->second, first_image.string()));
    }
  }
  return camera;
}

// The velodyne scans in the frame range (frames without a time are counted in
// *lost), each of a valid size.
std::vector<SensorFile> ScanFilesInRange(const SensorSeries& velodyne, FrameRange range, std::size_t* lost) {
  std::vector<SensorFile> scan_files;
  for (std::size_t frame = range.first; frame < range.end; ++frame) {
    if (velodyne.times[frame])
      scan_files.push_back({*velodyne.times[frame], velodyne.DataFile(frame)});
    else
      ++*lost;
  }
  if (scan_files.empty()) {
    Fail(velodyne.timestamps_file.string(), "frames",
         fmt::format("no scan in frames {}..{}", range.first, range.end - 1), "at least one velodyne scan");
  }
  for (const SensorFile& file : scan_files) ScanRecordCount(file);  // size a multiple of 16
  return scan_files;
}

// T_world_base at the OXTS records of the frame range plus one neighbouring
// record on each side (frames of the range without a time are counted in *lost).
Trajectory OxtsTrajectory(const SensorSeries& oxts, std::size_t frames, FrameRange range,
                          const Eigen::Isometry3d& T_imu_base, std::size_t* lost) {
  const std::optional<std::size_t> first_record = [&]() -> std::optional<std::size_t> {
    for (std::size_t frame = 0; frame < frames; ++frame) {
      if (oxts.times[frame]) return frame;
    }
    return std::nullopt;
  }();
  if (!first_record) Fail(oxts.timestamps_file.string(), "frames", "no line with a time", "at least one OXTS record");
  const double lat0 = ReadOxts(oxts.DataFile(*first_record)).lat;  // the devkit's scale: the drive's first record
  std::vector<TimeUs> pose_times;
  std::vector<Eigen::Isometry3d> T_world_imu;
  const std::size_t from = range.first > 0 ? range.first - 1 : 0;
  const std::size_t to = std::min(range.end + 1, frames);
  for (std::size_t frame = from; frame < to; ++frame) {
    if (!oxts.times[frame]) {
      if (frame >= range.first && frame < range.end) ++*lost;
      continue;
    }
    pose_times.push_back(*oxts.times[frame]);
    T_world_imu.push_back(ImuPoseFromOxts(ReadOxts(oxts.DataFile(frame)), lat0));
  }
  if (pose_times.empty()) {
    Fail(oxts.timestamps_file.string(), "frames", fmt::format("no OXTS record in frames {}..{}", from, to - 1),
         "at least one OXTS record in the range");
  }
  // Mercator coordinates are ~1e6 m: move the origin to the first record so
  // the numbers in trajectory.csv stay small (the rotation is untouched).
  const Eigen::Vector3d origin = T_world_imu.front().translation();
  std::vector<Eigen::Isometry3d> T_world_base;
  for (Eigen::Isometry3d pose : T_world_imu) {
    pose.translation() -= origin;
    T_world_base.push_back(pose * T_imu_base);
  }
  return Trajectory(std::move(pose_times), std::move(T_world_base));
}

// No GPS/IMU: the caller's trajectory from the scans (lidar odometry).
Trajectory TrajectoryFromScans(const fs::path& drive_dir, const std::vector<SensorFile>& scan_files,
                               const Eigen::Isometry3d& T_base_velo, const KittiImportOptions& options) {
  Trajectory from_scans = options.trajectory_from_scans(scan_files, T_base_velo);
  if (from_scans.size() < 2) {
    Fail((drive_dir / "velodyne_points").string(), "trajectory", "none could be made from the scans",
         "a trajectory from the velodyne scans (no oxts/)");
  }
  return from_scans;
}

// rig.yaml's `extra:`: where the dataset came from and how it was converted.
YAML::Node ImportNotes(const fs::path& drive_dir, const KittiCalibration& calibration, FrameRange range,
                       const DriveSeries& drive, const std::vector<std::string>& without_timestamps) {
  YAML::Node extra;
  extra["source"] = "kitti";
  extra["source_dir"] = drive_dir.string();
  extra["calibration_dir"] = calibration.directory.string();
  extra["frames"].push_back(range.first);
  extra["frames"].push_back(range.end - 1);
  extra["frames"].SetStyle(YAML::EmitterStyle::Flow);
  extra["cameras"] =
      "rectified KITTI cameras: pinhole from P_rect_0i, T_base_camera from P_rect_0i's last column (translation only)";
  extra["trajectory"] =
      drive.oxts
          ? "OXTS poses by the devkit's Mercator conversion (scale from the drive's first record), world x east, "
            "y north, z up, origin at the first written record"
          : "no oxts/: estimated from the velodyne scans (lidar odometry), world = the base frame at the first scan";
  if (drive.synthetic_times) {
    extra["times"] = "no timestamps.txt in " + fmt::format("{}", fmt::join(without_timestamps, ", ")) +
                     ": frame k at k x 100 ms (10 Hz) for every sensor";
  }
  extra["ground_truth"] =
      "ground_truth.yaml holds KITTI's own reference extrinsic ([R_rect_00 | 0] * calib_velo_to_cam), found with "
      "targets; a reference, not exact truth";
  return extra;
}

// Copies the images (cameras/<camera>/, in the order of rig.cameras) and the
// scans (lidars/velodyne/) unchanged into the dataset at root, named by time.
void CopySensorFiles(const fs::path& root, const Rig& rig, const std::vector<std::vector<SensorFile>>& image_files,
                     const std::vector<SensorFile>& scan_files, const KittiImportOptions& options) {
  std::size_t total = scan_files.size();
  for (const std::vector<SensorFile>& files : image_files) total += files.size();
  std::size_t done = 0;
  const auto copy = [&](const SensorFile& file, const fs::path& folder) {
    ThrowIfInterrupted();  // StagedOutput's destructor then removes the partial copy
    fs::copy_file(file.path, folder / (std::to_string(file.t_us) + file.path.extension().string()));
    ++done;
    if (options.progress) options.progress(done, total);
  };
  for (std::size_t c = 0; c < image_files.size(); ++c) {
    const fs::path folder = root / "cameras" / rig.cameras[c].name;
    fs::create_directories(folder);
    for (const SensorFile& file : image_files[c]) copy(file, folder);
  }
  const fs::path lidar_folder = root / "lidars" / kLidarName;
  fs::create_directories(lidar_folder);
  for (const SensorFile& file : scan_files) copy(file, lidar_folder);
}

}  // namespace

KittiImportSummary ImportKitti(const fs::path& drive_dir_in, const fs::path& output,
                               const KittiImportOptions& options) {
  std::error_code error;
  fs::path drive_dir = fs::absolute(drive_dir_in).lexically_normal();
  if (!drive_dir.has_filename()) drive_dir = drive_dir.parent_path();  // "drive/" -> "drive"
  const std::string layout_hint =
      "a KITTI raw synced drive folder (image_0i/, oxts/, velodyne_points/, each with timestamps.txt and data/)";
  if (!fs::is_directory(drive_dir, error)) Fail(drive_dir.string(), "drive", "not a directory", layout_hint);
  std::string why;
  if (!options.IsValid(&why)) Fail(drive_dir.string(), "options", why, "valid import options");
  const fs::path target = CheckOutputFolder(output, options.overwrite);
  const std::vector<int> cameras = ChooseCameras(drive_dir, options.cameras, layout_hint);

  // Everything is read and checked before anything is written.
  KittiImportSummary summary;
  const KittiCalibration calibration = ReadKittiCalibration(drive_dir, cameras);
  const DriveSeries drive = ReadDriveSeries(drive_dir, cameras, options, &summary.without_timestamps);
  const FrameRange range = SelectFrames(drive_dir, options, drive.frames);
  summary.first_frame = range.first;
  summary.frames = range.end - range.first;
  summary.calibration_dir = calibration.directory;
  const DriveExtrinsics extrinsics = ComputeExtrinsics(calibration, cameras);

  Rig rig;
  rig.base_frame = CameraName(cameras.front());
  std::vector<std::vector<SensorFile>> image_files(drive.images.size());
  for (std::size_t c = 0; c < drive.images.size(); ++c) {
    rig.cameras.push_back(ImportCamera(drive.images[c], cameras[c], cameras.front(), calibration, extrinsics, range,
                                       &image_files[c], &summary.lost));
    summary.cameras.push_back(rig.cameras.back().name);
  }
  LidarInfo lidar;
  lidar.name = kLidarName;
  lidar.kind = LidarKind::k3d;
  lidar.T_base_lidar = extrinsics.T_base_velo;
  rig.lidars.push_back(lidar);
  const std::vector<SensorFile> scan_files = ScanFilesInRange(drive.velodyne, range, &summary.lost);
  const Trajectory trajectory =
      drive.oxts ? OxtsTrajectory(*drive.oxts, drive.frames, range, extrinsics.T_imu_base, &summary.lost)
                 : TrajectoryFromScans(drive_dir, scan_files, extrinsics.T_base_velo, options);
  summary.trajectory_from_scans = !drive.oxts;
  rig.trajectory_source = drive.oxts ? TrajectorySource::kIns : TrajectorySource::kLidarOdometry;

  StagedOutput staged(target);
  const fs::path& root = staged.Staging();
  WriteRig(root / "rig.yaml", rig, ImportNotes(drive_dir, calibration, range, drive, summary.without_timestamps));
  WriteTrajectory(root / "trajectory.csv", trajectory);
  GroundTruth truth;
  truth.T_base_lidar[kLidarName] = extrinsics.T_base_velo;
  WriteGroundTruth(root / "ground_truth.yaml", truth);
  CopySensorFiles(root, rig, image_files, scan_files, options);
  for (const std::vector<SensorFile>& files : image_files) summary.images += files.size();
  summary.scans = scan_files.size();
  OpenDataset(root);  // the result must read back as a valid dataset

  ThrowIfInterrupted();  // the last point at which the output can still be left as it was
  staged.Commit();

  summary.dataset = target;
  summary.base_frame = rig.base_frame;
  summary.poses = trajectory.size();
  return summary;
}

}  // namespace scenecal::io
