// The analytic gradient of the B-spline pair cost against central
// differences, determinism of the cost over thread counts, and the L-BFGS
// lower level against the simplex on a synthetic scene built here: a slanted
// plane with a smooth albedo seen by a distorted (radtan) camera, two scans of
// lidar points on it whose reflectance is a monotone function of the albedo.
#include <cmath>
#include <cstdint>
#include <random>
#include <utility>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <tbb/global_control.h>

#include "core/calibrate.hpp"
#include "core/geometry.hpp"
#include "core/gradient_solver.hpp"
#include "core/nelder_mead.hpp"
#include "core/pair_cost.hpp"

namespace scenecal {
namespace {

double Albedo(double a, double b) {  // smooth, in [0, 1]
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
  // The plane in the image frame (camera at scan 0): origin 4 m ahead, slanted.
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
  // Two scans: the second taken from a camera pose 0.3 m further back and
  // turned 1 degree (T_basek_basej, base = camera); its points are stored in
  // its own lidar frame.
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
      // Inside the view with a margin, so few samples enter or leave the image.
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

PairCost MakeCost(const Synthetic& s, Binning binning) {
  PairCostOptions options;
  options.histogram.binning = binning;
  options.swathe.occlusion = false;
  std::vector<SceneSwathe> swathes;
  swathes.push_back(
      SceneSwathe::Build(s.scene, s.camera, s.image, {&s.scans[0], &s.scans[1]}, options.swathe, NormalisationOptions{}));
  PairCost cost(s.camera, "lidar", std::move(swathes), options);
  cost.RefreshVisibility(s.T_camera_lidar);
  return cost;
}

Eigen::Isometry3d Perturbed(const Eigen::Isometry3d& T, double metres, double degrees) {
  Vector6d delta;
  delta << metres, -0.5 * metres, 0.7 * metres, RadiansFromDegrees(degrees), RadiansFromDegrees(-0.6 * degrees),
      RadiansFromDegrees(0.4 * degrees);
  return ExpSE3(delta) * T;
}

void ExpectGradientMatchesCentralDifferences(TransformUpdate update, const Eigen::Vector3d& pivot) {
  const Synthetic s = MakeSynthetic();
  const PairCost cost = MakeCost(s, Binning::kBSpline);
  ASSERT_EQ(cost.UsedSceneCount(), 1);
  const Eigen::Isometry3d T = Perturbed(s.T_camera_lidar, 0.02, 0.5);
  Vector6d analytic;
  const double value = cost.EvaluateWithGradient(T, update, pivot, &analytic);
  EXPECT_EQ(value, cost.Evaluate(T));  // same kernel, same samples, same order
  Vector6d numeric;
  for (int axis = 0; axis < 6; ++axis) {
    const double h = axis < 3 ? 1e-3 : 2e-4;  // metres, radians: ~0.1 px
    Vector6d delta = Vector6d::Zero();
    delta[axis] = h;
    numeric[axis] = (cost.Evaluate(ApplyTransformUpdate(T, delta, update, pivot)) -
                     cost.Evaluate(ApplyTransformUpdate(T, -delta, update, pivot))) /
                    (2.0 * h);
  }
  // Per axis within 5% of the gradient's size (float pixels, bilinear kinks and
  // samples crossing the border make the numeric one slightly rough).
  ASSERT_GT(analytic.norm(), 0.0);
  for (int axis = 0; axis < 6; ++axis) {
    // Translation and rotation parts have different units: compare each with its own part's size.
    const double scale = axis < 3 ? numeric.head<3>().norm() : numeric.tail<3>().norm();
    EXPECT_NEAR(analytic[axis], numeric[axis], 0.05 * scale) << "axis " << axis << "\nanalytic " << analytic.transpose()
                                                             << "\nnumeric  " << numeric.transpose();
  }
}

TEST(CostGradient, MatchesCentralDifferencesAboutPivot) {
  ExpectGradientMatchesCentralDifferences(TransformUpdate::kAboutSourcePoint, Eigen::Vector3d(0.5, -1.0, 3.0));
}

TEST(CostGradient, MatchesCentralDifferencesLeftTwist) {
  ExpectGradientMatchesCentralDifferences(TransformUpdate::kLeftTwist, Eigen::Vector3d::Zero());
}

TEST(CostGradient, HardBinningHasZeroGradient) {
  const Synthetic s = MakeSynthetic();
  const PairCost cost = MakeCost(s, Binning::kHard);
  Vector6d gradient = Vector6d::Ones();
  const double value =
      cost.EvaluateWithGradient(s.T_camera_lidar, TransformUpdate::kLeftTwist, Eigen::Vector3d::Zero(), &gradient);
  EXPECT_EQ(value, cost.Evaluate(s.T_camera_lidar));
  EXPECT_EQ(gradient, Vector6d::Zero());
}

TEST(PairCostSpeed, CostIsBitIdenticalForOneAndTwoThreads) {
  const Synthetic s = MakeSynthetic();
  for (const Binning binning : {Binning::kHard, Binning::kBSpline}) {
    // Several scenes, so the threads really split the work.
    PairCostOptions options;
    options.histogram.binning = binning;
    std::vector<SceneSwathe> swathes;
    for (int k = 0; k < 6; ++k)
      swathes.push_back(SceneSwathe::Build(s.scene, s.camera, s.image, {&s.scans[k % 2], &s.scans[(k + 1) % 2]},
                                           options.swathe, NormalisationOptions{}));
    PairCost cost(s.camera, "lidar", std::move(swathes), options);
    cost.RefreshVisibility(s.T_camera_lidar);
    const Eigen::Isometry3d T = Perturbed(s.T_camera_lidar, 0.01, 0.3);
    double one = 0.0, two = 0.0;
    {
      const tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 1);
      one = cost.Evaluate(T);
    }
    {
      const tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 2);
      for (int repeat = 0; repeat < 5; ++repeat) {
        two = cost.Evaluate(T);
        EXPECT_EQ(one, two) << BinningName(binning);
      }
    }
    EXPECT_TRUE(std::isfinite(one));
  }
}

TEST(GradientSolver, LbfgsRecoversTheTruthWithFewerEvaluationsThanTheSimplex) {
  const Synthetic s = MakeSynthetic();
  const PairCost cost = MakeCost(s, Binning::kBSpline);
  const Eigen::Isometry3d start = Perturbed(s.T_camera_lidar, 0.03, 1.0);
  std::size_t count = 0;
  const Eigen::Vector3d sum = cost.SumProjectedLidarPoints(start, &count);
  ASSERT_GT(count, 0u);
  const Eigen::Vector3d pivot = sum / static_cast<double>(count);

  GradientSolverOptions lbfgs_options;
  lbfgs_options.pivot_source = pivot;
  std::string why;
  ASSERT_TRUE(lbfgs_options.IsValid(&why)) << why << " pivot " << pivot.transpose() << " count " << count;
  Eigen::Isometry3d lbfgs = start;
  const GradientSolverSummary lbfgs_summary = MinimiseWithGradient(cost, lbfgs_options, &lbfgs);

  NelderMeadOptions simplex_options;
  simplex_options.pivot_source = pivot;
  Eigen::Isometry3d simplex = start;
  const NelderMeadSummary simplex_summary =
      MinimiseOverTransform([&](const Eigen::Isometry3d& T) { return cost.Evaluate(T); }, simplex_options, &simplex);

  const double lbfgs_t = TranslationError(lbfgs, s.T_camera_lidar), lbfgs_r = RotationErrorDegrees(lbfgs, s.T_camera_lidar);
  const double simplex_t = TranslationError(simplex, s.T_camera_lidar),
               simplex_r = RotationErrorDegrees(simplex, s.T_camera_lidar);
  std::printf("lbfgs:   %s; error %.2f mm %.3f deg\n", lbfgs_summary.BriefReport().c_str(), 1e3 * lbfgs_t, lbfgs_r);
  std::printf("simplex: %s; error %.2f mm %.3f deg\n", simplex_summary.BriefReport().c_str(), 1e3 * simplex_t,
              simplex_r);
  EXPECT_LT(lbfgs_summary.final_value, lbfgs_summary.initial_value);
  EXPECT_LT(lbfgs_t, 0.003);
  EXPECT_LT(lbfgs_r, 0.1);
  EXPECT_LT(lbfgs_summary.evaluations, simplex_summary.evaluations);
}

// A deterministic jitter in [-amplitude / 2, amplitude / 2), constant on cells
// of 1 / resolution of the scaled offset e: rounding no gradient sees.
double Jitter(const Vector6d& e, double resolution, double amplitude) {
  std::uint64_t hash = 1469598103934665603ull;
  for (int k = 0; k < 6; ++k)
    hash = (hash ^ static_cast<std::uint64_t>(std::llround(e[k] * resolution))) * 1099511628211ull;
  return amplitude * (static_cast<double>(hash >> 11) / 9007199254740992.0 - 0.5);
}

// One parameter scale per axis of the solver's update: metres (translation), radians (rotation).
Vector6d ParameterScales(const GradientSolverOptions& options) {
  Vector6d scales;
  scales << Eigen::Vector3d::Constant(options.initial_step_translation_m),
      Eigen::Vector3d::Constant(options.initial_step_rotation_rad);
  return scales;
}

// A bowl as flat as NID near its minimum, with a cost's rounding jitter: 0.97 +
// 1e-6 x |e / width|^2 (e = Log(T * T_min^-1), width one parameter scale per
// axis), started two widths away along every axis. Ceres' first step is the
// gradient itself when its max norm is below 1: ~4e-6 scaled units, gaining
// ~1e-11, below the jitter, and the run ended where it started (as joint did
// 0.23 deg from the truth on world 1). With the cost normalised by the start's
// gradient the first step is one scale long.
TEST(GradientSolver, LbfgsCrossesAFlatBowlFromItsFirstStep) {
  const Eigen::Isometry3d T_min = TransformFromTuple((Vector6d() << 0.4, -1.1, 2.0, 0.1, -0.2, 1.5).finished());
  GradientSolverOptions options;
  options.initial_step_translation_m = 0.005;
  options.initial_step_rotation_rad = RadiansFromDegrees(0.1);
  const Vector6d width = ParameterScales(options);
  // Plus a deterministic jitter of +-1e-9, as a sum over ~1e6 single-precision
  // samples has (measured on NID: ~2e-9 between points 1e-4 deg apart).
  const auto bowl = [&](const Eigen::Isometry3d& T) {
    const Vector6d e = LogSE3(T * T_min.inverse()).cwiseQuotient(width);
    return 0.97 + 1e-6 * e.squaredNorm() + Jitter(e, 1e9, 2e-9);
  };
  const CostWithGradient cost = [&](const Eigen::Isometry3d& T, Vector6d* gradient) {
    if (gradient != nullptr) {
      // The exact gradient: an analytic one does not see the rounding either.
      const auto smooth = [&](const Eigen::Isometry3d& X) {
        return 1e-6 * LogSE3(X * T_min.inverse()).cwiseQuotient(width).squaredNorm();
      };
      *gradient = CentralDifferenceGradient(smooth, T, options.transform_update, options.pivot_source,
                                            Vector6d::Constant(1e-6));
    }
    return bowl(T);
  };
  const Eigen::Isometry3d start = ExpSE3(2.0 * width) * T_min;
  Eigen::Isometry3d T = start;
  const GradientSolverSummary summary = MinimiseWithGradient(cost, options, &T);
  std::printf("%s\n", summary.BriefReport().c_str());
  EXPECT_TRUE(summary.converged) << summary.termination;
  EXPECT_GT(summary.iterations, 1);
  EXPECT_NEAR(summary.initial_value, bowl(start), 1e-14);  // reported unscaled
  EXPECT_NEAR(summary.final_value, bowl(T), 1e-14);
  const Vector6d left = LogSE3(T * T_min.inverse()).cwiseQuotient(width);
  EXPECT_LT(left.cwiseAbs().maxCoeff(), 0.05) << left.transpose();
}

// A cost rough below a small scale (a deterministic jitter the gradient does
// not see, as points crossing the image border give the NID): line searches of
// at most 4 trial steps end the run on fewer evaluations than Ceres' 20, as
// near the minimum.
TEST(GradientSolver, ShortLineSearchesSpendFewerEvaluationsOnARoughCost) {
  const Eigen::Isometry3d T_min = TransformFromTuple((Vector6d() << 0.2, -0.4, 1.0, 0.1, 0.05, -0.3).finished());
  GradientSolverOptions options;
  const Vector6d width = ParameterScales(options);
  const auto smooth = [&](const Eigen::Isometry3d& T) {
    return 1e-4 * LogSE3(T * T_min.inverse()).cwiseQuotient(width).squaredNorm();
  };
  const auto rough = [&](const Eigen::Isometry3d& T) {
    const Vector6d e = LogSE3(T * T_min.inverse()).cwiseQuotient(width);
    return 0.95 + smooth(T) + Jitter(e, 1e6, 1e-8);
  };
  const CostWithGradient cost = [&](const Eigen::Isometry3d& T, Vector6d* gradient) {
    if (gradient != nullptr) {
      *gradient = CentralDifferenceGradient(smooth, T, options.transform_update, options.pivot_source,
                                            Vector6d::Constant(1e-6));
    }
    return rough(T);
  };
  const Eigen::Isometry3d start = ExpSE3(3.0 * width) * T_min;
  const auto solve = [&](int steps, Eigen::Isometry3d* T) {
    options.line_search_max_steps = steps;
    *T = start;
    return MinimiseWithGradient(cost, options, T);
  };
  Eigen::Isometry3d long_end, short_end;
  const GradientSolverSummary long_searches = solve(20, &long_end);
  const GradientSolverSummary short_searches = solve(4, &short_end);
  std::printf("20 steps: %s\n4 steps: %s\n", long_searches.BriefReport().c_str(),
              short_searches.BriefReport().c_str());
  EXPECT_LT(short_searches.evaluations, long_searches.evaluations);
  // Both end where the roughness (1e-8 against 1e-4 per scale^2) leaves the minimum undetermined: ~0.01 scale.
  for (const Eigen::Isometry3d& T : {long_end, short_end}) {
    EXPECT_LT(LogSE3(T * T_min.inverse()).cwiseQuotient(width).cwiseAbs().maxCoeff(), 0.05);
  }
  options.line_search_max_steps = 0;
  EXPECT_FALSE(options.IsValid());
}

// A coarse-to-fine schedule ends its middle stages at the coarse function tolerance, its first and last at the
// run's own. The valley's floor falls slowly (one direction 1000 times flatter) and each stage's minimum is
// elsewhere (as a blur moves it): a loose coarse tolerance cuts the middle stage's tail only, and the last stage
// still ends at its minimum.
TEST(GradientSolver, MiddleStagesStopAtTheCoarseTolerance) {
  const Eigen::Isometry3d T_min = TransformFromTuple((Vector6d() << 0.2, -0.4, 1.0, 0.1, 0.05, -0.3).finished());
  GradientSolverOptions options;
  const Vector6d width = ParameterScales(options);
  Vector6d curvature;
  curvature << 1e-4, 1e-4, 1e-4, 1e-4, 1e-4, 1e-7;
  double shift = 0.0;  // the current stage's minimum, in parameter scales along every axis
  const auto valley = [&](const Eigen::Isometry3d& T) {
    const Vector6d e = LogSE3(T * T_min.inverse()).cwiseQuotient(width) - Vector6d::Constant(shift);
    return 0.9 + e.cwiseAbs2().dot(curvature);
  };
  const CostWithGradient cost = [&](const Eigen::Isometry3d& T, Vector6d* gradient) {
    if (gradient != nullptr) {
      *gradient = CentralDifferenceGradient(valley, T, options.transform_update, options.pivot_source,
                                            Vector6d::Constant(1e-6));
    }
    return valley(T);
  };
  const auto prepare = [&](const OptimisationStage& stage, const Eigen::Isometry3d&) {
    shift = 10.0 * stage.blur_fraction;
  };
  const Eigen::Isometry3d start = ExpSE3(Vector6d::Constant(3.0).cwiseProduct(width)) * T_min;
  const std::vector<OptimisationStage> three = {{1.0, 0.2, 0}, {1.0, 0.1, 0}, {1.0, 0.0, 0}};
  const auto solve = [&](double coarse_tolerance, const std::vector<OptimisationStage>& stages,
                         Eigen::Isometry3d* T) {
    options.coarse_function_tolerance = coarse_tolerance;
    *T = start;
    return MinimiseCoarseToFineWithGradient(cost, prepare, options, stages, 1.0, T);
  };
  Eigen::Isometry3d loose_end, tight_end;
  const std::vector<GradientSolverSummary> loose = solve(1e-6, three, &loose_end);
  const std::vector<GradientSolverSummary> tight = solve(0.0, three, &tight_end);  // every stage at 1e-10
  ASSERT_EQ(loose.size(), 3u);
  ASSERT_EQ(tight.size(), 3u);
  std::printf("evaluations per stage at 1e-6: %d %d %d, at 1e-10: %d %d %d; ends %.3g and %.3g above the minimum\n",
              loose[0].evaluations, loose[1].evaluations, loose[2].evaluations, tight[0].evaluations,
              tight[1].evaluations, tight[2].evaluations, valley(loose_end) - 0.9, valley(tight_end) - 0.9);
  EXPECT_EQ(loose[0].evaluations, tight[0].evaluations);  // the first stage runs to the run's own tolerance
  EXPECT_EQ(loose[0].final_value, tight[0].final_value);
  EXPECT_LT(loose[1].evaluations, tight[1].evaluations);
  EXPECT_GT(loose[1].final_value, tight[1].final_value);
  // The last stage at the run's own tolerance: both end at its minimum.
  EXPECT_LT(valley(loose_end) - 0.9, 1e-9);
  EXPECT_LT(valley(tight_end) - 0.9, 1e-9);
  // With two stages there is no middle one.
  Eigen::Isometry3d two_loose, two_tight;
  const std::vector<OptimisationStage> two = {three[0], three[2]};
  EXPECT_EQ(solve(1e-6, two, &two_loose).back().evaluations, solve(0.0, two, &two_tight).back().evaluations);
  EXPECT_TRUE(two_loose.isApprox(two_tight, 0.0));
}

// --run-radius-*: a run whose minimum lies 1 m / 20 deg away stops at the wall
// around its start (the wall's pull balances the bowl's within a millimetre);
// without a radius the same run reaches the minimum.
TEST(GradientSolver, RunRadiusKeepsARunNearItsStart) {
  const Eigen::Isometry3d start = TransformFromTuple((Vector6d() << 0.1, 0.2, -0.3, 0.05, 0.1, -0.2).finished());
  Vector6d away;
  away << 0.6, -0.8, 0.0, 0.0, RadiansFromDegrees(20.0), 0.0;  // 1 m and 20 deg
  const Eigen::Isometry3d T_min = ExpSE3(away) * start;
  const auto bowl = [&](const Eigen::Isometry3d& T) { return 0.97 + 0.001 * LogSE3(T * T_min.inverse()).squaredNorm(); };
  GradientSolverOptions options;
  const CostWithGradient cost = [&](const Eigen::Isometry3d& T, Vector6d* gradient) {
    if (gradient != nullptr) {
      *gradient = CentralDifferenceGradient(bowl, T, options.transform_update, options.pivot_source,
                                            Vector6d::Constant(1e-6));
    }
    return bowl(T);
  };
  const auto moved = [&](const Eigen::Isometry3d& T) {
    return std::pair{(T.translation() - start.translation()).norm(),
                     Eigen::AngleAxisd(T.linear() * start.linear().transpose()).angle()};
  };

  Eigen::Isometry3d free_end = start;
  MinimiseWithGradient(cost, options, &free_end);
  EXPECT_LT(LogSE3(free_end * T_min.inverse()).norm(), 1e-3);

  options.run_radius_translation_m = 0.2;
  options.run_radius_rotation_rad = RadiansFromDegrees(5.0);
  Eigen::Isometry3d walled_end = start;
  const GradientSolverSummary summary = MinimiseWithGradient(cost, options, &walled_end);
  const auto [translation_m, rotation_rad] = moved(walled_end);
  EXPECT_GT(translation_m, 0.19);  // it went as far as the wall lets it
  EXPECT_LT(translation_m, 0.201);
  EXPECT_GT(rotation_rad, RadiansFromDegrees(4.9));
  EXPECT_LT(rotation_rad, RadiansFromDegrees(5.02));
  EXPECT_TRUE(std::isfinite(summary.final_value));

  options.run_radius_rotation_rad = std::nan("");
  EXPECT_FALSE(options.IsValid());
  options.run_radius_rotation_rad = RadiansFromDegrees(180.0);
  EXPECT_FALSE(options.IsValid());
  options.run_radius_rotation_rad = 0.0;
  options.run_radius_translation_m = -0.1;
  EXPECT_FALSE(options.IsValid());
}

}  // namespace
}  // namespace scenecal
