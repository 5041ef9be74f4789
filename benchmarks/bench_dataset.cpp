// The cost kernel on a real calibration problem: the `joint` cost of a
// dataset (EvaluateJoint over every camera of its first lidar, hard NID, 32
// bins, the CLI defaults otherwise, swathes trimmed at the rig.yaml guess) at
// the rig.yaml guess, against the number of scenes, of scans per scene
// (--max-scans-per-scene thinning, 0 = all) and of threads. Two kernels: the
// ForEachProjected visitor of PairCost::SceneCost (what calibrate runs)
// and SceneSwathe::AddHardCounts (benchmarks/hard_kernel_cost.hpp).
//
// Before timing, every configuration checks AddHardCounts against the visitor
// path (ForEachProjected + BilinearSampler + HardBin) scene by scene: the 32x32
// count tables at the guess and at 8 poses 2 cm / 1 deg around it, on the sharp
// images and with the default stages' blurs (0.0015 and 0.004 of the image
// width). Any differing bin count fails the benchmark; the counters say how
// many samples were compared (`checked_samples`) and how many bins differed
// (`mismatched_bins`, 0).
//
// Dataset: $SCENECAL_BENCH_DATASET, default /tmp/rc
// (scenecal simulate --preset robotcar --seed 1 --output /tmp/rc).
// Run: build-bench/bin/bench_dataset [--benchmark_filter=...]
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include "core/calibrate.hpp"
#include "core/geometry.hpp"
#include "core/scenes.hpp"
#include "hard_kernel_cost.hpp"
#include "io/dataset.hpp"

