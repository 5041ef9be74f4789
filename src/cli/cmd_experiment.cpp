// `scenecal experiment --preset P --output DIR [...]`: the paper's protocol
// (section IV, Fig. 7 and 8). Simulates a dataset (or takes --dataset), loads
// the scenes once, draws --guesses initial guesses (the truth moved by exactly
// the given magnitudes in random directions from --seed; every scheme and
// metric starts from the same guesses), calibrates with every scheme x metric
// from every guess, and writes DIR/runs.csv and DIR/report.html.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include "cli/commands.hpp"
#include "cli/config.hpp"
#include "cli/cost_arguments.hpp"
#include "cli/load_input.hpp"
#include "cli/validators.hpp"
#include "core/calibrate_alternating.hpp"
#include "core/calibrator.hpp"
#include "core/geometry.hpp"
#include "io/dataset.hpp"
#include "io/error.hpp"
#include "io/option_file.hpp"
#include "io/output_path.hpp"
#include "io/staged_output.hpp"
#include "report/html_report.hpp"
#include "sim/simulator.hpp"

namespace scenecal::cli {

namespace {

struct ExperimentArguments {
  std::string preset = "robotcar";
  std::string dataset;  // empty: simulate into OUTPUT/dataset
  std::string output;
  std::uint64_t seed = 1;
  int guesses = 5;
  double perturb_translation_m = 0.1;
  double perturb_rotation_deg = 3.0;
  std::vector<std::string> schemes = {"once", "joint", "alt"};
  std::vector<std::string> metrics = {"nid", "mi"};
  AlternatingArguments alternating;  // --scheme alt's options, as calibrate's
  int threads = kCoreDefaults.threads;
  std::string image_size;     // WxH; empty: the simulator's default
  double distance_m = 380.0;  // simulated drive length
  int max_iterations = kCoreDefaults.nelder_mead.max_iterations;
  std::string lower_solver = LowerSolverName(kCoreDefaults.lower_solver);  // lbfgs: B-spline binning for every run
  std::string stages = StageScheduleText(kCoreDefaults.stages);
  RunRadiusArguments run_radius;  // lbfgs: how far one run may move
  int overlay_scenes = 1;
  bool force = false;
  CostArguments cost;              // scenes, swathes, histogram, normalisation, occlusion (not the metric)
  MotionCorrectionArguments motion;
  ConfigArguments config;          // --config, --setting
  AppliedConfiguration applied;    // what the preset set (ApplyConfiguration)
  CLI::App* command = nullptr;     // its options, recorded in OUTPUT/options.yaml
};

// Everything recorded of one calibration for one lidar.
struct RunRecord {
  int guess = 0;
  std::string scheme;
  std::string metric;
  std::string lidar;
  bool success = false;
  std::string termination;
  Eigen::Isometry3d T_base_lidar_initial = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_base_lidar = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_base_lidar_truth = Eigen::Isometry3d::Identity();
  double initial_cost = std::numeric_limits<double>::quiet_NaN();  // mean over the lidar's pairs
  double final_cost = std::numeric_limits<double>::quiet_NaN();
  int evaluations = 0;
  double seconds = 0.0;
};

std::string Method(const std::string& scheme, const std::string& metric) { return scheme + "-" + metric; }

std::string FormatDuration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "?";
  const long long s = std::llround(seconds);
  return s >= 3600 ? fmt::format("{}:{:02}:{:02}", s / 3600, (s / 60) % 60, s % 60)
                   : fmt::format("{}:{:02}", s / 60, s % 60);
}

// CSV field: quoted when it holds a separator, quote or line break.
std::string CsvField(const std::string& text) {
  if (text.find_first_of(",\"\n\r") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) {
    if (c == '"') quoted += '"';
    quoted += c;
  }
  return quoted + "\"";
}

std::string Number(double value, int precision = 6) {
  return std::isfinite(value) ? fmt::format("{:.{}g}", value, precision) : "nan";
}

// One row per run and lidar. Errors: total translation (m) and rotation (deg);
// per axis in the 6-tuple (tuple(estimate) - tuple(truth): x, y, z m; roll,
// pitch, yaw deg, as the report's Fig. 8); and the translation error
// t_est - t_gt (m) and rotation error R_est * R_gt^T as a rotation vector
// (deg), both in the base frame (the base camera: x right, y down, z forward);
// the same for the initial guess.
std::string RunsCsv(const std::vector<RunRecord>& runs) {
  std::string csv =
      "guess,scheme,metric,method,lidar,success,translation_error_m,rotation_error_deg,"
      "error_x_m,error_y_m,error_z_m,error_roll_deg,error_pitch_deg,error_yaw_deg,"
      "base_dx_m,base_dy_m,base_dz_m,base_rx_deg,base_ry_deg,base_rz_deg,"
      "initial_translation_error_m,initial_rotation_error_deg,initial_base_dx_m,initial_base_dy_m,initial_base_dz_m,"
      "initial_base_rx_deg,initial_base_ry_deg,initial_base_rz_deg,initial_cost,cost,evaluations,seconds,termination\n";
  for (const RunRecord& run : runs) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    Vector6d tuple_error = Vector6d::Constant(nan);
    Eigen::Vector3d base_dt = Eigen::Vector3d::Constant(nan), base_dr = Eigen::Vector3d::Constant(nan);
    double translation = nan, rotation = nan;
    if (run.success) {
      tuple_error = report::TupleError(run.T_base_lidar, run.T_base_lidar_truth);
      base_dt = run.T_base_lidar.translation() - run.T_base_lidar_truth.translation();
      base_dr = LogSO3(run.T_base_lidar.linear() * run.T_base_lidar_truth.linear().transpose()) * 180.0 / kPi;
      translation = TranslationError(run.T_base_lidar, run.T_base_lidar_truth);
      rotation = RotationErrorDegrees(run.T_base_lidar, run.T_base_lidar_truth);
    }
    std::vector<std::string> fields = {std::to_string(run.guess), run.scheme, run.metric,
                                       Method(run.scheme, run.metric), CsvField(run.lidar),
                                       run.success ? "1" : "0", Number(translation), Number(rotation)};
    for (int k = 0; k < 6; ++k) fields.push_back(Number(k < 3 ? tuple_error[k] : tuple_error[k] * 180.0 / kPi));
    for (int k = 0; k < 3; ++k) fields.push_back(Number(base_dt[k]));
    for (int k = 0; k < 3; ++k) fields.push_back(Number(base_dr[k]));
    fields.push_back(Number(TranslationError(run.T_base_lidar_initial, run.T_base_lidar_truth)));
    fields.push_back(Number(RotationErrorDegrees(run.T_base_lidar_initial, run.T_base_lidar_truth)));
    const Eigen::Vector3d initial_dt = run.T_base_lidar_initial.translation() - run.T_base_lidar_truth.translation();
    const Eigen::Vector3d initial_dr =
        LogSO3(run.T_base_lidar_initial.linear() * run.T_base_lidar_truth.linear().transpose()) * 180.0 / kPi;
    for (int k = 0; k < 3; ++k) fields.push_back(Number(initial_dt[k]));
    for (int k = 0; k < 3; ++k) fields.push_back(Number(initial_dr[k]));
    fields.push_back(Number(run.initial_cost, 8));
    fields.push_back(Number(run.final_cost, 8));
    fields.push_back(std::to_string(run.evaluations));
    fields.push_back(fmt::format("{:.2f}", run.seconds));
    fields.push_back(CsvField(run.termination));
    for (std::size_t i = 0; i < fields.size(); ++i) csv += (i == 0 ? "" : ",") + fields[i];
    csv += "\n";
  }
  return csv;
}

