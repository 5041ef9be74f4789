#include "core/motion_estimation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include "core/nelder_mead.hpp"
#include "core/validation.hpp"

namespace scenecal {

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

double CorrectionFrame::Cost() const {
  double sum = 0.0;
  for (const std::function<double()>& cost : costs_) sum += cost();
  return sum / static_cast<double>(costs_.size());
}

std::map<TimeUs, CorrectionFrame> CorrectionFramesByTime(const std::vector<PairCost*>& pairs,
                                                         const std::vector<Eigen::Isometry3d>& T_camera_lidar) {
  std::map<TimeUs, CorrectionFrame> frames_by_time;
  for (std::size_t p = 0; p < pairs.size() && p < T_camera_lidar.size(); ++p) {
    PairCost* pair = pairs[p];
    const Eigen::Isometry3d* T = &T_camera_lidar[p];
    for (const std::size_t s : pair->used_) {
      frames_by_time[pair->scenes_[s].ImageTime()].Add(&pair->scenes_[s],
                                                       [pair, s, T] { return pair->SceneCost(s, *T, nullptr); });
    }
  }
  return frames_by_time;
}

namespace {

// A correction's four terms in the order scale, turn a, turn b, roll, and back.
Eigen::Vector4d TermsOf(const SwatheMotionCorrection& c) {
  return {c.scale, c.turn_a_rad_per_m, c.turn_b_rad_per_m, c.roll_rad_per_m};
}
SwatheMotionCorrection CorrectionOf(const Eigen::Vector4d& terms) {
  return SwatheMotionCorrection{terms[0], terms[1], terms[2], terms[3]};
}

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
    return CorrectionOf(terms);
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
  const Eigen::Vector4d start_terms = TermsOf(frame.Correction());
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
  const std::map<TimeUs, CorrectionFrame> frames_by_time = CorrectionFramesByTime(pairs, T_camera_lidar);
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
    for (const SceneSwathe& scene : pair->Scenes()) summary.corrections.push_back(scene.MotionCorrection());
  return summary;
}

namespace {

// Frame `held_out`'s correction predicted from its neighbours in time (linear
// between the two; the one there is at an end of the drive).
SwatheMotionCorrection Predicted(const std::vector<TimeUs>& times, const std::vector<const CorrectionFrame*>& frames,
                                 std::size_t held_out) {
  const bool has_before = held_out > 0, has_after = held_out + 1 < frames.size();
  Eigen::Vector4d terms = Eigen::Vector4d::Zero();
  if (has_before && has_after) {
    const double t0 = static_cast<double>(times[held_out - 1]), t1 = static_cast<double>(times[held_out + 1]);
    const double w = (static_cast<double>(times[held_out]) - t0) / (t1 - t0);
    terms = (1.0 - w) * TermsOf(frames[held_out - 1]->Correction()) + w * TermsOf(frames[held_out + 1]->Correction());
  } else if (has_before || has_after) {
    terms = TermsOf(frames[has_before ? held_out - 1 : held_out + 1]->Correction());
  }
  return CorrectionOf(terms);
}

}  // namespace

std::string DriftTestResult::Describe() const {
  if (!enough_frames) return fmt::format("{} camera frame(s): too few for the held-out drift test", frames);
  return fmt::format("held-out cost change {:+.5f} +- {:.5f} (t = {:+.1f}, {} of {} frames lower): {}",
                     mean_cost_change, standard_error,
                     standard_error > 0.0 ? mean_cost_change / standard_error : 0.0, frames_lower, frames,
                     drift_found ? "drift found" : "no drift found");
}

DriftTestResult TestDrift(const std::vector<PairCost*>& pairs, const std::vector<Eigen::Isometry3d>& T_camera_lidar,
                          const DriftTestOptions& options) {
  const std::map<TimeUs, CorrectionFrame> by_time = CorrectionFramesByTime(pairs, T_camera_lidar);
  std::vector<TimeUs> times;
  std::vector<const CorrectionFrame*> frames;
  for (const auto& [time, frame] : by_time) {
    times.push_back(time);
    frames.push_back(&frame);
  }
  const std::size_t n = frames.size();
  DriftTestResult result;
  result.frames = static_cast<int>(n);
  result.enough_frames = n >= static_cast<std::size_t>(std::max(options.min_frames, 3));
  if (!result.enough_frames) return result;

  std::vector<SwatheMotionCorrection> found(n);  // restored at the end
  for (std::size_t i = 0; i < n; ++i) found[i] = frames[i]->Correction();
  const auto set_all = [&](const SwatheMotionCorrection& correction) {
    for (const CorrectionFrame* frame : frames) frame->Apply(correction);
  };
  set_all({});
  std::vector<double> without(n), with(n);
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) { without[i] = frames[i]->Cost(); });

  MotionCorrectionOptions motion = options.motion;
  motion.drive_scale = false;
  const FreeTerms free_terms(motion);
  if (free_terms.Count() == 0) throw std::invalid_argument("TestDrift: no per-frame term to estimate");
  for (std::size_t parity = 0; parity < 2; ++parity) {
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
      if (i % 2 == parity) CorrectFrame(*frames[i], free_terms, motion);
    });
    std::vector<SwatheMotionCorrection> predicted(n);
    for (std::size_t i = 0; i < n; ++i) {
      if (i % 2 != parity) predicted[i] = Predicted(times, frames, i);
    }
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
      if (i % 2 == parity) return;
      frames[i]->Apply(predicted[i]);
      with[i] = frames[i]->Cost();
    });
    set_all({});
  }
  for (std::size_t i = 0; i < n; ++i) frames[i]->Apply(found[i]);

  double sum = 0.0, sum_squares = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double change = with[i] - without[i];
    sum += change;
    sum_squares += change * change;
    if (change < 0.0) ++result.frames_lower;
  }
  const double count = static_cast<double>(n);
  result.mean_cost_change = sum / count;
  const double variance = std::max(0.0, (sum_squares - count * result.mean_cost_change * result.mean_cost_change) /
                                            (count - 1.0));
  result.standard_error = std::sqrt(variance / count);
  result.drift_found = result.mean_cost_change < -options.min_t_statistic * result.standard_error;
  return result;
}

}  // namespace scenecal
