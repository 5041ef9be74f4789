// `scenecal calibrate DATASET --output FILE [...]`: selects scenes from the
// file timestamps, loads only the images and scans they need, runs
// Calibrate (core/calibrate.hpp) and writes the result atomically. With
// ground truth in the dataset, prints the errors per lidar and per pair.
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include "cli/commands.hpp"
#include "core/calibrate.hpp"
#include "core/geometry.hpp"
#include "io/dataset.hpp"

namespace scenecal::cli {

namespace {

struct CalibrateArguments {
  std::string dataset;
  std::string output;
  std::string scheme = "joint";
  std::string metric = "nid";
  int scenes = 30;
  double swathe_length_m = 10.0;
  std::string direction = "forward";
  int bins = 32;
  std::string binning = "hard";
  std::string normalise_reflectance = "rank";
  std::string normalise_intensity = "none";
  int threads = 0;
  std::uint64_t seed = 1;
  double time_budget_s = 0.0;
  int max_iterations = 200;
  std::string stages = "1:0.004:2,0.3:0.0015:1,0.1:0:1";
  double step_translation_m = 0.05;
  double step_rotation_deg = 1.0;
  int min_points = 300;
  int max_scans_per_scene = 0;
  double min_speed_mps = 0.5;
  bool no_occlusion = false;
  std::string rotation_pivot = "origin";
  double perturb_translation_m = 0.0;
  double perturb_rotation_deg = 0.0;
  bool perturb_from_truth = false;
};

// Moves T by exactly translation_m and rotation_deg in random directions (base
// frame, left-multiplied) drawn from rng.
Eigen::Isometry3d Perturb(const Eigen::Isometry3d& T, double translation_m, double rotation_deg, std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  const auto random_unit = [&] {
    Eigen::Vector3d v;
    do {
      v = Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    } while (v.norm() < 1e-9);
    return Eigen::Vector3d(v.normalized());
  };
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
  offset.translation() = translation_m * random_unit();
  offset.linear() = ExpSO3(RadiansFromDegrees(rotation_deg) * random_unit());
  Eigen::Isometry3d moved = T;
  moved.linear() = offset.linear() * T.linear();
  moved.translation() = T.translation() + offset.translation();
  return moved;
}

// Errors of an estimate against the truth, FORMAT.md plus per axis:
// translation t_est - t_gt (cm) and the roll/pitch/yaw of R_est * R_gt^T
// (deg), i.e. the rotation error expressed in the transform's target frame.
std::string ErrorLine(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& truth) {
  const Eigen::Vector3d dt = (estimate.translation() - truth.translation()) * 100.0;
  const Eigen::Vector3d drpy = RollPitchYawFromRotation(estimate.linear() * truth.linear().transpose()) * 180.0 / kPi;
  return fmt::format(
      "translation {:.4f} m, rotation {:.3f} deg | dx {:+.2f} dy {:+.2f} dz {:+.2f} cm | droll {:+.3f} dpitch "
      "{:+.3f} dyaw {:+.3f} deg",
      TranslationError(estimate, truth), RotationErrorDegrees(estimate, truth), dt.x(), dt.y(), dt.z(), drpy.x(),
      drpy.y(), drpy.z());
}

// "SCALE[:BLUR[:RESTARTS]],..." -> stages; false when malformed.
bool ParseStages(const std::string& text, std::vector<OptimisationStage>* stages) {
  stages->clear();
  std::istringstream entries(text);
  for (std::string entry; std::getline(entries, entry, ',');) {
    std::istringstream fields(entry);
    std::vector<std::string> parts;
    for (std::string part; std::getline(fields, part, ':');) parts.push_back(part);
    if (parts.empty() || parts.size() > 3) return false;
    OptimisationStage stage;
    try {
      std::size_t used = 0;
      stage.step_scale = std::stod(parts[0], &used);
      if (used != parts[0].size()) return false;
      if (parts.size() > 1) {
        stage.blur_fraction = std::stod(parts[1], &used);
        if (used != parts[1].size()) return false;
      }
      if (parts.size() > 2) {
        stage.restarts = std::stoi(parts[2], &used);
        if (used != parts[2].size()) return false;
      }
    } catch (const std::exception&) {
      return false;
    }
    stages->push_back(stage);
  }
  return !stages->empty();
}

int Run(const CalibrateArguments& args) {
  const auto start = std::chrono::steady_clock::now();
  CalibrationOptions options;
  // Arguments already checked by CLI11 validators; parse into the enums.
  ParseCalibrationScheme(args.scheme, &options.scheme);
  options.cost.metric = *ParseMetricKind(args.metric);
  options.cost.histogram.reflectance_bins = args.bins;
  options.cost.histogram.intensity_bins = args.bins;
  options.cost.histogram.binning = *ParseBinning(args.binning);
  options.cost.min_points_per_scene = args.min_points;
  options.cost.swathe.occlusion = !args.no_occlusion;
  options.pivot_at_observed_centroid = args.rotation_pivot == "centroid";
  options.normalisation.reflectance = *ParseNormalisation(args.normalise_reflectance);
  options.normalisation.intensity = *ParseNormalisation(args.normalise_intensity);
  options.scenes.scenes_per_camera = args.scenes;
  options.scenes.swathe_length_m = args.swathe_length_m;
  ParseSwatheDirection(args.direction, &options.scenes.direction);
  options.scenes.max_scans_per_scene = args.max_scans_per_scene;
  options.scenes.min_speed_mps = args.min_speed_mps;
  options.nelder_mead.max_iterations = args.max_iterations;
  options.nelder_mead.initial_step_translation_m = args.step_translation_m;
  options.nelder_mead.initial_step_rotation_rad = RadiansFromDegrees(args.step_rotation_deg);
  if (!ParseStages(args.stages, &options.stages)) {
    spdlog::error("--stages: expected comma-separated SCALE[:BLUR[:RESTARTS]] entries, got '{}'", args.stages);
    return kExitInvalidInput;
  }
  options.threads = args.threads;
  options.seed = args.seed;
  options.time_budget_s = args.time_budget_s;
  std::string why;
  if (!options.IsValid(&why)) {
    spdlog::error("invalid options: {}", why);
    return kExitInvalidInput;
  }
  if (options.scheme == CalibrationScheme::kAlt) {
    spdlog::error("--scheme alt is not available in this build; use once or joint");
    return kExitInvalidInput;
  }
  std::optional<tbb::global_control> thread_limit;
  if (args.threads > 0) {
    thread_limit.emplace(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(args.threads));
  }

  spdlog::info("opening {}", args.dataset);
  const io::Dataset dataset = io::OpenDataset(args.dataset);

  std::map<std::string, std::vector<TimeUs>> image_times, scan_times;
  for (const auto& [camera, files] : dataset.images) {
    for (const io::SensorFile& f : files) image_times[camera].push_back(f.t_us);
  }
  for (const auto& [lidar, files] : dataset.scans) {
    for (const io::SensorFile& f : files) scan_times[lidar].push_back(f.t_us);
  }
  CalibrationInput input;
  input.rig = dataset.rig;
  if (args.perturb_from_truth && !dataset.ground_truth) {
    spdlog::error("--perturb-from-truth needs ground_truth.yaml in {}", args.dataset);
    return kExitInvalidInput;
  }
  if (args.perturb_translation_m > 0.0 || args.perturb_rotation_deg > 0.0 || args.perturb_from_truth) {
    std::mt19937_64 rng(args.seed);
    for (LidarInfo& lidar : input.rig.lidars) {
      Eigen::Isometry3d base_guess = lidar.T_base_lidar;
      if (args.perturb_from_truth) {
        const auto truth = dataset.ground_truth->T_base_lidar.find(lidar.name);
        if (truth == dataset.ground_truth->T_base_lidar.end()) {
          spdlog::error("--perturb-from-truth: ground_truth.yaml has no T_base_lidar for lidar {}", lidar.name);
          return kExitInvalidInput;
        }
        base_guess = truth->second;
      }
      lidar.T_base_lidar = Perturb(base_guess, args.perturb_translation_m, args.perturb_rotation_deg, rng);
      spdlog::info("lidar {}: initial guess = {} moved by {} m and {} deg (seed {})", lidar.name,
                   args.perturb_from_truth ? "the truth" : "rig.yaml's guess", args.perturb_translation_m,
                   args.perturb_rotation_deg, args.seed);
    }
  }
  input.selection = SelectScenes(dataset.rig, dataset.trajectory, image_times, scan_times, options.scenes);
  std::istringstream report(input.selection.Report());
  for (std::string line; std::getline(report, line);) spdlog::info("{}", line);

  // Load only what the scenes use, in parallel.
  std::vector<std::pair<std::string, const io::SensorFile*>> image_files, scan_files;
  {
    std::set<std::pair<std::string, TimeUs>> images_needed, scans_needed;
    for (const Scene& scene : input.selection.scenes) {
      images_needed.insert({scene.camera, scene.image_t_us});
      for (const SwatheScan& scan : scene.scans) scans_needed.insert({scene.lidar, scan.t_us});
    }
    const auto find = [](const std::vector<io::SensorFile>& files, TimeUs t) {
      const auto it = std::lower_bound(files.begin(), files.end(), t,
                                       [](const io::SensorFile& f, TimeUs time) { return f.t_us < time; });
      return it != files.end() && it->t_us == t ? &*it : nullptr;
    };
    for (const auto& [camera, t] : images_needed) image_files.push_back({camera, find(dataset.images.at(camera), t)});
    for (const auto& [lidar, t] : scans_needed) scan_files.push_back({lidar, find(dataset.scans.at(lidar), t)});
  }
  spdlog::info("loading {} images and {} scans", image_files.size(), scan_files.size());
  std::vector<GreyImage> images(image_files.size());
  std::vector<LidarScan> scans(scan_files.size());
  tbb::parallel_for(std::size_t{0}, image_files.size(), [&](std::size_t i) {
    images[i] = io::ReadImage(*image_files[i].second, dataset.rig.FindCamera(image_files[i].first)->model);
  });
  tbb::parallel_for(std::size_t{0}, scan_files.size(), [&](std::size_t i) { scans[i] = io::ReadScan(*scan_files[i].second); });
  for (std::size_t i = 0; i < images.size(); ++i) {
    input.images[image_files[i].first][image_files[i].second->t_us] = std::move(images[i]);
  }
  std::size_t points = 0;
  for (std::size_t i = 0; i < scans.size(); ++i) {
    points += scans[i].points.size();
    input.scans[scan_files[i].first][scan_files[i].second->t_us] = std::move(scans[i]);
  }
  const double load_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  spdlog::info("loaded {} lidar points in {:.2f} s", points, load_s);

  spdlog::info("calibrating: scheme {}, metric {}, {} bins {}, reflectance {}, stages {}, up to {} iterations a run",
               args.scheme, args.metric, args.bins, args.binning, args.normalise_reflectance, args.stages,
               args.max_iterations);
  CalibrationOutcome outcome = Calibrate(input, options, [](const std::string& message) { spdlog::info("{}", message); });
  if (outcome.status == CalibrationStatus::kInvalidOptions) {
    spdlog::error("{}", outcome.why);
    return kExitInvalidInput;
  }
  if (outcome.status == CalibrationStatus::kCannotCalibrate) {
    spdlog::error("the data cannot be calibrated: {}", outcome.why);
    return kExitFailure;
  }
  for (const PairReport& pair : outcome.pairs) {
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
  CalibrationResult& result = outcome.result;
  result.timings_s["load"] = load_s;
  if (args.perturb_translation_m > 0.0 || args.perturb_rotation_deg > 0.0 || args.perturb_from_truth) {
    result.settings["perturb_initial"] =
        fmt::format("{} m, {} deg, seed {}, from {}", args.perturb_translation_m, args.perturb_rotation_deg, args.seed,
                    args.perturb_from_truth ? "truth" : "rig.yaml");
  }
  result.timings_s["total"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  for (const std::string& warning : result.warnings) spdlog::warn("{}", warning);
  io::WriteCalibrationResult(args.output, result);
  spdlog::info("wrote {} ({})", args.output, result.termination);

  if (dataset.ground_truth) {
    const GroundTruth& truth = *dataset.ground_truth;
    for (const LidarCalibration& lidar : result.lidars) {
      const auto gt = truth.T_base_lidar.find(lidar.lidar);
      if (gt == truth.T_base_lidar.end()) continue;
      const LidarInfo* initial = input.rig.FindLidar(lidar.lidar);
      fmt::print("lidar {} T_base_lidar error: {}\n", lidar.lidar, ErrorLine(lidar.T_base_lidar, gt->second));
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
  return kExitSuccess;
}

}  // namespace

CommandRunner AddCalibrateCommand(CLI::App& app) {
  auto args = std::make_shared<CalibrateArguments>();
  CLI::App* command = app.add_subcommand(
      "calibrate",
      "Calibrate every lidar of DATASET against its cameras (targetless, from the drive) and write FILE.\n"
      "Exit 1 with the reason when the data cannot be calibrated; 2 for bad arguments or input data.");
  command->add_option("dataset", args->dataset, "Dataset folder (FORMAT.md)")->required()->check(CLI::ExistingDirectory);
  command->add_option("-o,--output", args->output, "Result file (YAML, written atomically)")->required();
  command->add_option("--scheme", args->scheme,
                      "once: each camera/lidar pair alone; joint: one problem per lidar over T_base_lidar, the "
                      "cost summed over all cameras through the known camera transforms")
      ->check(CLI::IsMember({"once", "joint", "alt"}))
      ->capture_default_str();
  command->add_option("--metric", args->metric, "nid (normalised information distance) or mi (mutual information)")
      ->check(CLI::IsMember({"nid", "mi"}))
      ->capture_default_str();
  command->add_option("--scenes", args->scenes, "Camera frames (scenes) per camera, spread over the drive by distance")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  command->add_option("--swathe-length", args->swathe_length_m,
                      "Swathe length L in metres: the scans taken while the vehicle travels L m")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_option("--direction", args->direction,
                      "Swathe window: forward (the L m after the frame), backward (before), both (L m each side)")
      ->check(CLI::IsMember({"forward", "backward", "both"}))
      ->capture_default_str();
  command->add_option("--bins", args->bins, "Histogram bins per variable (reflectance and intensity)")
      ->check(CLI::Range(2, 512))
      ->capture_default_str();
  command->add_option("--binning", args->binning, "hard (one bin per sample) or bspline (cubic B-spline Parzen window)")
      ->check(CLI::IsMember({"hard", "bspline"}))
      ->capture_default_str();
  command->add_option("--normalise", args->normalise_reflectance,
                      "Mapping of lidar reflectance to [0, 1] per scene: none, minmax (1st..99th percentile), rank "
                      "(histogram equalisation)")
      ->check(CLI::IsMember({"none", "minmax", "rank"}))
      ->capture_default_str();
  command->add_option("--normalise-intensity", args->normalise_intensity,
                      "Mapping of image intensity to [0, 1] per image: none, minmax, rank")
      ->check(CLI::IsMember({"none", "minmax", "rank"}))
      ->capture_default_str();
  command->add_option("--threads", args->threads, "Worker threads; 0 = all hardware threads")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_option("--seed", args->seed,
                      "Seed of the random directions of --perturb-translation/--perturb-rotation (the calibration "
                      "itself is deterministic)")
      ->capture_default_str();
  command->add_option("--perturb-translation", args->perturb_translation_m,
                      "Robustness studies: move each lidar's initial guess by exactly this many metres in a random "
                      "direction (from --seed) before calibrating")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_option("--perturb-rotation", args->perturb_rotation_deg,
                      "Robustness studies: rotate each lidar's initial guess by exactly this many degrees about a "
                      "random axis (from --seed)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_option("--time-budget", args->time_budget_s,
                      "Wall-clock budget of the optimisation in seconds; 0 = none. The best point so far is kept.")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_option("--max-iterations", args->max_iterations, "Nelder-Mead iterations per stage")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  command->add_option("--stages", args->stages,
                      "Coarse-to-fine schedule, comma-separated SCALE[:BLUR[:RESTARTS]] per stage: SCALE multiplies "
                      "the initial simplex steps, BLUR is the image blur (Gaussian sigma as a fraction of the image "
                      "width), RESTARTS the extra Nelder-Mead runs while the cost still improves. Images and "
                      "visibility are refreshed before each stage. '1' = one plain run (the paper).")
      ->capture_default_str();
  command->add_option("--step-translation", args->step_translation_m, "Initial simplex step, metres (first stage)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_option("--step-rotation", args->step_rotation_deg, "Initial simplex step, degrees (first stage)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_option("--min-points", args->min_points,
                      "Projected points a scene needs to count (scenes with fewer are ignored)")
      ->check(CLI::Range(1, 100000000))
      ->capture_default_str();
  command->add_option("--max-scans-per-scene", args->max_scans_per_scene,
                      "Cap on scans per swathe (evenly thinned); 0 = no cap")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_option("--min-speed", args->min_speed_mps, "Frames taken below this speed (m/s) are skipped")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_flag("--perturb-from-truth", args->perturb_from_truth,
                    "Robustness studies: start from ground_truth.yaml's T_base_lidar (moved by --perturb-*) instead "
                    "of rig.yaml's guess");
  command->add_flag("--no-occlusion", args->no_occlusion, "Disable the z-buffer occlusion test");
  command->add_option("--rotation-pivot", args->rotation_pivot,
                      "Point the simplex rotates the lidar about: origin (the lidar's origin) or centroid (the "
                      "centroid of the lidar points seen at the initial guess)")
      ->check(CLI::IsMember({"origin", "centroid"}))
      ->capture_default_str();
  return [args] { return Run(*args); };
}

}  // namespace scenecal::cli
