// Calibration schemes over the pair costs (core/pair_cost.hpp):
//   once  - each (camera, lidar) pair alone: T_camera_lidar by Nelder-Mead on
//           its own cost; each pair implies T_base_lidar = T_base_camera *
//           T_camera_lidar, and their spread is reported.
//   joint - one problem per lidar over T_base_lidar: the mean of the pair costs
//           over all cameras, through the fixed known T_base_camera.
//   alt   - the paper's alternating scheme (core/alternating.*; dispatched here
//           when available).
// Each optimisation runs a coarse-to-fine schedule: the lower solver
// (Nelder-Mead, or L-BFGS with analytic gradients: options.lower_solver)
// restarted from the best point with smaller initial steps, the visibility
// masks refreshed before every stage (never inside one).
//
// Core rules: no files, no printing; progress goes to a callback and data
// that cannot be calibrated is a status with the reason, not an exception.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/alternating.hpp"
#include "core/calibration_result.hpp"
#include "core/enum_names.hpp"
#include "core/geometry.hpp"
#include "core/gradient_solver.hpp"
#include "core/metric.hpp"
#include "core/nelder_mead.hpp"
#include "core/motion_estimation.hpp"
#include "core/normalisation.hpp"
#include "core/pair_cost.hpp"
#include "core/rig.hpp"
#include "core/scenes.hpp"

