#include "core/calibrate.hpp"

#include "core/calibrate_alternating.hpp"
#include "core/interrupt.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <set>
#include <sstream>

#include <fmt/format.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

namespace scenecal {

namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

std::string FormatNumber(double value) {
  std::ostringstream out;
  out.precision(6);
  out << value;
  return out.str();
}

std::string FormatVector(const Eigen::Vector3d& v) {
  return "[" + FormatNumber(v.x()) + ", " + FormatNumber(v.y()) + ", " + FormatNumber(v.z()) + "]";
}

}  // namespace

bool ParseCalibrationScheme(const std::string& name, CalibrationScheme* scheme) {
  if (name == "once") *scheme = CalibrationScheme::kOnce;
  else if (name == "joint") *scheme = CalibrationScheme::kJoint;
  else if (name == "alt") *scheme = CalibrationScheme::kAlt;
  else return false;
  return true;
}

const char* CalibrationSchemeName(CalibrationScheme scheme) {
  switch (scheme) {
    case CalibrationScheme::kOnce: return "once";
    case CalibrationScheme::kJoint: return "joint";
    case CalibrationScheme::kAlt: return "alt";
  }
  return "unknown";
}

bool CalibrationOptions::IsValid(std::string* why) const {
  const auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!cost.IsValid(why)) return false;
  if (!normalisation.IsValid(why)) return false;
  if (!scenes.IsValid(why)) return false;
  if (!nelder_mead.IsValid(why)) return false;
  if (!gradient.IsValid(why)) return false;
  if (lower_solver == LowerSolver::kLbfgs && cost.histogram.binning != Binning::kBSpline) {
    return fail(std::string("the lbfgs lower solver needs B-spline binning (the cost with ") +
                BinningName(cost.histogram.binning) +
                " binning is piecewise constant and has no gradient); use bspline binning or the simplex");
  }
  if (stages.empty()) return fail("stages needs at least one stage");
  for (const OptimisationStage& stage : stages) {
    if (!(stage.step_scale > 0.0) || !std::isfinite(stage.step_scale))
      return fail("stage step scales must be positive numbers");
    if (!(stage.blur_fraction >= 0.0) || !(stage.blur_fraction < 0.5))
      return fail("stage blur fractions must be in [0, 0.5)");
    if (stage.restarts < 0) return fail("stage restarts must be >= 0");
  }
  if (!(restart_min_improvement >= 0.0)) return fail("restart_min_improvement must be >= 0");
  if (threads < 0) return fail("threads must be 0 (all) or positive");
  if (!std::isfinite(swathe_trim_margin_m)) return fail("swathe_trim_margin_m must be a finite number of metres");
  if (!(range_split_m >= 0.0) || !std::isfinite(range_split_m))
    return fail("range_split_m must be 0 (off) or a positive number of metres");
  if (thin_max_points_per_cell < 0) return fail("thin_max_points_per_cell must be 0 (off) or positive");
  if (thin_cell_px < 1) return fail("thin_cell_px must be a positive number of pixels");
  if (!(thin_margin_px >= 0.0) || !std::isfinite(thin_margin_px))
    return fail("thin_margin_px must be a finite number of pixels >= 0");
  if (motion_correction && !motion.IsValid(why)) return false;
  if (motion_correction_first_stage < 0) return fail("motion_correction_first_stage must be >= 0");
  if (!(time_budget_s >= 0.0) || !std::isfinite(time_budget_s)) return fail("time_budget_s must be >= 0 seconds");
  if (!(agreement_warning_translation_m > 0.0) || !(agreement_warning_rotation_deg > 0.0))
    return fail("agreement warning thresholds must be positive");
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
                               " iterations a run, function tolerance " + FormatNumber(options.gradient.function_tolerance) +
                               "; one cost + gradient evaluation costs ~" + FormatNumber(kGradientEvaluationCost) +
                               " plain evaluations)";
  } else {
    settings["lower_solver"] = "simplex (Nelder-Mead)";
  }
  settings["normalise_reflectance"] = NormalisationName(options.normalisation.reflectance);
  settings["normalise_intensity"] = NormalisationName(options.normalisation.intensity);
  settings["intensity_highpass"] =
      options.normalisation.intensity_highpass_width_fraction > 0.0
          ? FormatNumber(options.normalisation.intensity_highpass_width_fraction) + " of the image width"
          : std::string("off");
  settings["scenes_per_camera"] = std::to_string(options.scenes.scenes_per_camera);
  settings["swathe_length_m"] = FormatNumber(options.scenes.swathe_length_m);
  settings["direction"] = SwatheDirectionName(options.scenes.direction);
  settings["odometry_scale_percent"] = FormatNumber(100.0 * options.scenes.odometry_scale);
  settings["swathe_trim_margin_m"] = FormatNumber(options.swathe_trim_margin_m);
  settings["min_points_per_scene"] = std::to_string(options.cost.min_points_per_scene);
  settings["occlusion"] =
      options.cost.swathe.occlusion
          ? fmt::format("zbuffer (cell {} px, margin {} x depth + {} m)",
                        options.cost.swathe.occlusion_cell_px > 0
                            ? std::to_string(options.cost.swathe.occlusion_cell_px)
                            : std::string("width/80"),
                        FormatNumber(options.cost.swathe.occlusion_relative_margin),
                        FormatNumber(options.cost.swathe.occlusion_absolute_margin_m))
          : "off";
  settings["refresh_border_px"] = FormatNumber(options.cost.swathe.refresh_border_px);
  settings["range_split_m"] = FormatNumber(options.range_split_m);
  settings["thinning"] = options.thin_max_points_per_cell > 0
                             ? fmt::format("{} points per {} px cell at the initial guess, margin {} px",
                                           options.thin_max_points_per_cell, options.thin_cell_px,
                                           FormatNumber(options.thin_margin_px))
                             : "off";
  if (options.motion_correction) {
    const MotionCorrectionOptions& motion = options.motion;
    std::string per_frame = std::string(motion.scale ? " scale" : "") + (motion.turn ? " turn" : "") +
                            (motion.roll ? " roll" : "");
    if (!per_frame.empty()) per_frame = "per frame:" + per_frame + " ";
    settings["motion_correction"] =
        fmt::format("from stage {}: {}{}(scale within {} %, rates within {} deg/m)",
                    options.motion_correction_first_stage, motion.drive_scale ? "drive-scale; " : "", per_frame,
                    FormatNumber(100.0 * motion.max_scale),
                    FormatNumber(DegreesFromRadians(motion.max_rate_rad_per_m)));
  } else {
    settings["motion_correction"] = "off";
  }
  settings["lidar_range_m"] =
      FormatNumber(options.cost.swathe.min_range_m) + " .. " + FormatNumber(options.cost.swathe.max_range_m);
  settings["threads"] = std::to_string(options.threads);
  settings["seed"] = std::to_string(options.seed);
}

