// `scenecal profile DATASET --output FILE.csv [--at truth|guess|RESULT]`:
// samples the calibration cost along each of the six degrees of freedom
// through one extrinsic, for every lidar's joint cost (T_base_lidar, base
// frame axes) and every (camera, lidar) pair's cost (T_camera_lidar, camera
// frame axes). Each DoF moves the lidar's origin along an axis or turns the
// lidar about its origin (core/nelder_mead.hpp kAboutSourcePoint), the same
// decomposition as calibrate's error lines (dx dy dz droll dpitch dyaw).
//
// What it answers: where the cost's minimum lies relative to the centre (at
// the truth of a simulated dataset: the bias of the cost itself, apart from
// any optimiser), and how sharply the data constrain each direction.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "cli/commands.hpp"
#include "cli/cost_arguments.hpp"
#include "cli/load_input.hpp"
#include "cli/validators.hpp"
#include "core/calibrate.hpp"
#include "core/geometry.hpp"
#include "core/interrupt.hpp"
#include "core/nelder_mead.hpp"
#include "io/dataset.hpp"
#include "io/error.hpp"
#include "io/output_path.hpp"

namespace scenecal::cli {

namespace {

struct ProfileArguments {
  std::string dataset;
  std::string output;
  std::string at = "truth";
  std::string lidar;  // empty = every lidar
  std::string toward;  // empty = no line profile
  bool per_scene = false;
  std::string costs = "all";
  double half_range_translation_m = 0.05;
  double half_range_rotation_deg = 0.5;
  int samples = 41;
  double blur_fraction = 0.0;
  int threads = 0;
  CostArguments cost;
};

// The six DoF, then the line toward --toward (offset s: 0 at the centre, 1 at the target).
const char* const kDofNames[7] = {"x", "y", "z", "roll", "pitch", "yaw", "line"};
constexpr int kLine = 6;
constexpr double kLineFirst = -1.0, kLineLast = 2.0;

// Where a sampled profile is lowest: the lowest sample, refined by a least
// squares parabola through the samples within `half_window` of it (the hard
// binned cost is piecewise constant, so one sample alone is noisy).
struct ProfileMinimum {
  double sample_offset = 0.0;   // offset of the lowest sample
  double fitted_offset = std::numeric_limits<double>::quiet_NaN();  // vertex of the parabola; NaN if not convex
  double rise = 0.0;            // mean of the two end samples minus the lowest sample
};

ProfileMinimum FindMinimum(const std::vector<double>& offsets, const std::vector<double>& costs, int half_window) {
  ProfileMinimum minimum;
  std::size_t best = offsets.size();
  for (std::size_t i = 0; i < costs.size(); ++i) {
    if (std::isfinite(costs[i]) && (best == offsets.size() || costs[i] < costs[best])) best = i;
  }
  if (best == offsets.size()) {
    minimum.sample_offset = std::numeric_limits<double>::quiet_NaN();
    minimum.rise = std::numeric_limits<double>::quiet_NaN();
    return minimum;
  }
  minimum.sample_offset = offsets[best];
  minimum.rise = 0.5 * (costs.front() + costs.back()) - costs[best];
  const std::size_t first = best >= static_cast<std::size_t>(half_window) ? best - half_window : 0;
  const std::size_t last = std::min(offsets.size() - 1, best + half_window);
  std::vector<std::size_t> used;
  for (std::size_t i = first; i <= last; ++i) {
    if (std::isfinite(costs[i])) used.push_back(i);
  }
  if (used.size() < 3) return minimum;
  // Fit c = a u^2 + b u + c0 in u = (offset - sample_offset) / step for conditioning.
  const double step = offsets.size() > 1 ? offsets[1] - offsets[0] : 1.0;
  Eigen::MatrixXd A(used.size(), 3);
  Eigen::VectorXd y(used.size());
  for (std::size_t r = 0; r < used.size(); ++r) {
    const double u = (offsets[used[r]] - minimum.sample_offset) / step;
    A.row(static_cast<Eigen::Index>(r)) << u * u, u, 1.0;
    y(static_cast<Eigen::Index>(r)) = costs[used[r]];
  }
  const Eigen::Vector3d coefficients = A.colPivHouseholderQr().solve(y);
  if (coefficients(0) > 0.0) {
    const double vertex_u = -coefficients(1) / (2.0 * coefficients(0));
    if (std::abs(vertex_u) <= half_window) minimum.fitted_offset = minimum.sample_offset + vertex_u * step;
  }
  return minimum;
}

// A calibrate result when `spec` is a path, nothing for "truth", "guess" or "".
std::optional<CalibrationResult> ReadResultIfPath(const std::string& spec) {
  if (spec.empty() || spec == "truth" || spec == "guess") return std::nullopt;
  return io::ReadCalibrationResult(spec);
}

// T_base_lidar of `lidar` in the extrinsics named by spec: "truth"
// (ground_truth.yaml), "guess" (rig.yaml) or a result (read into `result`).
std::optional<Eigen::Isometry3d> FindExtrinsic(const std::string& spec, const io::Dataset& dataset,
                                               const std::optional<CalibrationResult>& result,
                                               const LidarInfo& lidar) {
  if (spec == "guess") return lidar.T_base_lidar;
  if (spec == "truth") {
    if (!dataset.ground_truth) return std::nullopt;
    const auto found = dataset.ground_truth->T_base_lidar.find(lidar.name);
    if (found == dataset.ground_truth->T_base_lidar.end()) return std::nullopt;
    return found->second;
  }
  const auto found = std::find_if(result->lidars.begin(), result->lidars.end(),
                                  [&](const LidarCalibration& l) { return l.lidar == lidar.name; });
  if (found == result->lidars.end()) return std::nullopt;
  return found->T_base_lidar;
}

struct Profile {
  std::string name;   // "joint LIDAR" or "CAMERA/LIDAR"
  std::string frame;  // frame of the axes
  std::array<std::vector<double>, 7> costs;  // per DoF, then the line (empty without --toward)
  bool in_summary = true;                    // printed in the summary table (not the --per-scene curves)
};

// Offsets as written: metres, degrees, or the line's fraction.
double WrittenOffset(int dof, double offset) { return dof >= 3 && dof < kLine ? DegreesFromRadians(offset) : offset; }

// Where every profile is sampled: the same offsets along each DoF, then along
// the line toward --toward.
class DofSampler {
 public:
  explicit DofSampler(const ProfileArguments& args)
      : args_(args), samples_(args.samples | 1), dofs_(args.toward.empty() ? 6 : 7) {}

