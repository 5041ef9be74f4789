#include "cli/load_input.hpp"

#include "core/number_text.hpp"

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

namespace {

void LogSelection(const SceneSelection& selection) {
  std::istringstream report(selection.Report());
  for (std::string line; std::getline(report, line);) spdlog::info("{}", line);
}

}  // namespace

LoadedScenes SelectAndLoadScenes(const io::Dataset& dataset, const SceneOptions& scene_options,
                                 CalibrationInput* input, io::ImageChannel channel) {
  LoadedScenes loaded;
  try {
    loaded = io::LoadCalibrationInput(dataset, scene_options, input, channel);
  } catch (const io::CannotCalibrate&) {
    LogSelection(input->selection);
    throw;
  }
  LogSelection(input->selection);
  spdlog::info("loaded {} images and {} scans", loaded.images, loaded.scans);
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

std::string StageScheduleText(const std::vector<OptimisationStage>& stages) {
  std::string text;
  for (const OptimisationStage& stage : stages) {
    text += (text.empty() ? "" : ",") + NumberText(stage.step_scale) + ":" + NumberText(stage.blur_fraction) + ":" +
            std::to_string(stage.restarts);
  }
  return text;
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
