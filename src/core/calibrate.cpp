#include "core/calibrate.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <memory>
#include <set>
#include <sstream>
#include <type_traits>

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include "core/interrupt.hpp"
#include "core/number_text.hpp"
#include "core/validation.hpp"

namespace scenecal {

bool ParseCalibrationScheme(const std::string& name, CalibrationScheme* scheme) {
  return ParseEnumName(kCalibrationSchemeNames, name, scheme);
}

const char* CalibrationSchemeName(CalibrationScheme scheme) { return EnumName(kCalibrationSchemeNames, scheme); }

bool CalibrationOptions::IsValid(std::string* why) const {
  if (!cost.IsValid(why)) return false;
  if (!normalisation.IsValid(why)) return false;
  if (!scenes.IsValid(why)) return false;
  if (!nelder_mead.IsValid(why)) return false;
  if (!gradient.IsValid(why)) return false;
  if (lower_solver == LowerSolver::kLbfgs && cost.histogram.binning != Binning::kBSpline) {
    return Invalid(why, std::string("the lbfgs lower solver needs B-spline binning (the cost with ") +
                BinningName(cost.histogram.binning) +
                " binning is piecewise constant and has no gradient); use bspline binning or the simplex");
  }
  if (stages.empty()) return Invalid(why, "stages needs at least one stage");
  for (const OptimisationStage& stage : stages) {
    if (!(stage.step_scale > 0.0) || !std::isfinite(stage.step_scale))
      return Invalid(why, "stage step scales must be positive numbers");
    if (!(stage.blur_fraction >= 0.0) || !(stage.blur_fraction < 0.5))
      return Invalid(why, "stage blur fractions must be in [0, 0.5)");
    if (stage.restarts < 0) return Invalid(why, "stage restarts must be >= 0");
  }
  if (!(restart_min_improvement >= 0.0)) return Invalid(why, "restart_min_improvement must be >= 0");
  if (threads < 0) return Invalid(why, "threads must be 0 (all) or positive");
  if (!std::isfinite(swathe_trim_margin_m)) return Invalid(why, "swathe_trim_margin_m must be a finite number of metres");
  if (!(range_split_m >= 0.0) || !std::isfinite(range_split_m))
    return Invalid(why, "range_split_m must be 0 (off) or a positive number of metres");
  if (thin_max_points_per_cell < 0) return Invalid(why, "thin_max_points_per_cell must be 0 (off) or positive");
  if (thin_cell_px < 1) return Invalid(why, "thin_cell_px must be a positive number of pixels");
  if (!(thin_margin_px >= 0.0) || !std::isfinite(thin_margin_px))
    return Invalid(why, "thin_margin_px must be a finite number of pixels >= 0");
  if (motion_correction && !motion.IsValid(why)) return false;
  if (motion_correction_first_stage < 0) return Invalid(why, "motion_correction_first_stage must be >= 0");
  if (!(time_budget_s >= 0.0) || !std::isfinite(time_budget_s)) return Invalid(why, "time_budget_s must be >= 0 seconds");
  if (!(agreement_warning_translation_m > 0.0) || !(agreement_warning_rotation_deg > 0.0))
    return Invalid(why, "agreement warning thresholds must be positive");
  return true;
}

Eigen::Isometry3d MeanTransform(const std::vector<Eigen::Isometry3d>& transforms) {
  if (transforms.empty()) return Eigen::Isometry3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Vector3d rotation_offset = Eigen::Vector3d::Zero();
  const Eigen::Matrix3d reference = transforms.front().linear();
  for (const Eigen::Isometry3d& t : transforms) {
    translation += t.translation();
    rotation_offset += LogSO3(t.linear() * reference.transpose());
  }
  const double n = static_cast<double>(transforms.size());
  Eigen::Isometry3d mean = Eigen::Isometry3d::Identity();
  mean.linear() = ExpSO3(rotation_offset / n) * reference;
  mean.translation() = translation / n;
  return mean;
}

int InformativeChoiceStage(const CalibrationOptions& options) {
  if (options.scenes.choice != SceneChoice::kInformative) return -1;
  if (options.scheme == CalibrationScheme::kAlt) return 0;
  const int stages = static_cast<int>(options.stages.size());
  return std::clamp(options.scenes.informative_after_stages, 0, std::max(0, stages - 1));
}

namespace {
std::string InformativeChoiceTiming(const CalibrationOptions& options) {
  const int stage = InformativeChoiceStage(options);
  return stage <= 0 ? std::string(", chosen at the initial guess")
                    : ", chosen after the first " + std::to_string(stage) + " stage(s), which use the whole pool";
}
}  // namespace

void RecordCommonSettings(const CalibrationOptions& options, CalibrationResult* result) {
  std::map<std::string, std::string>& settings = result->settings;
  settings["scheme"] = CalibrationSchemeName(options.scheme);
  settings["metric"] = MetricKindName(options.cost.metric);
  settings["bins"] = std::to_string(options.cost.histogram.reflectance_bins) + "x" +
                     std::to_string(options.cost.histogram.intensity_bins);
  settings["binning"] = BinningName(options.cost.histogram.binning);
  if (options.lower_solver == LowerSolver::kLbfgs) {
    settings["lower_solver"] = "lbfgs (Ceres GradientProblemSolver, analytic B-spline gradient, at most " +
                               std::to_string(options.gradient.max_iterations) +
                               " iterations a run, at most " + std::to_string(options.gradient.line_search_max_steps) +
                               " trial steps a line search, function tolerance " +
                               NumberText(options.gradient.function_tolerance) + " (stages between the first and the last " +
                               NumberText(options.gradient.MiddleStageFunctionTolerance()) +
                               ")" +
                               "; one cost + gradient evaluation costs ~" + NumberText(kGradientEvaluationCost) +
                               " plain evaluations)";
    const GradientSolverOptions& g = options.gradient;
    settings["run_radius"] = g.run_radius_translation_m > 0.0 || g.run_radius_rotation_rad > 0.0
                                 ? NumberText(g.run_radius_translation_m) + " m, " +
                                       NumberText(DegreesFromRadians(g.run_radius_rotation_rad)) +
                                       " deg from each run's start (0 = no limit)"
                                 : std::string("no limit");
  } else {
    settings["lower_solver"] = "simplex (Nelder-Mead)";
  }
  settings["normalise_reflectance"] = NormalisationName(options.normalisation.reflectance);
  settings["normalise_intensity"] = NormalisationName(options.normalisation.intensity);
  settings["intensity_highpass"] =
      options.normalisation.intensity_highpass_width_fraction > 0.0
          ? NumberText(options.normalisation.intensity_highpass_width_fraction) + " of the image width"
          : std::string("off");
  settings["scenes_per_camera"] = std::to_string(options.scenes.scenes_per_camera);
  if (options.scenes.choice == SceneChoice::kInformative) {
    settings["scene_choice"] =
        std::string("informative of ") + std::to_string(options.scenes.CandidatesPerCamera()) + " per camera" +
        InformativeChoiceTiming(options) +
        (options.scenes.auto_variance_ratio > 0.0
             ? ", as many as bring the predicted variance within " + NumberText(options.scenes.auto_variance_ratio) +
                   "x of the whole pool's (at least " + std::to_string(options.scenes.min_auto_scenes) + ")"
             : std::string());
  } else {
    settings["scene_choice"] = "spread";
  }
  settings["swathe_length_m"] = NumberText(options.scenes.swathe_length_m);
  settings["direction"] = SwatheDirectionName(options.scenes.direction);
  settings["odometry_scale_percent"] = NumberText(100.0 * options.scenes.odometry_scale);
  settings["swathe_trim_margin_m"] = NumberText(options.swathe_trim_margin_m);
  settings["min_points_per_scene"] = std::to_string(options.cost.min_points_per_scene);
  settings["occlusion"] =
      options.cost.swathe.occlusion
          ? fmt::format("zbuffer (cell {} px, margin {} x depth + {} m)",
                        options.cost.swathe.occlusion_cell_px > 0
                            ? std::to_string(options.cost.swathe.occlusion_cell_px)
                            : std::string("width/80"),
                        NumberText(options.cost.swathe.occlusion_relative_margin),
                        NumberText(options.cost.swathe.occlusion_absolute_margin_m))
          : "off";
  settings["refresh_border_px"] = NumberText(options.cost.swathe.refresh_border_px);
  settings["range_split_m"] = NumberText(options.range_split_m);
  settings["thinning"] = options.thin_max_points_per_cell > 0
                             ? fmt::format("{} points per {} px cell at the initial guess, margin {} px",
                                           options.thin_max_points_per_cell, options.thin_cell_px,
                                           NumberText(options.thin_margin_px))
                             : "off";
  if (options.motion_correction) {
    const MotionCorrectionOptions& motion = options.motion;
    std::string per_frame = std::string(motion.scale ? " scale" : "") + (motion.turn ? " turn" : "") +
                            (motion.roll ? " roll" : "");
    if (!per_frame.empty()) per_frame = "per frame:" + per_frame + " ";
    settings["motion_correction"] =
        fmt::format("from stage {}: {}{}(scale within {} %, rates within {} deg/m)",
                    options.motion_correction_first_stage, motion.drive_scale ? "drive-scale; " : "", per_frame,
                    NumberText(100.0 * motion.max_scale),
                    NumberText(DegreesFromRadians(motion.max_rate_rad_per_m)));
  } else {
    settings["motion_correction"] = "off";
  }
  settings["lidar_range_m"] =
      NumberText(options.cost.swathe.min_range_m) + " .. " + NumberText(options.cost.swathe.max_range_m);
  settings["threads"] = std::to_string(options.threads);
  settings["seed"] = std::to_string(options.seed);
}

SwatheImages PreparedImageCache::Get(const std::string& camera, TimeUs image_t_us, const cv::Mat& intensity,
                                     const NormalisationOptions& normalisation) {
  const std::pair<std::string, TimeUs> key{camera, image_t_us};
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    const auto found = images_.find(key);
    if (found != images_.end()) return found->second;
  }
  // Prepared outside the lock (the frames of one pair are prepared in parallel);
  // a frame prepared twice at once keeps the first copy stored.
  SwatheImages prepared = SwatheImages::Prepare(intensity, normalisation);
  const std::lock_guard<std::mutex> lock(mutex_);
  return images_.emplace(key, std::move(prepared)).first->second;
}

