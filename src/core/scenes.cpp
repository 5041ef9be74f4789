#include "core/scenes.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <set>
#include <sstream>

#include "core/validation.hpp"

namespace scenecal {

bool ParseSwatheDirection(const std::string& name, SwatheDirection* direction) {
  return ParseEnumName(kSwatheDirectionNames, name, direction);
}

const char* SwatheDirectionName(SwatheDirection direction) { return EnumName(kSwatheDirectionNames, direction); }

bool ParseSceneChoice(const std::string& name, SceneChoice* choice) {
  return ParseEnumName(kSceneChoiceNames, name, choice);
}

const char* SceneChoiceName(SceneChoice choice) { return EnumName(kSceneChoiceNames, choice); }

bool SceneOptions::IsValid(std::string* why) const {
  if (scenes_per_camera < 1) return Invalid(why, "scenes_per_camera must be at least 1");
  if (informative_pool_factor < 1 || informative_pool_factor > 20)
    return Invalid(why, "informative_pool_factor must be within 1..20");
  if (scenes_per_camera > 1000000 / informative_pool_factor)
    return Invalid(why, "scenes_per_camera times informative_pool_factor must be at most 1000000");
  if (!(auto_variance_ratio == 0.0 || (auto_variance_ratio > 1.0 && std::isfinite(auto_variance_ratio))))
    return Invalid(why, "auto_variance_ratio must be 0 (a fixed count) or a factor above 1");
  if (min_auto_scenes < 1) return Invalid(why, "min_auto_scenes must be at least 1");
  if (informative_after_stages < 0) return Invalid(why, "informative_after_stages must be 0 or more");
  if (!(swathe_length_m > 0.0) || !std::isfinite(swathe_length_m))
    return Invalid(why, "swathe_length_m must be a positive number of metres");
  if (!(min_speed_mps >= 0.0) || !std::isfinite(min_speed_mps)) return Invalid(why, "min_speed_mps must be >= 0 (m/s)");
  if (!(speed_window_s > 0.0) || !std::isfinite(speed_window_s)) return Invalid(why, "speed_window_s must be > 0 (s)");
  if (max_scans_per_scene < 0) return Invalid(why, "max_scans_per_scene must be 0 (no cap) or positive");
  if (!(std::abs(odometry_scale) < 0.2)) return Invalid(why, "odometry_scale must be a fraction within (-0.2, 0.2)");
  return true;
}

int SceneSelection::FramesOf(const std::string& lidar) const {
  std::set<TimeUs> times;
  for (const Scene& scene : scenes) {
    if (scene.lidar == lidar) times.insert(scene.image_t_us);
  }
  return static_cast<int>(times.size());
}

std::string SceneSelection::Report() const {
  std::ostringstream out;
  out << "scene selection" << (static_dataset ? " (static dataset: scans at the image time)" : "") << ":";
  for (const CameraSelectionReport& c : cameras) {
    out << "\n  camera " << c.camera << ": " << c.images << " images, " << c.selected << " selected of "
        << c.eligible << " eligible; skipped " << c.skipped_no_pose << " without pose, " << c.skipped_standing_still
        << " standing still, " << c.skipped_window_outside << " with the swathe window off the trajectory";
  }
  for (const LidarSelectionReport& p : pairs) {
    out << "\n  " << p.camera << " / " << p.lidar << ": " << p.scenes << " scenes, " << p.scans_used
        << " scans; " << p.frames_without_scans << " frames without scans";
    if (p.short_swathe_scenes > 0) {
      out << "; " << p.short_swathe_scenes
          << " scenes from frames without a whole swathe (standing or near the drive's ends: a 3d lidar's scans "
             "at the travel there is)";
    }
    if (p.scans_without_pose > 0) out << ", " << p.scans_without_pose << " scans without pose";
  }
  return out.str();
}

std::string SceneSelection::WhyNoScenes(const LidarInfo& lidar) const {
  for (const Scene& scene : scenes) {
    if (scene.lidar == lidar.name) return "";
  }
  std::ostringstream out;
  out << "lidar " << lidar.name << " (" << (lidar.kind == LidarKind::k2d ? "2d" : "3d") << "): no scene.";
  for (const CameraSelectionReport& c : cameras) {
    out << " Camera " << c.camera << ": " << c.images << " images; left out " << c.skipped_no_pose
        << " outside the trajectory, " << c.skipped_standing_still << " standing still, " << c.skipped_window_outside
        << " with the " << swathe_length_m << " m swathe window off the trajectory";
    for (const LidarSelectionReport& p : pairs) {
      if (p.camera == c.camera && p.lidar == lidar.name && p.frames_without_scans > 0) {
        out << ", " << p.frames_without_scans << " without a scan of " << lidar.name << " in their window";
      }
    }
    out << ".";
  }
  out << " The trajectory covers " << std::round(trajectory_length_m * 100.0) / 100.0 << " m.";
  if (lidar.kind == LidarKind::k2d && !static_dataset) {
    out << " A 2d (push-broom) lidar sees the scene only through the vehicle's motion: each image needs "
        << swathe_length_m << " m of travel at more than a walking pace within the trajectory.";
  }
  return out.str();
}

namespace {

constexpr double kMicrosecondsPerSecond = 1e6;

// Mean speed (m/s) over [t - window, t + window] clipped to the trajectory.
double SpeedAt(const Trajectory& trajectory, TimeUs t, double window_s) {
  const auto window_us = static_cast<TimeUs>(window_s * kMicrosecondsPerSecond);
  const TimeUs t0 = std::max(trajectory.times_us().front(), t - window_us);
  const TimeUs t1 = std::min(trajectory.times_us().back(), t + window_us);
  if (t1 <= t0) return 0.0;
  return (trajectory.DistanceAt(t1) - trajectory.DistanceAt(t0)) / (static_cast<double>(t1 - t0) / kMicrosecondsPerSecond);
}

// Indices of `count` items spread evenly over [0, n).
std::vector<std::size_t> ThinEvenly(std::size_t n, std::size_t count) {
  std::vector<std::size_t> kept;
  for (std::size_t i = 0; i < count; ++i) {
    kept.push_back(static_cast<std::size_t>((static_cast<double>(i) + 0.5) * static_cast<double>(n) /
                                            static_cast<double>(count)));
  }
  return kept;
}

// Picks up to `count` of the frames (given by distance travelled, ascending)
// spread evenly by distance: for each target distance the nearest unused frame.
std::vector<std::size_t> SpreadByDistance(const std::vector<double>& distances_m, std::size_t count) {
  const std::size_t n = distances_m.size();
  std::vector<std::size_t> chosen;
  if (n <= count) {
    for (std::size_t i = 0; i < n; ++i) chosen.push_back(i);
    return chosen;
  }
  std::vector<bool> used(n, false);
  const double first = distances_m.front();
  const double span = distances_m.back() - first;
  for (std::size_t i = 0; i < count; ++i) {
    const double target = count == 1 ? first + 0.5 * span
                                     : first + span * static_cast<double>(i) / static_cast<double>(count - 1);
    std::size_t best = n;
    double best_gap = 0.0;
    for (std::size_t f = 0; f < n; ++f) {
      if (used[f]) continue;
      const double gap = std::abs(distances_m[f] - target);
      if (best == n || gap < best_gap) {
        best = f;
        best_gap = gap;
      }
    }
    used[best] = true;
    chosen.push_back(best);
  }
  std::sort(chosen.begin(), chosen.end());
  return chosen;
}

// The scans of a swathe clipped to the trajectory: those within
// [from_m, to_m] of travel. With less than kMinShortSwatheTravelM of travel
// in reach (a standing vehicle) further scans repeat the same view, so the
// scan nearest the image time is taken alone, if the vehicle moved less than
// that between the two.
constexpr double kMinShortSwatheTravelM = 0.5;
// Less travel than this between two scans: the vehicle stood (a crawl at
// 0.1 m/s still moves it between 10 Hz scans).
constexpr double kStandingTravelM = 0.01;

std::vector<TimeUs> ShortSwathe(const Trajectory& trajectory, const std::vector<TimeUs>& scan_times, TimeUs t_k,
                                double from_m, double to_m) {
  std::vector<TimeUs> window;
  std::optional<TimeUs> nearest;
  for (const TimeUs t : scan_times) {
    if (t < trajectory.times_us().front() || t > trajectory.times_us().back()) continue;
    const double d = trajectory.DistanceAt(t);
    if (d >= from_m && d <= to_m) window.push_back(t);
    if (!nearest || std::abs(t - t_k) < std::abs(*nearest - t_k)) nearest = t;
  }
  const double travel_m =
      window.empty() ? 0.0 : trajectory.DistanceAt(window.back()) - trajectory.DistanceAt(window.front());
  if (travel_m >= kMinShortSwatheTravelM) {
    // Scans taken where the one before was (standing) repeat its view: at a
    // stop they outnumbered the moving scans of a window 75 to 94 (simulated
    // spin3d recordings of 8 frames; with them two of four runs ended 9-12 cm
    // off, without them 0.5-2.1 cm).
    std::vector<TimeUs> moved;
    for (const TimeUs t : window) {
      if (moved.empty() || trajectory.DistanceAt(t) - trajectory.DistanceAt(moved.back()) >= kStandingTravelM) {
        moved.push_back(t);
      }
    }
    return moved;
  }
  if (nearest && std::abs(trajectory.DistanceAt(*nearest) - trajectory.DistanceAt(t_k)) < kMinShortSwatheTravelM) {
    return {*nearest};
  }
  return {};
}

// How far a swathe reaches, in metres of travel before and after the image.
struct SwatheReach {
  double before_m = 0.0;
  double after_m = 0.0;
};

// What every (camera, lidar) pair's selection reads.
struct SelectionContext {
  const Trajectory& trajectory;
  const SceneOptions& options;
  SwatheReach reach;
  bool static_dataset = false;
  double total_m = 0.0;  // the trajectory's length
};

const std::vector<TimeUs>& TimesOf(const std::map<std::string, std::vector<TimeUs>>& times_us,
                                   const std::string& sensor) {
  static const std::vector<TimeUs> kNoTimes;
  const auto it = times_us.find(sensor);
  return it == times_us.end() ? kNoTimes : it->second;
}

// A camera's frames with a pose, with their distance travelled.
struct CameraFrames {
  std::vector<TimeUs> eligible_times;  // with a whole swathe at more than the minimum speed
  std::vector<double> eligible_distances;
  // Frames with a pose that cannot have a whole swathe (standing, or too
  // near the drive's ends): a 3D lidar still sees the scene from there.
  std::vector<TimeUs> short_times;
  std::vector<double> short_distances;
};

CameraFrames ClassifyFrames(const SelectionContext& context, const std::vector<TimeUs>& image_times,
                            CameraSelectionReport* report) {
  const Trajectory& trajectory = context.trajectory;
  CameraFrames frames;
  for (const TimeUs t : image_times) {
    ++report->images;
    if (!trajectory.PoseAt(t)) {
      ++report->skipped_no_pose;
      continue;
    }
    const double d = trajectory.DistanceAt(t);
    if (!context.static_dataset) {
      if (SpeedAt(trajectory, t, context.options.speed_window_s) < context.options.min_speed_mps) {
        ++report->skipped_standing_still;
        frames.short_times.push_back(t);
        frames.short_distances.push_back(d);
        continue;
      }
      if (d - context.reach.before_m < 0.0 || d + context.reach.after_m > context.total_m) {
        ++report->skipped_window_outside;
        frames.short_times.push_back(t);
        frames.short_distances.push_back(d);
        continue;
      }
    }
    frames.eligible_times.push_back(t);
    frames.eligible_distances.push_back(d);
  }
  return frames;
}

// Distance grows with time, so the window is a contiguous run of scans
// around t_k: walk back while within before_m, forward while within after_m.
std::vector<TimeUs> ContiguousSwathe(const Trajectory& trajectory, const std::vector<TimeUs>& scan_times, TimeUs t_k,
                                     double d_k, const SwatheReach& reach) {
  const auto first_after = std::lower_bound(scan_times.begin(), scan_times.end(), t_k);
  auto begin = first_after;
  if (reach.before_m > 0.0) {
    while (begin != scan_times.begin() && trajectory.DistanceAt(*(begin - 1)) >= d_k - reach.before_m &&
           *(begin - 1) >= trajectory.times_us().front()) {
      --begin;
    }
  }
  auto end = first_after;
  if (reach.after_m > 0.0) {
    while (end != scan_times.end() && trajectory.DistanceAt(*end) <= d_k + reach.after_m &&
           *end <= trajectory.times_us().back()) {
      ++end;
    }
  } else {
    // backward only: include a scan taken exactly at t_k
    while (end != scan_times.end() && *end == t_k) ++end;
  }
  return std::vector<TimeUs>(begin, end);
}

// The scan times of the scene at image time t_k (d_k m travelled), thinned to the cap.
std::vector<TimeUs> SceneWindow(const SelectionContext& context, const std::vector<TimeUs>& scan_times, TimeUs t_k,
                                double d_k, bool short_swathe) {
  std::vector<TimeUs> window;
  if (context.static_dataset) {
    const auto range = std::equal_range(scan_times.begin(), scan_times.end(), t_k);
    window.assign(range.first, range.second);
  } else if (short_swathe) {
    const SwatheReach& reach = context.reach;
    window = ShortSwathe(context.trajectory, scan_times, t_k, d_k - reach.before_m, d_k + reach.after_m);
  } else {
    window = ContiguousSwathe(context.trajectory, scan_times, t_k, d_k, context.reach);
  }
  const int max_scans = context.options.max_scans_per_scene;
  if (max_scans > 0 && window.size() > static_cast<std::size_t>(max_scans)) {
    std::vector<TimeUs> thinned;
    for (const std::size_t i : ThinEvenly(window.size(), static_cast<std::size_t>(max_scans)))
      thinned.push_back(window[i]);
    window.swap(thinned);
  }
  return window;
}

// The scans of `window` with a pose, relative to the image's base pose.
void AddScans(const SelectionContext& context, const std::vector<TimeUs>& window, Scene* scene,
              LidarSelectionReport* report) {
  const Eigen::Isometry3d T_world_basek = *context.trajectory.PoseAt(scene->image_t_us);
  for (const TimeUs t_j : window) {
    const std::optional<Eigen::Isometry3d> T_world_basej = context.trajectory.PoseAt(t_j);
    if (!T_world_basej) {
      ++report->scans_without_pose;
      continue;
    }
    Eigen::Isometry3d T_basek_basej = T_world_basek.inverse() * *T_world_basej;
    // A relative position scales with the distances.
    T_basek_basej.translation() *= 1.0 + context.options.odometry_scale;
    scene->scans.push_back({t_j, T_basek_basej});
  }
}

// The scenes of one (camera, lidar) pair, appended to *scenes; `chosen`
// indexes the camera's eligible frames.
LidarSelectionReport SelectPairScenes(const SelectionContext& context, const std::string& camera,
                                      const LidarInfo& lidar, const std::vector<TimeUs>& scan_times,
                                      const CameraFrames& frames, const std::vector<std::size_t>& chosen,
                                      std::vector<Scene>* scenes) {
  LidarSelectionReport report;
  report.camera = camera;
  report.lidar = lidar.name;
  // A 3D scan is a scene by itself, so a 3D lidar also takes frames without
  // a whole swathe (standing, or near the drive's ends), each with the scans
  // of the travel there is: all of them on a recording without one whole
  // swathe, and elsewhere one per place, as many as fill the wanted count
  // (on 3-12 frames cut from the simulated spin3d drives, runs that used 1-2
  // of their frames ended 1-45 cm off; docs/findings.md, "Few frames").
  struct Pick {
    TimeUs t_us;
    double distance_m;
    bool short_swathe;
  };
  std::vector<Pick> picks;
  for (const std::size_t index : chosen) {
    picks.push_back({frames.eligible_times[index], frames.eligible_distances[index], false});
  }
  const std::size_t wanted = static_cast<std::size_t>(context.options.CandidatesPerCamera());
  if (lidar.kind == LidarKind::k3d && !picks.empty() && picks.size() < wanted) {
    // One frame per place: frames at a stop repeat one view.
    std::vector<std::size_t> places;
    for (std::size_t i = 0; i < frames.short_times.size(); ++i) {
      const auto near = [&](double distance_m) {
        return std::abs(distance_m - frames.short_distances[i]) < kMinShortSwatheTravelM;
      };
      const bool taken =
          std::any_of(picks.begin(), picks.end(), [&](const Pick& pick) { return near(pick.distance_m); }) ||
          std::any_of(places.begin(), places.end(), [&](std::size_t j) { return near(frames.short_distances[j]); });
      if (!taken) places.push_back(i);
    }
    const std::size_t fill = std::min(places.size(), wanted - picks.size());
    for (const std::size_t k : ThinEvenly(places.size(), fill)) {
      picks.push_back({frames.short_times[places[k]], frames.short_distances[places[k]], true});
    }
    std::sort(picks.begin(), picks.end(), [](const Pick& a, const Pick& b) { return a.t_us < b.t_us; });
  } else if (lidar.kind == LidarKind::k3d && picks.empty()) {
    // No whole swathe anywhere: every frame there is, spread by time
    // (standing frames share one distance, and their images still differ).
    const std::size_t count = std::min(frames.short_times.size(), wanted);
    for (const std::size_t index : ThinEvenly(frames.short_times.size(), count)) {
      picks.push_back({frames.short_times[index], frames.short_distances[index], true});
    }
  }
  for (const Pick& pick : picks) {
    Scene scene;
    scene.camera = camera;
    scene.lidar = lidar.name;
    scene.image_t_us = pick.t_us;
    scene.distance_m = pick.distance_m;
    AddScans(context, SceneWindow(context, scan_times, scene.image_t_us, scene.distance_m, pick.short_swathe), &scene,
             &report);
    if (scene.scans.empty()) {
      ++report.frames_without_scans;
      continue;
    }
    ++report.scenes;
    if (pick.short_swathe) ++report.short_swathe_scenes;
    report.scans_used += static_cast<int>(scene.scans.size());
    scenes->push_back(std::move(scene));
  }
  return report;
}

}  // namespace

SceneSelection SelectScenes(const Rig& rig, const Trajectory& trajectory,
                            const std::map<std::string, std::vector<TimeUs>>& image_times_us,
                            const std::map<std::string, std::vector<TimeUs>>& scan_times_us,
                            const SceneOptions& options) {
  SceneSelection selection;
  if (trajectory.empty()) return selection;
  selection.static_dataset = trajectory.size() == 1;
  selection.swathe_length_m = options.swathe_length_m;
  const double total_m = trajectory.TotalDistance();
  selection.trajectory_length_m = total_m;
  const double length_m = options.swathe_length_m;
  SelectionContext context{trajectory, options, {}, selection.static_dataset, total_m};
  context.reach.before_m = options.direction == SwatheDirection::kForward ? 0.0 : length_m;
  context.reach.after_m = options.direction == SwatheDirection::kBackward ? 0.0 : length_m;

  for (const CameraInfo& camera : rig.cameras) {
    CameraSelectionReport camera_report;
    camera_report.camera = camera.name;
    const CameraFrames frames = ClassifyFrames(context, TimesOf(image_times_us, camera.name), &camera_report);
    camera_report.eligible = static_cast<int>(frames.eligible_times.size());
    const std::vector<std::size_t> chosen =
        SpreadByDistance(frames.eligible_distances, static_cast<std::size_t>(options.CandidatesPerCamera()));
    camera_report.selected = static_cast<int>(chosen.size());
    selection.cameras.push_back(camera_report);

    for (const LidarInfo& lidar : rig.lidars) {
      selection.pairs.push_back(SelectPairScenes(context, camera.name, lidar, TimesOf(scan_times_us, lidar.name),
                                                 frames, chosen, &selection.scenes));
    }
  }
  return selection;
}

}  // namespace scenecal