// Quantile q in [0, 1] with linear interpolation between order statistics
// (numpy's default); NaN for no values.
double Quantile(std::vector<double> values, double q) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(values.begin(), values.end());
  const double position = q * static_cast<double>(values.size() - 1);
  const std::size_t below = static_cast<std::size_t>(std::floor(position));
  const std::size_t above = std::min(below + 1, values.size() - 1);
  return values[below] + (position - static_cast<double>(below)) * (values[above] - values[below]);
}

// Markdown table per method: successful runs, median [q1, q3] of the
// translation (cm) and rotation (deg) errors, and the median absolute
// rotation error about each base axis (deg; base camera: x right, y down,
// z forward) and translation error along it (cm).
std::string SummaryTable(const std::vector<RunRecord>& runs, const std::vector<std::string>& methods) {
  std::string table =
      "| method | runs ok | translation error cm: median [q1, q3] | rotation error deg: median [q1, q3] | "
      "median abs dx, dy, dz cm | median abs rx, ry, rz deg |\n|---|---|---|---|---|---|\n";
  for (const std::string& method : methods) {
    std::vector<double> translation, rotation;
    std::array<std::vector<double>, 6> axes;
    int attempted = 0;
    for (const RunRecord& run : runs) {
      if (Method(run.scheme, run.metric) != method) continue;
      ++attempted;
      if (!run.success) continue;
      translation.push_back(100.0 * TranslationError(run.T_base_lidar, run.T_base_lidar_truth));
      rotation.push_back(RotationErrorDegrees(run.T_base_lidar, run.T_base_lidar_truth));
      const Eigen::Vector3d dt = run.T_base_lidar.translation() - run.T_base_lidar_truth.translation();
      const Eigen::Vector3d dr = LogSO3(run.T_base_lidar.linear() * run.T_base_lidar_truth.linear().transpose());
      for (int k = 0; k < 3; ++k) {
        axes[static_cast<std::size_t>(k)].push_back(100.0 * std::abs(dt[k]));
        axes[static_cast<std::size_t>(k + 3)].push_back(std::abs(dr[k]) * 180.0 / kPi);
      }
    }
    const auto spread = [](const std::vector<double>& v, int digits) {
      return fmt::format("{:.{}f} [{:.{}f}, {:.{}f}]", Quantile(v, 0.5), digits, Quantile(v, 0.25), digits,
                         Quantile(v, 0.75), digits);
    };
    table += fmt::format("| {} | {}/{} | {} | {} | {:.2f}, {:.2f}, {:.2f} | {:.3f}, {:.3f}, {:.3f} |\n", method,
                         translation.size(), attempted, spread(translation, 2), spread(rotation, 3),
                         Quantile(axes[0], 0.5), Quantile(axes[1], 0.5), Quantile(axes[2], 0.5),
                         Quantile(axes[3], 0.5), Quantile(axes[4], 0.5), Quantile(axes[5], 0.5));
  }
  return table;
}