PairCost BuildPairCost(const CalibrationInput& input, const CameraInfo& camera, const std::string& lidar,
                       const CalibrationOptions& options, PreparedImageCache* image_cache) {
  std::vector<const Scene*> scenes;
  for (const Scene& scene : input.selection.scenes) {
    if (scene.camera == camera.name && scene.lidar == lidar) scenes.push_back(&scene);
  }
  const auto images_it = input.images.find(camera.name);
  const auto scans_it = input.scans.find(lidar);
  const LidarInfo* lidar_info = input.rig.FindLidar(lidar);  // its T_base_lidar is the initial guess
  // Per scene: one swathe, or one per lidar range band (range_split_m).
  std::vector<std::vector<SceneSwathe>> swathes(scenes.size());
  tbb::parallel_for(std::size_t{0}, scenes.size(), [&](std::size_t s) {
    ThrowIfInterrupted();
    const Scene& scene = *scenes[s];
    if (images_it == input.images.end() || scans_it == input.scans.end()) return;
    const auto image = images_it->second.find(scene.image_t_us);
    if (image == images_it->second.end()) return;
    std::vector<const LidarScan*> scans;
    for (const SwatheScan& swathe_scan : scene.scans) {
      const auto scan = scans_it->second.find(swathe_scan.t_us);
      if (scan == scans_it->second.end()) return;
      scans.push_back(&scan->second);
    }
    // Once per frame: the swathes of its range bands and the trimming pass share them.
    const SwatheImages images =
        image_cache != nullptr
            ? image_cache->Get(camera.name, scene.image_t_us, image->second.intensity, options.normalisation)
            : SwatheImages::Prepare(image->second.intensity, options.normalisation);
    const auto build = [&](const Scene& kept_scene, const std::vector<const LidarScan*>& kept_scans) {
      if (options.range_split_m <= 0.0) {
        swathes[s] = {SceneSwathe::Build(kept_scene, camera, images, kept_scans, options.cost.swathe,
                                         options.normalisation)};
        return;
      }
      SwatheOptions near = options.cost.swathe, far = options.cost.swathe;
      near.max_range_m = std::min(near.max_range_m, options.range_split_m);
      far.min_range_m = std::max(far.min_range_m, options.range_split_m);
      swathes[s] = {};
      for (const SwatheOptions* band : {&near, &far}) {
        if (!(band->max_range_m > band->min_range_m)) continue;  // the band lies outside the range window
        swathes[s].push_back(SceneSwathe::Build(kept_scene, camera, images, kept_scans, *band,
                                                options.normalisation));
      }
    };
    if (options.swathe_trim_margin_m < 0.0 || lidar_info == nullptr) return build(scene, scans);
    SceneSwathe whole =
        SceneSwathe::Build(scene, camera, images, scans, options.cost.swathe, options.normalisation);
    const std::vector<std::size_t> per_scan =
        whole.CountProjectedPerScan(camera.T_camera_base() * lidar_info->T_base_lidar);
    double first_m = std::numeric_limits<double>::infinity(), last_m = -first_m;
    for (std::size_t j = 0; j < per_scan.size(); ++j) {
      if (per_scan[j] == 0) continue;
      const double travel_m = scene.scans[j].T_basek_basej.translation().norm();
      first_m = std::min(first_m, travel_m);
      last_m = std::max(last_m, travel_m);
    }
    if (!(first_m <= last_m)) return build(scene, scans);  // nothing projects at the initial guess: keep it whole
    Scene trimmed = scene;
    trimmed.scans.clear();
    std::vector<const LidarScan*> kept_scans;
    for (std::size_t j = 0; j < scene.scans.size(); ++j) {
      const double travel_m = scene.scans[j].T_basek_basej.translation().norm();
      if (travel_m < first_m - options.swathe_trim_margin_m || travel_m > last_m + options.swathe_trim_margin_m)
        continue;
      trimmed.scans.push_back(scene.scans[j]);
      kept_scans.push_back(scans[j]);
    }
    if (trimmed.scans.size() == scene.scans.size() && options.range_split_m <= 0.0) {
      swathes[s] = {std::move(whole)};  // nothing trimmed: no need to build it again
      return;
    }
    build(trimmed, kept_scans);
  });
  if (options.thin_max_points_per_cell > 0 && lidar_info != nullptr) {
    const Eigen::Isometry3d T_camera_lidar_guess = camera.T_camera_base() * lidar_info->T_base_lidar;
    tbb::parallel_for(std::size_t{0}, swathes.size(), [&](std::size_t s) {
      for (SceneSwathe& swathe : swathes[s]) {
        swathe.ThinByImageDensity(camera.model, T_camera_lidar_guess, options.thin_cell_px,
                                  options.thin_max_points_per_cell, options.thin_margin_px);
      }
    });
  }
  std::vector<SceneSwathe> kept;
  for (auto& scene_swathes : swathes) {
    for (SceneSwathe& swathe : scene_swathes) kept.push_back(std::move(swathe));
  }
  return PairCost(camera, lidar, std::move(kept), options.cost);
}

