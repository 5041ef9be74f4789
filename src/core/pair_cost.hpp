// The cost of one (camera, lidar) pair, the paper's eq. 9:
//   f_p(T_camera_lidar) = (1 / S_p) * sum over scenes s of Cost(X_s, Y_s; T),
// where Cost is NID or -MI (core/metric.hpp CostValue) of the joint histogram
// of normalised lidar reflectance X and image intensity Y at the pixels the
// scene's swathe points project to.
//
// Usage (this is what the `once`, `joint` and `alt` schemes build on):
//   PairCost cost(camera, "rear", std::move(swathes), options);
//   cost.RefreshVisibility(T0);            // occlusion + which scenes count
//   double f = cost.Evaluate(T);           // thread-safe, const, TBB over scenes
//   ... optimiser run (e.g. MinimiseOverTransform) ...
//   cost.RefreshVisibility(T_best);        // between runs only, never inside
// Scenes with fewer than min_points_per_scene projected (visible) points at
// the last refresh, or with a constant image or constant reflectance, are
// ignored (and counted) until the next refresh, so the set of scenes, and
// with it the cost, does not jump during an optimiser run.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/metric.hpp"
#include "core/rig.hpp"
#include "core/scene_information.hpp"
#include "core/swathe.hpp"

namespace scenecal {

class CorrectionFrame;  // core/motion_estimation.hpp

struct PairCostOptions {
  HistogramOptions histogram;
  MetricKind metric = MetricKind::kNid;
  SwatheOptions swathe;
  // A scene needs at least this many projected, visible points to count.
  int min_points_per_scene = 300;

  bool IsValid(std::string* why = nullptr) const;
};

// Why a scene is left out of the cost (kUsed when it is not).
enum class SceneState { kUsed, kTooFewPoints, kConstantImage, kConstantReflectance };
const char* SceneStateName(SceneState state);

struct SceneEvaluation {
  TimeUs image_t_us = 0;
  std::size_t projected_points = 0;  // visible points projecting into the image
  double cost = 0.0;                 // CostValue of this scene alone
  SceneState state = SceneState::kUsed;
};

class PairCost {
 public:
  PairCost(CameraInfo camera, std::string lidar, std::vector<SceneSwathe> scenes, PairCostOptions options);

  const CameraInfo& Camera() const { return camera_; }
  const std::string& Lidar() const { return lidar_; }
  const PairCostOptions& Options() const { return options_; }
  const std::vector<SceneSwathe>& Scenes() const { return scenes_; }

  // Mean cost over the used scenes; NaN when no scene is used. Thread-safe.
  double Evaluate(const Eigen::Isometry3d& T_camera_lidar) const;
  // The cost (as Evaluate, same value) and its gradient with respect to the
  // local update delta = [rho; phi] of ApplyTransformUpdate(T_camera_lidar,
  // delta, update, pivot_source) at delta = 0 (core/nelder_mead.hpp). Analytic
  // for B-spline binning (samples entering or leaving the image are ignored);
  // zero for hard binning (piecewise constant). NaN cost and zero gradient when
  // no scene is used. Thread-safe; deterministic (scenes summed in order).
  double EvaluateWithGradient(const Eigen::Isometry3d& T_camera_lidar, TransformUpdate update,
                              const Eigen::Vector3d& pivot_source, Vector6d* gradient) const;

  // Per-scene detail at T_camera_lidar (every scene; state from the last refresh).
  std::vector<SceneEvaluation> EvaluateScenes(const Eigen::Isometry3d& T_camera_lidar) const;

  // Recomputes each scene's visibility mask at T_camera_lidar and which scenes
  // are used. Returns the number of used scenes. Not thread-safe (mutates).
  int RefreshVisibility(const Eigen::Isometry3d& T_camera_lidar);

  // Blurs every scene's image with a Gaussian of 1-sigma = fraction * image
  // width (pixels); 0 restores the sharp images. Between optimiser runs only.
  // A blur also thins the scored points (SwatheOptions::blur_px_per_point_stride).
  void SetImageBlur(double fraction_of_width);
  // The histogram's binning from now on (the uncertainty scores the swathes
  // with B-spline binning, whose cost is smooth).
  void SetBinning(Binning binning) { options_.histogram.binning = binning; }

