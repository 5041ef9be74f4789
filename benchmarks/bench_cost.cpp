// Throughput of the pair cost (PairCost::Evaluate): projection, bilinear
// sampling, joint histogram, NID, over every point of every used scene.
//
// Data: the real OpenCalib frame 1 (/work/shared/data/opencalib/1: 1920x1200
// radtan camera, 101k-point 3D sweep, reference T_camera_lidar). The points in
// front of the camera form one "scan"; a scene's swathe repeats that scan
// under small relative poses (as a driving swathe would), and every scene uses
// the real image. Sizes (printed as counters): 4 scenes, and per scene
// kScansX1 x {1, 2, 4} scans, i.e. ~0.26 M, ~0.52 M and ~1.05 M points per
// evaluation. Items per second = swathe points (visible) per second, counted
// before culling; the `projected` counter is the fraction that lands in the image.
//
// Run: cmake -S . -B build-bench -DSCENECAL_BUILD_BENCHMARKS=ON &&
//      cmake --build build-bench -j2 --target bench_cost && build-bench/bin/bench_cost
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <tbb/global_control.h>

#include "core/geometry.hpp"
#include "core/nelder_mead.hpp"
#include "core/pair_cost.hpp"
#include "hard_kernel_cost.hpp"
#include "io/opencalib.hpp"
#include "io/pcd.hpp"

namespace scenecal {
namespace {

constexpr int kScenes = 4;

struct RealFrame {
  CameraInfo camera;
  Eigen::Isometry3d T_camera_lidar = Eigen::Isometry3d::Identity();
  cv::Mat intensity;  // CV_32FC1 in [0, 1]
  LidarScan scan;     // points that project into the image, lidar frame
};

const RealFrame& Frame() {
  static const RealFrame frame = [] {
    const std::filesystem::path dir = std::filesystem::path(SCENECAL_SHARED_DATA_DIR) / "opencalib" / "1";
    RealFrame f;
    const io::OpenCalibCalibration calibration = io::ReadOpenCalibCalibration(dir / "calib.txt");
    const cv::Mat grey = cv::imread((dir / "calib.jpg").string(), cv::IMREAD_GRAYSCALE);
    if (grey.empty()) throw std::runtime_error("cannot read " + (dir / "calib.jpg").string());
    grey.convertTo(f.intensity, CV_32F, 1.0 / 255.0);
    f.camera.name = "cam";
    f.camera.model.width = grey.cols;
    f.camera.model.height = grey.rows;
    f.camera.model.kind = CameraModelKind::kRadTan;
    f.camera.model.fx = calibration.fx;
    f.camera.model.fy = calibration.fy;
    f.camera.model.cx = calibration.cx;
    f.camera.model.cy = calibration.cy;
    f.camera.model.distortion = calibration.distortion;
    f.T_camera_lidar = calibration.T_camera_lidar;
    for (const LidarPoint& p : io::ReadPcd(dir / "calib.pcd").points) {
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
      // Keep the points that project into the image at the reference: a
      // swathe is built for its camera, so nearly all its points project.
      Eigen::Vector2d pixel;
      if (f.camera.model.Project(f.T_camera_lidar * Eigen::Vector3d(p.x, p.y, p.z), &pixel, 0.0, 1.0))
        f.scan.points.push_back(p);
    }
    return f;
  }();
  return frame;
}

// Scans per scene at size x1: ~65k swathe points per scene, ~260k per evaluation.
int ScansX1() {
  const auto per_scan = static_cast<double>(Frame().scan.points.size());
  return std::max(1, static_cast<int>(std::lround(65000.0 / per_scan)));
}

std::unique_ptr<PairCost> MakeCost(Binning binning, int size_factor) {
  const RealFrame& f = Frame();
  PairCostOptions options;
  options.histogram.binning = binning;
  const int scans = ScansX1() * size_factor;
  std::vector<SceneSwathe> swathes;
  for (int s = 0; s < kScenes; ++s) {
    Scene scene;
    scene.camera = "cam";
    scene.lidar = "lidar";
    scene.image_t_us = s;
    std::vector<const LidarScan*> scan_pointers;
    for (int j = 0; j < scans; ++j) {
      // A few centimetres and a tenth of a degree apart, like consecutive scans of a swathe.
      Vector6d tuple;
      tuple << 0.01 * j, 0.005 * s, 0.03 * j, 0.0, RadiansFromDegrees(0.1 * j), RadiansFromDegrees(0.05 * s);
      scene.scans.push_back({j, TransformFromTuple(tuple)});
      scan_pointers.push_back(&f.scan);
    }
    swathes.push_back(SceneSwathe::Build(scene, f.camera, f.intensity, scan_pointers, options.swathe,
                                         NormalisationOptions{}));
  }
  auto cost = std::make_unique<PairCost>(f.camera, "lidar", std::move(swathes), options);
  cost->RefreshVisibility(f.T_camera_lidar);
  return cost;
}

std::size_t VisiblePoints(const PairCost& cost) {
  std::size_t points = 0;
  for (const SceneSwathe& swathe : cost.Scenes()) points += swathe.VisibleCount();
  return points;
}

// Args: binning (0 hard, 1 B-spline), threads, size factor (1, 2, 4).
void BM_Evaluate(benchmark::State& state) {
  const auto binning = state.range(0) == 0 ? Binning::kHard : Binning::kBSpline;
  const tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                                    static_cast<std::size_t>(state.range(1)));
  const std::unique_ptr<PairCost> cost = MakeCost(binning, static_cast<int>(state.range(2)));
  const Eigen::Isometry3d T = Frame().T_camera_lidar;
  const std::size_t points = VisiblePoints(*cost);
  std::size_t projected = 0;
  for (const std::size_t p : cost->ProjectedAtRefresh()) projected += p;
  double sink = 0.0;
  for (auto _ : state) {
    sink += cost->Evaluate(T);
    benchmark::DoNotOptimize(sink);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * points));
  state.counters["points"] = static_cast<double>(points);
  state.counters["scenes"] = cost->UsedSceneCount();
  state.counters["projected"] = static_cast<double>(projected) / static_cast<double>(points);
  state.SetLabel(std::string(BinningName(binning)) + " nid");
}

