// `scenecal simulate`: writes a simulated street dataset (FORMAT.md) with ground truth.
#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "cli/commands.hpp"
#include "cli/validators.hpp"
#include "io/output_path.hpp"
#include "sim/simulator.hpp"

namespace scenecal::cli {
namespace {

struct SimulateArguments {
  std::string preset = "robotcar";
  std::string output;
  std::string image_size;
  bool no_stop = false;
  bool no_shadows = false;
  std::vector<std::string> drift_parts{"scale-bias", "scale-waves", "rates"};
  sim::SimulationOptions options;
};

}  // namespace

CommandRunner AddSimulateCommand(CLI::App& app) {
  auto args = std::make_shared<SimulateArguments>();
  sim::SimulationOptions& o = args->options;
  CLI::App* cmd = app.add_subcommand(
      "simulate",
      "Generate a simulated street drive (cameras, lidars, drifting odometry, ground truth) as a dataset.");
  cmd->add_option("--preset", args->preset, "Sensor rig: robotcar | trinocular | spin3d")
      ->check(CLI::IsMember({"robotcar", "trinocular", "spin3d"}))
      ->capture_default_str();
  cmd->add_option("--seed", o.seed, "Seed of the world, the drive and every noise")->capture_default_str();
  cmd->add_option("--output", args->output, "Dataset directory to create (must be empty or absent)")->required();
  auto* duration = cmd->add_option("--duration", o.duration_s, "Drive for this many seconds (instead of --distance)");
  cmd->add_option("--distance", o.distance_m, "Drive this many metres")->capture_default_str()->excludes(duration);
  cmd->add_option("--speed", o.speed_mps, "Mean speed (m/s)")->capture_default_str();
  cmd->add_option("--image-rate", o.image_rate_hz, "Images per second per camera (Hz)")->capture_default_str();
  cmd->add_option("--image-size", args->image_size, "Image size WxH (intrinsics scale from 1280x960)")
      ->check(kImageSize)
      ->default_str("1280x960");
  cmd->add_option("--perturb-translation", o.perturb_translation_m,
                  "Initial guess in rig.yaml = truth moved by this much (m), per lidar")
      ->capture_default_str();
  cmd->add_option("--perturb-rotation", o.perturb_rotation_deg,
                  "Initial guess in rig.yaml = truth rotated by this much (deg), per lidar")
      ->capture_default_str();
  cmd->add_option("--odometry-noise", o.odometry_noise,
                  "Scale of the odometry drift in trajectory.csv (0: true motion, 1: ~0.5% and ~0.01 deg/m)")
      ->capture_default_str();
  cmd->add_option("--odometry-drift", args->drift_parts,
                  "Which parts of the odometry drift to simulate, a comma list of scale-bias (one scale error for "
                  "the whole drive), scale-waves (its wander along the drive) and rates (heading and pitch rate "
                  "errors); the parts left out are zero and the others are exactly those of the whole drift (to "
                  "study what each part does to a calibration)")
      ->delimiter(',')
      ->check(CLI::IsMember({"scale-bias", "scale-waves", "rates"}))
      ->default_str("scale-bias,scale-waves,rates");
  cmd->add_option("--camera-perturb-translation", o.camera_perturb_translation_m,
                  "Make the known inter-camera transforms in rig.yaml wrong by this much (m)")
      ->capture_default_str();
  cmd->add_option("--camera-perturb-rotation", o.camera_perturb_rotation_deg,
                  "Make the known inter-camera transforms in rig.yaml wrong by this much (deg)")
      ->capture_default_str();
  cmd->add_option("--lidar-rate", o.lidar_2d_rate_hz, "Scan rate of push-broom (2d) lidars (Hz)")->capture_default_str();
  cmd->add_option("--lidar-3d-rate", o.lidar_3d_rate_hz, "Sweep rate of the spinning (3d) lidar (Hz)")
      ->capture_default_str();
  cmd->add_option("--spin-azimuth-step", o.spin_azimuth_step_deg, "Azimuth step of the spinning lidar (deg)")
      ->capture_default_str();
  cmd->add_flag("--no-stop", args->no_stop, "Drive without the short stop");
  cmd->add_flag("--no-shadows", args->no_shadows, "Render without cast shadows (faster)");
  cmd->add_flag("--ideal-reflectance", o.ideal_reflectance,
                "Lidar reflectance from the surface alone, without its fall-off with the incidence angle and the "
                "range (to test what those trends do to a calibration)");
  cmd->add_option("--vignetting", o.render.vignetting,
                  "Relative fall-off of the image brightness at the corners (0: none)")
      ->check(CLI::Range(0.0, 0.9))
      ->capture_default_str();
  cmd->add_flag("--force", o.overwrite, "Replace the output directory if it is not empty");

  return [args]() -> int {
    sim::SimulationOptions options = args->options;
    sim::ParsePreset(args->preset, &options.preset);
    options.include_stop = !args->no_stop;
    options.render.shadows = !args->no_shadows;
    const auto has_part = [&](const char* part) {
      return std::find(args->drift_parts.begin(), args->drift_parts.end(), part) != args->drift_parts.end();
    };
    options.odometry_drift_parts = {has_part("scale-bias"), has_part("scale-waves"), has_part("rates")};
    if (!args->image_size.empty()) ParseImageSize(args->image_size, &options.image_width, &options.image_height);
    std::string why;
    if (!options.IsValid(&why)) {
      spdlog::error("simulate: {}", why);
      return kExitInvalidInput;
    }
    io::CheckOutputFolderWritable(args->output, "--output");
    spdlog::info("simulate: preset {}, seed {}, output {}", args->preset, options.seed, args->output);
    const sim::SimulationSummary summary =
        sim::Simulate(options, args->output, [](double fraction, const std::string& message) {
          spdlog::info("simulate: {:5.1f}% {}", 100.0 * fraction, message);
        });
    std::printf("%s\n", summary.BriefReport().c_str());
    return kExitSuccess;
  };
}

}  // namespace scenecal::cli
