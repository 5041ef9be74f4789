// The L-BFGS lower solver wired into the schemes (--lower-solver lbfgs):
//  - the joint cost's gradient with respect to T_base_lidar (chain rule through
//    T_camera_lidar = T_base_camera^-1 * T_base_lidar) against central
//    differences, for a smooth test function (tight) and for the B-spline NID
//    pair costs of a synthetic scene (within the roughness of the bilinear image);
//  - the alt lower level (eq. 13) with L-BFGS on costs with known minima
//    (gradient by central differences) and on a small simulated RobotCar
//    dataset (analytic gradient): it recovers a perturbed transform;
//  - the options and the CLI: lbfgs needs B-spline binning (exit 2 for
//    --binning hard), picks it when --binning is not given and records it.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <set>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <unistd.h>

#include "core/alternating.hpp"
#include "core/calibrate.hpp"
#include "core/calibrate_alternating.hpp"
#include "core/calibrator.hpp"
#include "core/geometry.hpp"
#include "core/gradient_solver.hpp"
#include "core/pair_cost.hpp"
#include "core/upper_level.hpp"
#include "io/dataset.hpp"
#include "sim/simulator.hpp"
#include "support/shared_simulation.hpp"
#include "support/small_dataset.hpp"

namespace scenecal {
namespace {

namespace fs = std::filesystem;

// Large rotations and a metre-scale offset, so that a wrong frame or a missing
// lever-arm term in the chain rule shows.
Eigen::Isometry3d TBaseCamera(int camera) {
  Vector6d tuple;
  if (camera == 0) {
    tuple << 0.8, -0.4, 1.1, RadiansFromDegrees(-80), RadiansFromDegrees(25), RadiansFromDegrees(140);
  } else {
    tuple << -0.6, 0.9, 0.3, RadiansFromDegrees(95), RadiansFromDegrees(-30), RadiansFromDegrees(-60);
  }
  return TransformFromTuple(tuple);
}

Vector6d BaseDifferenceGradient(const std::function<double(const Eigen::Isometry3d&)>& cost,
                                const Eigen::Isometry3d& T, TransformUpdate update, const Eigen::Vector3d& pivot,
                                double h_translation, double h_rotation) {
  Vector6d steps;
  steps << Eigen::Vector3d::Constant(h_translation), Eigen::Vector3d::Constant(h_rotation);
  return CentralDifferenceGradient(cost, T, update, pivot, steps);
}

// A smooth, non-symmetric function of T_camera_lidar (so every component of
// the gradient is non-zero and of its own size).
double SmoothCameraCost(const Eigen::Isometry3d& T_camera_lidar) {
  const Vector6d log = LogSE3(T_camera_lidar);
  Vector6d weights;
  weights << 1.0, 2.0, 0.5, 3.0, 1.5, 0.7;
  return log.cwiseProduct(weights).squaredNorm() + std::sin(log[0] + 2.0 * log[4]) + 0.3 * log[2] * log[3];
}

void ExpectChainRuleExact(TransformUpdate update, const Eigen::Vector3d& pivot) {
  Vector6d tuple;
  tuple << 0.3, -1.2, 0.7, RadiansFromDegrees(20), RadiansFromDegrees(-35), RadiansFromDegrees(50);
  const Eigen::Isometry3d T_base_lidar = TransformFromTuple(tuple);
  for (int camera = 0; camera < 2; ++camera) {
    const Eigen::Isometry3d T_base_camera = TBaseCamera(camera);
    const auto camera_cost = [](const Eigen::Isometry3d& T) { return SmoothCameraCost(T); };
    const auto base_cost = [&](const Eigen::Isometry3d& T) { return SmoothCameraCost(T_base_camera.inverse() * T); };
    const Vector6d gradient_camera = BaseDifferenceGradient(camera_cost, T_base_camera.inverse() * T_base_lidar,
                                                            update, pivot, 1e-6, 1e-6);
    const Vector6d mapped = BaseGradientFromCameraGradient(T_base_camera, update, gradient_camera);
    const Vector6d numeric = BaseDifferenceGradient(base_cost, T_base_lidar, update, pivot, 1e-6, 1e-6);
    ASSERT_GT(numeric.norm(), 0.1);
    EXPECT_LT((mapped - numeric).norm(), 1e-6 * numeric.norm())
        << "camera " << camera << "\nmapped  " << mapped.transpose() << "\nnumeric " << numeric.transpose();
  }
}

TEST(JointGradient, ChainRuleMatchesCentralDifferencesAboutPivot) {
  ExpectChainRuleExact(TransformUpdate::kAboutSourcePoint, Eigen::Vector3d(0.4, -2.0, 1.5));
}

TEST(JointGradient, ChainRuleMatchesCentralDifferencesLeftTwist) {
  ExpectChainRuleExact(TransformUpdate::kLeftTwist, Eigen::Vector3d::Zero());
}

// The synthetic scene of test_gradient_solver.cpp: a slanted plane with a
// smooth albedo seen by a radtan camera, two scans of lidar points on it.
double Albedo(double a, double b) {
  return 0.5 + 0.25 * std::sin(7.0 * a + 1.0) * std::cos(3.0 * b) + 0.2 * std::sin(5.0 * b - 2.0 * a);
}

struct Synthetic {
  CameraInfo camera;
  Eigen::Isometry3d T_camera_lidar;
  cv::Mat image;
  std::vector<LidarScan> scans;
  Scene scene;
};

Synthetic MakeSynthetic() {
  Synthetic s;
  s.camera.name = "cam";
  s.camera.model.width = 640;
  s.camera.model.height = 480;
  s.camera.model.kind = CameraModelKind::kRadTan;
  s.camera.model.fx = s.camera.model.fy = 600.0;
  s.camera.model.cx = 320.5;
  s.camera.model.cy = 240.5;
  s.camera.model.distortion = {-0.1, 0.02, 0.001, -0.0005, 0.0};
  Vector6d tuple;
  tuple << 0.4, -0.3, 0.2, RadiansFromDegrees(-3), RadiansFromDegrees(4), RadiansFromDegrees(2);
  s.T_camera_lidar = TransformFromTuple(tuple);
  const Eigen::Matrix3d r = RotationFromRollPitchYaw(RadiansFromDegrees(10), RadiansFromDegrees(25), 0);
  const Eigen::Vector3d origin(0, 0, 4.0), axis_a = r.col(0), axis_b = r.col(1), normal = r.col(2);
  s.image = cv::Mat(s.camera.model.height, s.camera.model.width, CV_32FC1, cv::Scalar(0.5f));
  for (int v = 0; v < s.image.rows; ++v) {
    for (int u = 0; u < s.image.cols; ++u) {
      const Eigen::Vector3d d = s.camera.model.Unproject(Eigen::Vector2d(u, v));
      const double t = normal.dot(origin) / normal.dot(d);
      const Eigen::Vector3d p = t * d - origin;
      s.image.at<float>(v, u) = static_cast<float>(Albedo(p.dot(axis_a), p.dot(axis_b)));
    }
  }
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  s.scene.camera = "cam";
  s.scene.lidar = "lidar";
  Vector6d scan_pose;
  scan_pose << 0.05, 0.0, -0.3, 0.0, RadiansFromDegrees(1.0), 0.0;
  const Eigen::Isometry3d T_basek_basej[2] = {Eigen::Isometry3d::Identity(), TransformFromTuple(scan_pose)};
  for (int j = 0; j < 2; ++j) {
    s.scene.scans.push_back({j, T_basek_basej[j]});
    LidarScan scan;
    const Eigen::Isometry3d T_lidarj_camerak = (T_basek_basej[j] * s.T_camera_lidar).inverse();
    for (int i = 0; i < 30000; ++i) {
      const double a = 1.4 * unit(rng), b = 1.0 * unit(rng);
      const Eigen::Vector3d q = T_lidarj_camerak * (origin + a * axis_a + b * axis_b);
      const double reflectance = 5.0 + 200.0 * std::pow(Albedo(a, b), 1.5);
      scan.points.push_back({static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()),
                             static_cast<float>(reflectance)});
    }
    s.scans.push_back(std::move(scan));
  }
  return s;
}

// Two pairs on the synthetic scene under cameras with the transforms above
// (the second camera 3 cm / 1 degree away from where the scene puts it, so
// the pairs disagree a little and both gradients are non-zero).
struct JointFixture {
  Synthetic s = MakeSynthetic();
  std::vector<std::unique_ptr<PairCost>> costs;
  std::vector<const PairCost*> pairs;
  Eigen::Isometry3d T_base_lidar;

