// Importer for scenes in TRI's DGP format (the Dataset Governance Policy
// format of DDAD and other Toyota Research Institute data sets), turned into a
// native dataset (docs/FORMAT.md): several cameras, lidars, and world poses per
// datum.
//
// A scene folder holds scene_<hash>.json (the datums, each with its file, its
// timestamp and its world pose; samples grouping the datums of one frame and
// naming their calibration), calibration/<key>.json (per sensor, its pose in
// the vehicle frame and its intrinsics), rgb/<camera>/<t>.jpg|png images and
// point_cloud/<lidar>/<t>.npz point clouds. Annotations are not needed.
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/rig.hpp"
#include "core/trajectory.hpp"
#include "io/error.hpp"

namespace scenecal::io {

// A scene file (scene_<hash>.json), as far as a calibrator needs it.
struct DgpDatum {
  enum class Kind { kImage, kPointCloud };
  Kind kind = Kind::kImage;
  std::string key;       // the datum's key, as samples name it
  std::string sensor;    // id.name, e.g. CAMERA_01 or LIDAR
  std::string filename;  // relative to the scene folder
  std::string timestamp;                // id.timestamp as written (RFC 3339)
  TimeUs raw_t_us = 0;                  // id.timestamp as microseconds since the epoch
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();  // the datum's pose (m)
  int width = 0, height = 0;            // images: pixels
  std::vector<std::string> point_format;  // point clouds: the columns, e.g. X Y Z INTENSITY
};

struct DgpScene {
  std::vector<DgpDatum> data;                 // images and point clouds (other kinds are skipped)
  std::size_t skipped_data = 0;               // datums of other kinds (radar, files, ...)
  std::size_t samples = 0;                    // frames
  std::vector<std::string> calibration_keys;  // distinct, in the order the samples name them
};

// One sensor of a calibration file: its pose in the vehicle frame and its
// intrinsics (zero for a lidar).
struct DgpSensorCalibration {
  std::string name;
  Eigen::Isometry3d T_vehicle_sensor = Eigen::Isometry3d::Identity();
  double fx = 0, fy = 0, cx = 0, cy = 0, skew = 0;  // pixels
  bool fisheye = false;                             // OpenCV fisheye model (k1..k4)
  double k1 = 0, k2 = 0, k3 = 0, k4 = 0, p1 = 0, p2 = 0;
  // A distortion term scenecal's camera models do not have (k5, k6, xi, ...), non-zero: its name.
  std::string unsupported_term;
};

struct DgpCalibration {
  std::vector<DgpSensorCalibration> sensors;
  const DgpSensorCalibration* Find(const std::string& name) const;
};

// Parse the JSON text of a scene or a calibration file; InputError naming
// `name` and the field (e.g. data[3].datum.image.pose.rotation.qw) on anything
// malformed: a missing or mistyped field, a non-finite number, a quaternion
// whose norm is off by more than 1e-3, a timestamp that is not RFC 3339.
DgpScene ParseDgpScene(const std::string& json_text, const std::string& name);
DgpCalibration ParseDgpCalibration(const std::string& json_text, const std::string& name);

// An RFC 3339 time "2019-03-28T11:10:09.112358Z" (UTC, 0..9 fraction digits,
// or an offset such as +02:00) as microseconds since the Unix epoch, rounded
// down; nullopt when it is not of that form.
std::optional<TimeUs> ParseRfc3339(const std::string& text);

struct DgpImportOptions {
  std::vector<std::string> cameras;  // camera names to import; empty: every camera of the scene
  std::string base_camera;           // base frame; empty: the first imported camera by name
  bool overwrite = false;            // replace a non-empty output folder
  // Called after each image or scan written (done, total); may be empty.
  std::function<void(std::size_t done, std::size_t total)> progress;
};

struct DgpImportSummary {
  std::filesystem::path dataset;
  std::filesystem::path scene_file;
  std::vector<std::string> cameras;  // imported
  std::vector<std::string> lidars;   // imported
  std::string base_frame;
  std::size_t frames = 0;  // samples of the scene
  std::size_t images = 0;
  std::size_t scans = 0;
  std::size_t points = 0;      // lidar points written (every scan)
  std::size_t poses = 0;       // trajectory rows
  bool times_in_100ns = false; // the scene's timestamps were read as 100 ns units (see ImportDgp)
  // The largest disagreement between datums of one time about the vehicle's
  // pose (cameras firing together each carry a pose): metres and degrees.
  double pose_disagreement_m = 0.0;
  double pose_disagreement_deg = 0.0;
};

// Converts the scene to a dataset at output (built beside it and renamed at the
// end: no partial dataset; a non-empty output is refused unless overwrite).
// Everything is read and checked before anything is written.
// - Cameras from the calibration's intrinsics (pinhole fx fy cx cy; radtan when
//   k1, k2, p1, p2, k3 are given and not all zero; a non-zero skew or another
//   distortion model is refused) and the image datums' width and height, checked
//   against the files' headers. T_base_camera = T_vehicle_base^-1 *
//   T_vehicle_camera from the calibration's extrinsics (each a sensor's pose in
//   the vehicle frame): the known inter-camera transforms.
// - Every point-cloud sensor is a 3D lidar; T_base_lidar from its extrinsic is
//   the initial guess and ground_truth.yaml (the recording's reference, not
//   exact truth). Points (X, Y, Z and INTENSITY of point_format, in the lidar's
//   frame) are written as FORMAT.md scans.
// - Times: each datum's id.timestamp (RFC 3339). A time in an impossible year
//   (after 2200) is the 100 ns count that some DGP writers store, read as
//   microseconds: it is then divided by 10 (summary.times_in_100ns; the log says so).
// - Trajectory: each datum's world pose is T_world_sensor at its time, so
//   T_world_base = pose * T_vehicle_sensor^-1 * T_vehicle_base, one row per
//   distinct datum time (datums at one time averaged; their disagreement is in
//   the summary), origin moved to the first row's position.
DgpImportSummary ImportDgp(const std::filesystem::path& scene_dir, const std::filesystem::path& output,
                           const DgpImportOptions& options);

}  // namespace scenecal::io
