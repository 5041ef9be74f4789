// The options that define a pair's cost (scenes, swathes, lidar range,
// histogram, metric, normalisation, image channel, occlusion), shared by
// `calibrate` and `profile` so both build exactly the same cost from the same
// command-line words; and two steps every data command starts with (the
// thread cap, opening the dataset with the single-frame defaults).
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <tbb/global_control.h>

#include "core/calibrate.hpp"
#include "core/number_text.hpp"
#include "io/dataset.hpp"

namespace scenecal::cli {

// The core's defaults: every option below starts from them (and --help shows them).
inline const CalibrationOptions kCoreDefaults{};

struct CostArguments {
  std::string metric = MetricKindName(kCoreDefaults.cost.metric);
  std::string scenes = std::to_string(kCoreDefaults.scenes.scenes_per_camera);  // a count, or "auto"
  std::string scene_choice = SceneChoiceName(kCoreDefaults.scenes.choice);
  int scene_pool = kCoreDefaults.scenes.informative_pool_factor;
  int scene_choice_after = kCoreDefaults.scenes.informative_after_stages;
  double swathe_length_m = kCoreDefaults.scenes.swathe_length_m;
  std::string direction = SwatheDirectionName(kCoreDefaults.scenes.direction);
  int bins = kCoreDefaults.cost.histogram.reflectance_bins;
  std::string binning = BinningName(kCoreDefaults.cost.histogram.binning);
  std::string normalise_reflectance = NormalisationName(kCoreDefaults.normalisation.reflectance);
  std::string normalise_intensity = NormalisationName(kCoreDefaults.normalisation.intensity);
  double image_highpass = kCoreDefaults.normalisation.intensity_highpass_width_fraction;  // of the image width; 0 = off
  std::string image_channel = "grey";  // io::ImageChannel: grey | exg
  int min_points = kCoreDefaults.cost.min_points_per_scene;
  int max_scans_per_scene = kCoreDefaults.scenes.max_scans_per_scene;
  double swathe_trim_margin_m = kCoreDefaults.swathe_trim_margin_m;
  double min_speed_mps = kCoreDefaults.scenes.min_speed_mps;
  double odometry_scale_percent = 100.0 * kCoreDefaults.scenes.odometry_scale;  // a known scale error of the odometry
  bool no_occlusion = !kCoreDefaults.cost.swathe.occlusion;
  int occlusion_cell_px = kCoreDefaults.cost.swathe.occlusion_cell_px;  // 0 = automatic (image width / 80)
  // Hidden if depth > nearest * (1 + relative) + absolute.
  double occlusion_relative_margin = kCoreDefaults.cost.swathe.occlusion_relative_margin;
  double occlusion_absolute_margin_m = kCoreDefaults.cost.swathe.occlusion_absolute_margin_m;
  // Pixels, or N% of the widest image (RefreshBorderPx).
  std::string refresh_border = NumberText(kCoreDefaults.cost.swathe.refresh_border_px);
  double blur_px_per_point_stride = kCoreDefaults.cost.swathe.blur_px_per_point_stride;  // 0 = every point
  double min_range_m = kCoreDefaults.cost.swathe.min_range_m;  // lidar points nearer than this (lidar frame) are dropped
  double max_range_m = kCoreDefaults.cost.swathe.max_range_m;  // and farther than this
  double range_split_m = kCoreDefaults.range_split_m;          // 0 = one histogram per scene
  int thin = kCoreDefaults.thin_max_points_per_cell;           // points kept per crowded image cell; 0 = off
  int thin_cell_px = kCoreDefaults.thin_cell_px;
  double thin_margin_px = kCoreDefaults.thin_margin_px;
  // Set by AddCostOptions; after parsing, count() > 0 when given on the command line.
  CLI::Option* bins_option = nullptr;
  CLI::Option* binning_option = nullptr;
  CLI::Option* normalise_intensity_option = nullptr;

