#include "core/pair_cost.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
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

namespace {

// The used scenes of one image time, over the pairs: they share one motion correction.
class CorrectionFrame {
 public:
  void Add(SceneSwathe* swathe, std::function<double()> cost) {
    swathes_.push_back(swathe);
    costs_.push_back(std::move(cost));
  }
  SwatheMotionCorrection Correction() const { return swathes_.front()->MotionCorrection(); }
  void Apply(const SwatheMotionCorrection& correction) const {
    for (SceneSwathe* swathe : swathes_) swathe->SetMotionCorrection(correction);
  }
  // The mean of the scenes' costs at their pairs' transforms.
  double Cost() const {
    double sum = 0.0;
    for (const std::function<double()>& cost : costs_) sum += cost();
    return sum / static_cast<double>(costs_.size());
  }

 private:
  std::vector<SceneSwathe*> swathes_;
  std::vector<std::function<double()>> costs_;  // per scene
};

// The drive's scale: one value in every frame, scored by the mean of all
// frames' costs, so that it cannot follow each frame's own misfit the way a
// per-frame scale does. Leaves every frame at the answer and *costs (per
// frame) at their costs there.
NelderMeadSummary EstimateDriveScale(const std::vector<const CorrectionFrame*>& frames,
                                     const MotionCorrectionOptions& options, std::vector<double>* costs) {
  const auto drive_cost = [&](const Eigen::VectorXd& candidate) {
    if (std::abs(candidate[0]) > options.max_scale) return std::numeric_limits<double>::infinity();
    tbb::parallel_for(std::size_t{0}, frames.size(), [&](std::size_t g) {
      SwatheMotionCorrection correction = frames[g]->Correction();
      correction.scale = candidate[0];
      frames[g]->Apply(correction);
      (*costs)[g] = frames[g]->Cost();
    });
    double sum = 0.0;
    for (const double c : *costs) sum += c;
    return sum / static_cast<double>(costs->size());
  };
  Eigen::VectorXd x(1);
  x[0] = frames.front()->Correction().scale;
  NelderMeadOptions nelder_mead;
  nelder_mead.max_iterations = options.max_iterations;
  const Eigen::VectorXd step = Eigen::VectorXd::Constant(1, options.initial_step_scale);
  const NelderMeadSummary drive = MinimiseNelderMead(drive_cost, step, step * 0.01, nelder_mead, &x);
  drive_cost(x);  // leave every frame at the answer
  return drive;
}

// The terms each frame's correction is free to move, in the order scale,
// turn a, turn b, roll, with their simplex steps and bounds.
class FreeTerms {
 public:
  explicit FreeTerms(const MotionCorrectionOptions& options) {
    terms_.reserve(4);
    for (int term = 0; term < 4; ++term) {
      const bool is_free = term == 0 ? options.scale : term == 3 ? options.roll : options.turn;
      if (is_free) terms_.push_back(term);
    }
    const double rate = options.max_rate_rad_per_m, rate_step = options.initial_step_rate_rad_per_m;
    const Eigen::Vector4d bounds(options.max_scale, rate, rate, rate);
    const Eigen::Vector4d term_steps(options.initial_step_scale, rate_step, rate_step, rate_step);
    steps_.resize(Count());
    bounds_.resize(Count());
    for (Eigen::Index i = 0; i < Count(); ++i) {
      steps_[i] = term_steps[Term(i)];
      bounds_[i] = bounds[Term(i)];
    }
  }
  Eigen::Index Count() const { return static_cast<Eigen::Index>(terms_.size()); }
  const Eigen::VectorXd& Steps() const { return steps_; }
  bool InBounds(const Eigen::VectorXd& x) const { return !(x.array().abs() > bounds_.array()).any(); }
  // x: the free terms of all four.
  Eigen::VectorXd From(const Eigen::Vector4d& terms) const {
    Eigen::VectorXd x(Count());
    for (Eigen::Index i = 0; i < Count(); ++i) x[i] = terms[Term(i)];
    return x;
  }
  // The free terms from x, the others as they were in `base`.
  SwatheMotionCorrection Correction(const Eigen::VectorXd& x, const Eigen::Vector4d& base) const {
    Eigen::Vector4d terms = base;
    for (std::size_t i = 0; i < terms_.size(); ++i) terms[terms_[i]] = x[static_cast<Eigen::Index>(i)];
    return SwatheMotionCorrection{terms[0], terms[1], terms[2], terms[3]};
  }

