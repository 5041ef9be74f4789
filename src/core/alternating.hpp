// The paper's hierarchical alternating optimisation (section III-B/C,
// equations 12-14), for any number of cameras and lidars.
//
// For each alternation i = 0, 1, ...:
//  - lower level (eq. 13), for every (camera p, lidar L) pair independently:
//      T^_pL = argmin f_pL(T^) + |T^ (-) T_pL|^2_{P^i},  T_pL (upper) held fixed;
//  - upper level (eq. 14), for every lidar: the pairs' T_pL from the lower
//    solutions and the known inter-camera transforms (SolveUpperLevel);
//  - P^(i+1) = w * P^i.
// Differences are SE(3) logarithms (geometry.hpp). The lower-level problems are
// handed to a LowerLevelBackend, so they can run on threads or on MPI ranks.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/enum_names.hpp"
#include "core/geometry.hpp"
#include "core/gradient_solver.hpp"
#include "core/nelder_mead.hpp"

namespace scenecal {

// Where the penalty's sigmas are stated. The difference T^ (-) T = Log(T^ * T^-1)
// of two camera-lidar transforms is a twist in the camera frame, in which a
// turn of the lidar about its own origin also shifts it by the lever arm (the
// lidar's distance from the camera times the angle).
//  kLidar: P^i is the covariance of the lidar's pose about its own origin
//    (sigma_t of its position, sigma_phi of its orientation), carried into the
//    camera-frame difference by the adjoint of the upper estimate.
//  kCamera: P^i is diagonal in the camera-frame difference itself: a turn then
//    also pays the lever arm's shift at sigma_t, e.g. 17x the rotation
//    information for a lidar 4 m away with sigma_t = sigma_phi (numerically),
//    which held the lower levels' rotations back (docs/findings.md, "The alternating scheme's penalty holds in the lidar frame").
enum class PenaltyFrame { kLidar, kCamera };
inline constexpr auto kPenaltyFrameNames =
    MakeEnumNames<PenaltyFrame>({{PenaltyFrame::kLidar, "lidar"}, {PenaltyFrame::kCamera, "camera"}});
const char* PenaltyFrameName(PenaltyFrame frame);  // "lidar", "camera"
bool ParsePenaltyFrame(const std::string& name, PenaltyFrame* frame);

// (P^i)^-1 in camera-frame difference coordinates for a pair whose upper
// estimate is T_camera_lidar: diag(1/sigma_t^2, 1/sigma_phi^2) in the frame.
Matrix6d PairPenaltyInformation(double sigma_translation_m, double sigma_rotation_rad, PenaltyFrame frame,
                                const Eigen::Isometry3d& T_camera_lidar);

struct AlternatingOptions {
  int max_alternations = 20;                 // the paper: 20
  // Read by the calibration's coarse-to-fine schedule (calibrate_alternating):
  // its stages are spread over the first this many alternations (0 = all);
  // the later ones stay in the sharp stage and only tighten the coupling.
  int stage_alternations = 0;
  double initial_sigma_translation_m = 5.0;  // P^0 (the paper: 5 m)
  double initial_sigma_rotation_rad = 5.0;   // P^0 (the paper: 5 rad)
  double covariance_shrink = 0.5;            // w in P^(i+1) = w P^i, in (0, 1)
  PenaltyFrame penalty_frame = PenaltyFrame::kLidar;
  // Early stop once both levels moved less than these between two alternations
  // and every lower solution agrees with its upper one within them.
  double stop_translation_m = 2e-4;
  double stop_rotation_rad = 2e-5;
  // No early stop before this many alternations (e.g. until a coarse-to-fine
  // schedule has reached its sharpest stage).
  int min_alternations = 1;
  // The schedule's positions (alternation indices) where a coarse-to-fine stage
  // begins, ascending; read only with skip_settled.
  std::vector<int> stage_starts;
  // Adaptive schedule: an alternation in which both levels moved by less than
  // settle_factor x the stop thresholds (x the stage's coarseness, Settled) is
  // not repeated with the same stage and a barely tighter penalty. Before the
  // last stage the schedule goes on at the next stage's first position; in the
  // last stage it advances two positions, so the penalty tightens twice as fast
  // while the levels follow it without moving. Off: the paper's one position
  // per alternation.
  bool skip_settled = false;
  double settle_factor = 10.0;
  // Simplex search of the lower level (the paper: 200 iterations). Its initial
  // steps are capped by the current penalty sigma, so later alternations
  // search a neighbourhood of the size the penalty allows.
  NelderMeadOptions lower;
  // The lower level's optimiser: the simplex (the paper) or L-BFGS. With
  // L-BFGS, f's gradient comes from PairObjective::cost_with_gradient (central
  // differences of f when it is empty) and the penalty's from central
  // differences; lower_gradient's parameter scales are capped by the penalty
  // sigma like the simplex steps, and its transform_update / pivot_source are
  // those of `lower`.
  LowerSolver lower_solver = LowerSolver::kSimplex;
  GradientSolverOptions lower_gradient;
  // Factor on the lower level's initial steps (simplex) or parameter scales
  // (lbfgs) per alternation, before the penalty-sigma cap: a coarse-to-fine
  // schedule's finer stages search a smaller neighbourhood, as they do in the
  // once and joint schemes. Alternations beyond its end (or all, when empty) use 1.
  std::vector<double> lower_step_scale;
  // Used for the inter-camera term when the rig states no T_base_camera_sigma:
  // sub-millimetre factory calibration, as the paper assumes for the Bumblebee.
  double default_camera_sigma_translation_m = 0.0005;
  double default_camera_sigma_rotation_rad = 0.0002;
  // The levels "agree" at the end when every lower solution is within these of
  // its upper one (the paper's Fig. 4: both converge to the same optimum);
  // otherwise the result carries a warning (FinishAlternating).
  double agreement_translation_m = 1e-3;
  double agreement_rotation_rad = 1.7453e-4;  // 0.01 deg
  // Wall-clock budget for the whole optimisation (0 = none); when it runs out the
  // best estimate so far is returned with the termination saying so.
  double time_budget_s = 0.0;

