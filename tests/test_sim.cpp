// The street simulator: determinism, geometric consistency of images and scans
// with the ground truth, dataset validity, and the appearance model.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include "core/geometry.hpp"
#include "io/dataset.hpp"
#include "io/error.hpp"
#include "sim/noise.hpp"
#include "sim/simulator.hpp"

namespace scenecal::sim {
namespace {
namespace fs = std::filesystem;

fs::path TempDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("scenecal_test_sim_" + std::to_string(::getpid()) + "_" + name);
  fs::remove_all(dir);
  return dir;
}

// A small, quick dataset: 320x240 images at 2 Hz, a few seconds of drive.
SimulationOptions SmallOptions(std::uint64_t seed) {
  SimulationOptions options;
  options.seed = seed;
  options.duration_s = 3.0;
  options.include_stop = false;
  options.image_width = 320;
  options.image_height = 240;
  options.image_rate_hz = 2.0;
  options.perturb_translation_m = 0.1;
  options.perturb_rotation_deg = 3.0;
  options.camera_perturb_translation_m = 0.01;
  options.camera_perturb_rotation_deg = 0.5;
  return options;
}

std::string ReadFileBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::vector<fs::path> RelativeFiles(const fs::path& root) {
  std::vector<fs::path> files;
  for (const auto& entry : fs::recursive_directory_iterator(root))
    if (entry.is_regular_file()) files.push_back(fs::relative(entry.path(), root));
  std::sort(files.begin(), files.end());
  return files;
}

// One dataset shared by the tests that only read it.
class SimulatedDataset : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = new fs::path(TempDir("shared"));
    summary_ = new SimulationSummary(Simulate(SmallOptions(7), *root_));
  }
  static void TearDownTestSuite() {
    fs::remove_all(*root_);
    delete summary_;
    delete root_;
  }
  static fs::path* root_;
  static SimulationSummary* summary_;
};
fs::path* SimulatedDataset::root_ = nullptr;
SimulationSummary* SimulatedDataset::summary_ = nullptr;

TEST(Simulator, SameSeedGivesIdenticalFilesAnotherSeedDiffers) {
  SimulationOptions options = SmallOptions(11);
  options.duration_s = 2.0;
  const fs::path a = TempDir("det_a"), b = TempDir("det_b"), c = TempDir("det_c");
  Simulate(options, a);
  {
    // A different thread count must not change a byte.
    tbb::task_arena single_thread(1);
    single_thread.execute([&] { Simulate(options, b); });
  }
  options.seed = 12;
  Simulate(options, c);
  const auto files_a = RelativeFiles(a), files_b = RelativeFiles(b);
  ASSERT_EQ(files_a, files_b);
  ASSERT_GT(files_a.size(), 10u);
  for (const fs::path& f : files_a) EXPECT_EQ(ReadFileBytes(a / f), ReadFileBytes(b / f)) << f;
  std::size_t differing = 0, compared = 0;
  for (const fs::path& f : RelativeFiles(c)) {
    // The true extrinsics are the preset's, whatever the seed.
    if (!fs::exists(a / f) || f == "ground_truth.yaml") continue;
    ++compared;
    if (ReadFileBytes(a / f) != ReadFileBytes(c / f)) ++differing;
  }
  EXPECT_GT(compared, 10u);
  EXPECT_EQ(differing, compared) << "another seed must change every data file";
  for (const auto& dir : {a, b, c}) fs::remove_all(dir);
}

