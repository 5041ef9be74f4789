// The uncertainty estimate (core/uncertainty.hpp) on a small simulated
// RobotCar dataset with exact odometry: a finite 1-sigma where the cost curves,
// a larger one from fewer scenes, undetermined directions when the search
// cannot show a rise, refusal with too few scenes; the CLI writes it.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include "core/basin_check.hpp"
#include "core/calibrate.hpp"
#include "core/nelder_mead.hpp"
#include "core/uncertainty.hpp"
#include "io/dataset.hpp"
#include "support/small_dataset.hpp"

namespace scenecal {
namespace {

namespace fs = std::filesystem;

class UncertaintyOnSimulation : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = fs::temp_directory_path() / ("scenecal_test_uncertainty_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_);
    dataset_ = test::SharedSmallRobotCar();
  }
  static void TearDownTestSuite() { fs::remove_all(root_); }

  // Every camera's pair with the rear lidar, B-spline binning, `scenes` scenes per camera, visibility at the truth.
  struct PairsAtTruth {
    CalibrationInput input;
    Eigen::Isometry3d truth;
    std::vector<std::unique_ptr<PairCost>> costs;
    std::vector<const PairCost*> pairs;
  };
  static PairsAtTruth BuildAtTruth(int scenes) {
    const io::Dataset dataset = io::OpenDataset(dataset_);
    CalibrationOptions options;
    options.scenes.scenes_per_camera = scenes;
    options.cost.histogram.binning = Binning::kBSpline;
    PairsAtTruth built{test::LoadCalibrationInput(dataset, options.scenes),
                       dataset.ground_truth->T_base_lidar.at("lms_rear"), {}, {}};
    for (const CameraInfo& camera : built.input.rig.cameras) {
      built.costs.push_back(std::make_unique<PairCost>(BuildPairCost(built.input, camera, "lms_rear", options)));
      built.costs.back()->RefreshVisibility(camera.T_camera_base() * built.truth);
      built.pairs.push_back(built.costs.back().get());
    }
    return built;
  }

  // The estimate at the truth from `scenes` scenes per camera.
  static LidarUncertainty AtTruth(int scenes, const UncertaintyOptions& uncertainty_options = {}) {
    const PairsAtTruth built = BuildAtTruth(scenes);
    return EstimateLidarUncertainty(built.pairs, built.truth, uncertainty_options);
  }