std::vector<OptimisationStage> DefaultStages() { return {{1.0, 0.004, 2}, {0.3, 0.0015, 1}, {0.1, 0.0, 1}}; }

std::vector<OptimisationStage> WithoutWideStages(const std::vector<OptimisationStage>& stages) {
  std::vector<OptimisationStage> narrow;
  std::copy_if(stages.begin(), stages.end(), std::back_inserter(narrow),
               [](const OptimisationStage& stage) { return stage.step_scale < 1.0; });
  return narrow.empty() ? stages : narrow;
}

namespace {

// The coarse-to-fine loop of both local solvers: per stage, prepare(stage, T),
// scale the first stage's steps by the stage's, and run the solver from the
// best point, again while a run still improves the cost by more than
// restart_min_improvement. Ends early when a run says so (run_ended).
template <class SolverOptions, class Summary>
std::vector<Summary> CoarseToFine(
    const std::function<void(const OptimisationStage& stage, const Eigen::Isometry3d&)>& prepare,
    const SolverOptions& options, const std::vector<OptimisationStage>& stages, double restart_min_improvement,
    Eigen::Isometry3d* transform, const StopRequested& stop_requested,
    const std::function<Summary(const SolverOptions&, Eigen::Isometry3d*)>& run_once,
    const std::function<bool(const Summary&)>& run_ended) {
  std::vector<Summary> runs;
  for (std::size_t s = 0; s < stages.size(); ++s) {
    const OptimisationStage& stage = stages[s];
    if (stop_requested && stop_requested()) break;
    if (prepare) prepare(stage, *transform);
    SolverOptions stage_options = options;
    stage_options.initial_step_translation_m *= stage.step_scale;
    stage_options.initial_step_rotation_rad *= stage.step_scale;
    if constexpr (std::is_same_v<SolverOptions, GradientSolverOptions>) {
      if (s > 0 && s + 1 < stages.size()) {
        stage_options.function_tolerance = stage_options.MiddleStageFunctionTolerance();
      }
    }
    for (int run = 0; run <= stage.restarts; ++run) {
      runs.push_back(run_once(stage_options, transform));
      const Summary& last = runs.back();
      if (run_ended(last)) return runs;
      if (!(last.initial_value - last.final_value > restart_min_improvement)) break;
    }
  }
  return runs;
}

}  // namespace

