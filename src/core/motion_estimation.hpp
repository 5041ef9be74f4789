// Odometry drift inside the swathes: each camera frame's correction
// (SwatheMotionCorrection) estimated from the images, and a held-out test of
// whether the drift is there at all.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/geometry.hpp"
#include "core/pair_cost.hpp"
#include "core/swathe_motion.hpp"

namespace scenecal {

// Odometry drift correction (SwatheMotionCorrection), estimated by
// EstimateMotionCorrections (below): for each camera frame, the terms that
// minimise that frame's own cost at a fixed T_camera_lidar, within the bounds
// (Nelder-Mead, from the frame's previous correction); the drive's scale from
// all frames together.
struct MotionCorrectionOptions {
  // Which terms are estimated (the others keep the frame's current values: 0 at first); at least one.
  bool scale = false;
  bool turn = true;   // both rates across the travel (heading and pitch, whichever way the base is turned)
  bool roll = false;  // the rate about the travel
  // One scale error for the whole drive (the odometry's scale bias), shared by
  // every frame and estimated from all frames' costs together before the
  // per-frame terms; with `scale` as well, each frame then refines it.
  bool drive_scale = false;
  double max_scale = 0.02;                         // |scale| bound (fraction)
  double max_rate_rad_per_m = RadiansFromDegrees(0.05);  // bound on each rate
  double initial_step_scale = 0.004;               // simplex steps
  double initial_step_rate_rad_per_m = 1.7453e-4;  // 0.01 deg/m
  int max_iterations = 60;

  bool IsValid(std::string* why = nullptr) const;
};

struct MotionCorrectionSummary {
  int frames = 0;            // camera frames corrected (with a used scene)
  int evaluations = 0;       // frame-cost evaluations, all frames
  double cost_before = 0.0;  // mean over the frames of their cost before and after
  double cost_after = 0.0;
  int drive_evaluations = 0;  // of the drive's scale (options.drive_scale), all frames each
  std::vector<SwatheMotionCorrection> corrections;  // per scene: the pairs' Scenes() one after the other
};

// The used scenes of one image time, over several pairs (the cameras of a rig
// that fire together, a frame's range bands, several lidars): they share one
// correction, and their cost is the mean of theirs at their pairs' transforms.
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
  double Cost() const;

 private:
  std::vector<SceneSwathe*> swathes_;
  std::vector<std::function<double()>> costs_;  // per scene
};

// The used scenes of every pair (states of its last refresh) by image time,
// each pair scored at its T_camera_lidar (one per pair; both must outlive the frames).
std::map<TimeUs, CorrectionFrame> CorrectionFramesByTime(const std::vector<PairCost*>& pairs,
                                                         const std::vector<Eigen::Isometry3d>& T_camera_lidar);

// Estimates each frame's SwatheMotionCorrection with every pair at its
// T_camera_lidar (one per pair) and applies it to their swathes: the used
// scenes with the same image time, over all pairs (the cameras of a rig that
// fire together, a frame's range bands, several lidars), share one correction
// and minimise their mean cost. With options.drive_scale the scale is first
// chosen for all frames together (the mean of the frames' costs); then the
// frames' own terms, independently (in parallel). Uses the scene states of
// each pair's last refresh. Between optimiser runs only.
MotionCorrectionSummary EstimateMotionCorrections(const std::vector<PairCost*>& pairs,
                                                  const std::vector<Eigen::Isometry3d>& T_camera_lidar,
                                                  const MotionCorrectionOptions& options);

// Whether the trajectory drifts within the swathes, from the data alone: a
// correction that follows the odometry's drift (smooth along the drive)
// predicts the next frame's, while one that fits each frame's own misfit (exact
// odometry) does not. The frames are split into two interleaved halves; each
// half's corrections are estimated on its own frames (options.motion, at the
// pairs' transforms), each frame of the other half gets the correction
// interpolated in time from its two neighbours, and its cost with that
// correction is compared with its cost without. Every frame is held out once.
struct DriftTestOptions {
  MotionCorrectionOptions motion;  // the per-frame terms estimated (drive_scale is not: one value has no neighbours)
  double min_t_statistic = 2.0;    // keep the correction when the held-out cost falls by this many standard errors
  int min_frames = 6;              // fewer frames: no verdict
};

struct DriftTestResult {
  int frames = 0;                  // camera frames with a used scene, each held out once
  double mean_cost_change = 0.0;   // held-out cost with the predicted correction minus without, mean over frames
  double standard_error = 0.0;     // of that mean
  int frames_lower = 0;            // held-out frames whose cost the predicted correction lowered
  bool enough_frames = false;      // frames >= min_frames
  bool drift_found = false;        // the correction lowered the held-out cost by >= min_t_statistic errors

  // e.g. "held-out cost -0.00123 +- 0.00021 (t = -5.9, 22 of 28 frames lower): drift found".
  std::string Describe() const;
};

// The test at each pair's T_camera_lidar (the pairs refreshed there). Leaves
// every swathe's correction as it found it. Between optimiser runs only.
DriftTestResult TestDrift(const std::vector<PairCost*>& pairs, const std::vector<Eigen::Isometry3d>& T_camera_lidar,
                          const DriftTestOptions& options);

}  // namespace scenecal