  JointFixture() {
    T_base_lidar = TBaseCamera(0) * s.T_camera_lidar;
    PairCostOptions options;
    options.histogram.binning = Binning::kBSpline;
    options.swathe.occlusion = false;
    Vector6d offset;
    offset << 0.03, -0.01, 0.02, RadiansFromDegrees(1.0), 0.0, RadiansFromDegrees(-0.5);
    const Eigen::Isometry3d T_base_camera[2] = {TBaseCamera(0), T_base_lidar * s.T_camera_lidar.inverse() *
                                                                    ExpSE3(offset)};
    for (int c = 0; c < 2; ++c) {
      CameraInfo camera = s.camera;
      camera.name = c == 0 ? "cam0" : "cam1";
      camera.T_base_camera = T_base_camera[c];
      std::vector<SceneSwathe> swathes;
      swathes.push_back(SceneSwathe::Build(s.scene, camera, s.image, {&s.scans[0], &s.scans[1]}, options.swathe,
                                           NormalisationOptions{}));
      costs.push_back(std::make_unique<PairCost>(camera, "lidar", std::move(swathes), options));
      costs.back()->RefreshVisibility(camera.T_camera_base() * T_base_lidar);
      pairs.push_back(costs.back().get());
    }
  }
};

void ExpectJointGradientMatchesCentralDifferences(TransformUpdate update, const Eigen::Vector3d& pivot) {
  const JointFixture f;
  ASSERT_EQ(f.pairs[0]->UsedSceneCount(), 1);
  ASSERT_EQ(f.pairs[1]->UsedSceneCount(), 1);
  Vector6d delta;
  delta << 0.01, -0.015, 0.008, RadiansFromDegrees(0.3), RadiansFromDegrees(-0.2), RadiansFromDegrees(0.25);
  const Eigen::Isometry3d T = ExpSE3(delta) * f.T_base_lidar;
  Vector6d analytic;
  const double value = EvaluateJointWithGradient(f.pairs, T, update, pivot, &analytic);
  EXPECT_EQ(value, EvaluateJoint(f.pairs, T));  // the same mean, in the same order
  const auto joint = [&](const Eigen::Isometry3d& T_base_lidar) { return EvaluateJoint(f.pairs, T_base_lidar); };
  // ~0.1 px steps, as in test_gradient_solver.cpp's pair-cost check.
  const Vector6d numeric = BaseDifferenceGradient(joint, T, update, pivot, 1e-3, 2e-4);
  ASSERT_GT(analytic.norm(), 0.0);
  for (int axis = 0; axis < 6; ++axis) {
    const double scale = axis < 3 ? numeric.head<3>().norm() : numeric.tail<3>().norm();
    EXPECT_NEAR(analytic[axis], numeric[axis], 0.05 * scale)
        << "axis " << axis << "\nanalytic " << analytic.transpose() << "\nnumeric  " << numeric.transpose();
  }
  // Without a gradient pointer: the plain cost.
  EXPECT_EQ(EvaluateJointWithGradient(f.pairs, T, update, pivot, nullptr), value);
}

TEST(JointGradient, NidMatchesCentralDifferencesAboutPivot) {
  ExpectJointGradientMatchesCentralDifferences(TransformUpdate::kAboutSourcePoint, Eigen::Vector3d(0.3, -0.5, 1.0));
}

TEST(JointGradient, NidMatchesCentralDifferencesLeftTwist) {
  ExpectJointGradientMatchesCentralDifferences(TransformUpdate::kLeftTwist, Eigen::Vector3d::Zero());
}

TEST(GradientSolverStop, StopRequestedEndsTheRunAndKeepsTheBestPoint) {
  const Eigen::Isometry3d minimum = TransformFromTuple((Vector6d() << 0.2, -0.1, 0.3, 0.1, -0.2, 0.05).finished());
  const CostWithGradient cost = [&](const Eigen::Isometry3d& T, Vector6d* gradient) {
    const auto value = [&](const Eigen::Isometry3d& X) { return LogSE3(X * minimum.inverse()).squaredNorm(); };
    if (gradient != nullptr)
      *gradient = CentralDifferenceGradient(value, T, TransformUpdate::kAboutSourcePoint, Eigen::Vector3d::Zero(),
                                            Vector6d::Constant(1e-6));
    return value(T);
  };
  GradientSolverOptions options;
  Eigen::Isometry3d free_run = Eigen::Isometry3d::Identity();
  const GradientSolverSummary full = MinimiseWithGradient(cost, options, &free_run);
  EXPECT_FALSE(full.stopped);
  EXPECT_LT(TranslationError(free_run, minimum), 1e-4);
  int polls = 0;
  Eigen::Isometry3d stopped_run = Eigen::Isometry3d::Identity();
  const GradientSolverSummary stopped =
      MinimiseWithGradient(cost, options, &stopped_run, [&] { return ++polls >= 2; });
  EXPECT_TRUE(stopped.stopped);
  EXPECT_FALSE(stopped.converged);
  EXPECT_LE(stopped.iterations, 2);
  EXPECT_LT(stopped.iterations, full.iterations);
  EXPECT_LT(stopped.final_value, stopped.initial_value);  // the progress so far is kept
  EXPECT_EQ(cost(stopped_run, nullptr), stopped.final_value);
}

TEST(LowerSolverOptions, LbfgsNeedsBSplineBinning) {
  CalibrationOptions options;
  options.lower_solver = LowerSolver::kLbfgs;
  options.cost.histogram.binning = Binning::kHard;
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("B-spline"), std::string::npos) << why;
  const CalibrationOutcome outcome = Calibrate(CalibrationInput{}, options);
  EXPECT_EQ(outcome.status, CalibrationStatus::kInvalidOptions);
  options.cost.histogram.binning = Binning::kBSpline;
  EXPECT_TRUE(options.IsValid(&why)) << why;
  LowerSolver parsed = LowerSolver::kSimplex;
  EXPECT_TRUE(ParseLowerSolver("lbfgs", &parsed));
  EXPECT_EQ(parsed, LowerSolver::kLbfgs);
  EXPECT_STREQ(LowerSolverName(parsed), "lbfgs");
  EXPECT_FALSE(ParseLowerSolver("bfgs", &parsed));
}

