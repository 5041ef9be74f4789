// The hard NID cost of a PairCost computed with SceneSwathe::AddHardCounts
// (vectorised sampling and binning) instead of the ForEachProjected visitor of
// PairCost::SceneCost: per used scene an integer table, JointHistogram::AddCounts,
// CostValue; scenes in parallel, summed in scene order. The same value as
// PairCost::Evaluate (the benchmarks check it bit for bit before timing).
#pragma once

#include <cstdint>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/pair_cost.hpp"

namespace scenecal::bench {

inline std::vector<std::size_t> UsedScenes(const PairCost& cost) {
  std::vector<std::size_t> used;
  for (std::size_t s = 0; s < cost.States().size(); ++s) {
    if (cost.States()[s] == SceneState::kUsed) used.push_back(s);
  }
  return used;
}

inline double HardKernelCost(const PairCost& cost, const std::vector<std::size_t>& used,
                             const Eigen::Isometry3d& T_camera_lidar) {
  std::vector<double> scene_costs(used.size(), 0.0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, used.size(), 1),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t i = range.begin(); i != range.end(); ++i) {
                        JointHistogram histogram(cost.Options().histogram);
                        const int nx = histogram.ReflectanceBins(), ny = histogram.IntensityBins();
                        thread_local std::vector<std::uint32_t> counts;
                        counts.assign(static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny), 0u);
                        const std::size_t samples =
                            cost.Scenes()[used[i]].AddHardCounts(T_camera_lidar, nx, ny, counts.data());
                        histogram.AddCounts(counts.data(), samples);
                        scene_costs[i] = CostValue(ComputeInformation(histogram), cost.Options().metric);
                      }
                    });
  double sum = 0.0;
  for (const double c : scene_costs) sum += c;
  return sum / static_cast<double>(used.size());
}

}  // namespace scenecal::bench
