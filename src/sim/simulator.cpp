#include "sim/simulator.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <system_error>

#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include "core/geometry.hpp"
#include "core/interrupt.hpp"
#include "core/validation.hpp"
#include "io/dataset.hpp"
#include "io/error.hpp"
#include "io/temporary_paths.hpp"
#include "sim/noise.hpp"

namespace scenecal::sim {
namespace fs = std::filesystem;

bool ParsePreset(const std::string& name, Preset* preset) { return ParseEnumName(kPresetNames, name, preset); }

const char* PresetName(Preset preset) { return EnumName(kPresetNames, preset); }

bool SimulationOptions::IsValid(std::string* why) const {
  const auto finite = [](double x) { return std::isfinite(x); };
  if (duration_s == 0.0 && !(finite(distance_m) && distance_m >= 5.0 && distance_m <= 20000.0))
    return Invalid(why, fmt::format("distance must be in [5, 20000] m, got {}", distance_m));
  if (!(finite(duration_s) && duration_s >= 0.0 && duration_s <= 3600.0))
    return Invalid(why, fmt::format("duration must be in [0, 3600] s (0: drive by distance), got {}", duration_s));
  if (duration_s > 0.0 && duration_s < 1.0)
    return Invalid(why, fmt::format("duration must be at least 1 s, got {}", duration_s));
  if (!(finite(speed_mps) && speed_mps >= 0.5 && speed_mps <= 30.0))
    return Invalid(why, fmt::format("speed must be in [0.5, 30] m/s, got {}", speed_mps));
  if (!(finite(image_rate_hz) && image_rate_hz > 0.0 && image_rate_hz <= 30.0))
    return Invalid(why, fmt::format("image rate must be in (0, 30] Hz, got {}", image_rate_hz));
  if (image_width < 16 || image_width > 8192 || image_height < 16 || image_height > 8192)
    return Invalid(why, fmt::format("image size must be within 16..8192 pixels, got {}x{}", image_width, image_height));
  if (!(finite(perturb_translation_m) && perturb_translation_m >= 0.0 && perturb_translation_m <= 10.0))
    return Invalid(why, fmt::format("perturb-translation must be in [0, 10] m, got {}", perturb_translation_m));
  if (!(finite(perturb_rotation_deg) && perturb_rotation_deg >= 0.0 && perturb_rotation_deg < 180.0))
    return Invalid(why, fmt::format("perturb-rotation must be in [0, 180) deg, got {}", perturb_rotation_deg));
  if (!(finite(camera_perturb_translation_m) && camera_perturb_translation_m >= 0.0 &&
        camera_perturb_translation_m <= 1.0))
    return Invalid(why,
                   fmt::format("camera-perturb-translation must be in [0, 1] m, got {}", camera_perturb_translation_m));
  if (!(finite(camera_perturb_rotation_deg) && camera_perturb_rotation_deg >= 0.0 &&
        camera_perturb_rotation_deg < 90.0))
    return Invalid(why,
                   fmt::format("camera-perturb-rotation must be in [0, 90) deg, got {}", camera_perturb_rotation_deg));
  if (!(finite(odometry_noise) && odometry_noise >= 0.0 && odometry_noise <= 100.0))
    return Invalid(why, fmt::format("odometry-noise must be in [0, 100], got {}", odometry_noise));
  if (!(finite(lidar_2d_rate_hz) && lidar_2d_rate_hz > 0.0 && lidar_2d_rate_hz <= 200.0))
    return Invalid(why, fmt::format("2D lidar rate must be in (0, 200] Hz, got {}", lidar_2d_rate_hz));
  if (!(finite(lidar_3d_rate_hz) && lidar_3d_rate_hz > 0.0 && lidar_3d_rate_hz <= 50.0))
    return Invalid(why, fmt::format("3D lidar rate must be in (0, 50] Hz, got {}", lidar_3d_rate_hz));
  if (!(finite(spin_azimuth_step_deg) && spin_azimuth_step_deg >= 0.05 && spin_azimuth_step_deg <= 5.0))
    return Invalid(why,
                   fmt::format("spinning lidar azimuth step must be in [0.05, 5] deg, got {}", spin_azimuth_step_deg));
  if (!(finite(trajectory_rate_hz) && trajectory_rate_hz >= 10.0 && trajectory_rate_hz <= 1000.0))
    return Invalid(why, fmt::format("trajectory rate must be in [10, 1000] Hz, got {}", trajectory_rate_hz));
  return true;
}

// ---------------------------------------------------------------------------
// Presets

namespace {

Eigen::Isometry3d Translation(double x, double y, double z) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

CameraInfo MakeCamera(const std::string& name, const SimulationOptions& options) {
  // Bumblebee XB3 wide at 1280x960, scaled to the requested size (pixel
  // centres at integer coordinates, so the centre scales about -0.5).
  const double sx = options.image_width / 1280.0, sy = options.image_height / 960.0;
  CameraInfo camera;
  camera.name = name;
  camera.model.width = options.image_width;
  camera.model.height = options.image_height;
  camera.model.kind = CameraModelKind::kPinhole;
  camera.model.fx = 983.044 * sx;
  camera.model.fy = 983.044 * sy;
  camera.model.cx = (643.647 + 0.5) * sx - 0.5;
  camera.model.cy = (493.379 + 0.5) * sy - 0.5;
  return camera;
}

}  // namespace

SimulatedRig MakeRig(const SimulationOptions& options) {
  SimulatedRig result;
  // Left camera in V: forward-looking optical frame (z_C = x_V, x_C = y_V,
  // y_C = z_V), pitched down by 15 deg about its x axis.
  Eigen::Matrix3d R_vehicle_level_camera;
  R_vehicle_level_camera << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  Eigen::Isometry3d T_vehicle_left = Translation(1.71, 0.12, 1.19);
  T_vehicle_left.linear() = R_vehicle_level_camera * RotationFromRollPitchYaw(RadiansFromDegrees(-15.0), 0.0, 0.0);
  result.T_vehicle_base = T_vehicle_left;
  const Eigen::Isometry3d T_base_vehicle = T_vehicle_left.inverse();

  Rig& rig = result.rig;
  rig.base_frame = "left";
  const auto add_camera = [&](const std::string& name, double offset_along_x) {
    CameraInfo camera = MakeCamera(name, options);
    camera.T_base_camera = Translation(offset_along_x, 0.0, 0.0);
    rig.cameras.push_back(camera);
  };
  const auto add_lidar = [&](const std::string& name, const Eigen::Isometry3d& T_vehicle_lidar, const LidarModel& model) {
    LidarInfo lidar;
    lidar.name = name;
    lidar.kind = model.kind;
    lidar.T_base_lidar = T_base_vehicle * T_vehicle_lidar;
    rig.lidars.push_back(lidar);
    LidarModel& stored = result.lidar_models[name] = model;
    if (options.ideal_reflectance) {
      stored.incidence_exponent = 0.0;
      stored.range_falloff_m = std::numeric_limits<double>::infinity();
    }
  };
  // RobotCar SDK extrinsics of the SICK LMS-151 lidars in V.
  const Eigen::Isometry3d T_vehicle_lms_rear =
      TransformFromTuple((Vector6d() << -2.5850, 0.2852, 1.0885, -2.8405, -1.5090, -0.3614).finished());
  const Eigen::Isometry3d T_vehicle_lms_front =
      TransformFromTuple((Vector6d() << 1.7589, 0.2268, 1.0411, -0.0437, -1.4572, 0.0356).finished());
  switch (options.preset) {
    case Preset::kRobotCar:
      add_camera("left", 0.0);
      add_camera("right", 0.239983);
      add_lidar("lms_rear", T_vehicle_lms_rear, LidarModel::PushBroom());
      break;
    case Preset::kTrinocular:
      add_camera("left", 0.0);
      add_camera("centre", 0.12);
      add_camera("right", 0.24);
      add_lidar("lms_rear", T_vehicle_lms_rear, LidarModel::PushBroom());
      add_lidar("lms_front", T_vehicle_lms_front, LidarModel::PushBroom());
      break;
    case Preset::kSpin3d: {
      add_camera("left", 0.0);
      add_camera("right", 0.239983);
      // On the roof above the cameras, level: x forward, y left, z up.
      Eigen::Isometry3d T_vehicle_spin = Translation(1.35, 0.24, 0.9);
      T_vehicle_spin.linear() = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
      add_lidar("spin", T_vehicle_spin, LidarModel::Spinning(options.spin_azimuth_step_deg));
      break;
    }
  }
  return result;
}

// ---------------------------------------------------------------------------

std::string SimulationSummary::BriefReport() const {
  std::string cameras, lidars;
  std::size_t images = 0, scans = 0;
  for (const CameraInfo& c : rig.cameras) {
    cameras += fmt::format("{}{}", cameras.empty() ? "" : ", ", c.name);
    if (auto it = images_per_camera.find(c.name); it != images_per_camera.end()) images += it->second;
  }
  for (const LidarInfo& l : rig.lidars) {
    const std::size_t n = scans_per_lidar.count(l.name) ? scans_per_lidar.at(l.name) : 0;
    lidars += fmt::format("{}{} ({}, {} scans)", lidars.empty() ? "" : ", ", l.name,
                          l.kind == LidarKind::k2d ? "2d" : "3d", n);
    scans += n;
  }
  const int width = rig.cameras.empty() ? 0 : rig.cameras.front().model.width;
  const int height = rig.cameras.empty() ? 0 : rig.cameras.front().model.height;
  const double no_return_percent =
      lidar_returns + lidar_no_returns > 0 ? 100.0 * lidar_no_returns / double(lidar_returns + lidar_no_returns) : 0.0;
  return fmt::format(
      "Simulated preset '{}' (seed {}) into {}: {} cameras ({}) at {}x{} with {} images in all ({} per camera), "
      "{} lidar(s): {}, {} scans with {} returns ({:.1f}% no-returns); {:.1f} m driven in {:.1f} s{}, trajectory "
      "of {} poses; {:.1f} MB on disk, generated in {:.1f} s.",
      preset, seed, output.string(), rig.cameras.size(), cameras, width, height, images,
      rig.cameras.empty() ? 0 : images / rig.cameras.size(), rig.lidars.size(), lidars, scans, lidar_returns,
      no_return_percent, distance_m, duration_s,
      stop_duration_s > 0 ? fmt::format(" (including a {:.1f} s stop)", stop_duration_s) : std::string(),
      odometry_trajectory.size(), bytes_on_disk / 1e6, wall_time_s);
}

namespace {

// Truth moved by exactly `translation_m` and `rotation_deg` in random directions.
Eigen::Isometry3d Perturb(const Eigen::Isometry3d& truth, double translation_m, double rotation_deg, KeyedRandom* random) {
  const auto unit = [&] {
    Eigen::Vector3d v;
    do v = Eigen::Vector3d(random->Gaussian(), random->Gaussian(), random->Gaussian());
    while (v.norm() < 1e-6);
    return Eigen::Vector3d(v.normalized());
  };
  const Eigen::Vector3d direction = unit();
  const Eigen::Vector3d axis = unit();
  Eigen::Isometry3d result = truth;
  result.translation() = truth.translation() + translation_m * direction;
  result.linear() = ExpSO3(RadiansFromDegrees(rotation_deg) * axis) * truth.linear();
  return result;
}

std::vector<TimeUs> RegularTimes(TimeUs first, TimeUs last, double rate_hz) {
  std::vector<TimeUs> times;
  const double period_us = 1e6 / rate_hz;
  for (std::int64_t i = 0;; ++i) {
    const TimeUs t = first + static_cast<TimeUs>(std::llround(i * period_us));
    if (t > last) break;
    times.push_back(t);
  }
  return times;
}

std::uintmax_t DirectorySize(const fs::path& root) {
  std::uintmax_t total = 0;
  for (const auto& entry : fs::recursive_directory_iterator(root)) {
    if (entry.is_regular_file()) total += entry.file_size();
  }
  return total;
}

using ProgressCallback = std::function<void(double, const std::string&)>;

// The output directory as an absolute path; throws when it exists and is not a
// directory, or is not empty and may not be replaced.
fs::path CheckedTarget(const fs::path& output, bool overwrite) {
  fs::path target = fs::absolute(output).lexically_normal();
  if (target.filename().empty()) target = target.parent_path();
  if (fs::exists(target)) {
    if (!fs::is_directory(target))
      throw io::InputError(fmt::format("{}: exists and is not a directory", target.string()));
    if (!fs::is_empty(target) && !overwrite) {
      throw io::InputError(
          fmt::format("{}: output directory is not empty (use --force to replace it)", target.string()));
    }
  }
  return target;
}

// Passes progress on from any thread, one call at a time, skipping steps
// under 2% unless forced.
class ProgressThrottle {
 public:
  explicit ProgressThrottle(const ProgressCallback& progress) : progress_(progress) {}