PairCost BuildPairCost(const CalibrationInput& input, const CameraInfo& camera, const std::string& lidar,
                       const CalibrationOptions& options) {
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
    const SwatheImages images = SwatheImages::Prepare(image->second.intensity, options.normalisation);
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
        whole.CountProjectedPerScan(camera.T_base_camera.inverse() * lidar_info->T_base_lidar);
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
    const Eigen::Isometry3d T_camera_lidar_guess = camera.T_base_camera.inverse() * lidar_info->T_base_lidar;
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

std::vector<NelderMeadSummary> MinimiseCoarseToFine(
    const std::function<double(const Eigen::Isometry3d&)>& cost,
    const std::function<void(const OptimisationStage& stage, const Eigen::Isometry3d&)>& prepare,
    const NelderMeadOptions& options, const std::vector<OptimisationStage>& stages, double restart_min_improvement,
    Eigen::Isometry3d* transform, const StopRequested& stop_requested) {
  std::vector<NelderMeadSummary> runs;
  for (const OptimisationStage& stage : stages) {
    if (stop_requested && stop_requested()) break;
    if (prepare) prepare(stage, *transform);
    NelderMeadOptions stage_options = options;
    stage_options.initial_step_translation_m *= stage.step_scale;
    stage_options.initial_step_rotation_rad *= stage.step_scale;
    for (int run = 0; run <= stage.restarts; ++run) {
      runs.push_back(MinimiseOverTransform(cost, stage_options, transform, stop_requested));
      const NelderMeadSummary& last = runs.back();
      if (last.termination == NelderMeadTermination::kStopRequested ||
          last.termination == NelderMeadTermination::kNonFiniteCost) {
        return runs;
      }
      if (!(last.initial_value - last.final_value > restart_min_improvement)) break;
    }
  }
  return runs;
}

std::vector<GradientSolverSummary> MinimiseCoarseToFineWithGradient(
    const CostWithGradient& cost,
    const std::function<void(const OptimisationStage& stage, const Eigen::Isometry3d&)>& prepare,
    const GradientSolverOptions& options, const std::vector<OptimisationStage>& stages,
    double restart_min_improvement, Eigen::Isometry3d* transform, const StopRequested& stop_requested) {
  std::vector<GradientSolverSummary> runs;
  for (const OptimisationStage& stage : stages) {
    if (stop_requested && stop_requested()) break;
    if (prepare) prepare(stage, *transform);
    GradientSolverOptions stage_options = options;
    stage_options.initial_step_translation_m *= stage.step_scale;
    stage_options.initial_step_rotation_rad *= stage.step_scale;
    for (int run = 0; run <= stage.restarts; ++run) {
      runs.push_back(MinimiseWithGradient(cost, stage_options, transform, stop_requested));
      const GradientSolverSummary& last = runs.back();
      if (last.stopped || last.start_not_finite) return runs;
      if (!(last.initial_value - last.final_value > restart_min_improvement)) break;
    }
  }
  return runs;
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
            FormatNumber(kGradientEvaluationCost) + " plain ones)";
  }
  return text;
}