TEST_F(SimulatedDataset, OpensAndEveryFileReadsBack) {
  const io::Dataset dataset = io::OpenDataset(*root_);
  ASSERT_EQ(dataset.rig.cameras.size(), 2u);
  ASSERT_EQ(dataset.rig.lidars.size(), 1u);
  EXPECT_EQ(dataset.rig.base_frame, "left");
  ASSERT_TRUE(dataset.ground_truth.has_value());
  for (const CameraInfo& camera : dataset.rig.cameras) {
    const auto& files = dataset.images.at(camera.name);
    EXPECT_EQ(files.size(), summary_->images_per_camera.at(camera.name));
    EXPECT_GE(files.size(), 5u);
    for (const io::SensorFile& file : files) {
      const GreyImage image = io::ReadImage(file, camera.model);
      EXPECT_EQ(image.intensity.cols, 320);
      EXPECT_EQ(image.intensity.rows, 240);
      EXPECT_TRUE(dataset.trajectory.PoseAt(file.t_us).has_value());
    }
  }
  const auto& scans = dataset.scans.at("lms_rear");
  EXPECT_EQ(scans.size(), summary_->scans_per_lidar.at("lms_rear"));
  std::size_t points = 0, no_returns = 0;
  for (const io::SensorFile& file : scans) {
    const LidarScan scan = io::ReadScan(file);
    EXPECT_EQ(scan.points.size() + scan.no_returns, 541u);
    for (const LidarPoint& p : scan.points) {
      EXPECT_EQ(p.z, 0.0f);  // a 2D lidar measures in its x-y plane
      EXPECT_GE(p.reflectance, 0.0f);
    }
    points += scan.points.size();
    no_returns += scan.no_returns;
  }
  EXPECT_EQ(points, summary_->lidar_returns);
  EXPECT_EQ(no_returns, summary_->lidar_no_returns);
  EXPECT_GT(no_returns, 0u) << "sky and weak returns must appear as NaN records";
  EXPECT_GT(points, 20 * no_returns / 10) << "most beams return";
}

TEST_F(SimulatedDataset, GroundTruthDiffersFromRigByTheRequestedMagnitudes) {
  const io::Dataset dataset = io::OpenDataset(*root_);
  const SimulationOptions options = SmallOptions(7);
  const GroundTruth& truth = *dataset.ground_truth;
  for (const LidarInfo& lidar : dataset.rig.lidars) {
    const Eigen::Isometry3d& T_true = truth.T_base_lidar.at(lidar.name);
    EXPECT_NEAR(TranslationError(lidar.T_base_lidar, T_true), options.perturb_translation_m, 1e-6);
    EXPECT_NEAR(RotationErrorDegrees(lidar.T_base_lidar, T_true), options.perturb_rotation_deg, 1e-5);
  }
  ASSERT_EQ(truth.T_base_camera.size(), 1u);  // the right camera; the base camera is the identity
  const CameraInfo* right = dataset.rig.FindCamera("right");
  ASSERT_NE(right, nullptr);
  const Eigen::Isometry3d& T_true = truth.T_base_camera.at("right");
  EXPECT_NEAR(T_true.translation().x(), 0.239983, 1e-9);
  EXPECT_NEAR(TranslationError(right->T_base_camera, T_true), options.camera_perturb_translation_m, 1e-6);
  EXPECT_NEAR(RotationErrorDegrees(right->T_base_camera, T_true), options.camera_perturb_rotation_deg, 1e-5);
  ASSERT_TRUE(right->T_base_camera_sigma.has_value());
  EXPECT_GT((*right->T_base_camera_sigma).minCoeff(), 0.0);
}

TEST_F(SimulatedDataset, WorldPointSeenByACameraProjectsToItsPixel) {
  const io::Dataset dataset = io::OpenDataset(*root_);
  const World& world = *summary_->world;
  int checked = 0;
  for (const char* name : {"left", "right"}) {
    const CameraInfo& camera = *dataset.rig.FindCamera(name);
    // Truth of the camera transform: ground_truth.yaml where rig.yaml is perturbed.
    const auto truth_it = dataset.ground_truth->T_base_camera.find(name);
    const Eigen::Isometry3d T_base_camera =
        truth_it != dataset.ground_truth->T_base_camera.end() ? truth_it->second : camera.T_base_camera;
    for (const io::SensorFile& file : dataset.images.at(name)) {
      const auto T_world_base = summary_->true_trajectory.PoseAt(file.t_us);
      ASSERT_TRUE(T_world_base.has_value());
      const Eigen::Isometry3d T_world_camera = *T_world_base * T_base_camera;
      for (const Eigen::Vector2d& pixel : {Eigen::Vector2d(20.3, 200.7), Eigen::Vector2d(160, 120),
                                          Eigen::Vector2d(300.5, 30.2), Eigen::Vector2d(77, 222)}) {
        const Eigen::Vector3d direction = (T_world_camera.linear() * camera.model.Unproject(pixel)).normalized();
        const auto hit = world.Intersect({T_world_camera.translation(), direction}, 400.0);
        if (!hit) continue;  // sky
        Eigen::Vector2d projected;
        ASSERT_TRUE(camera.model.Project(T_world_camera.inverse() * hit->point, &projected));
        EXPECT_LT((projected - pixel).norm(), 0.01) << name << " at " << file.t_us;
        ++checked;
      }
    }
  }
  RecordProperty("pixels_checked", std::to_string(checked));
  EXPECT_GT(checked, 30);
}