  static fs::path root_;
  static fs::path dataset_;
};

fs::path UncertaintyOnSimulation::root_;
fs::path UncertaintyOnSimulation::dataset_;

TEST_F(UncertaintyOnSimulation, FiniteSigmaAtTheTruth) {
  const LidarUncertainty estimate = AtTruth(24);
  ASSERT_TRUE(estimate.estimated) << estimate.why;
  EXPECT_GE(estimate.units, 20);
  ASSERT_EQ(estimate.directions.size(), 6u);
  int determined = 0;
  for (const UncertainDirection& d : estimate.directions) {
    if (!d.determined) continue;
    ++determined;
    EXPECT_GT(d.sigma_units, 0.0);
    EXPECT_LT(d.sigma_units, 16.0);
  }
  // The lateral translation and the yaw of a push-broom swathe on a street are
  // always visible (lane lines); at least these directions must be determined.
  EXPECT_GE(determined, 3);
  // Directions: unit norm in the 1 cm ~ 0.1 deg scaling, mutually orthogonal.
  Vector6d scale;
  scale << Eigen::Vector3d::Constant(0.01), Eigen::Vector3d::Constant(RadiansFromDegrees(0.1));
  for (std::size_t i = 0; i < 6; ++i) {
    const Vector6d xi = estimate.directions[i].direction.cwiseQuotient(scale);
    EXPECT_NEAR(xi.norm(), 1.0, 1e-9);
    for (std::size_t j = i + 1; j < 6; ++j) {
      EXPECT_NEAR(xi.dot(estimate.directions[j].direction.cwiseQuotient(scale)), 0.0, 1e-9);
    }
  }
  if (estimate.determined) {
    for (int i = 0; i < 6; ++i) {
      EXPECT_TRUE(std::isfinite(estimate.sigma_tuple[i]));
      EXPECT_GT(estimate.sigma_tuple[i], 0.0);
    }
    EXPECT_LT(estimate.sigma_tuple.head<3>().maxCoeff(), 0.16);
  }
}

TEST_F(UncertaintyOnSimulation, FewerScenesGiveALargerSigma) {
  // 8 instead of 21 scenes (all a 120 m drive offers) widen each direction,
  // but by less than sqrt(21 / 8) = 1.6: the 21 scenes lie closer than their
  // swathes are long and share points, and the long-run variance counts their
  // correlation (measured: 1.14; 1.37 when the scenes were taken as
  // independent). A sigma estimated from 8 scenes is itself uncertain (~25 %
  // per direction), so the test takes the median ratio over the six directions.
  const LidarUncertainty many = AtTruth(24);
  const LidarUncertainty few = AtTruth(8);
  ASSERT_TRUE(many.estimated) << many.why;
  ASSERT_TRUE(few.estimated) << few.why;
  EXPECT_EQ(few.units, 8);
  EXPECT_GT(many.units, 2 * few.units);
  std::vector<double> ratios;
  for (std::size_t i = 0; i < 6; ++i) {
    ASSERT_TRUE(many.directions[i].determined && few.directions[i].determined) << "direction " << i;
    ratios.push_back(few.directions[i].sigma_units / many.directions[i].sigma_units);
  }
  std::sort(ratios.begin(), ratios.end());
  const double median = 0.5 * (ratios[2] + ratios[3]);
  EXPECT_GT(median, 1.05);
  EXPECT_LT(median, 2.6);
}

// Where the basin check ran, a side of the search stops once two steps in a
// row rose significantly: the same sigmas as the full search (no cost comes
// back within k further out on this drive), on fewer evaluations.
TEST_F(UncertaintyOnSimulation, StoppingAtAConfirmedRiseKeepsTheSigmas) {
  const LidarUncertainty full = AtTruth(24);
  UncertaintyOptions stopping;
  stopping.search_past_rise = false;
  const LidarUncertainty stopped = AtTruth(24, stopping);
  ASSERT_TRUE(full.estimated && stopped.estimated) << full.why << stopped.why;
  ASSERT_EQ(full.directions.size(), stopped.directions.size());
  for (std::size_t i = 0; i < full.directions.size(); ++i) {
    EXPECT_EQ(full.directions[i].determined, stopped.directions[i].determined) << "direction " << i;
    EXPECT_DOUBLE_EQ(full.directions[i].sigma_units, stopped.directions[i].sigma_units) << "direction " << i;
  }
  // 1 + 42 for the Hessian, then 7 steps a side in full.
  EXPECT_EQ(full.evaluations, 1 + 42 + 6 * 2 * 7);
  EXPECT_LT(stopped.evaluations, full.evaluations - 12);
}

// edge_information_d in the base axes against each camera's own information
// (SceneSwathe::AlignmentInformation, camera axes) with the change carried
// into the camera by the library's own transform updates: the same squared
// misalignment for any d, and a sensible size for a 0.1 deg turn.
TEST_F(UncertaintyOnSimulation, EdgeInformationIsTheCamerasMisalignmentOfAChange) {
  const PairsAtTruth built = BuildAtTruth(8);
  const std::vector<const PairCost*>& pairs = built.pairs;
  const Eigen::Isometry3d& truth = built.truth;
  const LidarUncertainty estimate = EstimateLidarUncertainty(pairs, truth, {});
  ASSERT_TRUE(estimate.estimated) << estimate.why;
  const Matrix6d& information = estimate.edge_information_d;
  EXPECT_LT((information - information.transpose()).norm(), 1e-9 * information.norm());
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Matrix6d>(information).eigenvalues()[0], 0.0);
  constexpr double kStep = 1e-6;
  for (int trial = 0; trial < 4; ++trial) {
    Vector6d d = Vector6d::Random();
    d.head<3>() *= 0.01;                       // ~1 cm
    d.tail<3>() *= RadiansFromDegrees(0.1);    // ~0.1 deg
    double squared = 0.0, weight = 0.0;
    for (const PairCost* pair : pairs) {
      const Eigen::Isometry3d T_camera_lidar = pair->Camera().T_camera_base() * truth;
      const Eigen::Isometry3d moved = pair->Camera().T_camera_base() *
                                      ApplyTransformUpdate(truth, kStep * d, TransformUpdate::kAboutSourcePoint);
      const Vector6d d_camera =
          TransformUpdateBetween(T_camera_lidar, moved, TransformUpdate::kAboutSourcePoint) / kStep;
      double pair_weight = 0.0;
      const Matrix6d pair_information = pair->AlignmentInformation(T_camera_lidar, &pair_weight);
      squared += d_camera.dot(pair_information * d_camera);
      weight += pair_weight;
    }
    ASSERT_GT(weight, 0.0);
    EXPECT_NEAR(d.dot(information * d), squared / weight, 1e-6 * squared / weight) << "d " << d.transpose();
  }
  // A 0.1 deg turn about the base's vertical axis moves the edges by about f x 0.1 deg (more towards the image's
  // sides, and the lidar origin's offset from the camera adds a shift), a fair fraction of it normal to them:
  // pixels, not millimetres or radians.
  const Vector6d turn = Vector6d::Unit(5) * RadiansFromDegrees(0.1);
  const double focal_px = built.input.rig.cameras.front().model.fx;
  const double rms_px = std::sqrt(turn.dot(information * turn));
  EXPECT_LT(rms_px, 3.0 * focal_px * RadiansFromDegrees(0.1));
  EXPECT_GT(rms_px, 0.1 * focal_px * RadiansFromDegrees(0.1));
}

TEST_F(UncertaintyOnSimulation, NoRiseWithinTheSearchIsUndetermined) {
  UncertaintyOptions tiny;
  tiny.max_search_units = 0.25;  // 2.5 mm / 0.025 deg: the cost cannot rise significantly
  tiny.significance = 50.0;
  const LidarUncertainty estimate = AtTruth(24, tiny);
  ASSERT_TRUE(estimate.estimated) << estimate.why;
  EXPECT_FALSE(estimate.determined);
  EXPECT_NE(estimate.why.find("does not rise significantly"), std::string::npos) << estimate.why;
  EXPECT_EQ(estimate.sigma_tuple, Vector6d::Zero());
}