std::optional<Eigen::Vector3d> ObservedCentroid(const std::vector<const PairCost*>& pairs,
                                                const Eigen::Isometry3d& T_base_lidar) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  std::size_t count = 0;
  for (const PairCost* pair : pairs) {
    std::size_t n = 0;
    sum += pair->SumProjectedLidarPoints(pair->Camera().T_base_camera.inverse() * T_base_lidar, &n);
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
    T_camera_lidar.push_back(pair->Camera().T_base_camera.inverse() * T_base_lidar);
    pair->RefreshVisibility(T_camera_lidar.back());
  }
  EstimateMotionCorrections(pairs, T_camera_lidar, options.motion);
  for (std::size_t p = 0; p < pairs.size(); ++p) pairs[p]->RefreshVisibility(T_camera_lidar[p]);
}

void PreparePairForStage(PairCost& pair, const OptimisationStage& stage, const Eigen::Isometry3d& T_camera_lidar) {
  pair.SetImageBlur(stage.blur_fraction);
  pair.RefreshVisibility(T_camera_lidar);
}

namespace {

struct LidarProblem {
  const LidarInfo* lidar = nullptr;
  std::vector<std::unique_ptr<PairCost>> pairs;  // one per camera, rig order
};

}  // namespace

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
  return std::to_string(summary.frames) + " frames, cost " + FormatNumber(summary.cost_before) + " -> " +
         FormatNumber(summary.cost_after) + ", largest scale " + FormatNumber(100.0 * max_scale) + " %, turn " +
         FormatNumber(DegreesFromRadians(max_turn)) + " deg/m, roll " + FormatNumber(DegreesFromRadians(max_roll)) +
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