TEST_F(SimulatedDataset, LidarPointsLieOnWorldSurfacesOnlyWithTheTrueExtrinsic) {
  const io::Dataset dataset = io::OpenDataset(*root_);
  const World& world = *summary_->world;
  const double sigma = summary_->lidar_models.at("lms_rear").range_noise_m;
  // Fraction of points whose range agrees with the world within 2 sigma, and the largest disagreement.
  const auto agreement = [&](const Eigen::Isometry3d& T_base_lidar, double* worst) {
    std::size_t total = 0, close = 0;
    *worst = 0.0;
    const auto& scans = dataset.scans.at("lms_rear");
    for (std::size_t j = 0; j < scans.size(); j += 5) {
      const LidarScan scan = io::ReadScan(scans[j]);
      const Eigen::Isometry3d T_world_lidar = *summary_->true_trajectory.PoseAt(scan.t_us) * T_base_lidar;
      for (const LidarPoint& p : scan.points) {
        const Eigen::Vector3d p_world = T_world_lidar * Eigen::Vector3d(p.x, p.y, p.z);
        const Eigen::Vector3d origin = T_world_lidar.translation();
        const double measured = (p_world - origin).norm();
        const auto hit = world.Intersect({origin, (p_world - origin) / measured}, 100.0, 0.1);
        const double error = hit ? std::abs(hit->distance - measured) : 100.0;
        *worst = std::max(*worst, error);
        close += error < 2.0 * sigma;
        ++total;
      }
    }
    return static_cast<double>(close) / std::max<std::size_t>(total, 1);
  };
  double worst_true = 0.0, worst_guess = 0.0;
  const double fraction_true = agreement(dataset.ground_truth->T_base_lidar.at("lms_rear"), &worst_true);
  const double fraction_guess = agreement(dataset.rig.FindLidar("lms_rear")->T_base_lidar, &worst_guess);
  RecordProperty("fraction_true", std::to_string(fraction_true));
  RecordProperty("fraction_guess", std::to_string(fraction_guess));
  RecordProperty("worst_true_m", std::to_string(worst_true));
  EXPECT_GT(fraction_true, 0.93);  // 95.4 % of a Gaussian lies within 2 sigma
  EXPECT_LT(worst_true, 6.0 * sigma);
  EXPECT_LT(fraction_guess, 0.5) << "the perturbed initial guess must not fit the world";
}

