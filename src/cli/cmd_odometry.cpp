// scenecal odometry DATASET --lidar NAME: a trajectory from a 3D lidar's own
// scans (scan-to-local-map ICP), for recordings without poses or with poor ones.
#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "cli/commands.hpp"
#include "cli/validators.hpp"
#include "core/geometry.hpp"
#include "core/interrupt.hpp"
#include "io/dataset.hpp"
#include "io/output_path.hpp"
#include "cli/odometry_plugin.hpp"
#include "odometry/lidar_odometry.hpp"

namespace scenecal::cli {

namespace fs = std::filesystem;

namespace {

// T_base_lidar from rig.yaml ("guess"), ground_truth.yaml ("truth") or a result file.
Eigen::Isometry3d LidarExtrinsic(const fs::path& root, const LidarInfo& lidar, const std::string& source) {
  if (source == "guess") return lidar.T_base_lidar;
  if (source == "truth") {
    const fs::path file = root / "ground_truth.yaml";
    const GroundTruth truth = io::ReadGroundTruth(file);
    const auto found = truth.T_base_lidar.find(lidar.name);
    if (found == truth.T_base_lidar.end()) {
      throw io::InputError(file.string() + ": lidars." + lidar.name + ": missing; expected the lidar's true extrinsic "
                           "(--extrinsic truth)");
    }
    return found->second;
  }
  const CalibrationResult result = io::ReadCalibrationResult(source);
  for (const LidarCalibration& calibration : result.lidars) {
    if (calibration.lidar == lidar.name) return calibration.T_base_lidar;
  }
  throw io::InputError(source + ": lidars." + lidar.name + ": missing; expected a result that calibrated this lidar");
}

struct OdometryArguments {
  std::string dataset;
  std::string lidar;
  std::string output;
  std::string extrinsic = "guess";
  bool force = false;
  odometry::LidarOdometryOptions odometry;
};

// The rig's lidar `name`, which must be a 3d lidar (rig.yaml in `root`).
const LidarInfo& FindScanningLidar(const fs::path& root, const Rig& rig, const std::string& name) {
  const LidarInfo* lidar = rig.FindLidar(name);
  if (lidar == nullptr) {
    std::string names;
    for (const LidarInfo& l : rig.lidars) names += (names.empty() ? "" : ", ") + l.name;
    throw io::InputError((root / "rig.yaml").string() + ": lidars: no lidar '" + name + "'; expected one of " +
                         names);
  }
  if (lidar->kind != LidarKind::k3d) {
    throw io::InputError((root / "rig.yaml").string() + ": lidars." + lidar->name +
                         ".kind: 2d; expected a 3d lidar (a 2d scan line has nothing to register)");
  }
  return *lidar;
}

// The odometry over the scans of `files` (in time order), with a log line
// about every 10% of them.
std::vector<odometry::OdometryStep> RegisterScans(const odometry::LidarOdometryOptions& options,
                                                  const std::vector<io::SensorFile>& files) {
  const odometry::RunLidarOdometryFn run_odometry = LoadOdometryPlugin();
  const auto start = std::chrono::steady_clock::now();
  std::size_t handed = 0, next_report = 1;
  return run_odometry(options, [&](LidarScan* scan) {
    // Asked for scan i once scans 0..i-1 are registered.
    if (handed >= next_report || handed == files.size()) {
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      spdlog::info("registered {}/{} scans ({:.1f} s)", handed, files.size(), seconds);
      next_report = handed + std::max<std::size_t>(files.size() / 10, 1);
    }
    if (handed == files.size()) return false;
    ThrowIfInterrupted();  // a scan takes ~0.1 s: Ctrl-C stops here, before anything is written
    *scan = io::ReadScan(files[handed++]);
    return true;
  });
}

// Logs the odometry's drift against the recorded trajectory (read from `recorded`).
void LogDrift(const std::vector<TimeUs>& times, const std::vector<Eigen::Isometry3d>& T_world_base,
              const Trajectory& reference, const fs::path& recorded) {
  const odometry::DriftStatistics drift = odometry::CompareWithReference(times, T_world_base, reference, 100.0);
  if (drift.compared < 2) return;
  spdlog::info("against {} ({} poses, {:.1f} m): end error {:.3f} m, {:.3f} deg", recorded.string(), drift.compared,
               drift.distance_m, drift.end_translation_m, drift.end_rotation_deg);
  // Per distance only over a drive long enough for the ratio to mean something.
  if (drift.distance_m >= 10.0) {
    spdlog::info("end error per distance: {:.2f} %, {:.4f} deg/m", 100.0 * drift.end_translation_m / drift.distance_m,
                 drift.end_rotation_deg / drift.distance_m);
  }
  if (drift.segments > 0) {
    spdlog::info("over {} segments of 100 m: translation drift {:.2f} %, rotation drift {:.4f} deg/m",
                 drift.segments, drift.segment_translation_percent, drift.segment_rotation_deg_per_m);
  }
}

int RunOdometry(const OdometryArguments& args) {
  const fs::path root(args.dataset);
  const Rig rig = io::ReadRig(root / "rig.yaml");
  const LidarInfo& lidar = FindScanningLidar(root, rig, args.lidar);
  std::string why;
  if (!args.odometry.IsValid(&why)) throw io::InputError("odometry options: " + why);
  const fs::path recorded = root / "trajectory.csv";
  const fs::path output = args.output.empty() ? recorded : fs::path(args.output);
  io::CheckOutputFile(output, "--output");
  std::error_code error;
  if (fs::exists(output, error) && !args.force) {
    throw io::InputError(output.string() + ": --output: exists; expected a new file (--force replaces it)");
  }
  // The recorded trajectory, if any, to measure the odometry against (read
  // before it may be replaced).
  std::optional<Trajectory> reference;
  if (fs::exists(recorded, error)) reference = io::ReadTrajectory(recorded);

  const Eigen::Isometry3d T_base_lidar = LidarExtrinsic(root, lidar, args.extrinsic);
  const std::vector<io::SensorFile> files = io::ListLidarScans(root, lidar.name);
  spdlog::info("lidar odometry of {} ({} scans): voxel {} m, range {}..{} m, {} keyframes in the map", lidar.name,
               files.size(), args.odometry.voxel_m, args.odometry.min_range_m, args.odometry.max_range_m,
               args.odometry.map_keyframes);
  const std::vector<odometry::OdometryStep> steps = RegisterScans(args.odometry, files);

  // Base poses: world = the base frame at the first scan.
  std::vector<TimeUs> times;
  std::vector<Eigen::Isometry3d> T_world_base;
  std::size_t weak = 0;
  double fitness_sum = 0.0;
  for (const odometry::OdometryStep& step : steps) {
    times.push_back(step.t_us);
    T_world_base.push_back(T_base_lidar * step.T_world_lidar * T_base_lidar.inverse());
    weak += step.weak;
    fitness_sum += step.fitness;
  }
  const Trajectory trajectory(times, T_world_base);
  io::WriteTrajectory(output, trajectory);
  spdlog::info("wrote {}: {} poses over {:.2f} m, mean fitness {:.3f}", output.string(), times.size(),
               trajectory.TotalDistance(), fitness_sum / static_cast<double>(times.size()));
  if (weak > 0) {
    spdlog::warn("{} of {} scans registered weakly (fewer than {:.0f} % of their points near the map): their poses "
                 "follow the motion before them",
                 weak, times.size(), 100.0 * args.odometry.min_fitness);
  }
  if (reference) LogDrift(times, T_world_base, *reference, recorded);
  return kExitSuccess;
}

// The registration's own options: scan filtering and the local map.
void AddRegistrationOptions(CLI::App* command, odometry::LidarOdometryOptions* odometry) {
  command->add_option("--voxel", odometry->voxel_m, "Down-sampling voxel for scans and map (m)")
      ->check(kPositive)
      ->capture_default_str();
  command->add_option("--min-range", odometry->min_range_m, "Drop returns nearer than this (m; the vehicle)")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--max-range", odometry->max_range_m, "Drop returns beyond this (m)")
      ->check(kPositive)
      ->capture_default_str();
  command->add_option("--keyframes", odometry->map_keyframes, "Keyframes in the local map")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
}

}  // namespace

CommandRunner AddOdometryCommand(CLI::App& app) {
  auto args = std::make_shared<OdometryArguments>();
  CLI::App* command = app.add_subcommand(
      "odometry",
      "Estimate the vehicle's trajectory from a 3D lidar's scans (each scan registered to a local map of the\n"
      "last keyframes by point-to-plane ICP with a robust kernel) and write it as trajectory.csv. The poses\n"
      "are the base frame's, through rig.yaml's T_base_lidar (the current guess: an error in its rotation\n"
      "turns the whole trajectory with it), at the scan times; world = the base frame at the first scan.\n"
      "When the dataset already has a trajectory.csv, the odometry's drift against it is printed.");
  command
      ->add_option("dataset", args->dataset, "Dataset folder (rig.yaml and lidars/<lidar>/; trajectory.csv optional)")
      ->required();
  command->add_option("--lidar", args->lidar, "The 3d lidar whose scans are registered")->required();
  command->add_option("-o,--output", args->output,
                      "Trajectory file to write (default DATASET/trajectory.csv; replacing it needs --force)");
  command->add_flag("--force", args->force, "Replace an existing trajectory file");
  command->add_option("--extrinsic", args->extrinsic,
                      "The lidar's T_base_lidar that turns its motion into the base frame's: guess (rig.yaml), "
                      "truth (ground_truth.yaml) or the path of a calibrate result (to refine the trajectory "
                      "after a calibration)")
      ->capture_default_str();
  AddRegistrationOptions(command, &args->odometry);
  return [args] { return RunOdometry(*args); };
}

}  // namespace scenecal::cli