// Checks the comma lists and option combinations; the reason in *why.
bool CheckArguments(const ExperimentArguments& args, std::string* why) {
  const auto unique = [](std::vector<std::string> v) {
    std::sort(v.begin(), v.end());
    return std::adjacent_find(v.begin(), v.end()) == v.end();
  };
  if (args.schemes.empty() || !unique(args.schemes)) {
    *why = "--schemes: give each of once, joint, alt at most once";
    return false;
  }
  if (args.metrics.empty() || !unique(args.metrics)) {
    *why = "--metrics: give each of nid, mi at most once";
    return false;
  }
  return true;
}

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The calibration options every run starts from; kExitInvalidInput (logged)
// when they are invalid.
int MakeRunOptions(const ExperimentArguments& args, CalibrationOptions* options) {
  ApplyCostArguments(args.cost, options);  // each run then sets its metric
  ApplyMotionCorrectionArguments(args.motion, options);
  options->nelder_mead.max_iterations = args.max_iterations;
  options->nelder_mead.initial_step_translation_m = 0.05;
  options->nelder_mead.initial_step_rotation_rad = RadiansFromDegrees(1.0);
  ParseLowerSolver(args.lower_solver, &options->lower_solver);
  if (options->lower_solver == LowerSolver::kLbfgs) {
    // Gradients exist only for the smooth (B-spline) histogram.
    options->cost.histogram.binning = Binning::kBSpline;
    options->gradient.initial_step_translation_m = options->nelder_mead.initial_step_translation_m;
    options->gradient.initial_step_rotation_rad = options->nelder_mead.initial_step_rotation_rad;
  }
  ApplyRunRadiusArguments(args.run_radius, options);
  options->threads = args.threads;
  options->seed = args.seed;
  if (!ParseStageSchedule(args.stages, &options->stages)) {
    spdlog::error("--stages: expected comma-separated SCALE[:BLUR[:RESTARTS]] entries, got '{}'", args.stages);
    return kExitInvalidInput;
  }
  std::string why;
  if (!options->IsValid(&why)) {
    spdlog::error("invalid options: {}", why);
    return kExitInvalidInput;
  }
  args.alternating.ApplyTo(&options->alternating);
  if (!AlternatingOptionsFor(*options).IsValid(&why)) {
    spdlog::error("invalid alt options: {}", why);
    return kExitInvalidInput;
  }
  return kExitSuccess;
}

// The experiment's dataset: where it is read from, and where it is once the
// experiment is done.
struct DatasetPlace {
  std::string path;
  std::string shown;
};

