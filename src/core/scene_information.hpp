// The informative scene choice (SceneChoice::kInformative): from a pool of
// scenes, keep those that together constrain the extrinsic most.
//
// Each scene's information matrix H_s (SceneSwathe::AlignmentInformation, at
// the initial guess) is scaled to the uncertainty's units (1 cm of
// translation counts as 0.1 deg of rotation), and scenes are added greedily,
// each time the one that most lowers trace((sum H_s + ridge)^-1): the A-optimal
// design, i.e. the smallest sum of the predicted variances over the six
// directions, so a scene that only repeats well-constrained directions loses
// to one that constrains the weakest. The pool is spread by distance first, so
// the kept scenes never crowd into one stretch of the drive.
#pragma once

#include <cstddef>
#include <vector>

#include "core/geometry.hpp"

namespace scenecal {

struct InformativeChoiceOptions {
  // Units of the parameter: metres and radians that count alike.
  double unit_translation_m = 0.01;
  double unit_rotation_rad = 0.1 * 3.14159265358979323846 / 180.0;
  // Regularises the first picks (fewer scenes than directions): this fraction
  // of the mean scene's trace, on every direction.
  double ridge_fraction = 1e-3;
  // > 0: the count is chosen by the data (`--scenes auto`): stop adding once
  // the predicted variance is within this factor of the whole pool's (and at
  // least min_count are chosen); `count` is then the most that are kept.
  double max_variance_ratio = 0.0;
  std::size_t min_count = 1;
  // The pool is in drive order (spread by distance): a frame next to a chosen
  // one is taken only once no other frame is left. Neighbouring frames see the
  // same structure, so their information is not independent, and a choice
  // crowded into a few stretches of the drive can lose the basin.
  bool separate_neighbours = true;
};

struct InformativeChoice {
  std::vector<std::size_t> chosen;  // indices into the pool, ascending
  // trace of (information + ridge)^-1 in units^2 with the chosen scenes and with the whole pool.
  double predicted_variance_chosen = 0.0;
  double predicted_variance_pool = 0.0;
};

// information: per pool scene (metres / radians, any fixed axes). Keeps
// min(count, pool) scenes (fewer with max_variance_ratio); scenes with no
// information are chosen last.
InformativeChoice ChooseInformativeScenes(const std::vector<Matrix6d>& information, std::size_t count,
                                          const InformativeChoiceOptions& options = {});

}  // namespace scenecal
