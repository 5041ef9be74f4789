// Scene selection and swathe windows on synthetic trajectories.
#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/geometry.hpp"
#include "core/scenes.hpp"

namespace scenecal {
namespace {

constexpr TimeUs kSecond = 1'000'000;

Rig OneCameraOneLidar() {
  Rig rig;
  rig.base_frame = "left";
  CameraInfo camera;
  camera.name = "left";
  rig.cameras.push_back(camera);
  LidarInfo lidar;
  lidar.name = "rear";
  rig.lidars.push_back(lidar);
  return rig;
}

// Straight drive along x at 1 m/s for 100 s, except standing still (x held)
// between 40 s and 60 s. Samples every 0.1 s.
Trajectory DriveWithStop() {
  std::vector<TimeUs> times;
  std::vector<Eigen::Isometry3d> poses;
  for (int i = 0; i <= 1000; ++i) {
    const double t = 0.1 * i;
    const double x = t < 40.0 ? t : (t < 60.0 ? 40.0 : t - 20.0);
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = Eigen::Vector3d(x, 0, 0);
    times.push_back(static_cast<TimeUs>(i) * kSecond / 10);
    poses.push_back(pose);
  }
  return Trajectory(times, poses);
}

std::vector<TimeUs> Every(TimeUs period, TimeUs begin, TimeUs end) {
  std::vector<TimeUs> times;
  for (TimeUs t = begin; t <= end; t += period) times.push_back(t);
  return times;
}

TEST(Scenes, OptionsValidation) {
  SceneOptions options;
  std::string why;
  EXPECT_TRUE(options.IsValid(&why)) << why;
  options.swathe_length_m = 0.0;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("swathe_length_m"), std::string::npos);
  options = SceneOptions{};
  options.scenes_per_camera = 0;
  EXPECT_FALSE(options.IsValid());
  SwatheDirection direction;
  EXPECT_TRUE(ParseSwatheDirection("both", &direction));
  EXPECT_EQ(direction, SwatheDirection::kBoth);
  EXPECT_FALSE(ParseSwatheDirection("sideways", &direction));
  options = SceneOptions{};
  options.odometry_scale = 0.25;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("odometry_scale"), std::string::npos);
}

TEST(Scenes, SpreadsFramesByDistanceAndSkipsStandingStill) {
  const Trajectory trajectory = DriveWithStop();  // 80 m in total
  SceneOptions options;
  options.scenes_per_camera = 8;
  options.swathe_length_m = 10.0;
  const SceneSelection selection =
      SelectScenes(OneCameraOneLidar(), trajectory, {{"left", Every(kSecond / 10, 0, 100 * kSecond)}},
                   {{"rear", Every(kSecond / 50, 0, 100 * kSecond)}}, options);
  ASSERT_EQ(selection.cameras.size(), 1u);
  const CameraSelectionReport& report = selection.cameras[0];
  EXPECT_EQ(report.images, 1001);
  EXPECT_EQ(report.selected, 8);
  // About 19 s of standing still (the speed window smooths the edges).
  EXPECT_GT(report.skipped_standing_still, 180);
  EXPECT_LT(report.skipped_standing_still, 200);
  // The last 10 m cannot hold a forward window.
  EXPECT_GT(report.skipped_window_outside, 90);
  ASSERT_EQ(selection.scenes.size(), 8u);
  std::vector<double> distances;
  for (const Scene& scene : selection.scenes) {
    EXPECT_FALSE(scene.image_t_us > 40 * kSecond + kSecond / 2 && scene.image_t_us < 60 * kSecond - kSecond / 2)
        << "frame at " << scene.image_t_us << " us is inside the stop";
    distances.push_back(scene.distance_m);
  }
  // Eligible distances span [0, 70] m; 8 frames -> every 10 m.
  for (std::size_t i = 0; i < distances.size(); ++i) {
    EXPECT_NEAR(distances[i], 10.0 * static_cast<double>(i), 0.6) << "frame " << i;
  }
}