// Simulates --preset into staging/dataset, which becomes final_output/dataset
// at the end; records the simulation in *settings. kExitInvalidInput (logged)
// for a bad simulation.
int SimulateDataset(const ExperimentArguments& args, const std::filesystem::path& staging,
                    const std::filesystem::path& final_output, DatasetPlace* place,
                    std::map<std::string, std::string>* settings) {
  sim::SimulationOptions simulation;
  sim::ParsePreset(args.preset, &simulation.preset);
  simulation.seed = args.seed;
  simulation.distance_m = args.distance_m;
  simulation.overwrite = args.force;
  if (!args.image_size.empty()) ParseImageSize(args.image_size, &simulation.image_width, &simulation.image_height);
  std::string why;
  if (!simulation.IsValid(&why)) {
    spdlog::error("simulation: {}", why);
    return kExitInvalidInput;
  }
  io::CheckOutputFolder(final_output / "dataset", args.force);
  place->path = (staging / "dataset").string();
  place->shown = (final_output / "dataset").string();
  spdlog::info("simulating preset {} (seed {}, {} m, {}x{}) into {}", args.preset, args.seed, args.distance_m,
               simulation.image_width, simulation.image_height, place->shown);
  int last_percent = -10;
  const sim::SimulationSummary summary =
      sim::Simulate(simulation, place->path, [&](double fraction, const std::string& message) {
        const int percent = static_cast<int>(100.0 * fraction);
        if (percent >= last_percent + 10) {
          last_percent = percent;
          spdlog::info("simulate: {:3d}% {}", percent, message);
        }
      });
  spdlog::info("{}", summary.BriefReport());
  (*settings)["simulation"] = fmt::format("preset {}, seed {}, {} m, {}x{}", args.preset, args.seed, args.distance_m,
                                          simulation.image_width, simulation.image_height);
  return kExitSuccess;
}

// Fits the options to the dataset: the refresh border for these images,
// --setting (whether it fits the data) and calibrate's single-frame defaults,
// the last two recorded in *settings. kExitInvalidInput (logged) when the setting does
// not fit or the dataset lacks the truth of a lidar.
int FitToDataset(const ExperimentArguments& args, const io::Dataset& dataset, const std::string& dataset_shown,
                 CalibrationOptions* options, std::map<std::string, std::string>* settings) {
  if (!dataset.ground_truth) {
    spdlog::error("{}: the experiment compares with the truth and needs ground_truth.yaml", dataset_shown);
    return kExitInvalidInput;
  }
  options->cost.swathe.refresh_border_px = RefreshBorderPx(args.cost.refresh_border, dataset.rig);
  const AppliedConfiguration& applied = args.applied;
  if (!applied.setting.empty()) {
    const std::string misfit = DataMisfit(applied.requires_data, dataset.rig, dataset.trajectory.size());
    if (!misfit.empty()) {
      spdlog::error("--setting {} on {}: {}", applied.setting, dataset_shown, misfit);
      return kExitInvalidInput;
    }
    spdlog::info("--setting {}: {} (refresh border {:g} px)", applied.setting,
                 fmt::join(applied.setting_words, " "), options->cost.swathe.refresh_border_px);
    (*settings)["setting"] = fmt::format("{}: {}", applied.setting, fmt::join(applied.setting_words, " "));
  }
  const std::string single_frame_defaults = ApplySingleFrameDefaults(dataset, args.cost.BinsGiven(), options);
  if (!single_frame_defaults.empty()) {
    spdlog::info("single-frame 3D-lidar data: {}", single_frame_defaults);
    (*settings)["single_frame_defaults"] = single_frame_defaults;
  }
  for (const LidarInfo& lidar : dataset.rig.lidars) {
    if (dataset.ground_truth->T_base_lidar.find(lidar.name) == dataset.ground_truth->T_base_lidar.end()) {
      spdlog::error("{}: ground_truth.yaml has no T_base_lidar for lidar {}", dataset_shown, lidar.name);
      return kExitInvalidInput;
    }
  }
  return kExitSuccess;
}

using Guess = std::map<std::string, Eigen::Isometry3d>;  // per lidar: the initial T_base_lidar

// The guesses, per lidar: the truth moved by exactly the given magnitudes.
std::vector<Guess> DrawGuesses(const ExperimentArguments& args, const Rig& rig, const GroundTruth& truth) {
  std::mt19937_64 rng(args.seed);
  std::vector<Guess> guesses(static_cast<std::size_t>(args.guesses));
  for (auto& guess : guesses) {
    for (const LidarInfo& lidar : rig.lidars) {
      guess[lidar.name] =
          PerturbExactly(truth.T_base_lidar.at(lidar.name), args.perturb_translation_m, args.perturb_rotation_deg, rng);
    }
  }
  return guesses;
}

void SetGuess(const Guess& guess, Rig* rig) {
  for (LidarInfo& lidar : rig->lidars) lidar.T_base_lidar = guess.at(lidar.name);
}

