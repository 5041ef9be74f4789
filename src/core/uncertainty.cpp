#include "core/uncertainty.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <memory>

#include <Eigen/Eigenvalues>
#include <fmt/format.h>

#include "core/interrupt.hpp"
#include "core/nelder_mead.hpp"

namespace scenecal {
namespace {

Eigen::Isometry3d Moved(const Eigen::Isometry3d& T_base_lidar, const Vector6d& d) {
  return ApplyTransformUpdate(T_base_lidar, d, TransformUpdate::kAboutSourcePoint);
}

// The joint cost of one lidar split into independent units (image times):
// F = sum_u G_u, G_u = sum of the unit's scene costs weighted as the joint
// cost weights them (mean over pairs of the mean over each pair's scenes).
class UnitCosts {
 public:
  explicit UnitCosts(const std::vector<const PairCost*>& pairs) {
    for (const PairCost* pair : pairs) {
      if (pair->UsedSceneCount() > 0) pairs_.push_back(pair);
    }
  }
  bool Empty() const { return pairs_.empty(); }
  int Evaluations() const { return evaluations_; }

  std::map<TimeUs, double> Evaluate(const Eigen::Isometry3d& T_base_lidar) {
    ThrowIfInterrupted();
    ++evaluations_;
    std::map<TimeUs, double> units;
    const double pair_weight = 1.0 / static_cast<double>(pairs_.size());
    for (const PairCost* pair : pairs_) {
      const double weight = pair_weight / static_cast<double>(pair->UsedSceneCount());
      for (const SceneEvaluation& scene :
           pair->EvaluateScenes(pair->Camera().T_camera_base() * T_base_lidar)) {
        if (scene.state != SceneState::kUsed) continue;
        units[scene.image_t_us] += weight * scene.cost;
      }
    }
    return units;
  }

 private:
  std::vector<const PairCost*> pairs_;
  int evaluations_ = 0;
};

double Total(const std::map<TimeUs, double>& units) {
  double sum = 0.0;
  for (const auto& [t, cost] : units) sum += cost;
  return sum;
}

// The paired change of F from `reference` to `moved` and its standard error
// (the units' changes taken as independent draws).
struct PairedChange {
  double change = 0.0;
  double standard_error = 0.0;
};
PairedChange Compare(const std::map<TimeUs, double>& reference, const std::map<TimeUs, double>& moved) {
  std::vector<double> changes;
  changes.reserve(reference.size());
  for (const auto& [t, cost] : reference) {
    const auto it = moved.find(t);
    changes.push_back(it == moved.end() ? 0.0 : it->second - cost);
  }
  const double n = static_cast<double>(changes.size());
  PairedChange result;
  for (const double c : changes) result.change += c;
  const double mean = result.change / n;
  double squares = 0.0;
  for (const double c : changes) squares += (c - mean) * (c - mean);
  // Var(sum) = n Var(unit), Var(unit) estimated with n - 1.
  result.standard_error = n > 1.0 ? std::sqrt(squares * n / (n - 1.0)) : 0.0;
  return result;
}

double WrapAngle(double angle) { return std::remainder(angle, 2.0 * M_PI); }

// d(tuple)/d(d) at T_base_lidar, by central differences.
Matrix6d TupleJacobian(const Eigen::Isometry3d& T_base_lidar) {
  constexpr double kStep = 1e-6;
  Matrix6d jacobian;
  for (int j = 0; j < 6; ++j) {
    Vector6d d = Vector6d::Zero();
    d[j] = kStep;
    Vector6d difference = TupleFromTransform(Moved(T_base_lidar, d)) - TupleFromTransform(Moved(T_base_lidar, -d));
    for (int k = 3; k < 6; ++k) difference[k] = WrapAngle(difference[k]);
    jacobian.col(j) = difference / (2.0 * kStep);
  }
  return jacobian;
}

// Hessian of F in search units by central differences with unit steps; f0 = F(0).
Matrix6d UnitHessian(const std::function<double(const Vector6d&)>& F, double f0) {
  Matrix6d hessian;
  for (int i = 0; i < 6; ++i) {
    const Vector6d e = Vector6d::Unit(i);
    hessian(i, i) = F(e) - 2.0 * f0 + F(-e);
  }
  // Off-diagonals from the points already evaluated plus two per pair (30 instead of 60 evaluations):
  // F(ei+ej) + F(-ei-ej) = 2 F0 + Hii + Hjj + 2 Hij + O(h^4).
  for (int i = 0; i < 6; ++i) {
    for (int j = i + 1; j < 6; ++j) {
      const Vector6d ei = Vector6d::Unit(i), ej = Vector6d::Unit(j);
      hessian(i, j) = hessian(j, i) =
          (F(ei + ej) + F(-ei - ej) - 2.0 * f0 - hessian(i, i) - hessian(j, j)) / 2.0;
    }
  }
  return hessian;
}

// Along one side of a direction: where the paired rise first exceeds k
// standard errors (-1: nowhere), and the farthest step still within k.
struct SideCrossing {
  double crossing = -1.0;
  double farthest_indistinct = 0.0;
};

// The joint cost around the estimate in search units: x (dimensionless), d = scale .* x.
class RiseSearch {
 public:
  RiseSearch(UnitCosts* costs, const std::map<TimeUs, double>& at_estimate, const Eigen::Isometry3d& T_base_lidar,
             const Vector6d& scale, const UncertaintyOptions& options)
      : costs_(costs), at_estimate_(at_estimate), T_base_lidar_(T_base_lidar), scale_(scale),
        k_(options.significance) {
    for (double a = 0.25; a <= options.max_search_units + 1e-9; a *= 2.0) steps_.push_back(a);
  }