// A straight drive along x: `speed` m/s for `seconds`, poses every 0.1 s.
Trajectory StraightDrive(double speed_mps, int seconds) {
  std::vector<TimeUs> times;
  std::vector<Eigen::Isometry3d> poses;
  for (int i = 0; i <= 10 * seconds; ++i) {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = Eigen::Vector3d(speed_mps * 0.1 * i, 0, 0);
    times.push_back(static_cast<TimeUs>(i) * kSecond / 10);
    poses.push_back(pose);
  }
  return Trajectory(times, poses);
}

// One camera, a 2D push-broom lidar "rear" and a 3D lidar "roof".
Rig PushBroomAndRoofLidar() {
  Rig rig = OneCameraOneLidar();
  rig.lidars[0].kind = LidarKind::k2d;
  LidarInfo roof;
  roof.name = "roof";
  roof.kind = LidarKind::k3d;
  rig.lidars.push_back(roof);
  return rig;
}

// Recordings without one whole swathe: a 3D lidar's scans are scenes by
// themselves (standing: the nearest scan; short: the travel there is); a 2D
// lidar gets none, and the counts say why.
TEST(Scenes, StandingAndShortRecordingsServeA3dLidarOnly) {
  const Rig rig = PushBroomAndRoofLidar();
  const std::map<std::string, std::vector<TimeUs>> images = {{"left", Every(kSecond / 10, 0, 3 * kSecond)}};
  const std::map<std::string, std::vector<TimeUs>> scans = {{"rear", Every(kSecond / 10, kSecond / 50, 3 * kSecond)},
                                                            {"roof", Every(kSecond / 10, kSecond / 50, 3 * kSecond)}};
  SceneOptions options;
  options.scenes_per_camera = 5;

  const SceneSelection standing = SelectScenes(rig, StraightDrive(0.0, 3), images, scans, options);
  EXPECT_EQ(standing.cameras[0].skipped_standing_still, 31);
  ASSERT_EQ(standing.pairs.size(), 2u);
  EXPECT_EQ(standing.pairs[0].scenes, 0) << "a 2d lidar needs motion";
  EXPECT_EQ(standing.pairs[1].scenes, 5);
  EXPECT_EQ(standing.pairs[1].short_swathe_scenes, 5);
  std::vector<TimeUs> frame_times;
  for (const Scene& scene : standing.scenes) {
    EXPECT_EQ(scene.lidar, "roof");
    ASSERT_EQ(scene.scans.size(), 1u) << "standing: the nearest scan only";
    EXPECT_EQ(std::abs(scene.scans[0].t_us - scene.image_t_us), kSecond / 50);
    frame_times.push_back(scene.image_t_us);
  }
  // Spread over the recording's time, not the first five frames.
  ASSERT_EQ(frame_times.size(), 5u);
  EXPECT_GT(frame_times.back() - frame_times.front(), 2 * kSecond);
  EXPECT_NE(standing.Report().find("without a whole swathe"), std::string::npos) << standing.Report();
  // The refusal names the step that removed the 2d lidar's frames and what it needs.
  const std::string why = standing.WhyNoScenes(rig.lidars[0]);
  EXPECT_NE(why.find("31 standing still"), std::string::npos) << why;
  EXPECT_NE(why.find("2d (push-broom)"), std::string::npos) << why;
  EXPECT_NE(why.find("10 m of travel"), std::string::npos) << why;
  EXPECT_EQ(standing.WhyNoScenes(rig.lidars[1]), "");
  // Camera frames with a scene, per lidar (what decides whether a preset's wide stages run).
  EXPECT_EQ(standing.FramesOf("roof"), 5);
  EXPECT_EQ(standing.FramesOf("rear"), 0);
  EXPECT_EQ(standing.FramesOf("no such lidar"), 0);
  SceneSelection stereo;  // two cameras of one frame count once
  stereo.scenes = {{"left", "roof", 10, 0.0, {}}, {"right", "roof", 10, 0.0, {}}, {"left", "roof", 20, 1.0, {}}};
  EXPECT_EQ(stereo.FramesOf("roof"), 2);

  // 3 m of travel at 1 m/s: the 10 m forward swathe never fits; the 3D lidar
  // takes the scans ahead that the trajectory has.
  const SceneSelection short_drive = SelectScenes(rig, StraightDrive(1.0, 3), images, scans, options);
  EXPECT_EQ(short_drive.cameras[0].eligible, 0);
  EXPECT_EQ(short_drive.pairs[0].scenes, 0);
  EXPECT_EQ(short_drive.pairs[1].scenes, 5);
  for (const Scene& scene : short_drive.scenes) {
    SCOPED_TRACE(scene.image_t_us);
    ASSERT_FALSE(scene.scans.empty());
    if (3 * kSecond - scene.image_t_us >= kSecond / 2) {
      // Every scan ahead of the image (forward swathe), up to the trajectory's end.
      for (const SwatheScan& scan : scene.scans) EXPECT_GE(scan.t_us, scene.image_t_us);
      const auto ahead = std::count_if(scans.at("roof").begin(), scans.at("roof").end(),
                                       [&](TimeUs t) { return t >= scene.image_t_us && t <= 3 * kSecond; });
      EXPECT_EQ(static_cast<long>(scene.scans.size()), ahead);
    } else {
      // Less than 0.5 m ahead: the nearest scan alone.
      ASSERT_EQ(scene.scans.size(), 1u);
      EXPECT_LE(std::abs(scene.scans[0].t_us - scene.image_t_us), kSecond / 20);
    }
  }

  // A drive long enough for whole swathes keeps the usual selection for both.
  const std::map<std::string, std::vector<TimeUs>> long_images = {{"left", Every(kSecond / 10, 0, 30 * kSecond)}};
  const std::map<std::string, std::vector<TimeUs>> long_scans = {
      {"rear", Every(kSecond / 10, kSecond / 50, 30 * kSecond)}, {"roof", Every(kSecond / 10, kSecond / 50, 30 * kSecond)}};
  const SceneSelection moving = SelectScenes(rig, StraightDrive(1.0, 30), long_images, long_scans, options);
  EXPECT_EQ(moving.pairs[0].scenes, 5);
  EXPECT_EQ(moving.pairs[1].scenes, 5);
  EXPECT_EQ(moving.pairs[1].short_swathe_scenes, 0);
}

