// scenecal import FORMAT SOURCE --output DATASET: converts other data layouts
// into a native dataset (FORMAT.md).
#include <chrono>
#include <optional>
#include <set>
#include <sstream>

#include <spdlog/spdlog.h>

#include "cli/commands.hpp"
#include "cli/validators.hpp"
#include "io/kitti.hpp"
#include "io/opencalib.hpp"
#include "io/output_path.hpp"

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

}  // namespace

CommandRunner AddImportCommand(CLI::App& app) {
  struct Options {
    std::string format;
    std::string source;
    std::string output;
    bool force = false;
    std::string cameras;
    std::size_t first = 0;
    std::size_t count = 0;
  };
  auto options = std::make_shared<Options>();
  CLI::App* command = app.add_subcommand(
      "import",
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
      "    since the Unix epoch, timestamps read as UTC). An empty timestamps.txt line (lost frame) is skipped.");
  command->add_option("format", options->format, "Source layout: opencalib | kitti")
      ->required()
      ->check(CLI::IsMember({"opencalib", "kitti"}));
  command->add_option("source", options->source, "Source folder (opencalib: the set's folder; kitti: the drive folder)")
      ->required();
  command->add_option("-o,--output", options->output, "Dataset folder to create")->required();
  command->add_flag("--force", options->force, "Replace a non-empty output folder");
  command->add_option("--cameras", options->cameras,
                      "kitti: cameras to import, indices 0..3 or names, e.g. 0,1 (grey stereo) or 2,3 (colour); "
                      "default every image_0i folder present");
  command->add_option("--first", options->first, "kitti: first frame index to import (default 0)")->check(kNonNegative);
  command->add_option("--count", options->count, "kitti: number of frames from --first (default: to the end)")
      ->check(kPositive);
  return [options, command] {
    io::CheckOutputFolderWritable(options->output, "--output");
    const bool kitti_options = command->count("--cameras") + command->count("--first") + command->count("--count") > 0;
    if (options->format == "opencalib") {
      if (kitti_options) {
        spdlog::error("--cameras, --first and --count apply to the kitti format only");
        return kExitInvalidInput;
      }
      const io::OpenCalibImportSummary summary = io::ImportOpenCalib(options->source, options->output, options->force);
      spdlog::info("imported {} -> {}: image {}x{}, {} lidar points ({} no-returns)", options->source,
                   summary.dataset.string(), summary.image_width, summary.image_height, summary.points,
                   summary.no_returns);
      return kExitSuccess;
    }

    io::KittiImportOptions kitti;
    if (command->count("--cameras") > 0) {
      const std::optional<std::vector<int>> cameras = ParseCameraList(options->cameras);
      if (!cameras) {
        spdlog::error("--cameras '{}': expected distinct camera indices 0..3 separated by commas, e.g. 0,1 or 2,3",
                      options->cameras);
        return kExitInvalidInput;
      }
      kitti.cameras = *cameras;
    }
    kitti.first = options->first;
    if (command->count("--count") > 0) kitti.count = options->count;
    kitti.overwrite = options->force;
    // Copying a drive takes a while: report about every 10% of the files.
    std::size_t next_report = 0;
    const auto start = std::chrono::steady_clock::now();
    kitti.progress = [&next_report, start](std::size_t done, std::size_t total) {
      if (done < next_report && done != total) return;
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      spdlog::info("copied {}/{} images and scans ({:.0f}%, {:.1f} s)", done, total, 100.0 * done / total, seconds);
      next_report = done + std::max<std::size_t>(total / 10, 1);
    };
    spdlog::info("reading and checking the KITTI drive {}", options->source);
    const io::KittiImportSummary summary = io::ImportKitti(options->source, options->output, kitti);
    std::string names;
    for (const std::string& name : summary.cameras) names += (names.empty() ? "" : ",") + name;
    spdlog::info(
        "imported {} -> {}: frames {}..{}, cameras {} (base {}), lidar velodyne, {} images, {} scans, "
        "{} trajectory rows; calibration from {}",
        options->source, summary.dataset.string(), summary.first_frame, summary.first_frame + summary.frames - 1, names,
        summary.base_frame, summary.images, summary.scans, summary.poses, summary.calibration_dir.string());
    if (summary.lost > 0) {
      spdlog::warn("{} sensor frames in the range had no data (empty timestamps.txt lines) and were skipped",
                   summary.lost);
    }
    return kExitSuccess;
  };
}

}  // namespace scenecal::cli