// Every calibration's records (one per lidar), and the first guess's results
// per method for the overlays.
struct ExperimentRuns {
  std::vector<RunRecord> runs;
  std::map<std::string, std::map<std::string, Eigen::Isometry3d>> first_guess_results;  // method -> lidar -> result
  int done = 0;  // calibrations run
};

// Adds the records of one calibration from guess g (one per lidar of `rig`,
// which holds the guess) to *experiment; returns the summary for its log line.
std::string RecordCalibration(const CalibrationOutcome& outcome, const Rig& rig, const GroundTruth& truth, int g,
                              const std::string& scheme, const std::string& metric, double seconds,
                              ExperimentRuns* experiment) {
  int evaluations = 0;
  for (const OptimisationReport& optimisation : outcome.optimisations) evaluations += optimisation.evaluations;
  if (evaluations == 0 && outcome.alternating) evaluations = outcome.alternating->solved.total_evaluations;
  std::string summary;
  for (const LidarInfo& lidar : rig.lidars) {
    RunRecord run;
    run.guess = g;
    run.scheme = scheme;
    run.metric = metric;
    run.lidar = lidar.name;
    run.T_base_lidar_initial = lidar.T_base_lidar;
    run.T_base_lidar_truth = truth.T_base_lidar.at(lidar.name);
    run.evaluations = evaluations;
    run.seconds = seconds;
    run.termination = outcome.status == CalibrationStatus::kSuccess ? outcome.result.termination : outcome.why;
    for (const LidarCalibration& result : outcome.result.lidars) {
      if (result.lidar == lidar.name && outcome.status == CalibrationStatus::kSuccess) {
        run.success = true;
        run.T_base_lidar = result.T_base_lidar;
      }
    }
    double initial_sum = 0, final_sum = 0;
    int pairs = 0;
    for (const PairReport& pair : outcome.pairs) {
      if (pair.lidar != lidar.name) continue;
      initial_sum += pair.initial_cost;
      final_sum += pair.final_cost;
      ++pairs;
    }
    if (pairs > 0) {
      run.initial_cost = initial_sum / pairs;
      run.final_cost = final_sum / pairs;
    }
    if (run.success) {
      if (g == 0) experiment->first_guess_results[Method(scheme, metric)][lidar.name] = run.T_base_lidar;
      summary += fmt::format(" {}: {:.2f} cm, {:.3f} deg;", lidar.name,
                             100.0 * TranslationError(run.T_base_lidar, run.T_base_lidar_truth),
                             RotationErrorDegrees(run.T_base_lidar, run.T_base_lidar_truth));
    } else {
      summary += fmt::format(" {}: failed ({});", lidar.name, run.termination);
    }
    experiment->runs.push_back(std::move(run));
  }
  return summary;
}

// Calibrates with every scheme x metric from every guess (set in input->rig),
// and rewrites output/runs.csv after every calibration.
ExperimentRuns RunCalibrations(const ExperimentArguments& args, const CalibrationOptions& options,
                               const GroundTruth& truth, const std::vector<Guess>& guesses,
                               std::chrono::steady_clock::time_point start, const std::filesystem::path& output,
                               CalibrationInput* input) {
  const int total = args.guesses * static_cast<int>(args.schemes.size() * args.metrics.size());
  spdlog::info("{} runs: {} guesses x schemes {} x metrics {}; guesses {} m, {} deg from the truth (seed {})", total,
               args.guesses, fmt::join(args.schemes, ","), fmt::join(args.metrics, ","), args.perturb_translation_m,
               args.perturb_rotation_deg, args.seed);
  ExperimentRuns experiment;
  const double calibration_start_s = SecondsSince(start);
  for (int g = 0; g < args.guesses; ++g) {
    SetGuess(guesses[static_cast<std::size_t>(g)], &input->rig);
    for (const std::string& scheme : args.schemes) {
      for (const std::string& metric : args.metrics) {
        CalibrationOptions run_options = options;
        ParseCalibrationScheme(scheme, &run_options.scheme);
        run_options.cost.metric = *ParseMetricKind(metric);
        const auto run_start = std::chrono::steady_clock::now();
        const auto log_progress = [](const std::string& message) { spdlog::debug("{}", message); };
        const CalibrationOutcome outcome = Calibrate(*input, run_options, log_progress);
        const double seconds = SecondsSince(run_start);
        const std::string summary =
            RecordCalibration(outcome, input->rig, truth, g, scheme, metric, seconds, &experiment);
        const int done = ++experiment.done;
        const double spent_s = SecondsSince(start) - calibration_start_s;
        spdlog::log(outcome.status == CalibrationStatus::kSuccess ? spdlog::level::info : spdlog::level::warn,
                    "[{}/{}] guess {} {}:{} ({:.1f} s) | elapsed {}, about {} left", done, total, g + 1,
                    Method(scheme, metric), summary, seconds, FormatDuration(SecondsSince(start)),
                    FormatDuration(spent_s / done * (total - done)));
        // Written after every run (in the staging folder: a run that is
        // killed outright leaves it there, hidden beside OUTPUT, with what it measured).
        io::WriteFileAtomically((output / "runs.csv").string(), RunsCsv(experiment.runs));
      }
    }
  }
  return experiment;
}