// A drive with fewer whole swathes than wanted: a 3D lidar fills the count
// with the other frames (in time order, each with the travel there is); a 2D
// lidar keeps the whole swathes only; where the count is met nothing is added.
TEST(Scenes, A3dLidarFillsTheCountWithFramesWithoutAWholeSwathe) {
  const Rig rig = PushBroomAndRoofLidar();
  // 12 m at 1 m/s, an image a second: only the frames at 0, 1 and 2 m have 10 m ahead.
  const std::map<std::string, std::vector<TimeUs>> images = {{"left", Every(kSecond, 0, 12 * kSecond)}};
  const std::map<std::string, std::vector<TimeUs>> scans = {{"rear", Every(kSecond / 10, kSecond / 50, 12 * kSecond)},
                                                            {"roof", Every(kSecond / 10, kSecond / 50, 12 * kSecond)}};
  SceneOptions options;
  options.scenes_per_camera = 30;
  const Trajectory trajectory = StraightDrive(1.0, 12);
  const SceneSelection selection = SelectScenes(rig, trajectory, images, scans, options);
  EXPECT_EQ(selection.cameras[0].eligible, 3);
  EXPECT_EQ(selection.cameras[0].skipped_window_outside, 10);
  ASSERT_EQ(selection.pairs.size(), 2u);
  EXPECT_EQ(selection.pairs[0].scenes, 3) << "a 2d lidar needs the whole swathe";
  EXPECT_EQ(selection.pairs[0].short_swathe_scenes, 0);
  EXPECT_EQ(selection.pairs[1].scenes, 13);
  EXPECT_EQ(selection.pairs[1].short_swathe_scenes, 10);
  EXPECT_EQ(selection.FramesOf("roof"), 13);
  EXPECT_EQ(selection.FramesOf("rear"), 3);
  TimeUs previous = -1;
  for (const Scene& scene : selection.scenes) {
    if (scene.lidar != "roof") continue;
    SCOPED_TRACE(scene.image_t_us);
    EXPECT_GT(scene.image_t_us, previous) << "in time order";
    previous = scene.image_t_us;
    ASSERT_FALSE(scene.scans.empty());
    const double ahead_m = std::min(10.0, 12.0 - scene.distance_m);
    if (ahead_m >= 0.5) {
      // The forward swathe up to the trajectory's end (or its whole 10 m).
      EXPECT_GE(scene.scans.front().t_us, scene.image_t_us);
      EXPECT_NEAR(trajectory.DistanceAt(scene.scans.back().t_us) - scene.distance_m, ahead_m, 0.15);
    } else {
      ASSERT_EQ(scene.scans.size(), 1u) << "less than 0.5 m ahead: the nearest scan alone";
    }
  }

  options.scenes_per_camera = 3;  // the whole swathes meet the count
  const SceneSelection enough = SelectScenes(rig, trajectory, images, scans, options);
  EXPECT_EQ(enough.pairs[1].scenes, 3);
  EXPECT_EQ(enough.pairs[1].short_swathe_scenes, 0);
}