  int samples() const { return samples_; }  // per DoF: odd, so the centre itself is sampled
  int dofs() const { return dofs_; }        // the six, and the line with --toward

  // The offsets along a DoF: metres (x, y, z) or radians (roll, pitch, yaw).
  // The line's offsets are fractions of the way to the target.
  std::vector<double> Offsets(int dof) const {
    const double half = dof < 3 ? args_.half_range_translation_m : RadiansFromDegrees(args_.half_range_rotation_deg);
    const double first = dof == kLine ? kLineFirst : -half, last = dof == kLine ? kLineLast : half;
    // The line has the DoFs' step relative to its half-range 1, so it samples 0 and 1 exactly.
    const int count = dof == kLine ? 3 * (samples_ - 1) / 2 + 1 : samples_;
    std::vector<double> offsets(static_cast<std::size_t>(count), 0.0);
    for (int i = 0; count > 1 && i < count; ++i) offsets[i] = first + (last - first) * i / (count - 1);
    return offsets;
  }

  // Cost evaluations per profile.
  int Evaluations() const { return 6 * samples_ + (dofs_ > 6 ? static_cast<int>(Offsets(kLine).size()) : 0); }

  // Samples cost(T, dof) along each DoF of the local update about the centre's
  // origin, then along the update that reaches `target`.
  void Sample(const std::function<double(const Eigen::Isometry3d&, int dof)>& cost, const Eigen::Isometry3d& centre,
              const Eigen::Isometry3d& target, Profile* profile) const {
    const Vector6d to_target = TransformUpdateBetween(centre, target, TransformUpdate::kAboutSourcePoint);
    for (int dof = 0; dof < dofs_; ++dof) {
      const std::vector<double> offsets = Offsets(dof);
      profile->costs[dof].resize(offsets.size());
      for (std::size_t i = 0; i < offsets.size(); ++i) {
        ThrowIfInterrupted();
        Vector6d delta = Vector6d::Zero();
        if (dof == kLine) {
          delta = offsets[i] * to_target;
        } else {
          delta(dof) = offsets[i];
        }
        profile->costs[dof][i] = cost(ApplyTransformUpdate(centre, delta, TransformUpdate::kAboutSourcePoint), dof);
      }
    }
  }

 private:
  const ProfileArguments& args_;
  int samples_;
  int dofs_;
};

// The sampled profiles and their CSV rows.
struct ProfileTable {
  std::vector<Profile> profiles;
  std::string csv = "profile,frame,dof,offset,cost\n";