// A schedule's wide stages (the first stage's whole steps) are the ones left
// out on recordings with few frames; a schedule of wide stages only stays.
TEST(StageSchedule, WithoutWideStagesKeepsTheNarrowOnes) {
  const std::vector<OptimisationStage> preset = {{1.0, 0.02, 1}, {1.0, 0.004, 2}, {0.3, 0.0015, 1}, {0.1, 0.0, 1}};
  const std::vector<OptimisationStage> narrow = WithoutWideStages(preset);
  ASSERT_EQ(narrow.size(), 2u);
  EXPECT_DOUBLE_EQ(narrow[0].step_scale, 0.3);
  EXPECT_DOUBLE_EQ(narrow[0].blur_fraction, 0.0015);
  EXPECT_EQ(narrow[0].restarts, 1);
  EXPECT_DOUBLE_EQ(narrow[1].step_scale, 0.1);
  EXPECT_EQ(WithoutWideStages(DefaultStages()).size(), 2u);
  const std::vector<OptimisationStage> paper = {{1.0, 0.0, 0}};
  ASSERT_EQ(WithoutWideStages(paper).size(), 1u);
  EXPECT_DOUBLE_EQ(WithoutWideStages(paper)[0].step_scale, 1.0);
}

// The alt lower level on costs with known minima (no analytic gradient: central differences).
TEST(AlternatingLbfgs, BowlsConvergeToTheTruthWithFewerEvaluationsThanTheSimplex) {
  const Eigen::Isometry3d T_base_right = TransformFromTuple((Vector6d() << 0.24, 0, 0, 0, 0, 0).finished());
  const Eigen::Isometry3d truth = TransformFromTuple((Vector6d() << -0.3, 1.2, -4.0, -2.84, 0.06, -0.36).finished());
  const Vector6d width = (Vector6d() << 0.05, 0.05, 0.05, 0.02, 0.02, 0.02).finished();
  const auto bowl = [&](const Eigen::Isometry3d& T_min) {
    PairObjective objective;
    objective.cost = [=](const Eigen::Isometry3d& T) { return LogSE3(T * T_min.inverse()).cwiseQuotient(width).squaredNorm(); };
    return objective;
  };
  AlternatingProblem problem;
  problem.cameras = {{"left", Eigen::Isometry3d::Identity(), std::nullopt}, {"right", T_base_right, std::nullopt}};
  problem.lidars = {{"rear", ExpSE3((Vector6d() << 0.06, -0.05, 0.04, 0.02, -0.03, 0.025).finished()) * truth}};
  problem.pairs = {{0, 0}, {1, 0}};
  int evaluations[2] = {0, 0};
  for (const LowerSolver solver : {LowerSolver::kSimplex, LowerSolver::kLbfgs}) {
    ThreadLowerLevelBackend backend({bowl(truth), bowl(T_base_right.inverse() * truth)});
    AlternatingOptions options;
    options.lower_solver = solver;
    const AlternatingResult result = SolveAlternating(problem, options, backend);
    ASSERT_TRUE(result.success) << result.termination;
    EXPECT_LT(TranslationError(result.T_base_lidar[0], truth), 1e-3) << LowerSolverName(solver);
    EXPECT_LT(RotationErrorDegrees(result.T_base_lidar[0], truth), 0.02) << LowerSolverName(solver);
    evaluations[solver == LowerSolver::kLbfgs] = result.total_evaluations;
    EXPECT_EQ(result.total_gradient_evaluations > 0, solver == LowerSolver::kLbfgs);
    for (const AlternationRecord& record : result.history) {
      ASSERT_EQ(record.lower_gradient_evaluations.size(), 2u);
    }
  }
  std::cout << "[ measured ] bowls: simplex " << evaluations[0] << ", lbfgs " << evaluations[1] << " evaluations\n";
  EXPECT_LT(3 * evaluations[1], evaluations[0]);
}