// On a drive with a stop, the frames that fill a 3D lidar's count are one
// per place (the stop's frames repeat one view), and a short swathe keeps
// one scan of those taken standing (they repeat one view) and every moving one.
TEST(Scenes, TheFillTakesOneFramePerPlaceAndOneScanPerPosition) {
  Rig rig = OneCameraOneLidar();
  rig.lidars[0].kind = LidarKind::k3d;
  const Trajectory trajectory = DriveWithStop();  // 80 m; standing at 40 m from 40 s to 60 s
  SceneOptions options;
  options.scenes_per_camera = 60;  // more than the frames with a whole swathe
  // An image every 2 s from 1 s: 10 taken standing at 40 m, 1 m from the moving frames either side.
  const std::map<std::string, std::vector<TimeUs>> images = {{"left", Every(2 * kSecond, kSecond, 100 * kSecond)}};
  const std::map<std::string, std::vector<TimeUs>> scans = {{"rear", Every(kSecond / 10, kSecond / 50, 100 * kSecond)}};
  const SceneSelection selection = SelectScenes(rig, trajectory, images, scans, options);
  ASSERT_GE(selection.cameras[0].skipped_standing_still, 8);
  ASSERT_GT(selection.pairs[0].short_swathe_scenes, 0);
  int at_the_stop = 0;
  std::vector<double> places;
  for (const Scene& scene : selection.scenes) {
    SCOPED_TRACE(scene.image_t_us);
    if (scene.image_t_us > 40 * kSecond && scene.image_t_us < 60 * kSecond) ++at_the_stop;
    for (const double place : places) EXPECT_GE(std::abs(scene.distance_m - place), 0.5) << "one frame per place";
    places.push_back(scene.distance_m);
    if (scene.distance_m + 10.0 <= 80.0) continue;  // a whole swathe: every scan of its window
    // Every scan to the drive's end, 0.1 m apart.
    ASSERT_GT(scene.scans.size(), 1u);
    EXPECT_NEAR(trajectory.DistanceAt(scene.scans.back().t_us), 80.0, 0.1);
    for (std::size_t j = 1; j < scene.scans.size(); ++j) {
      const double step_m =
          trajectory.DistanceAt(scene.scans[j].t_us) - trajectory.DistanceAt(scene.scans[j - 1].t_us);
      EXPECT_NEAR(step_m, 0.1, 1e-6);
    }
  }
  EXPECT_EQ(at_the_stop, 1) << "the stop's frames repeat one view";
  // The drive's end: the frames there fill the count, down to the last one (1 m before the end).
  EXPECT_NEAR(places.back(), 79.0, 0.05);

  // A standing scene's scans: from a frame at the stop, the window starts with one scan for the whole stop.
  options.swathe_length_m = 50.0;  // no frame after 30 m has a whole swathe: the stop's frame fills
  const SceneSelection long_swathes = SelectScenes(rig, trajectory, images, scans, options);
  bool stop_scene_seen = false;
  for (const Scene& scene : long_swathes.scenes) {
    if (std::abs(scene.distance_m - 40.0) >= 0.5 || scene.scans.empty()) continue;
    stop_scene_seen = true;
    const auto standing = std::count_if(scene.scans.begin(), scene.scans.end(), [&](const SwatheScan& scan) {
      return std::abs(trajectory.DistanceAt(scan.t_us) - 40.0) < 1e-9;
    });
    EXPECT_EQ(standing, 1) << "one scan for the 20 s standing";
    EXPECT_GT(scene.scans.size(), 100u) << "and the 40 m of travel after it, every 0.1 m";
  }
  EXPECT_TRUE(stop_scene_seen);
}

