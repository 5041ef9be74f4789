// A global check of a calibration result: do the data pin each lidar's
// extrinsic down, or only the optimiser's path?
//
// The local uncertainty (core/uncertainty.hpp) measures the spread within
// the basin the optimiser ended in. On a push-broom swathe the cost can be
// flat for degrees along a tilt coupled with a shift (docs/findings.md, "A
// push-broom lidar's tilt is weakly constrained"): the local sigma is then small, yet runs from other starts
// end degrees apart. This check measures that directly. For each lidar the
// joint cost (mean over cameras through the known T_base_camera) is
// minimised again from starts turned by +-offset about each base axis
// (through the lidar's origin) away from the answer, with the later stages
// of the calibration's coarse-to-fine schedule and its lower solver (each
// stage run once, and L-BFGS to the middle stages' function tolerance: an end
// needs resolving only well within the agreement bounds). The
// runs agree when every one ends within agree_* of the answer; otherwise the
// spread, and each end's cost against the answer's (sharp images, visibility
// refreshed at the answer for both), tell a flat valley (equal costs: the
// data cannot choose) from a better minimum elsewhere (lower cost).
//
// Core rules: no files, no printing; progress through the callback.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/calibrate.hpp"
#include "core/calibration_result.hpp"
#include "core/geometry.hpp"

namespace scenecal {

struct BasinCheckOptions {
  double offset_rad = RadiansFromDegrees(1.0);  // each start is the answer turned this much about one base axis
  // The runs agree when each ends within both of these of the answer.
  double agree_translation_m = 0.01;
  double agree_rotation_rad = RadiansFromDegrees(0.1);
  // The restarts run the last this many stages of the calibration's schedule
  // (at least 1, at most all): by default the final (sharp) one, whose steps
  // cover the offset. Counted from the end, so that stages prepended to widen
  // the basin do not change the check.
  int last_stages = 1;
  // A restart's end replaces the answer (BetterRestart) only when its cost is
  // lower by more than this many standard errors of the drop over the scenes:
  // on a flat valley the ends' costs differ by what no scene agrees on.
  double adopt_min_standard_errors = 2.0;
  // The run from the answer itself comes first: the answer is at rest when
  // that run stays within this fraction of both agreement bounds (the answer
  // is where the solver rests, not a point it stopped short at on a slope).
  double at_rest_fraction = 0.5;
  // With the answer at rest, a restart whose best point so far lies within
  // this fraction of both agreement bounds has come back, and stops there
  // (the rest of the run would only polish the approach to the answer, and
  // its end counts as the answer). 0 runs every restart to its own
  // convergence. At 0.25 the restarts along a push-broom tilt crept the last
  // few hundredths of a degree along its flat valley; 0.5 took 8-32 % fewer
  // evaluations, 0.9 another 7-22 % on the simulated RobotCar drives (the
  // restarts about the vertical axis crept from 0.9 to 0.5 of the rotation
  // bound), the sigmas within 4 % (BENCHMARK.md, "Basin check and
  // uncertainty").
  double came_back_fraction = 0.9;
  // The trajectory's scale error, 1 sigma (fraction of each distance
  // travelled; 0: not measured). The images cannot tell a scale error from a
  // shift of the lidar along the travel (docs/findings.md, "The drive's scale
  // is invisible to the images"), so no restart and no spread over the scenes
  // sees it: the same run is made once more from the answer with every
  // swathe's steps lengthened by this fraction, and its end is where a
  // 1-sigma scale error moves the answer.
  double scale_sigma = 0.0;
  // With a drift model in use (CalibrationOptions::motion_correction): the
  // same run once more from the answer with every swathe's drift correction
  // removed. Its end is the answer without the model, so how far the model
  // moves the answer is measured where no such answer was solved for (a
  // trajectory_source that names drifting odometry skips the solve without
  // the model). With no correction at all, the end is the answer itself.
  bool without_drift_model = false;

  bool IsValid(std::string* why = nullptr) const;
  // Whether an end this far from the answer agrees with it.
  bool Agrees(double translation_apart_m, double rotation_apart_rad) const {
    return translation_apart_m <= agree_translation_m && rotation_apart_rad <= agree_rotation_rad;
  }
  // Whether a point this far from the answer is within came_back_fraction of both bounds.
  bool CameBack(double translation_apart_m, double rotation_apart_rad) const {
    return Within(came_back_fraction, translation_apart_m, rotation_apart_rad);
  }
  // Whether the run from the answer ended within at_rest_fraction of both bounds.
  bool AtRest(double translation_apart_m, double rotation_apart_rad) const {
    return Within(at_rest_fraction, translation_apart_m, rotation_apart_rad);
  }