// A small simulated RobotCar drive (stereo + rear push-broom lidar), exact odometry.
class LowerSolverOnSimulation : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = fs::temp_directory_path() / ("scenecal_test_lower_solver_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_);
    dataset_ = test::SharedSimulation("robotcar", [](const fs::path& folder) {
      sim::SimulationOptions options = test::SmallSimulationOptions(1);
      options.distance_m = 90.0;
      sim::Simulate(options, folder);
    });
  }
  static void TearDownTestSuite() { fs::remove_all(root_); }

  // Shared by the suite's processes: read only.
  static fs::path DatasetPath() { return dataset_; }

  static CalibrationInput Load(const io::Dataset& dataset, const SceneOptions& scene_options) {
    return test::LoadCalibrationInput(dataset, scene_options);
  }

  static fs::path root_;
  static fs::path dataset_;
};

fs::path LowerSolverOnSimulation::root_;
fs::path LowerSolverOnSimulation::dataset_;

// One lower-level problem (eq. 13) with a loose penalty, on the blurred images
// of the first alternations: L-BFGS on the real pair objective (analytic
// gradient) moves a perturbed T_camera_lidar towards the truth, reaching the
// simplex's objective with far fewer evaluations.
TEST_F(LowerSolverOnSimulation, LbfgsLowerLevelRecoversAPerturbedTransform) {
  const io::Dataset dataset = io::OpenDataset(DatasetPath());
  CalibrationOptions options;
  options.scheme = CalibrationScheme::kAlt;
  options.lower_solver = LowerSolver::kLbfgs;
  options.cost.histogram.binning = Binning::kBSpline;
  options.scenes.scenes_per_camera = 6;
  // The first stage's steps these assertions were measured with (the default turns 1 deg).
  options.nelder_mead.initial_step_rotation_rad = 0.02;
  options.gradient.initial_step_rotation_rad = 0.02;
  const CalibrationInput input = Load(dataset, options.scenes);
  Calibrator calibrator(input, options);
  ASSERT_EQ(calibrator.Status(), CalibrationStatus::kSuccess) << calibrator.Why();
  const AlternatingOptions alternating = AlternatingOptionsFor(options);
  std::vector<PairObjective> objectives = calibrator.AlternatingObjectives();
  ASSERT_FALSE(objectives.empty());
  const AlternatingPair& pair = calibrator.AlternatingPairs().pairs[0];
  const Eigen::Isometry3d truth = dataset.rig.cameras[static_cast<std::size_t>(pair.camera)].T_camera_base() *
                                  dataset.ground_truth->T_base_lidar.at("lms_rear");
  const Eigen::Isometry3d start =
      ExpSE3((Vector6d() << 0.02, -0.015, 0.01, RadiansFromDegrees(0.6), RadiansFromDegrees(-0.5),
              RadiansFromDegrees(0.4))
                 .finished()) *
      truth;
  LowerLevelTask task;
  task.pair = 0;
  task.alternation = 0;  // blurred images (the first stage)
  task.T_camera_lidar_start = start;
  task.T_camera_lidar_upper = start;
  task.penalty_information = PenaltyInformation(5.0, 5.0);
  task.options = alternating.lower;
  task.gradient = alternating.lower_gradient;
  LowerLevelOutcome outcomes[2];
  for (const LowerSolver solver : {LowerSolver::kSimplex, LowerSolver::kLbfgs}) {
    task.solver = solver;
    LowerLevelOutcome& outcome = outcomes[solver == LowerSolver::kLbfgs];
    outcome = SolveLowerLevel(objectives[0], task, {});
    std::cout << "[ measured ] " << LowerSolverName(solver) << " lower level: " << TranslationError(start, truth) * 100.0
              << " cm, " << RotationErrorDegrees(start, truth) << " deg -> "
              << TranslationError(outcome.T_camera_lidar, truth) * 100.0 << " cm, "
              << RotationErrorDegrees(outcome.T_camera_lidar, truth) << " deg, objective "
              << outcome.summary.initial_value << " -> " << outcome.objective << " in " << outcome.summary.evaluations
              << " evaluations (" << outcome.gradient_evaluations << " with gradient)\n";
  }
  const LowerLevelOutcome& lbfgs = outcomes[1];
  const LowerLevelOutcome& simplex = outcomes[0];
  EXPECT_GT(lbfgs.gradient_evaluations, 0);
  EXPECT_LE(lbfgs.gradient_evaluations, lbfgs.summary.evaluations);
  EXPECT_EQ(simplex.gradient_evaluations, 0);
  EXPECT_LT(TranslationError(lbfgs.T_camera_lidar, truth), 0.25 * TranslationError(start, truth));
  EXPECT_LT(RotationErrorDegrees(lbfgs.T_camera_lidar, truth), 0.75 * RotationErrorDegrees(start, truth));
  // At least 90% of the simplex's decrease of the objective, with at least 3
  // times fewer evaluations.
  const double start_objective = simplex.summary.initial_value;
  EXPECT_DOUBLE_EQ(lbfgs.summary.initial_value, start_objective);  // through L-BFGS' value scale and back
  EXPECT_GT(start_objective - lbfgs.objective, 0.9 * (start_objective - simplex.objective));
  EXPECT_LT(3 * lbfgs.summary.evaluations, simplex.summary.evaluations);
  // objective = f + penalty at the answer; cost = f alone.
  EXPECT_EQ(lbfgs.cost, objectives[0].cost(lbfgs.T_camera_lidar));
  EXPECT_LE(lbfgs.cost, lbfgs.objective);
}