TEST(Scenes, ForwardBackwardAndBothWindows) {
  const Trajectory trajectory = DriveWithStop();
  const auto scans = Every(kSecond / 50, 0, 100 * kSecond);
  for (const SwatheDirection direction :
       {SwatheDirection::kForward, SwatheDirection::kBackward, SwatheDirection::kBoth}) {
    SceneOptions options;
    options.scenes_per_camera = 5;
    options.swathe_length_m = 5.0;
    options.direction = direction;
    const SceneSelection selection =
        SelectScenes(OneCameraOneLidar(), trajectory, {{"left", Every(kSecond / 10, 0, 100 * kSecond)}},
                     {{"rear", scans}}, options);
    ASSERT_EQ(selection.scenes.size(), 5u) << SwatheDirectionName(direction);
    for (const Scene& scene : selection.scenes) {
      ASSERT_FALSE(scene.scans.empty());
      const double before = direction == SwatheDirection::kForward ? 0.0 : 5.0;
      const double after = direction == SwatheDirection::kBackward ? 0.0 : 5.0;
      for (const SwatheScan& scan : scene.scans) {
        const double d = trajectory.DistanceAt(scan.t_us);
        EXPECT_GE(d, scene.distance_m - before - 1e-9);
        EXPECT_LE(d, scene.distance_m + after + 1e-9);
        if (direction == SwatheDirection::kForward) {
          EXPECT_GE(scan.t_us, scene.image_t_us);
        }
        if (direction == SwatheDirection::kBackward) {
          EXPECT_LE(scan.t_us, scene.image_t_us);
        }
        // Straight drive along x: the relative pose is a pure x shift of d_j - d_k.
        EXPECT_NEAR(scan.T_basek_basej.translation().x(), d - scene.distance_m, 1e-9);
      }
      // The window is filled: scans reach (within one scan spacing) both ends.
      const double first = trajectory.DistanceAt(scene.scans.front().t_us) - scene.distance_m;
      const double last = trajectory.DistanceAt(scene.scans.back().t_us) - scene.distance_m;
      EXPECT_NEAR(first, -before, 0.05);
      EXPECT_NEAR(last, after, 0.05);
    }
    ASSERT_EQ(selection.pairs.size(), 1u);
    EXPECT_EQ(selection.pairs[0].scenes, 5);
  }
}

