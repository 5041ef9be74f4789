#include "cli/calibrate_alt.hpp"

#include <stdexcept>

#include <spdlog/spdlog.h>

#ifdef SCENECAL_HAVE_MPI
#include "distributed/mpi_backend.hpp"
#endif

namespace scenecal::cli {

ProcessGroup::ProcessGroup(const std::string& backend) {
  if (backend != "mpi") return;
#ifdef SCENECAL_HAVE_MPI
  auto session = std::make_shared<distributed::MpiSession>(nullptr, nullptr);
  rank_ = session->rank();
  size_ = session->size();
  session_ = session;
#else
  throw std::runtime_error("--backend mpi: this build of scenecal has no MPI (install libopenmpi-dev and rebuild)");
#endif
}

ProcessGroup::~ProcessGroup() = default;

void ProcessGroup::AbortAll(int exit_code) {
#ifdef SCENECAL_HAVE_MPI
  if (distributed()) {
    spdlog::default_logger()->flush();
    distributed::AbortAllRanks(exit_code);
  }
#else
  (void)exit_code;
#endif
}

std::optional<CalibrationOutcome> SolveOnGroup(Calibrator& calibrator, ProcessGroup& group) {
  if (!group.distributed()) return calibrator.Solve();
#ifdef SCENECAL_HAVE_MPI
  // Every rank read the same data, so every rank reaches the same verdict;
  // the fingerprints below catch ranks that did not.
  if (calibrator.Status() != CalibrationStatus::kSuccess) return calibrator.Solve();
  std::string why;
  if (!distributed::FingerprintsAgree(calibrator.AlternatingFingerprint(), &why)) {
    throw std::runtime_error("--backend mpi: " + why);
  }
  if (!group.IsRoot()) {
    std::vector<PairObjective> objectives = calibrator.AlternatingObjectives();
    for (std::size_t p = 0; p < objectives.size(); ++p) {
      if (!distributed::OwnsPair(static_cast<int>(p), group.rank(), group.size())) objectives[p] = PairObjective{};
    }
    distributed::ServeLowerLevel(std::move(objectives), calibrator.AlternatingBatchHook({}));
    return std::nullopt;
  }
  spdlog::info("MPI: {} pair(s) over {} rank(s)", calibrator.AlternatingPairs().pairs.size(), group.size());
  CalibrationOutcome outcome =
      calibrator.Solve([](std::vector<PairObjective> objectives, LowerLevelBatchHook before_batch) {
        return std::make_unique<distributed::MpiLowerLevelBackend>(std::move(objectives), std::move(before_batch));
      });
  outcome.result.settings["backend"] = "mpi, " + std::to_string(group.size()) + " ranks";
  return outcome;
#else
  return calibrator.Solve();
#endif
}

}  // namespace scenecal::cli
