#include "io/calibration_input.hpp"

#include <algorithm>
#include <map>
#include <set>
#include <utility>
#include <vector>

#include <tbb/parallel_for.h>

#include "core/interrupt.hpp"

namespace scenecal::io {

LoadedScenes LoadCalibrationInput(const Dataset& dataset, const SceneOptions& scene_options, CalibrationInput* input,
                                  ImageChannel channel) {
  std::map<std::string, std::vector<TimeUs>> image_times, scan_times;
  for (const auto& [camera, files] : dataset.images) {
    for (const SensorFile& f : files) image_times[camera].push_back(f.t_us);
  }
  for (const auto& [lidar, files] : dataset.scans) {
    for (const SensorFile& f : files) scan_times[lidar].push_back(f.t_us);
  }
  input->selection = SelectScenes(dataset.rig, dataset.trajectory, image_times, scan_times, scene_options);
  // A lidar without scenes is refused here, naming the selection step that
  // removed its frames (not later, as if the images lacked information).
  for (const LidarInfo& lidar : dataset.rig.lidars) {
    const std::string why = input->selection.WhyNoScenes(lidar);
    if (why.empty()) continue;
    std::string advice;
    if (lidar.kind == LidarKind::k2d && scene_options.swathe_length_m > input->selection.trajectory_length_m) {
      advice = " Record a longer drive, or shorten --swathe-length (at most the drive's length).";
    }
    throw CannotCalibrate("the data cannot be calibrated: " + why + advice);
  }

  // Load only what the scenes use, in parallel.
  std::vector<std::pair<std::string, const SensorFile*>> image_files, scan_files;
  {
    std::set<std::pair<std::string, TimeUs>> images_needed, scans_needed;
    for (const Scene& scene : input->selection.scenes) {
      images_needed.insert({scene.camera, scene.image_t_us});
      for (const SwatheScan& scan : scene.scans) scans_needed.insert({scene.lidar, scan.t_us});
    }
    const auto find = [](const std::vector<SensorFile>& files, TimeUs t) {
      const auto it = std::lower_bound(files.begin(), files.end(), t,
                                       [](const SensorFile& f, TimeUs time) { return f.t_us < time; });
      return it != files.end() && it->t_us == t ? &*it : nullptr;
    };
    for (const auto& [camera, t] : images_needed) image_files.push_back({camera, find(dataset.images.at(camera), t)});
    for (const auto& [lidar, t] : scans_needed) scan_files.push_back({lidar, find(dataset.scans.at(lidar), t)});
  }
  std::vector<GreyImage> images(image_files.size());
  std::vector<LidarScan> scans(scan_files.size());
  tbb::parallel_for(std::size_t{0}, image_files.size(), [&](std::size_t i) {
    ThrowIfInterrupted();
    images[i] = ReadImage(*image_files[i].second, dataset.rig.FindCamera(image_files[i].first)->model, channel);
  });
  tbb::parallel_for(std::size_t{0}, scan_files.size(),
                    [&](std::size_t i) {
                      ThrowIfInterrupted();
                      scans[i] = ReadScan(*scan_files[i].second);
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

}  // namespace scenecal::io
