// The street simulator: builds a procedural street, drives a sensor rig
// through it, and writes a dataset in the FORMAT.md layout.
//
// Frames: the rig is laid out in the RobotCar vehicle frame V (x forward,
// y right, z down, road at V z = +3.0) and every sensor is then expressed in
// the base frame (the left camera): T_base_X = T_V_left^-1 * T_V_X.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>

#include <Eigen/Geometry>

#include "core/enum_names.hpp"
#include "core/rig.hpp"
#include "core/trajectory.hpp"
#include "sim/motion.hpp"
#include "sim/sensors.hpp"
#include "sim/world.hpp"

namespace scenecal::sim {

enum class Preset {
  kRobotCar,    // Bumblebee XB3 stereo at the front, rear SICK LMS-151 push-broom
  kTrinocular,  // three cameras 0.12 m apart, rear and front push-broom lidars
  kSpin3d,      // stereo pair, 32-beam spinning lidar on the roof
};
inline constexpr auto kPresetNames = MakeEnumNames<Preset>(
    {{Preset::kRobotCar, "robotcar"}, {Preset::kTrinocular, "trinocular"}, {Preset::kSpin3d, "spin3d"}});
bool ParsePreset(const std::string& name, Preset* preset);  // "robotcar" | "trinocular" | "spin3d"
const char* PresetName(Preset preset);

struct SimulationOptions {
  Preset preset = Preset::kRobotCar;
  std::uint64_t seed = 1;
  double distance_m = 380.0;   // length of the drive, unless duration_s > 0
  double duration_s = 0.0;     // > 0: drive for this long instead
  double speed_mps = 6.5;      // mean speed (m/s)
  bool include_stop = true;    // one short stop part-way (standing frames)
  double image_rate_hz = 1.0;  // per camera
  int image_width = 1280;      // pixels; intrinsics scale from the presets' 1280x960
  int image_height = 960;
  // The initial guess in rig.yaml is the truth moved by exactly these
  // magnitudes (m, deg) in random directions, per lidar.
  double perturb_translation_m = 0.05;
  double perturb_rotation_deg = 2.0;
  double odometry_noise = 1.0;  // 0: trajectory.csv is the true motion; 1: default drift
  OdometryDriftParts odometry_drift_parts;  // which parts of the drift (all by default)
  // The known inter-camera transforms in rig.yaml are wrong by these
  // magnitudes (m, deg); ground_truth.yaml then holds their true values.
  double camera_perturb_translation_m = 0.0;
  double camera_perturb_rotation_deg = 0.0;
  double lidar_2d_rate_hz = 50.0;
  double lidar_3d_rate_hz = 10.0;
  double spin_azimuth_step_deg = 0.4;
  double trajectory_rate_hz = 100.0;
  RenderSettings render;
  // Lidar reflectance = surface reflectivity (and noise) only: no dependence on
  // the incidence angle or the range (a test of what those trends do).
  bool ideal_reflectance = false;
  bool overwrite = false;  // replace a non-empty output directory

  bool IsValid(std::string* why = nullptr) const;
};

// Sensors of a preset with their TRUE extrinsics (in the base frame).
struct SimulatedRig {
  Rig rig;                                  // true transforms; base_frame = "left"
  std::map<std::string, LidarModel> lidar_models;
  Eigen::Isometry3d T_vehicle_base = Eigen::Isometry3d::Identity();  // V <- left camera
};
SimulatedRig MakeRig(const SimulationOptions& options);

struct SimulationSummary {
  std::filesystem::path output;
  std::string preset;
  std::uint64_t seed = 0;
  Rig rig;               // as written to rig.yaml (perturbed initial guesses)
  Rig true_rig;          // the true transforms of every sensor
  GroundTruth ground_truth;  // as written to ground_truth.yaml
  // TRUE T_world_base, with a sample at every sensor timestamp (so PoseAt is
  // exact there), and the drifting odometry written to trajectory.csv.
  Trajectory true_trajectory;
  Trajectory odometry_trajectory;
  std::shared_ptr<const World> world;
  std::map<std::string, LidarModel> lidar_models;
  std::map<std::string, std::size_t> images_per_camera;
  std::map<std::string, std::size_t> scans_per_lidar;
  std::size_t lidar_returns = 0;
  std::size_t lidar_no_returns = 0;
  double distance_m = 0.0;
  double duration_s = 0.0;
  double stop_duration_s = 0.0;
  std::uintmax_t bytes_on_disk = 0;
  double wall_time_s = 0.0;

  // One paragraph: sensors, frames, scans, distance, size on disk.
  std::string BriefReport() const;
};

// Generates the dataset into `output` (written to a temporary sibling folder
// and renamed at the end, so no partial dataset is left behind). Throws
// io::InputError when the options are invalid or `output` is not empty (and
// options.overwrite is false), std::runtime_error when writing fails.
// `progress(fraction, message)` is called from one thread at a time.
SimulationSummary Simulate(const SimulationOptions& options, const std::filesystem::path& output,
                           const std::function<void(double fraction, const std::string& message)>& progress = {});

// The first timestamp of every simulated dataset (microseconds).
constexpr TimeUs kSimulationEpochUs = 1418381798000000;

}  // namespace scenecal::sim
