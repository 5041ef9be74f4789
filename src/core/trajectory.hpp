// The base frame's trajectory: T_world_base at increasing times, interpolated
// between samples (linear translation, slerp rotation).
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Geometry>

namespace scenecal {

using TimeUs = std::int64_t;  // microseconds, one clock for every sensor

class Trajectory {
 public:
  Trajectory() = default;
  // times_us strictly increasing, same length as poses; checked by the reader.
  Trajectory(std::vector<TimeUs> times_us, std::vector<Eigen::Isometry3d> T_world_base);

  bool empty() const { return times_us_.empty(); }
  std::size_t size() const { return times_us_.size(); }
  const std::vector<TimeUs>& times_us() const { return times_us_; }
  const std::vector<Eigen::Isometry3d>& poses() const { return T_world_base_; }

  // T_world_base at time t; nullopt outside [first, last] (a single-row
  // trajectory has a pose only at its own time).
  std::optional<Eigen::Isometry3d> PoseAt(TimeUs t) const;
  // Distance travelled (metres, along the samples) from the first sample to
  // time t, clamped to the covered span.
  double DistanceAt(TimeUs t) const;
  double TotalDistance() const;

 private:
  std::vector<TimeUs> times_us_;
  std::vector<Eigen::Isometry3d> T_world_base_;
  std::vector<double> cumulative_distance_m_;
};

}  // namespace scenecal
