// `scenecal calibrate DATASET --output FILE [...]`: selects scenes from the
// file timestamps, loads only the images and scans they need, runs
// Calibrate (core/calibrate.hpp) and writes the result atomically. With
// ground truth in the dataset, prints the errors per lidar and per pair.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include "cli/calibrate_alt.hpp"
#include "cli/commands.hpp"
#include "cli/config.hpp"
#include "cli/cost_arguments.hpp"
#include "cli/interrupt_handling.hpp"
#include "cli/load_input.hpp"
#include "cli/report_writer.hpp"
#include "cli/uncertainty_report.hpp"
#include "cli/validators.hpp"
#include "cli/warning_advice.hpp"
#include "core/calibrator.hpp"
#include "core/geometry.hpp"
#include "core/interrupt.hpp"
#include "io/dataset.hpp"
#include "io/outcome_yaml.hpp"
#include "io/output_path.hpp"

namespace scenecal::cli {

namespace {

struct CalibrateArguments {
  std::string dataset;
  std::string output;
  std::string scheme = CalibrationSchemeName(kCoreDefaults.scheme);
  CostArguments cost;  // metric, scenes, swathes, histogram, normalisation, occlusion
  MotionCorrectionArguments motion;
  std::string lower_solver = LowerSolverName(kCoreDefaults.lower_solver);
  int lbfgs_iterations = kCoreDefaults.gradient.max_iterations;
  int lbfgs_line_search_steps = kCoreDefaults.gradient.line_search_max_steps;
  RunRadiusArguments run_radius;
  int threads = kCoreDefaults.threads;
  std::uint64_t seed = kCoreDefaults.seed;
  double time_budget_s = kCoreDefaults.time_budget_s;
  int max_iterations = kCoreDefaults.nelder_mead.max_iterations;
  std::string stages = StageScheduleText(kCoreDefaults.stages);
  std::string final_swathe = "same";  // --final-swathe: same, or centred (the last stage again, both sides)
  double step_translation_m = kCoreDefaults.nelder_mead.initial_step_translation_m;
  double step_rotation_deg = DegreesFromRadians(kCoreDefaults.nelder_mead.initial_step_rotation_rad);
  std::string rotation_pivot = "origin";
  double perturb_translation_m = 0.0;
  double perturb_rotation_deg = 0.0;
  bool perturb_from_truth = false;
  std::string report_dir;  // --report: HTML report directory; empty = none
  bool no_uncertainty = false;  // --no-uncertainty: skip the uncertainty estimate
  bool no_basin_check = false;  // --no-basin-check: skip the restarts from further away
  bool keep_calibration_answer = false;  // --keep-calibration-answer: a lower-cost restart end does not replace it
  double basin_offset_deg = 1.0;
  std::string odometry_scale_sigma = "auto";  // --odometry-scale-sigma: percent, or auto (from the trajectory's source)
  AlternatingArguments alternating;  // --scheme alt
  std::string backend = "threads";   // --backend: where alt's lower levels run, threads | mpi
  ConfigArguments config;            // --config, --setting
  AppliedConfiguration applied;      // what the preset set (ApplyConfiguration)
  CLI::App* command = nullptr;       // its options: to tell set ones from defaults, and for the result
};

// One line on an estimate's error against the truth: FORMAT.md's translation and
// rotation errors, then per axis (difference of translations, cm; roll, pitch,
// yaw of R_estimate * R_truth^T, deg).
std::string ErrorLine(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& truth) {
  const Eigen::Vector3d dt = (estimate.translation() - truth.translation()) * 100.0;
  const Eigen::Vector3d drpy = RollPitchYawFromRotation(estimate.linear() * truth.linear().transpose()) * 180.0 / kPi;
  return fmt::format(
      "translation {:.4f} m, rotation {:.3f} deg | dx {:+.2f} dy {:+.2f} dz {:+.2f} cm | droll {:+.3f} dpitch "
      "{:+.3f} dyaw {:+.3f} deg",
      TranslationError(estimate, truth), RotationErrorDegrees(estimate, truth), dt.x(), dt.y(), dt.z(), drpy.x(),
      drpy.y(), drpy.z());
}

bool LowerSolverFromPreset(const AppliedConfiguration& applied) {
  const std::vector<std::string>& words = applied.setting_words;
  return std::any_of(words.begin(), words.end(),
                     [](const std::string& word) { return word.starts_with("--lower-solver "); });
}

// The calibration's options from the command line; kExitInvalidInput (logged)
// when they do not fit together.
int MakeCalibrationOptions(const CalibrateArguments& args, CalibrationOptions* options) {
  // Arguments already checked by CLI11 validators; parse into the enums.
  ParseCalibrationScheme(args.scheme, &options->scheme);
  ApplyCostArguments(args.cost, options);
  ApplyMotionCorrectionArguments(args.motion, options);
  ParseLowerSolver(args.lower_solver, &options->lower_solver);
  if (options->lower_solver == LowerSolver::kLbfgs) {
    if (!args.cost.BinningGiven()) {
      options->cost.histogram.binning = Binning::kBSpline;  // gradients need it; recorded in the result's settings
    } else if (options->cost.histogram.binning != Binning::kBSpline) {
      spdlog::error("--lower-solver lbfgs{} needs --binning bspline: with --binning {} the cost is piecewise constant "
                    "and has no gradient (use --lower-solver simplex for hard binning)",
                    LowerSolverFromPreset(args.applied) ? " (from --setting " + args.applied.setting + ")" : "",
                    args.cost.binning);
      return kExitInvalidInput;
    }
  }
  options->pivot_at_observed_centroid = args.rotation_pivot == "centroid";
  options->nelder_mead.max_iterations = args.max_iterations;
  options->nelder_mead.initial_step_translation_m = args.step_translation_m;
  options->nelder_mead.initial_step_rotation_rad = RadiansFromDegrees(args.step_rotation_deg);
  options->gradient.max_iterations = args.lbfgs_iterations;
  options->gradient.line_search_max_steps = args.lbfgs_line_search_steps;
  options->gradient.initial_step_translation_m = args.step_translation_m;
  options->gradient.initial_step_rotation_rad = RadiansFromDegrees(args.step_rotation_deg);
  ApplyRunRadiusArguments(args.run_radius, options);
  if (!ParseStageSchedule(args.stages, &options->stages)) {
    spdlog::error("--stages: expected comma-separated SCALE[:BLUR[:RESTARTS]] entries, got '{}'", args.stages);
    return kExitInvalidInput;
  }
  options->threads = args.threads;
  options->seed = args.seed;
  options->time_budget_s = args.time_budget_s;
  args.alternating.ApplyTo(&options->alternating);
  if (options->alternating.stage_alternations > options->alternating.max_alternations &&
      args.applied.PresetSet("--stage-alternations")) {
    // The preset's span is for its own --alternations; with fewer given, its stages spread over those.
    spdlog::info("--setting {}: --stage-alternations {} capped at --alternations {}", args.applied.setting,
                 options->alternating.stage_alternations, options->alternating.max_alternations);
    options->alternating.stage_alternations = options->alternating.max_alternations;
  }
  std::string why;
  if (!options->IsValid(&why)) {
    spdlog::error("invalid options: {}", why);
    return kExitInvalidInput;
  }
  if (args.backend == "mpi" && options->scheme != CalibrationScheme::kAlt) {
    spdlog::error("--backend mpi distributes the lower levels of --scheme alt; it does not apply to --scheme {}",
                  args.scheme);
    return kExitInvalidInput;
  }
  return kExitSuccess;
}

// --setting on the opened dataset: whether it fits the data (logged with
// what it set). kExitInvalidInput (logged) when it does not fit.
int CheckSettingFitsDataset(const CalibrateArguments& args, const io::Dataset& dataset,
                            const CalibrationOptions& options) {
  if (args.final_swathe == "centred" && dataset.rig.HasPushBroomLidar()) {
    spdlog::error("--final-swathe centred on {}: rig.yaml has a 2D (push-broom) lidar, whose swathe sees a camera's "
                  "view on one side of the frame only; centred swathes are for 3D lidars (--final-swathe same)",
                  args.dataset);
    return kExitInvalidInput;
  }
  if (args.final_swathe == "centred" && dataset.trajectory.size() < 2) {
    spdlog::error("--final-swathe centred on {}: a single-pose trajectory has no swathe to centre "
                  "(--final-swathe same)", args.dataset);
    return kExitInvalidInput;
  }
  const AppliedConfiguration& applied = args.applied;
  if (applied.setting.empty()) return kExitSuccess;
  if (const std::string misfit = DataMisfit(applied.requires_data, dataset.rig, dataset.trajectory.size());
      !misfit.empty()) {
    spdlog::error("--setting {} on {}: {}", applied.setting, args.dataset, misfit);
    return kExitInvalidInput;
  }
  spdlog::info("--setting {}: {} (refresh border {:g} px)", applied.setting, fmt::join(applied.setting_words, " "),
               options.cost.swathe.refresh_border_px);
  return kExitSuccess;
}

bool PerturbsInitialGuesses(const CalibrateArguments& args) {
  return args.perturb_translation_m > 0.0 || args.perturb_rotation_deg > 0.0 || args.perturb_from_truth;
}

// --perturb-*: moves each lidar's initial guess in *rig (rig.yaml's, or with
// --perturb-from-truth the truth) by exactly the given magnitudes in random
// directions from --seed. kExitInvalidInput (logged) without the truth asked for.
int PerturbInitialGuesses(const CalibrateArguments& args, const io::Dataset& dataset, Rig* rig) {
  if (args.perturb_from_truth && !dataset.ground_truth) {
    spdlog::error("--perturb-from-truth needs ground_truth.yaml in {}", args.dataset);
    return kExitInvalidInput;
  }
  if (!PerturbsInitialGuesses(args)) return kExitSuccess;
  std::mt19937_64 rng(args.seed);
  for (LidarInfo& lidar : rig->lidars) {
    Eigen::Isometry3d base_guess = lidar.T_base_lidar;
    if (args.perturb_from_truth) {
      const auto truth = dataset.ground_truth->T_base_lidar.find(lidar.name);
      if (truth == dataset.ground_truth->T_base_lidar.end()) {
        spdlog::error("--perturb-from-truth: ground_truth.yaml has no T_base_lidar for lidar {}", lidar.name);
        return kExitInvalidInput;
      }
      base_guess = truth->second;
    }
    lidar.T_base_lidar = PerturbExactly(base_guess, args.perturb_translation_m, args.perturb_rotation_deg, rng);
    spdlog::info("lidar {}: initial guess = {} moved by {} m and {} deg (seed {})", lidar.name,
                 args.perturb_from_truth ? "the truth" : "rig.yaml's guess", args.perturb_translation_m,
                 args.perturb_rotation_deg, args.seed);
  }
  return kExitSuccess;
}

// What the benchmarks found for push-broom lidars and for drift corrections
// per lidar, where the options given may not be the best.
void LogAdviceForRig(const CalibrateArguments& args, const CalibrationOptions& options, const Rig& rig) {
  const bool has_push_broom = rig.HasPushBroomLidar();
  const std::string source = TrajectorySourceName(rig.trajectory_source);
  const std::string fitting_preset = PushBroomPresetFor(rig.trajectory_source);
  if (has_push_broom && !fitting_preset.empty() && !args.applied.setting.empty() &&
      args.applied.setting != fitting_preset) {
    spdlog::warn("rig.yaml says the trajectory is {}; --setting {} was measured for that, not --setting {}", source,
                 fitting_preset, args.applied.setting);
  } else if (has_push_broom && options.range_split_m <= 0.0) {
    // 10 m push-broom swathes leave the tilt nearly free (docs/findings.md, "A push-broom lidar's tilt is weakly
    // constrained").
    spdlog::info("push-broom lidar: its tilt is weakly determined by 10 m swathes; on the simulated drives (rear "
                 "and front push-broom lidars) 30 m swathes scored near and far apart did much better: {}; README, "
                 "\"What to expect\"",
                 fitting_preset.empty()
                     ? std::string("--setting push-broom (good odometry) or push-broom-drifting (visual odometry)")
                     : fmt::format("--setting {} (rig.yaml: trajectory_source {})", fitting_preset, source));
  } else if (has_push_broom && options.scenes.swathe_length_m >= 20.0 && !options.motion_correction &&
             args.applied.setting != "push-broom" &&  // that preset says the odometry is good
             (rig.trajectory_source == TrajectorySource::kUnknown ||
              rig.trajectory_source == TrajectorySource::kVisualOdometry)) {
    // Long swathes collect the odometry's drift (docs/findings.md, "Odometry drift moves the minimum along the
    // flat direction").
    spdlog::info("push-broom lidar with {} m swathes: if the trajectory is visual odometry (drifting ~0.01 deg/m; "
                 "rig.yaml: trajectory_source {}), --motion-correction turn,drive-scale (--setting "
                 "push-broom-drifting) corrects each frame's swathe and the drive's scale (on two of three simulated "
                 "drives 0.68-0.85 deg -> 0.12-0.14 deg, 1.4-1.6 cm); with exact odometry it costs 0.1-0.4 deg",
                 options.scenes.swathe_length_m, source);
  }
  if (options.motion_correction && options.motion.drive_scale && options.scheme != CalibrationScheme::kAlt &&
      rig.lidars.size() > 1) {
    // Only alt's correction spans the lidars (BENCHMARK.md, "Trinocular rig").
    spdlog::warn("--scheme {} corrects the drift of each lidar alone, each with its own drive scale; on the simulated "
                 "trinocular rig that tilted the front lidar 0.6 deg, where alt, which shares one correction among "
                 "the lidars, ended 0.18 deg off",
                 args.scheme);
  }
}

void LogCalibrationPlan(const CalibrateArguments& args, const CalibrationOptions& options) {
  const bool lbfgs = options.lower_solver == LowerSolver::kLbfgs;
  spdlog::info("calibrating: scheme {}, metric {}, {} bins {}, reflectance {}, stages {}, lower solver {}, up to {} "
               "iterations a run",
               args.scheme, args.cost.metric, options.cost.histogram.reflectance_bins,
               BinningName(options.cost.histogram.binning),
               args.cost.normalise_reflectance, args.stages, args.lower_solver,
               lbfgs ? args.lbfgs_iterations : args.max_iterations);
  if (lbfgs) {
    spdlog::info("lbfgs: evaluations are counted with and without the gradient; one cost + gradient evaluation "
                 "costs ~{} plain cost evaluations",
                 kGradientEvaluationCost);
  }
}

// The exit code of a solved calibration (logged when it failed).
int OutcomeExitCode(const CalibrationOutcome& outcome) {
  if (outcome.status == CalibrationStatus::kInvalidOptions) {
    spdlog::error("{}", outcome.why);
    return kExitInvalidInput;
  }
  if (outcome.status == CalibrationStatus::kCannotCalibrate) {
    spdlog::error("the data cannot be calibrated: {}", outcome.why);
    return kExitFailure;
  }
  return kExitSuccess;
}

void LogPairReports(const std::vector<PairReport>& pairs) {
  for (const PairReport& pair : pairs) {
    std::size_t min_points = 0, max_points = 0;
    if (!pair.projected_points.empty()) {
      min_points = *std::min_element(pair.projected_points.begin(), pair.projected_points.end());
      max_points = *std::max_element(pair.projected_points.begin(), pair.projected_points.end());
    }
    spdlog::info("pair {}/{}: {} of {} scenes used ({} too few points, {} constant image, {} constant reflectance), "
                 "{}..{} projected points per scene, cost {:.6f} -> {:.6f}",
                 pair.camera, pair.lidar, pair.scenes_used, pair.scenes, pair.scenes_too_few_points,
                 pair.scenes_constant_image, pair.scenes_constant_reflectance, min_points, max_points,
                 pair.initial_cost, pair.final_cost);
  }
}

// The command line's choices that the result records beside the core's settings.
void RecordCommandSettings(const CalibrateArguments& args, const std::string& single_frame_defaults,
                           const std::string& few_frames, CalibrationResult* result) {
  result->settings["image_channel"] = io::ImageChannelName(args.cost.ImageChannel());
  const AppliedConfiguration& applied = args.applied;
  if (!applied.setting.empty()) {
    result->settings["setting"] = applied.setting + (applied.setting_words.empty()
                                                         ? ""
                                                         : fmt::format(": {}", fmt::join(applied.setting_words, " ")));
  }
  if (applied.automatic) result->settings["setting_chosen_by"] = "--setting auto: " + applied.automatic_reason;
  if (!args.config.files.empty()) result->settings["config"] = fmt::format("{}", fmt::join(args.config.files, ", "));
  if (!single_frame_defaults.empty()) result->settings["single_frame_defaults"] = single_frame_defaults;
  if (!few_frames.empty()) result->settings["few_frames"] = few_frames;
  if (PerturbsInitialGuesses(args)) {
    result->settings["perturb_initial"] =
        fmt::format("{} m, {} deg, seed {}, from {}", args.perturb_translation_m, args.perturb_rotation_deg, args.seed,
                    args.perturb_from_truth ? "truth" : "rig.yaml");
  }
}

// The trajectory's scale error (1 sigma, fraction) whose effect on the
// answer the basin check measures for the sigma, and in *why where that
// figure comes from. The images cannot see the scale (docs/findings.md, "The
// drive's scale is invisible to the images"), so it follows what the
// trajectory is.
double TrajectoryScaleSigma(const CalibrateArguments& args, TrajectorySource source, bool drift_modelled,
                            std::string* why) {
  // Good stereo visual odometry and lidar odometry drift 0.5-1 % of the
  // distance travelled (KITTI's odometry benchmark), an INS with GNSS or a
  // scale measured outside a few hundredths of a percent.
  constexpr double kOdometrySigma = 0.005, kKnownSigma = 0.0005;
  if (args.odometry_scale_sigma != "auto") {
    *why = "--odometry-scale-sigma";
    return std::stod(args.odometry_scale_sigma) / 100.0;
  }
  if (args.cost.odometry_scale_percent != 0.0) {
    *why = "the scale given with --odometry-scale, taken as known to 0.05 %";
    return kKnownSigma;
  }
  switch (source) {
    case TrajectorySource::kExact: *why = "rig.yaml: trajectory_source exact"; return 0.0;
    case TrajectorySource::kIns: *why = "rig.yaml: trajectory_source ins (0.05 %)"; return kKnownSigma;
    case TrajectorySource::kLidarOdometry:
    case TrajectorySource::kVisualOdometry:
      *why = fmt::format("rig.yaml: trajectory_source {} (0.5 %: good odometry drifts 0.5-1 % of the distance)",
                         TrajectorySourceName(source));
      return kOdometrySigma;
    case TrajectorySource::kUnknown: break;
  }
  if (drift_modelled) {
    *why = "trajectory_source not given and the trajectory drifts: taken as odometry's 0.5 % (good odometry drifts "
           "0.5-1 % of the distance); rig.yaml's trajectory_source or --odometry-scale-sigma say otherwise";
    return kOdometrySigma;
  }
  *why = "trajectory_source not given and no drift model in use: the scale taken as exact; rig.yaml's "
         "trajectory_source or --odometry-scale-sigma say otherwise";
  return 0.0;
}

// The uncertainty estimate and the basin check of the answer (into *result,
// *extra and *verdicts), unless --no-uncertainty / --no-basin-check or the time budget
// is spent: it counts from the command's `start`.
// other_answers: per lidar, its answer under another model that the final one
// replaced (auto's push-broom answer before the drift model; the one-sided
// swathes' answer before the centred final stage): its offset enters the sigma.
void CheckAnswer(const CalibrateArguments& args, const CalibrationOptions& options, Calibrator& calibrator,
                 std::chrono::steady_clock::time_point start, const OtherAnswers& other_answers,
                 CalibrationResult* result, YAML::Node* extra, LidarVerdicts* verdicts) {
  const auto budget_spent = [&] {
    const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return args.time_budget_s > 0.0 && elapsed_s >= args.time_budget_s;
  };
  std::vector<LidarUncertainty> local_estimates;
  std::vector<LidarBasinCheck> basin_checks;
  // The basin check first: a restart that ends at a lower cost may become the
  // answer, and the uncertainty is then estimated there.
  if (!args.no_basin_check) {
    if (budget_spent()) {
      // The check runs the final stage six times per lidar: not within a spent budget.
      spdlog::warn("no basin check: the time budget ({} s) is spent", args.time_budget_s);
      result->settings["basin_check"] = "skipped: time budget spent";
    } else {
      std::string scale_why;
      const double scale_sigma = TrajectoryScaleSigma(args, calibrator.Input().rig.trajectory_source,
                                                      options.motion_correction, &scale_why);
      result->settings["trajectory_scale_sigma"] = fmt::format("{:g} % ({})", 100.0 * scale_sigma, scale_why);
      // With the drift model and no answer solved without it (trajectory_source named drifting odometry, or an
      // explicit setting), the check measures how far the model moves the answer: the sigma needs that offset.
      const bool without_drift_model = options.motion_correction && other_answers.by_lidar.empty();
      (*extra)["basin_check"] = ReportBasinCheck(calibrator, args.basin_offset_deg, !args.keep_calibration_answer,
                                                 scale_sigma, without_drift_model, result, &basin_checks);
    }
  }
  if (!args.no_uncertainty && budget_spent()) {
    spdlog::warn("no uncertainty estimate: the time budget ({} s) is spent", args.time_budget_s);
    result->settings["uncertainty"] = "skipped: time budget spent";
  } else if (!args.no_uncertainty) {
    if (options.motion_correction) {
      spdlog::info("uncertainty: the frames' drift corrections are held as estimated at the answer; their own "
                   "freedom is not in it (with --motion-correction the error can be several times larger)");
    }
    (*extra)["uncertainty"] = ReportUncertainty(calibrator, basin_checks, result, &local_estimates);
  }
  if (!local_estimates.empty()) {
    YAML::Node uncertainty = (*extra)["uncertainty"];
    ReportErrorEstimate(local_estimates, basin_checks, other_answers, options.motion_correction, result,
                        &uncertainty, verdicts);
  }
}

// With ground truth in the dataset: the errors of the result per lidar (and
// of its initial guess in `rig`) and per pair, on stdout.
// uncertainty: the result's `uncertainty` mapping (its edge_pixel_covariance gives the error in pixels).
void PrintErrorsAgainstTruth(const io::Dataset& dataset, const Rig& rig, const CalibrationResult& result,
                             const YAML::Node& uncertainty) {
  if (!dataset.ground_truth) return;
  const GroundTruth& truth = *dataset.ground_truth;
  for (const LidarCalibration& lidar : result.lidars) {
    const auto gt = truth.T_base_lidar.find(lidar.lidar);
    if (gt == truth.T_base_lidar.end()) continue;
    const LidarInfo* initial = rig.FindLidar(lidar.lidar);
    fmt::print("lidar {} T_base_lidar error: {}\n", lidar.lidar, ErrorLine(lidar.T_base_lidar, gt->second));
    if (lidar.covariance) {
      // 6 degrees of freedom: 95 % of errors within 3.55 when the covariance is right.
      constexpr double kEllipsoid95 = 3.55;
      const double mahalanobis = std::sqrt(TupleMahalanobisSquared(lidar.T_base_lidar, gt->second, *lidar.covariance));
      const bool inside = mahalanobis <= kEllipsoid95;
      fmt::print("lidar {} T_base_lidar error in sigmas: Mahalanobis {:.2f} ({} the 95 % ellipsoid: {} {:.2f})\n",
                 lidar.lidar, mahalanobis, inside ? "inside" : "outside", inside ? "<=" : ">", kEllipsoid95);
    }
    const YAML::Node entry = uncertainty.IsDefined() && uncertainty.IsMap() ? uncertainty[lidar.lidar] : YAML::Node();
    const YAML::Node edges = entry.IsDefined() && entry.IsMap() ? entry["edge_pixel_covariance"] : YAML::Node();
    if (edges.IsDefined() && edges.IsSequence() && edges.size() == 36) {
      Matrix6d one_pixel;
      for (int k = 0; k < 36; ++k) one_pixel.data()[k] = edges[k].as<double>();
      // The RMS misalignment, normal to the image edges, that an error this size causes.
      fmt::print("lidar {} T_base_lidar error in pixels: {:.2f} px RMS normal to the image edges\n", lidar.lidar,
                 std::sqrt(TupleMahalanobisSquared(lidar.T_base_lidar, gt->second, one_pixel)));
    }
    if (initial != nullptr) {
      fmt::print("lidar {} initial guess error: {}\n", lidar.lidar, ErrorLine(initial->T_base_lidar, gt->second));
    }
  }
  for (const PairCalibration& pair : result.pairs) {
    const auto gt = truth.T_base_lidar.find(pair.lidar);
    const CameraInfo* camera = dataset.rig.FindCamera(pair.camera);
    if (gt == truth.T_base_lidar.end() || camera == nullptr) continue;
    const auto camera_truth = truth.T_base_camera.find(pair.camera);
    const Eigen::Isometry3d T_base_camera =
        camera_truth == truth.T_base_camera.end() ? camera->T_base_camera : camera_truth->second;
    fmt::print("pair {}/{} T_camera_lidar error: {}\n", pair.camera, pair.lidar,
               ErrorLine(pair.T_camera_lidar, T_base_camera.inverse() * gt->second));
  }
}

// One solve with the options as the command line, its files and its preset
// now give them: the input, the calibrator built over it (which keeps a
// reference to it: not movable) and its outcome.
struct DatasetSolve {
  CalibrationOptions options;
  std::string single_frame_defaults;
  std::string few_frames;  // what NarrowScheduleForFewFrames changed, for the result
  CalibrationInput input;
  std::unique_ptr<Calibrator> calibrator;
  std::optional<CalibrationOutcome> outcome;  // none on an MPI rank that served lower levels
  double load_s = 0.0;
};

// Frames with a scene a lidar needs before a preset's wide stages run: half
// the 30 frames with which they were measured to widen the basin. On short
// windows of the simulated drives (1-8 frames) they walked up to 1.5 m off
// from starts 10 cm / 2 deg away, and 44-58 cm on the real DGP scene, where
// the narrow stages alone ended at most 45 cm, resp. 12 cm off, most within a
// few (BENCHMARK.md, "Short recordings").
constexpr int kMinFramesForWideStages = 15;

// A preset's schedule (--stages set by --setting, not given) without its wide
// stages when a lidar has fewer than kMinFramesForWideStages frames with a
// scene. Returns what it did (logged), or "" when it left the schedule alone.
std::string NarrowScheduleForFewFrames(const CalibrateArguments& args, const CalibrationInput& input,
                                       CalibrationOptions* options) {
  if (!args.applied.PresetSet("--stages")) return {};
  std::string fewest_lidar;
  int fewest = kMinFramesForWideStages;
  for (const LidarInfo& lidar : input.rig.lidars) {
    const int frames = input.selection.FramesOf(lidar.name);
    if (frames > 0 && frames < fewest) {
      fewest = frames;
      fewest_lidar = lidar.name;
    }
  }
  if (fewest_lidar.empty()) return {};
  const std::vector<OptimisationStage> narrow = WithoutWideStages(options->stages);
  const int dropped = static_cast<int>(options->stages.size() - narrow.size());
  if (dropped == 0) return {};
  const std::string text = fmt::format(
      "{} camera frame(s) with a scene for lidar {} (fewer than {}): the schedule {} without its wide stages, {}; "
      "on so few views they walk off along what the data do not constrain (--stages sets a schedule)",
      fewest, fewest_lidar, kMinFramesForWideStages, StageScheduleText(options->stages), StageScheduleText(narrow));
  options->stages = narrow;
  // A drift correction from a later stage stays after at least one stage (not at the initial guess).
  if (options->motion_correction_first_stage > 0) {
    options->motion_correction_first_stage = std::max(1, options->motion_correction_first_stage - dropped);
  }
  // The result's options block then holds the schedule that ran, so that --config repeats the run.
  SetOptionValue(args.command->get_option("--stages"), StageScheduleText(narrow));
  spdlog::warn("{}", text);
  return text;
}

bool AnyThreeDLidar(const Rig& rig) {
  return std::any_of(rig.lidars.begin(), rig.lidars.end(),
                     [](const LidarInfo& lidar) { return lidar.kind == LidarKind::k3d; });
}

// The informative scene choice on a rig with a 3D lidar, --scene-choice-after
// not given: before the schedule's last stage. Chosen after the first stage,
// one simulated spin3d world of three lost the basin from both starts (16-17
// cm off, --scenes auto 36-38 cm; 12.8 cm off still after the two wide stages,
// which every frame of the pool brings back and the frames chosen there do
// not); before the last stage every run ended within 0.55 cm. On the push-broom
// rigs the first stage was enough and the choice after it was the more accurate
// in translation (BENCHMARK.md, "Informative scenes").
void ChooseLateForThreeDLidars(const CalibrateArguments& args, const Rig& rig, CalibrationOptions* options) {
  if (options->scenes.choice != SceneChoice::kInformative || options->scheme == CalibrationScheme::kAlt) return;
  CLI::Option* after = args.command->get_option("--scene-choice-after");
  if (after->count() > 0 || options->stages.size() < 2 || !AnyThreeDLidar(rig)) return;
  options->scenes.informative_after_stages = static_cast<int>(options->stages.size()) - 1;
  spdlog::info("informative scene choice with a 3D lidar: after the first {} stage(s), before the last",
               options->scenes.informative_after_stages);
  // The result's options block then holds the choice that ran, so that --config repeats the run.
  SetOptionValue(after, std::to_string(options->scenes.informative_after_stages));
}

// Options, scenes, calibrator, solve: kExitSuccess with *solve filled, else
// the exit code (logged). `spent_s`: seconds of the command already spent,
// taken off --time-budget (a second solve gets what the first left).
// `start_from`: T_base_lidar per lidar to start from instead of the initial
// guess (a second solve starting where the first ended); `adjust`: changes
// the options of such a second solve; a solve that cannot calibrate is
// logged as an error unless `log_failure` is false (the caller falls back).
int SolveDataset(const CalibrateArguments& args, const io::Dataset& dataset, ProcessGroup& group,
                 DatasetSolve* solve, double spent_s = 0.0,
                 const std::map<std::string, Eigen::Isometry3d>& start_from = {},
                 const std::function<void(CalibrationOptions*)>& adjust = {}, bool log_failure = true) {
  const auto start = std::chrono::steady_clock::now();
  if (const int exit_code = MakeCalibrationOptions(args, &solve->options); exit_code != kExitSuccess) return exit_code;
  if (solve->options.time_budget_s > 0.0) {
    solve->options.time_budget_s = std::max(solve->options.time_budget_s - spent_s, 1e-3);
  }
  ApplyDatasetDefaults(dataset, args.cost, &solve->options, &solve->single_frame_defaults);
  if (adjust) adjust(&solve->options);
  if (const int exit_code = CheckSettingFitsDataset(args, dataset, solve->options); exit_code != kExitSuccess) {
    return exit_code;
  }
  solve->input.rig = dataset.rig;
  if (const int exit_code = PerturbInitialGuesses(args, dataset, &solve->input.rig); exit_code != kExitSuccess) {
    return exit_code;
  }
  for (LidarInfo& lidar : solve->input.rig.lidars) {
    if (const auto given = start_from.find(lidar.name); given != start_from.end()) lidar.T_base_lidar = given->second;
  }
  const LoadedScenes loaded = SelectAndLoadScenes(dataset, solve->options.scenes, &solve->input, args.cost.ImageChannel());
  solve->load_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  spdlog::info("loaded {} lidar points in {:.2f} s", loaded.lidar_points, solve->load_s);
  if (std::string narrowed = NarrowScheduleForFewFrames(args, solve->input, &solve->options); !narrowed.empty()) {
    solve->few_frames = std::move(narrowed);
  }
  ChooseLateForThreeDLidars(args, solve->input.rig, &solve->options);
  LogAdviceForRig(args, solve->options, solve->input.rig);
  LogCalibrationPlan(args, solve->options);
  solve->calibrator = std::make_unique<Calibrator>(solve->input, solve->options,
                                                   [](const std::string& message) { spdlog::info("{}", message); });
  solve->outcome = SolveOnGroup(*solve->calibrator, group);
  if (!log_failure && solve->outcome && solve->outcome->status != CalibrationStatus::kSuccess) return kExitFailure;
  return solve->outcome ? OutcomeExitCode(*solve->outcome) : kExitSuccess;
}

// An empty solve in place of *solve for the next one (its scenes freed before
// the next's are loaded), keeping what the result reports of the first's
// schedule.
void StartNextSolve(std::unique_ptr<DatasetSolve>* solve) {
  const std::string few_frames = (*solve)->few_frames;
  solve->reset();
  *solve = std::make_unique<DatasetSolve>();
  (*solve)->few_frames = few_frames;
}

// --setting auto: the preset for the data (ChooseSetting), applied and logged.
AutomaticChoice ChooseAutomatically(CalibrateArguments* args, const io::Dataset& dataset, const ProcessGroup& group) {
  if (!args->applied.automatic) return {};
  const AutomaticChoice choice = ChooseSetting(dataset.rig, dataset.trajectory.size(), !group.distributed());
  args->applied.automatic_reason = choice.reason;
  if (!choice.preset.empty()) ApplyPreset(args->command, choice.preset, &args->applied);
  spdlog::info("--setting auto: {} ({})", choice.preset.empty() ? std::string("no preset") : choice.preset,
               choice.reason);
  return choice;
}

// --setting auto on a push-broom drive whose trajectory's source is unknown:
// the held-out drift test at the push-broom answer. When it finds drift,
// push-broom-drifting solves again, all its stages, starting from the
// push-broom answer (closer than the initial guess: fewer alternations, the
// same or smaller errors on the simulated drives; BENCHMARK.md, "The no-flag
// default against the presets"). *evidence: the test's figures, for the result;
// *replaced_answers: the push-broom answer per lidar when the drift model replaced it.
int DecideOnDrift(CalibrateArguments* args, const io::Dataset& dataset, ProcessGroup& group,
                  std::unique_ptr<DatasetSolve>* solve, double spent_s, std::string* evidence,
                  std::map<std::string, Eigen::Isometry3d>* replaced_answers) {
  if (args->time_budget_s > 0.0 && spent_s >= args->time_budget_s) {
    spdlog::warn("no held-out drift test: the time budget ({} s) is spent; the push-broom answer stands",
                 args->time_budget_s);
    *evidence = "skipped: time budget spent";
    return kExitSuccess;
  }
  const auto start = std::chrono::steady_clock::now();
  DriftTestOptions test;
  test.motion = (*solve)->options.motion;
  test.motion.turn = true;  // the per-frame rates: how visual odometry drifts
  test.motion.scale = test.motion.roll = test.motion.drive_scale = false;
  const DriftTestResult drift = (*solve)->calibrator->TestDriftAt((*solve)->outcome->result, test);
  *evidence = fmt::format("{} ({:.1f} s)", drift.Describe(),
                          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  spdlog::info("held-out drift test at the push-broom answer (each frame's turn rates predicted from its "
               "neighbours'): {}",
               *evidence);
  if (!drift.drift_found) return kExitSuccess;
  ApplyPreset(args->command, "push-broom-drifting", &args->applied);
  args->applied.automatic_reason +=
      "; the trajectory drifts within the swathes: push-broom-drifting, started from the push-broom answer";
  spdlog::info("--setting auto: push-broom-drifting, solving again from the push-broom answer");
  std::map<std::string, Eigen::Isometry3d> push_broom_answer;
  for (const LidarCalibration& lidar : (*solve)->outcome->result.lidars) {
    push_broom_answer[lidar.lidar] = lidar.T_base_lidar;
  }
  *replaced_answers = push_broom_answer;
  StartNextSolve(solve);
  const double tested_s = spent_s + std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return SolveDataset(*args, dataset, group, solve->get(), tested_s, push_broom_answer);
}

// --final-swathe centred: the schedule's last stage again, from the first
// solve's answer, on swathes reaching half --swathe-length before and after
// each frame (as many metres of travel as one-sided). The first solve's scenes
// go first (memory). Centred swathes that leave nothing to calibrate (a lidar
// that sees the cameras' view on one side of the frame only) are a warning:
// the last stage then runs again on one-sided swathes from the first answer.
// *evidence: what was done, for the result; *first_answers: the first answer
// per lidar when the centred one replaced it.
int CentreFinalStage(const CalibrateArguments& args, const io::Dataset& dataset, ProcessGroup& group,
                     std::unique_ptr<DatasetSolve>* solve, double spent_s, std::string* evidence,
                     std::map<std::string, Eigen::Isometry3d>* first_answers) {
  if (group.distributed()) {
    spdlog::warn("--final-swathe centred: not across MPI ranks; the one-sided answer stands");
    *evidence = "skipped: not across MPI ranks";
    return kExitSuccess;
  }
  if (args.time_budget_s > 0.0 && spent_s >= args.time_budget_s) {
    spdlog::warn("--final-swathe centred: the time budget ({} s) is spent; the one-sided answer stands",
                 args.time_budget_s);
    *evidence = "skipped: time budget spent";
    return kExitSuccess;
  }
  std::map<std::string, Eigen::Isometry3d> answers;
  for (const LidarCalibration& lidar : (*solve)->outcome->result.lidars) answers[lidar.lidar] = lidar.T_base_lidar;
  const OptimisationStage last = (*solve)->options.stages.back();
  const double half_m = 0.5 * (*solve)->options.scenes.swathe_length_m;
  const std::string stage_text = StageScheduleText({last});
  const auto last_stage_only = [last](CalibrationOptions* options) { options->stages = {last}; };
  const auto centred = [&](CalibrationOptions* options) {
    last_stage_only(options);
    options->scenes.direction = SwatheDirection::kBoth;
    options->scenes.swathe_length_m = half_m;
  };
  spdlog::info("--final-swathe centred: the last stage ({}) again from the answer, on swathes {:g} m either side of "
               "each frame",
               stage_text, half_m);
  StartNextSolve(solve);
  const int exit_code = SolveDataset(args, dataset, group, solve->get(), spent_s, answers, centred, false);
  if (exit_code == kExitSuccess) {
    std::vector<std::string> moved;
    for (const LidarCalibration& lidar : (*solve)->outcome->result.lidars) {
      const auto first = answers.find(lidar.lidar);
      if (first == answers.end()) continue;
      moved.push_back(fmt::format("{} by {:.2f} cm, {:.3f} deg", lidar.lidar,
                                  100.0 * TranslationError(lidar.T_base_lidar, first->second),
                                  RotationErrorDegrees(lidar.T_base_lidar, first->second)));
    }
    *first_answers = answers;
    *evidence = fmt::format("centred: the last stage ({}) again from the one-sided answer on swathes {:g} m either "
                            "side of each frame; it moved {}",
                            stage_text, half_m, fmt::join(moved, "; "));
    spdlog::info("--final-swathe {}", *evidence);
    return kExitSuccess;
  }
  if (!(*solve)->outcome) return exit_code;  // the options or the setting did not fit: logged
  const std::string why = (*solve)->outcome->why;
  spdlog::warn("--final-swathe centred: the centred swathes cannot be calibrated ({}); the last stage runs again on "
               "one-sided swathes from their answer",
               why);
  *evidence = fmt::format("not applied: the centred swathes cannot be calibrated ({})", why);
  StartNextSolve(solve);
  return SolveDataset(args, dataset, group, solve->get(), spent_s, answers, last_stage_only);
}

// The informative scene choice's warning: experimental everywhere, and no
// better than as many spread frames on a 3D lidar.
std::string InformativeChoiceWarning(const Rig& rig) {
  if (AnyThreeDLidar(rig)) {
    return "the informative scene choice is experimental, and no gain for a 3D lidar: on the simulated spin3d "
           "drives 15 informative frames per camera, chosen before the last stage, ended 0.36 cm off (median) "
           "against 0.28 cm for 15 spread frames, and chosen after the first stage they lost one world of three "
           "(16-38 cm off) (BENCHMARK.md, \"Informative scenes\"); check the answer against the default "
           "--scene-choice spread";
  }
  return "the informative scene choice is experimental: at 15 frames per camera it lowered the error on the "
         "simulated RobotCar-like drive and for the trinocular rear lidar but raised the front lidar's translation "
         "error (BENCHMARK.md, \"Informative scenes\"); check the answer against the default --scene-choice spread";
}

int RunCalibration(CalibrateArguments& args, ProcessGroup& group) {
  const auto start = std::chrono::steady_clock::now();
  // Before any work: a result that could not be written would waste the run.
  // Only rank 0 writes, and other hosts need not have its output folder.
  if (group.IsRoot()) {
    io::CheckOutputFile(args.output, "--output");
    if (!args.report_dir.empty()) io::CheckOutputFolderWritable(args.report_dir, "--report");
  }
  const auto thread_limit = LimitThreads(args.threads);
  spdlog::info("opening {}", args.dataset);
  const io::Dataset dataset = io::OpenDataset(args.dataset);
  const AutomaticChoice choice = ChooseAutomatically(&args, dataset, group);

  auto solve = std::make_unique<DatasetSolve>();
  if (const int exit_code = SolveDataset(args, dataset, group, solve.get());
      exit_code != kExitSuccess || !solve->outcome) {
    return exit_code;  // an error, or a serving MPI rank: rank 0 writes
  }
  const Rig initial_guesses = solve->input.rig;  // a second solve starts elsewhere
  std::string drift_evidence;
  // Answers of the same data under another model, whose offsets enter the sigma: the push-broom answers the drift
  // model replaced, or the one-sided answers the centred final stage replaced.
  std::map<std::string, Eigen::Isometry3d> other_answers;
  std::string other_answers_are;
  if (choice.test_drift) {
    const double first_solve_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (const int exit_code = DecideOnDrift(&args, dataset, group, &solve, first_solve_s, &drift_evidence,
                                              &other_answers);
        exit_code != kExitSuccess) {
      return exit_code;
    }
    solve->outcome->result.timings_s["push_broom_solve"] = first_solve_s;
    other_answers_are = "the answer without the drift model";
  }
  std::string final_swathe_evidence;
  if (args.final_swathe == "centred") {
    const double first_solve_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (const int exit_code = CentreFinalStage(args, dataset, group, &solve, first_solve_s, &final_swathe_evidence,
                                                 &other_answers);
        exit_code != kExitSuccess) {
      return exit_code;
    }
    solve->outcome->result.timings_s["one_sided_solve"] = first_solve_s;
    other_answers_are = "the one-sided swathes' answer";
  }
  Calibrator& calibrator = *solve->calibrator;
  CalibrationOutcome& outcome = *solve->outcome;
  AddOptionAdvice(&outcome);  // the core's warnings name no option: this command's that act on them
  LogPairReports(outcome.pairs);
  CalibrationResult& result = outcome.result;
  result.timings_s["load"] = solve->load_s;
  RecordCommandSettings(args, solve->single_frame_defaults, solve->few_frames, &result);
  if (!drift_evidence.empty()) result.settings["drift_test"] = drift_evidence;
  if (!final_swathe_evidence.empty()) result.settings["final_swathe"] = final_swathe_evidence;
  if (solve->options.scenes.choice == SceneChoice::kInformative) {
    result.warnings.push_back(InformativeChoiceWarning(dataset.rig));
  }
  result.settings["trajectory_source"] = TrajectorySourceName(dataset.rig.trajectory_source);
  YAML::Node extra(YAML::NodeType::Map);
  CalibrationReportOptions report_options;
  CheckAnswer(args, solve->options, calibrator, start, {other_answers, other_answers_are}, &result, &extra,
              &report_options.verdicts);
  result.timings_s["total"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  for (const std::string& warning : result.warnings) spdlog::warn("{}", warning);
  // Each frame's drift correction: what the odometry did over its swathe, as the images saw it.
  if (!outcome.motion_corrections.empty()) {
    extra["motion_correction"] = io::MotionCorrectionYaml(outcome.motion_corrections);
  }
  // The per-alternation history (lower and upper solutions per pair) for the paper's Fig. 4 and 6.
  if (outcome.alternating) extra["history"] = io::AlternatingHistoryYaml(*outcome.alternating);
  // Every option as used: `scenecal calibrate DATASET --config RESULT` repeats the run.
  extra["options"] = io::OptionsYaml(RunOptions(args.command));
  // The report first: it takes a while, and an interruption or a failure
  // there must not leave a result file without the report asked for.
  if (!args.report_dir.empty()) {
    WriteCalibrationReport(args.report_dir, calibrator, outcome, dataset, report_options);
  }
  io::WriteCalibrationResult(args.output, result, extra);
  spdlog::info("wrote {} ({})", args.output, result.termination);
  PrintErrorsAgainstTruth(dataset, initial_guesses, result, std::as_const(extra)["uncertainty"]);
  return kExitSuccess;
}

// MPI starts before any data is read (every rank loads the same inputs). A
// rank that fails ends every rank at once: the others would otherwise wait in
// a collective for it forever.
int Run(CalibrateArguments& args) {
  ProcessGroup group(args.scheme == "alt" ? args.backend : "threads");
  if (!group.distributed()) return RunCalibration(args, group);
  if (!group.IsRoot()) spdlog::set_level(spdlog::level::warn);
  int exit_code = kExitFailure;
  try {
    exit_code = RunCalibration(args, group);
  } catch (const Interrupted&) {
    // The other ranks may wait in a collective for this one: end them all.
    spdlog::error("rank {}: interrupted by {}; no output written", group.rank(), InterruptSignalName());
    group.AbortAll(InterruptExitCode());
  } catch (const io::InputError& e) {
    spdlog::error("rank {}: {}", group.rank(), e.what());
    group.AbortAll(kExitInvalidInput);
  } catch (const std::exception& e) {
    spdlog::error("rank {}: {}", group.rank(), e.what());
    group.AbortAll(kExitFailure);
  }
  // A rank that stops with an error before the others reach a collective ends them too.
  if (exit_code != kExitSuccess) group.AbortAll(exit_code);
  return exit_code;
}

// The local optimiser and the threads it runs on.
void AddSolverOptions(CLI::App* command, CalibrateArguments* args) {
  command->add_option("--lower-solver", args->lower_solver,
                      "Local optimiser of every stage (once, joint) and of the alt lower level: simplex (Nelder-Mead, "
                      "the paper; derivative free, any binning) or lbfgs (quasi-Newton with analytic gradients of the "
                      "B-spline metric: far fewer cost evaluations; needs --binning bspline, which it selects when "
                      "--binning is not given)")
      ->check(CLI::IsMember({"simplex", "lbfgs"}))
      ->capture_default_str();
  command->add_option("--lbfgs-iterations", args->lbfgs_iterations,
                      "--lower-solver lbfgs: iterations per run (per stage, per alt lower level); --step-translation "
                      "and --step-rotation set its parameter scales")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  command->add_option("--lbfgs-line-search-steps", args->lbfgs_line_search_steps,
                      "--lower-solver lbfgs: trial steps per line search. The cost is rough below ~1e-3 of a "
                      "parameter scale, where long searches gain nothing: on the RobotCar-like drive 20 (Ceres' "
                      "default) took 404 evaluations where 4 took 217, for the same answer; 20 is the more thorough "
                      "search (BENCHMARK.md)")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  AddRunRadiusOptions(command, &args->run_radius);
  command->add_option("--threads", args->threads, "Worker threads; 0 = all hardware threads")
      ->check(kNonNegative)
      ->capture_default_str();
}

// Robustness studies: each lidar's initial guess moved in a random direction from --seed.
void AddPerturbationOptions(CLI::App* command, CalibrateArguments* args) {
  command->add_option("--seed", args->seed,
                      "Seed of the random directions of --perturb-translation/--perturb-rotation (the calibration "
                      "itself is deterministic)")
      ->capture_default_str();
  command->add_option("--perturb-translation", args->perturb_translation_m,
                      "Robustness studies: move each lidar's initial guess by exactly this many metres in a random "
                      "direction (from --seed) before calibrating")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--perturb-rotation", args->perturb_rotation_deg,
                      "Robustness studies: rotate each lidar's initial guess by exactly this many degrees about a "
                      "random axis (from --seed)")
      ->check(kNonNegative)
      ->capture_default_str();
}

// How long the optimisation runs and in which coarse-to-fine steps.
void AddScheduleOptions(CLI::App* command, CalibrateArguments* args) {
  command->add_option("--time-budget", args->time_budget_s,
                      "Wall-clock budget of the optimisation in seconds; 0 = none. The optimisation stops when it "
                      "runs out and keeps the best point so far; loading the data (and for --scheme alt building the "
                      "swathes) comes before it. The uncertainty and the basin check are skipped once the command has "
                      "run for longer than the budget; --report is written regardless")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--max-iterations", args->max_iterations,
                      "Nelder-Mead iterations per run (per stage; per alt lower level)")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  command->add_option("--stages", args->stages,
                      fmt::format("Coarse-to-fine schedule, comma-separated SCALE[:BLUR[:RESTARTS]] per stage: SCALE "
                                  "multiplies the initial simplex steps, BLUR is the image blur (Gaussian sigma as a "
                                  "fraction of the image width), RESTARTS the extra Nelder-Mead runs while the cost "
                                  "still improves. Images and visibility are refreshed before each stage. '1' = one "
                                  "plain run (the paper). A preset's schedule loses its wide stages (SCALE 1) when a "
                                  "lidar has fewer than {} camera frames with a scene: on so few views they walk off "
                                  "(BENCHMARK.md, \"Short recordings\"); given here, the schedule runs as given",
                                  kMinFramesForWideStages))
      ->capture_default_str();
  command->add_option("--final-swathe", args->final_swathe,
                      "same: every stage on the swathes of --direction; centred (3D lidars): then the last stage "
                      "again, from that answer, on swathes reaching half --swathe-length before and after each "
                      "frame. Scans on one side of the frame see the scene from elsewhere and carry the odometry's "
                      "drift away from it, which moves the answer along the camera's depth axis; on a centred "
                      "swathe both cancel to first order (the coarse stages keep one side: centred from the start "
                      "lost the basin). The offset between the two answers enters the sigma (BENCHMARK.md, spin3d)")
      ->check(CLI::IsMember({"same", "centred"}))
      ->capture_default_str();
  command->add_option("--step-translation", args->step_translation_m,
                      "Initial simplex step (lbfgs: parameter scale), metres (first stage)")
      ->check(kPositive)
      ->capture_default_str();
  command->add_option("--step-rotation", args->step_rotation_deg,
                      "Initial simplex step (lbfgs: parameter scale), degrees (first stage)")
      ->check(kPositive)
      ->capture_default_str();
}

// Where the optimisation starts (robustness studies) and what the simplex turns the lidar about.
void AddStartOptions(CLI::App* command, CalibrateArguments* args) {
  command->add_flag("--perturb-from-truth", args->perturb_from_truth,
                    "Robustness studies: start from ground_truth.yaml's T_base_lidar (moved by --perturb-*) instead "
                    "of rig.yaml's guess");
  command->add_option("--rotation-pivot", args->rotation_pivot,
                      "Point the simplex rotates the lidar about: origin (the lidar's origin) or centroid (the "
                      "centroid of the lidar points seen at the initial guess)")
      ->check(CLI::IsMember({"origin", "centroid"}))
      ->capture_default_str();
}

// What follows the calibration: the uncertainty, the basin check and the report.
void AddAfterCalibrationOptions(CLI::App* command, CalibrateArguments* args) {
  command->add_flag("--no-uncertainty", args->no_uncertainty,
                    "Skip the uncertainty estimate after the calibration (by default each lidar gets a local "
                    "1-sigma per parameter, or a warning naming the directions the data do not determine; with the "
                    "basin check's restarts it becomes the result's sigma and covariance and a verdict: good, weak "
                    "along a named direction, or unreliable; ~130 cost evaluations: seconds for push-broom "
                    "swathes, minutes for dense 3D sweeps; skipped when --time-budget is spent by then)");
  command->add_flag("--no-basin-check", args->no_basin_check,
                    "Skip the basin check after the calibration (by default the joint cost is minimised again from "
                    "the answer turned +-1 deg about each base axis, and a warning says when those runs end apart: "
                    "the data then do not pin the extrinsic down, however small the local sigma; a run that ends "
                    "apart at a clearly lower cost becomes the answer; six runs of the last stage, each once and to "
                    "the middle stages' looser tolerance, a run stopping once back within 0.9 cm / 0.09 deg "
                    "of an answer where the same run rests (and counting as that answer), one more run with the "
                    "trajectory's distances longer by its scale error (--odometry-scale-sigma), and with the drift "
                    "model on and no answer solved without it, one with the drift corrections removed (how far the "
                    "model moves the answer enters the sigma): ~3 x its evaluations; skipped when --time-budget is "
                    "spent by then; without it the verdict is at best weak: the local spread alone does not see a "
                    "flat valley)");
  command->add_flag("--keep-calibration-answer", args->keep_calibration_answer,
                    "Basin check: keep the calibration's own answer even where a restart ended apart from it (beyond "
                    "1 cm / 0.1 deg) at a cost lower by more than two standard errors of the drop over the scenes (by "
                    "default that end becomes the answer, as the solver had stopped short of the cost's minimum, and "
                    "the calibration's answer is kept as basin_check.LIDAR.calibration_answer; not under --scheme alt "
                    "when a camera's T_base_camera has a sigma in rig.yaml)");
  command->add_option("--basin-offset", args->basin_offset_deg,
                      "Basin check: turn the restarts' starts this many degrees away from the answer")
      ->check(CLI::Range(0.01, 44.9))
      ->capture_default_str();
  command->add_option("--odometry-scale-sigma", args->odometry_scale_sigma,
                      "Basin check: the trajectory's scale error, 1 sigma in percent, whose effect enters the "
                      "result's sigma: the images cannot tell it from a shift of the lidar along the travel, so one "
                      "more run minimises the cost from the answer with every distance that much longer (a push-broom "
                      "lidar moved 1.2-1.9 cm per 0.1 % on the simulated drives). auto: 0.5 for visual or lidar "
                      "odometry (rig.yaml's trajectory_source) or an unknown source in which the drift test found "
                      "drift, 0.05 for an INS or a scale given with --odometry-scale, 0 for exact poses or an unknown "
                      "source without drift")
      ->check([](const std::string& text) -> std::string {
        if (text == "auto") return "";
        try {
          std::size_t used = 0;
          const double value = std::stod(text, &used);
          if (used == text.size() && std::isfinite(value) && value >= 0.0 && value < 20.0) return "";
        } catch (const std::exception&) {
        }
        return "expected auto or a percentage in [0, 20), got '" + text + "'";
      })
      ->capture_default_str();
  command->add_option("--report", args->report_dir,
                      "Write an HTML report with convergence, cost slices and overlays into this directory "
                      "(report.html and PNGs)")
      ->configurable(false);  // an output path: on the command line only
}

}  // namespace

CommandRunner AddCalibrateCommand(CLI::App& app) {
  auto args = std::make_shared<CalibrateArguments>();
  CLI::App* command = app.add_subcommand(
      "calibrate",
      "Calibrate every lidar of DATASET against its cameras (targetless, from the drive) and write FILE.\n"
      "Exit 1 with the reason when the data cannot be calibrated; 2 for bad arguments or input data.");
  command->add_option("dataset", args->dataset, "Dataset folder (docs/FORMAT.md)")
      ->required()
      ->check(CLI::ExistingDirectory);
  command->add_option("-o,--output", args->output, "Result file (YAML, written atomically)")
      ->required()
      ->configurable(false);
  command->add_option("--scheme", args->scheme,
                      "alt: the paper's alternating optimisation (a lower-level optimiser per camera/lidar pair, an "
                      "upper-level least squares through the known camera transforms, quadratic penalties with a "
                      "shrinking covariance); once: each camera/lidar pair alone; joint: one problem per lidar over "
                      "T_base_lidar, the cost summed over all cameras through the known camera transforms")
      ->check(CLI::IsMember({"once", "joint", "alt"}))
      ->capture_default_str();
  args->command = command;
  AddConfigOptions(command, &args->config, /*automatic=*/true);
  AddCostOptions(command, &args->cost);
  AddMotionCorrectionOptions(command, &args->motion);
  AddSolverOptions(command, args.get());
  AddPerturbationOptions(command, args.get());
  AddScheduleOptions(command, args.get());
  AddStartOptions(command, args.get());
  AddAfterCalibrationOptions(command, args.get());
  AddAlternatingOptions(command, &args->alternating);
  command->add_option("--backend", args->backend,
                      "Where the lower levels of --scheme alt run: threads (this process) or mpi (the ranks of "
                      "mpirun; every rank reads the dataset, rank 0 writes the result)")
      ->check(CLI::IsMember({"threads", "mpi"}))
      ->capture_default_str();
  return [args] {
    args->applied = ApplyConfiguration(args->command, args->config);
    return Run(*args);
  };
}

}  // namespace scenecal::cli
