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
#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

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

// ---------------------------------------------------------------------------
// Each cost kernel beside a read-only bound measured in the same run.
//
// The bound is a loop that only reads what the kernel reads, in the kernel's
// order: each point's coordinates, reflectance and visibility flag, and the
// four pixels of its bilinear sample (at the pixel the kernel projects it to,
// precomputed: a 4-byte offset a point, read in place of the projection; pixel
// (0, 0) for points that do not project). Every iteration
// times the kernel and then the bound, so both see the same machine load; the
// ratio kernel / bound is what to compare on a shared, noisy machine. Scenes
// are shared out to the threads as PairCost does (one task per scene).
//
// Data: synthetic, 1 M points projecting into a 1280x960 pinhole image
// (fx = fy = 1000 px, a plane 10 m ahead, ~0.8 points per pixel; image:
// uniform noise blurred by 1.5 px; reflectance: the image at the point plus
// noise), in raster order or shuffled, cut into 4 scenes of 250 k
// consecutive points; or the OpenCalib frame of BM_Evaluate at size x4 (4
// scenes, ~0.8 M points, 1920x1200 radtan).
//
//   bench_cost --benchmark_filter=BM_KernelVsBound --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
//
// Counters: kernel_Mpts and bound_Mpts (M points per second, wall time;
// points = visible swathe points), ratio = kernel_Mpts / bound_Mpts.

enum class BoundData { kSyntheticRaster, kSyntheticRandom, kOpenCalib };
enum class BoundKernel { kHard, kBSpline, kBSplineGradient };
constexpr std::array<const char*, 3> kBoundDataNames = {"synthetic raster", "synthetic random", "opencalib x4"};
constexpr std::array<const char*, 3> kBoundKernelNames = {"hard nid", "bspline nid", "bspline nid + gradient"};

constexpr int kSyntheticWidth = 1280, kSyntheticHeight = 960;
constexpr int kSyntheticPoints = 1'000'000;
constexpr int kSyntheticScenes = 4;
constexpr double kSyntheticFocalPx = 1000.0, kSyntheticDepthM = 10.0;

struct SyntheticFrame {
  CameraInfo camera;
  cv::Mat intensity;                 // CV_32FC1 in [0, 1]
  std::vector<LidarPoint> raster;    // lidar frame = camera frame, metres; row by row
};

const SyntheticFrame& Synthetic() {
  static const SyntheticFrame frame = [] {
    SyntheticFrame f;
    f.camera.name = "cam";
    f.camera.model.width = kSyntheticWidth;
    f.camera.model.height = kSyntheticHeight;
    f.camera.model.kind = CameraModelKind::kPinhole;
    f.camera.model.fx = f.camera.model.fy = kSyntheticFocalPx;
    f.camera.model.cx = 0.5 * kSyntheticWidth;
    f.camera.model.cy = 0.5 * kSyntheticHeight;
    cv::Mat noise(kSyntheticHeight, kSyntheticWidth, CV_32FC1);
    cv::setRNGSeed(5);
    cv::randu(noise, 0.0f, 1.0f);
    cv::GaussianBlur(noise, f.intensity, cv::Size(0, 0), 1.5);
    cv::normalize(f.intensity, f.intensity, 0.0, 1.0, cv::NORM_MINMAX);
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> jitter(0.0f, 0.5f), reflectance_noise(0.0f, 1.0f);
    // Rows of points from the top of the image down, each left to right, inside the sampling margin.
    const int per_row = (kSyntheticPoints + kSyntheticHeight - 3) / (kSyntheticHeight - 2);
    const double step_u = (kSyntheticWidth - 2.0) / per_row;
    for (int k = 0; k < kSyntheticPoints; ++k) {
      const double u = 0.5 + step_u * (k % per_row) + jitter(rng);
      const double v = 0.5 + (k / per_row) + jitter(rng);
      const float pixel = f.intensity.at<float>(static_cast<int>(v), static_cast<int>(u));
      LidarPoint p;
      p.z = static_cast<float>(kSyntheticDepthM);
      p.x = static_cast<float>((u - f.camera.model.cx) / kSyntheticFocalPx * kSyntheticDepthM);
      p.y = static_cast<float>((v - f.camera.model.cy) / kSyntheticFocalPx * kSyntheticDepthM);
      p.reflectance = 255.0f * (0.7f * pixel + 0.3f * reflectance_noise(rng));
      f.raster.push_back(p);
    }
    return f;
  }();
  return frame;
}

