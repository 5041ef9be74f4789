#include "sim/motion.hpp"

#include <algorithm>
#include <cmath>

#include "core/geometry.hpp"
#include "sim/noise.hpp"

namespace scenecal::sim {
namespace {

constexpr double kTwoPi = 6.283185307179586;

}  // namespace

Drive::Drive(std::uint64_t seed, const DriveOptions& options) {
  KeyedRandom random(seed, 800);
  const double mean = options.mean_speed_mps;
  const double period1 = random.Uniform(25.0, 40.0), phase1 = random.Uniform(0.0, kTwoPi);
  const double period2 = random.Uniform(8.0, 14.0), phase2 = random.Uniform(0.0, kTwoPi);
  const auto nominal_speed = [&](double t) {
    return mean * (1.0 + 0.15 * std::sin(kTwoPi * t / period1 + phase1) + 0.08 * std::sin(kTwoPi * t / period2 + phase2));
  };
  const bool by_duration = options.duration_s > 0.0;
  const double expected_distance = by_duration ? options.duration_s * mean : options.distance_m;
  const double stop_at = options.include_stop ? expected_distance * random.Uniform(0.4, 0.6) : 1e300;
  const double braking = 1.6, accelerating = 1.2;  // m/s^2

  enum class Phase { kBeforeStop, kStopped, kAfterStop } phase = Phase::kBeforeStop;
  double s = 0.0, v = nominal_speed(0.0), t = 0.0, stopped_since = 0.0;
  s_.push_back(s);
  v_.push_back(v);
  while (by_duration ? t < options.duration_s : s < options.distance_m) {
    t += dt_s_;
    switch (phase) {
      case Phase::kBeforeStop: {
        const double remaining = stop_at - s;
        const double v_brake = std::sqrt(std::max(0.0, 2.0 * braking * remaining));
        v = std::min({nominal_speed(t), v_brake, v + accelerating * dt_s_});
        if (v * dt_s_ >= remaining) {  // arrived: stand still exactly at stop_at
          s = stop_at;
          v = 0.0;
          phase = Phase::kStopped;
          stopped_since = t;
        } else {
          s += v * dt_s_;
        }
        break;
      }
      case Phase::kStopped:
        v = 0.0;
        if (t - stopped_since >= options.stop_duration_s) phase = Phase::kAfterStop;
        break;
      case Phase::kAfterStop:
        v = std::min(nominal_speed(t), v + accelerating * dt_s_);
        s += v * dt_s_;
        break;
    }
    s_.push_back(s);
    v_.push_back(v);
  }
  duration_s_ = t;
  // Acceleration, low-passed like a suspension's response (tau 0.35 s).
  a_smooth_.assign(v_.size(), 0.0);
  for (std::size_t i = 1; i < v_.size(); ++i) {
    const double a_raw = (v_[i] - v_[i - 1]) / dt_s_;
    a_smooth_[i] = a_smooth_[i - 1] + (a_raw - a_smooth_[i - 1]) * dt_s_ / 0.35;
  }
  const auto waves = [&](int count, double amplitude, double lambda_min, double lambda_max) {
    std::vector<Wave> result;
    for (int i = 0; i < count; ++i) {
      result.push_back({amplitude * random.Uniform(0.5, 1.0), kTwoPi / random.Uniform(lambda_min, lambda_max),
                        random.Uniform(0.0, kTwoPi)});
    }
    return result;
  };
  pitch_ = waves(3, RadiansFromDegrees(0.2), 6.0, 45.0);
  roll_ = waves(3, RadiansFromDegrees(0.15), 5.0, 40.0);
  wander_ = waves(2, 0.12, 25.0, 90.0);
}

double Drive::Sample(const std::vector<double>& values, double t_s) const {
  const double x = std::clamp(t_s / dt_s_, 0.0, static_cast<double>(values.size() - 1));
  const auto i = std::min(static_cast<std::size_t>(x), values.size() - 2);
  const double f = x - static_cast<double>(i);
  return values[i] + (values[i + 1] - values[i]) * f;
}

double Drive::StreetPositionAt(double t_s) const { return Sample(s_, t_s); }
double Drive::SpeedAt(double t_s) const { return Sample(v_, t_s); }

Eigen::Isometry3d Drive::T_world_vehicle(double t_s, const World& world) const {
  const CentreLine& line = world.centre_line();
  const double s = StreetPositionAt(t_s);
  const double v = SpeedAt(t_s);
  const double a = Sample(a_smooth_, t_s);
  double d = world.layout().driving_lane_offset, d_slope = 0.0, pitch = 0.0, roll = 0.0, bounce = 0.0;
  for (const Wave& w : wander_) {
    d += w.amplitude * std::sin(w.wavenumber * s + w.phase);
    d_slope += w.amplitude * w.wavenumber * std::cos(w.wavenumber * s + w.phase);
  }
  for (const Wave& w : pitch_) pitch += w.amplitude * std::sin(w.wavenumber * s + w.phase);
  for (const Wave& w : roll_) roll += w.amplitude * std::sin(w.wavenumber * s + w.phase);
  // Suspension bounce (m), at most 1 cm per road wave.
  for (const Wave& w : pitch_) bounce += 0.01 * w.amplitude / RadiansFromDegrees(0.2) * std::cos(w.wavenumber * s + w.phase);
  // Nose dips when braking, squats when accelerating; leans out of curves.
  pitch += RadiansFromDegrees(0.5) * a;
  roll += RadiansFromDegrees(0.4) * v * v * line.Curvature(s);

  const double heading = line.Heading(s) + std::atan(d_slope);  // world, counter-clockwise from x
  const Eigen::Vector2d xy = line.ToWorld(s, d);
  // V is z-down, W is z-up: flip about x, then yaw (clockwise in the flipped frame), pitch, roll.
  const Eigen::Matrix3d flip = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = flip * RotationFromRollPitchYaw(roll, pitch, -heading);
  T.translation() = Eigen::Vector3d(xy.x(), xy.y(), kVehicleOriginHeight + bounce);
  return T;
}

// ---------------------------------------------------------------------------

OdometryDrift::OdometryDrift(std::uint64_t seed, double scale, const OdometryDriftParts& parts) : scale_(scale) {
  KeyedRandom random(seed, 900);
  // Three waves of amplitude A have an RMS of A * sqrt(3 / 2); choose A for a target RMS.
  const auto waves = [&](double rms, double lambda_min, double lambda_max) {
    std::vector<Wave> result;
    const double amplitude = rms * std::sqrt(2.0 / 3.0);
    for (int i = 0; i < 3; ++i) {
      result.push_back({amplitude * (random.Chance(0.5) ? 1.0 : -1.0), kTwoPi / random.Uniform(lambda_min, lambda_max),
                        random.Uniform(0.0, kTwoPi)});
    }
    return result;
  };
  scale_bias_ = 0.004 * random.Gaussian();
  scale_waves_ = waves(0.003, 60.0, 400.0);
  yaw_ = waves(RadiansFromDegrees(0.01), 30.0, 300.0);
  pitch_ = waves(RadiansFromDegrees(0.01), 30.0, 300.0);
  // Drawn above in any case: the parts kept are those of the whole drift.
  if (!parts.scale_bias) scale_bias_ = 0.0;
  if (!parts.scale_waves) scale_waves_.clear();
  if (!parts.rate_waves) {
    yaw_.clear();
    pitch_.clear();
  }
}

double OdometryDrift::Sum(const std::vector<Wave>& waves, double s) {
  double sum = 0.0;
  for (const Wave& w : waves) sum += w.amplitude * std::sin(w.wavenumber * s + w.phase);
  return sum;
}

double OdometryDrift::ScaleError(double s) const { return scale_ * (scale_bias_ + Sum(scale_waves_, s)); }
double OdometryDrift::YawRateError(double s) const { return scale_ * Sum(yaw_, s); }
double OdometryDrift::PitchRateError(double s) const { return scale_ * Sum(pitch_, s); }

std::vector<Eigen::Isometry3d> OdometryDrift::Apply(const std::vector<Eigen::Isometry3d>& T_world_vehicle_true,
                                                    const std::vector<double>& distance_m) const {
  std::vector<Eigen::Isometry3d> odometry(T_world_vehicle_true.size());
  if (odometry.empty()) return odometry;
  odometry[0] = T_world_vehicle_true[0];
  for (std::size_t i = 0; i + 1 < odometry.size(); ++i) {
    const Eigen::Isometry3d delta = T_world_vehicle_true[i].inverse() * T_world_vehicle_true[i + 1];
    const double ds = distance_m[i + 1] - distance_m[i];
    const double s_mid = 0.5 * (distance_m[i] + distance_m[i + 1]);
    Eigen::Isometry3d drifted = delta;
    drifted.translation() *= 1.0 + ScaleError(s_mid);
    // Heading (about V z) and pitch (about V y) errors accumulate with distance.
    drifted.linear() = delta.linear() * RotationFromRollPitchYaw(0.0, PitchRateError(s_mid) * ds, YawRateError(s_mid) * ds);
    odometry[i + 1] = odometry[i] * drifted;
  }
  return odometry;
}

}  // namespace scenecal::sim