std::vector<NelderMeadSummary> MinimiseCoarseToFine(
    const std::function<double(const Eigen::Isometry3d&)>& cost,
    const std::function<void(const OptimisationStage& stage, const Eigen::Isometry3d&)>& prepare,
    const NelderMeadOptions& options, const std::vector<OptimisationStage>& stages, double restart_min_improvement,
    Eigen::Isometry3d* transform, const StopRequested& stop_requested) {
  return CoarseToFine<NelderMeadOptions, NelderMeadSummary>(
      prepare, options, stages, restart_min_improvement, transform, stop_requested,
      [&](const NelderMeadOptions& stage_options, Eigen::Isometry3d* T) {
        return MinimiseOverTransform(cost, stage_options, T, stop_requested);
      },
      [](const NelderMeadSummary& last) {
        return last.termination == NelderMeadTermination::kStopRequested ||
               last.termination == NelderMeadTermination::kNonFiniteCost;
      });
}

std::vector<GradientSolverSummary> MinimiseCoarseToFineWithGradient(
    const CostWithGradient& cost,
    const std::function<void(const OptimisationStage& stage, const Eigen::Isometry3d&)>& prepare,
    const GradientSolverOptions& options, const std::vector<OptimisationStage>& stages,
    double restart_min_improvement, Eigen::Isometry3d* transform, const StopRequested& stop_requested) {
  return CoarseToFine<GradientSolverOptions, GradientSolverSummary>(
      prepare, options, stages, restart_min_improvement, transform, stop_requested,
      [&](const GradientSolverOptions& stage_options, Eigen::Isometry3d* T) {
        return MinimiseWithGradient(cost, stage_options, T, stop_requested);
      },
      [](const GradientSolverSummary& last) { return last.stopped || last.start_not_finite; });
}

