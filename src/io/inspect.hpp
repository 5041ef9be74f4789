// What a user wants to know about a dataset before calibrating it, and
// whether it can be calibrated at all (`scenecal inspect`).
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "io/dataset.hpp"

namespace scenecal::io {

struct TimeSpan {
  TimeUs first_us = 0;
  TimeUs last_us = 0;
  double DurationS() const { return 1e-6 * static_cast<double>(last_us - first_us); }
};

struct CameraSummary {
  std::string name;
  std::size_t images = 0;
  std::optional<TimeSpan> span;            // of the image times
  double rate_hz = 0.0;                    // (images - 1) / span; 0 with fewer than 2 images
  std::size_t outside_trajectory = 0;      // images with no pose (outside the trajectory's span)
  std::size_t with_scans_nearby = 0;       // images inside the span with >= 1 scan of any lidar nearby
  // Per lidar (same order as the rig): images with >= 1 scan of that lidar nearby.
  std::vector<std::size_t> with_scans_of_lidar;
};

struct LidarSummary {
  std::string name;
  std::size_t scans = 0;
  std::optional<TimeSpan> span;
  double rate_hz = 0.0;
  std::size_t outside_trajectory = 0;
  bool contents_read = false;  // false with quick: the counts below come from file sizes
  std::size_t points_min = 0, points_median = 0, points_max = 0;  // per scan (finite points)
  std::size_t points_total = 0;
  std::size_t no_returns = 0;  // records skipped for a non-finite value (0 when !contents_read)
};

struct DatasetSummary {
  std::vector<CameraSummary> cameras;  // rig order
  std::vector<LidarSummary> lidars;    // rig order
  std::size_t trajectory_rows = 0;
  TimeSpan trajectory_span;
  double distance_m = 0.0;
  double mean_speed_m_s = 0.0;         // distance / duration; 0 for a single row
  double standing_still_s = 0.0;       // time in trajectory intervals slower than standing_speed_m_s
  bool static_dataset = false;         // one trajectory row
  bool ground_truth = false;
  bool contents_read = false;          // images and scans decoded
  double nearby_distance_m = 10.0;     // "scan near an image": within this travel of it
  bool can_calibrate = false;
  std::vector<std::string> problems;   // why it cannot be calibrated (empty when it can)
  std::vector<std::string> warnings;   // usable, but worth knowing
};

struct SummaryOptions {
  bool read_contents = true;            // decode every image and scan (all errors surface)
  double nearby_distance_m = 10.0;      // a scan counts for an image within this travel (m)
  double standing_speed_m_s = 0.05;     // slower than this counts as standing still
};

// progress(done, total) is called while images and scans are read (may be empty).
// Throws InputError for the first unreadable file.
DatasetSummary SummariseDataset(const Dataset& dataset, const SummaryOptions& options = {},
                                const std::function<void(std::size_t, std::size_t)>& progress = {});

// Human-readable report of the rig and the summary (for stdout).
std::string FormatDatasetSummary(const Dataset& dataset, const DatasetSummary& summary);

}  // namespace scenecal::io
