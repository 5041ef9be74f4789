// The `alt` scheme in the calibrate command: threads or MPI ranks.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include <yaml-cpp/yaml.h>

#include "core/calibrate_alternating.hpp"

namespace scenecal::cli {

struct AlternatingArguments {
  std::string backend = "threads";  // threads | mpi
  int alternations = 20;
  int stage_alternations = 0;  // 0: the stages spread over all alternations
  double shrink = 0.5;
  std::string penalty_frame = "lidar";  // PenaltyFrameName
  // Not given: DefaultAlternatingOptions' (the paper's 5 m / 5 rad with the simplex, looser with lbfgs).
  std::optional<double> sigma0_translation_m;
  std::optional<double> sigma0_rotation_rad;
  double stop_translation_m = 2e-4;
  double stop_rotation_deg = 1e-3;
  double camera_sigma_translation_m = 0.0005;
  double camera_sigma_rotation_deg = 0.0115;
};

// MPI state of this process (rank 0 of 1 without MPI).
class ProcessGroup {
 public:
  // Starts MPI when backend == "mpi"; throws when this build has no MPI.
  explicit ProcessGroup(const std::string& backend);
  ~ProcessGroup();
  bool IsRoot() const { return rank_ == 0; }
  int rank() const { return rank_; }
  int size() const { return size_; }
  bool distributed() const { return session_ != nullptr; }
  // Ends every rank with this exit code (MPI_Abort); a no-op without MPI.
  void AbortAll(int exit_code);

 private:
  std::shared_ptr<void> session_;
  int rank_ = 0;
  int size_ = 1;
};

struct AlternatingRun {
  CalibrationOutcome outcome;
  AlternatingResult details;
  AlternatingProblem problem;  // names of the cameras, lidars and pairs of details
  bool wrote_nothing = false;  // a serving MPI rank: it has no result to write
};

// Runs the alternating scheme. On MPI, every rank calls this with the same
// input; rank 0 returns the outcome, the others return wrote_nothing = true.
AlternatingRun RunAlternating(const CalibrationInput& input, const CalibrationOptions& options,
                              const AlternatingArguments& arguments, ProcessGroup& group);

AlternatingOptions MakeAlternatingOptions(const CalibrationOptions& options, const AlternatingArguments& arguments);

// The per-alternation history (the paper's Fig. 4) as YAML for the result file.
YAML::Node HistoryYaml(const AlternatingResult& details, const AlternatingProblem& problem);

}  // namespace scenecal::cli
