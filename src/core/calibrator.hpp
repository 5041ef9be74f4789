// The calibration pipeline: one object built once from the calibration input
// and the options, owning every (camera, lidar) pair cost. It solves the
// scheme of the options (once, joint or the paper's alt, whose lower levels run
// on an injected backend: threads by default, MPI ranks from src/distributed),
// and the steps after the solve (uncertainty, basin check, report) reuse the
// costs it built instead of building them again.
//
// Core rules: no files, no printing; progress goes to the callback, and data
// that cannot be calibrated is a status with the reason.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <tbb/global_control.h>

#include "core/basin_check.hpp"
#include "core/calibrate.hpp"
#include "core/calibrate_alternating.hpp"
#include "core/uncertainty.hpp"

namespace scenecal {

// Makes the backend that runs alt's lower levels from the pairs' objectives and
// the batch hook (ThreadLowerLevelBackend when none is given).
using LowerLevelBackendFactory = std::function<std::unique_ptr<LowerLevelBackend>(
    std::vector<PairObjective> objectives, LowerLevelBatchHook before_batch)>;

class Calibrator {
 public:
  // Validates the options and builds every pair's cost at the rig's initial
  // guess (the input must outlive the calibrator). Status() says whether the
  // data can be calibrated.
  Calibrator(const CalibrationInput& input, const CalibrationOptions& options, ProgressCallback progress = {});
  ~Calibrator();
  Calibrator(const Calibrator&) = delete;
  Calibrator& operator=(const Calibrator&) = delete;

  CalibrationStatus Status() const { return status_; }
  const std::string& Why() const { return why_; }
  const CalibrationOptions& Options() const { return options_; }
  const CalibrationInput& Input() const { return input_; }

  // Solves options.scheme from the initial guess. alt's lower levels run on
  // the backend that lower_levels makes (threads when empty). Returns the
  // status of construction when it was not kSuccess.
  CalibrationOutcome Solve(const LowerLevelBackendFactory& lower_levels = {});

  // alt, for the MPI ranks that serve lower levels: the objectives and the
  // batch hook Solve hands to its backend, and a digest of what was built
  // (equal on every rank that read the same inputs).
  std::vector<PairObjective> AlternatingObjectives();
  LowerLevelBatchHook AlternatingBatchHook(const ProgressCallback& progress);
  std::uint64_t AlternatingFingerprint() const;
  const AlternatingProblem& AlternatingPairs() const { return alternating_.problem; }

  // After Solve, the pairs of one lidar (those with scenes) prepared at
  // T_base_lidar: sharp images, `binning`, visibility there and, with
  // options.motion_correction, the frames' drift corrections re-estimated
  // there (shared across the pairs), so that they score what the
  // calibration ended on.
  // only_camera: that camera's pair alone (its drift correction then its own).
  std::vector<PairCost*> PairsAt(const std::string& lidar, const Eigen::Isometry3d& T_base_lidar, Binning binning,
                                 const std::string& only_camera = "");
  // The pair (camera, lidar) alone prepared as PairsAt does, or null when it has no scene.
  PairCost* PairAt(const std::string& camera, const std::string& lidar, const Eigen::Isometry3d& T_base_lidar);

  // Each lidar's local uncertainty at the result (core/uncertainty.hpp), on
  // the B-spline cost of the same swathes. A lidar with a checked basin in
  // basin_checks (by name) is searched without search_past_rise: the check's
  // restarts look for the other basins.
  std::vector<LidarUncertainty> EstimateUncertainty(const CalibrationResult& result,
                                                    const UncertaintyOptions& uncertainty_options,
                                                    const std::vector<LidarBasinCheck>& basin_checks = {});
  // The held-out drift test (core/motion_estimation.hpp) with every lidar at
  // its answer in `result`, all lidars' swathes of a camera frame together
  // (the drift is the trajectory's).
  DriftTestResult TestDriftAt(const CalibrationResult& result, const DriftTestOptions& test_options);
  // The basin check at the result (core/basin_check.hpp).
  std::vector<LidarBasinCheck> CheckBasins(const CalibrationResult& result, const BasinCheckOptions& check_options);
  // After CheckBasins: each lidar whose restarts ended outside the agreement
  // bounds at a lower cost than its answer (BetterRestart) gets the lowest end
  // as its answer in *result: T_base_lidar, and its pairs' T_camera_lidar
  // through the known T_base_camera with their costs there (sharp images,
  // visibility refreshed). Its check records it (AdoptRestart). Not under alt
  // when a camera's T_base_camera has a sigma: alt's answer then need not keep
  // the known transforms that the check's joint cost holds. Returns the lidars
  // whose answer changed.
  std::vector<std::string> AdoptBetterRestarts(const BasinCheckOptions& check_options, CalibrationResult* result,
                                               std::vector<LidarBasinCheck>* checks);

