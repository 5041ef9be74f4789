#include "cli/setting.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

namespace scenecal::cli {

namespace {

constexpr double kSwatheLengthM = 30.0;
constexpr double kRangeSplitM = 6.0;
constexpr double kThinPointsPerCell = 2.0;
constexpr double kRefreshBorderFraction = 0.0375;  // of the image width: 48 px at 1280
constexpr double kHighpassFraction = 0.0234;       // of the image width: 30 px at 1280
// At most; alt stops by itself once its levels have settled (26 left them 0.018 deg apart with a known
// inter-camera transform 0.05 deg off: BENCHMARK.md, "The alternating scheme against once and joint").
constexpr double kAlternations = 40.0;
constexpr double kStageAlternations = 20.0;

SettingOption Number(const char* name, double value) { return {name, fmt::format("{:g}", value), value}; }

}  // namespace

bool GivenOnCommandLine(const CLI::App* command, const std::string& name) {
  const CLI::Option* option = command == nullptr ? nullptr : command->get_option_no_throw(name);
  return option != nullptr && option->count() > 0;
}

const std::vector<std::string>& SettingNames() {
  static const std::vector<std::string> names{"push-broom", "push-broom-drifting"};
  return names;
}

std::vector<SettingOption> SettingOptions(const std::string& setting, bool with_alt, bool odometry_scale_given) {
  const std::vector<std::string>& names = SettingNames();
  if (std::find(names.begin(), names.end(), setting) == names.end()) return {};
  std::vector<SettingOption> options{Number("--swathe-length", kSwatheLengthM),
                                     Number("--range-split", kRangeSplitM),
                                     Number("--thin", kThinPointsPerCell),
                                     {"--lower-solver", "lbfgs"}};
  if (setting == "push-broom-drifting") {
    // The drift misplaces the texture: no high-pass; each frame's swathe re-posed instead, with one
    // scale for the whole drive unless it is given (the images hardly measure it: BENCHMARK.md,
    // "RobotCar, drifting odometry"; docs/findings.md, "The drive's scale is invisible to the images").
    options.push_back({"--motion-correction", odometry_scale_given ? "turn" : "turn,drive-scale"});
  } else {
    options.push_back(Number("--image-highpass", kHighpassFraction));
  }
  if (with_alt) {
    options.push_back(Number("--alternations", kAlternations));
    options.push_back(Number("--stage-alternations", kStageAlternations));
  }
  return options;
}

double SettingRefreshBorderPx(const Rig& rig) {
  int widest_px = 0;
  for (const CameraInfo& camera : rig.cameras) widest_px = std::max(widest_px, camera.model.width);
  return std::round(kRefreshBorderFraction * widest_px);
}

std::string SettingMisfit(const Rig& rig, std::size_t trajectory_poses) {
  const char* why = !rig.HasPushBroomLidar() ? "no push-broom lidar (rig.yaml: no lidar of kind 2d)"
                    : trajectory_poses < 2     ? "a single-pose trajectory"
                                               : nullptr;
  if (why == nullptr) return "";
  return fmt::format("the data have {}; the setting is for swathes that a moving 2D (push-broom) lidar builds over a "
                     "drive (on single frames its fixed point sets and L-BFGS run away: BENCHMARK.md)",
                     why);
}

std::string SettingHelp() {
  // Written from the lists above, so that the help says what the settings do.
  const auto typed = [](const std::vector<SettingOption>& options) {
    std::string words;
    for (const SettingOption& option : options) words += (words.empty() ? "" : " ") + option.name + " " + option.value;
    return words;
  };
  const auto only_in = [](const std::vector<SettingOption>& a, const std::vector<SettingOption>& b) {
    std::vector<SettingOption> left;
    for (const SettingOption& option : a) {
      const auto same_name = [&](const SettingOption& other) { return other.name == option.name; };
      if (std::none_of(b.begin(), b.end(), same_name)) left.push_back(option);
    }
    return left;
  };
  const std::vector<SettingOption> good = SettingOptions("push-broom", false);
  const std::vector<SettingOption> drifting = SettingOptions("push-broom-drifting", false);
  return fmt::format(
      "A named bundle of options measured together; any of them given on the command line keeps its own value. "
      "push-broom (a moving 2D lidar, good odometry: RTK-INS, lidar odometry): {}, --refresh-border {:g} % of the "
      "widest image ({:g} px at 1280), and for the alt scheme {}. push-broom-drifting (visual odometry, ~0.01 "
      "deg/m): the same with {} instead of {} ({} when --odometry-scale gives the drive's scale). Recorded in "
      "the result's settings (README, \"What to expect\")",
      typed(good), 100.0 * kRefreshBorderFraction, std::round(kRefreshBorderFraction * 1280.0),
      typed(only_in(SettingOptions("push-broom", true), good)), typed(only_in(drifting, good)),
      typed(only_in(good, drifting)),
      typed(only_in(SettingOptions("push-broom-drifting", false, true), good)));
}

}  // namespace scenecal::cli
