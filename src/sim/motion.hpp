// The simulated drive: true motion of the vehicle along the street, and the
// drifting odometry that a visual-odometry or INS system would report.
//
// Vehicle frame V (RobotCar convention): x forward, y right, z down; its
// origin is kVehicleOriginHeight metres above the road surface.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>

#include "sim/world.hpp"

namespace scenecal::sim {

constexpr double kVehicleOriginHeight = 3.0;  // m above the road (the road is at V z = +3.0)

struct DriveOptions {
  double distance_m = 380.0;  // drive until this distance ...
  double duration_s = 0.0;    // ... or, when > 0, for this long
  double mean_speed_mps = 6.5;
  bool include_stop = true;   // one short stop part-way
  double stop_duration_s = 3.0;
};

class Drive {
 public:
  // Integrates the speed profile (1 ms steps) from the seed; the street
  // coordinate s starts at 0.
  Drive(std::uint64_t seed, const DriveOptions& options);

  double duration_s() const { return duration_s_; }
  double total_distance_m() const { return s_.back(); }
  // Arc length of the street at time t (s), clamped to the drive.
  double StreetPositionAt(double t_s) const;
  double SpeedAt(double t_s) const;
  // True pose of the vehicle frame in the world at time t (s from the start),
  // driving in the world's left-hand lane.
  Eigen::Isometry3d T_world_vehicle(double t_s, const World& world) const;

 private:
  double Sample(const std::vector<double>& values, double t_s) const;

  double dt_s_ = 1e-3;
  double duration_s_ = 0.0;
  std::vector<double> s_, v_, a_smooth_;  // arc length (m), speed (m/s), low-passed acceleration (m/s^2)
  // Road-induced pitch/roll and lateral wander: sums of sinusoids in distance.
  struct Wave {
    double amplitude, wavenumber, phase;
  };
  std::vector<Wave> pitch_, roll_, wander_;
};

// Which parts of the odometry drift are simulated (all by default). The parts
// are drawn from the seed whether used or not, so that a dataset with some
// parts left out drifts exactly as the whole one does in the parts it keeps.
struct OdometryDriftParts {
  bool scale_bias = true;   // a constant scale error over the drive (~0.4 %)
  bool scale_waves = true;  // the scale error's wander along the drive (~0.3 % rms, 60-400 m)
  bool rate_waves = true;   // heading and pitch rate errors (~0.01 deg/m rms each, 30-300 m)
};

// Odometry drift, all as smooth functions of distance travelled, scaled by
// `scale` (0 = exact): a scale error of ~0.5 % and heading and pitch rate
// errors of ~0.01 deg/m; `parts` leaves some of them out.
class OdometryDrift {
 public:
  OdometryDrift(std::uint64_t seed, double scale, const OdometryDriftParts& parts = {});
  double ScaleError(double s) const;        // fraction
  double YawRateError(double s) const;      // rad/m
  double PitchRateError(double s) const;    // rad/m

  // Odometry poses of the vehicle for true poses sampled along the drive
  // (same length); the first pose is exact.
  std::vector<Eigen::Isometry3d> Apply(const std::vector<Eigen::Isometry3d>& T_world_vehicle_true,
                                       const std::vector<double>& distance_m) const;

 private:
  struct Wave {
    double amplitude, wavenumber, phase;
  };
  static double Sum(const std::vector<Wave>& waves, double s);
  double scale_;
  double scale_bias_;
  std::vector<Wave> scale_waves_, yaw_, pitch_;
};

}  // namespace scenecal::sim