  void Report(double fraction, const std::string& message, bool force = false) {
    if (!progress_) return;
    std::lock_guard lock(mutex_);
    if (!force && fraction - last_reported_ < 0.02) return;
    last_reported_ = fraction;
    progress_(fraction, message);
  }

 private:
  const ProgressCallback& progress_;
  std::mutex mutex_;
  double last_reported_ = -1.0;
};

DriveOptions DriveOptionsOf(const SimulationOptions& options) {
  DriveOptions drive_options;
  drive_options.distance_m = options.distance_m;
  drive_options.duration_s = options.duration_s;
  drive_options.mean_speed_mps = options.speed_mps;
  drive_options.include_stop = options.include_stop;
  return drive_options;
}

// The drive through its world: the true pose of the rig's base at any time.
struct DriveScene {
  const Drive& drive;
  const World& world;
  Eigen::Isometry3d T_vehicle_base;

  Eigen::Isometry3d T_world_base(TimeUs t) const {
    return drive.T_world_vehicle(static_cast<double>(t - kSimulationEpochUs) * 1e-6, world) * T_vehicle_base;
  }
};

// Sensor timestamps (microseconds), all inside the trajectory's span.
struct SensorTimes {
  std::vector<TimeUs> images;                        // every camera's
  std::map<std::string, std::vector<TimeUs>> scans;  // per lidar name
};

SensorTimes PlanSensorTimes(const Rig& rig, const SimulationOptions& options, TimeUs t_first, TimeUs t_last) {
  SensorTimes times;
  times.images = RegularTimes(t_first + 200000, t_last - 100000, options.image_rate_hz);
  for (std::size_t i = 0; i < rig.lidars.size(); ++i) {
    const LidarInfo& lidar = rig.lidars[i];
    const double rate = lidar.kind == LidarKind::k2d ? options.lidar_2d_rate_hz : options.lidar_3d_rate_hz;
    const TimeUs first = t_first + 100000 + 3000 + 7000 * static_cast<TimeUs>(i);  // staggered per lidar
    times.scans[lidar.name] = RegularTimes(first, t_last - 50000, rate);
  }
  return times;
}

// The odometry (written) on a regular grid; the truth there and at every sensor time.
void ComputeTrajectories(const DriveScene& scene, const SimulationOptions& options, TimeUs t_first, TimeUs t_last,
                         const SensorTimes& sensor_times, SimulationSummary* summary) {
  const std::vector<TimeUs> grid = RegularTimes(t_first, t_last, options.trajectory_rate_hz);
  std::vector<Eigen::Isometry3d> T_world_vehicle_grid;
  std::vector<double> distance_grid;
  for (const TimeUs t : grid) {
    const double t_s = static_cast<double>(t - kSimulationEpochUs) * 1e-6;
    T_world_vehicle_grid.push_back(scene.drive.T_world_vehicle(t_s, scene.world));
    distance_grid.push_back(scene.drive.StreetPositionAt(t_s));
  }
  const OdometryDrift drift(options.seed, options.odometry_noise, options.odometry_drift_parts);
  std::vector<Eigen::Isometry3d> T_world_base_odometry = drift.Apply(T_world_vehicle_grid, distance_grid);
  for (auto& T : T_world_base_odometry) T = T * scene.T_vehicle_base;
  std::vector<TimeUs> true_times = grid;
  true_times.insert(true_times.end(), sensor_times.images.begin(), sensor_times.images.end());
  for (const auto& [name, times] : sensor_times.scans) true_times.insert(true_times.end(), times.begin(), times.end());
  std::sort(true_times.begin(), true_times.end());
  true_times.erase(std::unique(true_times.begin(), true_times.end()), true_times.end());
  std::vector<Eigen::Isometry3d> true_poses;
  true_poses.reserve(true_times.size());
  for (const TimeUs t : true_times) true_poses.push_back(scene.T_world_base(t));
  summary->true_trajectory = Trajectory(true_times, std::move(true_poses));
  summary->odometry_trajectory = Trajectory(grid, std::move(T_world_base_odometry));
}

// The rig as written: perturbed lidar guesses, optionally wrong camera
// transforms; the true values of what was perturbed go to *ground_truth.
Rig WrittenRig(const Rig& true_rig, const SimulationOptions& options, GroundTruth* ground_truth) {
  Rig written = true_rig;
  // The simulated drift is visual odometry's (~0.01 deg/m); without it the poses are exact.
  written.trajectory_source =
      options.odometry_noise > 0.0 ? TrajectorySource::kVisualOdometry : TrajectorySource::kExact;
  KeyedRandom lidar_random(options.seed, 1000), camera_random(options.seed, 1100);
  for (LidarInfo& lidar : written.lidars) {
    ground_truth->T_base_lidar[lidar.name] = lidar.T_base_lidar;
    lidar.T_base_lidar =
        Perturb(lidar.T_base_lidar, options.perturb_translation_m, options.perturb_rotation_deg, &lidar_random);
  }
  const bool perturb_cameras = options.camera_perturb_translation_m > 0.0 || options.camera_perturb_rotation_deg > 0.0;
  if (!perturb_cameras) return written;
  for (CameraInfo& camera : written.cameras) {
    if (camera.name == written.base_frame) continue;
    ground_truth->T_base_camera[camera.name] = camera.T_base_camera;
    camera.T_base_camera = Perturb(camera.T_base_camera, options.camera_perturb_translation_m,
                                   options.camera_perturb_rotation_deg, &camera_random);
    // 1-sigma per component as large as the whole error (floored: zero would mean a hard constraint).
    const double sigma_t = std::max(options.camera_perturb_translation_m, 1e-4);
    const double sigma_r = std::max(RadiansFromDegrees(options.camera_perturb_rotation_deg), 1e-4);
    camera.T_base_camera_sigma = (Vector6d() << sigma_t, sigma_t, sigma_t, sigma_r, sigma_r, sigma_r).finished();
  }
  return written;
}

struct ImageTask {
  std::size_t camera;
  std::size_t frame;
  TimeUs t;
};

struct ScanTask {
  std::size_t lidar;
  std::size_t scan;
  TimeUs t;
};

// What rendering and scanning read: the true sensors, the drive and where the files go.
struct Recording {
  const SimulationOptions& options;
  const SimulatedRig& simulated;
  const DriveScene& scene;
  const SensorTimes& times;
  const fs::path& directory;
};

// Progress of the sensor data in units of rays cast, mapped onto [0.03, 0.98].
class RayProgress {
 public:
  RayProgress(ProgressThrottle* report, double total_work) : report_(report), total_work_(total_work) {}

