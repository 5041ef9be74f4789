#include "core/pair_cost.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <stdexcept>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/interrupt.hpp"
#include "core/validation.hpp"

namespace scenecal {

bool PairCostOptions::IsValid(std::string* why) const {
  if (!histogram.IsValid(why)) return false;
  if (!swathe.IsValid(why)) return false;
  if (min_points_per_scene < 1) return Invalid(why, "min_points_per_scene must be at least 1");
  return true;
}

const char* SceneStateName(SceneState state) {
  switch (state) {
    case SceneState::kUsed: return "used";
    case SceneState::kTooFewPoints: return "too few projected points";
    case SceneState::kConstantImage: return "constant image";
    case SceneState::kConstantReflectance: return "constant reflectance";
  }
  return "unknown";
}

PairCost::PairCost(CameraInfo camera, std::string lidar, std::vector<SceneSwathe> scenes, PairCostOptions options)
    : camera_(std::move(camera)), lidar_(std::move(lidar)), scenes_(std::move(scenes)), options_(options) {
  states_.assign(scenes_.size(), SceneState::kUsed);
  projected_at_refresh_.assign(scenes_.size(), 0);
  // Until the first refresh: every informative scene with enough points at all.
  for (std::size_t s = 0; s < scenes_.size(); ++s) {
    if (scenes_[s].ImageIsConstant()) states_[s] = SceneState::kConstantImage;
    else if (scenes_[s].ReflectanceIsConstant()) states_[s] = SceneState::kConstantReflectance;
    else if (scenes_[s].PointCount() < static_cast<std::size_t>(options_.min_points_per_scene))
      states_[s] = SceneState::kTooFewPoints;
    if (states_[s] == SceneState::kUsed) used_.push_back(s);
  }
}

void PairCost::SetImageBlur(double fraction_of_width) {
  tbb::parallel_for(std::size_t{0}, scenes_.size(), [&](std::size_t s) {
    ThrowIfInterrupted();
    const double sigma_px = fraction_of_width * static_cast<double>(scenes_[s].Image().cols);
    scenes_[s].SetImageBlur(sigma_px, PointStrideForBlur(sigma_px, options_.swathe.blur_px_per_point_stride));
  });
}

Eigen::Vector3d PairCost::SumProjectedLidarPoints(const Eigen::Isometry3d& T_camera_lidar, std::size_t* count) const {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  std::size_t total = 0;
  for (const std::size_t s : used_) {
    std::size_t n = 0;
    sum += scenes_[s].SumProjectedLidarPoints(T_camera_lidar, &n);
    total += n;
  }
  if (count != nullptr) *count = total;
  return sum;
}

int PairCost::UsedSceneCount() const { return static_cast<int>(used_.size()); }

int PairCost::CountState(SceneState state) const {
  return static_cast<int>(std::count(states_.begin(), states_.end(), state));
}

int PairCost::RefreshVisibility(const Eigen::Isometry3d& T_camera_lidar) {
  tbb::parallel_for(std::size_t{0}, scenes_.size(), [&](std::size_t s) {
    ThrowIfInterrupted();
    scenes_[s].RefreshVisibility(T_camera_lidar, options_.swathe);
    projected_at_refresh_[s] = scenes_[s].CountProjected(T_camera_lidar);
  });
  used_.clear();
  for (std::size_t s = 0; s < scenes_.size(); ++s) {
    if (scenes_[s].ImageIsConstant()) states_[s] = SceneState::kConstantImage;
    else if (scenes_[s].ReflectanceIsConstant()) states_[s] = SceneState::kConstantReflectance;
    else if (projected_at_refresh_[s] < static_cast<std::size_t>(options_.min_points_per_scene))
      states_[s] = SceneState::kTooFewPoints;
    else states_[s] = SceneState::kUsed;
    if (states_[s] == SceneState::kUsed) used_.push_back(s);
  }
  return static_cast<int>(used_.size());
}

int PairCost::FrameCount() const {
  std::vector<TimeUs> times;
  for (const SceneSwathe& scene : scenes_) times.push_back(scene.ImageTime());
  std::sort(times.begin(), times.end());
  return static_cast<int>(std::unique(times.begin(), times.end()) - times.begin());
}

std::vector<SwatheMotionCorrection> PairCost::MotionCorrections() const {
  std::vector<SwatheMotionCorrection> corrections;
  corrections.reserve(scenes_.size());
  for (const SceneSwathe& scene : scenes_) corrections.push_back(scene.MotionCorrection());
  return corrections;
}

void PairCost::SetMotionCorrections(const std::vector<SwatheMotionCorrection>& corrections) {
  if (corrections.size() != scenes_.size()) {
    throw std::invalid_argument("PairCost::SetMotionCorrections: one correction per scene expected");
  }
  for (std::size_t s = 0; s < scenes_.size(); ++s) scenes_[s].SetMotionCorrection(corrections[s]);
}

std::vector<Matrix6d> PairCost::UsedScenesInformation(const Eigen::Isometry3d& T_camera_lidar,
                                                      std::vector<double>* gradient_weights) const {
  std::vector<Matrix6d> per_scene(scenes_.size(), Matrix6d::Zero());
  if (gradient_weights != nullptr) gradient_weights->assign(scenes_.size(), 0.0);
  tbb::parallel_for(std::size_t{0}, used_.size(), [&](std::size_t k) {
    ThrowIfInterrupted();
    const std::size_t s = used_[k];
    per_scene[s] = scenes_[s].AlignmentInformation(
        T_camera_lidar, gradient_weights != nullptr ? &(*gradient_weights)[s] : nullptr);
  });
  return per_scene;
}

Matrix6d PairCost::AlignmentInformation(const Eigen::Isometry3d& T_camera_lidar, double* gradient_weight) const {
  std::vector<double> weights;
  const std::vector<Matrix6d> per_scene = UsedScenesInformation(T_camera_lidar, &weights);
  Matrix6d information = Matrix6d::Zero();
  double weight = 0.0;
  for (const std::size_t s : used_) {  // in order: deterministic
    information += per_scene[s];
    weight += weights[s];
  }
  *gradient_weight = weight;
  return information;
}

InformativeChoice PairCost::KeepMostInformative(const Eigen::Isometry3d& T_camera_lidar, int count,
                                                const InformativeChoiceOptions& options) {
  const std::vector<Matrix6d> per_scene = UsedScenesInformation(T_camera_lidar);
  // One candidate per camera frame: its swathes together.
  std::map<TimeUs, std::size_t> frame_of_time;
  for (const SceneSwathe& scene : scenes_) frame_of_time.emplace(scene.ImageTime(), 0);
  std::size_t next = 0;
  for (auto& [time, frame] : frame_of_time) frame = next++;
  std::vector<Matrix6d> per_frame(frame_of_time.size(), Matrix6d::Zero());
  for (std::size_t s = 0; s < scenes_.size(); ++s) per_frame[frame_of_time.at(scenes_[s].ImageTime())] += per_scene[s];
  InformativeChoice choice = ChooseInformativeScenes(per_frame, static_cast<std::size_t>(std::max(0, count)), options);
  std::vector<bool> keep_frame(per_frame.size(), false);
  for (const std::size_t frame : choice.chosen) keep_frame[frame] = true;
  std::vector<SceneSwathe> kept;
  for (SceneSwathe& scene : scenes_) {
    if (keep_frame[frame_of_time.at(scene.ImageTime())]) kept.push_back(std::move(scene));
  }
  scenes_ = std::move(kept);
  // Every kept scene counts until the next refresh decides.
  states_.assign(scenes_.size(), SceneState::kUsed);
  projected_at_refresh_.assign(scenes_.size(), 0);
  used_.clear();
  for (std::size_t s = 0; s < scenes_.size(); ++s) used_.push_back(s);
  return choice;
}

double PairCost::SceneCost(std::size_t scene, const Eigen::Isometry3d& T_camera_lidar, std::size_t* projected) const {
  const SceneSwathe& swathe = scenes_[scene];
  JointHistogram histogram(options_.histogram);
  if (options_.histogram.binning == Binning::kHard) {
    // Integer counts in a per-thread table (no allocation once warm), added to
    // the histogram once: exact, and the same weights as AddHard per sample
    // (AddHardCounts: the same bins as ForEachProjected + Sampler + HardBin,
    // with the sampling and binning vectorised).
    const int nx = histogram.ReflectanceBins(), ny = histogram.IntensityBins();
    thread_local std::vector<std::uint32_t> counts;
    counts.assign(static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny), 0u);
    const std::size_t samples = swathe.AddHardCounts(T_camera_lidar, nx, ny, counts.data());
    histogram.AddCounts(counts.data(), samples);
  } else {
    // The same weights, bit for bit, as ForEachProjected + AddBSpline per point.
    swathe.AddBSplineSamples(T_camera_lidar, &histogram);
  }
  if (projected != nullptr) *projected = histogram.Samples();
  return CostValue(ComputeInformation(histogram), options_.metric);
}