 private:
  int Term(Eigen::Index i) const { return terms_[static_cast<std::size_t>(i)]; }
  std::vector<int> terms_;
  Eigen::VectorXd steps_, bounds_;
};

struct FrameOutcome {
  int evaluations = 0;
  double before = 0.0, after = 0.0;
};

// One frame's free terms by the simplex, from its correction before; leaves the frame at the answer.
FrameOutcome CorrectFrame(const CorrectionFrame& frame, const FreeTerms& free_terms,
                          const MotionCorrectionOptions& options) {
  const SwatheMotionCorrection start = frame.Correction();
  const Eigen::Vector4d start_terms(start.scale, start.turn_a_rad_per_m, start.turn_b_rad_per_m, start.roll_rad_per_m);
  Eigen::VectorXd x = free_terms.From(start_terms);
  NelderMeadOptions nelder_mead;
  nelder_mead.max_iterations = options.max_iterations;
  const auto cost = [&](const Eigen::VectorXd& candidate) {
    if (!free_terms.InBounds(candidate)) {
      return std::numeric_limits<double>::infinity();  // outside the bounds: worse than any cost
    }
    frame.Apply(free_terms.Correction(candidate, start_terms));
    return frame.Cost();
  };
  const Eigen::VectorXd& steps = free_terms.Steps();
  const NelderMeadSummary summary = MinimiseNelderMead(cost, steps, steps * 0.01, nelder_mead, &x);
  frame.Apply(free_terms.Correction(x, start_terms));
  return {summary.evaluations, summary.initial_value, summary.final_value};
}

// The frames' mean costs before and after; the drive's cost before instead, when it was estimated.
void AddOutcomes(const std::vector<FrameOutcome>& outcomes, double drive_cost_before,
                 MotionCorrectionSummary* summary) {
  for (const FrameOutcome& outcome : outcomes) {
    ++summary->frames;
    summary->evaluations += outcome.evaluations;
    summary->cost_before += outcome.before;
    summary->cost_after += outcome.after;
  }
  if (summary->frames > 0) {
    summary->cost_before /= summary->frames;
    summary->cost_after /= summary->frames;
  }
  if (!std::isnan(drive_cost_before)) summary->cost_before = drive_cost_before;
}

}  // namespace

MotionCorrectionSummary EstimateMotionCorrections(const std::vector<PairCost*>& pairs,
                                                  const std::vector<Eigen::Isometry3d>& T_camera_lidar,
                                                  const MotionCorrectionOptions& options) {
  // The used scenes of each image time, over the pairs.
  std::map<TimeUs, CorrectionFrame> frames_by_time;
  for (std::size_t p = 0; p < pairs.size() && p < T_camera_lidar.size(); ++p) {
    PairCost* pair = pairs[p];
    const Eigen::Isometry3d* T = &T_camera_lidar[p];
    for (const std::size_t s : pair->used_) {
      frames_by_time[pair->scenes_[s].ImageTime()].Add(&pair->scenes_[s],
                                                       [pair, s, T] { return pair->SceneCost(s, *T, nullptr); });
    }
  }
  std::vector<const CorrectionFrame*> frames;
  for (const auto& [time, frame] : frames_by_time) frames.push_back(&frame);

  MotionCorrectionSummary summary;
  double drive_cost_before = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> costs(frames.size());  // each frame's, at the drive's scale last tried
  if (options.drive_scale && !frames.empty()) {
    const NelderMeadSummary drive = EstimateDriveScale(frames, options, &costs);
    summary.drive_evaluations = drive.evaluations;
    drive_cost_before = drive.initial_value;
  }

  const FreeTerms free_terms(options);
  std::vector<FrameOutcome> outcomes(frames.size());
  if (free_terms.Count() > 0) {
    tbb::parallel_for(std::size_t{0}, frames.size(),
                      [&](std::size_t g) { outcomes[g] = CorrectFrame(*frames[g], free_terms, options); });
  } else {  // the drive's scale alone: the frames' costs at its answer, from its last evaluation
    for (std::size_t g = 0; g < frames.size(); ++g) outcomes[g].before = outcomes[g].after = costs[g];
  }
  AddOutcomes(outcomes, drive_cost_before, &summary);
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