TEST(Scenes, ScanCapThinsEvenly) {
  SceneOptions options;
  options.scenes_per_camera = 3;
  options.max_scans_per_scene = 20;
  const SceneSelection selection =
      SelectScenes(OneCameraOneLidar(), DriveWithStop(), {{"left", Every(kSecond / 10, 0, 100 * kSecond)}},
                   {{"rear", Every(kSecond / 50, 0, 100 * kSecond)}}, options);
  ASSERT_EQ(selection.scenes.size(), 3u);
  for (const Scene& scene : selection.scenes) {
    EXPECT_EQ(scene.scans.size(), 20u);
    // Evenly thinned: still spans most of the 10 m window.
    EXPECT_GT(scene.scans.back().T_basek_basej.translation().x() - scene.scans.front().T_basek_basej.translation().x(),
              8.0);
  }
}

TEST(Scenes, StaticSingleFrameDataset) {
  const TimeUs t0 = 1'418'381'798'086'398;
  const Trajectory trajectory({t0}, {Eigen::Isometry3d::Identity()});
  const SceneSelection selection = SelectScenes(OneCameraOneLidar(), trajectory, {{"left", {t0}}},
                                                {{"rear", {t0 - 5, t0, t0 + 7}}}, SceneOptions{});
  EXPECT_TRUE(selection.static_dataset);
  ASSERT_EQ(selection.scenes.size(), 1u);
  const Scene& scene = selection.scenes[0];
  EXPECT_EQ(scene.image_t_us, t0);
  ASSERT_EQ(scene.scans.size(), 1u);
  EXPECT_EQ(scene.scans[0].t_us, t0);
  EXPECT_TRUE(scene.scans[0].T_basek_basej.isApprox(Eigen::Isometry3d::Identity()));
}

TEST(Scenes, NoLidarScansInWindowIsCounted) {
  SceneOptions options;
  options.scenes_per_camera = 4;
  // Scans only during the first 20 s: later frames get none.
  const SceneSelection selection =
      SelectScenes(OneCameraOneLidar(), DriveWithStop(), {{"left", Every(kSecond / 10, 0, 100 * kSecond)}},
                   {{"rear", Every(kSecond / 50, 0, 20 * kSecond)}}, options);
  ASSERT_EQ(selection.pairs.size(), 1u);
  EXPECT_EQ(selection.pairs[0].scenes + selection.pairs[0].frames_without_scans, 4);
  EXPECT_GE(selection.pairs[0].frames_without_scans, 2);
  EXPECT_FALSE(selection.Report().empty());
}

// Circular drive (radius 20 m, 2 m/s, heading tangent): the cached relative
// poses must equal the closed-form T_world_base(t_k)^-1 * T_world_base(t_j).
TEST(Scenes, CachedRelativePoseMatchesDirectComputation) {
  const double radius = 20.0, speed = 2.0;
  const auto pose_at = [&](double t) {
    const double angle = speed * t / radius;
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = Eigen::Vector3d(radius * std::sin(angle), radius * (1.0 - std::cos(angle)), 0.1 * std::sin(t));
    pose.linear() = RotationFromRollPitchYaw(0.02 * std::sin(0.5 * t), 0.01 * t, angle);
    return pose;
  };
  std::vector<TimeUs> times;
  std::vector<Eigen::Isometry3d> poses;
  for (int i = 0; i <= 3000; ++i) {  // 30 s at 100 Hz
    times.push_back(static_cast<TimeUs>(i) * kSecond / 100);
    poses.push_back(pose_at(0.01 * i));
  }
  const Trajectory trajectory(times, poses);
  SceneOptions options;
  options.scenes_per_camera = 4;
  options.direction = SwatheDirection::kBoth;
  // Scan times off the trajectory samples, so interpolation is exercised.
  const SceneSelection selection =
      SelectScenes(OneCameraOneLidar(), trajectory, {{"left", Every(kSecond / 15, 0, 30 * kSecond)}},
                   {{"rear", Every(kSecond / 37, 3333, 30 * kSecond)}}, options);
  ASSERT_EQ(selection.scenes.size(), 4u);
  for (const Scene& scene : selection.scenes) {
    const Eigen::Isometry3d T_world_basek = pose_at(static_cast<double>(scene.image_t_us) / kSecond);
    for (const SwatheScan& scan : scene.scans) {
      const Eigen::Isometry3d direct = T_world_basek.inverse() * pose_at(static_cast<double>(scan.t_us) / kSecond);
      // Interpolating 10 ms samples of a smooth path: sub-millimetre agreement.
      EXPECT_LT(TranslationError(scan.T_basek_basej, direct), 1e-3);
      EXPECT_LT(RotationErrorDegrees(scan.T_basek_basej, direct), 1e-3);
    }
  }
}