 private:
  bool Within(double fraction, double translation_apart_m, double rotation_apart_rad) const {
    return translation_apart_m <= fraction * agree_translation_m && rotation_apart_rad <= fraction * agree_rotation_rad;
  }
};

struct BasinRestart {
  int axis = 0;         // base axis of the start's rotation: 0 x, 1 y, 2 z
  double sign = 1.0;    // +1 or -1
  Eigen::Isometry3d T_base_lidar_end = Eigen::Isometry3d::Identity();
  double translation_apart_m = 0.0;    // |t_end - t_answer|
  double rotation_apart_rad = 0.0;     // angle of R_end * R_answer^T
  double cost_end = 0.0;               // joint cost at the end, visibility at the answer
  // Standard error of cost_answer - cost_end from its spread over the scenes
  // (each pair's scenes taken as independent, the pairs as fully correlated:
  // they share the frames).
  double cost_drop_standard_error = 0.0;
  int evaluations = 0;
  // Stopped once back near the answer (BasinCheckOptions::came_back_fraction):
  // where it stopped is the stopping rule's, and it counts as the answer.
  bool came_back = false;
};

struct LidarBasinCheck {
  std::string lidar;
  bool checked = false;  // false: `why` says why (no used scene at the answer, time budget)
  std::string why;
  bool agree = false;    // every restart ended within the agreement bounds
  // The run from the answer itself (BasinCheckOptions::came_back_fraction):
  // whether it stayed, so that restarts could stop once back, and its cost.
  bool answer_at_rest = false;
  int answer_rest_evaluations = 0;
  double cost_answer = 0.0;  // joint cost at the answer (sharp images, visibility at the answer)
  double max_translation_apart_m = 0.0;
  double max_rotation_apart_rad = 0.0;
  std::vector<BasinRestart> restarts;  // x-, x+, y-, y+, z-, z+
  // The run with the trajectory's scale moved by scale_sigma (BasinCheckOptions), when it ran.
  bool scale_measured = false;
  double scale_sigma = 0.0;  // fraction
  Eigen::Isometry3d T_base_lidar_scale_moved = Eigen::Isometry3d::Identity();  // where that run ended
  // Its move from the answer it started at, as d = [rho (m), phi (rad)]
  // (TransformUpdate::kAboutSourcePoint): kept when a restart is adopted.
  Vector6d scale_move_d = Vector6d::Zero();
  int scale_evaluations = 0;
  // The run with the drift corrections removed (BasinCheckOptions::without_drift_model), when it ran.
  bool drift_model_measured = false;
  Eigen::Isometry3d T_base_lidar_without_drift_model = Eigen::Isometry3d::Identity();  // where that run ended
  Vector6d drift_model_move_d = Vector6d::Zero();  // from that end to the answer it started at, as scale_move_d
  int drift_model_evaluations = 0;
  int evaluations = 0;
  double seconds = 0.0;
  // The calibration's own answer, where the restarts started from and where
  // a restart that came back came back to.
  Eigen::Isometry3d T_base_lidar_calibrated = Eigen::Isometry3d::Identity();
  // Set when a restart's end replaced the answer (AdoptRestart): its index in
  // `restarts`, and the calibration's own answer's cost. cost_answer,
  // the distances and `agree` are then those of the new answer; the costs
  // were all taken with the visibility at the calibration's own answer.
  int adopted_restart = -1;
  double cost_calibrated = 0.0;
  double calibrated_translation_apart_m = 0.0;  // of the calibration's own answer from the new one
  double calibrated_rotation_apart_rad = 0.0;
};

// The restarts above for one lidar's answer, on its pair costs (those with
// scenes) prepared at the answer (Calibrator::PairsAt: sharp images,
// visibility and drift corrections there). Unchecked, with the reason, when
// the answer has no usable scene. Calibrator::CheckBasins runs it per lidar.
LidarBasinCheck CheckLidarBasin(const std::vector<PairCost*>& pairs, const LidarCalibration& answer,
                                const CalibrationOptions& options, const BasinCheckOptions& check_options,
                                const ProgressCallback& progress = {});

// The restart whose end is a better answer than the calibration's, or -1: of
// the restarts that ended apart from the answer (outside the agreement
// bounds) with a cost lower by more than adopt_min_standard_errors standard
// errors and by more than min_cost_drop, the one that ended lowest. The answer then is not the cost's minimum but a
// point where the solver stopped short, as on flat valleys (docs/findings.md,
// "A spinning lidar's forward translation bias"). An end within the bounds is
// the same minimum, whatever its cost.
int BetterRestart(const LidarBasinCheck& check, const BasinCheckOptions& check_options, double min_cost_drop = 0.0);

// Makes restart `index`'s end the answer (*T_base_lidar, in: the
// calibration's answer, out: that end) and re-measures every distance and the
// agreement from it, the calibration's own answer counting as one more end.
void AdoptRestart(int index, const BasinCheckOptions& check_options, LidarBasinCheck* check,
                  Eigen::Isometry3d* T_base_lidar);

// The ends the check found beside the answer: every restart's, with the
// calibration's own answer in place of an adopted restart's and of one that
// came back to it.
std::vector<Eigen::Isometry3d> EndsBesideAnswer(const LidarBasinCheck& check);

}  // namespace scenecal