TEST_F(UncertaintyOnSimulation, TooFewScenesAreRefused) {
  UncertaintyOptions options;
  options.min_units = 50;
  const LidarUncertainty estimate = AtTruth(8, options);
  EXPECT_FALSE(estimate.estimated);
  EXPECT_NE(estimate.why.find("needs at least 50"), std::string::npos) << estimate.why;
}

TEST_F(UncertaintyOnSimulation, CliWritesTheEstimate) {
  const fs::path output = root_ / "result.yaml";
  const std::string command = std::string(SCENECAL_CLI_PATH) + " calibrate " + dataset_.string() +
                              " --output " + output.string() +
                              " --setting paper --scheme joint --scenes 12 --stages 1 --max-iterations 30"
                              " --odometry-scale-sigma 0.3 > " +
                              (root_ / "out.txt").string() + " 2> " + (root_ / "log.txt").string();
  ASSERT_EQ(std::system(command.c_str()), 0);
  const YAML::Node result = YAML::LoadFile(output.string());
  const YAML::Node entry = result["uncertainty"]["lms_rear"];
  ASSERT_TRUE(entry.IsMap());
  EXPECT_TRUE(entry["estimated"].as<bool>());
  EXPECT_EQ(entry["scenes"].as<int>(), 12);
  EXPECT_EQ(entry["directions"].size(), 6u);
  // The basin check ran, so the search stopped each side at a confirmed rise (a full search takes 127).
  if (entry["determined"].as<bool>()) {
    EXPECT_LT(entry["evaluations"].as<int>(), 127);
  }
  // The local sigma is there exactly when every direction is determined.
  EXPECT_EQ(entry["local_sigma_tuple"].IsDefined(), entry["determined"].as<bool>());
  // FORMAT.md's sigma and covariance of the result: local + the basin check's restarts, so at least the local
  // sigma on every axis; a verdict, and the error against the truth in sigmas on stdout.
  const YAML::Node lidar = result["lidars"]["lms_rear"];
  ASSERT_TRUE(lidar["sigma"].IsSequence());
  ASSERT_EQ(lidar["covariance"].size(), 6u);
  for (int k = 0; k < 6; ++k) {
    EXPECT_NEAR(lidar["covariance"][k][k].as<double>(), std::pow(lidar["sigma"][k].as<double>(), 2), 1e-15);
    if (entry["determined"].as<bool>()) {
      EXPECT_GE(lidar["sigma"][k].as<double>(), entry["local_sigma_tuple"][k].as<double>() * (1.0 - 1e-9));
    }
  }
  const std::string verdict = entry["verdict"].as<std::string>();
  EXPECT_TRUE(verdict == "good" || verdict == "weak" || verdict == "unreliable") << verdict;
  EXPECT_EQ(verdict != "good", entry["verdict_reason"].IsDefined());
  std::ifstream printed(root_ / "out.txt");
  const std::string out((std::istreambuf_iterator<char>(printed)), std::istreambuf_iterator<char>());
  const std::string sigmas_line = "lidar lms_rear T_base_lidar error in sigmas: Mahalanobis ";
  const std::size_t sigmas = out.find(sigmas_line);
  ASSERT_NE(sigmas, std::string::npos) << out;
  // Inside or outside the 95 % ellipsoid, as the distance says.
  const double mahalanobis = std::stod(out.substr(sigmas + sigmas_line.size()));
  EXPECT_NE(out.find(mahalanobis <= 3.55 ? "(inside the 95 % ellipsoid: <= 3.55)"
                                         : "(outside the 95 % ellipsoid: > 3.55)",
                     sigmas),
            std::string::npos)
      << out;
  // The size of a 1-pixel misalignment of the edges, and the error in those pixels.
  ASSERT_TRUE(entry["edge_pixel_covariance"].IsSequence());
  EXPECT_EQ(entry["edge_pixel_covariance"].size(), 36u);
  EXPECT_NE(out.find("lidar lms_rear T_base_lidar error in pixels: "), std::string::npos) << out;
  // The weakest direction in words, in the base camera's axes.
  EXPECT_NE(entry["weakest_direction"].as<std::string>().find(" the base camera's "), std::string::npos)
      << entry["weakest_direction"];
  // A scale error of the trajectory given: the basin check's run with longer distances, and its part of the sigma.
  EXPECT_EQ(result["settings"]["trajectory_scale_sigma"].as<std::string>(), "0.3 % (--odometry-scale-sigma)");
  const YAML::Node scale_run = result["basin_check"]["lms_rear"]["scale_run"];
  ASSERT_TRUE(scale_run.IsMap());
  EXPECT_DOUBLE_EQ(scale_run["scale_sigma_percent"].as<double>(), 0.3);
  EXPECT_NE(entry["sigma_method"].as<std::string>().find("+ the answer's move under a 0.30 % scale error of the "
                                                         "trajectory (basin_check.lms_rear.scale_run)"),
            std::string::npos)
      << entry["sigma_method"];
  EXPECT_EQ(result["settings"]["occlusion"].as<std::string>(), "zbuffer (cell width/80 px, margin 0.2 x depth + 0.3 m)");
  // And --no-uncertainty leaves it out (here with other z-buffer settings, recorded as given).
  const std::string skip = std::string(SCENECAL_CLI_PATH) + " calibrate " + dataset_.string() +
                           " --output " + output.string() +
                           " --setting paper --scheme joint --scenes 12 --stages 1 --max-iterations 30 --no-uncertainty"
                           " --occlusion-cell 12 --occlusion-margin 0.1 --occlusion-margin-abs 0.25"
                           " --refresh-border 16 --min-range 2 --max-range 40 > /dev/null 2>&1";
  ASSERT_EQ(std::system(skip.c_str()), 0);
  const YAML::Node skipped = YAML::LoadFile(output.string());
  EXPECT_FALSE(skipped["uncertainty"].IsDefined());
  EXPECT_FALSE(skipped["lidars"]["lms_rear"]["sigma"].IsDefined());
  EXPECT_EQ(skipped["settings"]["occlusion"].as<std::string>(), "zbuffer (cell 12 px, margin 0.1 x depth + 0.25 m)");
  EXPECT_EQ(skipped["settings"]["refresh_border_px"].as<double>(), 16.0);
  EXPECT_EQ(result["settings"]["refresh_border_px"].as<double>(), 0.0);
  EXPECT_EQ(skipped["settings"]["lidar_range_m"].as<std::string>(), "2 .. 40");
  EXPECT_EQ(result["settings"]["lidar_range_m"].as<std::string>(), "1 .. 100");
}

