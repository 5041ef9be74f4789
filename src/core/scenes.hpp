// Scene selection (paper II-B): which camera frames k are used, and which lidar
// scans j form the swathe that is projected into each of them.
//
// Pure function of the rig, the trajectory and the sensor timestamps: no image
// or scan is read. A scene is one (camera frame, lidar) combination; its
// swathe holds the scans j of that lidar taken while the vehicle travels the
// L metres after (forward), before (backward) or around (both) time k, with
// each scan's pose relative to the camera frame's pose cached once:
//   T_basek_basej = T_world_base(t_k)^-1 * T_world_base(t_j).
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/enum_names.hpp"
#include "core/rig.hpp"
#include "core/trajectory.hpp"

namespace scenecal {

enum class SwatheDirection { kForward, kBackward, kBoth };
inline constexpr auto kSwatheDirectionNames = MakeEnumNames<SwatheDirection>(
    {{SwatheDirection::kForward, "forward"}, {SwatheDirection::kBackward, "backward"},
     {SwatheDirection::kBoth, "both"}});
// "forward" | "backward" | "both"; false for anything else.
bool ParseSwatheDirection(const std::string& name, SwatheDirection* direction);
const char* SwatheDirectionName(SwatheDirection direction);

// How the S frames per camera are chosen: spread evenly by distance (the
// paper), or the S most informative of a pool spread by distance (the pool's
// swathes are built, then core/scene_information.hpp keeps the scenes whose
// edges constrain the extrinsic most).
enum class SceneChoice { kSpread, kInformative };
inline constexpr auto kSceneChoiceNames = MakeEnumNames<SceneChoice>(
    {{SceneChoice::kSpread, "spread"}, {SceneChoice::kInformative, "informative"}});
bool ParseSceneChoice(const std::string& name, SceneChoice* choice);
const char* SceneChoiceName(SceneChoice choice);

// `--scenes auto`: from the paper's S frames per camera spread by distance,
// the informative choice keeps the fewest whose predicted variance is within
// this factor of all S frames' (its sigma within sqrt(2)). The pool is the
// spread set itself, not a larger one: picked from every frame of a drive,
// the most informative frames crowd together and the answer got worse
// (BENCHMARK.md, "Informative scenes").
inline constexpr double kAutoSceneVarianceRatio = 2.0;

struct SceneOptions {
  int scenes_per_camera = 30;        // S camera frames per camera (the paper: 30)
  SceneChoice choice = SceneChoice::kSpread;
  // informative: the pool holds this many times S frames (spread by distance).
  int informative_pool_factor = 2;
  // informative, `--scenes auto`: > 0 keeps the fewest frames (at least
  // min_auto_scenes, at most S) whose predicted variance is within this
  // factor of the whole pool's; 0 keeps S.
  double auto_variance_ratio = 0.0;
  int min_auto_scenes = 8;
  // informative, once and joint schemes: the first this many stages of the
  // schedule run on the whole pool and the choice is made at their answer
  // (at most all stages but the last). The wide blurred first stage needs
  // every frame to keep the basin (from the initial guess, 12-15 chosen
  // frames lost it on a trinocular world), and the choice is sharper from a
  // guess that is already near. alt chooses at the initial guess (its lower
  // levels may run on other ranks).
  int informative_after_stages = 1;
  double swathe_length_m = 10.0;     // L, distance travelled while the swathe is gathered (the paper: 10 m)
  SwatheDirection direction = SwatheDirection::kForward;
  // Frames taken while the base moves slower than this (m/s, averaged over
  // +-speed_window_s) are skipped: a standing vehicle builds no swathe and
  // repeats the same view.
  double min_speed_mps = 0.5;
  double speed_window_s = 0.5;
  // Cap on scans per scene (evenly thinned when exceeded); 0 = no cap.
  int max_scans_per_scene = 0;
  // A known scale error of the odometry (fraction; e.g. 0.003 when it reports
  // distances 0.3 % short): the swathes' scan poses are built with every
  // distance of the trajectory multiplied by 1 + odometry_scale. The images
  // cannot tell a scale error from a shift of the lidar along the travel, so a
  // scale known from elsewhere (GNSS, wheel odometry) belongs here.
  double odometry_scale = 0.0;

  bool IsValid(std::string* why = nullptr) const;
  // Frames per camera SelectScenes picks: S, or the informative choice's pool.
  int CandidatesPerCamera() const {
    return choice == SceneChoice::kInformative ? scenes_per_camera * informative_pool_factor : scenes_per_camera;
  }
};

// One scan of a swathe: its time and its cached pose relative to the frame.
struct SwatheScan {
  TimeUs t_us = 0;
  Eigen::Isometry3d T_basek_basej = Eigen::Isometry3d::Identity();  // base at scan time -> base at image time
};

struct Scene {
  std::string camera;
  std::string lidar;
  TimeUs image_t_us = 0;
  double distance_m = 0.0;  // distance travelled at the image time (from the trajectory start)
  std::vector<SwatheScan> scans;
};

// Counts per camera, so the CLI can say what was used and why frames were left out.
struct CameraSelectionReport {
  std::string camera;
  int images = 0;                 // image timestamps offered
  int skipped_no_pose = 0;        // outside the trajectory
  int skipped_standing_still = 0; // speed below min_speed_mps
  int skipped_window_outside = 0; // the swathe window leaves the trajectory
  int eligible = 0;
  int selected = 0;
};

struct LidarSelectionReport {
  std::string camera;
  std::string lidar;
  int scenes = 0;                // selected frames that got at least one scan of this lidar
  int frames_without_scans = 0;  // selected frames with no scan of this lidar in their window
  int scans_used = 0;            // total over scenes (a scan may serve several scenes)
  int scans_without_pose = 0;    // scans in a window but outside the trajectory
  // 3D lidar: scenes from frames without a whole swathe (standing, or near
  // the drive's ends), with the scans of the travel there is (the nearest
  // scan alone when standing). Every such frame where no frame of the camera
  // has a whole swathe; elsewhere as many as fill the wanted count.
  int short_swathe_scenes = 0;
};

struct SceneSelection {
  std::vector<Scene> scenes;  // ordered by camera, then lidar, then time
  std::vector<CameraSelectionReport> cameras;
  std::vector<LidarSelectionReport> pairs;
  bool static_dataset = false;  // one-row trajectory: scans taken at the image time
  double swathe_length_m = 0.0;      // as asked (SceneOptions)
  double trajectory_length_m = 0.0;  // distance the whole trajectory covers

  // Multi-line human-readable summary (for the CLI log).
  std::string Report() const;
  // Camera frames (distinct image times, over every camera) with a scene of this lidar.
  int FramesOf(const std::string& lidar) const;
  // Empty when the lidar has a scene; else why not, step by step: per camera
  // the images left out by each selection step, and what the lidar's kind needs.
  std::string WhyNoScenes(const LidarInfo& lidar) const;
};

// image_times_us: by camera name; scan_times_us: by lidar name; each sorted
// ascending. Cameras and lidars not in the rig are ignored.
SceneSelection SelectScenes(const Rig& rig, const Trajectory& trajectory,
                            const std::map<std::string, std::vector<TimeUs>>& image_times_us,
                            const std::map<std::string, std::vector<TimeUs>>& scan_times_us,
                            const SceneOptions& options);

}  // namespace scenecal