// The report's methods, runs and settings (the overlays apart): Fig. 7 box
// plots, Fig. 8 per-DoF errors, the runs.
report::ExperimentReportData MakeReportData(const ExperimentArguments& args, const CalibrationOptions& options,
                                            const std::vector<RunRecord>& runs, const std::string& dataset_shown,
                                            const std::map<std::string, std::string>& settings,
                                            std::chrono::steady_clock::time_point start) {
  report::ExperimentReportData data;
  data.title = fmt::format("scenecal experiment: {} guesses x {} schemes x {} metrics", args.guesses,
                           args.schemes.size(), args.metrics.size());
  data.description = fmt::format(
      "Dataset {}. Each initial guess is the true T_base_lidar moved by exactly {} m and {} deg in random "
      "directions (seed {}); every scheme and metric starts from the same {} guesses. Errors are those of the "
      "calibrated T_base_lidar against ground_truth.yaml.",
      dataset_shown, args.perturb_translation_m, args.perturb_rotation_deg, args.seed, args.guesses);
  for (const std::string& scheme : args.schemes) {
    for (const std::string& metric : args.metrics) {
      data.methods.push_back(Method(scheme, metric));
      if (scheme == "alt") data.per_dof_methods.push_back(Method(scheme, metric));
    }
  }
  for (const RunRecord& run : runs) {
    report::ExperimentRun row = report::MakeExperimentRun(Method(run.scheme, run.metric), run.lidar, run.guess,
                                                          run.success ? run.T_base_lidar : run.T_base_lidar_initial,
                                                          run.T_base_lidar_truth, run.seconds, run.success,
                                                          run.termination);
    data.runs.push_back(row);
  }
  data.settings = settings;
  data.settings["dataset"] = dataset_shown;
  data.settings["guesses"] = fmt::format("{} ({} m, {} deg from the truth, seed {})", args.guesses,
                                         args.perturb_translation_m, args.perturb_rotation_deg, args.seed);
  data.settings["schemes"] = fmt::format("{}", fmt::join(args.schemes, ", "));
  data.settings["metrics"] = fmt::format("{}", fmt::join(args.metrics, ", "));
  data.settings["scenes per camera"] = args.cost.scenes;
  data.settings["swathe length"] = fmt::format("{} m", args.cost.swathe_length_m);
  const AlternatingArguments& alt = args.alternating;
  data.settings["alternations (alt)"] =
      std::to_string(alt.alternations) +
      (alt.stage_alternations > 0 ? ", the stages over the first " + std::to_string(alt.stage_alternations) : "") +
      "; penalty in the " + alt.penalty_frame + " frame; " + alt.schedule + " schedule";
  data.settings["lower solver"] = args.lower_solver + " (" + BinningName(options.cost.histogram.binning) + " binning)";
  if (options.lower_solver == LowerSolver::kLbfgs) {
    data.settings["L-BFGS iterations per run"] = std::to_string(options.gradient.max_iterations);
  } else {
    data.settings["Nelder-Mead iterations per stage"] = std::to_string(args.max_iterations);
  }
  data.settings["stages"] = args.stages;
  data.settings["wall time"] = FormatDuration(SecondsSince(start));
  return data;
}

