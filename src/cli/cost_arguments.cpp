#include "cli/cost_arguments.hpp"

#include <algorithm>
#include <cmath>

#include <spdlog/spdlog.h>

#include "cli/load_input.hpp"
#include "cli/validators.hpp"
#include "core/geometry.hpp"

namespace scenecal::cli {

namespace {

// Which scans make up a scene (the frames, the swathe window).
void AddSceneOptions(CLI::App* command, CostArguments* args) {
  command
      ->add_option("--scenes", args->scenes,
                   "Camera frames (scenes) per camera: a count (spread over the drive by distance unless "
                   "--scene-choice informative; where fewer frames have a whole swathe, a 3d lidar fills the count "
                   "with frames taken standing or near the drive's ends, one per place), or auto: of " +
                       std::to_string(kCoreDefaults.scenes.scenes_per_camera) +
                       " frames spread by distance, the informative choice keeps the fewest (at least " +
                       std::to_string(kCoreDefaults.scenes.min_auto_scenes) + ") whose predicted variance is within " +
                       NumberText(kAutoSceneVarianceRatio) +
                       "x of all of them (experimental: on the RobotCar-like drive 11-14 frames ended 0.26 cm / "
                       "0.126 deg from the truth, median, against 0.13 cm / 0.088 deg with 30 spread ones; "
                       "BENCHMARK.md, \"Informative scenes\")")
      ->check(CLI::Validator(
          [](std::string& input) -> std::string {
            if (input == "auto") return {};
            std::size_t used = 0;
            long value = 0;
            try {
              value = std::stol(input, &used);
            } catch (const std::exception&) {
              used = 0;
            }
            return used == input.size() && !input.empty() && value >= 1 && value <= 100000
                       ? std::string()
                       : input + " is not a count within 1..100000 or auto";
          },
          "COUNT|auto"))
      ->capture_default_str();
  command
      ->add_option("--scene-choice", args->scene_choice,
                   "How the --scenes frames are chosen: spread (evenly by distance, the paper) or informative (a pool "
                   "of --scene-pool times as many frames is built, spread by distance; the first --scene-choice-after "
                   "stages run on the whole pool, then each camera keeps the frames whose image edges and reflectance "
                   "steps constrain the extrinsic most at their answer, covering its weakest directions first, never "
                   "two neighbouring frames while others are left; --scenes auto implies informative). At 15 frames "
                   "it lowered the median translation error of 15 spread frames by 62 % on the RobotCar-like drive "
                   "and both errors of the trinocular rear lidar by a third, but raised the front lidar's translation "
                   "error by 39 %: experimental (BENCHMARK.md, \"Informative scenes\")")
      ->check(CLI::IsMember({"spread", "informative"}))
      ->capture_default_str();
  command
      ->add_option("--scene-pool", args->scene_pool,
                   "informative with a --scenes count: the pool holds this many times --scenes frames per camera, "
                   "spread by distance (each is loaded and its swathe built once)")
      ->check(CLI::Range(1, 20))
      ->capture_default_str();
  command
      ->add_option("--scene-choice-after", args->scene_choice_after,
                   "informative, schemes once and joint: the first this many stages of --stages run on every frame of "
                   "the pool and the informative frames are chosen at their answer (at most all stages but the last); "
                   "0 chooses at the initial guess, as alt always does. Chosen at the initial guess, 12-15 frames lost "
                   "the basin on a trinocular world (57 cm / 18 deg off); after the first stage none did. With a 3D "
                   "lidar, unless given: before the last stage (after the first, one simulated spin3d world of three "
                   "ended 16-38 cm off)")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  command->add_option("--swathe-length", args->swathe_length_m,
                      "Swathe length L in metres: the scans taken while the vehicle travels L m")
      ->check(kPositive)
      ->capture_default_str();
  command->add_option("--direction", args->direction,
                      "Swathe window: forward (the L m after the frame), backward (before), both (L m each side)")
      ->check(CLI::IsMember({"forward", "backward", "both"}))
      ->capture_default_str();
}

// The joint histogram and what the images and the reflectance contribute to it.
// --bins, --binning and --normalise-intensity have automatic defaults (their
// help says which): no default string, so that a result records them only
// when they were set, and --config RESULT chooses them again the same way.
void AddHistogramOptions(CLI::App* command, CostArguments* args) {
  args->bins_option =
      command
          ->add_option("--bins", args->bins,
                       "Histogram bins per variable (reflectance and intensity). Default: 32, but " +
                           std::to_string(kSingleFrameBins) +
                           " on single-frame 3D-lidar data (a static dataset, e.g. from import opencalib)")
          ->check(CLI::Range(2, 512));
  args->binning_option =
      command
          ->add_option("--binning", args->binning,
                       "hard (one bin per sample) or bspline (cubic B-spline Parzen window, smooth). Default: hard, "
                       "but bspline with --lower-solver lbfgs")
          ->check(CLI::IsMember({"hard", "bspline"}));
  command->add_option("--normalise", args->normalise_reflectance,
                      "Mapping of lidar reflectance to [0, 1] per scene: none, minmax (1st..99th percentile), rank "
                      "(histogram equalisation)")
      ->check(CLI::IsMember({"none", "minmax", "rank"}))
      ->capture_default_str();
  args->normalise_intensity_option =
      command
          ->add_option("--normalise-intensity", args->normalise_intensity,
                       "Mapping of image intensity to [0, 1] per image: none, minmax, rank. Default: none, but rank "
                       "with --image-channel exg")
          ->check(CLI::IsMember({"none", "minmax", "rank"}));
  command->add_option("--image-highpass", args->image_highpass,
                      "Subtract each image's local mean (Gaussian, sigma = this fraction of the image width) before "
                      "scoring, so the texture and edges count and not the brightness of whole regions, whose "
                      "relation to the lidar's infrared reflectance differs by material; 0 = off. Only in the "
                      "stages without blur (the blurred coarse stages keep the whole image). With the recommended "
                      "push-broom setting and exact odometry 0.0234 (30 px at 1280) took the median rotation error "
                      "from 0.14-0.31 to 0.03-0.11 deg; with drifting odometry it made things worse (docs/findings.md)")
      ->check(CLI::Range(0.0, 0.5))
      ->capture_default_str();
  command->add_option("--image-channel", args->image_channel,
                      "What the images contribute: grey (their grey level) or exg (excess green 2G-R-B of colour "
                      "images: vegetation, bright in the lidar's near infrared but dark in grey, becomes bright; "
                      "for real street scenes with trees and hedges; colour images only)")
      ->check(CLI::IsMember({"grey", "exg"}))
      ->capture_default_str();
}

// Which scenes count and which of their scans are kept; the trajectory's scale.
void AddScanSelectionOptions(CLI::App* command, CostArguments* args) {
  command->add_option("--min-points", args->min_points,
                      "Projected points a scene needs to count (scenes with fewer are ignored)")
      ->check(CLI::Range(1, 100000000))
      ->capture_default_str();
  command->add_option("--max-scans-per-scene", args->max_scans_per_scene,
                      "Cap on scans per swathe (evenly thinned); 0 = no cap")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--swathe-trim", args->swathe_trim_margin_m,
                      "Keep only the scans of a swathe whose points reach the image at the initial guess, plus this "
                      "margin (metres of travel) either side; negative keeps every scan of the window")
      ->capture_default_str();
  command
      ->add_option("--min-speed", args->min_speed_mps,
                   "Frames taken below this speed (m/s) have no swathe: a 2d lidar skips them, a 3d lidar uses them "
                   "only to fill --scenes (the scan nearest the image and the travel that follows)")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--odometry-scale", args->odometry_scale_percent,
                      "A known scale error of the trajectory, in percent: its distances are taken as (1 + P / 100) "
                      "x what it says (e.g. 0.3 when visual odometry reports them 0.3 % short, from GNSS or a "
                      "measured drive). The images cannot tell a scale error from a shift of the lidar along the "
                      "travel: each 0.1 % moves a push-broom lidar's estimate 1.3-1.7 cm on the simulated drive "
                      "(docs/findings.md, \"The drive's scale is invisible to the images\")")
      ->check(CLI::Range(-19.9, 19.9))
      ->capture_default_str();
}