std::unique_ptr<PairCost> MakeSyntheticCost(Binning binning, bool shuffled) {
  const SyntheticFrame& f = Synthetic();
  std::vector<LidarPoint> points = f.raster;
  if (shuffled) {
    std::mt19937 rng(13);
    std::shuffle(points.begin(), points.end(), rng);
  }
  PairCostOptions options;
  options.histogram.binning = binning;
  options.swathe.occlusion = false;  // one plane: nothing to hide
  const SwatheImages images = SwatheImages::Prepare(f.intensity, NormalisationOptions{});
  std::vector<SceneSwathe> swathes;
  const std::size_t per_scene = points.size() / kSyntheticScenes;
  for (int s = 0; s < kSyntheticScenes; ++s) {
    Scene scene;
    scene.camera = "cam";
    scene.lidar = "lidar";
    scene.image_t_us = s;
    scene.scans.push_back({0, Eigen::Isometry3d::Identity()});
    LidarScan scan;
    scan.points.assign(points.begin() + static_cast<std::ptrdiff_t>(s * per_scene),
                       points.begin() + static_cast<std::ptrdiff_t>((s + 1) * per_scene));
    swathes.push_back(SceneSwathe::Build(scene, f.camera, images, {&scan}, options.swathe, NormalisationOptions{}));
  }
  auto cost = std::make_unique<PairCost>(f.camera, "lidar", std::move(swathes), options);
  cost->RefreshVisibility(Eigen::Isometry3d::Identity());
  return cost;
}

// A cost of each data set and binning, built once (building 1 M points takes seconds).
const PairCost& BoundCost(BoundData data, Binning binning) {
  static std::map<std::pair<BoundData, Binning>, std::unique_ptr<PairCost>> costs;
  std::unique_ptr<PairCost>& cost = costs[{data, binning}];
  if (!cost) {
    cost = data == BoundData::kOpenCalib ? MakeCost(binning, 4)
                                         : MakeSyntheticCost(binning, data == BoundData::kSyntheticRandom);
  }
  return *cost;
}

Eigen::Isometry3d BoundPose(BoundData data) {
  return data == BoundData::kOpenCalib ? Frame().T_camera_lidar : Eigen::Isometry3d::Identity();
}

// What the bound of one scene reads: its arrays, its image and each point's top-left pixel offset.
struct BoundScene {
  SceneSwathe::PointArrays points;
  const float* image = nullptr;
  std::ptrdiff_t stride = 0;  // floats per row
  std::vector<std::int32_t> offset;
};

std::vector<BoundScene> MakeBoundScenes(const PairCost& cost, const Eigen::Isometry3d& T_camera_lidar) {
  std::vector<BoundScene> scenes;
  for (const std::size_t s : bench::UsedScenes(cost)) {
    const SceneSwathe& swathe = cost.Scenes()[s];
    BoundScene scene;
    scene.points = swathe.Points();
    scene.image = swathe.Image().ptr<float>();
    scene.stride = static_cast<std::ptrdiff_t>(swathe.Image().step1());
    scene.offset.assign(swathe.PointCount(), 0);
    swathe.ForEachProjected(T_camera_lidar, true, [&](std::size_t point, float, float u, float v, float) {
      scene.offset[point] = static_cast<std::int32_t>(static_cast<int>(v) * scene.stride + static_cast<int>(u));
    });
    scenes.push_back(std::move(scene));
  }
  return scenes;
}

