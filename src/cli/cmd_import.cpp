// scenecal import FORMAT SOURCE --output DATASET: converts other data layouts
// into a native dataset (FORMAT.md).
#include <chrono>
#include <functional>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include "cli/commands.hpp"
#include "cli/odometry_plugin.hpp"
#include "cli/validators.hpp"
#include "core/interrupt.hpp"
#include "io/dgp.hpp"
#include "io/kitti.hpp"
#include "io/opencalib.hpp"
#include "io/output_path.hpp"
#include "odometry/lidar_odometry.hpp"

namespace scenecal::cli {

namespace {

// "0,1" or "image_02,image_03" -> camera indices 0..3; nullopt when malformed.
std::optional<std::vector<int>> ParseCameraList(const std::string& text) {
  std::vector<int> indices;
  std::istringstream items(text);
  for (std::string item; std::getline(items, item, ',');) {
    if (item.rfind("image_0", 0) == 0) item = item.substr(7);
    if (item.size() != 1 || item[0] < '0' || item[0] > '3') return std::nullopt;
    indices.push_back(item[0] - '0');
  }
  if (indices.empty() || (!text.empty() && text.back() == ',')) return std::nullopt;
  if (std::set<int>(indices.begin(), indices.end()).size() != indices.size()) return std::nullopt;
  return indices;
}

// "CAMERA_01,CAMERA_05" -> names; nullopt when empty, malformed or repeated.
std::optional<std::vector<std::string>> ParseNameList(const std::string& text) {
  std::vector<std::string> names;
  std::istringstream items(text);
  for (std::string item; std::getline(items, item, ',');) {
    if (item.empty()) return std::nullopt;
    names.push_back(item);
  }
  if (names.empty() || text.back() == ',') return std::nullopt;
  if (std::set<std::string>(names.begin(), names.end()).size() != names.size()) return std::nullopt;
  return names;
}

// Copying a recording takes a while: a log line about every 10% of the files.
std::function<void(std::size_t, std::size_t)> ProgressLogger(const char* what) {
  const auto start = std::chrono::steady_clock::now();
  return [next_report = std::size_t{0}, start, what](std::size_t done, std::size_t total) mutable {
    if (done < next_report && done != total) return;
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    spdlog::info("{} {}/{} images and scans ({:.0f}%, {:.1f} s)", what, done, total, 100.0 * done / total, seconds);
    next_report = done + std::max<std::size_t>(total / 10, 1);
  };
}

struct ImportArguments {
  std::string format;
  std::string source;
  std::string output;
  bool force = false;
  std::string cameras;
  std::string base_camera;
  std::size_t first = 0;
  std::size_t count = 0;
};

// `scenecal import`'s description: the layouts it reads and what it writes of each.
const char* const kImportDescription =
    "Convert data from another layout into a native dataset.\n"
    "  opencalib SOURCE: a folder with calib.txt (K, D, T = T_camera_lidar), calib.pcd and calib.jpg|calib.png\n"
    "    (OpenCalib lidar2camera) -> a static dataset with one camera, one 3d lidar and the reference T\n"
    "    as the initial guess and as ground_truth.yaml.\n"
    "  kitti DRIVE: a KITTI raw synced+rectified drive, e.g. 2011_09_26/2011_09_26_drive_0005_sync/ with\n"
    "    image_00..image_03/ (timestamps.txt, data/0000000000.png ...), oxts/ (timestamps.txt, data/*.txt)\n"
    "    and velodyne_points/ (timestamps.txt, data/*.bin); calib_cam_to_cam.txt, calib_velo_to_cam.txt and\n"
    "    calib_imu_to_velo.txt in the date folder above the drive (or in the drive folder).\n"
    "    Writes cameras image_0i (rectified pinhole from P_rect_0i; base frame image_00, or the lowest\n"
    "    imported camera), lidar velodyne (3d; T_base_lidar = [R_rect_00 | 0] * calib_velo_to_cam, as the\n"
    "    initial guess and as ground_truth.yaml: KITTI's reference, not exact truth), trajectory.csv of the\n"
    "    base frame from the OXTS records, images and scans copied unchanged and named by their time (us\n"
    "    since the Unix epoch, timestamps read as UTC). An empty timestamps.txt line (lost frame) is skipped.\n"
    "    Snippets without oxts/ get their trajectory from lidar odometry of the velodyne scans, and without\n"
    "    timestamps.txt every sensor's frame k is taken at k x 100 ms (10 Hz); the log warns of both.\n"
    "  dgp SCENE: a scene of TRI's DGP format (scene_<hash>.json, calibration/<key>.json, rgb/<camera>/,\n"
    "    point_cloud/<lidar>/*.npz). Writes every camera (or --cameras) with the calibration's intrinsics\n"
    "    and its extrinsics as the known inter-camera transforms (base frame --base-camera, default the first\n"
    "    by name), every point cloud sensor as a 3d lidar (its calibration as the initial guess and as\n"
    "    ground_truth.yaml: the recording's reference, not exact truth), trajectory.csv from the datums'\n"
    "    world poses, images copied unchanged and the .npz clouds (X, Y, Z, INTENSITY) as scans.";

// --cameras, when given, parsed by `parse` into *cameras; false (the reason
// logged: `expected` says what was expected) when malformed.
template <typename Camera>
bool ParseCamerasOption(const CLI::App& command, const std::string& text,
                        std::optional<std::vector<Camera>> (*parse)(const std::string&), const char* expected,
                        std::vector<Camera>* cameras) {
  if (command.count("--cameras") == 0) return true;
  const std::optional<std::vector<Camera>> parsed = parse(text);
  if (!parsed) {
    spdlog::error("--cameras '{}': expected {}", text, expected);
    return false;
  }
  *cameras = *parsed;
  return true;
}

int ImportDgpScene(const ImportArguments& args, const CLI::App& command) {
  if (command.count("--first") + command.count("--count") > 0) {
    spdlog::error("--first and --count apply to the kitti format only");
    return kExitInvalidInput;
  }
  io::DgpImportOptions dgp;
  if (!ParseCamerasOption(command, args.cameras, &ParseNameList,
                          "distinct camera names separated by commas, e.g. CAMERA_01,CAMERA_05", &dgp.cameras)) {
    return kExitInvalidInput;
  }
  dgp.base_camera = args.base_camera;
  dgp.overwrite = args.force;
  dgp.progress = ProgressLogger("wrote");
  spdlog::info("reading and checking the DGP scene {}", args.source);
  const io::DgpImportSummary summary = io::ImportDgp(args.source, args.output, dgp);
  spdlog::info("imported {} -> {}: {} frames, cameras {} (base {}), lidars {}, {} images, {} scans ({} points), "
               "{} trajectory rows",
               summary.scene_file.string(), summary.dataset.string(), summary.frames, fmt::join(summary.cameras, ","),
               summary.base_frame, fmt::join(summary.lidars, ","), summary.images, summary.scans, summary.points,
               summary.poses);
  if (summary.times_in_100ns) {
    spdlog::warn("the scene's timestamps lie after the year 2200 when read as microseconds: read as 100 ns units");
  }
  // Datums of one time each carry the vehicle's pose: they should agree.
  if (summary.pose_disagreement_m > 0.01 || summary.pose_disagreement_deg > 0.05) {
    spdlog::warn("datums of the same time disagree about the vehicle's pose by up to {:.3f} m / {:.3f} deg; "
                 "the trajectory takes their mean",
                 summary.pose_disagreement_m, summary.pose_disagreement_deg);
  }
  return kExitSuccess;
}

int ImportOpenCalibSet(const ImportArguments& args, const CLI::App& command) {
  if (command.count("--cameras") + command.count("--first") + command.count("--count") > 0) {
    spdlog::error("--cameras, --first and --count apply to the kitti format only");
    return kExitInvalidInput;
  }
  const io::OpenCalibImportSummary summary = io::ImportOpenCalib(args.source, args.output, args.force);
  spdlog::info("imported {} -> {}: image {}x{}, {} lidar points ({} no-returns)", args.source,
               summary.dataset.string(), summary.image_width, summary.image_height, summary.points,
               summary.no_returns);
  return kExitSuccess;
}

// Snippets without oxts/: the trajectory of the base frame from lidar
// odometry of the velodyne scans.
Trajectory TrajectoryFromScans(const std::vector<io::SensorFile>& scans, const Eigen::Isometry3d& T_base_velo) {
  spdlog::warn("no oxts/: the trajectory comes from lidar odometry of the {} velodyne scans (scenecal odometry "
               "measures such a trajectory against a recorded one)",
               scans.size());
  std::size_t handed = 0;
  const std::vector<odometry::OdometryStep> steps = LoadOdometryPlugin()({}, [&](LidarScan* scan) {
    if (handed == scans.size()) return false;
    ThrowIfInterrupted();
    *scan = io::ReadScan(scans[handed++]);
    return true;
  });
  std::vector<TimeUs> times;
  std::vector<Eigen::Isometry3d> T_world_base;
  std::size_t weak = 0;
  for (const odometry::OdometryStep& step : steps) {
    times.push_back(step.t_us);
    T_world_base.push_back(T_base_velo * step.T_world_lidar * T_base_velo.inverse());
    weak += step.weak;
  }
  if (weak > 0) spdlog::warn("lidar odometry: {} of {} scans registered weakly", weak, scans.size());
  return Trajectory(times, T_world_base);
}

int ImportKittiDrive(const ImportArguments& args, const CLI::App& command) {
  io::KittiImportOptions kitti;
  if (!ParseCamerasOption(command, args.cameras, &ParseCameraList,
                          "distinct camera indices 0..3 separated by commas, e.g. 0,1 or 2,3", &kitti.cameras)) {
    return kExitInvalidInput;
  }
  kitti.first = args.first;
  if (command.count("--count") > 0) kitti.count = args.count;
  kitti.overwrite = args.force;
  kitti.progress = ProgressLogger("copied");
  kitti.trajectory_from_scans = TrajectoryFromScans;
  spdlog::info("reading and checking the KITTI drive {}", args.source);
  const io::KittiImportSummary summary = io::ImportKitti(args.source, args.output, kitti);
  std::string names;
  for (const std::string& name : summary.cameras) names += (names.empty() ? "" : ",") + name;
  spdlog::info(
      "imported {} -> {}: frames {}..{}, cameras {} (base {}), lidar velodyne, {} images, {} scans, "
      "{} trajectory rows; calibration from {}",
      args.source, summary.dataset.string(), summary.first_frame, summary.first_frame + summary.frames - 1, names,
      summary.base_frame, summary.images, summary.scans, summary.poses, summary.calibration_dir.string());
  if (!summary.without_timestamps.empty()) {
    spdlog::warn("no timestamps.txt in {}: every sensor's frame k taken at k x 100 ms (KITTI's nominal 10 Hz)",
                 fmt::join(summary.without_timestamps, ", "));
  }
  if (summary.lost > 0) {
    spdlog::warn("{} sensor frames in the range had no data (empty timestamps.txt lines) and were skipped",
                 summary.lost);
  }
  return kExitSuccess;
}

int RunImport(const ImportArguments& args, const CLI::App& command) {
  io::CheckOutputFolderWritable(args.output, "--output");
  if (command.count("--base-camera") > 0 && args.format != "dgp") {
    spdlog::error("--base-camera applies to the dgp format only");
    return kExitInvalidInput;
  }
  if (args.format == "dgp") return ImportDgpScene(args, command);
  if (args.format == "opencalib") return ImportOpenCalibSet(args, command);
  return ImportKittiDrive(args, command);
}

}  // namespace

CommandRunner AddImportCommand(CLI::App& app) {
  auto args = std::make_shared<ImportArguments>();
  CLI::App* command = app.add_subcommand("import", kImportDescription);
  command->add_option("format", args->format, "Source layout: opencalib | kitti | dgp")
      ->required()
      ->check(CLI::IsMember({"opencalib", "kitti", "dgp"}));
  command
      ->add_option("source", args->source,
                   "Source folder (opencalib: the set's folder; kitti: the drive folder; dgp: the scene folder)")
      ->required();
  command->add_option("-o,--output", args->output, "Dataset folder to create")->required();
  command->add_flag("--force", args->force, "Replace a non-empty output folder");
  command->add_option("--cameras", args->cameras,
                      "kitti: cameras to import, indices 0..3 or names, e.g. 0,1 (grey stereo) or 2,3 (colour); "
                      "default every image_0i folder present. dgp: camera names, e.g. CAMERA_01,CAMERA_05; default "
                      "every camera of the scene");
  command->add_option("--base-camera", args->base_camera,
                      "dgp: the camera whose frame is the base frame (default: the first imported camera by name)");
  command->add_option("--first", args->first, "kitti: first frame index to import (default 0)")->check(kNonNegative);
  command->add_option("--count", args->count, "kitti: number of frames from --first (default: to the end)")
      ->check(kPositive);
  return [args, command] { return RunImport(*args, *command); };
}

}  // namespace scenecal::cli