// Measured on the OpenCalib frame (benchmarks/bench_cost.cpp, B-spline NID, 1
// thread, 0.22 M and 0.42 M points): 6.5 ms against 3.25 ms and 14.0 ms against
// 7.0 ms CPU time per evaluation (median of 3), i.e. 2.0 (the gradient is a second
// pass over the samples recorded by the histogram pass, with the closed-form
// projection derivatives).
const double kGradientEvaluationCost = 2.0;

std::string DescribeEvaluations(LowerSolver solver, int evaluations, int gradient_evaluations) {
  std::string text = std::to_string(evaluations) + " cost evaluations";
  if (solver == LowerSolver::kLbfgs) {
    text += " (" + std::to_string(gradient_evaluations) + " with gradient, each ~" +
            NumberText(kGradientEvaluationCost) + " plain ones)";
  }
  return text;
}

std::optional<Eigen::Vector3d> ObservedCentroid(const std::vector<const PairCost*>& pairs,
                                                const Eigen::Isometry3d& T_base_lidar) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  std::size_t count = 0;
  for (const PairCost* pair : pairs) {
    std::size_t n = 0;
    sum += pair->SumProjectedLidarPoints(pair->Camera().T_camera_base() * T_base_lidar, &n);
    count += n;
  }
  if (count == 0) return std::nullopt;
  return sum / static_cast<double>(count);
}

void MinimiseWithLowerSolver(const CalibrationOptions& options, const std::vector<OptimisationStage>& stages,
                             const NelderMeadOptions& nelder_mead,
                             const std::function<double(const Eigen::Isometry3d&)>& cost,
                             const CostWithGradient& cost_with_gradient,
                             const std::function<void(const OptimisationStage& stage, const Eigen::Isometry3d&)>&
                                 prepare,
                             Eigen::Isometry3d* transform, OptimisationReport* report,
                             const StopRequested& stop_requested) {
  report->solver = options.lower_solver;
  if (options.lower_solver == LowerSolver::kLbfgs) {
    GradientSolverOptions gradient = options.gradient;
    gradient.transform_update = nelder_mead.transform_update;
    gradient.pivot_source = nelder_mead.pivot_source;
    report->gradient_runs = MinimiseCoarseToFineWithGradient(
        cost_with_gradient, prepare, gradient, stages, options.restart_min_improvement, transform, stop_requested);
    for (const auto& run : report->gradient_runs) {
      report->evaluations += run.evaluations;
      report->gradient_evaluations += run.gradient_evaluations;
    }
  } else {
    report->stages = MinimiseCoarseToFine(cost, prepare, nelder_mead, stages, options.restart_min_improvement,
                                          transform, stop_requested);
    for (const auto& stage : report->stages) report->evaluations += stage.evaluations;
  }
}