// Which projected points are scored: the z-buffer occlusion test and the image border.
void AddVisibilityOptions(CLI::App* command, CostArguments* args) {
  command->add_flag("--no-occlusion", args->no_occlusion, "Disable the z-buffer occlusion test");
  command->add_option("--occlusion-cell", args->occlusion_cell_px,
                      "Z-buffer cell in pixels (a point is hidden when a point of its cell is nearer by the "
                      "margin); 0 = image width / 80. Larger cells hide more of what is truly occluded between "
                      "sparse points, but also the far part of a road seen at a grazing angle")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--occlusion-margin", args->occlusion_relative_margin,
                      "Z-buffer: a point is hidden when its depth exceeds the cell's nearest by this fraction plus "
                      "--occlusion-margin-abs")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--occlusion-margin-abs", args->occlusion_absolute_margin_m,
                      "Z-buffer: the absolute part of the margin, metres")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--refresh-border", args->refresh_border,
                      "Score only the points at least this many pixels inside the image where visibility is "
                      "refreshed (each stage): a fixed set instead of points entering and leaving at the border, so "
                      "the cost is the smooth function L-BFGS's analytic gradient describes; N% is N percent of the "
                      "widest image's width; 0 = off. Part of the push-broom presets with --lower-solver lbfgs and "
                      "30 m swathes (3.75%: 48 px at 1280). With 10 m swathes it was better on one simulated world "
                      "and worse on two, with the simplex mixed (docs/findings.md, \"Tried and not kept\")")
      ->check(kPixelsOrPercent)
      ->capture_default_str();
  command->add_option("--coarse-point-stride", args->blur_px_per_point_stride,
                      "A blurred stage (--stages) scores every k-th point, k = the blur's sigma in pixels / this "
                      "(rounded down; 0 = every point). At 8 the push-broom setting's first stage (25.6 px at 1280) "
                      "scores every third point: the trinocular calibration 48 s -> 36 s at the same errors, but one "
                      "of 15 starts 30 cm / 10 deg off lost the basin (BENCHMARK.md)")
      ->check(kNonNegative)
      ->capture_default_str();
}

