#include "core/scene_information.hpp"

#include <algorithm>
#include <limits>

#include <Eigen/Cholesky>

namespace scenecal {

namespace {

// trace(A^-1) of a symmetric positive definite matrix; +inf when it is not.
double TraceOfInverse(const Matrix6d& a) {
  const Eigen::LLT<Matrix6d> llt(a);
  if (llt.info() != Eigen::Success) return std::numeric_limits<double>::infinity();
  return llt.solve(Matrix6d::Identity()).trace();
}

}  // namespace

InformativeChoice ChooseInformativeScenes(const std::vector<Matrix6d>& information, std::size_t count,
                                          const InformativeChoiceOptions& options) {
  InformativeChoice choice;
  const std::size_t n = information.size();
  if (n == 0 || count == 0) return choice;
  Vector6d scale;
  scale << Eigen::Vector3d::Constant(options.unit_translation_m), Eigen::Vector3d::Constant(options.unit_rotation_rad);
  // In units: H_units = S H S (d = S d_units).
  std::vector<Matrix6d> scaled(n);
  double mean_trace = 0.0;
  Matrix6d pool = Matrix6d::Zero();
  for (std::size_t s = 0; s < n; ++s) {
    scaled[s] = scale.asDiagonal() * information[s] * scale.asDiagonal();
    if (!scaled[s].allFinite()) scaled[s].setZero();
    mean_trace += scaled[s].trace() / static_cast<double>(n);
    pool += scaled[s];
  }
  const double ridge = std::max(options.ridge_fraction * mean_trace / 6.0, std::numeric_limits<double>::min());
  const Matrix6d prior = ridge * Matrix6d::Identity();
  choice.predicted_variance_pool = TraceOfInverse(pool + prior);

  std::vector<bool> taken(n, false);
  std::vector<bool> beside_taken(n, false);  // a pool neighbour of a chosen frame
  Matrix6d sum = prior;
  const std::size_t wanted = std::min(count, n);
  while (choice.chosen.size() < wanted) {
    bool any_apart = false;
    for (std::size_t s = 0; s < n; ++s) any_apart = any_apart || (!taken[s] && !beside_taken[s]);
    std::size_t best = n;
    double best_variance = std::numeric_limits<double>::infinity();
    for (std::size_t s = 0; s < n; ++s) {
      if (taken[s]) continue;
      if (options.separate_neighbours && any_apart && beside_taken[s]) continue;
      const double variance = TraceOfInverse(sum + scaled[s]);
      // Strictly better only: ties keep the earlier scene (deterministic).
      if (best == n || variance < best_variance) {
        best = s;
        best_variance = variance;
      }
    }
    taken[best] = true;
    if (best > 0) beside_taken[best - 1] = true;
    if (best + 1 < n) beside_taken[best + 1] = true;
    sum += scaled[best];
    choice.chosen.push_back(best);
    if (options.max_variance_ratio > 0.0 && choice.chosen.size() >= options.min_count &&
        best_variance <= options.max_variance_ratio * choice.predicted_variance_pool)
      break;
  }
  choice.predicted_variance_chosen = TraceOfInverse(sum);
  std::sort(choice.chosen.begin(), choice.chosen.end());
  return choice;
}

}  // namespace scenecal
