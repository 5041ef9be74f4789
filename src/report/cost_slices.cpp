#include "report/cost_slices.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/interrupt.hpp"
#include "core/upper_level.hpp"
#include "core/validation.hpp"

namespace scenecal::report {

bool CostSliceOptions::IsValid(std::string* why) const {
  if (!(half_range_translation_m > 0) || !std::isfinite(half_range_translation_m))
    return Invalid(why, "half_range_translation_m must be positive and finite");
  if (!(half_range_rotation_rad > 0) || !std::isfinite(half_range_rotation_rad))
    return Invalid(why, "half_range_rotation_rad must be positive and finite");
  if (samples < 3) return Invalid(why, "samples must be at least 3");
  if (max_alternations < 1) return Invalid(why, "max_alternations must be at least 1");
  return true;
}

const char* TangentName(int dof) {
  static constexpr const char* kNames[6] = {"x", "y", "z", "rx", "ry", "rz"};
  return dof >= 0 && dof < 6 ? kNames[dof] : "?";
}

CostSliceSet SampleCostSlices(const TransformCost& cost, const Eigen::Isometry3d& centre,
                              const CostSliceOptions& options) {
  CostSliceSet set;
  set.centre = centre;
  const int samples = std::max(3, options.samples | 1);  // odd: the centre is a sample
  for (int dof = 0; dof < 6; ++dof) {
    CostSlice& slice = set.slices[static_cast<std::size_t>(dof)];
    slice.dof = dof;
    const double half = dof < 3 ? options.half_range_translation_m : options.half_range_rotation_rad;
    for (int s = 0; s < samples; ++s) {
      ThrowIfInterrupted();  // `calibrate --report` samples a few hundred costs
      const double offset = -half + 2.0 * half * s / (samples - 1);
      Vector6d twist = Vector6d::Zero();
      twist[dof] = offset;
      const double value = cost(ExpSE3(twist) * centre);
      slice.offsets.push_back(offset);
      slice.costs.push_back(std::isfinite(value) ? value : std::numeric_limits<double>::quiet_NaN());
    }
  }
  return set;
}

std::vector<int> SlicedAlternations(int count, int max_alternations) {
  std::vector<int> chosen;
  if (count <= 0) return chosen;
  const int wanted = std::clamp(max_alternations, 1, count);
  if (wanted == 1) return {count - 1};
  for (int k = 0; k < wanted; ++k) {
    const int index = static_cast<int>(std::lround(static_cast<double>(k) * (count - 1) / (wanted - 1)));
    if (chosen.empty() || chosen.back() != index) chosen.push_back(index);
  }
  return chosen;
}

namespace {

std::vector<CostSliceSet> SliceHistory(const TransformCost& cost,
                                       const std::function<void(const Eigen::Isometry3d&)>& refresh,
                                       const std::vector<AlternationRecord>& history, int pair,
                                       const Eigen::Isometry3d& T_camera_lidar_initial,
                                       const CostSliceOptions& options) {
  std::vector<CostSliceSet> sets;
  if (pair < 0) return sets;
  const std::size_t p = static_cast<std::size_t>(pair);
  for (int i : SlicedAlternations(static_cast<int>(history.size()), options.max_alternations)) {
    const AlternationRecord& record = history[static_cast<std::size_t>(i)];
    if (p >= record.T_camera_lidar_lower.size()) continue;
    const Eigen::Isometry3d centre = record.T_camera_lidar_lower[p];
    Eigen::Isometry3d upper_held = T_camera_lidar_initial;
    if (i > 0 && p < history[static_cast<std::size_t>(i - 1)].T_camera_lidar_upper.size())
      upper_held = history[static_cast<std::size_t>(i - 1)].T_camera_lidar_upper[p];
    const bool penalised = options.include_penalty && record.sigma_translation_m > 0 && record.sigma_rotation_rad > 0;
    const Matrix6d information =
        penalised ? PairPenaltyInformation(record.sigma_translation_m, record.sigma_rotation_rad, options.penalty_frame,
                                           upper_held)
                  : Matrix6d::Zero();
    const TransformCost objective = [&](const Eigen::Isometry3d& T) {
      double value = cost(T);
      if (penalised) {
        const Vector6d difference = DifferenceLog(T, upper_held);
        value += difference.dot(information * difference);
      }
      return value;
    };
    if (refresh) refresh(centre);
    CostSliceSet set = SampleCostSlices(objective, centre, options);
    set.alternation = record.alternation;
    set.penalised = penalised;
    set.label = "alternation " + std::to_string(record.alternation);
    sets.push_back(std::move(set));
  }
  return sets;
}

}  // namespace

std::vector<CostSliceSet> SampleAlternationSlices(PairCost& cost, const std::vector<AlternationRecord>& history,
                                                  int pair, const Eigen::Isometry3d& T_camera_lidar_initial,
                                                  const CostSliceOptions& options) {
  std::function<void(const Eigen::Isometry3d&)> refresh;
  if (options.refresh_visibility) refresh = [&cost](const Eigen::Isometry3d& T) { cost.RefreshVisibility(T); };
  return SliceHistory([&cost](const Eigen::Isometry3d& T) { return cost.Evaluate(T); }, refresh, history, pair,
                      T_camera_lidar_initial, options);
}

std::vector<CostSliceSet> SampleAlternationSlices(const TransformCost& cost,
                                                  const std::vector<AlternationRecord>& history, int pair,
                                                  const Eigen::Isometry3d& T_camera_lidar_initial,
                                                  const CostSliceOptions& options) {
  return SliceHistory(cost, {}, history, pair, T_camera_lidar_initial, options);
}

}  // namespace scenecal::report