namespace scenecal {

enum class CalibrationScheme { kOnce, kJoint, kAlt };
inline constexpr auto kCalibrationSchemeNames = MakeEnumNames<CalibrationScheme>(
    {{CalibrationScheme::kOnce, "once"}, {CalibrationScheme::kJoint, "joint"}, {CalibrationScheme::kAlt, "alt"}});
bool ParseCalibrationScheme(const std::string& name, CalibrationScheme* scheme);  // "once" | "joint" | "alt"
const char* CalibrationSchemeName(CalibrationScheme scheme);

// One stage of the coarse-to-fine schedule. Before the stage the images are
// blurred and the visibility masks refreshed at the current estimate; then
// Nelder-Mead runs with the initial steps scaled by step_scale, and is rerun
// from its answer (up to `restarts` times) while a run still improves the
// cost by more than restart_min_improvement: a fresh simplex escapes the
// premature collapse Nelder-Mead suffers in 6-D on a rough cost.
struct OptimisationStage {
  double step_scale = 1.0;
  double blur_fraction = 0.0;  // Gaussian 1-sigma as a fraction of the image width; 0 = sharp
  int restarts = 0;
};
std::vector<OptimisationStage> DefaultStages();
// The schedule without its wide stages, those that search with the first
// stage's whole steps (step_scale >= 1): they widen the basin, but only many
// views keep them on course. Unchanged when every stage is wide.
std::vector<OptimisationStage> WithoutWideStages(const std::vector<OptimisationStage>& stages);

// Solver options with the first stage's steps (simplex) or parameter scales (lbfgs).
template <class SolverOptions>
SolverOptions WithInitialSteps(SolverOptions options, double translation_m, double rotation_rad) {
  options.initial_step_translation_m = translation_m;
  options.initial_step_rotation_rad = rotation_rad;
  return options;
}

// The alt scheme's own settings (the paper's by default). Its lower level's
// solver, steps, stages and time budget come from the rest of
// CalibrationOptions (AlternatingOptionsFor in core/calibrate_alternating.hpp).
struct AlternatingSettings {
  int max_alternations = 20;   // the paper: 20
  int stage_alternations = 0;  // spread the stages over the first this many alternations (0 = over all)
  double covariance_shrink = 0.5;  // w in P^(i+1) = w P^i, in (0, 1)
  PenaltyFrame penalty_frame = PenaltyFrame::kLidar;
  // P^0's sigmas (metres, radians); 0 = by the lower solver: the paper's 5 m /
  // 5 rad with the simplex, kLbfgsInitialSigma with lbfgs.
  double initial_sigma_translation_m = 0.0;
  double initial_sigma_rotation_rad = 0.0;
  // Early stop once both levels move, and disagree, by less than these.
  double stop_translation_m = 2e-4;
  double stop_rotation_rad = RadiansFromDegrees(1e-3);
  // AlternatingOptions::skip_settled: settled alternations end their stage (false: the paper's fixed schedule).
  bool skip_settled = false;
  // 1-sigma of known camera transforms that rig.yaml gives no T_base_camera_sigma for.
  double default_camera_sigma_translation_m = 0.0005;
  double default_camera_sigma_rotation_rad = RadiansFromDegrees(0.0115);
  // The levels "agree" at the end within these; otherwise the result warns.
  double agreement_translation_m = 1e-3;
  double agreement_rotation_rad = 1.7453e-4;  // 0.01 deg
};

struct CalibrationOptions {
  CalibrationScheme scheme = CalibrationScheme::kAlt;
  AlternatingSettings alternating;     // scheme kAlt
  PairCostOptions cost;                // metric, histogram bins and binning, range/occlusion, min points
  NormalisationOptions normalisation;  // reflectance and intensity mapping to [0, 1]
  SceneOptions scenes;                 // used by the caller's SelectScenes; recorded in the settings
  // Steps of the first stage (0.05 m, 1 deg), iterations per stage, tolerances.
  NelderMeadOptions nelder_mead = WithInitialSteps(NelderMeadOptions{}, 0.05, RadiansFromDegrees(1.0));
  // Coarse-to-fine schedule (one entry with scale 1, no blur and no restarts
  // = a single Nelder-Mead run, the paper).
  std::vector<OptimisationStage> stages = DefaultStages();
  // Local optimiser of every stage (once, joint) and of the alt lower level.
  // kLbfgs needs B-spline binning (cost.histogram.binning): IsValid says so.
  LowerSolver lower_solver = LowerSolver::kSimplex;
  // kLbfgs: iterations per run, tolerances and the parameter scales of the
  // first stage (the scales are multiplied by each stage's step_scale, as the
  // simplex steps are; the alt lower level caps them by the penalty sigma).
  // Its transform_update and pivot_source are taken from nelder_mead's and the
  // rotation pivot option, so both solvers search the same parameterisation.
  GradientSolverOptions gradient = WithInitialSteps(GradientSolverOptions{}, 0.05, RadiansFromDegrees(1.0));
  int threads = 0;           // worker threads for TBB; 0 = all hardware threads
  std::uint64_t seed = 1;    // recorded; the pipeline is deterministic (no random choices)
  double time_budget_s = 0;  // wall-clock budget of Calibrate (from its start); 0 = none. Best point so far kept.
  // once: warn when the pairs' implied T_base_lidar disagree by more than this.
  double agreement_warning_translation_m = 0.02;
  double agreement_warning_rotation_deg = 0.3;
  double restart_min_improvement = 1e-5;  // cost units
  // Rotate the lidar about the centroid (lidar frame) of its points that project
  // at the initial guess, instead of about the lidar's origin: a push-broom
  // swathe's weak direction (a tilt about the lateral axis through the road
  // the scans hit) then lies along one parameter, which Nelder-Mead follows
  // better than a diagonal valley. Off by default: on the simulated RobotCar
  // data it did not improve the accuracy (4 perturbed starts, mixed results).
  bool pivot_at_observed_centroid = false;
  // Swathe trimming (metres of travel; negative = keep every scan). A scan
  // only counts when its points land in the image; for a rear push-broom
  // lidar and a forward camera that starts ~6 m after the image, so most of a
  // window that starts at the image carries nothing. Each scene keeps the
  // scans whose travel from the image (|T_basek_basej| translation) lies
  // within this margin of the first and last scan with points projecting at
  // the initial guess; the margin covers the initial guess's error.
  double swathe_trim_margin_m = 1.0;
  // Lidar range bands (metres; 0 = off): each scene's points nearer and farther
  // than this from the lidar are scored as two scenes (each its own joint
  // histogram), so the few far returns (walls, parked cars) weigh as much as
  // the many near road returns. Visibility is then tested within a band.
  double range_split_m = 0.0;
  // Density thinning (thin_max_points_per_cell 0 = off): each scene's points
  // are projected at the initial guess into square cells of thin_cell_px
  // pixels and a crowded cell keeps about thin_max_points_per_cell of them
  // (SceneSwathe::ThinByImageDensity); points farther than thin_margin_px
  // outside the image at the guess are dropped. Long swathes (--swathe-length
  // 30) pile the far scans' points onto few pixels: thinning makes them cheap.
  int thin_max_points_per_cell = 0;
  int thin_cell_px = 4;
  double thin_margin_px = 128.0;
  // Per-frame odometry drift correction (every scheme): before each stage from
  // motion_correction_first_stage on (0 = the first), every camera frame's
  // swathe gets the scale and pitch and heading rates that minimise its own
  // cost at the current estimate (PairCost::EstimateMotionCorrections), held
  // during the stage (alt: estimated at the upper estimates before the stage's
  // first alternation, for every lidar's pairs together, AlternatingSetup::
  // BatchHook; the other schemes per lidar). For long swathes from drifting
  // odometry.
  bool motion_correction = false;
  int motion_correction_first_stage = 1;
  MotionCorrectionOptions motion;