  void Append(const Profile& profile, const DofSampler& sampler) {
    for (int dof = 0; dof < sampler.dofs(); ++dof) {
      const std::vector<double> offsets = sampler.Offsets(dof);
      for (std::size_t i = 0; i < offsets.size(); ++i) {
        csv += fmt::format("{},{},{},{:.9g},{:.9g}\n", profile.name, profile.frame, kDofNames[dof],
                           WrittenOffset(dof, offsets[i]), profile.costs[dof][i]);
      }
    }
    profiles.push_back(profile);
  }
};

// Moves each lidar to profile (--lidar, or every lidar with the extrinsics
// asked for) to its centre (--at) in input->rig (it also becomes the "initial
// guess" whose projecting scans swathe trimming keeps), and finds its --toward
// target. Returns kExitInvalidInput (logged) when the extrinsics are missing.
int PlaceLidarsAtCentres(const ProfileArguments& args, const io::Dataset& dataset, CalibrationInput* input,
                         std::map<std::string, Eigen::Isometry3d>* targets, std::vector<std::string>* profiled) {
  if (!args.lidar.empty() && input->rig.FindLidar(args.lidar) == nullptr) {
    spdlog::error("--lidar {}: {}/rig.yaml has no lidar of that name", args.lidar, args.dataset);
    return kExitInvalidInput;
  }
  for (const std::string* spec : {&args.at, &args.toward}) {
    if (*spec == "truth" && !dataset.ground_truth) {
      spdlog::error("{} truth needs {}/ground_truth.yaml (simulated data); use guess or the path of a result",
                    spec == &args.at ? "--at" : "--toward", args.dataset);
      return kExitInvalidInput;
    }
  }
  const std::optional<CalibrationResult> at_result = ReadResultIfPath(args.at);
  const std::optional<CalibrationResult> toward_result = ReadResultIfPath(args.toward);
  for (LidarInfo& lidar : input->rig.lidars) {
    if (!args.lidar.empty() && lidar.name != args.lidar) continue;
    const auto centre = FindExtrinsic(args.at, dataset, at_result, lidar);
    const auto target = args.toward.empty() ? centre : FindExtrinsic(args.toward, dataset, toward_result, lidar);
    for (const auto& [spec, found] : {std::pair{args.at, centre}, std::pair{args.toward, target}}) {
      if (found || spec.empty()) continue;
      const std::string message =
          fmt::format("lidar {}: {} has no T_base_lidar for it", lidar.name,
                      spec == "truth" ? args.dataset + "/ground_truth.yaml" : spec);
      if (!args.lidar.empty()) {
        spdlog::error("{}", message);
        return kExitInvalidInput;
      }
      spdlog::warn("{}; not profiled", message);
    }
    if (!centre || !target) continue;
    lidar.T_base_lidar = *centre;
    (*targets)[lidar.name] = *target;
    profiled->push_back(lidar.name);
  }
  if (profiled->empty()) {
    spdlog::error("no lidar to profile");
    return kExitInvalidInput;
  }
  return kExitSuccess;
}

// The profile of one pair's cost (T_camera_lidar along camera axes, from the
// lidar's centre toward T_base_lidar_target) and, with --per-scene, of every
// used scene's own cost along the same samples (one evaluation gives them all).
void ProfilePair(const PairCost& pair, const LidarInfo& lidar, const Eigen::Isometry3d& T_base_lidar_target,
                 bool per_scene, const DofSampler& sampler, ProfileTable* table) {
  Profile profile{pair.Camera().name + "/" + lidar.name, pair.Camera().name, {}};
  spdlog::info("profiling {} ({} evaluations)", profile.name, sampler.Evaluations());
  const Eigen::Isometry3d T_camera_base = pair.Camera().T_camera_base();
  std::vector<std::size_t> used_scenes;
  for (std::size_t s = 0; s < pair.States().size(); ++s) {
    if (per_scene && pair.States()[s] == SceneState::kUsed) used_scenes.push_back(s);
  }
  std::vector<Profile> scene_profiles(used_scenes.size());
  const auto cost = [&](const Eigen::Isometry3d& T, int dof) {
    if (used_scenes.empty()) return pair.Evaluate(T);
    const std::vector<SceneEvaluation> scenes = pair.EvaluateScenes(T);
    double sum = 0.0;
    for (std::size_t k = 0; k < used_scenes.size(); ++k) {
      std::vector<double>& costs = scene_profiles[k].costs[static_cast<std::size_t>(dof)];
      costs.push_back(scenes[used_scenes[k]].cost);
      sum += costs.back();
    }
    return sum / static_cast<double>(used_scenes.size());
  };
  sampler.Sample(cost, T_camera_base * lidar.T_base_lidar, T_camera_base * T_base_lidar_target, &profile);
  table->Append(profile, sampler);
  for (std::size_t k = 0; k < used_scenes.size(); ++k) {
    scene_profiles[k].name = fmt::format("{} scene {}", profile.name, pair.Scenes()[used_scenes[k]].ImageTime());
    scene_profiles[k].frame = profile.frame;
    scene_profiles[k].in_summary = false;
    table->Append(scene_profiles[k], sampler);
  }
}

// Profiles the lidar's joint cost and its pairs' costs (as --costs asks) from
// its centre toward T_base_lidar_target; false (logged) when no pair has a
// scene to score.
bool ProfileLidar(const ProfileArguments& args, const CalibrationOptions& options, const CalibrationInput& input,
                  const LidarInfo& lidar, const Eigen::Isometry3d& T_base_lidar_target, const DofSampler& sampler,
                  ProfileTable* table) {
  std::vector<std::unique_ptr<PairCost>> pairs;
  std::vector<const PairCost*> used_pairs;
  for (const CameraInfo& camera : input.rig.cameras) {
    auto pair = std::make_unique<PairCost>(BuildPairCost(input, camera, lidar.name, options));
    pair->SetImageBlur(args.blur_fraction);
    const int used = pair->RefreshVisibility(camera.T_camera_base() * lidar.T_base_lidar);
    spdlog::info("pair {}/{}: {} of {} scenes used at the centre", camera.name, lidar.name, used,
                 pair->SceneCount());
    if (used > 0) used_pairs.push_back(pair.get());
    pairs.push_back(std::move(pair));
  }
  if (used_pairs.empty()) {
    spdlog::error("{}", DescribeUnusable(lidar.name, pairs, options.cost.min_points_per_scene));
    return false;
  }
  if (args.costs != "pairs") {
    Profile profile{"joint " + lidar.name, "base", {}};
    spdlog::info("profiling {} ({} evaluations)", profile.name, sampler.Evaluations());
    sampler.Sample([&](const Eigen::Isometry3d& T, int) { return EvaluateJoint(used_pairs, T); }, lidar.T_base_lidar,
                   T_base_lidar_target, &profile);
    table->Append(profile, sampler);
  }
  if (args.costs != "joint") {
    for (const PairCost* pair : used_pairs) {
      ProfilePair(*pair, lidar, T_base_lidar_target, args.per_scene, sampler, table);
    }
  }
  return true;
}

// The summary: per profile and DoF, where the minimum lies and how much the cost rises over the range.
void PrintSummary(const std::vector<Profile>& profiles, const DofSampler& sampler) {
  fmt::print("{:<22} {:>6} {:>6} {:>12} {:>12} {:>10}\n", "profile", "frame", "dof", "lowest", "fitted min",
             "rise");
  for (const Profile& profile : profiles) {
    if (!profile.in_summary) continue;
    for (int dof = 0; dof < sampler.dofs(); ++dof) {
      const ProfileMinimum minimum =
          FindMinimum(sampler.Offsets(dof), profile.costs[dof], std::max(2, sampler.samples() / 8));
      const double scale = dof < 3 ? 100.0 : dof < kLine ? 180.0 / kPi : 1.0;
      const char* unit = dof < 3 ? "cm" : dof < kLine ? "deg" : "";
      fmt::print("{:<22} {:>6} {:>6} {:>+9.3f} {:<3}{:>+9.3f} {:<3}{:>10.6f}\n", profile.name, profile.frame,
                 kDofNames[dof], minimum.sample_offset * scale, unit, minimum.fitted_offset * scale, unit,
                 minimum.rise);
    }
  }
}

int RunProfile(const ProfileArguments& args) {
  const auto start = std::chrono::steady_clock::now();
  io::CheckOutputFile(args.output, "--output");
  CalibrationOptions options;
  ApplyCostArguments(args.cost, &options);
  std::string why;
  if (!options.IsValid(&why)) {
    spdlog::error("invalid options: {}", why);
    return kExitInvalidInput;
  }
  const auto thread_limit = LimitThreads(args.threads);
  std::string single_frame_defaults;
  const io::Dataset dataset = OpenDatasetWithDefaults(args.dataset, args.cost, &options, &single_frame_defaults);

  CalibrationInput input;
  input.rig = dataset.rig;
  std::map<std::string, Eigen::Isometry3d> targets;
  std::vector<std::string> profiled;
  if (const int exit_code = PlaceLidarsAtCentres(args, dataset, &input, &targets, &profiled);
      exit_code != kExitSuccess) {
    return exit_code;
  }
  const LoadedScenes loaded = SelectAndLoadScenes(dataset, options.scenes, &input, args.cost.ImageChannel());
  spdlog::info("loaded {} lidar points in {:.2f} s", loaded.lidar_points,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());

  const DofSampler sampler(args);
  ProfileTable table;
  for (const LidarInfo& lidar : input.rig.lidars) {
    if (std::find(profiled.begin(), profiled.end(), lidar.name) == profiled.end()) continue;
    if (!ProfileLidar(args, options, input, lidar, targets.at(lidar.name), sampler, &table)) return kExitFailure;
  }
  io::WriteFileAtomically(args.output, table.csv);
  spdlog::info("wrote {} ({:.1f} s)", args.output,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  PrintSummary(table.profiles, sampler);
  return kExitSuccess;
}

}  // namespace

CommandRunner AddProfileCommand(CLI::App& app) {
  auto args = std::make_shared<ProfileArguments>();
  CLI::App* command = app.add_subcommand(
      "profile",
      "Sample the calibration cost along each degree of freedom through one extrinsic (the truth, the guess or a\n"
      "result) and write the curves to a CSV file; print where each curve is lowest. At the truth of a simulated\n"
      "dataset the offsets are the bias of the cost itself; the rise says how sharply the data constrain each\n"
      "direction. Joint cost: T_base_lidar moved along base-frame axes; pairs: T_camera_lidar along camera axes;\n"
      "rotations turn the lidar about its own origin (as in calibrate's error lines).\n"
      "CSV columns: profile (\"joint LIDAR\" or \"CAMERA/LIDAR\"), frame, dof (x y z roll pitch yaw), offset (m or\n"
      "deg), cost. Exit 1 when no scene can be scored; 2 for bad arguments or input data.");
  command->add_option("dataset", args->dataset, "Dataset folder (docs/FORMAT.md)")
      ->required()
      ->check(CLI::ExistingDirectory);
  command->add_option("-o,--output", args->output, "CSV file of the sampled curves (written atomically)")->required();
  command->add_option("--at", args->at,
                      "Centre of the profiles: truth (ground_truth.yaml), guess (rig.yaml) or the path of a "
                      "calibrate result")
      ->capture_default_str();
  command->add_option("--toward", args->toward,
                      "Also sample the straight line (in the same update) from the centre through these extrinsics: "
                      "truth, guess or a result path; offsets -1..2 with 1 at them (dof 'line')");
  command->add_flag("--per-scene", args->per_scene,
                    "Also write each used scene's own cost curves (profile \"CAMERA/LIDAR scene TIME_US\"), to see "
                    "which scenes constrain or pull which direction");
  command->add_option("--lidar", args->lidar, "Profile only this lidar (default: every lidar)");
  command->add_option("--costs", args->costs, "joint (per lidar), pairs (per camera and lidar) or all")
      ->check(CLI::IsMember({"joint", "pairs", "all"}))
      ->capture_default_str();
  command->add_option("--half-range-translation", args->half_range_translation_m,
                      "Translation offsets span +- this many metres")
      ->check(kPositive)
      ->capture_default_str();
  command->add_option("--half-range-rotation", args->half_range_rotation_deg,
                      "Rotation offsets span +- this many degrees")
      ->check(kPositive)
      ->capture_default_str();
  command->add_option("--samples", args->samples,
                      "Samples per degree of freedom (made odd, so the centre is one); the line gets as many per unit "
                      "of its offset, so it samples the centre (0) and the target (1) too")
      ->check(CLI::Range(1, 100001))
      ->capture_default_str();
  command->add_option("--blur", args->blur_fraction,
                      "Image blur, Gaussian sigma as a fraction of the image width (0: sharp, the final stage of "
                      "calibrate)")
      ->check(CLI::Range(0.0, 0.1))
      ->capture_default_str();
  command->add_option("--threads", args->threads, "Worker threads; 0 = all hardware threads")
      ->check(kNonNegative)
      ->capture_default_str();
  AddCostOptions(command, &args->cost);
  return [args] { return RunProfile(*args); };
}

}  // namespace scenecal::cli
