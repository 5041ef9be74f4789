// Importer for KITTI raw drives, synced and rectified ("..._sync" folders of
// the KITTI raw data set, Geiger et al. 2013), turned into a native dataset
// (FORMAT.md): cameras image_00..image_03 (rectified pinhole), lidar
// "velodyne" (3d), trajectory from the OXTS GPS/IMU.
//
// KITTI's calibration (calib_*.txt) is the data set's own reference, estimated
// with checkerboard targets: a reference to compare against, not exact truth
// (its error is not stated in the files), and rig.yaml's extra section says so.
// Only synced+rectified drives are understood: the images must already be
// rectified and the sensors' timestamps.txt files numbered frame by frame.
#pragma once

#include <array>
#include <cstddef>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Geometry>

#include "core/trajectory.hpp"
#include "io/dataset.hpp"
#include "io/error.hpp"

namespace scenecal::io {

// A KITTI timestamps.txt line "2011-09-26 13:02:25.964389445" (no zone: read
// as UTC; 0 to 9 fraction digits) as microseconds since the Unix epoch,
// rounded to the nearest microsecond; nullopt when it is not of that form or
// not a valid date and time.
std::optional<TimeUs> ParseKittiTimestamp(std::string_view text);

// The calibration of a drive, in KITTI's devkit conventions. Cameras are
// indexed 0..3 (image_00..image_03).
struct KittiCalibration {
  // calib_cam_to_cam.txt P_rect_0i: 3x4 projection of rectified camera i,
  // pixel ~ P_rect_0i * [p_cam0rect; 1]; only for the cameras asked for.
  std::array<std::optional<Eigen::Matrix<double, 3, 4>>, 4> P_rect;
  // calib_cam_to_cam.txt R_rect_00: rotation from unrectified camera 0 into
  // rectified camera 0 (snapped to the nearest rotation).
  Eigen::Matrix3d R_rect_00 = Eigen::Matrix3d::Identity();
  Eigen::Isometry3d T_cam0_velo = Eigen::Isometry3d::Identity();  // calib_velo_to_cam.txt R, T (m); unrectified cam0
  Eigen::Isometry3d T_velo_imu = Eigen::Isometry3d::Identity();   // calib_imu_to_velo.txt R, T (m)
  std::filesystem::path directory;                                // where the three files were found
};

// Reads calib_cam_to_cam.txt, calib_velo_to_cam.txt and calib_imu_to_velo.txt
// from the drive's parent folder (the date folder), or else from the drive
// folder itself. P_rect_0i is required for every index in cameras. Other keys
// (calib_time, S_, K_, D_, delta_f, ...) are ignored. InputError names the
// file, the line or key, what was found and what was expected.
KittiCalibration ReadKittiCalibration(const std::filesystem::path& drive_dir, const std::vector<int>& cameras);

// The parsers of a drive's text files, on a file's content already in memory
// (the importer reads the files and calls these); `name` stands for the file
// in messages. InputError as ReadKittiCalibration.
// calib_cam_to_cam.txt: sets R_rect_00 and P_rect[i] for every index in cameras.
void ParseKittiCamToCam(const std::string& text, const std::string& name, const std::vector<int>& cameras,
                        KittiCalibration* calibration);
// calib_velo_to_cam.txt or calib_imu_to_velo.txt: the rigid [R | T] of the
// "R:" (9) and "T:" (3, metres) lines; `what` names the transform in messages.
Eigen::Isometry3d ParseKittiRigidTransform(const std::string& text, const std::string& name, const std::string& what);

// The first six of an OXTS record's 30 numbers (oxts/data/<frame>.txt).
struct KittiOxtsRecord {
  double lat = 0, lon = 0, alt = 0;     // degrees, degrees, metres
  double roll = 0, pitch = 0, yaw = 0;  // radians (yaw 0 = east, counter-clockwise)
};
KittiOxtsRecord ParseKittiOxts(const std::string& text, const std::string& name);

// A sensor's timestamps.txt: a time per line (ParseKittiTimestamp), strictly
// increasing; nullopt for an empty line (a lost frame).
std::vector<std::optional<TimeUs>> ParseKittiTimestamps(const std::string& text, const std::string& name);

struct KittiImportOptions {
  std::vector<int> cameras;          // indices 0..3; empty: every image_0i folder present
  std::size_t first = 0;             // first frame (index into the drive's timestamps.txt files)
  std::optional<std::size_t> count;  // frames from first; nullopt: to the end of the drive
  bool overwrite = false;            // replace a non-empty output folder
  // Called after each image or scan copied (done, total); may be empty. For
  // progress reports: the io layer does not log.
  std::function<void(std::size_t done, std::size_t total)> progress;
  // For drives without oxts/: the base frame's trajectory from the imported
  // scans (in time order) and the velodyne's extrinsic T_base_velo, e.g. by
  // lidar odometry (the io layer has none of its own). Empty: such a drive is
  // refused.
  std::function<Trajectory(const std::vector<SensorFile>& scans, const Eigen::Isometry3d& T_base_velo)>
      trajectory_from_scans;