namespace scenecal {
namespace {

std::filesystem::path DatasetPath() {
  const char* path = std::getenv("SCENECAL_BENCH_DATASET");
  return path != nullptr ? std::filesystem::path(path) : std::filesystem::path("/tmp/rc");
}

struct Problem {
  std::vector<std::unique_ptr<PairCost>> pairs;  // one per camera, the dataset's first lidar
  Eigen::Isometry3d T_base_lidar = Eigen::Isometry3d::Identity();
  std::size_t swathe_points = 0;     // visible swathe points of the used scenes, all pairs
  std::size_t projected_points = 0;  // of which project at the guess
  int used_scenes = 0;
};

// Loads the dataset's scenes like calibrate does (SelectScenes, BuildPairCost, visibility at the guess).
std::unique_ptr<Problem> LoadProblem(int scenes_per_camera, int max_scans_per_scene) {
  const io::Dataset dataset = io::OpenDataset(DatasetPath());
  CalibrationOptions options;
  options.scenes.scenes_per_camera = scenes_per_camera;
  options.scenes.max_scans_per_scene = max_scans_per_scene;
  CalibrationInput input;
  input.rig = dataset.rig;
  std::map<std::string, std::vector<TimeUs>> image_times, scan_times;
  for (const auto& [camera, files] : dataset.images) {
    for (const io::SensorFile& f : files) image_times[camera].push_back(f.t_us);
  }
  for (const auto& [lidar, files] : dataset.scans) {
    for (const io::SensorFile& f : files) scan_times[lidar].push_back(f.t_us);
  }
  input.selection = SelectScenes(dataset.rig, dataset.trajectory, image_times, scan_times, options.scenes);
  std::set<std::pair<std::string, TimeUs>> images_needed, scans_needed;
  for (const Scene& scene : input.selection.scenes) {
    images_needed.insert({scene.camera, scene.image_t_us});
    for (const SwatheScan& scan : scene.scans) scans_needed.insert({scene.lidar, scan.t_us});
  }
  for (const auto& [camera, t] : images_needed) {
    for (const io::SensorFile& f : dataset.images.at(camera)) {
      if (f.t_us == t) input.images[camera][t] = io::ReadImage(f, dataset.rig.FindCamera(camera)->model);
    }
  }
  std::vector<std::pair<std::string, const io::SensorFile*>> scan_files;
  for (const auto& [lidar, t] : scans_needed) {
    for (const io::SensorFile& f : dataset.scans.at(lidar)) {
      if (f.t_us == t) scan_files.push_back({lidar, &f});
    }
  }
  std::vector<LidarScan> scans(scan_files.size());
  tbb::parallel_for(std::size_t{0}, scan_files.size(), [&](std::size_t i) { scans[i] = io::ReadScan(*scan_files[i].second); });
  for (std::size_t i = 0; i < scans.size(); ++i) input.scans[scan_files[i].first][scan_files[i].second->t_us] = scans[i];

  auto problem = std::make_unique<Problem>();
  const LidarInfo& lidar = dataset.rig.lidars.front();
  problem->T_base_lidar = lidar.T_base_lidar;
  for (const CameraInfo& camera : dataset.rig.cameras) {
    auto pair = std::make_unique<PairCost>(BuildPairCost(input, camera, lidar.name, options));
    const Eigen::Isometry3d T_camera_lidar = camera.T_camera_base() * lidar.T_base_lidar;
    pair->RefreshVisibility(T_camera_lidar);
    for (const std::size_t s : bench::UsedScenes(*pair)) {
      problem->swathe_points += pair->Scenes()[s].VisibleCount();
      problem->projected_points += pair->ProjectedAtRefresh()[s];
    }
    problem->used_scenes += pair->UsedSceneCount();
    problem->pairs.push_back(std::move(pair));
  }
  return problem;
}

Problem& CachedProblem(int scenes_per_camera, int max_scans_per_scene) {
  static std::map<std::pair<int, int>, std::unique_ptr<Problem>> cache;
  auto& problem = cache[{scenes_per_camera, max_scans_per_scene}];
  if (!problem) problem = LoadProblem(scenes_per_camera, max_scans_per_scene);
  return *problem;
}

// The hard count table of one scene through the visitor path (what PairCost::SceneCost counts).
std::vector<std::uint32_t> VisitorCounts(const SceneSwathe& swathe, const Eigen::Isometry3d& T, int bins) {
  std::vector<std::uint32_t> counts(static_cast<std::size_t>(bins * bins), 0u);
  const SceneSwathe::BilinearSampler sample = swathe.Sampler();
  swathe.ForEachProjected(T, true, [&](std::size_t, float x01, float u, float v, float) {
    ++counts[static_cast<std::size_t>(HardBin(x01, bins) * bins + HardBin(sample(u, v), bins))];
  });
  return counts;
}

// Compares AddHardCounts with the visitor path (see the file comment). Mutates
// the blur of the pairs' images and restores the sharp ones.
void CheckAgainstVisitor(Problem& problem, std::size_t* checked_samples, std::size_t* mismatched_bins) {
  *checked_samples = 0;
  *mismatched_bins = 0;
  std::vector<Eigen::Isometry3d> poses = {problem.T_base_lidar};
  for (int axis = 0; axis < 3; ++axis) {
    for (const double sign : {-1.0, 1.0}) {
      if (axis == 2 && sign < 0) continue;
      Vector6d delta = Vector6d::Zero();
      delta(axis) = 0.02 * sign;
      delta(3 + (axis + 1) % 3) = RadiansFromDegrees(1.0) * sign;
      poses.push_back(ExpSE3(delta) * problem.T_base_lidar);
    }
  }
  poses.push_back(ExpSE3((Vector6d() << 0.02, 0.02, 0.02, 0.01, 0.01, 0.01).finished()) * problem.T_base_lidar);
  poses.push_back(ExpSE3((Vector6d() << -0.02, 0.01, -0.02, -0.01, 0.02, -0.01).finished()) * problem.T_base_lidar);
  constexpr int kBins = 32;
  for (const double blur : {0.0, 0.0015, 0.004}) {
    for (auto& pair : problem.pairs) {
      pair->SetImageBlur(blur);
      for (const Eigen::Isometry3d& T_base_lidar : poses) {
        const Eigen::Isometry3d T = pair->Camera().T_camera_base() * T_base_lidar;
        for (const SceneSwathe& swathe : pair->Scenes()) {
          const std::vector<std::uint32_t> expected = VisitorCounts(swathe, T, kBins);
          std::vector<std::uint32_t> counts(expected.size(), 0u);
          *checked_samples += swathe.AddHardCounts(T, kBins, kBins, counts.data());
          for (std::size_t i = 0; i < counts.size(); ++i) *mismatched_bins += counts[i] != expected[i];
        }
      }
    }
  }
  for (auto& pair : problem.pairs) pair->SetImageBlur(0.0);
}

double JointHardKernelCost(const Problem& problem, const std::vector<std::vector<std::size_t>>& used) {
  // EvaluateJoint's mean over the pairs, each through AddHardCounts (pairs in order).
  double sum = 0.0;
  int counted = 0;
  for (std::size_t p = 0; p < problem.pairs.size(); ++p) {
    if (used[p].empty()) continue;
    const PairCost& pair = *problem.pairs[p];
    sum += bench::HardKernelCost(pair, used[p], pair.Camera().T_camera_base() * problem.T_base_lidar);
    ++counted;
  }
  return sum / counted;
}

// Args: scenes per camera, max scans per scene (0 = all), threads, kernel (0 visitor, 1 AddHardCounts).
void BM_JointCost(benchmark::State& state) {
  if (!std::filesystem::exists(DatasetPath() / "rig.yaml")) {
    state.SkipWithError(("no dataset at " + DatasetPath().string() + " (set SCENECAL_BENCH_DATASET)").c_str());
    return;
  }
  const tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                                    static_cast<std::size_t>(state.range(2)));
  Problem& problem = CachedProblem(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  // Checked once per configuration (samples compared, bins differing).
  static std::map<std::pair<int, int>, std::pair<std::size_t, std::size_t>> checked;
  const std::pair<int, int> key{static_cast<int>(state.range(0)), static_cast<int>(state.range(1))};
  if (checked.count(key) == 0) CheckAgainstVisitor(problem, &checked[key].first, &checked[key].second);
  const auto [checked_samples, mismatched_bins] = checked[key];
  if (mismatched_bins != 0) {
    state.SkipWithError("AddHardCounts differs from the visitor path");
    return;
  }
  std::vector<const PairCost*> pairs;
  std::vector<std::vector<std::size_t>> used;
  for (const auto& pair : problem.pairs) {
    pairs.push_back(pair.get());
    used.push_back(bench::UsedScenes(*pair));
  }
  const bool hard_counts = state.range(3) == 1;
  if (JointHardKernelCost(problem, used) != EvaluateJoint(pairs, problem.T_base_lidar)) {
    state.SkipWithError("AddHardCounts joint cost differs from EvaluateJoint");
    return;
  }
  double sink = 0.0;
  for (auto _ : state) {
    sink += hard_counts ? JointHardKernelCost(problem, used) : EvaluateJoint(pairs, problem.T_base_lidar);
    benchmark::DoNotOptimize(sink);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * problem.swathe_points));
  state.counters["points"] = static_cast<double>(problem.swathe_points);
  state.counters["projected"] = static_cast<double>(problem.projected_points);
  state.counters["scenes"] = problem.used_scenes;
  state.counters["checked_samples"] = static_cast<double>(checked_samples);
  state.counters["mismatched_bins"] = static_cast<double>(mismatched_bins);
  state.SetLabel(hard_counts ? "AddHardCounts" : "visitor (PairCost::Evaluate)");
}

void JointCostArguments(benchmark::internal::Benchmark* b) {
  b->ArgNames({"scenes", "max_scans", "threads", "kernel"});
  for (const int kernel : {0, 1}) {
    for (const int threads : {1, 2}) {
      for (const int scenes : {5, 10, 15, 20, 30, 40}) b->Args({scenes, 0, threads, kernel});
      for (const int max_scans : {8, 16, 32, 48}) b->Args({30, max_scans, threads, kernel});
    }
  }
}
BENCHMARK(BM_JointCost)->Apply(JointCostArguments)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace scenecal

BENCHMARK_MAIN();
