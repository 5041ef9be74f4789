// Cost slices (the paper's Fig. 6): a cost of a transform sampled along each
// of the 6 degrees of freedom around a centre, one at a time, with the local
// update T = ExpSE3(delta_k e_k) * T_centre (tangent ordering [rho; phi] of
// geometry.hpp). For T_camera_lidar this perturbs in the camera frame: k = 0..2
// translate along camera x (right), y (down), z (forward); k = 3..5 rotate
// about those axes.
//
// Usage for the alternating scheme (light to dark per alternation):
//   PairCost& cost = ...;                                // the pair's cost
//   auto curves = SampleAlternationSlices(cost, result.history, pair, T_camera_lidar_initial, {});
//   -> one CostSliceSet per sliced alternation, around its lower solution, of
//      f_p (or, with include_penalty, f_p + that alternation's penalty: the
//      function the lower level minimised).
// For `once` / `joint`: SampleCostSlices(f, T_result, {}) gives one set.
#pragma once

#include <array>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/alternating.hpp"
#include "core/geometry.hpp"
#include "core/pair_cost.hpp"

namespace scenecal::report {

struct CostSliceOptions {
  double half_range_translation_m = 0.05;                     // +-5 cm
  double half_range_rotation_rad = RadiansFromDegrees(0.5);  // +-0.5 deg
  int samples = 21;  // per DoF, evenly over [-half, +half]; forced odd so 0 is sampled
  // SampleAlternationSlices: slice at most this many alternations, evenly
  // spread, always including the first and the last (each costs 6 x samples
  // evaluations).
  int max_alternations = 8;
  // Add |T (-) T_upper|^2_{P^i} as the lower level did (exactly the function it
  // minimised, as in the paper's Fig. 6). Off by default: late in the schedule
  // the penalty dwarfs the data term and hides which directions the data constrains.
  bool include_penalty = false;
  PenaltyFrame penalty_frame = PenaltyFrame::kLidar;  // as AlternatingOptions::penalty_frame of the run
  bool refresh_visibility = true;   // PairCost: refresh the z-buffer at each centre first

  bool IsValid(std::string* why = nullptr) const;
};

// Names of the tangent directions, for labels: "x", "y", "z", "rx", "ry", "rz".
const char* TangentName(int dof);

struct CostSlice {
  int dof = 0;                   // 0..5, tangent index
  std::vector<double> offsets;   // delta_k: metres (dof 0-2) or radians (dof 3-5)
  std::vector<double> costs;     // cost at ExpSE3(delta_k e_k) * centre; NaN where undefined
};

struct CostSliceSet {
  std::string label;  // e.g. "alternation 3"
  int alternation = -1;  // -1 when not from an alternation
  bool penalised = false;  // the samples include the alternation's penalty term
  Eigen::Isometry3d centre = Eigen::Isometry3d::Identity();
  std::array<CostSlice, 6> slices;
};

using TransformCost = std::function<double(const Eigen::Isometry3d&)>;

// Samples `cost` along each DoF around `centre` (cost called 6 * samples times, serially;
// the cost may parallelise internally).
CostSliceSet SampleCostSlices(const TransformCost& cost, const Eigen::Isometry3d& centre,
                              const CostSliceOptions& options = {});

// Which alternations SampleAlternationSlices slices: up to max_alternations of
// 0..count-1, evenly spread, first and last included, ascending.
std::vector<int> SlicedAlternations(int count, int max_alternations);

// Fig. 6 for one pair of an alternating result: around the lower solution of
// each sliced alternation i, the lower-level objective of that alternation,
//   f_p(T) [+ |DifferenceLog(T, T_upper_held)|^2 with P^i from the record's sigmas],
// where T_upper_held is the upper estimate the lower level started from: the
// previous alternation's upper solution, or T_camera_lidar_initial for i = 0.
// `pair` indexes the records' per-pair vectors. Refreshes the cost's
// visibility at each centre when options.refresh_visibility (and leaves it at
// the last centre).
std::vector<CostSliceSet> SampleAlternationSlices(PairCost& cost, const std::vector<AlternationRecord>& history,
                                                  int pair, const Eigen::Isometry3d& T_camera_lidar_initial,
                                                  const CostSliceOptions& options = {});
// Same with any cost function (no visibility refresh).
std::vector<CostSliceSet> SampleAlternationSlices(const TransformCost& cost,
                                                  const std::vector<AlternationRecord>& history, int pair,
                                                  const Eigen::Isometry3d& T_camera_lidar_initial,
                                                  const CostSliceOptions& options = {});

}  // namespace scenecal::report
