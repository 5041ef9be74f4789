// Lower-level problems spread over MPI ranks (the paper's Remark 1).
//
// Every rank builds the same AlternatingProblem and the pair objectives of the
// pairs it owns (pair p is owned by rank p % size). Rank 0 runs
// SolveAlternating with an MpiLowerLevelBackend; the other ranks call
// ServeLowerLevel, which answers batches until rank 0 sends the end. Results are
// bit-identical to the thread backend: each pair is solved by the same
// deterministic code, only elsewhere.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/alternating.hpp"

namespace scenecal::distributed {

// RAII wrapper around MPI_Init_thread / MPI_Finalize.
class MpiSession {
 public:
  MpiSession(int* argc, char*** argv);
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  int rank() const { return rank_; }
  int size() const { return size_; }

 private:
  int rank_ = 0;
  int size_ = 1;
};

// Ends every rank at once (MPI_Abort) after a rank failed on its own, so the
// others never wait forever in a collective.
[[noreturn]] void AbortAllRanks(int exit_code);

// True when the pair is solved on this rank.
bool OwnsPair(int pair, int rank, int size);

// Checks that every rank built the same problem: compares a fingerprint
// (e.g. a hash of pair names, scene and point counts, options) across ranks.
// Returns false on every rank, with *why naming the ranks that differ, when
// they do not all agree. Collective: every rank must call it.
bool FingerprintsAgree(std::uint64_t fingerprint, std::string* why);

// Rank 0's backend: broadcasts each batch, solves its own pairs, gathers the
// rest. `local` holds this rank's objectives indexed by pair (entries of
// pairs owned by other ranks may be empty).
class MpiLowerLevelBackend : public LowerLevelBackend {
 public:
  // before_batch runs on every rank with the whole batch (AlternatingSetup::BatchHook).
  explicit MpiLowerLevelBackend(std::vector<PairObjective> local, LowerLevelBatchHook before_batch = {});
  ~MpiLowerLevelBackend() override;  // tells the serving ranks to finish
  std::vector<LowerLevelOutcome> Solve(const std::vector<LowerLevelTask>& tasks,
                                       const StopRequested& stop_requested) override;
  // Sends the end message now (idempotent; the destructor calls it too).
  void Finish();

 private:
  std::vector<PairObjective> local_;
  LowerLevelBatchHook before_batch_;
  bool finished_ = false;
};

// Ranks other than 0: serve batches until rank 0 finishes. `time_budget_s`
// bounds each batch on this rank too (0 = none).
void ServeLowerLevel(std::vector<PairObjective> local, const LowerLevelBatchHook& before_batch = {});

}  // namespace scenecal::distributed