  bool IsValid(std::string* why = nullptr) const;
};

struct KittiImportSummary {
  std::filesystem::path dataset;
  std::filesystem::path calibration_dir;
  std::vector<std::string> cameras;  // imported, e.g. image_00
  std::string base_frame;            // the lowest imported camera
  std::size_t first_frame = 0;       // the frame range imported: [first_frame, first_frame + frames)
  std::size_t frames = 0;
  std::size_t images = 0;  // image files written (every camera)
  std::size_t scans = 0;   // scan files written
  std::size_t poses = 0;   // trajectory rows
  std::size_t lost = 0;    // sensor frames in the range with an empty timestamp line (KITTI data loss)
  // Folders without timestamps.txt: every sensor then takes its frame index
  // at 10 Hz (frame k at k x 100000 us), KITTI's nominal rate.
  std::vector<std::string> without_timestamps;
  bool trajectory_from_scans = false;  // no oxts/: options.trajectory_from_scans made trajectory.csv
};

// Converts the drive to a dataset at output (a temporary folder beside it,
// renamed at the end, so no partial dataset is ever left; a non-empty output
// is refused unless options.overwrite). Everything is read and checked before
// anything is written. Frames and conventions:
// - cameras image_0i: pinhole, no distortion, fx fy cx cy from P_rect_0i,
//   size of the first image; images copied unchanged as
//   cameras/image_0i/<t_us>.png at the camera's own timestamps.
// - base frame: the lowest imported camera b (image_00 when imported).
//   Rectified cameras differ by a translation only: T_cami_cam0 =
//   [I | K_i^-1 * P_rect_0i(:, 3)], so T_base_cami = T_camb_cam0 * T_cami_cam0^-1.
// - lidar "velodyne" (3d): T_base_velo = T_camb_cam0 * [R_rect_00 | 0] *
//   T_cam0_velo, in rig.yaml (initial guess) and ground_truth.yaml (KITTI's
//   reference); scans copied unchanged as lidars/velodyne/<t_us>.bin.
// - trajectory: T_world_base = T_world_imu * T_velo_imu^-1 * T_base_velo^-1
//   at the OXTS times, T_world_imu from the devkit's Mercator conversion
//   (scale from the latitude of the drive's first OXTS record, world x east,
//   y north, z up, origin at the first written record's position). The rows
//   cover the frame range plus one neighbouring record on each side (when the
//   drive has it), so images and scans at the range's ends have a pose.
// - A frame whose timestamps.txt line is empty (KITTI's lost data) has no
//   data file and is skipped for that sensor (counted in `lost`).
// - Published snippets often hold only image_0x/ and velodyne_points/: a
//   folder without timestamps.txt gives every sensor 10 Hz frame times (its
//   data files numbered by frame; a gap is a lost frame), and without oxts/
//   the trajectory comes from options.trajectory_from_scans (summary says so).
KittiImportSummary ImportKitti(const std::filesystem::path& drive_dir, const std::filesystem::path& output,
                               const KittiImportOptions& options);

}  // namespace scenecal::io