 private:
  struct LidarPairs {
    const LidarInfo* lidar = nullptr;
    std::vector<std::unique_ptr<PairCost>> pairs;  // one per camera, rig order
    std::vector<double> initial_costs;             // per pair, at the initial guess
  };

  // The state of one once/joint solve: its outcome so far, the runs' one-line summaries, the time budget.
  struct OnceOrJointRun {
    CalibrationOutcome outcome;
    std::vector<std::string> terminations;
    StopRequested stop_requested;
  };
  using StagePreparation = std::function<void(const OptimisationStage& stage, const Eigen::Isometry3d&)>;

  CalibrationStatus Cannot(CalibrationStatus status, std::string why);
  void BuildPairs();
  // SceneChoice::kInformative: the pair keeps its scenes_per_camera most informative frames of the pool, judged at
  // T_camera_lidar (Solve runs once, so each pair chooses once).
  void KeepInformativeFrames(PairCost& pair, const Eigen::Isometry3d& T_camera_lidar);
  // Whether a once/joint solve makes the informative choice before its stage stage_index (not 0: made at construction).
  bool ChoosesInformativeBefore(int stage_index) const;
  void BuildAlternatingSetup();
  CalibrationOutcome SolveOnceOrJoint();
  // joint: one problem over the lidar's T_base_lidar; once: one per pair. Fill each pair's T_camera_lidar and
  // whether it was solved.
  void SolveJoint(LidarPairs& problem, std::vector<Eigen::Isometry3d>* T_camera_lidar, std::vector<bool>* solved,
                  OnceOrJointRun* run);
  void SolveEachPair(LidarPairs& problem, std::vector<Eigen::Isometry3d>* T_camera_lidar,
                     std::vector<bool>* solved, OnceOrJointRun* run);
  // One optimisation problem: logs its start, runs the coarse-to-fine schedule on *transform with the lower
  // solver (cost_with_gradient for lbfgs only; nelder_mead carries both solvers' parameterisation), logs and
  // records its runs.
  void Optimise(const std::string& name, double initial_cost, const NelderMeadOptions& nelder_mead,
                const std::function<double(const Eigen::Isometry3d&)>& cost,
                const CostWithGradient& cost_with_gradient, const StagePreparation& prepare,
                Eigen::Isometry3d* transform, OnceOrJointRun* run);
  // Drift correction of the swathes before a stage (options.motion_correction): the pairs given share each
  // frame's correction.
  void CorrectMotionBeforeStage(const std::vector<PairCost*>& pairs, const OptimisationStage& stage,
                                const std::vector<Eigen::Isometry3d>& T_camera_lidar_now, const std::string& lidar);
  // Final costs at the answer, the pairs' and the lidar's results (the mean of the pairs' implied T_base_lidar);
  // false (the outcome says why) when no pair was solved.
  bool FinishLidar(LidarPairs& problem, const std::vector<Eigen::Isometry3d>& T_camera_lidar,
                   const std::vector<bool>& solved, OnceOrJointRun* run);
  CalibrationOutcome SolveAlternating(const LowerLevelBackendFactory& lower_levels);
  LidarPairs* FindLidar(const std::string& lidar);
  void Say(const std::string& message) const;

  const CalibrationInput& input_;
  CalibrationOptions options_;
  AlternatingOptions alternating_options_;
  ProgressCallback progress_;
  std::optional<tbb::global_control> thread_limit_;
  CalibrationStatus status_ = CalibrationStatus::kSuccess;
  std::string why_;
  std::vector<LidarPairs> lidars_;  // rig order
  AlternatingSetup alternating_;    // the pairs with usable scenes at the initial guess (alt)
  double build_s_ = 0.0;
};

}  // namespace scenecal