// Overlays of the first guess: the headline method (alt-nid when run) per pair.
void AddOverlays(const ExperimentArguments& args, const CalibrationOptions& options, const ExperimentRuns& experiment,
                 const std::vector<Guess>& guesses, CalibrationInput* input, report::ExperimentReportData* data) {
  const auto& first_guess_results = experiment.first_guess_results;
  std::string overlay_method = data->methods.front();
  if (first_guess_results.count("alt-nid") != 0) overlay_method = "alt-nid";
  else if (!first_guess_results.empty() && first_guess_results.count(overlay_method) == 0)
    overlay_method = first_guess_results.begin()->first;
  if (args.overlay_scenes <= 0 || first_guess_results.count(overlay_method) == 0) return;
  SetGuess(guesses.front(), &input->rig);
  CalibrationOptions overlay_options = options;
  ParseCalibrationScheme(overlay_method.substr(0, overlay_method.find('-')), &overlay_options.scheme);
  overlay_options.cost.metric = *ParseMetricKind(overlay_method.substr(overlay_method.find('-') + 1));
  for (const auto& [lidar_name, T_base_lidar] : first_guess_results.at(overlay_method)) {
    const LidarInfo* lidar = input->rig.FindLidar(lidar_name);
    for (const CameraInfo& camera : input->rig.cameras) {
      PairCost cost = BuildPairCost(*input, camera, lidar_name, overlay_options);
      if (cost.Scenes().empty()) continue;
      const Eigen::Isometry3d T_camera_lidar_initial = camera.T_camera_base() * lidar->T_base_lidar;
      const Eigen::Isometry3d T_camera_lidar = camera.T_camera_base() * T_base_lidar;
      PreparePairForStage(cost, OptimisationStage{1.0, 0.0, 0}, T_camera_lidar);
      for (report::OverlayFigure& figure :
           report::MakePairOverlays(cost, T_camera_lidar_initial, T_camera_lidar,
                                    fmt::format("overlay_{}_{}_{}", overlay_method, camera.name, lidar_name),
                                    args.overlay_scenes)) {
        figure.title = overlay_method + ", guess 1: " + figure.title;
        data->overlays.push_back(std::move(figure));
      }
    }
  }
}

int RunExperiment(const ExperimentArguments& args) {
  const auto start = std::chrono::steady_clock::now();
  std::string why;
  if (!CheckArguments(args, &why)) {
    spdlog::error("{}", why);
    return kExitInvalidInput;
  }
  CalibrationOptions options;
  if (const int exit_code = MakeRunOptions(args, &options); exit_code != kExitSuccess) return exit_code;
  const auto thread_limit = LimitThreads(args.threads);

  // The dataset: given, or simulated into OUTPUT/dataset.
  io::CheckOutputFolderWritable(args.output, "--output");
  std::filesystem::path final_output = std::filesystem::absolute(args.output).lexically_normal();
  if (!final_output.has_filename()) final_output = final_output.parent_path();  // "out/" -> "out"
  // Everything is written into a hidden folder beside OUTPUT and moved into it
  // at the end: an interrupted or failed experiment leaves OUTPUT as it was
  // (its other files stay; dataset/, runs.csv, report.html ... are replaced).
  io::StagedOutput staged(final_output, "experiment");
  const std::filesystem::path& output = staged.Staging();
  DatasetPlace dataset_place{args.dataset, args.dataset};
  std::map<std::string, std::string> settings;
  if (dataset_place.path.empty()) {
    if (const int exit_code = SimulateDataset(args, output, final_output, &dataset_place, &settings);
        exit_code != kExitSuccess) {
      return exit_code;
    }
  } else if (!args.image_size.empty()) {
    spdlog::warn("--image-size applies to the simulation only; ignored with --dataset");
  }

  const io::Dataset dataset = io::OpenDataset(dataset_place.path);
  if (const int exit_code = FitToDataset(args, dataset, dataset_place.shown, &options, &settings);
      exit_code != kExitSuccess) {
    return exit_code;
  }
  const GroundTruth& truth = *dataset.ground_truth;
  CalibrationInput input;
  input.rig = dataset.rig;
  const LoadedScenes loaded = SelectAndLoadScenes(dataset, options.scenes, &input, args.cost.ImageChannel());
  spdlog::info("loaded {} images, {} scans, {} lidar points in {:.1f} s", loaded.images, loaded.scans,
               loaded.lidar_points, SecondsSince(start));

  const std::vector<Guess> guesses = DrawGuesses(args, dataset.rig, truth);
  const ExperimentRuns experiment = RunCalibrations(args, options, truth, guesses, start, output, &input);

  // The report: Fig. 7 box plots, Fig. 8 per-DoF errors, the runs, overlays.
  report::ExperimentReportData data =
      MakeReportData(args, options, experiment.runs, dataset_place.shown, settings, start);
  AddOverlays(args, options, experiment, guesses, &input, &data);
  report::WriteReportDirectory(output.string(), report::RenderExperimentReport(data),
                               report::ExperimentReportAttachments(data));
  spdlog::info("wrote {} and {} ({} runs, {})", (final_output / "runs.csv").string(),
               (final_output / "report.html").string(), experiment.done, FormatDuration(SecondsSince(start)));

  // A summary per method (Markdown) on stdout and in DIR/summary.md.
  const std::string summary = SummaryTable(experiment.runs, data.methods);
  fmt::print("{}", summary);
  io::WriteFileAtomically((output / "summary.md").string(), summary);
  // Every option as used: `scenecal experiment --config OUTPUT/options.yaml` repeats the experiment.
  YAML::Emitter options_yaml;
  options_yaml << io::OptionsYaml(RunOptions(args.command));
  io::WriteFileAtomically((output / "options.yaml").string(), std::string(options_yaml.c_str()) + "\n");
  staged.CommitEntries();
  bool any_success = false;
  for (const RunRecord& run : experiment.runs) any_success = any_success || run.success;
  if (!any_success) {
    spdlog::error("no run could be calibrated (see the termination column of {})",
                  (final_output / "runs.csv").string());
    return kExitFailure;
  }
  return kExitSuccess;
}

}  // namespace