// Which lidar points are kept (range, thinning) and how a scene's points are split.
void AddPointSelectionOptions(CLI::App* command, CostArguments* args) {
  command->add_option("--min-range", args->min_range_m,
                      "Lidar points nearer than this many metres to the lidar are dropped (the vehicle's body, "
                      "spray); must be below --max-range")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--max-range", args->max_range_m, "Lidar points farther than this many metres are dropped")
      ->check(kPositive)
      ->capture_default_str();
  command->add_option("--range-split", args->range_split_m,
                      "Score each scene's lidar points nearer and farther than this many metres from the lidar as "
                      "two scenes (each its own joint histogram), so the few far returns weigh as much as the many "
                      "near ones; 0 = off")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--thin", args->thin,
                      "Thin crowded swathes: project each scene's points at the initial guess into cells of "
                      "--thin-cell pixels and keep about this many per cell (far scans of long swathes pile onto "
                      "few pixels); points more than --thin-margin pixels outside the image are dropped; 0 = off")
      ->check(CLI::Range(0, 1000000))
      ->capture_default_str();
  command->add_option("--thin-cell", args->thin_cell_px, "Cell size of --thin (pixels)")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  command->add_option("--thin-margin", args->thin_margin_px,
                      "With --thin, points projecting farther than this many pixels outside the image at the "
                      "initial guess are dropped (keep it above the pixel motion the guess's error allows)")
      ->check(CLI::Range(0.0, 100000.0))
      ->capture_default_str();
}

}  // namespace

void AddCostOptions(CLI::App* command, CostArguments* args) {
  command->add_option("--metric", args->metric, "nid (normalised information distance) or mi (mutual information)")
      ->check(CLI::IsMember({"nid", "mi"}))
      ->capture_default_str();
  AddCostOptionsExceptMetric(command, args);
}

