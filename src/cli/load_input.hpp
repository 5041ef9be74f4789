// Scene selection and loading shared by `calibrate` and `experiment`: selects
// the scenes from the file timestamps and reads only the images and scans they
// use, in parallel. Also the exact-magnitude perturbation of an initial guess
// used by robustness studies.
#pragma once

#include <cstddef>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/calibrate.hpp"
#include "io/calibration_input.hpp"
#include "io/dataset.hpp"

namespace scenecal::cli {

using io::LoadedScenes;

// io::LoadCalibrationInput, logging the selection report and the counts
// with spdlog.
LoadedScenes SelectAndLoadScenes(const io::Dataset& dataset, const SceneOptions& scene_options,
                                 CalibrationInput* input, io::ImageChannel channel = io::ImageChannel::kGrey);

// A single-frame dataset of 3D lidars: a one-row (static) trajectory, so every
// scene is one image and one sweep taken at the same time (e.g. `import
// opencalib`), and every lidar is 3d. Such a scene projects ~10^4 points.
bool IsSingleFrame3d(const io::Dataset& dataset);

// Settings chosen automatically for single-frame 3D-lidar data, for the options
// the user did not set (bins_given: --bins was on the command line): 8 histogram
// bins per variable instead of 32, since one sweep gives ~10^4 samples for the
// joint histogram (~10 a bin at 32x32: a noisy NID with false minima; measured
// on the OpenCalib frames in BENCHMARK.md). Returns what was changed, for the
// log and the result's settings ("" when nothing was, or the data is not
// single-frame 3D).
std::string ApplySingleFrameDefaults(const io::Dataset& dataset, bool bins_given, CalibrationOptions* options);
constexpr int kSingleFrameBins = 8;

// Moves T by exactly translation_m (metres, base frame) and rotation_deg
// (degrees, about an axis through T's origin, left-multiplied) in random
// directions drawn from rng.
Eigen::Isometry3d PerturbExactly(const Eigen::Isometry3d& T, double translation_m, double rotation_deg,
                                 std::mt19937_64& rng);

// "SCALE[:BLUR[:RESTARTS]],..." -> coarse-to-fine stages (calibrate's --stages);
// false when malformed.
bool ParseStageSchedule(const std::string& text, std::vector<OptimisationStage>* stages);
// The inverse: "1:0.004:2,0.3:0.0015:1,0.1:0:1" for DefaultStages().
std::string StageScheduleText(const std::vector<OptimisationStage>& stages);

}  // namespace scenecal::cli
