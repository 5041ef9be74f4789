// The process group of `calibrate` (one process, or the ranks of mpirun for
// --backend mpi) and the solve on it: the alt scheme's lower levels on the
// ranks, through the Calibrator's backend (core/calibrator.hpp).
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "core/calibrator.hpp"

namespace scenecal::cli {

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

// Solves on the group: on this process, or with MPI (every rank built the same
// calibrator) rank 0 solves with the lower levels spread over the ranks while
// the others serve their pairs and return nothing.
std::optional<CalibrationOutcome> SolveOnGroup(Calibrator& calibrator, ProcessGroup& group);

}  // namespace scenecal::cli