// A known odometry scale error (--odometry-scale): the scans' poses are those
// of the trajectory with every distance stretched by 1 + scale, and their
// rotations are untouched.
TEST(Scenes, OdometryScaleStretchesTheScanPoses) {
  const auto drive = [](double stretch) {
    std::vector<TimeUs> times;
    std::vector<Eigen::Isometry3d> poses;
    for (int i = 0; i <= 2000; ++i) {  // 20 s at 100 Hz, turning and climbing
      const double t = 0.01 * i;
      Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
      pose.translation() =
          stretch * Eigen::Vector3d(30.0 * std::sin(0.1 * t), 30.0 * (1.0 - std::cos(0.1 * t)), 0.2 * t);
      pose.linear() = RotationFromRollPitchYaw(0.01 * std::sin(t), 0.005 * t, 0.1 * t);
      times.push_back(static_cast<TimeUs>(i) * kSecond / 100);
      poses.push_back(pose);
    }
    return Trajectory(times, poses);
  };
  SceneOptions options;
  options.scenes_per_camera = 3;
  const std::map<std::string, std::vector<TimeUs>> images{{"left", Every(kSecond / 2, 0, 20 * kSecond)}};
  const std::map<std::string, std::vector<TimeUs>> scans{{"rear", Every(kSecond / 50, 0, 20 * kSecond)}};
  const SceneSelection as_given = SelectScenes(OneCameraOneLidar(), drive(1.0), images, scans, options);
  const SceneSelection stretched = SelectScenes(OneCameraOneLidar(), drive(1.02), images, scans, options);
  options.odometry_scale = 0.02;
  const SceneSelection corrected = SelectScenes(OneCameraOneLidar(), drive(1.0), images, scans, options);
  ASSERT_EQ(corrected.scenes.size(), as_given.scenes.size());
  ASSERT_EQ(corrected.scenes.size(), 3u);
  std::size_t compared = 0;
  double largest_given_error = 0.0;
  for (std::size_t s = 0; s < corrected.scenes.size(); ++s) {
    const Scene& scene = corrected.scenes[s];
    ASSERT_EQ(scene.scans.size(), as_given.scenes[s].scans.size());  // the window is the trajectory's own
    for (std::size_t j = 0; j < scene.scans.size(); ++j) {
      const Eigen::Isometry3d& given = as_given.scenes[s].scans[j].T_basek_basej;
      EXPECT_NEAR((scene.scans[j].T_basek_basej.translation() - 1.02 * given.translation()).norm(), 0.0, 1e-9);
      EXPECT_LT(RotationErrorDegrees(scene.scans[j].T_basek_basej, given), 1e-9);
      // The same as a trajectory 2 % longer (compared where both windows hold the scan).
      for (const Scene& other : stretched.scenes) {
        if (other.image_t_us != scene.image_t_us) continue;
        for (const SwatheScan& scan : other.scans) {
          if (scan.t_us != scene.scans[j].t_us) continue;
          EXPECT_LT(TranslationError(scene.scans[j].T_basek_basej, scan.T_basek_basej), 1e-6);
          largest_given_error = std::max(largest_given_error, TranslationError(given, scan.T_basek_basej));
          ++compared;
        }
      }
    }
  }
  EXPECT_GT(compared, 100u);
  EXPECT_GT(largest_given_error, 0.05);  // what the scale error would have left in the swathes
}

}  // namespace
}  // namespace scenecal