  double F(const Vector6d& x) { return Total(costs_->Evaluate(Moved(T_base_lidar_, scale_.cwiseProduct(x)))); }

  // Along the unit eigenvector x, both sides: the step where the paired rise exceeds k standard errors.
  UncertainDirection Along(const Vector6d& x, double curvature) {
    UncertainDirection direction;
    direction.direction = scale_.cwiseProduct(x);
    direction.curvature = curvature;
    const SideCrossing positive = Side(x, 1.0), negative = Side(x, -1.0);
    if (positive.crossing > 0.0 && negative.crossing > 0.0) {
      direction.determined = true;
      direction.sigma_units = 0.5 * (positive.crossing + negative.crossing) / (2.0 * k_);
    } else {
      direction.flat_units = std::max(positive.farthest_indistinct, negative.farthest_indistinct);
    }
    return direction;
  }

 private:
  // The search goes on past the first significant rise: a cost that comes
  // back within k standard errors further out means another basin the data
  // cannot tell from this one, and the side counts as without a crossing.
  SideCrossing Side(const Vector6d& x, double sign) {
    SideCrossing side;
    double previous_step = 0.0, previous_ratio = 0.0;
    for (const double a : steps_) {
      const PairedChange change =
          Compare(at_estimate_, costs_->Evaluate(Moved(T_base_lidar_, scale_.cwiseProduct(sign * a * x))));
      const double ratio = change.standard_error > 0.0 ? change.change / change.standard_error
                                                       : (change.change > 0.0 ? 1e9 : 0.0);
      if (ratio <= k_) side.farthest_indistinct = a;
      if (ratio > k_ && side.crossing < 0.0) {
        const double fraction = (k_ - previous_ratio) / (ratio - previous_ratio);
        side.crossing = previous_step + std::clamp(fraction, 0.0, 1.0) * (a - previous_step);
      }
      previous_step = a;
      previous_ratio = std::max(0.0, ratio);  // below zero: the cost fell; the rise starts from here
    }
    // Indistinct beyond the first crossing: no crossing on this side after all.
    if (side.crossing > 0.0 && side.farthest_indistinct > side.crossing) side.crossing = -1.0;
    return side;
  }

