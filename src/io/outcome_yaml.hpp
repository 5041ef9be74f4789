// The typed parts of a calibration outcome as YAML for the result file's
// extra keys (FORMAT.md allows keys beyond its own): alt's per-alternation
// history and the frames' drift corrections.
#pragma once

#include <vector>

#include <yaml-cpp/yaml.h>

#include "core/calibrate.hpp"

namespace scenecal::io {

// `history`: per alternation, the penalty, the moves, the levels' gap and per
// pair the lower and upper T_camera_lidar ([x y z roll pitch yaw]), its cost
// and evaluations (the paper's Fig. 4 and 6).
YAML::Node AlternatingHistoryYaml(const AlternatingHistory& history);

// `motion_correction`: per pair and camera frame, the drift correction
// (scale in %, rates in deg/m).
YAML::Node MotionCorrectionYaml(const std::vector<FrameMotionCorrection>& frames);

}  // namespace scenecal::io