  void Advance(double work, const std::string& message) {
    double expected = done_work_.load();
    while (!done_work_.compare_exchange_weak(expected, expected + work)) {
    }
    report_->Report(0.03 + 0.95 * (expected + work) / std::max(1.0, total_work_), message);
  }

 private:
  ProgressThrottle* report_;
  double total_work_;
  std::atomic<double> done_work_{0.0};
};

double RaysToCast(const Recording& recording, const std::vector<ScanTask>& scan_tasks) {
  const Rig& rig = recording.simulated.rig;
  double total_work = 0.0;
  for (std::size_t c = 0; c < rig.cameras.size(); ++c)
    total_work += double(recording.times.images.size()) * rig.cameras[c].model.width * rig.cameras[c].model.height;
  for (const ScanTask& task : scan_tasks)
    total_work += double(recording.simulated.lidar_models.at(rig.lidars[task.lidar].name).beam_directions.size());
  return total_work;
}

void RenderImages(const Recording& recording, const std::vector<ImageTask>& tasks, RayProgress* progress) {
  tbb::parallel_for(std::size_t{0}, tasks.size(), [&](std::size_t i) {
    ThrowIfInterrupted();  // unwinds to WriteDataset's catch, which removes the temporary folder
    const ImageTask& task = tasks[i];
    const CameraInfo& camera = recording.simulated.rig.cameras[task.camera];
    const Eigen::Isometry3d T_world_camera = recording.scene.T_world_base(task.t) * camera.T_base_camera;
    const cv::Mat image = RenderImage(recording.scene.world, camera.model, T_world_camera, recording.options.render,
                                      HashKey(recording.options.seed, 2000 + task.camera, task.frame));
    io::WriteImage(recording.directory / "cameras" / camera.name / fmt::format("{}.png", task.t), image);
    progress->Advance(double(camera.model.width) * camera.model.height,
                      fmt::format("rendered image {}/{}", task.frame + 1, recording.times.images.size()));
  });
}

void ScanLidars(const Recording& recording, const std::vector<ScanTask>& tasks, RayProgress* progress,
                SimulationSummary* summary) {
  std::atomic<std::size_t> returns{0}, no_returns{0};
  tbb::parallel_for(std::size_t{0}, tasks.size(), [&](std::size_t i) {
    ThrowIfInterrupted();
    const ScanTask& task = tasks[i];
    const LidarInfo& lidar = recording.simulated.rig.lidars[task.lidar];
    const LidarModel& model = recording.simulated.lidar_models.at(lidar.name);
    const Eigen::Isometry3d T_world_lidar = recording.scene.T_world_base(task.t) * lidar.T_base_lidar;
    ScanStatistics statistics;
    const std::vector<LidarPoint> points =
        ScanLidar(recording.scene.world, model, T_world_lidar,
                  HashKey(recording.options.seed, 3000 + task.lidar, task.scan), &statistics);
    io::WriteScan(recording.directory / "lidars" / lidar.name / fmt::format("{}.bin", task.t), points);
    returns += statistics.returns;
    no_returns += statistics.no_returns;
    progress->Advance(double(model.beam_directions.size()), fmt::format("scanned {} {}/{}", lidar.name, task.scan + 1,
                                                                        recording.times.scans.at(lidar.name).size()));
  });
  summary->lidar_returns = returns;
  summary->lidar_no_returns = no_returns;
}

// Renders every image and scans every scan into recording.directory.
void RecordSensors(const Recording& recording, ProgressThrottle* report, SimulationSummary* summary) {
  const Rig& rig = recording.simulated.rig;
  std::vector<ImageTask> image_tasks;
  for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
    for (std::size_t k = 0; k < recording.times.images.size(); ++k)
      image_tasks.push_back({c, k, recording.times.images[k]});
    summary->images_per_camera[rig.cameras[c].name] = recording.times.images.size();
  }
  std::vector<ScanTask> scan_tasks;
  for (std::size_t l = 0; l < rig.lidars.size(); ++l) {
    const auto& times = recording.times.scans.at(rig.lidars[l].name);
    for (std::size_t j = 0; j < times.size(); ++j) scan_tasks.push_back({l, j, times[j]});
    summary->scans_per_lidar[rig.lidars[l].name] = times.size();
  }
  RayProgress progress(report, RaysToCast(recording, scan_tasks));
  RenderImages(recording, image_tasks, &progress);
  ScanLidars(recording, scan_tasks, &progress, summary);
}

// Everything is written into a temporary sibling of `target` and renamed at the end.
void WriteDataset(const fs::path& target, const SimulationOptions& options, const SimulatedRig& simulated,
                  const DriveScene& scene, const SensorTimes& times, ProgressThrottle* report,
                  SimulationSummary* summary) {
  std::error_code ec;
  const fs::path temporary =
      target.parent_path() / fmt::format(".{}.partial-{}", target.filename().string(), static_cast<long>(::getpid()));
  fs::remove_all(temporary, ec);
  const io::RegisteredTemporaryPath registration(temporary);  // for a process that must end at once
  fs::create_directories(temporary);
  try {
    io::WriteDatasetSkeleton(temporary, summary->rig, summary->odometry_trajectory, summary->ground_truth);
    RecordSensors({options, simulated, scene, times, temporary}, report, summary);
    summary->bytes_on_disk = DirectorySize(temporary);

    if (fs::exists(target)) fs::remove_all(target);
    fs::rename(temporary, target);
  } catch (...) {
    fs::remove_all(temporary, ec);
    throw;
  }
}

}  // namespace