  // Sum of the lidar-frame coordinates (metres) of the visible points that
  // project under T_camera_lidar, over the used scenes; *count gets their number.
  Eigen::Vector3d SumProjectedLidarPoints(const Eigen::Isometry3d& T_camera_lidar, std::size_t* count) const;

  // The used scenes' alignment information at T_camera_lidar summed
  // (SceneSwathe::AlignmentInformation, visibility of the last refresh), and
  // in *gradient_weight their summed gradient weights. Thread-safe.
  Matrix6d AlignmentInformation(const Eigen::Isometry3d& T_camera_lidar, double* gradient_weight) const;

  // The informative scene choice (core/scene_information.hpp): keeps the
  // `count` camera frames (each with all its swathes, e.g. its range bands)
  // whose used scenes constrain T_camera_lidar most, judged at T_camera_lidar
  // with the visibility of the last refresh; frames with no used scene count
  // as uninformative. Returns the choice over the frames (ascending time).
  // Refresh the visibility afterwards. Not thread-safe (mutates).
  InformativeChoice KeepMostInformative(const Eigen::Isometry3d& T_camera_lidar, int count,
                                        const InformativeChoiceOptions& options = {});
  // Distinct camera frames (image times) among the scenes.
  int FrameCount() const;

  // Every scene's drift correction, in scene order; and setting them all (the
  // order and count of MotionCorrections()). Not thread-safe (mutates);
  // refresh the visibility afterwards if the swathes moved far.
  std::vector<SwatheMotionCorrection> MotionCorrections() const;
  void SetMotionCorrections(const std::vector<SwatheMotionCorrection>& corrections);

  int UsedSceneCount() const;
  int SceneCount() const { return static_cast<int>(scenes_.size()); }
  int CountState(SceneState state) const;
  const std::vector<SceneState>& States() const { return states_; }
  // Projected, visible points per scene at the last refresh.
  const std::vector<std::size_t>& ProjectedAtRefresh() const { return projected_at_refresh_; }

 private:
  // Each scene's SceneSwathe::AlignmentInformation at T_camera_lidar (zero for
  // a scene not used), and in *gradient_weights (when given) its gradient weight; by scene index.
  std::vector<Matrix6d> UsedScenesInformation(const Eigen::Isometry3d& T_camera_lidar,
                                              std::vector<double>* gradient_weights = nullptr) const;
  double SceneCost(std::size_t scene, const Eigen::Isometry3d& T_camera_lidar, std::size_t* projected) const;
  // SceneCost plus, when gradient is given, the scene's gradient (EvaluateWithGradient).
  double SceneCostAndGradient(std::size_t scene, const Eigen::Isometry3d& T_camera_lidar, TransformUpdate update,
                              const Eigen::Vector3d& pivot_source, Vector6d* gradient) const;

  CameraInfo camera_;
  std::string lidar_;
  std::vector<SceneSwathe> scenes_;
  PairCostOptions options_;
  std::vector<SceneState> states_;
  std::vector<std::size_t> projected_at_refresh_;
  std::vector<std::size_t> used_;  // indices of used scenes

  // The drift corrections (core/motion_estimation.hpp) set the swathes of the used scenes.
  friend std::map<TimeUs, CorrectionFrame> CorrectionFramesByTime(const std::vector<PairCost*>& pairs,
                                                                  const std::vector<Eigen::Isometry3d>& T_camera_lidar);
};

// The `joint` cost of one lidar: the mean over cameras of each pair's cost at
// T_camera_lidar = T_base_camera^-1 * T_base_lidar (the known camera
// transforms held fixed). Pairs with no used scene are skipped; NaN when none
// has one. Thread-safe.
double EvaluateJoint(const std::vector<const PairCost*>& pairs, const Eigen::Isometry3d& T_base_lidar);

}  // namespace scenecal