double PairCost::Evaluate(const Eigen::Isometry3d& T_camera_lidar) const {
  if (used_.empty()) return std::numeric_limits<double>::quiet_NaN();
  // Scenes in parallel, each filled in a fixed order by one task, and summed
  // in scene order: the same input gives bit-identical costs whatever the
  // thread count or scheduling (the MPI backend relies on it).
  thread_local std::vector<double> scene_costs;
  std::vector<double>& costs = scene_costs;
  costs.assign(used_.size(), 0.0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, used_.size(), 1),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t i = range.begin(); i != range.end(); ++i)
                        costs[i] = SceneCost(used_[i], T_camera_lidar, nullptr);
                    });
  double sum = 0.0;
  for (const double c : costs) sum += c;
  return sum / static_cast<double>(used_.size());
}

double PairCost::SceneCostAndGradient(std::size_t scene, const Eigen::Isometry3d& T_camera_lidar,
                                      TransformUpdate update, const Eigen::Vector3d& pivot_source,
                                      Vector6d* gradient) const {
  const SceneSwathe& swathe = scenes_[scene];
  if (options_.histogram.binning == Binning::kHard) {
    *gradient = Vector6d::Zero();  // piecewise constant
    return SceneCost(scene, T_camera_lidar, nullptr);
  }
  JointHistogram histogram(options_.histogram);
  // As SceneCost (the same cost), recording the samples for the gradient pass
  // (per thread, storage reused across calls).
  thread_local SceneSwathe::GradientSamples samples;
  swathe.AddBSplineSamples(T_camera_lidar, &histogram, &samples);
  CostGradient dcost;
  dcost.Compute(histogram, options_.metric);
  *gradient = swathe.SampleGradientSum(samples, T_camera_lidar, update, pivot_source, dcost);
  return CostValue(ComputeInformation(histogram), options_.metric);
}