namespace {

std::string StagesBrief(const std::vector<NelderMeadSummary>& stages) {
  int evaluations = 0, iterations = 0;
  for (const auto& s : stages) {
    evaluations += s.evaluations;
    iterations += s.iterations;
  }
  std::ostringstream out;
  out << stages.size() << " runs, " << iterations << " iterations, " << evaluations << " evaluations";
  if (!stages.empty()) out << ", last: " << NelderMeadTerminationName(stages.back().termination);
  return out.str();
}

std::string GradientRunsBrief(const std::vector<GradientSolverSummary>& runs) {
  int evaluations = 0, gradient_evaluations = 0, iterations = 0;
  for (const auto& r : runs) {
    evaluations += r.evaluations;
    gradient_evaluations += r.gradient_evaluations;
    iterations += r.iterations;
  }
  std::ostringstream out;
  out << runs.size() << " lbfgs runs, " << iterations << " iterations, "
      << DescribeEvaluations(LowerSolver::kLbfgs, evaluations, gradient_evaluations);
  if (!runs.empty()) out << ", last: " << (runs.back().converged ? "converged" : "not converged");
  return out.str();
}

}  // namespace

CalibrationOutcome Calibrate(const CalibrationInput& input, const CalibrationOptions& options,
                             const ProgressCallback& progress) {
  const auto start = Clock::now();
  CalibrationOutcome outcome;
  const auto say = [&](const std::string& message) {
    if (progress) progress(message);
  };
  const auto cannot = [&](CalibrationStatus status, std::string why) {
    outcome.status = status;
    outcome.why = std::move(why);
    return outcome;
  };
  std::string why;
  if (!options.IsValid(&why)) return cannot(CalibrationStatus::kInvalidOptions, "invalid options: " + why);
  if (options.scheme == CalibrationScheme::kAlt) {
    return CalibrateAlternating(input, options, DefaultAlternatingOptions(options), progress);
  }
  if (input.rig.cameras.empty() || input.rig.lidars.empty()) {
    return cannot(CalibrationStatus::kCannotCalibrate, "the rig needs at least one camera and one lidar");
  }
  std::optional<tbb::global_control> thread_limit;
  if (options.threads > 0) {
    thread_limit.emplace(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(options.threads));
  }
  const Clock::time_point deadline =
      start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(options.time_budget_s));
  const StopRequested stop_requested = [&] { return options.time_budget_s > 0.0 && Clock::now() > deadline; };

  // Settings, for the record.
  CalibrationResult& result = outcome.result;
  RecordCommonSettings(options, &result);
  result.settings["rotation_pivot"] = options.pivot_at_observed_centroid ? "observed centroid" : "lidar origin";
  const bool lbfgs = options.lower_solver == LowerSolver::kLbfgs;
  result.settings["max_iterations_per_run"] =
      std::to_string(lbfgs ? options.gradient.max_iterations : options.nelder_mead.max_iterations);
  std::string stages;
  for (const OptimisationStage& s : options.stages) {
    stages += (stages.empty() ? "" : "; ") + std::string("step x") + FormatNumber(s.step_scale) + " blur " +
              FormatNumber(s.blur_fraction) + " restarts " + std::to_string(s.restarts);
  }
  result.settings["stages"] = stages;
  // Simplex: the initial simplex edges; lbfgs: the parameter scales (first stage).
  result.settings["initial_step_m"] = FormatNumber(lbfgs ? options.gradient.initial_step_translation_m
                                                         : options.nelder_mead.initial_step_translation_m);
  result.settings["initial_step_rad"] = FormatNumber(lbfgs ? options.gradient.initial_step_rotation_rad
                                                           : options.nelder_mead.initial_step_rotation_rad);
  result.settings["time_budget_s"] = FormatNumber(options.time_budget_s);

  // Build every pair's cost and check that each lidar has usable scenes.
  std::vector<LidarProblem> problems;
  for (const LidarInfo& lidar : input.rig.lidars) {
    LidarProblem problem;
    problem.lidar = &lidar;
    int scenes = 0;
    for (const CameraInfo& camera : input.rig.cameras) {
      problem.pairs.push_back(std::make_unique<PairCost>(BuildPairCost(input, camera, lidar.name, options)));
      scenes += problem.pairs.back()->SceneCount();
    }
    if (scenes == 0) {
      return cannot(CalibrationStatus::kCannotCalibrate,
                    "lidar " + lidar.name +
                        ": no scene: no camera frame has scans of this lidar within its swathe window, or the "
                        "images, scans and trajectory do not overlap in time");
    }
    int used = 0;
    for (auto& pair : problem.pairs) {
      used += pair->RefreshVisibility(pair->Camera().T_base_camera.inverse() * lidar.T_base_lidar);
    }
    if (used == 0) {
      return cannot(CalibrationStatus::kCannotCalibrate,
                    DescribeUnusable(lidar.name, problem.pairs, options.cost.min_points_per_scene));
    }
    problems.push_back(std::move(problem));
  }
  result.timings_s["build_swathes"] = SecondsSince(start);
  say("built " + std::to_string(problems.size()) + " lidar problem(s) in " +
      FormatNumber(result.timings_s["build_swathes"]) + " s");

  const auto optimise_start = Clock::now();
  std::vector<std::string> terminations;
  for (LidarProblem& problem : problems) {
    const LidarInfo& lidar = *problem.lidar;
    // Initial costs (visibility at the initial guess).
    std::vector<double> initial_costs;
    for (const auto& pair : problem.pairs) {
      initial_costs.push_back(pair->Evaluate(pair->Camera().T_base_camera.inverse() * lidar.T_base_lidar));
    }
    std::vector<Eigen::Isometry3d> T_camera_lidar(problem.pairs.size());
    std::vector<bool> solved(problem.pairs.size(), false);
    // One optimisation problem: log its start, run the coarse-to-fine schedule
    // on *transform with the chosen lower solver, log and record its runs.
    // cost_with_gradient is used by lbfgs only; nelder_mead carries the
    // parameterisation (update kind, pivot) of both solvers.
    const auto optimise = [&](const std::string& name, double initial_cost, const NelderMeadOptions& nelder_mead,
                              const std::function<double(const Eigen::Isometry3d&)>& cost,
                              const CostWithGradient& cost_with_gradient,
                              const std::function<void(const OptimisationStage&, const Eigen::Isometry3d&)>& prepare,
                              Eigen::Isometry3d* transform) {
      const auto problem_start = Clock::now();
      OptimisationReport report;
      report.problem = name;
      say(report.problem + ": start (" + LowerSolverName(options.lower_solver) + "), cost " +
          FormatNumber(initial_cost) + ", rotation pivot (lidar frame, m) " + FormatVector(nelder_mead.pivot_source));
      MinimiseWithLowerSolver(options, options.stages, nelder_mead, cost, cost_with_gradient, prepare, transform,
                              &report, stop_requested);
      std::string brief;
      double final_value = std::numeric_limits<double>::quiet_NaN();
      if (options.lower_solver == LowerSolver::kLbfgs) {
        if (!report.gradient_runs.empty()) final_value = report.gradient_runs.back().final_value;
        brief = GradientRunsBrief(report.gradient_runs);
      } else {
        if (!report.stages.empty()) final_value = report.stages.back().final_value;
        brief = StagesBrief(report.stages);
      }
      report.seconds = SecondsSince(problem_start);
      say(report.problem + ": " + brief + ", cost " +
          (std::isnan(final_value) ? std::string("-") : FormatNumber(final_value)) + ", " +
          FormatNumber(report.seconds) + " s");
      terminations.push_back(report.problem + ": " + brief);
      outcome.optimisations.push_back(report);
    };
    // Drift correction of the swathes before a stage (options.motion_correction):
    // the pairs given share each frame's correction.
    const auto correct_motion = [&](const std::vector<PairCost*>& pairs, const OptimisationStage& stage,
                                    const std::vector<Eigen::Isometry3d>& T_camera_lidar_now) {
      if (!options.motion_correction) return;
      // prepare is called with the elements of options.stages (MinimiseWithLowerSolver below).
      const auto in_schedule = std::find_if(options.stages.begin(), options.stages.end(),
                                            [&](const OptimisationStage& s) { return &s == &stage; });
      if (in_schedule - options.stages.begin() < options.motion_correction_first_stage) return;
      const MotionCorrectionSummary summary = EstimateMotionCorrections(pairs, T_camera_lidar_now, options.motion);
      // The visibility follows the re-posed scans.
      for (std::size_t p = 0; p < pairs.size(); ++p) pairs[p]->RefreshVisibility(T_camera_lidar_now[p]);
      std::string names;
      for (const PairCost* pair : pairs) names += (names.empty() ? "" : ", ") + pair->Camera().name + "/" + lidar.name;
      say("motion correction (" + names + "): " + DescribeMotionCorrection(summary));
    };
    if (options.scheme == CalibrationScheme::kJoint) {
      std::vector<const PairCost*> pairs;
      for (const auto& pair : problem.pairs) pairs.push_back(pair.get());
      Eigen::Isometry3d T_base_lidar = lidar.T_base_lidar;
      NelderMeadOptions nelder_mead = options.nelder_mead;
      if (options.pivot_at_observed_centroid) {
        nelder_mead.pivot_source = ObservedCentroid(pairs, T_base_lidar).value_or(nelder_mead.pivot_source);
      }
      optimise(
          "joint " + lidar.name, EvaluateJoint(pairs, T_base_lidar), nelder_mead,
          [&](const Eigen::Isometry3d& T) { return EvaluateJoint(pairs, T); },
          [&](const Eigen::Isometry3d& T, Vector6d* gradient) {
            return EvaluateJointWithGradient(pairs, T, nelder_mead.transform_update, nelder_mead.pivot_source,
                                             gradient);
          },
          [&](const OptimisationStage& stage, const Eigen::Isometry3d& T) {
            std::vector<PairCost*> stage_pairs;
            std::vector<Eigen::Isometry3d> stage_T_camera_lidar;
            for (auto& pair : problem.pairs) {
              stage_pairs.push_back(pair.get());
              stage_T_camera_lidar.push_back(pair->Camera().T_base_camera.inverse() * T);
              PreparePairForStage(*pair, stage, stage_T_camera_lidar.back());
            }
            correct_motion(stage_pairs, stage, stage_T_camera_lidar);
          },
          &T_base_lidar);
      for (std::size_t p = 0; p < problem.pairs.size(); ++p) {
        T_camera_lidar[p] = problem.pairs[p]->Camera().T_base_camera.inverse() * T_base_lidar;
        solved[p] = true;
      }
    } else {
      for (std::size_t p = 0; p < problem.pairs.size(); ++p) {
        PairCost& pair = *problem.pairs[p];
        T_camera_lidar[p] = pair.Camera().T_base_camera.inverse() * lidar.T_base_lidar;
        if (pair.UsedSceneCount() == 0) {
          result.warnings.push_back("pair " + pair.Camera().name + "/" + lidar.name +
                                    ": no usable scene at the initial guess; pair left out");
          continue;
        }
        NelderMeadOptions nelder_mead = options.nelder_mead;
        if (options.pivot_at_observed_centroid) {
          nelder_mead.pivot_source = ObservedCentroid({&pair}, lidar.T_base_lidar).value_or(nelder_mead.pivot_source);
        }
        optimise(
            "once " + pair.Camera().name + "/" + lidar.name, initial_costs[p], nelder_mead,
            [&](const Eigen::Isometry3d& T) { return pair.Evaluate(T); },
            [&](const Eigen::Isometry3d& T, Vector6d* gradient) {
              if (gradient == nullptr) return pair.Evaluate(T);
              return pair.EvaluateWithGradient(T, nelder_mead.transform_update, nelder_mead.pivot_source, gradient);
            },
            [&](const OptimisationStage& stage, const Eigen::Isometry3d& T) {
              PreparePairForStage(pair, stage, T);
              correct_motion({&pair}, stage, {T});
            },
            &T_camera_lidar[p]);
        solved[p] = true;
      }
    }

    // Final costs with visibility refreshed at the answer; per-pair results.
    std::vector<Eigen::Isometry3d> implied_base_lidar;
    for (std::size_t p = 0; p < problem.pairs.size(); ++p) {
      PairCost& pair = *problem.pairs[p];
      const Eigen::Isometry3d T_initial = pair.Camera().T_base_camera.inverse() * lidar.T_base_lidar;
      if (!solved[p]) {
        outcome.pairs.push_back(MakePairReport(pair, T_initial, initial_costs[p]));
        continue;
      }
      pair.SetImageBlur(0.0);
      pair.RefreshVisibility(T_camera_lidar[p]);
      if (options.motion_correction) AppendFrameMotionCorrections(pair, lidar.name, &outcome.motion_corrections);
      PairReport report = MakePairReport(pair, T_initial, initial_costs[p]);
      report.final_cost = pair.Evaluate(T_camera_lidar[p]);
      outcome.pairs.push_back(report);
      result.pairs.push_back({pair.Camera().name, lidar.name, T_camera_lidar[p], report.final_cost});
      implied_base_lidar.push_back(pair.Camera().T_base_camera * T_camera_lidar[p]);
    }
    if (implied_base_lidar.empty()) {
      return cannot(CalibrationStatus::kCannotCalibrate,
                    DescribeUnusable(lidar.name, problem.pairs, options.cost.min_points_per_scene));
    }
    LidarCalibration lidar_result;
    lidar_result.lidar = lidar.name;
    lidar_result.T_base_lidar = MeanTransform(implied_base_lidar);
    result.lidars.push_back(lidar_result);

    if (options.scheme == CalibrationScheme::kOnce && implied_base_lidar.size() > 1) {
      // Agreement of the pairs: the largest pairwise difference of their implied T_base_lidar.
      double spread_m = 0.0, spread_deg = 0.0;
      for (std::size_t a = 0; a < implied_base_lidar.size(); ++a) {
        for (std::size_t b = a + 1; b < implied_base_lidar.size(); ++b) {
          spread_m = std::max(spread_m, TranslationError(implied_base_lidar[a], implied_base_lidar[b]));
          spread_deg = std::max(spread_deg, RotationErrorDegrees(implied_base_lidar[a], implied_base_lidar[b]));
        }
      }
      result.settings["once_agreement_" + lidar.name + "_translation_m"] = FormatNumber(spread_m);
      result.settings["once_agreement_" + lidar.name + "_rotation_deg"] = FormatNumber(spread_deg);
      say("once " + lidar.name + ": pairs' T_base_lidar agree within " + FormatNumber(spread_m) + " m, " +
          FormatNumber(spread_deg) + " deg");
      if (spread_m > options.agreement_warning_translation_m || spread_deg > options.agreement_warning_rotation_deg) {
        result.warnings.push_back("lidar " + lidar.name + ": the pairs' T_base_lidar disagree by " +
                                  FormatNumber(spread_m) + " m and " + FormatNumber(spread_deg) +
                                  " deg; T_base_lidar is their mean");
      }
    }
  }
  result.timings_s["optimise"] = SecondsSince(optimise_start);
  result.timings_s["total"] = SecondsSince(start);
  std::string termination = CalibrationSchemeName(options.scheme) + std::string(" ") +
                            MetricKindName(options.cost.metric) + ": ";
  for (std::size_t i = 0; i < terminations.size(); ++i) termination += (i ? "; " : "") + terminations[i];
  if (stop_requested()) termination += " (time budget reached)";
  result.termination = termination;
  return outcome;
}

}  // namespace scenecal
