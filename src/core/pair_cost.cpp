#include "core/pair_cost.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>

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

bool MotionCorrectionOptions::IsValid(std::string* why) const {
  if (!(max_scale > 0.0 && max_scale < 0.5)) return Invalid(why, "motion correction: max_scale must be in (0, 0.5)");
  if (!(max_rate_rad_per_m > 0.0 && max_rate_rad_per_m < 0.1))
    return Invalid(why, "motion correction: max_rate_rad_per_m must be in (0, 0.1)");
  if (!(initial_step_scale > 0.0 && initial_step_scale <= max_scale))
    return Invalid(why, "motion correction: initial_step_scale must be in (0, max_scale]");
  if (!(initial_step_rate_rad_per_m > 0.0 && initial_step_rate_rad_per_m <= max_rate_rad_per_m))
    return Invalid(why, "motion correction: initial_step_rate_rad_per_m must be in (0, max_rate_rad_per_m]");
  if (max_iterations < 1) return Invalid(why, "motion correction: max_iterations must be at least 1");
  if (!scale && !turn && !roll && !drive_scale) return Invalid(why, "motion correction: no term to estimate");
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
    scenes_[s].SetImageBlur(fraction_of_width * static_cast<double>(scenes_[s].Image().cols));
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

MotionCorrectionSummary EstimateMotionCorrections(const std::vector<PairCost*>& pairs,
                                                  const std::vector<Eigen::Isometry3d>& T_camera_lidar,
                                                  const MotionCorrectionOptions& options) {
  struct Member {
    PairCost* pair;
    std::size_t scene;
    const Eigen::Isometry3d* T_camera_lidar;
  };
  // The used scenes of each image time, over the pairs.
  std::map<TimeUs, std::vector<Member>> frames;
  for (std::size_t p = 0; p < pairs.size() && p < T_camera_lidar.size(); ++p) {
    for (const std::size_t s : pairs[p]->used_)
      frames[pairs[p]->scenes_[s].ImageTime()].push_back({pairs[p], s, &T_camera_lidar[p]});
  }
  std::vector<const std::vector<Member>*> groups;
  for (const auto& [time, members] : frames) groups.push_back(&members);
  const auto apply = [](const std::vector<Member>& members, const SwatheMotionCorrection& correction) {
    for (const Member& member : members) member.pair->scenes_[member.scene].SetMotionCorrection(correction);
  };

  // The free terms, in the order scale, turn a, turn b, roll.
  std::vector<int> free_terms;
  free_terms.reserve(4);
  for (int term = 0; term < 4; ++term) {
    const bool free = term == 0 ? options.scale : term == 3 ? options.roll : options.turn;
    if (free) free_terms.push_back(term);
  }
  const double rate = options.max_rate_rad_per_m, rate_step = options.initial_step_rate_rad_per_m;
  const Eigen::Vector4d bounds(options.max_scale, rate, rate, rate);
  const Eigen::Vector4d term_steps(options.initial_step_scale, rate_step, rate_step, rate_step);
  const auto n = static_cast<Eigen::Index>(free_terms.size());
  Eigen::VectorXd steps(n), free_bounds(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    steps[i] = term_steps[free_terms[static_cast<std::size_t>(i)]];
    free_bounds[i] = bounds[free_terms[static_cast<std::size_t>(i)]];
  }
  // The free terms from x, the others as they were (base: the frame's correction before).
  const auto from_vector = [&](const Eigen::VectorXd& x, const Eigen::Vector4d& base) {
    Eigen::Vector4d terms = base;
    for (std::size_t i = 0; i < free_terms.size(); ++i) terms[free_terms[i]] = x[static_cast<Eigen::Index>(i)];
    return SwatheMotionCorrection{terms[0], terms[1], terms[2], terms[3]};
  };

  const auto frame_cost = [](const std::vector<Member>& members) {
    double sum = 0.0;
    for (const Member& member : members) sum += member.pair->SceneCost(member.scene, *member.T_camera_lidar, nullptr);
    return sum / static_cast<double>(members.size());
  };

  MotionCorrectionSummary summary;
  // The drive's scale first: one value in every frame, scored by the mean of
  // all frames' costs, so that it cannot follow each frame's own misfit the
  // way a per-frame scale does.
  double drive_cost_before = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> costs(groups.size());  // each frame's, at the drive's scale last tried
  if (options.drive_scale && !groups.empty()) {
    const auto drive_cost = [&](const Eigen::VectorXd& candidate) {
      if (std::abs(candidate[0]) > options.max_scale) return std::numeric_limits<double>::infinity();
      tbb::parallel_for(std::size_t{0}, groups.size(), [&](std::size_t g) {
        const std::vector<Member>& members = *groups[g];
        SwatheMotionCorrection correction = members.front().pair->scenes_[members.front().scene].MotionCorrection();
        correction.scale = candidate[0];
        apply(members, correction);
        costs[g] = frame_cost(members);
      });
      double sum = 0.0;
      for (const double c : costs) sum += c;
      return sum / static_cast<double>(costs.size());
    };
    const std::vector<Member>& first = *groups.front();
    Eigen::VectorXd x(1);
    x[0] = first.front().pair->scenes_[first.front().scene].MotionCorrection().scale;
    NelderMeadOptions nelder_mead;
    nelder_mead.max_iterations = options.max_iterations;
    const Eigen::VectorXd step = Eigen::VectorXd::Constant(1, options.initial_step_scale);
    const NelderMeadSummary drive = MinimiseNelderMead(drive_cost, step, step * 0.01, nelder_mead, &x);
    drive_cost(x);  // leave every frame at the answer
    summary.drive_evaluations = drive.evaluations;
    drive_cost_before = drive.initial_value;
  }

  struct FrameOutcome {
    int evaluations = 0;
    double before = 0.0, after = 0.0;
  };
  std::vector<FrameOutcome> outcomes(groups.size());
  if (n > 0) {
    tbb::parallel_for(std::size_t{0}, groups.size(), [&](std::size_t g) {
      const std::vector<Member>& members = *groups[g];
      const SwatheMotionCorrection start = members.front().pair->scenes_[members.front().scene].MotionCorrection();
      const Eigen::Vector4d start_terms(start.scale, start.turn_a_rad_per_m, start.turn_b_rad_per_m,
                                        start.roll_rad_per_m);
      Eigen::VectorXd x(n);
      for (Eigen::Index i = 0; i < n; ++i) x[i] = start_terms[free_terms[static_cast<std::size_t>(i)]];
      NelderMeadOptions nelder_mead;
      nelder_mead.max_iterations = options.max_iterations;
      const auto cost = [&](const Eigen::VectorXd& candidate) {
        if ((candidate.array().abs() > free_bounds.array()).any()) {
          return std::numeric_limits<double>::infinity();  // outside the bounds: worse than any cost
        }
        apply(members, from_vector(candidate, start_terms));
        return frame_cost(members);
      };
      const NelderMeadSummary frame = MinimiseNelderMead(cost, steps, steps * 0.01, nelder_mead, &x);
      apply(members, from_vector(x, start_terms));
      outcomes[g] = {frame.evaluations, frame.initial_value, frame.final_value};
    });
  } else {  // the drive's scale alone: the frames' costs at its answer, from its last evaluation
    for (std::size_t g = 0; g < groups.size(); ++g) outcomes[g].before = outcomes[g].after = costs[g];
  }

  for (const FrameOutcome& outcome : outcomes) {
    ++summary.frames;
    summary.evaluations += outcome.evaluations;
    summary.cost_before += outcome.before;
    summary.cost_after += outcome.after;
  }
  if (summary.frames > 0) {
    summary.cost_before /= summary.frames;
    summary.cost_after /= summary.frames;
  }
  if (!std::isnan(drive_cost_before)) summary.cost_before = drive_cost_before;
  for (const PairCost* pair : pairs)
    for (const SceneSwathe& scene : pair->scenes_) summary.corrections.push_back(scene.MotionCorrection());
  return summary;
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
