// Test support: a small simulated RobotCar dataset (stereo + rear push-broom
// lidar, 480x360 images, 120 m, exact odometry; or the trinocular rig on the
// same drive) and the calibration input that
// `scenecal calibrate` would load from it.
#pragma once

#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "core/calibrate.hpp"
#include "io/dataset.hpp"
#include "sim/simulator.hpp"
#include "shared_simulation.hpp"

namespace scenecal::test {

inline sim::SimulationOptions SmallSimulationOptions(std::uint64_t seed) {
  sim::SimulationOptions options;
  options.seed = seed;
  options.distance_m = 120.0;
  options.image_width = 480;
  options.image_height = 360;
  options.image_rate_hz = 1.0;
  options.odometry_noise = 0.0;
  options.perturb_translation_m = 0.05;
  options.perturb_rotation_deg = 2.0;
  return options;
}

inline void SimulateSmallRobotCar(const std::filesystem::path& root, std::uint64_t seed = 1) {
  sim::Simulate(SmallSimulationOptions(seed), root);
}

// The small RobotCar drive (seed 1), simulated once for all of a test executable's processes
// (support/shared_simulation.hpp): read only.
inline std::filesystem::path SharedSmallRobotCar() {
  return SharedSimulation("robotcar", [](const std::filesystem::path& folder) { SimulateSmallRobotCar(folder); });
}

// The same drive with the trinocular rig: three cameras, rear and front push-broom lidars.
inline void SimulateSmallTrinocular(const std::filesystem::path& root) {
  sim::SimulationOptions options = SmallSimulationOptions(1);
  options.preset = sim::Preset::kTrinocular;
  sim::Simulate(options, root);
}

// Selects scenes and loads what they use (what `scenecal calibrate` does).
inline CalibrationInput LoadCalibrationInput(const io::Dataset& dataset, const SceneOptions& scene_options) {
  std::map<std::string, std::vector<TimeUs>> image_times, scan_times;
  for (const auto& [camera, files] : dataset.images) {
    for (const auto& f : files) image_times[camera].push_back(f.t_us);
  }
  for (const auto& [lidar, files] : dataset.scans) {
    for (const auto& f : files) scan_times[lidar].push_back(f.t_us);
  }
  CalibrationInput input;
  input.rig = dataset.rig;
  input.selection = SelectScenes(dataset.rig, dataset.trajectory, image_times, scan_times, scene_options);
  for (const Scene& scene : input.selection.scenes) {
    for (const auto& f : dataset.images.at(scene.camera)) {
      if (f.t_us == scene.image_t_us) {
        input.images[scene.camera][f.t_us] = io::ReadImage(f, dataset.rig.FindCamera(scene.camera)->model);
      }
    }
    std::set<TimeUs> needed;
    for (const SwatheScan& scan : scene.scans) needed.insert(scan.t_us);
    for (const auto& f : dataset.scans.at(scene.lidar)) {
      if (needed.count(f.t_us) != 0 && input.scans[scene.lidar].count(f.t_us) == 0) {
        input.scans[scene.lidar][f.t_us] = io::ReadScan(f);
      }
    }
  }
  return input;
}

}  // namespace scenecal::test