void AddCostOptionsExceptMetric(CLI::App* command, CostArguments* args) {
  AddSceneOptions(command, args);
  AddHistogramOptions(command, args);
  AddScanSelectionOptions(command, args);
  AddVisibilityOptions(command, args);
  AddPointSelectionOptions(command, args);
}

io::ImageChannel CostArguments::ImageChannel() const {
  io::ImageChannel channel = io::ImageChannel::kGrey;
  io::ParseImageChannel(image_channel, &channel);  // validated by CLI11
  return channel;
}

void ApplyCostArguments(const CostArguments& args, CalibrationOptions* options) {
  // Values already checked by CLI11 validators; parse into the enums.
  options->cost.metric = *ParseMetricKind(args.metric);
  options->cost.histogram.reflectance_bins = args.bins;
  options->cost.histogram.intensity_bins = args.bins;
  options->cost.histogram.binning = *ParseBinning(args.binning);
  options->cost.min_points_per_scene = args.min_points;
  options->cost.swathe.occlusion = !args.no_occlusion;
  options->cost.swathe.occlusion_cell_px = args.occlusion_cell_px;
  options->cost.swathe.occlusion_relative_margin = args.occlusion_relative_margin;
  options->cost.swathe.occlusion_absolute_margin_m = args.occlusion_absolute_margin_m;
  options->cost.swathe.blur_px_per_point_stride = args.blur_px_per_point_stride;
  options->cost.swathe.min_range_m = args.min_range_m;
  options->cost.swathe.max_range_m = args.max_range_m;
  options->range_split_m = args.range_split_m;
  options->thin_max_points_per_cell = args.thin;
  options->thin_cell_px = args.thin_cell_px;
  options->thin_margin_px = args.thin_margin_px;
  options->normalisation.reflectance = *ParseNormalisation(args.normalise_reflectance);
  options->normalisation.intensity = *ParseNormalisation(args.normalise_intensity);
  options->normalisation.intensity_highpass_width_fraction = args.image_highpass;
  const bool intensity_given = args.normalise_intensity_option != nullptr && args.normalise_intensity_option->count() > 0;
  if (args.ImageChannel() == io::ImageChannel::kExcessGreen && !intensity_given) {
    options->normalisation.intensity = Normalisation::kRank;
  }
  ParseSceneChoice(args.scene_choice, &options->scenes.choice);
  options->scenes.informative_pool_factor = args.scene_pool;
  options->scenes.informative_after_stages = args.scene_choice_after;
  if (args.scenes == "auto") {
    // The pool is the paper's spread set; the data choose how many of it to keep.
    options->scenes.scenes_per_camera = kCoreDefaults.scenes.scenes_per_camera;
    options->scenes.informative_pool_factor = 1;
    options->scenes.choice = SceneChoice::kInformative;
    options->scenes.auto_variance_ratio = kAutoSceneVarianceRatio;
  } else {
    options->scenes.scenes_per_camera = std::stoi(args.scenes);  // checked by --scenes' validator
  }
  options->scenes.swathe_length_m = args.swathe_length_m;
  ParseSwatheDirection(args.direction, &options->scenes.direction);
  options->scenes.max_scans_per_scene = args.max_scans_per_scene;
  options->swathe_trim_margin_m = args.swathe_trim_margin_m;
  options->scenes.min_speed_mps = args.min_speed_mps;
  options->scenes.odometry_scale = args.odometry_scale_percent / 100.0;
}

double RefreshBorderPx(const std::string& text, const Rig& rig) {
  if (text.empty() || text.back() != '%') return std::stod(text);  // checked by kPixelsOrPercent
  int widest_px = 0;
  for (const CameraInfo& camera : rig.cameras) widest_px = std::max(widest_px, camera.model.width);
  return std::round(std::stod(text.substr(0, text.size() - 1)) / 100.0 * widest_px);
}

std::unique_ptr<tbb::global_control> LimitThreads(int threads) {
  if (threads <= 0) return nullptr;
  return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                               static_cast<std::size_t>(threads));
}