  bool IsValid(std::string* why = nullptr) const;
};

// The data a calibration needs: the rig, the selected scenes, and the images
// and scans those scenes use (others may be absent).
struct CalibrationInput {
  Rig rig;
  SceneSelection selection;
  std::map<std::string, std::map<TimeUs, GreyImage>> images;  // by camera, then image time
  std::map<std::string, std::map<TimeUs, LidarScan>> scans;   // by lidar, then scan time
};

// Per-pair diagnostics, for logs and reports.
struct PairReport {
  std::string camera;
  std::string lidar;
  int scenes = 0;
  int scenes_used = 0;  // at the final refresh
  int scenes_too_few_points = 0;
  int scenes_constant_image = 0;
  int scenes_constant_reflectance = 0;
  std::vector<std::size_t> projected_points;  // per scene, at the final estimate
  double initial_cost = 0.0;                  // at the initial guess (visibility at the initial guess)
  double final_cost = 0.0;                    // at the answer (visibility refreshed there)
  Eigen::Isometry3d T_camera_lidar_initial = Eigen::Isometry3d::Identity();
};

struct OptimisationReport {
  std::string problem;  // e.g. "joint rear" or "once left/rear"
  LowerSolver solver = LowerSolver::kSimplex;
  std::vector<NelderMeadSummary> stages;             // simplex: one summary per run
  std::vector<GradientSolverSummary> gradient_runs;  // lbfgs: one summary per run
  int evaluations = 0;           // cost evaluations (lbfgs: with or without the gradient)
  int gradient_evaluations = 0;  // lbfgs: of which also computed the gradient
  double seconds = 0.0;
};

enum class CalibrationStatus { kSuccess, kCannotCalibrate, kInvalidOptions };

// One camera frame's drift correction at the end (options.motion_correction).
struct FrameMotionCorrection {
  std::string camera;
  std::string lidar;
  TimeUs image_t_us = 0;
  SwatheMotionCorrection correction;
};

// alt's two levels ended apart (a warning's numbers): how far, and what would
// close the gap. The CLI words the remedy with its options.
struct LevelsApart {
  enum class Remedy { kLargerTimeBudget, kStagesOnFirstAlternations, kMoreAlternations };
  double translation_m = 0.0;  // largest gap between a pair's lower and upper solution
  double rotation_rad = 0.0;
  double sigma_translation_m = 0.0;  // the penalty's sigmas at the end
  double sigma_rotation_rad = 0.0;
  double covariance_shrink = 0.5;    // w
  Remedy remedy = Remedy::kMoreAlternations;
  int suggested_alternations = 0;        // kStagesOnFirstAlternations, kMoreAlternations
  int suggested_stage_alternations = 0;  // kStagesOnFirstAlternations
};

// alt's per-alternation history (the paper's Fig. 4 and 6) with the names of its pairs.
struct AlternatingHistory {
  AlternatingProblem problem;
  AlternatingResult solved;
};

struct CalibrationOutcome {
  CalibrationStatus status = CalibrationStatus::kSuccess;
  std::string why;  // for a status other than kSuccess
  CalibrationResult result;
  std::vector<PairReport> pairs;
  std::vector<OptimisationReport> optimisations;
  std::vector<FrameMotionCorrection> motion_corrections;  // per pair and frame, in time order
  std::optional<AlternatingHistory> alternating;          // scheme alt
  std::optional<LevelsApart> levels_apart;                // alt: its levels ended apart (also in result.warnings)
};

// Progress messages (one line each) for the caller to log.
using ProgressCallback = std::function<void(const std::string& message)>;

// The prepared images (SwatheImages) of camera frames, by camera and image
// time, so that the pairs of every lidar share one copy of a frame's images
// and of its blur. Thread-safe; the swathes keep what they use after it is gone.
class PreparedImageCache {
 public:
  SwatheImages Get(const std::string& camera, TimeUs image_t_us, const cv::Mat& intensity,
                   const NormalisationOptions& normalisation);

