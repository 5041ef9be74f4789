// The `alt` scheme's pieces over the pair costs of core/pair_cost.hpp: the
// problem, the lower levels' objectives and batch hook, the stage schedule
// over the alternations and the outcome. Calibrator (core/calibrator.hpp)
// runs them; with MPI every rank builds the same Calibrator, rank 0 solves on
// an MPI backend while the others serve their pairs.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/alternating.hpp"
#include "core/calibrate.hpp"

namespace scenecal {

// The alt problem over the pair costs that have usable scenes at the initial
// guess (the costs belong to the Calibrator, core/calibrator.hpp).
struct AlternatingSetup {
  AlternatingProblem problem;
  std::vector<PairCost*> costs;       // one per problem.pairs entry
  std::vector<double> initial_costs;  // f_p at the initial guess, per pair
  std::vector<std::string> warnings;  // pairs left out, and why

  // The objectives for the lower level: cost = PairCost::Evaluate; prepare =
  // the coarse-to-fine stage of the alternation (image blur) and a visibility
  // refresh at the estimate the run starts from.
  std::vector<PairObjective> Objectives(const CalibrationOptions& options, const AlternatingOptions& alternating);
  // With options.motion_correction, the backend's batch hook: on the first
  // alternation of every stage from options.motion_correction_first_stage on,
  // every pair is prepared for the stage at its upper estimate and the pairs of
  // all lidars share each frame's drift correction and the drive's scale
  // (EstimateMotionCorrections; the drift is the trajectory's), held until
  // the next stage; `progress` (may be empty) hears how far the frames' costs
  // fell. Empty without the correction.
  LowerLevelBatchHook BatchHook(const CalibrationOptions& options, const AlternatingOptions& alternating,
                                const ProgressCallback& progress);
  // A digest of what was built (pairs, scene and point counts, options), equal
  // on every rank that read the same inputs.
  std::uint64_t Fingerprint(const CalibrationOptions& options, const AlternatingOptions& alternating) const;
};

// The stage of options.stages that alternation i uses: the schedule is spread
// evenly over the first `span` alternations (the first on the blurred images);
// later ones stay in the last stage.
std::size_t StageIndexForAlternation(std::size_t stage_count, int alternation, int span);
const OptimisationStage& StageForAlternation(const std::vector<OptimisationStage>& stages, int alternation, int span);
// True when alternation i is the first of its stage (the drift correction and
// the adaptive schedule's jumps happen there).
bool IsStageStart(std::size_t stage_count, int alternation, int span);
// The first alternation of the last (sharpest) stage.
int FirstAlternationOfLastStage(const std::vector<OptimisationStage>& stages, int span);
// The span the stages are spread over: AlternatingOptions::stage_alternations
// when set (and below max_alternations), else max_alternations.
int StageSpan(const AlternatingOptions& alternating);

// Each of max_alternations' stage step_scale (AlternatingOptions::lower_step_scale).
std::vector<double> StepScalesForAlternations(const std::vector<OptimisationStage>& stages, int max_alternations,
                                              int span);

// alt's two levels ended further apart than the agreement thresholds (the
// numbers and what to change, nullopt when they agree): a larger time budget
// when it stopped the run, the stages kept on the first alternations when
// they span all of them, else how many alternations in all.
std::optional<LevelsApart> CheckLevelsApart(const AlternatingOptions& alternating, const AlternationRecord& last,
                                            bool stopped_by_time_budget);
// The result's warning for it, in the core's words (no command-line names).
std::string DescribeLevelsApart(const LevelsApart& apart);

// P^0's sigma (metres and radians) with L-BFGS lower levels: on the simulated
// push-broom drives the paper's 5 m / 5 rad left alt 0.1-2.9 deg off, this
// 0.16-0.25 deg (docs/findings.md, "The alternating scheme's penalty holds in the lidar frame").
inline constexpr double kLbfgsInitialSigma = 500.0;

// The alternating options of a calibration: options.alternating (the paper's
// settings by default: 20 alternations, P^0 from 5 m and 5 rad, w = 0.5) with
// the lower level's solver, steps, iterations and time budget and the
// coarse-to-fine stages taken from the rest of the options (the fields derived
// from the schedule: min_alternations, lower_step_scale); P^0 from
// kLbfgsInitialSigma with options.lower_solver = lbfgs unless given.
AlternatingOptions AlternatingOptionsFor(const CalibrationOptions& options);

// Turns the alternating result into the calibration outcome: T_base_lidar per
// lidar, each pair's upper-level T_camera_lidar with its final cost (sharp
// images, visibility refreshed there), settings and the termination.
CalibrationOutcome FinishAlternating(AlternatingSetup& setup, const AlternatingResult& solved,
                                     const CalibrationOptions& options, const AlternatingOptions& alternating);

// Progress line for one alternation (for logs).
std::string DescribeAlternation(const AlternationRecord& record, const AlternatingProblem& problem);

}  // namespace scenecal