double PairCost::EvaluateWithGradient(const Eigen::Isometry3d& T_camera_lidar, TransformUpdate update,
                                      const Eigen::Vector3d& pivot_source, Vector6d* gradient) const {
  *gradient = Vector6d::Zero();
  if (used_.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::vector<double> costs(used_.size(), 0.0);
  std::vector<Vector6d> gradients(used_.size(), Vector6d::Zero());
  tbb::parallel_for(std::size_t{0}, used_.size(), [&](std::size_t i) {
    costs[i] = SceneCostAndGradient(used_[i], T_camera_lidar, update, pivot_source, &gradients[i]);
  });
  double sum = 0.0;
  for (std::size_t i = 0; i < used_.size(); ++i) {  // scene order: deterministic
    sum += costs[i];
    *gradient += gradients[i];
  }
  *gradient /= static_cast<double>(used_.size());
  return sum / static_cast<double>(used_.size());
}

std::vector<SceneEvaluation> PairCost::EvaluateScenes(const Eigen::Isometry3d& T_camera_lidar) const {
  std::vector<SceneEvaluation> evaluations(scenes_.size());
  tbb::parallel_for(std::size_t{0}, scenes_.size(), [&](std::size_t s) {
    evaluations[s].image_t_us = scenes_[s].ImageTime();
    evaluations[s].state = states_[s];
    evaluations[s].cost = SceneCost(s, T_camera_lidar, &evaluations[s].projected_points);
  });
  return evaluations;
}

double EvaluateJoint(const std::vector<const PairCost*>& pairs, const Eigen::Isometry3d& T_base_lidar) {
  std::vector<double> costs(pairs.size(), std::numeric_limits<double>::quiet_NaN());
  tbb::parallel_for(std::size_t{0}, pairs.size(), [&](std::size_t p) {
    if (pairs[p]->UsedSceneCount() == 0) return;
    costs[p] = pairs[p]->Evaluate(pairs[p]->Camera().T_camera_base() * T_base_lidar);
  });
  double sum = 0.0;
  int counted = 0;
  for (const double c : costs) {
    if (std::isnan(c)) continue;
    sum += c;
    ++counted;
  }
  return counted == 0 ? std::numeric_limits<double>::quiet_NaN() : sum / counted;
}

}  // namespace scenecal