// The alt scheme with the L-BFGS lower level, a few alternations: the
// plumbing (settings, counts, termination) and a lower cost than at the start.
TEST_F(LowerSolverOnSimulation, AlternatingWithLbfgsRecordsItsSolver) {
  const io::Dataset dataset = io::OpenDataset(DatasetPath());
  CalibrationOptions options;
  options.scheme = CalibrationScheme::kAlt;
  options.lower_solver = LowerSolver::kLbfgs;
  options.cost.histogram.binning = Binning::kBSpline;
  options.scenes.scenes_per_camera = 4;
  options.stages = {{1.0, 0.0, 0}};
  const CalibrationInput input = Load(dataset, options.scenes);
  options.alternating.max_alternations = 3;
  const CalibrationOutcome outcome = Calibrate(input, options);
  ASSERT_EQ(outcome.status, CalibrationStatus::kSuccess) << outcome.why;
  ASSERT_TRUE(outcome.alternating.has_value());
  const AlternatingResult& details = outcome.alternating->solved;
  EXPECT_GT(details.total_gradient_evaluations, 0);
  EXPECT_LE(details.total_gradient_evaluations, details.total_evaluations);
  for (const PairReport& pair : outcome.pairs) EXPECT_LT(pair.final_cost, pair.initial_cost) << pair.camera;
  EXPECT_EQ(outcome.result.settings.at("binning"), "bspline");
  EXPECT_EQ(outcome.result.settings.at("lower_solver").rfind("lbfgs", 0), 0u) << outcome.result.settings.at("lower_solver");
  EXPECT_NE(outcome.result.settings.at("lower_level").find("L-BFGS"), std::string::npos);
  // L-BFGS lower levels start with a looser coupling than the paper's 5 m / 5 rad (the simplex keeps those).
  EXPECT_EQ(outcome.result.settings.at("penalty_sigma0"), "500 m, 500 rad");
  // --stage-alternations: the stages spread over the first N, the rest in the last stage.
  const std::vector<OptimisationStage> three = {{1.0, 0.004, 0}, {0.3, 0.0015, 0}, {0.1, 0.0, 0}};
  for (int i = 0; i < 20; ++i) {
    EXPECT_EQ(StageIndexForAlternation(three.size(), i, 20), static_cast<std::size_t>(std::min(2, i * 3 / 20)));
  }
  CalibrationOptions staged = options;
  staged.stages = three;
  staged.alternating.max_alternations = 26;
  staged.alternating.stage_alternations = 20;
  const AlternatingOptions spread = AlternatingOptionsFor(staged);
  EXPECT_EQ(StageSpan(spread), 20);
  EXPECT_EQ(spread.min_alternations, FirstAlternationOfLastStage(three, 20) + 1);
  ASSERT_EQ(spread.lower_step_scale.size(), 26u);
  for (int i = 0; i < 26; ++i) {
    EXPECT_EQ(spread.lower_step_scale[static_cast<std::size_t>(i)], i < 20 ? three[i * 3 / 20].step_scale : 0.1) << i;
  }
  staged.alternating.stage_alternations = 0;
  EXPECT_EQ(StageSpan(AlternatingOptionsFor(staged)), 26);
  AlternatingOptions too_many = spread;
  too_many.stage_alternations = 27;
  std::string stage_why;
  EXPECT_FALSE(too_many.IsValid(&stage_why));
  CalibrationOptions simplex = options;
  simplex.lower_solver = LowerSolver::kSimplex;
  EXPECT_EQ(AlternatingOptionsFor(simplex).initial_sigma_translation_m, 5.0);
  EXPECT_EQ(AlternatingOptionsFor(simplex).initial_sigma_rotation_rad, 5.0);
  EXPECT_NE(outcome.result.termination.find("with gradient"), std::string::npos) << outcome.result.termination;
  // Levels further apart at the end than the agreement thresholds: the result says so (the run
  // is deterministic, so thresholds at half and twice the gap found bracket it).
  const AlternationRecord& last = details.history.back();
  ASSERT_GT(last.max_disagreement_translation_m, 0.0);
  ASSERT_GT(last.max_disagreement_rotation_rad, 0.0);
  const auto levels_warnings = [&](double factor) {
    CalibrationOptions thresholds = options;
    thresholds.alternating.agreement_translation_m = factor * last.max_disagreement_translation_m;
    thresholds.alternating.agreement_rotation_rad = factor * last.max_disagreement_rotation_rad;
    const CalibrationOutcome rerun = Calibrate(input, thresholds);
    return std::count_if(rerun.result.warnings.begin(), rerun.result.warnings.end(), [](const std::string& w) {
      return w.find("lower and upper levels ended") != std::string::npos;
    });
  };
  EXPECT_EQ(levels_warnings(0.5), 1);
  EXPECT_EQ(levels_warnings(2.0), 0);
  ASSERT_EQ(outcome.optimisations.size(), 1u);
  EXPECT_EQ(outcome.optimisations[0].solver, LowerSolver::kLbfgs);
  EXPECT_EQ(outcome.optimisations[0].gradient_evaluations, details.total_gradient_evaluations);
}