  bool IsValid(std::string* why = nullptr) const;
  // How much coarser than the schedule's last position the stage at
  // `alternation` searches: the ratio of their lower_step_scale (at least 1;
  // 1 without step scales).
  double StageCoarseness(int alternation) const;
  // The adaptive schedule's test: both levels moved less than settle_factor x
  // the stop thresholds x StageCoarseness(alternation) in that alternation. A
  // stage whose steps are k times the last stage's resolves the answer k times
  // more coarsely than the last stage, and the stages after it refine what it
  // leaves.
  bool Settled(int alternation, double moved_translation_m, double moved_rotation_rad) const;
};

// One lower-level problem (eq. 13) as a backend receives it.
struct LowerLevelTask {
  int pair = 0;                                            // index into AlternatingProblem::pairs
  int alternation = 0;                                     // i, for the pair's coarse-to-fine preparation
  Eigen::Isometry3d T_camera_lidar_upper = Eigen::Isometry3d::Identity();  // T_pL, fixed
  Eigen::Isometry3d T_camera_lidar_start = Eigen::Isometry3d::Identity();  // where the simplex starts
  Matrix6d penalty_information = Matrix6d::Identity();    // (P^i)^-1
  NelderMeadOptions options;                              // simplex; its transform_update/pivot_source for both
  LowerSolver solver = LowerSolver::kSimplex;
  GradientSolverOptions gradient;                         // lbfgs (transform_update/pivot_source unused)
};

struct LowerLevelOutcome {
  Eigen::Isometry3d T_camera_lidar = Eigen::Isometry3d::Identity();  // T^_pL
  double cost = 0.0;       // f_pL(T^) alone (NID or -MI)
  double objective = 0.0;  // f + penalty
  // Simplex: its summary. L-BFGS: iterations, evaluations (all cost
  // evaluations of f, with or without gradient), initial_value and
  // final_value as for the simplex; termination kFunctionTolerance when a
  // tolerance was met, kStopRequested, kNonFiniteCost, else kMaxIterations.
  NelderMeadSummary summary;
  int gradient_evaluations = 0;  // lbfgs: evaluations of f that also computed its gradient
};

// Solves a batch of lower-level problems (one per pair), in any order or place,
// returning outcomes in the order of the tasks. Must be deterministic.
class LowerLevelBackend {
 public:
  virtual ~LowerLevelBackend() = default;
  virtual std::vector<LowerLevelOutcome> Solve(const std::vector<LowerLevelTask>& tasks,
                                               const StopRequested& stop_requested) = 0;
};

// The cost of one pair and the hook that prepares it before a lower-level run
// at alternation i from the estimate T (refresh occlusion, choose the image
// smoothing): called between optimiser runs, never inside one.
struct PairObjective {
  std::function<double(const Eigen::Isometry3d& T_camera_lidar)> cost;
  std::function<void(const Eigen::Isometry3d& T_camera_lidar, int alternation)> prepare;  // may be empty
  // f and its gradient with respect to the local update (update kind, pivot in
  // the lidar frame) of T_camera_lidar, for the lbfgs lower level; may be
  // empty (then central differences of cost).
  std::function<double(const Eigen::Isometry3d& T_camera_lidar, TransformUpdate update,
                       const Eigen::Vector3d& pivot_lidar, Vector6d* gradient)>
      cost_with_gradient;
};

// f + |T^ (-) T_upper|^2_P, minimised from task.T_camera_lidar_start by
// Nelder-Mead or L-BFGS (task.solver).
LowerLevelOutcome SolveLowerLevel(const PairObjective& objective, const LowerLevelTask& task,
                                  const StopRequested& stop_requested);

// Called with a whole batch of tasks before any of them is solved, on every
// process that solves some (with MPI: every rank, with the same batch): a
// change of the pairs' data shared across pairs, e.g. the swathes' drift
// correction at the upper estimates (AlternatingSetup::BatchHook). Must be
// deterministic, so that every rank makes the same change.
using LowerLevelBatchHook = std::function<void(const std::vector<LowerLevelTask>& tasks)>;

// Runs the tasks on the calling process, pairs in parallel (TBB).
class ThreadLowerLevelBackend : public LowerLevelBackend {
 public:
  explicit ThreadLowerLevelBackend(std::vector<PairObjective> objectives, LowerLevelBatchHook before_batch = {})
      : objectives_(std::move(objectives)), before_batch_(std::move(before_batch)) {}
  std::vector<LowerLevelOutcome> Solve(const std::vector<LowerLevelTask>& tasks,
                                       const StopRequested& stop_requested) override;

