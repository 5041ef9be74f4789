#include "cli/load_input.hpp"

#include <algorithm>
#include <exception>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include "core/geometry.hpp"
#include "core/interrupt.hpp"

namespace scenecal::cli {

LoadedScenes SelectAndLoadScenes(const io::Dataset& dataset, const SceneOptions& scene_options,
                                 CalibrationInput* input, io::ImageChannel channel) {
  std::map<std::string, std::vector<TimeUs>> image_times, scan_times;
  for (const auto& [camera, files] : dataset.images) {
    for (const io::SensorFile& f : files) image_times[camera].push_back(f.t_us);
  }
  for (const auto& [lidar, files] : dataset.scans) {
    for (const io::SensorFile& f : files) scan_times[lidar].push_back(f.t_us);
  }
  input->selection = SelectScenes(dataset.rig, dataset.trajectory, image_times, scan_times, scene_options);
  std::istringstream report(input->selection.Report());
  for (std::string line; std::getline(report, line);) spdlog::info("{}", line);
  // A lidar without scenes is refused here, naming the selection step that
  // removed its frames (not later, as if the images lacked information).
  for (const LidarInfo& lidar : dataset.rig.lidars) {
    const std::string why = input->selection.WhyNoScenes(lidar);
    if (why.empty()) continue;
    std::string advice;
    if (lidar.kind == LidarKind::k2d && scene_options.swathe_length_m > input->selection.trajectory_length_m) {
      advice = " Record a longer drive, or shorten --swathe-length (at most the drive's length).";
    }
    throw std::runtime_error("the data cannot be calibrated: " + why + advice);
  }

  // Load only what the scenes use, in parallel.
  std::vector<std::pair<std::string, const io::SensorFile*>> image_files, scan_files;
  {
    std::set<std::pair<std::string, TimeUs>> images_needed, scans_needed;
    for (const Scene& scene : input->selection.scenes) {
      images_needed.insert({scene.camera, scene.image_t_us});
      for (const SwatheScan& scan : scene.scans) scans_needed.insert({scene.lidar, scan.t_us});
    }
    const auto find = [](const std::vector<io::SensorFile>& files, TimeUs t) {
      const auto it = std::lower_bound(files.begin(), files.end(), t,
                                       [](const io::SensorFile& f, TimeUs time) { return f.t_us < time; });
      return it != files.end() && it->t_us == t ? &*it : nullptr;
    };
    for (const auto& [camera, t] : images_needed) image_files.push_back({camera, find(dataset.images.at(camera), t)});
    for (const auto& [lidar, t] : scans_needed) scan_files.push_back({lidar, find(dataset.scans.at(lidar), t)});
  }
  spdlog::info("loading {} images and {} scans", image_files.size(), scan_files.size());
  std::vector<GreyImage> images(image_files.size());
  std::vector<LidarScan> scans(scan_files.size());
  tbb::parallel_for(std::size_t{0}, image_files.size(), [&](std::size_t i) {
    ThrowIfInterrupted();
    images[i] = io::ReadImage(*image_files[i].second, dataset.rig.FindCamera(image_files[i].first)->model, channel);
  });
  tbb::parallel_for(std::size_t{0}, scan_files.size(),
                    [&](std::size_t i) {
                      ThrowIfInterrupted();
                      scans[i] = io::ReadScan(*scan_files[i].second);
                    });
  LoadedScenes loaded;
  loaded.images = images.size();
  loaded.scans = scans.size();
  for (std::size_t i = 0; i < images.size(); ++i) {
    input->images[image_files[i].first][image_files[i].second->t_us] = std::move(images[i]);
  }
  for (std::size_t i = 0; i < scans.size(); ++i) {
    loaded.lidar_points += scans[i].points.size();
    input->scans[scan_files[i].first][scan_files[i].second->t_us] = std::move(scans[i]);
  }
  return loaded;
}

bool IsSingleFrame3d(const io::Dataset& dataset) {
  if (dataset.trajectory.size() != 1 || dataset.rig.lidars.empty()) return false;
  return std::all_of(dataset.rig.lidars.begin(), dataset.rig.lidars.end(),
                     [](const LidarInfo& lidar) { return lidar.kind == LidarKind::k3d; });
}

std::string ApplySingleFrameDefaults(const io::Dataset& dataset, bool bins_given, CalibrationOptions* options) {
  if (!IsSingleFrame3d(dataset) || bins_given) return "";
  options->cost.histogram.reflectance_bins = kSingleFrameBins;
  options->cost.histogram.intensity_bins = kSingleFrameBins;
  return "bins " + std::to_string(kSingleFrameBins) + "x" + std::to_string(kSingleFrameBins) +
         " (single-frame 3D-lidar data: ~10^4 samples per histogram; --bins overrides)";
}

Eigen::Isometry3d PerturbExactly(const Eigen::Isometry3d& T, double translation_m, double rotation_deg,
                                 std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  const auto random_unit = [&] {
    Eigen::Vector3d v;
    do {
      v = Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    } while (v.norm() < 1e-9);
    return Eigen::Vector3d(v.normalized());
  };
  // Draw order (translation direction, then rotation axis) as calibrate's --perturb-*.
  const Eigen::Vector3d translation = translation_m * random_unit();
  const Eigen::Matrix3d rotation = ExpSO3(RadiansFromDegrees(rotation_deg) * random_unit());
  Eigen::Isometry3d moved = T;
  moved.linear() = rotation * T.linear();
  moved.translation() = T.translation() + translation;
  return moved;
}

bool ParseStageSchedule(const std::string& text, std::vector<OptimisationStage>* stages) {
  stages->clear();
  std::istringstream entries(text);
  for (std::string entry; std::getline(entries, entry, ',');) {
    std::istringstream fields(entry);
    std::vector<std::string> parts;
    for (std::string part; std::getline(fields, part, ':');) parts.push_back(part);
    if (parts.empty() || parts.size() > 3) return false;
    OptimisationStage stage;
    try {
      std::size_t used = 0;
      stage.step_scale = std::stod(parts[0], &used);
      if (used != parts[0].size()) return false;
      if (parts.size() > 1) {
        stage.blur_fraction = std::stod(parts[1], &used);
        if (used != parts[1].size()) return false;
      }
      if (parts.size() > 2) {
        stage.restarts = std::stoi(parts[2], &used);
        if (used != parts[2].size()) return false;
      }
    } catch (const std::exception&) {
      return false;
    }
    stages->push_back(stage);
  }
  return !stages->empty();
}

}  // namespace scenecal::cli