  UnitCosts* costs_;
  const std::map<TimeUs, double>& at_estimate_;
  const Eigen::Isometry3d& T_base_lidar_;
  const Vector6d& scale_;
  double k_;                   // significance: standard errors of a significant rise
  std::vector<double> steps_;  // search steps, units
};

std::string WhyUndetermined(const std::vector<UncertainDirection>& directions, const UncertaintyOptions& options) {
  const auto open = std::count_if(directions.begin(), directions.end(),
                                  [](const UncertainDirection& d) { return !d.determined; });
  return fmt::format("the cost does not rise significantly along {} of 6 directions within {} cm / {} deg", open,
                     100.0 * options.max_search_units * options.unit_translation_m,
                     options.max_search_units * options.unit_rotation_rad * 180.0 / M_PI);
}

}  // namespace

bool UncertaintyOptions::IsValid(std::string* why) const {
  if (!(unit_translation_m > 0.0) || !(unit_rotation_rad > 0.0)) {
    if (why != nullptr) *why = "the search units must be positive";
    return false;
  }
  if (!(significance > 0.0) || !(max_search_units >= 0.25)) {
    if (why != nullptr) *why = "significance must be positive and max_search_units at least 0.25";
    return false;
  }
  if (min_units < 3) {
    if (why != nullptr) *why = "min_units must be at least 3";
    return false;
  }
  return true;
}

LidarUncertainty EstimateLidarUncertainty(const std::vector<const PairCost*>& pairs,
                                          const Eigen::Isometry3d& T_base_lidar, const UncertaintyOptions& options) {
  LidarUncertainty result;
  if (!options.IsValid(&result.why)) return result;
  UnitCosts costs(pairs);
  if (costs.Empty()) {
    result.why = "no pair has a scene with enough projected points";
    return result;
  }
  const std::map<TimeUs, double> at_estimate = costs.Evaluate(T_base_lidar);
  result.units = static_cast<int>(at_estimate.size());
  if (result.units < options.min_units) {
    result.why = fmt::format("{} independent scenes; the estimate needs at least {}", result.units, options.min_units);
    return result;
  }
  result.estimated = true;

  // Work in units: x (dimensionless), d = scale .* x.
  Vector6d scale;
  scale << Eigen::Vector3d::Constant(options.unit_translation_m), Eigen::Vector3d::Constant(options.unit_rotation_rad);
  RiseSearch search(&costs, at_estimate, T_base_lidar, scale, options);
  const Matrix6d hessian = UnitHessian([&](const Vector6d& x) { return search.F(x); }, Total(at_estimate));
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eigen(hessian);

  Matrix6d covariance_units = Matrix6d::Zero();
  bool all_determined = true;
  for (int v = 0; v < 6; ++v) {
    const Vector6d x = eigen.eigenvectors().col(v);
    const UncertainDirection direction = search.Along(x, eigen.eigenvalues()[v]);
    if (direction.determined) covariance_units += direction.sigma_units * direction.sigma_units * x * x.transpose();
    else all_determined = false;
    result.directions.push_back(direction);
  }
  result.evaluations = costs.Evaluations();
  if (!all_determined) {
    result.why = WhyUndetermined(result.directions, options);
    return result;
  }
  result.determined = true;
  result.covariance = scale.asDiagonal() * covariance_units * scale.asDiagonal();
  const Matrix6d jacobian = TupleJacobian(T_base_lidar);
  result.sigma_tuple = (jacobian * result.covariance * jacobian.transpose()).diagonal().cwiseMax(0.0).cwiseSqrt();
  return result;
}

std::string DescribeLocalUpdate(const Vector6d& d) {
  const double deg = 180.0 / M_PI;
  return fmt::format("dx {:+.2f} dy {:+.2f} dz {:+.2f} cm, rx {:+.3f} ry {:+.3f} rz {:+.3f} deg", 100.0 * d[0],
                     100.0 * d[1], 100.0 * d[2], deg * d[3], deg * d[4], deg * d[5]);
}

}  // namespace scenecal