io::Dataset OpenDatasetWithDefaults(const std::string& path, const CostArguments& args, CalibrationOptions* options,
                                    std::string* single_frame_defaults) {
  spdlog::info("opening {}", path);
  io::Dataset dataset = io::OpenDataset(path);
  ApplyDatasetDefaults(dataset, args, options, single_frame_defaults);
  return dataset;
}

void ApplyDatasetDefaults(const io::Dataset& dataset, const CostArguments& args, CalibrationOptions* options,
                          std::string* single_frame_defaults) {
  options->cost.swathe.refresh_border_px = RefreshBorderPx(args.refresh_border, dataset.rig);
  *single_frame_defaults = ApplySingleFrameDefaults(dataset, args.BinsGiven(), options);
  if (!single_frame_defaults->empty()) spdlog::info("single-frame 3D-lidar data: {}", *single_frame_defaults);
}

void AddMotionCorrectionOptions(CLI::App* command, MotionCorrectionArguments* args) {
  command->add_option("--motion-correction", args->terms,
                      "Correct each camera frame's swathe for odometry drift, for long swathes (--swathe-length 30) "
                      "from drifting odometry: the terms to estimate, a comma list of turn (rates across the "
                      "travel: heading and pitch), scale (of the distance travelled) and roll (rate about the "
                      "travel), each frame's from its own cost, and drive-scale (one scale for the whole drive, "
                      "from all frames' costs together; weakly determined: the images hardly tell a scale error "
                      "from the lidar's position along the travel, so give a known scale with --odometry-scale "
                      "instead); at the current estimate, before each stage from --motion-correction-from-stage "
                      "on (every scheme; alt: before the first alternation of each stage, at the upper estimates, "
                      "shared by the lower levels and by every lidar's swathes of a frame: the drift is the "
                      "trajectory's). Off when not given")
      ->delimiter(',')
      ->check(CLI::IsMember({"turn", "scale", "roll", "drive-scale"}));
  command->add_option("--motion-correction-from-stage", args->first_stage,
                      "First coarse-to-fine stage (0-based) before which the drift correction is estimated (from "
                      "the first, the guess's own error is taken for drift)")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  command->add_option("--motion-max-scale", args->max_scale_percent,
                      "Bound on the drift correction's scale (percent of the distance travelled)")
      ->check(CLI::Range(0.01, 20.0))
      ->capture_default_str();
  command->add_option("--motion-max-rate", args->max_rate_deg_per_m,
                      "Bound on each of the drift correction's rates (degrees per metre travelled)")
      ->check(CLI::Range(0.0005, 1.0))
      ->capture_default_str();
}

void ApplyMotionCorrectionArguments(const MotionCorrectionArguments& args, CalibrationOptions* options) {
  const auto has_term = [&](const char* term) {
    return std::find(args.terms.begin(), args.terms.end(), term) != args.terms.end();
  };
  options->motion_correction = !args.terms.empty();
  options->motion.scale = has_term("scale");
  options->motion.turn = has_term("turn");
  options->motion.roll = has_term("roll");
  options->motion.drive_scale = has_term("drive-scale");
  options->motion_correction_first_stage = args.first_stage;
  options->motion.max_scale = args.max_scale_percent / 100.0;
  options->motion.max_rate_rad_per_m = RadiansFromDegrees(args.max_rate_deg_per_m);
  // The simplex's first steps stay inside the bounds.
  options->motion.initial_step_scale = std::min(options->motion.initial_step_scale, options->motion.max_scale);
  options->motion.initial_step_rate_rad_per_m =
      std::min(options->motion.initial_step_rate_rad_per_m, options->motion.max_rate_rad_per_m);
}

void AddRunRadiusOptions(CLI::App* command, RunRadiusArguments* args) {
  command->add_option("--run-radius-translation", args->translation_m,
                      "--lower-solver lbfgs: how far (metres) one run may move the estimate from where it started; "
                      "beyond it a smooth wall adds to the cost. Far from the truth a blurred stage is nearly flat "
                      "and its line search can step metres, to poses that project few points and score well; the "
                      "wall keeps each run near its start while the schedule's runs together move further. 0 = no "
                      "limit (--setting push-broom sets 0.3)")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--run-radius-rotation", args->rotation_deg,
                      "--lower-solver lbfgs: the same for the rotation (degrees, below 180; 0 = no limit, "
                      "--setting push-broom sets 6)")
      ->check(kNonNegative)
      ->capture_default_str();
}