CommandRunner AddExperimentCommand(CLI::App& app) {
  auto args = std::make_shared<ExperimentArguments>();
  CLI::App* command = app.add_subcommand(
      "experiment",
      "The paper's experiment (Fig. 7 and 8): calibrate from several perturbed initial guesses with every scheme\n"
      "and metric, compare with the ground truth, and write OUTPUT/runs.csv and OUTPUT/report.html.\n"
      "Simulates the dataset into OUTPUT/dataset unless --dataset is given. Exit 2 for bad options or input,\n"
      "1 when no run could be calibrated.");
  command->add_option("--preset", args->preset, "Simulated rig: robotcar (stereo + rear push-broom) or trinocular")
      ->check(CLI::IsMember({"robotcar", "trinocular"}))
      ->capture_default_str();
  command->add_option("--dataset", args->dataset,
                      "Use this dataset (docs/FORMAT.md, with ground_truth.yaml) instead of simulating one")
      ->check(CLI::ExistingDirectory);
  command->add_option("-o,--output", args->output,
                      "Output directory (runs.csv, report.html, options.yaml, PNGs, dataset/)")
      ->required()
      ->configurable(false);
  command->add_option("--seed", args->seed, "Seed of the simulation and of the guesses' random directions")
      ->capture_default_str();
  command->add_option("--guesses", args->guesses, "Initial guesses (trials) per scheme and metric")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  command->add_option("--perturb-translation", args->perturb_translation_m,
                      "Each guess is the truth moved by exactly this many metres in a random direction")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--perturb-rotation", args->perturb_rotation_deg,
                      "... and rotated by exactly this many degrees about a random axis")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--schemes", args->schemes, "Comma-separated schemes: once, joint, alt")
      ->delimiter(',')
      ->check(CLI::IsMember({"once", "joint", "alt"}))
      ->capture_default_str();
  command->add_option("--metrics", args->metrics, "Comma-separated metrics: nid, mi")
      ->delimiter(',')
      ->check(CLI::IsMember({"nid", "mi"}))
      ->capture_default_str();
  AddAlternatingOptions(command, &args->alternating);
  command->add_option("--threads", args->threads, "Worker threads; 0 = all hardware threads")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--image-size", args->image_size,
                      "Simulated image size WxH (default: the simulator's 1280x960)")
      ->check(kImageSize);
  command->add_option("--distance", args->distance_m, "Simulated drive length in metres")
      ->check(kPositive)
      ->capture_default_str();
  command->add_option("--max-iterations", args->max_iterations, "Nelder-Mead iterations per stage (the paper: 200)")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  command->add_option("--lower-solver", args->lower_solver,
                      "Local optimiser of every run, as calibrate's --lower-solver: simplex (Nelder-Mead, hard "
                      "binning) or lbfgs (analytic gradients; every run then uses B-spline binning)")
      ->check(CLI::IsMember({"simplex", "lbfgs"}))
      ->capture_default_str();
  command->add_option("--stages", args->stages,
                      "Coarse-to-fine schedule, as calibrate's --stages (SCALE[:BLUR[:RESTARTS]],...)")
      ->capture_default_str();
  AddRunRadiusOptions(command, &args->run_radius);
  command->add_option("--overlay-scenes", args->overlay_scenes,
                      "Scenes per camera/lidar pair shown as overlays (first guess, alt-nid when run); 0 = none")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  command->add_flag("--force", args->force, "Replace OUTPUT/dataset when simulating into a non-empty one");
  AddCostOptionsExceptMetric(command, &args->cost);
  AddMotionCorrectionOptions(command, &args->motion);
  AddConfigOptions(command, &args->config);
  args->command = command;
  return [args] {
    args->applied = ApplyConfiguration(args->command, args->config);
    return RunExperiment(*args);
  };
}

}  // namespace scenecal::cli