TEST_F(LowerSolverOnSimulation, TimeBudgetStopsTheLbfgsSearch) {
  const io::Dataset dataset = io::OpenDataset(DatasetPath());
  CalibrationOptions options;
  options.scheme = CalibrationScheme::kJoint;
  options.lower_solver = LowerSolver::kLbfgs;
  options.cost.histogram.binning = Binning::kBSpline;
  options.scenes.scenes_per_camera = 5;
  options.time_budget_s = 0.2;
  const CalibrationInput input = Load(dataset, options.scenes);
  const CalibrationOutcome outcome = Calibrate(input, options);
  ASSERT_EQ(outcome.status, CalibrationStatus::kSuccess) << outcome.why;
  EXPECT_NE(outcome.result.termination.find("time budget"), std::string::npos) << outcome.result.termination;
  ASSERT_EQ(outcome.optimisations.size(), 1u);
  // Stopped well before the full schedule (seconds on this data).
  EXPECT_LT(outcome.result.timings_s.at("optimise"), 2.0);
}

int RunCli(const std::string& arguments, std::string* out) {
  const fs::path stdout_file = fs::temp_directory_path() / ("scenecal_lower_solver_out_" + std::to_string(::getpid()));
  const std::string command = std::string(SCENECAL_CLI_PATH) + " " + arguments + " >" + stdout_file.string() + " 2>&1";
  const int status = std::system(command.c_str());
  std::ifstream in(stdout_file);
  std::stringstream buffer;
  buffer << in.rdbuf();
  if (out != nullptr) *out = buffer.str();
  fs::remove(stdout_file);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST_F(LowerSolverOnSimulation, CliRejectsHardBinningWithLbfgs) {
  const fs::path output = root_ / "never.yaml";
  std::string text;
  EXPECT_EQ(RunCli("calibrate " + DatasetPath().string() + " --output " + output.string() +
                       " --lower-solver lbfgs --binning hard",
                   &text),
            2)
      << text;
  EXPECT_NE(text.find("--binning bspline"), std::string::npos) << text;
  EXPECT_FALSE(fs::exists(output));
  EXPECT_EQ(RunCli("calibrate " + DatasetPath().string() + " --output " + output.string() + " --lower-solver newton",
                   nullptr),
            2);
  EXPECT_FALSE(fs::exists(output));
}

TEST_F(LowerSolverOnSimulation, CliLbfgsSelectsAndRecordsBSplineBinning) {
  const fs::path output = root_ / "joint_lbfgs.yaml";
  std::string text;
  ASSERT_EQ(RunCli("calibrate " + DatasetPath().string() + " --output " + output.string() +
                       " --scheme joint --lower-solver lbfgs --scenes 3 --stages 1 --lbfgs-iterations 5",
                   &text),
            0)
      << text;
  const CalibrationResult result = io::ReadCalibrationResult(output);
  EXPECT_EQ(result.settings.at("binning"), "bspline");
  EXPECT_EQ(result.settings.at("lower_solver").rfind("lbfgs", 0), 0u) << result.settings.at("lower_solver");
  EXPECT_EQ(result.settings.at("max_iterations_per_run"), "5");
  EXPECT_NE(result.termination.find("with gradient"), std::string::npos) << result.termination;
  EXPECT_NE(text.find("plain cost evaluations"), std::string::npos) << text;
}

}  // namespace
}  // namespace scenecal