  bool BinsGiven() const { return bins_option != nullptr && bins_option->count() > 0; }
  bool BinningGiven() const { return binning_option != nullptr && binning_option->count() > 0; }
  io::ImageChannel ImageChannel() const;
};

// Registers the cost options on `command` (values validated by CLI11).
void AddCostOptions(CLI::App* command, CostArguments* args);
// The same without --metric, for a command that runs several metrics.
void AddCostOptionsExceptMetric(CLI::App* command, CostArguments* args);

// Copies the parsed cost options into `options` (metric, histogram, swathe,
// occlusion, normalisation, scene selection, trimming); the refresh border
// follows the images (RefreshBorderPx, once the dataset is open). With the excess-green
// channel the image intensity is rank-normalised unless --normalise-intensity
// was given (its values crowd a narrow band of [0, 1]).
void ApplyCostArguments(const CostArguments& args, CalibrationOptions* options);

// How far one L-BFGS run may move from its start (GradientSolverOptions' run
// radii), for calibrate and experiment alike.
struct RunRadiusArguments {
  double translation_m = kCoreDefaults.gradient.run_radius_translation_m;
  double rotation_deg = DegreesFromRadians(kCoreDefaults.gradient.run_radius_rotation_rad);
};
void AddRunRadiusOptions(CLI::App* command, RunRadiusArguments* args);
void ApplyRunRadiusArguments(const RunRadiusArguments& args, CalibrationOptions* options);

// The alt scheme's options (CalibrationOptions::alternating), with the core's
// defaults; angles in degrees as the command line takes them. For calibrate
// and experiment alike.
struct AlternatingArguments {
  int alternations = kCoreDefaults.alternating.max_alternations;
  int stage_alternations = kCoreDefaults.alternating.stage_alternations;
  double shrink = kCoreDefaults.alternating.covariance_shrink;
  std::string penalty_frame = PenaltyFrameName(kCoreDefaults.alternating.penalty_frame);
  // Not given: by the lower solver (the paper's 5 m / 5 rad with the simplex, looser with lbfgs).
  std::optional<double> sigma0_translation_m;
  std::optional<double> sigma0_rotation_rad;
  std::string schedule = kCoreDefaults.alternating.skip_settled ? "adaptive" : "fixed";
  double stop_translation_m = kCoreDefaults.alternating.stop_translation_m;
  double stop_rotation_deg = DegreesFromRadians(kCoreDefaults.alternating.stop_rotation_rad);
  double camera_sigma_translation_m = kCoreDefaults.alternating.default_camera_sigma_translation_m;
  double camera_sigma_rotation_deg = DegreesFromRadians(kCoreDefaults.alternating.default_camera_sigma_rotation_rad);

  void ApplyTo(AlternatingSettings* settings) const {
    settings->max_alternations = alternations;
    settings->stage_alternations = stage_alternations;
    settings->covariance_shrink = shrink;
    ParsePenaltyFrame(penalty_frame, &settings->penalty_frame);  // the CLI checked the name
    settings->initial_sigma_translation_m = sigma0_translation_m.value_or(0.0);
    settings->initial_sigma_rotation_rad = sigma0_rotation_rad.value_or(0.0);
    settings->stop_translation_m = stop_translation_m;
    settings->stop_rotation_rad = RadiansFromDegrees(stop_rotation_deg);
    settings->skip_settled = schedule == "adaptive";
    settings->default_camera_sigma_translation_m = camera_sigma_translation_m;
    settings->default_camera_sigma_rotation_rad = RadiansFromDegrees(camera_sigma_rotation_deg);
  }
};
// Registers the alt options on `command` (values validated by CLI11).
void AddAlternatingOptions(CLI::App* command, AlternatingArguments* alt);

// The per-frame drift correction of `calibrate` (CalibrationOptions::motion_correction).
struct MotionCorrectionArguments {
  std::vector<std::string> terms;  // of turn, scale, roll, drive-scale; empty = off
  int first_stage = kCoreDefaults.motion_correction_first_stage;
  double max_scale_percent = 100.0 * kCoreDefaults.motion.max_scale;
  double max_rate_deg_per_m = DegreesFromRadians(kCoreDefaults.motion.max_rate_rad_per_m);
};
void AddMotionCorrectionOptions(CLI::App* command, MotionCorrectionArguments* args);
void ApplyMotionCorrectionArguments(const MotionCorrectionArguments& args, CalibrationOptions* options);
// --refresh-border in pixels: the value, or N% of the rig's widest image.
double RefreshBorderPx(const std::string& text, const Rig& rig);

// Caps TBB's worker threads at `threads` while the returned object lives;
// nothing (no cap) for 0 = all hardware threads.
std::unique_ptr<tbb::global_control> LimitThreads(int threads);

// Sets the refresh border for the dataset's images (RefreshBorderPx) and
// applies the single-frame defaults for the options the user did not set
// (ApplySingleFrameDefaults; logged and returned in *single_frame_defaults,
// "" when none).
void ApplyDatasetDefaults(const io::Dataset& dataset, const CostArguments& args, CalibrationOptions* options,
                          std::string* single_frame_defaults);

// Opens the dataset at `path` (logged), then ApplyDatasetDefaults. Throws io::InputError.
io::Dataset OpenDatasetWithDefaults(const std::string& path, const CostArguments& args, CalibrationOptions* options,
                                    std::string* single_frame_defaults);

}  // namespace scenecal::cli
