#include "core/trajectory.hpp"

#include <algorithm>
#include <utility>

#include "core/geometry.hpp"

namespace scenecal {

Trajectory::Trajectory(std::vector<TimeUs> times_us, std::vector<Eigen::Isometry3d> T_world_base)
    : times_us_(std::move(times_us)), T_world_base_(std::move(T_world_base)) {
  cumulative_distance_m_.resize(T_world_base_.size(), 0.0);
  for (std::size_t i = 1; i < T_world_base_.size(); ++i) {
    cumulative_distance_m_[i] = cumulative_distance_m_[i - 1] +
        (T_world_base_[i].translation() - T_world_base_[i - 1].translation()).norm();
  }
}

std::optional<Eigen::Isometry3d> Trajectory::PoseAt(TimeUs t) const {
  if (times_us_.empty() || t < times_us_.front() || t > times_us_.back()) return std::nullopt;
  const auto upper = std::upper_bound(times_us_.begin(), times_us_.end(), t);
  const std::size_t i1 = static_cast<std::size_t>(upper - times_us_.begin());
  if (i1 == times_us_.size()) return T_world_base_.back();  // t == last time
  const std::size_t i0 = i1 - 1;
  const double alpha = static_cast<double>(t - times_us_[i0]) / static_cast<double>(times_us_[i1] - times_us_[i0]);
  return Interpolate(T_world_base_[i0], T_world_base_[i1], alpha);
}

double Trajectory::DistanceAt(TimeUs t) const {
  if (times_us_.empty()) return 0.0;
  if (t <= times_us_.front()) return 0.0;
  if (t >= times_us_.back()) return cumulative_distance_m_.back();
  const auto upper = std::upper_bound(times_us_.begin(), times_us_.end(), t);
  const std::size_t i1 = static_cast<std::size_t>(upper - times_us_.begin());
  const std::size_t i0 = i1 - 1;
  const double alpha = static_cast<double>(t - times_us_[i0]) / static_cast<double>(times_us_[i1] - times_us_[i0]);
  return cumulative_distance_m_[i0] + alpha * (cumulative_distance_m_[i1] - cumulative_distance_m_[i0]);
}

double Trajectory::TotalDistance() const {
  return cumulative_distance_m_.empty() ? 0.0 : cumulative_distance_m_.back();
}

}  // namespace scenecal