void ApplyRunRadiusArguments(const RunRadiusArguments& args, CalibrationOptions* options) {
  options->gradient.run_radius_translation_m = args.translation_m;
  options->gradient.run_radius_rotation_rad = RadiansFromDegrees(args.rotation_deg);
}

// The alt scheme's options (the alternations, the penalty).
void AddAlternatingOptions(CLI::App* command, AlternatingArguments* alt) {
  command->add_option("--alternations", alt->alternations, "alt: maximum number of alternations (the paper: 20)")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  command->add_option("--stage-alternations", alt->stage_alternations,
                      "alt: spread the coarse-to-fine stages (--stages) over the first N alternations; the "
                      "rest stay in the sharp stage and only tighten the penalty until the two levels agree "
                      "(0: over all). With --alternations 40 --stage-alternations 20 and the adaptive schedule "
                      "of the push-broom settings the levels settled below the stop thresholds after 12-17 "
                      "alternations (schedule positions 27-30) on the simulated drives (docs/findings.md)")
      ->check(CLI::Range(0, 10000))
      ->capture_default_str();
  command->add_option("--alternation-schedule", alt->schedule,
                      "alt: fixed (the paper: each alternation takes one penalty step and its share of the stages) "
                      "or adaptive (an alternation in which both levels moved less than 10 x the stop thresholds, "
                      "times how many times the last stage's steps its stage's are (--stages 1:..,0.1:..: 10 x in "
                      "the first), is not repeated: the run goes on at the next stage, or in the last stage "
                      "tightens the penalty two steps; the push-broom presets)")
      ->check(CLI::IsMember({"fixed", "adaptive"}))
      ->capture_default_str();
  command->add_option("--shrink", alt->shrink, "alt: covariance factor w of the penalty, P(i+1) = w P(i), in (0, 1)")
      ->check(CLI::Range(1e-6, 0.999999))
      ->capture_default_str();
  command->add_option("--penalty-frame", alt->penalty_frame,
                      "alt: where the penalty's sigmas hold: lidar (the lidar's position and its turn about its own "
                      "origin) or camera (the camera-frame difference itself, where a turn of a lidar metres away "
                      "also pays its lever-arm shift at the translation sigma and is held back)")
      ->check(CLI::IsMember({"lidar", "camera"}))
      ->capture_default_str();
  command->add_option("--sigma0-translation", alt->sigma0_translation_m,
                      "alt: initial penalty sigma, metres. Default: 5 (the paper) with the simplex lower level, 500 "
                      "with --lower-solver lbfgs, whose lower levels the paper's value already holds near the upper "
                      "estimate where the cost is flat (docs/findings.md, \"The alternating scheme's penalty holds "
                      "in the lidar frame\")")
      ->check(kPositive);
  command->add_option("--sigma0-rotation", alt->sigma0_rotation_rad,
                      "alt: initial penalty sigma, radians. Default: 5 (the paper) with the simplex, 500 with "
                      "--lower-solver lbfgs")
      ->check(kPositive);
  command->add_option("--stop-translation", alt->stop_translation_m,
                      "alt: stop early once both levels move, and disagree, by less than this many metres (and "
                      "--stop-rotation)")
      ->check(kNonNegative)
      ->capture_default_str();
  command
      ->add_option("--stop-rotation", alt->stop_rotation_deg, "alt: the rotation threshold of the early stop, degrees")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--camera-sigma-translation", alt->camera_sigma_translation_m,
                      "alt: 1-sigma of known camera transforms that rig.yaml gives no T_base_camera_sigma for, metres")
      ->check(kNonNegative)
      ->capture_default_str();
  command->add_option("--camera-sigma-rotation", alt->camera_sigma_rotation_deg,
                      "alt: the same for rotation, degrees")
      ->check(kNonNegative)
      ->capture_default_str();
}

}  // namespace scenecal::cli