TEST(Simulator, ReflectivityIsInformativeButNotAnAffineFunctionOfAlbedo) {
  SimulationOptions options;
  options.seed = 3;
  const World world = World::Generate(options.seed, -20.0, 200.0);
  const SimulatedRig rig = MakeRig(options);
  const Drive drive(options.seed, {});
  // Camera rays over the street from several places along the drive.
  std::vector<double> albedo, reflectivity;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1279.0), v(0.0, 959.0);
  for (double t = 1.0; t < 20.0; t += 1.0) {
    const Eigen::Isometry3d T_world_camera = drive.T_world_vehicle(t, world) * rig.T_vehicle_base;
    for (int i = 0; i < 1500; ++i) {
      const Eigen::Vector3d direction =
          (T_world_camera.linear() * rig.rig.cameras[0].model.Unproject({u(rng), v(rng)})).normalized();
      const auto hit = world.Intersect({T_world_camera.translation(), direction}, 200.0);
      if (!hit) continue;
      albedo.push_back(hit->albedo);
      reflectivity.push_back(hit->reflectivity);
    }
  }
  ASSERT_GT(albedo.size(), 10000u);
  const auto mean = [](const std::vector<double>& x) { return std::accumulate(x.begin(), x.end(), 0.0) / x.size(); };
  const double ma = mean(albedo), mr = mean(reflectivity);
  double sab = 0, saa = 0, srr = 0;
  for (std::size_t i = 0; i < albedo.size(); ++i) {
    sab += (albedo[i] - ma) * (reflectivity[i] - mr);
    saa += (albedo[i] - ma) * (albedo[i] - ma);
    srr += (reflectivity[i] - mr) * (reflectivity[i] - mr);
  }
  const double correlation = sab / std::sqrt(saa * srr);
  EXPECT_LT(std::abs(correlation), 0.9);

  // Mutual information from a 16x16 histogram over quantile bins, against shuffled pairs.
  const auto quantile_bins = [](const std::vector<double>& x) {
    std::vector<double> sorted = x;
    std::sort(sorted.begin(), sorted.end());
    std::vector<int> bins(x.size());
    for (std::size_t i = 0; i < x.size(); ++i) {
      const auto rank = std::lower_bound(sorted.begin(), sorted.end(), x[i]) - sorted.begin();
      bins[i] = static_cast<int>(16 * rank / static_cast<std::ptrdiff_t>(x.size()));
    }
    return bins;
  };
  const auto mutual_information = [](const std::vector<int>& a, const std::vector<int>& b) {
    std::vector<double> joint(256, 0.0), pa(16, 0.0), pb(16, 0.0);
    for (std::size_t i = 0; i < a.size(); ++i) {
      joint[a[i] * 16 + b[i]] += 1.0 / a.size();
      pa[a[i]] += 1.0 / a.size();
      pb[b[i]] += 1.0 / a.size();
    }
    double mi = 0.0;
    for (int i = 0; i < 16; ++i)
      for (int j = 0; j < 16; ++j)
        if (joint[i * 16 + j] > 0) mi += joint[i * 16 + j] * std::log(joint[i * 16 + j] / (pa[i] * pb[j]));
    return mi;
  };
  const std::vector<int> bins_albedo = quantile_bins(albedo), bins_reflectivity = quantile_bins(reflectivity);
  std::vector<int> shuffled = bins_reflectivity;
  std::shuffle(shuffled.begin(), shuffled.end(), rng);
  const double mi = mutual_information(bins_albedo, bins_reflectivity);
  const double mi_shuffled = mutual_information(bins_albedo, shuffled);
  ::testing::Test::RecordProperty("correlation", std::to_string(correlation));
  ::testing::Test::RecordProperty("mi_nats", std::to_string(mi));
  ::testing::Test::RecordProperty("mi_shuffled_nats", std::to_string(mi_shuffled));
  EXPECT_GT(mi, 0.1);  // nats
  EXPECT_GT(mi, 10.0 * mi_shuffled);
}

TEST(Simulator, OdometryIsExactWithoutNoiseAndDriftsWithIt) {
  SimulationOptions options = SmallOptions(21);
  options.duration_s = 6.0;
  options.image_rate_hz = 0.5;
  options.image_width = 64;
  options.image_height = 48;
  options.odometry_noise = 0.0;
  const fs::path exact_dir = TempDir("odo0"), drift_dir = TempDir("odo1");
  const SimulationSummary exact = Simulate(options, exact_dir);
  options.odometry_noise = 3.0;  // exaggerated so that a few seconds show it
  const SimulationSummary drifting = Simulate(options, drift_dir);
  const Trajectory written = io::ReadTrajectory(exact_dir / "trajectory.csv");
  double max_exact = 0.0, max_drift = 0.0;
  for (std::size_t i = 0; i < written.size(); ++i) {
    const Eigen::Isometry3d truth = *exact.true_trajectory.PoseAt(written.times_us()[i]);
    max_exact = std::max(max_exact, TranslationError(written.poses()[i], truth));
    max_drift = std::max(max_drift, TranslationError(drifting.odometry_trajectory.poses()[i], truth));
  }
  RecordProperty("max_drift_m", std::to_string(max_drift));
  EXPECT_LT(max_exact, 1e-6);
  EXPECT_GT(max_drift, 1e-3);
  EXPECT_LT(max_drift, 0.1 * drifting.distance_m);
  // rig.yaml says so.
  EXPECT_EQ(io::ReadRig(exact_dir / "rig.yaml").trajectory_source, TrajectorySource::kExact);
  EXPECT_EQ(io::ReadRig(drift_dir / "rig.yaml").trajectory_source, TrajectorySource::kVisualOdometry);
  fs::remove_all(exact_dir);
  fs::remove_all(drift_dir);
}