 private:
  std::vector<PairObjective> objectives_;
  LowerLevelBatchHook before_batch_;
};

struct AlternatingCamera {
  std::string name;
  Eigen::Isometry3d T_base_camera = Eigen::Isometry3d::Identity();  // known transform
  std::optional<Vector6d> sigma;  // its 1-sigma from the rig; zeros = exact

  Eigen::Isometry3d T_camera_base() const { return T_base_camera.inverse(); }
};

struct AlternatingPair {
  int camera = 0;  // index into AlternatingProblem::cameras
  int lidar = 0;   // index into AlternatingProblem::lidars
};

struct AlternatingLidar {
  std::string name;
  Eigen::Isometry3d T_base_lidar_initial = Eigen::Isometry3d::Identity();
};

struct AlternatingProblem {
  std::vector<AlternatingCamera> cameras;
  int base_camera = 0;
  std::vector<AlternatingLidar> lidars;
  std::vector<AlternatingPair> pairs;  // every (camera, lidar) with data

  bool IsValid(std::string* why = nullptr) const;
};

// Per alternation, per pair: what Fig. 4 and Fig. 6 of the paper plot.
struct AlternationRecord {
  int alternation = 0;
  double sigma_translation_m = 0.0;  // penalty sigma used at this alternation
  double sigma_rotation_rad = 0.0;
  std::vector<Eigen::Isometry3d> T_camera_lidar_lower;  // per pair
  std::vector<Eigen::Isometry3d> T_camera_lidar_upper;  // per pair, after the upper level
  std::vector<double> lower_cost;                       // f_p at the lower solution, per pair
  std::vector<int> lower_evaluations;                   // cost evaluations, per pair
  std::vector<int> lower_gradient_evaluations;          // lbfgs: of which with the gradient, per pair
  std::vector<double> upper_cost;                       // upper-level objective, per lidar
  double max_change_translation_m = 0.0;                // largest move of either level since the last alternation
  double max_change_rotation_rad = 0.0;
  double max_disagreement_translation_m = 0.0;          // largest |T^ (-) T| over pairs
  double max_disagreement_rotation_rad = 0.0;
  double elapsed_s = 0.0;
};

struct AlternatingResult {
  std::vector<Eigen::Isometry3d> T_base_lidar;           // per lidar
  std::vector<Eigen::Isometry3d> T_camera_lidar_upper;   // per pair
  std::vector<Eigen::Isometry3d> T_camera_lidar_lower;   // per pair
  std::vector<double> pair_cost;                         // f_p at the final lower solution
  std::vector<AlternationRecord> history;
  int alternations = 0;
  int total_evaluations = 0;
  int total_gradient_evaluations = 0;  // lbfgs: evaluations that also computed the gradient
  std::string termination;  // "converged ...", "max alternations", "time budget ..." or an error
  bool success = false;
};

using AlternatingProgress = std::function<void(const AlternationRecord&)>;

AlternatingResult SolveAlternating(const AlternatingProblem& problem, const AlternatingOptions& options,
                                   LowerLevelBackend& backend, const AlternatingProgress& progress = {});

}  // namespace scenecal