void EvaluateArguments(benchmark::internal::Benchmark* b) {
  b->ArgNames({"bspline", "threads", "size"});
  for (const int binning : {0, 1}) {
    for (const int threads : {1, 2}) {
      for (const int size : {1, 2, 4}) b->Args({binning, threads, size});
    }
  }
}
BENCHMARK(BM_Evaluate)->Apply(EvaluateArguments)->Unit(benchmark::kMillisecond)->UseRealTime();

// The hard NID cost of BM_Evaluate/bspline:0 computed with
// SceneSwathe::AddHardCounts (benchmarks/hard_kernel_cost.hpp) instead of the
// ForEachProjected visitor that PairCost::SceneCost uses; checked bit for bit
// against PairCost::Evaluate before timing (the benchmark fails otherwise).
// Args: threads, size factor.
void BM_HardKernel(benchmark::State& state) {
  const tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                                    static_cast<std::size_t>(state.range(0)));
  const std::unique_ptr<PairCost> cost = MakeCost(Binning::kHard, static_cast<int>(state.range(1)));
  const Eigen::Isometry3d T = Frame().T_camera_lidar;
  const std::vector<std::size_t> used = bench::UsedScenes(*cost);
  const double reference = cost->Evaluate(T);
  if (bench::HardKernelCost(*cost, used, T) != reference) {
    state.SkipWithError("AddHardCounts cost differs from PairCost::Evaluate");
    return;
  }
  const std::size_t points = VisiblePoints(*cost);
  double sink = 0.0;
  for (auto _ : state) {
    sink += bench::HardKernelCost(*cost, used, T);
    benchmark::DoNotOptimize(sink);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * points));
  state.counters["points"] = static_cast<double>(points);
  state.counters["scenes"] = static_cast<double>(used.size());
  state.SetLabel("hard nid, AddHardCounts");
}
BENCHMARK(BM_HardKernel)
    ->ArgNames({"threads", "size"})
    ->ArgsProduct({{1, 2}, {1, 2, 4}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Cost and analytic gradient (PairCost::EvaluateWithGradient, B-spline NID,
// the --lower-solver lbfgs kernel) on the same data as BM_Evaluate's B-spline
// cases: items per second against BM_Evaluate/bspline:1 gives the cost of one
// gradient evaluation in plain evaluations (kGradientEvaluationCost,
// core/calibrate.hpp). Args: threads, size factor.
void BM_EvaluateWithGradient(benchmark::State& state) {
  const tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                                    static_cast<std::size_t>(state.range(0)));
  const std::unique_ptr<PairCost> cost = MakeCost(Binning::kBSpline, static_cast<int>(state.range(1)));
  // Slightly off the reference, so the gradient is not near zero (the cost does not depend on it).
  Vector6d delta;
  delta << 0.01, -0.005, 0.008, RadiansFromDegrees(0.2), RadiansFromDegrees(-0.1), RadiansFromDegrees(0.15);
  const Eigen::Isometry3d T = ExpSE3(delta) * Frame().T_camera_lidar;
  const std::size_t points = VisiblePoints(*cost);
  double sink = 0.0;
  Vector6d gradient;
  // The cost of EvaluateWithGradient is Evaluate's, bit for bit (the same histogram).
  if (cost->EvaluateWithGradient(T, TransformUpdate::kAboutSourcePoint, Eigen::Vector3d::Zero(), &gradient) !=
      cost->Evaluate(T)) {
    state.SkipWithError("EvaluateWithGradient cost differs from Evaluate");
    return;
  }
  for (auto _ : state) {
    sink += cost->EvaluateWithGradient(T, TransformUpdate::kAboutSourcePoint, Eigen::Vector3d::Zero(), &gradient);
    sink += gradient.sum();
    benchmark::DoNotOptimize(sink);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * points));
  state.counters["points"] = static_cast<double>(points);
  state.counters["scenes"] = cost->UsedSceneCount();
  state.SetLabel("bspline nid + gradient");
}
BENCHMARK(BM_EvaluateWithGradient)
    ->ArgNames({"threads", "size"})
    ->Args({1, 1})
    ->Args({1, 2})
    ->Args({2, 1})
    ->Args({2, 2})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace scenecal

BENCHMARK_MAIN();