// The drift's parts (simulate --odometry-drift): each part left out is zero,
// the parts kept are exactly those of the whole drift, and together they add
// up to it.
TEST(Simulator, OdometryDriftPartsAreThoseOfTheWholeDrift) {
  const OdometryDrift whole(7, 1.0);
  const OdometryDrift bias_only(7, 1.0, {true, false, false});
  const OdometryDrift waves_only(7, 1.0, {false, true, false});
  const OdometryDrift rates_only(7, 1.0, {false, false, true});
  double largest_wave = 0.0, largest_rate = 0.0;
  for (double s = 0.0; s <= 400.0; s += 7.3) {
    SCOPED_TRACE(s);
    EXPECT_EQ(bias_only.ScaleError(s), bias_only.ScaleError(0.0));  // a constant
    EXPECT_EQ(bias_only.YawRateError(s), 0.0);
    EXPECT_EQ(waves_only.PitchRateError(s), 0.0);
    EXPECT_EQ(rates_only.ScaleError(s), 0.0);
    EXPECT_NEAR(bias_only.ScaleError(s) + waves_only.ScaleError(s), whole.ScaleError(s), 1e-15);
    EXPECT_EQ(rates_only.YawRateError(s), whole.YawRateError(s));
    EXPECT_EQ(rates_only.PitchRateError(s), whole.PitchRateError(s));
    largest_wave = std::max(largest_wave, std::abs(waves_only.ScaleError(s)));
    largest_rate = std::max(largest_rate, std::abs(rates_only.YawRateError(s)));
  }
  EXPECT_NE(bias_only.ScaleError(0.0), 0.0);
  EXPECT_GT(largest_wave, 1e-4);                  // a wander of tenths of a percent
  EXPECT_GT(largest_rate, RadiansFromDegrees(0.002));  // and rates of ~0.01 deg/m

  // The odometry of a drive with the rates alone keeps every step's length.
  std::vector<Eigen::Isometry3d> truth;
  std::vector<double> distance_m;
  for (int i = 0; i <= 100; ++i) {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = Eigen::Vector3d(0.5 * i, 0.0, 0.0);
    pose.linear() = Eigen::AngleAxisd(0.002 * i, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    truth.push_back(pose);
    distance_m.push_back(0.5 * i);
  }
  const std::vector<Eigen::Isometry3d> turned = rates_only.Apply(truth, distance_m);
  const std::vector<Eigen::Isometry3d> drifted = whole.Apply(truth, distance_m);
  double largest_length_change = 0.0, largest_whole_change = 0.0;
  for (std::size_t i = 0; i + 1 < truth.size(); ++i) {
    const double length = (truth[i].inverse() * truth[i + 1]).translation().norm();
    largest_length_change = std::max(
        largest_length_change, std::abs((turned[i].inverse() * turned[i + 1]).translation().norm() - length));
    largest_whole_change = std::max(
        largest_whole_change, std::abs((drifted[i].inverse() * drifted[i + 1]).translation().norm() - length));
  }
  EXPECT_LT(largest_length_change, 1e-12);
  EXPECT_GT(largest_whole_change, 1e-5);  // the whole drift does change them
  EXPECT_GT(TranslationError(turned.back(), truth.back()), 1e-3);  // and the rates still turn the drive
}

TEST(World, RaysHitTheRoadAndFacadesWhereTheGeometrySays) {
  const World world = World::Generate(9, -20.0, 120.0);
  const CentreLine& line = world.centre_line();
  // Straight down from 2 m above the centre line: the road, 2 m away, normal up.
  const Eigen::Vector2d centre = line.Position(30.0);
  const auto down = world.Intersect({Eigen::Vector3d(centre.x(), centre.y(), 2.0), -Eigen::Vector3d::UnitZ()}, 10.0);
  ASSERT_TRUE(down.has_value());
  EXPECT_NEAR(down->distance, 2.0, 1e-12);
  EXPECT_NEAR(down->normal.z(), 1.0, 1e-12);
  EXPECT_EQ(down->object, 0u);
  // Straight up from the road: sky unless under a tree or a lamp.
  int sky = 0;
  for (double s = 0.0; s < 100.0; s += 5.0) {
    const Eigen::Vector2d p = line.Position(s);
    sky += !world.Intersect({Eigen::Vector3d(p.x(), p.y(), 1.0), Eigen::Vector3d::UnitZ()}, 500.0).has_value();
  }
  EXPECT_GT(sky, 15);
  // Sideways at 1.5 m height: something (a car, a pole, a wall, a facade) within the street's width, facing back.
  int hits = 0;
  for (double s = 0.0; s < 100.0; s += 2.0) {
    const Eigen::Vector2d p = line.Position(s);
    const Eigen::Vector2d left = line.LeftNormal(s);
    const Ray ray{Eigen::Vector3d(p.x(), p.y(), 1.5), Eigen::Vector3d(left.x(), left.y(), 0.0)};
    const auto hit = world.Intersect(ray, 60.0);
    if (!hit) continue;
    ++hits;
    EXPECT_GT(hit->distance, world.layout().road_half_width - 2.5);
    EXPECT_LT(hit->normal.dot(ray.direction), 0.0);
    EXPECT_GE(hit->albedo, 0.0);
    EXPECT_LE(hit->albedo, 1.0);
    EXPECT_TRUE(world.Occluded(ray, hit->distance + 0.01));
    EXPECT_FALSE(world.Occluded(ray, hit->distance - 0.01));
  }
  EXPECT_GT(hits, 40);
}

TEST(Drive, StopsOnceAndStandsStill) {
  const Drive drive(4, {});
  const World world = World::Generate(4, -10.0, drive.total_distance_m() + 10.0);
  EXPECT_NEAR(drive.total_distance_m(), DriveOptions().distance_m, 0.1);
  double standing = 0.0, first_stop = -1.0;
  for (double t = 0.0; t < drive.duration_s(); t += 0.01) {
    if (drive.SpeedAt(t) == 0.0) {
      standing += 0.01;
      if (first_stop < 0) first_stop = t;
    }
  }
  EXPECT_NEAR(standing, DriveOptions().stop_duration_s, 0.05);
  ASSERT_GT(first_stop, 0.0);
  // The pose does not move while standing, and moves otherwise.
  const Eigen::Isometry3d a = drive.T_world_vehicle(first_stop + 0.5, world);
  const Eigen::Isometry3d b = drive.T_world_vehicle(first_stop + 2.5, world);
  EXPECT_LT(TranslationError(a, b), 1e-9);
  EXPECT_GT(TranslationError(drive.T_world_vehicle(1.0, world), drive.T_world_vehicle(2.0, world)), 2.0);
  // The road stays under the wheels: the vehicle origin is ~3 m above z = 0.
  for (double t = 0.0; t < drive.duration_s(); t += 1.0)
    EXPECT_NEAR(drive.T_world_vehicle(t, world).translation().z(), kVehicleOriginHeight, 0.035);
}

TEST(Simulator, RefusesNonEmptyOutputAndInvalidOptions) {
  SimulationOptions options = SmallOptions(5);
  options.duration_s = 1.0;
  options.image_width = 64;
  options.image_height = 48;
  const fs::path dir = TempDir("nonempty");
  fs::create_directories(dir);
  std::ofstream(dir / "keep.txt") << "user data";
  EXPECT_THROW(Simulate(options, dir), io::InputError);
  EXPECT_TRUE(fs::exists(dir / "keep.txt"));
  options.overwrite = true;
  Simulate(options, dir);
  EXPECT_FALSE(fs::exists(dir / "keep.txt"));
  EXPECT_TRUE(fs::exists(dir / "rig.yaml"));
  // No temporary folder is left next to the output.
  for (const auto& entry : fs::directory_iterator(dir.parent_path()))
    EXPECT_EQ(entry.path().filename().string().find(".scenecal_test_sim_" + std::to_string(::getpid())),
              std::string::npos);
  fs::remove_all(dir);

  std::string why;
  SimulationOptions bad;
  bad.speed_mps = -1.0;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_NE(why.find("speed"), std::string::npos);
  bad = SimulationOptions();
  bad.perturb_rotation_deg = 200.0;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_TRUE(SimulationOptions().IsValid(&why));
  EXPECT_THROW(Simulate(bad, TempDir("bad")), io::InputError);
}

TEST(Simulator, PresetsHaveTheirSensors) {
  SimulationOptions options;
  options.preset = Preset::kTrinocular;
  const SimulatedRig trinocular = MakeRig(options);
  ASSERT_EQ(trinocular.rig.cameras.size(), 3u);
  EXPECT_NEAR(trinocular.rig.cameras[2].T_base_camera.translation().x(), 0.24, 1e-12);
  ASSERT_EQ(trinocular.rig.lidars.size(), 2u);
  options.preset = Preset::kSpin3d;
  const SimulatedRig spin = MakeRig(options);
  ASSERT_EQ(spin.rig.lidars.size(), 1u);
  EXPECT_EQ(spin.rig.lidars[0].kind, LidarKind::k3d);
  // The spinning lidar sits above the cameras (camera y points down), level, its z axis up (V z is down).
  EXPECT_LT(spin.rig.lidars[0].T_base_lidar.translation().y(), 0.0);
  EXPECT_NEAR((spin.T_vehicle_base * spin.rig.lidars[0].T_base_lidar).linear().col(2).z(), -1.0, 1e-12);
  // The front push-broom lidar of the trinocular rig also looks down at the road, in front of the rear one.
  const Eigen::Isometry3d T_vehicle_front = trinocular.T_vehicle_base * trinocular.rig.lidars[1].T_base_lidar;
  EXPECT_GT(T_vehicle_front.linear().col(0).z(), 0.99);
  EXPECT_NEAR(T_vehicle_front.translation().x(), 1.7589, 1e-9);
  options.preset = Preset::kRobotCar;
  const SimulatedRig robotcar = MakeRig(options);
  // The rear lidar is ~4.3 m behind the cameras.
  EXPECT_NEAR((robotcar.T_vehicle_base * robotcar.rig.lidars[0].T_base_lidar).translation().x(), -2.585, 1e-9);
  // Its +x axis points down at the road (V z is down).
  const Eigen::Vector3d x_axis_in_vehicle =
      (robotcar.T_vehicle_base * robotcar.rig.lidars[0].T_base_lidar).linear().col(0);
  EXPECT_GT(x_axis_in_vehicle.z(), 0.99);
}

TEST(Simulator, CommandLineWritesADatasetAndRefusesToOverwrite) {
  const fs::path dir = TempDir("cli");
  const std::string command = std::string(SCENECAL_CLI_PATH) + " -q simulate --preset spin3d --seed 3 --duration 1.5 " +
                              "--image-size 64x48 --no-stop --output " + dir.string();
  FILE* pipe = popen((command + " 2>/dev/null").c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string out;
  char buffer[512];
  while (fgets(buffer, sizeof buffer, pipe)) out += buffer;
  EXPECT_EQ(pclose(pipe), 0);
  EXPECT_NE(out.find("spin3d"), std::string::npos) << out;
  EXPECT_TRUE(fs::exists(dir / "lidars" / "spin"));
  const io::Dataset dataset = io::OpenDataset(dir);
  EXPECT_EQ(dataset.rig.lidars.at(0).kind, LidarKind::k3d);
  EXPECT_GT(io::ReadScan(dataset.scans.at("spin").front()).points.size(), 5000u);
  const int again = std::system((command + " >/dev/null 2>&1").c_str());
  EXPECT_TRUE(WIFEXITED(again));
  EXPECT_EQ(WEXITSTATUS(again), 2);
  const int bad_size = std::system((std::string(SCENECAL_CLI_PATH) + " simulate --image-size 64by48 --output " +
                                    TempDir("cli_bad").string() + " >/dev/null 2>&1").c_str());
  EXPECT_EQ(WEXITSTATUS(bad_size), 2);
  fs::remove_all(dir);
}

// --vignetting changes only the fall-off towards the corners: without it the
// corners are brighter than with the default, the centre is the same.
TEST(Simulator, CommandLineVignettingDarkensOnlyTheCorners) {
  const auto simulate = [](const std::string& extra, const fs::path& dir) {
    return std::system((std::string(SCENECAL_CLI_PATH) +
                        " -q simulate --preset robotcar --seed 4 --duration 1.5 --image-size 160x120 --no-stop " +
                        extra + " --output " + dir.string() + " >/dev/null 2>&1")
                           .c_str());
  };
  const fs::path vignetted = TempDir("vignetting_default"), flat = TempDir("vignetting_none");
  ASSERT_EQ(simulate("", vignetted), 0);
  ASSERT_EQ(simulate("--vignetting 0", flat), 0);
  const io::Dataset a = io::OpenDataset(vignetted), b = io::OpenDataset(flat);
  const CameraModel& model = a.rig.cameras.at(0).model;
  const cv::Mat image_a = io::ReadImage(a.images.at("left").front(), model).intensity;
  const cv::Mat image_b = io::ReadImage(b.images.at("left").front(), model).intensity;
  double centre = 0.0, corners = 0.0;
  int centre_count = 0, corner_count = 0;
  for (int v = 0; v < image_a.rows; ++v) {
    for (int u = 0; u < image_a.cols; ++u) {
      const double du = (u - 79.5) / 80.0, dv = (v - 59.5) / 60.0;
      const double difference = image_b.at<float>(v, u) - image_a.at<float>(v, u);
      if (du * du + dv * dv < 0.04) {
        centre += std::abs(difference);
        ++centre_count;
      } else if (std::abs(du) > 0.8 && std::abs(dv) > 0.8) {
        corners += difference;
        ++corner_count;
      }
    }
  }
  ASSERT_GT(centre_count, 100);
  ASSERT_GT(corner_count, 100);
  EXPECT_LT(centre / centre_count, 0.01);
  EXPECT_GT(corners / corner_count, 0.03);
  EXPECT_EQ(WEXITSTATUS(simulate("--vignetting 2", TempDir("vignetting_bad"))), 2);
  fs::remove_all(vignetted);
  fs::remove_all(flat);
}

// The push-broom lidar's reflectance falls with the incidence angle and the
// range; ideal_reflectance removes both trends and nothing else: the scan of
// the same rays (same noise keys) without them, times cos(incidence)^0.8 x
// the range factor, is the default scan.
TEST(Simulator, IdealReflectanceRemovesOnlyTheIncidenceAndRangeTrends) {
  SimulationOptions options;
  options.seed = 3;
  const World world = World::Generate(options.seed, -20.0, 200.0);
  const Drive drive(options.seed, {});
  const SimulatedRig rig = MakeRig(options);
  options.ideal_reflectance = true;
  const SimulatedRig ideal_rig = MakeRig(options);
  const LidarModel& model = rig.lidar_models.at("lms_rear");
  const LidarModel& ideal = ideal_rig.lidar_models.at("lms_rear");
  EXPECT_EQ(ideal.incidence_exponent, 0.0);
  EXPECT_FALSE(std::isfinite(ideal.range_falloff_m));
  int compared = 0, far_compared = 0;
  for (double t = 2.0; t < 12.0; t += 1.0) {
    const Eigen::Isometry3d T_world_lidar =
        drive.T_world_vehicle(t, world) * rig.T_vehicle_base * rig.rig.lidars.at(0).T_base_lidar;
    const std::uint64_t key = HashKey(options.seed, static_cast<std::uint64_t>(t));
    const std::vector<LidarPoint> scan = ScanLidar(world, model, T_world_lidar, key);
    const std::vector<LidarPoint> ideal_scan = ScanLidar(world, ideal, T_world_lidar, key);
    ASSERT_EQ(scan.size(), ideal_scan.size());
    for (std::size_t b = 0; b < scan.size(); ++b) {
      if (!std::isfinite(scan[b].x) || !std::isfinite(ideal_scan[b].x)) continue;
      ASSERT_EQ(scan[b].x, ideal_scan[b].x);  // the same geometry
      if (ideal_scan[b].reflectance < 0.1f * static_cast<float>(model.reflectance_scale)) continue;  // additive noise
      const Eigen::Vector3d beam = T_world_lidar.linear() * model.beam_directions[b];
      const auto hit = world.Intersect({T_world_lidar.translation(), beam}, model.max_range_m, model.min_range_m);
      ASSERT_TRUE(hit.has_value());
      const double cos_incidence = std::abs(hit->normal.dot(beam));
      const double range_factor = 1.0 / (1.0 + std::pow(hit->distance / model.range_falloff_m, 2));
      const double expected = std::pow(cos_incidence, 0.8) * range_factor;
      // Both share the multiplicative and the additive noise draws: the difference left is
      // 0.004 x scale x g x (1 - expected) with g standard normal, below 0.02 x scale at 5 sigma.
      EXPECT_NEAR(scan[b].reflectance, expected * ideal_scan[b].reflectance, 0.02 * model.reflectance_scale)
          << "beam " << b;
      ++compared;
      if (hit->distance > 10.0) ++far_compared;
    }
  }
  EXPECT_GT(compared, 1000);
  EXPECT_GT(far_compared, 10);
}

}  // namespace
}  // namespace scenecal::sim