// A local estimate determined along each tuple axis with this sigma (in units).
LidarUncertainty DeterminedAlongEachAxis(const UncertaintyOptions& units, double sigma_units) {
  LidarUncertainty local;
  local.estimated = local.determined = true;
  for (int k = 0; k < 6; ++k) {
    UncertainDirection direction;
    direction.direction = Vector6d::Unit(k) * (k < 3 ? units.unit_translation_m : units.unit_rotation_rad);
    direction.determined = true;
    direction.sigma_units = sigma_units;
    local.directions.push_back(direction);
  }
  return local;
}

// The error estimate: local + the basin restarts' second moment + other
// answers' offsets, mapped to the tuple; the verdict from 2 sigma against
// 1 cm / 0.2 deg, `unreliable` for a flat direction or a drifting trajectory.
// A basin check whose six restarts all ended at the answer.
LidarBasinCheck EveryRestartCameBack(const Eigen::Isometry3d& answer) {
  LidarBasinCheck check;
  check.checked = true;
  for (int i = 0; i < 6; ++i) {
    BasinRestart restart;
    restart.T_base_lidar_end = answer;
    check.restarts.push_back(restart);
  }
  return check;
}

TEST(ErrorEstimate, SumsItsPartsAndJudges) {
  const UncertaintyOptions units;
  const Eigen::Isometry3d answer = TransformFromTuple((Vector6d() << 1.0, 0.2, 0.5, 0.0, 0.1, 0.3).finished());
  LidarUncertainty local = DeterminedAlongEachAxis(units, 0.1);  // 1 mm, 0.01 deg
  LidarErrorEstimate estimate = EstimateLidarError(answer, local, nullptr, {}, false, units);
  ASSERT_TRUE(estimate.estimated);
  EXPECT_NEAR(estimate.covariance_d(0, 0), 1e-6, 1e-12);
  EXPECT_NEAR(estimate.sigma_tuple[0], 1e-3, 1e-9);  // translation maps one to one
  EXPECT_DOUBLE_EQ(estimate.share_local, 1.0);
  // Small, but without a basin check not `good`: the local spread cannot see a flat valley.
  EXPECT_EQ(estimate.verdict, Verdict::kWeak);
  EXPECT_NE(estimate.verdict_reason.find("basin check did not run"), std::string::npos) << estimate.verdict_reason;
  LidarBasinCheck unchecked;  // skipped (time budget): as if absent
  EXPECT_EQ(EstimateLidarError(answer, local, &unchecked, {}, false, units).verdict, Verdict::kWeak);
  // With restarts that all came back to the answer it is.
  const LidarBasinCheck came_back = EveryRestartCameBack(answer);
  estimate = EstimateLidarError(answer, local, &came_back, {}, false, units);
  EXPECT_EQ(estimate.verdict, Verdict::kGood);
  EXPECT_TRUE(estimate.verdict_reason.empty()) << estimate.verdict_reason;

  // Two basin restarts ending 2 cm either side along y: their second moment adds (2 cm)^2.
  LidarBasinCheck basin;
  basin.checked = true;
  for (const double sign : {-1.0, 1.0}) {
    BasinRestart restart;
    restart.T_base_lidar_end = ApplyTransformUpdate(answer, Vector6d::Unit(1) * 0.02 * sign,
                                                    TransformUpdate::kAboutSourcePoint);
    basin.restarts.push_back(restart);
  }
  estimate = EstimateLidarError(answer, local, &basin, {}, false, units);
  EXPECT_NEAR(estimate.covariance_d(1, 1), 1e-6 + 4e-4, 1e-10);
  EXPECT_EQ(estimate.verdict, Verdict::kWeak);  // 2 sigma = 4 cm along y
  EXPECT_NE(estimate.verdict_reason.find("dy +2.00"), std::string::npos) << estimate.verdict_reason;
  // The same ends stopped once back near the answer: where they stopped is the stopping rule's, and they
  // count as the answer.
  LidarBasinCheck stopped_back = basin;
  stopped_back.T_base_lidar_calibrated = answer;  // as CheckLidarBasin records it
  for (BasinRestart& restart : stopped_back.restarts) restart.came_back = true;
  estimate = EstimateLidarError(answer, local, &stopped_back, {}, false, units);
  EXPECT_NEAR(estimate.covariance_d(1, 1), 1e-6, 1e-12);
  EXPECT_DOUBLE_EQ(estimate.share_basin, 0.0);
  for (const Eigen::Isometry3d& end : EndsBesideAnswer(stopped_back)) {
    EXPECT_TRUE(end.isApprox(answer));
  }

  // Another answer 0.5 deg away under another trajectory model, with drift.
  const Eigen::Isometry3d other =
      ApplyTransformUpdate(answer, Vector6d::Unit(4) * RadiansFromDegrees(0.5), TransformUpdate::kAboutSourcePoint);
  estimate = EstimateLidarError(answer, local, nullptr, {other}, true, units);
  // 0.5 deg = 5 units, 50 local sigmas: along it (0.5 deg)^2, and 50^2/6 local variances (here 25/6 units^2)
  // spread over every direction.
  const double unit_r = units.unit_rotation_rad, unit_t = units.unit_translation_m;
  EXPECT_NEAR(estimate.covariance_d(4, 4),
              std::pow(RadiansFromDegrees(0.01), 2) + std::pow(RadiansFromDegrees(0.5), 2) + 25.0 / 6.0 * unit_r * unit_r,
              1e-12);
  EXPECT_NEAR(estimate.covariance_d(0, 0), 1e-6 + 25.0 / 6.0 * unit_t * unit_t, 1e-12);
  EXPECT_EQ(estimate.verdict, Verdict::kUnreliable);
  EXPECT_GT(estimate.share_other_model, 0.99);
  // The other answer lies within 1 sigma along its own direction.
  EXPECT_LT(std::sqrt(TupleMahalanobisSquared(other, answer, estimate.covariance_tuple)), 1.0);
  // A local estimate ten times wider along z than elsewhere: the spread follows its shape, sized by the
  // offset's Mahalanobis length (5 units at 0.1 units sigma: 50), not by the units' scaling.
  LidarUncertainty oblong = DeterminedAlongEachAxis(units, 0.1);
  oblong.directions[2].sigma_units = 1.0;
  estimate = EstimateLidarError(answer, oblong, nullptr, {other}, false, units);
  const double spread = 50.0 * 50.0 / 6.0;  // times the local variance
  EXPECT_NEAR(estimate.covariance_d(2, 2), (1.0 + spread) * unit_t * unit_t, 1e-12);
  EXPECT_NEAR(estimate.covariance_d(0, 0), (1.0 + spread) * 0.01 * unit_t * unit_t, 1e-12);
  EXPECT_NEAR(estimate.covariance_d(4, 4),
              std::pow(RadiansFromDegrees(0.5), 2) + (1.0 + spread) * 0.01 * unit_r * unit_r, 1e-12);
  EXPECT_NEAR(estimate.covariance_d(0, 2), 0.0, 1e-15);
  EXPECT_EQ(estimate.verdict, Verdict::kWeak);
  // A drifting trajectory whose model's effect was not measured is never `good`.
  estimate = EstimateLidarError(answer, local, nullptr, {}, true, units);
  EXPECT_EQ(estimate.verdict, Verdict::kUnreliable);
  EXPECT_NE(estimate.verdict_reason.find("not measured"), std::string::npos) << estimate.verdict_reason;

  // A flat direction: unreliable, with a sigma of half the search range.
  local.directions[2].determined = false;
  local.directions[2].flat_units = 16.0;
  estimate = EstimateLidarError(answer, local, nullptr, {}, false, units);
  EXPECT_EQ(estimate.verdict, Verdict::kUnreliable);
  EXPECT_NEAR(estimate.sigma_tuple[2], 0.08, 1e-9);
  LidarUncertainty none;
  EXPECT_FALSE(EstimateLidarError(answer, none, nullptr, {}, false, units).estimated);
}

