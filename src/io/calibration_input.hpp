// The calibration input of a dataset: the scenes selected from the file
// timestamps (core/scenes.hpp) and only the images and scans they use, read
// in parallel.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>

#include "core/calibrate.hpp"
#include "io/dataset.hpp"

namespace scenecal::io {

// Valid data that cannot be calibrated (e.g. a lidar without scenes); the
// message names the selection step that removed its frames.
class CannotCalibrate : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct LoadedScenes {
  std::size_t images = 0;        // images read
  std::size_t scans = 0;         // scans read
  std::size_t lidar_points = 0;  // points in the scans read
};

// Fills input->selection (SelectScenes on the dataset's rig, trajectory and
// file times with `scene_options`; its Report() says what was selected and
// why), input->images and input->scans. input->rig is left as the caller set
// it. Images are read as `channel` (ReadImage). Throws InputError for
// unreadable files and CannotCalibrate for a lidar without scenes.
LoadedScenes LoadCalibrationInput(const Dataset& dataset, const SceneOptions& scene_options, CalibrationInput* input,
                                  ImageChannel channel = ImageChannel::kGrey);

}  // namespace scenecal::io