 private:
  std::mutex mutex_;
  std::map<std::pair<std::string, TimeUs>, SwatheImages> images_;
};

// Builds one pair's cost from the input's scenes of (camera, lidar).
// Scenes whose image or scans are missing from the input are left out. With
// `images`, frames already prepared for another lidar's pair are reused.
PairCost BuildPairCost(const CalibrationInput& input, const CameraInfo& camera, const std::string& lidar,
                       const CalibrationOptions& options, PreparedImageCache* images = nullptr);

// The coarse-to-fine schedule on any cost of a transform: for each stage,
// prepare(stage, T) (blur the images, refresh visibility), then Nelder-Mead
// runs (MinimiseOverTransform) with the stage's steps, with restarts.
// *transform is updated to the best point. Returns one summary per
// Nelder-Mead run. Stops early when stop_requested returns true.
std::vector<NelderMeadSummary> MinimiseCoarseToFine(
    const std::function<double(const Eigen::Isometry3d&)>& cost,
    const std::function<void(const OptimisationStage& stage, const Eigen::Isometry3d&)>& prepare,
    const NelderMeadOptions& options, const std::vector<OptimisationStage>& stages, double restart_min_improvement,
    Eigen::Isometry3d* transform, const StopRequested& stop_requested = {});

// The same schedule with L-BFGS (MinimiseWithGradient) as the local solver:
// the stage scales the parameter scales (options.initial_step_*) as it scales
// the simplex steps; a run is restarted (fresh curvature memory) while it
// still improves the cost by more than restart_min_improvement. Returns one
// summary per run. Stops early when stop_requested returns true or the cost
// cannot be evaluated at a run's start.
std::vector<GradientSolverSummary> MinimiseCoarseToFineWithGradient(
    const CostWithGradient& cost,
    const std::function<void(const OptimisationStage& stage, const Eigen::Isometry3d&)>& prepare,
    const GradientSolverOptions& options, const std::vector<OptimisationStage>& stages,
    double restart_min_improvement, Eigen::Isometry3d* transform, const StopRequested& stop_requested = {});

// The stages `stages` on *transform with options.lower_solver: Nelder-Mead
// (MinimiseCoarseToFine with `nelder_mead`: its steps and parameterisation)
// on `cost`, or L-BFGS (MinimiseCoarseToFineWithGradient with
// options.gradient, in nelder_mead's parameterisation) on
// `cost_with_gradient`. Fills report->solver, its runs and its evaluation
// counts (not its problem name or time).
void MinimiseWithLowerSolver(const CalibrationOptions& options, const std::vector<OptimisationStage>& stages,
                             const NelderMeadOptions& nelder_mead,
                             const std::function<double(const Eigen::Isometry3d&)>& cost,
                             const CostWithGradient& cost_with_gradient,
                             const std::function<void(const OptimisationStage& stage, const Eigen::Isometry3d&)>&
                                 prepare,
                             Eigen::Isometry3d* transform, OptimisationReport* report,
                             const StopRequested& stop_requested = {});

// What one cost + gradient evaluation costs in plain cost evaluations
// (PairCost::EvaluateWithGradient against PairCost::Evaluate, B-spline NID),
// measured with benchmarks/bench_cost.cpp (BM_EvaluateWithGradient against
// BM_Evaluate, 1 thread, same data). For logs and the result's settings.
extern const double kGradientEvaluationCost;

// One line on a lower solver's evaluation count, e.g. "1234 cost evaluations"
// or "321 cost evaluations (318 with gradient, each ~2 plain ones)".
std::string DescribeEvaluations(LowerSolver solver, int evaluations, int gradient_evaluations);

// The settings every scheme records in the result (scheme, metric, bins, scenes, ...).
// The stage before which the informative scene choice is made: 0 at the
// initial guess (alt, or informative_after_stages 0), k after the first k
// stages of a once/joint schedule; -1 when the scenes are spread.
int InformativeChoiceStage(const CalibrationOptions& options);

void RecordCommonSettings(const CalibrationOptions& options, CalibrationResult* result);

// Why no scene of a lidar's pairs carries information (for the status message).
std::string DescribeUnusable(const std::string& lidar, const std::vector<std::unique_ptr<PairCost>>& pairs,
                             int min_points);
// The diagnostics of a pair in its current state (scenes used at its last refresh).
PairReport MakePairReport(const PairCost& pair, const Eigen::Isometry3d& T_initial, double initial_cost);
// "N frames, cost a -> b, largest scale .. %, turn .. deg/m, roll .. deg/m":
// one pass of EstimateMotionCorrections, for the progress log.
std::string DescribeMotionCorrection(const MotionCorrectionSummary& summary);
// Appends the pair's drift corrections, one entry per camera frame (a frame's
// range bands share one), in the order of its scenes.
void AppendFrameMotionCorrections(const PairCost& pair, const std::string& lidar,
                                  std::vector<FrameMotionCorrection>* corrections);

// Centroid (lidar frame, metres) of the visible points of the used scenes that
// project under T_base_lidar, over every pair (T_camera_lidar = T_base_camera^-1
// * T_base_lidar); nothing when no point projects. The rotation pivot of
// CalibrationOptions::pivot_at_observed_centroid.
std::optional<Eigen::Vector3d> ObservedCentroid(const std::vector<const PairCost*>& pairs,
                                                const Eigen::Isometry3d& T_base_lidar);

// For pair costs built afresh after a calibration (uncertainty, basin check,
// report): with options.motion_correction, refreshes each pair's visibility at
// the answer T_base_lidar and estimates the frames' drift corrections there
// (shared across the pairs, EstimateMotionCorrections), so that they score the
// corrected swathes the calibration ended on; nothing without it.
void CorrectMotionAtAnswer(const CalibrationOptions& options, const std::vector<PairCost*>& pairs,
                           const Eigen::Isometry3d& T_base_lidar);

// Prepares a pair for a stage: blur and visibility at T_camera_lidar.
void PreparePairForStage(PairCost& pair, const OptimisationStage& stage, const Eigen::Isometry3d& T_camera_lidar);

CalibrationOutcome Calibrate(const CalibrationInput& input, const CalibrationOptions& options,
                             const ProgressCallback& progress = {});

// Mean of rigid transforms: translations averaged, rotations averaged in the
// tangent space at the first (exact for identical inputs).
Eigen::Isometry3d MeanTransform(const std::vector<Eigen::Isometry3d>& transforms);

}  // namespace scenecal