// The read-only pass over one scene: every value is read and folded into an
// integer sum (integer adds: no floating-point chain, and the compiler may
// vectorise the streams).
__attribute__((target_clones("avx2", "default"))) std::uint32_t ReadOnlyPass(
    const float* __restrict x, const float* __restrict y, const float* __restrict z,
    const float* __restrict reflectance01, const std::uint8_t* __restrict visible,
    const std::int32_t* __restrict offset, std::size_t count, const float* __restrict image, std::ptrdiff_t stride) {
  std::uint32_t sum = 0;
  for (std::size_t k = 0; k < count; ++k) {
    const float* pixel = image + offset[k];
    sum += std::bit_cast<std::uint32_t>(x[k]) + std::bit_cast<std::uint32_t>(y[k]) +
           std::bit_cast<std::uint32_t>(z[k]) + std::bit_cast<std::uint32_t>(reflectance01[k]) + visible[k] +
           std::bit_cast<std::uint32_t>(pixel[0]) + std::bit_cast<std::uint32_t>(pixel[1]) +
           std::bit_cast<std::uint32_t>(pixel[stride]) + std::bit_cast<std::uint32_t>(pixel[stride + 1]);
  }
  return sum;
}

std::uint32_t ReadOnlyBound(const std::vector<BoundScene>& scenes) {
  std::vector<std::uint32_t> sums(scenes.size(), 0u);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, scenes.size(), 1),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t i = range.begin(); i != range.end(); ++i) {
                        const BoundScene& s = scenes[i];
                        sums[i] = ReadOnlyPass(s.points.x.data(), s.points.y.data(), s.points.z.data(),
                                               s.points.reflectance01.data(), s.points.visible.data(),
                                               s.offset.data(), s.offset.size(), s.image, s.stride);
                      }
                    });
  std::uint32_t sum = 0;
  for (const std::uint32_t s : sums) sum += s;
  return sum;
}

// Args: data (BoundData), kernel (BoundKernel), threads.
void BM_KernelVsBound(benchmark::State& state) {
  const auto data = static_cast<BoundData>(state.range(0));
  const auto kernel = static_cast<BoundKernel>(state.range(1));
  const tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                                    static_cast<std::size_t>(state.range(2)));
  const PairCost& cost = BoundCost(data, kernel == BoundKernel::kHard ? Binning::kHard : Binning::kBSpline);
  const Eigen::Isometry3d T = BoundPose(data);
  const std::vector<BoundScene> scenes = MakeBoundScenes(cost, T);
  std::size_t points = 0;
  for (const BoundScene& scene : scenes) {
    for (const std::uint8_t visible : scene.points.visible) points += visible;
  }
  using Clock = std::chrono::steady_clock;
  double kernel_seconds = 0.0, bound_seconds = 0.0, sink = 0.0;
  Vector6d gradient;
  for (auto _ : state) {
    const Clock::time_point start = Clock::now();
    if (kernel == BoundKernel::kBSplineGradient) {
      sink += cost.EvaluateWithGradient(T, TransformUpdate::kAboutSourcePoint, Eigen::Vector3d::Zero(), &gradient);
      sink += gradient.sum();
    } else {
      sink += cost.Evaluate(T);
    }
    benchmark::DoNotOptimize(sink);
    const Clock::time_point kernel_end = Clock::now();
    std::uint32_t read = ReadOnlyBound(scenes);
    benchmark::DoNotOptimize(read);
    const Clock::time_point bound_end = Clock::now();
    const double seconds = std::chrono::duration<double>(kernel_end - start).count();
    state.SetIterationTime(seconds);
    kernel_seconds += seconds;
    bound_seconds += std::chrono::duration<double>(bound_end - kernel_end).count();
  }
  const double evaluated = static_cast<double>(state.iterations()) * static_cast<double>(points);
  state.SetItemsProcessed(static_cast<std::int64_t>(evaluated));
  state.counters["points"] = static_cast<double>(points);
  state.counters["kernel_Mpts"] = evaluated / kernel_seconds * 1e-6;
  state.counters["bound_Mpts"] = evaluated / bound_seconds * 1e-6;
  state.counters["ratio"] = bound_seconds / kernel_seconds;
  state.SetLabel(std::string(kBoundDataNames[static_cast<std::size_t>(data)]) + ", " +
                 kBoundKernelNames[static_cast<std::size_t>(kernel)]);
}
BENCHMARK(BM_KernelVsBound)
    ->ArgNames({"data", "kernel", "threads"})
    ->ArgsProduct({{0, 1, 2}, {0, 1, 2}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();

}  // namespace
}  // namespace scenecal

BENCHMARK_MAIN();