// The trajectory's scale, measured by the basin check's run with longer
// distances: its move's outer product joins the covariance (rank 1, along the
// move only), and with drift the verdict names it and what removes it.
TEST(ErrorEstimate, TheScaleRunsMoveAlongItsOwnDirection) {
  const UncertaintyOptions units;
  const Eigen::Isometry3d answer = TransformFromTuple((Vector6d() << 1.0, 0.2, 0.5, 0.0, 0.1, 0.3).finished());
  const LidarUncertainty local = DeterminedAlongEachAxis(units, 0.1);  // 1 mm, 0.01 deg
  LidarBasinCheck check = EveryRestartCameBack(answer);
  // With drift, its model's answer (here where the final one is: it adds nothing).
  const LidarErrorEstimate without = EstimateLidarError(answer, local, &check, {answer}, true, units);
  // 5 cm along z coupled with 0.6 deg about x: what a 0.5 % longer drive did to a rear push-broom lidar.
  const Vector6d move = (Vector6d() << 0.0, 0.0, 0.05, RadiansFromDegrees(0.6), 0.0, 0.0).finished();
  check.scale_measured = true;
  check.scale_sigma = 0.005;
  check.scale_move_d = move;
  check.T_base_lidar_scale_moved = ApplyTransformUpdate(answer, move, TransformUpdate::kAboutSourcePoint);
  const LidarErrorEstimate with = EstimateLidarError(answer, local, &check, {answer}, true, units);
  ASSERT_TRUE(with.estimated);
  EXPECT_LT((with.covariance_d - without.covariance_d - move * move.transpose()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_GT(with.share_scale, 0.99);
  EXPECT_DOUBLE_EQ(without.share_scale, 0.0);
  // An error along the move, as large, lies at 1 sigma; one across it (5 cm along x) stays 50 sigmas out.
  const Eigen::Isometry3d along = check.T_base_lidar_scale_moved;
  EXPECT_NEAR(std::sqrt(TupleMahalanobisSquared(along, answer, with.covariance_tuple)), 1.0, 0.02);
  const Eigen::Isometry3d across =
      ApplyTransformUpdate(answer, Vector6d::Unit(0) * 0.05, TransformUpdate::kAboutSourcePoint);
  EXPECT_GT(std::sqrt(TupleMahalanobisSquared(across, answer, with.covariance_tuple)), 45.0);
  EXPECT_EQ(with.verdict, Verdict::kUnreliable);
  EXPECT_NE(with.verdict_reason.find("scale error of the trajectory of 0.50 %"), std::string::npos)
      << with.verdict_reason;
  EXPECT_NE(with.verdict_reason.find("--odometry-scale"), std::string::npos) << with.verdict_reason;
  EXPECT_NE(with.verdict_reason.find("dz +5.00"), std::string::npos) << with.verdict_reason;
  // Without drift the same move makes it weak along it.
  const LidarErrorEstimate steady = EstimateLidarError(answer, local, &check, {}, false, units);
  EXPECT_EQ(steady.verdict, Verdict::kWeak);
  EXPECT_NE(steady.verdict_reason.find("dz +5.00"), std::string::npos) << steady.verdict_reason;
}

// The weak direction in words, in the base camera's axes: the larger part
// first (1 cm counting as 0.1 deg), its carrying axes, and the other part when
// it is at least a third as large.
TEST(ErrorEstimate, DescribesADirectionInTheCamerasAxes) {
  const double deg = RadiansFromDegrees(1.0);
  // The push-broom tilt: about the lateral axis, with a forward shift.
  EXPECT_EQ(DescribeDirectionInWords((Vector6d() << 0.0, 0.0, 0.019, 0.31 * deg, 0.0, 0.0).finished()),
            "a tilt about the base camera's lateral axis (x) of 0.310 deg, coupled with a shift along its optical "
            "axis (z) of 1.90 cm");
  // A shift alone (the rotation under a third of it), spread over two axes; the sign does not matter.
  EXPECT_EQ(DescribeDirectionInWords((Vector6d() << 0.0, -0.03, 0.04, 0.0, 0.0, 0.01 * deg).finished()),
            "a shift along the base camera's vertical and optical axes (y, z) of 5.00 cm");
  EXPECT_EQ(DescribeDirectionInWords((Vector6d() << 0.0, 0.0, 0.0, 0.0, -0.2 * deg, 0.0).finished()),
            "a turn about the base camera's vertical axis (y) of 0.200 deg");
  EXPECT_EQ(DescribeDirectionInWords((Vector6d() << 0.0, 0.0, 0.0, 0.1 * deg, 0.1 * deg, 0.1 * deg).finished()),
            "a rotation about the base camera's three axes (x, y, z) of 0.173 deg");
  EXPECT_EQ(DescribeDirectionInWords((Vector6d() << 0.002, 0.0, 0.0, 0.0, 0.0, 0.5 * deg).finished()),
            "a roll about the base camera's optical axis (z) of 0.500 deg");
  EXPECT_EQ(DescribeDirectionInWords(Vector6d::Zero()), "no direction");
  // The verdict names it so, with the numbers.
  const UncertaintyOptions units;
  const Eigen::Isometry3d answer = Eigen::Isometry3d::Identity();
  LidarBasinCheck basin = EveryRestartCameBack(answer);
  basin.restarts[0].T_base_lidar_end =
      ApplyTransformUpdate(answer, Vector6d::Unit(3) * RadiansFromDegrees(0.5), TransformUpdate::kAboutSourcePoint);
  const LidarErrorEstimate weak =
      EstimateLidarError(answer, DeterminedAlongEachAxis(units, 0.1), &basin, {}, false, units);
  EXPECT_EQ(weak.verdict, Verdict::kWeak);
  EXPECT_EQ(weak.verdict_reason.rfind("weak along a tilt about the base camera's lateral axis (x) of 0.2", 0), 0u)
      << weak.verdict_reason;
}

// A lower-cost restart end apart from the answer becomes the answer; the
// distances and the agreement are then measured from it, the calibration's
// own answer counting as one more end, and the basin part of the error
// estimate moves with it.
// Sizes in pixels: the one-pixel covariance is the inverse of the edges' information (an error that misaligns
// them by 1 px RMS lies at 1 under it), the floor adds alignment_floor_px^2 times it, largest along what the edges
// show least, and the sigma's own size is sqrt(trace(information x covariance)).
TEST(ErrorEstimate, APixelFloorAlongWhatTheEdgesShowLeast) {
  const UncertaintyOptions units;
  const double unit_t = units.unit_translation_m, unit_r = units.unit_rotation_rad;
  const Eigen::Isometry3d answer = TransformFromTuple((Vector6d() << 1.0, 0.2, 0.5, 0.0, 0.1, 0.3).finished());
  LidarUncertainty local = DeterminedAlongEachAxis(units, 0.1);  // 1 mm, 0.01 deg
  const LidarBasinCheck came_back = EveryRestartCameBack(answer);
  // No edge information (none measured): no floor, no sizes in pixels.
  const LidarErrorEstimate without = EstimateLidarError(answer, local, &came_back, {}, false, units);
  EXPECT_TRUE(without.one_pixel_covariance_tuple.isZero());
  EXPECT_EQ(without.sigma_px, 0.0);
  EXPECT_EQ(without.share_floor, 0.0);
  EXPECT_EQ(without.verdict, Verdict::kGood);
  // 1 cm moves the edges 4 px, 0.1 deg about x or y 2 px, about z only 0.02 px.
  Vector6d px_per_step;
  px_per_step << 4.0 / unit_t, 4.0 / unit_t, 4.0 / unit_t, 2.0 / unit_r, 2.0 / unit_r, 0.02 / unit_r;
  local.edge_information_d = px_per_step.cwiseAbs2().asDiagonal();
  ErrorEstimateOptions no_floor;
  no_floor.alignment_floor_px = 0.0;
  const LidarErrorEstimate sized = EstimateLidarError(answer, local, &came_back, {}, false, units, no_floor);
  EXPECT_EQ(sized.covariance_d, without.covariance_d);
  // 5 deg about the base z axis (1 / 0.02 steps of 0.1 deg) misaligns the edges by 1 px RMS.
  const Eigen::Isometry3d turned =
      ApplyTransformUpdate(answer, Vector6d::Unit(5) * unit_r / 0.02, TransformUpdate::kAboutSourcePoint);
  EXPECT_NEAR(TupleMahalanobisSquared(turned, answer, sized.one_pixel_covariance_tuple), 1.0, 1e-6);
  // A 1 mm sigma on each translation and 0.01 deg on each rotation: 3 x 0.4^2 + 2 x 0.2^2 + 0.002^2 px^2.
  EXPECT_NEAR(sized.sigma_px, std::sqrt(3 * 0.16 + 2 * 0.04 + 4e-6), 1e-9);

  // The default floor, 0.04 px: 0.04 / 0.02 = 2 steps (0.2 deg) more sigma about z, 0.1 mm along x.
  const ErrorEstimateOptions defaults;
  ASSERT_EQ(defaults.alignment_floor_px, 0.04);
  const LidarErrorEstimate floored = EstimateLidarError(answer, local, &came_back, {}, false, units);
  EXPECT_NEAR(floored.covariance_d(5, 5), std::pow(0.1 * unit_r, 2) + std::pow(2.0 * unit_r, 2), 1e-15);
  EXPECT_NEAR(floored.covariance_d(0, 0), std::pow(0.1 * unit_t, 2) + std::pow(0.04 * unit_t / 4.0, 2), 1e-15);
  EXPECT_NEAR(floored.covariance_d(0, 5), 0.0, 1e-15);
  EXPECT_GT(floored.share_floor, 0.9);
  // 2 sigma about z is now 0.4 deg: weak along it.
  EXPECT_EQ(floored.verdict, Verdict::kWeak);
  EXPECT_NE(floored.verdict_reason.find("rz +0.20"), std::string::npos) << floored.verdict_reason;
  // Half the floor (0.02 px): 1 step more about z, 2 sigma just above 0.2 deg, still weak.
  ErrorEstimateOptions half_floor;
  half_floor.alignment_floor_px = 0.02;
  const LidarErrorEstimate half = EstimateLidarError(answer, local, &came_back, {}, false, units, half_floor);
  EXPECT_NEAR(half.covariance_d(5, 5), std::pow(0.1 * unit_r, 2) + std::pow(unit_r, 2), 1e-15);
  EXPECT_EQ(half.verdict, Verdict::kWeak);
  EXPECT_NE(half.verdict_reason.find("rz +0.10"), std::string::npos) << half.verdict_reason;
  // Edges that leave a direction free give no one-pixel covariance and no floor.
  LidarUncertainty degenerate = local;
  degenerate.edge_information_d(5, 5) = 0.0;
  const LidarErrorEstimate free = EstimateLidarError(answer, degenerate, &came_back, {}, false, units);
  EXPECT_TRUE(free.one_pixel_covariance_tuple.isZero());
  EXPECT_EQ(free.share_floor, 0.0);
}

TEST(BasinAdoption, TakesTheLowestEndApartAndReMeasuresFromIt) {
  const Eigen::Isometry3d calibrated = TransformFromTuple((Vector6d() << 1.0, 0.2, 0.5, 0.0, 0.1, 0.3).finished());
  const auto moved = [&](double forward_m) {
    return ApplyTransformUpdate(calibrated, Vector6d::Unit(0) * forward_m, TransformUpdate::kAboutSourcePoint);
  };
  BasinCheckOptions options;  // agree within 1 cm / 0.1 deg
  LidarBasinCheck check;
  check.checked = true;
  check.cost_answer = 0.95;
  const std::vector<std::pair<double, double>> ends = {{0.002, 0.9501}, {0.040, 0.9492}, {0.045, 0.9490},
                                                       {0.050, 0.9493}, {0.003, 0.9500}, {0.001, 0.9502}};
  for (const auto& [forward_m, cost] : ends) {
    BasinRestart restart;
    restart.T_base_lidar_end = moved(forward_m);
    restart.translation_apart_m = forward_m;
    restart.cost_end = cost;
    restart.cost_drop_standard_error = 1e-4;
    check.restarts.push_back(restart);
  }
  // Agreeing restarts are never taken, nor ends that are not lower by the margin, nor an end within the
  // agreement bounds (the same minimum), however low.
  check.agree = true;
  EXPECT_EQ(BetterRestart(check, options), -1);
  check.agree = false;
  EXPECT_EQ(BetterRestart(check, options), 2);
  EXPECT_EQ(BetterRestart(check, options, 0.0011), -1);
  check.restarts[0].cost_end = 0.9480;  // 0.2 cm from the answer
  EXPECT_EQ(BetterRestart(check, options), 2);
  check.restarts[0].rotation_apart_rad = RadiansFromDegrees(0.2);  // now apart by its rotation
  EXPECT_EQ(BetterRestart(check, options), 0);
  check.restarts[0].rotation_apart_rad = 0.0;
  check.restarts[0].cost_end = 0.9501;
  // A drop that the scenes do not agree on (within 2 standard errors) is no better minimum: the next lowest is.
  check.restarts[2].cost_drop_standard_error = 6e-4;  // drop 1e-3
  EXPECT_EQ(BetterRestart(check, options), 1);        // drop 8e-4, 8 standard errors
  BasinCheckOptions strict = options;
  strict.adopt_min_standard_errors = 10.0;
  EXPECT_EQ(BetterRestart(check, strict), -1);
  check.restarts[2].cost_drop_standard_error = 1e-4;
  check.checked = false;
  EXPECT_EQ(BetterRestart(check, options), -1);
  check.checked = true;

  Eigen::Isometry3d answer = calibrated;
  AdoptRestart(2, options, &check, &answer);
  EXPECT_TRUE(answer.isApprox(moved(0.045)));
  EXPECT_EQ(check.adopted_restart, 2);
  EXPECT_TRUE(check.T_base_lidar_calibrated.isApprox(calibrated));
  EXPECT_DOUBLE_EQ(check.cost_calibrated, 0.95);
  EXPECT_DOUBLE_EQ(check.cost_answer, 0.9490);
  EXPECT_NEAR(check.restarts[2].translation_apart_m, 0.0, 1e-12);
  EXPECT_NEAR(check.restarts[1].translation_apart_m, 0.005, 1e-9);
  EXPECT_NEAR(check.restarts[0].translation_apart_m, 0.043, 1e-9);
  EXPECT_NEAR(check.max_translation_apart_m, 0.045, 1e-9);  // the calibration's own answer
  EXPECT_NEAR(check.calibrated_translation_apart_m, 0.045, 1e-9);
  EXPECT_NEAR(check.calibrated_rotation_apart_rad, 0.0, 1e-9);
  EXPECT_FALSE(check.agree);

  // The ends beside the new answer: the other restarts' and the calibration's own answer.
  const std::vector<Eigen::Isometry3d> beside = EndsBesideAnswer(check);
  ASSERT_EQ(beside.size(), 6u);
  EXPECT_TRUE(beside[2].isApprox(calibrated));
  EXPECT_TRUE(beside[3].isApprox(moved(0.050)));
  // A restart that had come back came back to the calibration's own answer, not to the adopted one.
  LidarBasinCheck with_came_back = check;
  with_came_back.restarts[3].came_back = true;
  EXPECT_TRUE(EndsBesideAnswer(with_came_back)[3].isApprox(calibrated));

  // The basin part of the error estimate is the ends' second moment about the new answer.
  const UncertaintyOptions units;
  const LidarUncertainty local = DeterminedAlongEachAxis(units, 0.1);
  const LidarErrorEstimate estimate = EstimateLidarError(answer, local, &check, {}, false, units);
  ASSERT_TRUE(estimate.estimated);
  double second_moment = 0.0;
  for (const double forward_m : {0.002, 0.040, 0.0, 0.050, 0.003, 0.001}) {
    second_moment += std::pow(forward_m - 0.045, 2) / 6.0;
  }
  EXPECT_NEAR(estimate.covariance_d(0, 0), 1e-6 + second_moment, 1e-9);  // translation along base x

  // Within the bounds of the new answer the ends agree again.
  LidarBasinCheck near = check;
  near.adopted_restart = -1;
  near.cost_answer = 0.95;
  for (BasinRestart& restart : near.restarts) restart.T_base_lidar_end = moved(0.040 + 0.001 * restart.cost_end);
  Eigen::Isometry3d near_answer = moved(0.035);
  near.agree = false;
  AdoptRestart(1, options, &near, &near_answer);
  EXPECT_TRUE(near.agree);  // ends within 0.1 mm of each other, the calibration's answer 0.5 cm away
  EXPECT_LT(near.max_translation_apart_m, 0.01);
}

}  // namespace
}  // namespace scenecal
