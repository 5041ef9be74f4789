// Drift correction of the odometry inside a swathe (SceneSwathe::SetMotionCorrection
// applies it to a swathe's scan poses).
#pragma once

#include <vector>

#include <Eigen/Geometry>

#include "core/trajectory.hpp"

namespace scenecal {

// A correction of the odometry inside one swathe, for drift the trajectory
// carries over the swathe's length (a nuisance estimated per camera frame,
// see PairCost::EstimateMotionCorrections). Along the chain of scan poses,
// from the image time outwards, every step of the trajectory is corrected:
// its length scaled by (1 + scale), the base turned by rate * length about
// the travel frame's axes, the step's direction by half that turn. The
// travel frame (in base k; the base's own axes may point anywhere, e.g. a
// camera's) has `forward` along the swathe's mean direction of travel and two
// axes across it: MotionAxes. A constant scale error and constant turn rates
// over the swathe (how visual odometry or an INS drifts: heading and pitch
// rates) are undone exactly to first order. Zero = the trajectory as given.
struct SwatheMotionCorrection {
  double scale = 0.0;                  // fraction of each step's length (e.g. 0.005 = 0.5 %)
  double turn_a_rad_per_m = 0.0;       // about the first axis across the travel, per metre travelled
  double turn_b_rad_per_m = 0.0;       // about the second axis across the travel
  double roll_rad_per_m = 0.0;         // about the direction of travel

  bool IsZero() const {
    return scale == 0.0 && turn_a_rad_per_m == 0.0 && turn_b_rad_per_m == 0.0 && roll_rad_per_m == 0.0;
  }
};

// The travel frame of a swathe (columns: across a, across b, forward; base k
// axes): forward along the chord from the first scan's position to the
// last's (time order); across a is the base axis most nearly perpendicular to
// it, made perpendicular; across b = forward x across a. Identity when the
// swathe does not move (a static scene).
Eigen::Matrix3d MotionAxes(const std::vector<Eigen::Isometry3d>& T_basek_basej);

// The poses T_basek_basej (base at scan time j -> base at image time k, scans
// in time order, image at time image_t_us) after `correction` (see above).
std::vector<Eigen::Isometry3d> CorrectSwatheMotion(const std::vector<TimeUs>& scan_t_us,
                                                   const std::vector<Eigen::Isometry3d>& T_basek_basej,
                                                   TimeUs image_t_us, const SwatheMotionCorrection& correction);

}  // namespace scenecal
