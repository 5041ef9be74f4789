#include "io/inspect.hpp"

#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>

namespace scenecal::io {

namespace {

bool InsideTrajectory(const Trajectory& trajectory, TimeUs t) {
  return !trajectory.empty() && t >= trajectory.times_us().front() && t <= trajectory.times_us().back();
}

std::optional<TimeSpan> SpanOf(const std::vector<SensorFile>& files) {
  if (files.empty()) return std::nullopt;
  return TimeSpan{files.front().t_us, files.back().t_us};
}

double RateHz(const std::vector<SensorFile>& files) {
  if (files.size() < 2) return 0.0;
  const double duration_s = 1e-6 * static_cast<double>(files.back().t_us - files.front().t_us);
  return duration_s > 0 ? static_cast<double>(files.size() - 1) / duration_s : 0.0;
}

std::string TupleText(const Eigen::Isometry3d& transform) {
  const Vector6d tuple = TupleFromTransform(transform);
  return fmt::format("x {:.4f} y {:.4f} z {:.4f} m, roll {:.3f} pitch {:.3f} yaw {:.3f} deg", tuple[0], tuple[1],
                     tuple[2], DegreesFromRadians(tuple[3]), DegreesFromRadians(tuple[4]),
                     DegreesFromRadians(tuple[5]));
}

std::string SpanText(const std::optional<TimeSpan>& span) {
  if (!span) return "no data";
  return fmt::format("{} .. {} us ({:.3f} s)", span->first_us, span->last_us, span->DurationS());
}

const std::vector<SensorFile>& FilesOf(const std::map<std::string, std::vector<SensorFile>>& listing,
                                       const std::string& sensor) {
  static const std::vector<SensorFile> no_files;
  const auto it = listing.find(sensor);
  return it == listing.end() ? no_files : it->second;
}

void SummariseTrajectory(const Trajectory& trajectory, const SummaryOptions& options, DatasetSummary* summary) {
  summary->trajectory_rows = trajectory.size();
  summary->static_dataset = trajectory.size() == 1;
  if (trajectory.empty()) return;
  summary->trajectory_span = {trajectory.times_us().front(), trajectory.times_us().back()};
  summary->distance_m = trajectory.TotalDistance();
  const double duration_s = summary->trajectory_span.DurationS();
  summary->mean_speed_m_s = duration_s > 0 ? summary->distance_m / duration_s : 0.0;
  for (std::size_t i = 1; i < trajectory.size(); ++i) {
    const double dt_s = 1e-6 * static_cast<double>(trajectory.times_us()[i] - trajectory.times_us()[i - 1]);
    const double step_m = (trajectory.poses()[i].translation() - trajectory.poses()[i - 1].translation()).norm();
    if (step_m < options.standing_speed_m_s * dt_s) summary->standing_still_s += dt_s;
  }
}

// One lidar's scans (read when options.read_contents; tick after each), and
// the travelled distance of those inside the trajectory (*distances_m, sorted
// as the times are).
LidarSummary SummariseLidar(const LidarInfo& lidar, const std::vector<SensorFile>& files,
                            const Trajectory& trajectory, const SummaryOptions& options,
                            const std::function<void()>& tick, std::vector<double>* distances_m) {
  LidarSummary s;
  s.name = lidar.name;
  s.scans = files.size();
  s.span = SpanOf(files);
  s.rate_hz = RateHz(files);
  s.contents_read = options.read_contents;
  std::vector<std::size_t> counts;
  counts.reserve(files.size());
  for (const SensorFile& file : files) {
    if (options.read_contents) {
      const LidarScan scan = ReadScan(file);
      counts.push_back(scan.points.size());
      s.no_returns += scan.no_returns;
      tick();
    } else {
      counts.push_back(ScanRecordCount(file));
    }
    if (InsideTrajectory(trajectory, file.t_us)) {
      distances_m->push_back(trajectory.DistanceAt(file.t_us));
    } else {
      ++s.outside_trajectory;
    }
  }
  if (!counts.empty()) {
    std::vector<std::size_t> sorted = counts;
    std::sort(sorted.begin(), sorted.end());
    s.points_min = sorted.front();
    s.points_max = sorted.back();
    s.points_median = sorted[sorted.size() / 2];
    for (const std::size_t c : counts) s.points_total += c;
  }
  return s;
}

// One camera's images (decoded when options.read_contents, tick after each;
// else their header sizes checked) and which have a scan of each lidar nearby
// (scan_distances_m: per lidar, as SummariseLidar gives them).
CameraSummary SummariseCamera(const CameraInfo& camera, const std::vector<SensorFile>& files,
                              const std::vector<std::vector<double>>& scan_distances_m, const Trajectory& trajectory,
                              const SummaryOptions& options, const std::function<void()>& tick) {
  CameraSummary s;
  s.name = camera.name;
  s.with_scans_of_lidar.assign(scan_distances_m.size(), 0);
  s.images = files.size();
  s.span = SpanOf(files);
  s.rate_hz = RateHz(files);
  for (const SensorFile& file : files) {
    if (options.read_contents) {
      ReadImage(file, camera.model);
      tick();
    } else if (const auto size = ImageFileSize(file.path);
               size && (size->first != camera.model.width || size->second != camera.model.height)) {
      throw InputError(fmt::format("{}: image size: {} x {} pixels; expected {} x {} pixels as in rig.yaml",
                                   file.path.string(), size->first, size->second, camera.model.width,
                                   camera.model.height));
    }
    if (!InsideTrajectory(trajectory, file.t_us)) {
      ++s.outside_trajectory;
      continue;
    }
    const double d = trajectory.DistanceAt(file.t_us);
    bool any = false;
    for (std::size_t l = 0; l < scan_distances_m.size(); ++l) {
      const std::vector<double>& distances = scan_distances_m[l];
      const auto first = std::lower_bound(distances.begin(), distances.end(), d - options.nearby_distance_m);
      if (first != distances.end() && *first <= d + options.nearby_distance_m) {
        ++s.with_scans_of_lidar[l];
        any = true;
      }
    }
    if (any) ++s.with_scans_nearby;
  }
  return s;
}

// Verdict: every lidar needs at least one image (of any camera) with one of
// its scans nearby; cameras without such images are left out (a warning).
void AddVerdict(const SummaryOptions& options, DatasetSummary* summary) {
  const std::string nearby = summary->static_dataset
                                 ? std::string("at the same time (static dataset)")
                                 : fmt::format("within {:g} m of travel", options.nearby_distance_m);
  for (std::size_t l = 0; l < summary->lidars.size(); ++l) {
    const LidarSummary& lidar = summary->lidars[l];
    std::size_t usable = 0;
    for (const CameraSummary& camera : summary->cameras) usable += camera.with_scans_of_lidar[l];
    if (lidar.scans == 0) {
      summary->problems.push_back(fmt::format("lidar '{}' has no scans (lidars/{}/ is missing or empty)", lidar.name,
                                              lidar.name));
    } else if (lidar.scans == lidar.outside_trajectory) {
      summary->problems.push_back(fmt::format("all {} scans of lidar '{}' lie outside the trajectory's time span",
                                              lidar.scans, lidar.name));
    } else if (usable == 0) {
      summary->problems.push_back(
          fmt::format("no image of any camera has a scan of lidar '{}' {}", lidar.name, nearby));
    } else if (options.read_contents && lidar.points_total == 0) {
      summary->problems.push_back(fmt::format("every scan of lidar '{}' is empty (no finite points)", lidar.name));
    }
    if (lidar.outside_trajectory > 0 && lidar.outside_trajectory < lidar.scans) {
      summary->warnings.push_back(
          fmt::format("{} of {} scans of lidar '{}' lie outside the trajectory and are left out",
                      lidar.outside_trajectory, lidar.scans, lidar.name));
    }
  }
  for (const CameraSummary& camera : summary->cameras) {
    if (camera.images == 0) {
      summary->warnings.push_back(fmt::format("camera '{}' has no images; it will not take part", camera.name));
    } else if (camera.with_scans_nearby == 0) {
      summary->warnings.push_back(
          fmt::format("no image of camera '{}' has a lidar scan {}; it will not take part", camera.name, nearby));
    }
    if (camera.outside_trajectory > 0) {
      summary->warnings.push_back(
          fmt::format("{} of {} images of camera '{}' lie outside the trajectory and are left out",
                      camera.outside_trajectory, camera.images, camera.name));
    }
  }
  summary->can_calibrate = summary->problems.empty();
}

}  // namespace

DatasetSummary SummariseDataset(const Dataset& dataset, const SummaryOptions& options,
                                const std::function<void(std::size_t, std::size_t)>& progress) {
  const Rig& rig = dataset.rig;
  DatasetSummary summary;
  summary.contents_read = options.read_contents;
  summary.nearby_distance_m = options.nearby_distance_m;
  summary.ground_truth = dataset.ground_truth.has_value();
  SummariseTrajectory(dataset.trajectory, options, &summary);

  // Contents: every image and scan is read, so that every problem surfaces now.
  std::size_t total = 0, done = 0;
  for (const auto& [name, files] : dataset.images) total += files.size();
  for (const auto& [name, files] : dataset.scans) total += files.size();
  const std::function<void()> tick = [&] {
    ++done;
    if (progress) progress(done, total);
  };

  // Lidars first: their scan distances along the trajectory decide "nearby".
  std::vector<std::vector<double>> scan_distances_m(rig.lidars.size());  // per lidar, of scans inside the trajectory
  for (std::size_t l = 0; l < rig.lidars.size(); ++l) {
    const LidarInfo& lidar = rig.lidars[l];
    summary.lidars.push_back(SummariseLidar(lidar, FilesOf(dataset.scans, lidar.name), dataset.trajectory, options,
                                            tick, &scan_distances_m[l]));
  }
  for (const CameraInfo& camera : rig.cameras) {
    summary.cameras.push_back(SummariseCamera(camera, FilesOf(dataset.images, camera.name), scan_distances_m,
                                              dataset.trajectory, options, tick));
  }
  AddVerdict(options, &summary);
  return summary;
}

std::string FormatDatasetSummary(const Dataset& dataset, const DatasetSummary& summary) {
  const Rig& rig = dataset.rig;
  std::string out;
  const auto line = [&out](const std::string& text) { out += text + "\n"; };
  line(fmt::format("dataset {}", dataset.root.string()));
  line(fmt::format("base frame: {}", rig.base_frame));
  line(fmt::format("cameras: {}", rig.cameras.size()));
  for (std::size_t i = 0; i < rig.cameras.size(); ++i) {
    const CameraInfo& camera = rig.cameras[i];
    const CameraModel& model = camera.model;
    const CameraSummary& s = summary.cameras[i];
    std::string distortion;
    for (const double k : model.distortion) distortion += fmt::format("{}{:.6g}", distortion.empty() ? "" : " ", k);
    line(fmt::format("  {}: {} {}x{} px, fx {:.3f} fy {:.3f} cx {:.3f} cy {:.3f} px, distortion [{}]", camera.name,
                     CameraModelKindName(model.kind), model.width, model.height, model.fx, model.fy, model.cx,
                     model.cy, distortion));
    line(fmt::format("    T_base_camera (known): {}", TupleText(camera.T_base_camera)));
    if (camera.T_base_camera_sigma) {
      const Vector6d& sigma = *camera.T_base_camera_sigma;
      line(fmt::format("    sigma: {:.4g} {:.4g} {:.4g} m, {:.4g} {:.4g} {:.4g} deg", sigma[0], sigma[1], sigma[2],
                       DegreesFromRadians(sigma[3]), DegreesFromRadians(sigma[4]), DegreesFromRadians(sigma[5])));
    }
    line(fmt::format("    images: {}, {}, {:.2f} Hz; outside trajectory: {}; with a scan nearby: {}", s.images,
                     SpanText(s.span), s.rate_hz, s.outside_trajectory, s.with_scans_nearby));
  }
  line(fmt::format("lidars: {}", rig.lidars.size()));
  for (std::size_t i = 0; i < rig.lidars.size(); ++i) {
    const LidarInfo& lidar = rig.lidars[i];
    const LidarSummary& s = summary.lidars[i];
    line(fmt::format("  {}: {}", lidar.name, lidar.kind == LidarKind::k2d ? "2d (push-broom)" : "3d"));
    line(fmt::format("    T_base_lidar (initial): {}", TupleText(lidar.T_base_lidar)));
    line(fmt::format("    scans: {}, {}, {:.2f} Hz; outside trajectory: {}", s.scans, SpanText(s.span), s.rate_hz,
                     s.outside_trajectory));
    if (s.scans > 0) {
      if (s.contents_read) {
        const double fraction = static_cast<double>(s.no_returns) /
                                std::max<double>(1.0, static_cast<double>(s.no_returns + s.points_total));
        line(fmt::format("    points per scan: min {} median {} max {}; no-returns {} ({:.2f} %)", s.points_min,
                         s.points_median, s.points_max, s.no_returns, 100.0 * fraction));
      } else {
        line(fmt::format("    records per scan (from file sizes, incl. no-returns): min {} median {} max {}",
                         s.points_min, s.points_median, s.points_max));
      }
    }
  }
  line(fmt::format("trajectory: {} rows, {}{}; source {}{}", summary.trajectory_rows,
                   SpanText(summary.trajectory_span), summary.static_dataset ? " (static dataset)" : "",
                   TrajectorySourceName(dataset.rig.trajectory_source),
                   dataset.rig.trajectory_source == TrajectorySource::kUnknown ? " (rig.yaml: no trajectory_source)"
                                                                               : " (rig.yaml)"));
  line(fmt::format("  distance travelled {:.2f} m, mean speed {:.2f} m/s, standing still {:.1f} s", summary.distance_m,
                   summary.mean_speed_m_s, summary.standing_still_s));
  line(fmt::format("ground truth: {}", summary.ground_truth ? "present (ground_truth.yaml)" : "absent"));
  if (!summary.contents_read) line("contents: not decoded (--quick); sizes only");
  for (const std::string& warning : summary.warnings) line("warning: " + warning);
  for (const std::string& problem : summary.problems) line("problem: " + problem);
  line(fmt::format("verdict: {}", summary.can_calibrate ? "can be calibrated" : "cannot be calibrated"));
  return out;
}

}  // namespace scenecal::io