SimulationSummary Simulate(const SimulationOptions& options, const fs::path& output, const ProgressCallback& progress) {
  const auto wall_start = std::chrono::steady_clock::now();
  std::string why;
  if (!options.IsValid(&why)) throw io::InputError("simulate: invalid options: " + why);
  const fs::path target = CheckedTarget(output, options.overwrite);
  ProgressThrottle report(progress);

  // The drive and the world around it.
  report.Report(0.0, "planning the drive", true);
  const DriveOptions drive_options = DriveOptionsOf(options);
  const Drive drive(options.seed, drive_options);
  report.Report(0.01, fmt::format("building the street world ({:.0f} m of drive)", drive.total_distance_m()), true);
  auto world = std::make_shared<World>(World::Generate(options.seed, -80.0, drive.total_distance_m() + 170.0));

  const SimulatedRig simulated = MakeRig(options);
  const TimeUs t_first = kSimulationEpochUs;
  const TimeUs t_last = kSimulationEpochUs + static_cast<TimeUs>(std::floor(drive.duration_s() * 1e6));
  const DriveScene scene{drive, *world, simulated.T_vehicle_base};
  const SensorTimes times = PlanSensorTimes(simulated.rig, options, t_first, t_last);

  SimulationSummary summary;
  report.Report(0.02, "computing the trajectory and odometry", true);
  ComputeTrajectories(scene, options, t_first, t_last, times, &summary);
  summary.output = target;
  summary.preset = PresetName(options.preset);
  summary.seed = options.seed;
  summary.true_rig = simulated.rig;
  summary.world = world;
  summary.lidar_models = simulated.lidar_models;
  summary.distance_m = drive.total_distance_m();
  summary.duration_s = static_cast<double>(t_last - t_first) * 1e-6;
  summary.stop_duration_s = options.include_stop ? drive_options.stop_duration_s : 0.0;
  summary.rig = WrittenRig(simulated.rig, options, &summary.ground_truth);

  WriteDataset(target, options, simulated, scene, times, &report, &summary);
  summary.wall_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  report.Report(1.0, "done", true);
  return summary;
}

}  // namespace scenecal::sim