void CorrectMotionAtAnswer(const CalibrationOptions& options, const std::vector<PairCost*>& pairs,
                           const Eigen::Isometry3d& T_base_lidar) {
  if (!options.motion_correction) return;
  std::vector<Eigen::Isometry3d> T_camera_lidar;
  for (PairCost* pair : pairs) {
    T_camera_lidar.push_back(pair->Camera().T_camera_base() * T_base_lidar);
    pair->RefreshVisibility(T_camera_lidar.back());
  }
  EstimateMotionCorrections(pairs, T_camera_lidar, options.motion);
  for (std::size_t p = 0; p < pairs.size(); ++p) pairs[p]->RefreshVisibility(T_camera_lidar[p]);
}

void PreparePairForStage(PairCost& pair, const OptimisationStage& stage, const Eigen::Isometry3d& T_camera_lidar) {
  pair.SetImageBlur(stage.blur_fraction);
  pair.RefreshVisibility(T_camera_lidar);
}


std::string DescribeUnusable(const std::string& lidar, const std::vector<std::unique_ptr<PairCost>>& pairs,
                             int min_points) {
  std::ostringstream out;
  out << "lidar " << lidar << ": no scene with enough information (at least " << min_points
      << " projected points, a non-constant image and non-constant reflectance) at the initial guess;";
  for (const auto& pair : pairs) {
    out << " " << pair->Camera().name << ": " << pair->SceneCount() << " scenes, "
        << pair->CountState(SceneState::kTooFewPoints) << " too few points, "
        << pair->CountState(SceneState::kConstantImage) << " constant image, "
        << pair->CountState(SceneState::kConstantReflectance) << " constant reflectance;";
  }
  return out.str();
}

std::string DescribeMotionCorrection(const MotionCorrectionSummary& summary) {
  double max_scale = 0.0, max_turn = 0.0, max_roll = 0.0;
  for (const SwatheMotionCorrection& c : summary.corrections) {
    max_scale = std::max(max_scale, std::abs(c.scale));
    max_turn = std::max(max_turn, std::hypot(c.turn_a_rad_per_m, c.turn_b_rad_per_m));
    max_roll = std::max(max_roll, std::abs(c.roll_rad_per_m));
  }
  return std::to_string(summary.frames) + " frames, cost " + NumberText(summary.cost_before) + " -> " +
         NumberText(summary.cost_after) + ", largest scale " + NumberText(100.0 * max_scale) + " %, turn " +
         NumberText(DegreesFromRadians(max_turn)) + " deg/m, roll " + NumberText(DegreesFromRadians(max_roll)) +
         " deg/m";
}

void AppendFrameMotionCorrections(const PairCost& pair, const std::string& lidar,
                                  std::vector<FrameMotionCorrection>* corrections) {
  std::set<TimeUs> recorded;
  for (const SceneSwathe& scene : pair.Scenes()) {
    if (recorded.insert(scene.ImageTime()).second)
      corrections->push_back({pair.Camera().name, lidar, scene.ImageTime(), scene.MotionCorrection()});
  }
}

PairReport MakePairReport(const PairCost& pair, const Eigen::Isometry3d& T_initial, double initial_cost) {
  PairReport report;
  report.camera = pair.Camera().name;
  report.lidar = pair.Lidar();
  report.scenes = pair.SceneCount();
  report.scenes_used = pair.UsedSceneCount();
  report.scenes_too_few_points = pair.CountState(SceneState::kTooFewPoints);
  report.scenes_constant_image = pair.CountState(SceneState::kConstantImage);
  report.scenes_constant_reflectance = pair.CountState(SceneState::kConstantReflectance);
  report.projected_points = pair.ProjectedAtRefresh();
  report.initial_cost = initial_cost;
  report.T_camera_lidar_initial = T_initial;
  return report;
}

}  // namespace scenecal
