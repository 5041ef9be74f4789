// Run under mpirun: the MPI backend gives the thread backend's result bit for
// bit, and a mismatch of inputs between ranks is detected on every rank.
#include <cstdio>

#include "core/alternating.hpp"
#include "distributed/mpi_backend.hpp"

using namespace scenecal;

namespace {

const Eigen::Isometry3d kT_base_right = TransformFromTuple((Vector6d() << 0.24, 0, 0, 0, 0, 0).finished());
const Eigen::Isometry3d kT_base_centre = TransformFromTuple((Vector6d() << 0.12, 0, 0, 0, 0, 0).finished());
const Eigen::Isometry3d kRear = TransformFromTuple((Vector6d() << -0.3, 1.2, -4.0, -2.84, 0.06, -0.36).finished());
const Eigen::Isometry3d kFront = TransformFromTuple((Vector6d() << 0.1, 1.3, 0.2, -0.04, -1.45, 0.03).finished());

PairObjective Bowl(const Eigen::Isometry3d& T_min, double scale) {
  PairObjective objective;
  objective.cost = [=](const Eigen::Isometry3d& T) {
    const Vector6d width = (Vector6d() << 0.05, 0.04, 0.06, 0.02, 0.03, 0.02).finished();
    const Vector6d e = LogSE3(T * T_min.inverse()).cwiseQuotient(width);
    return scale * e.squaredNorm() + 0.1 * std::sin(5.0 * e[0]);
  };
  return objective;
}

AlternatingProblem Problem(std::vector<PairObjective>* objectives) {
  AlternatingProblem problem;
  problem.cameras = {{"left", Eigen::Isometry3d::Identity(), std::nullopt},
                     {"centre", kT_base_centre, std::nullopt},
                     {"right", kT_base_right, std::nullopt}};
  problem.lidars = {{"rear", ExpSE3(Vector6d::Constant(0.02)) * kRear}, {"front", ExpSE3(Vector6d::Constant(-0.015)) * kFront}};
  for (int lidar = 0; lidar < 2; ++lidar) {
    for (int camera = 0; camera < 3; ++camera) {
      problem.pairs.push_back({camera, lidar});
      // Slightly inconsistent minima, so the upper level has work to do.
      Eigen::Isometry3d truth = lidar == 0 ? kRear : kFront;
      truth.translation().z() += 0.004 * camera;
      objectives->push_back(Bowl(problem.cameras[static_cast<std::size_t>(camera)].T_camera_base() * truth,
                                 1.0 + 0.5 * camera));
    }
  }
  return problem;
}

}  // namespace

int main(int argc, char** argv) {
  distributed::MpiSession session(&argc, &argv);
  int failures = 0;
  int checks = 0;
  const auto expect = [&](bool ok, const char* what) {
    ++checks;
    if (!ok) {
      ++failures;
      std::fprintf(stderr, "rank %d: FAILED: %s\n", session.rank(), what);
    }
  };

  // Matching inputs agree; one rank with a different fingerprint is found by all.
  std::string why;
  expect(distributed::FingerprintsAgree(42, &why), "equal fingerprints agree");
  const bool agree = distributed::FingerprintsAgree(session.rank() == session.size() - 1 ? 7 : 42, &why);
  expect(session.size() == 1 ? agree : !agree, "a differing rank is detected");
  if (session.size() > 1) expect(why.find(std::to_string(session.size() - 1)) != std::string::npos, "the message names the rank");

  std::vector<PairObjective> objectives;
  const AlternatingProblem problem = Problem(&objectives);
  // Both lower solvers (L-BFGS with central-difference gradients: the bowls have no analytic one).
  for (const LowerSolver solver : {LowerSolver::kSimplex, LowerSolver::kLbfgs}) {
    AlternatingOptions options;
    options.max_alternations = 8;
    options.lower_solver = solver;
    if (session.rank() != 0) {
      // Serving ranks only hold the objectives they own.
      std::vector<PairObjective> owned(objectives.size());
      for (std::size_t p = 0; p < objectives.size(); ++p) {
        if (distributed::OwnsPair(static_cast<int>(p), session.rank(), session.size())) owned[p] = objectives[p];
      }
      distributed::ServeLowerLevel(owned);
      continue;
    }
    AlternatingResult distributed_result;
    {
      distributed::MpiLowerLevelBackend backend(objectives);
      distributed_result = SolveAlternating(problem, options, backend);
    }
    ThreadLowerLevelBackend threads(objectives);
    const AlternatingResult thread_result = SolveAlternating(problem, options, threads);
    std::printf("%s: %d alternations, %d evaluations (%d with gradient)\n", LowerSolverName(solver),
                thread_result.alternations, thread_result.total_evaluations, thread_result.total_gradient_evaluations);
    expect(distributed_result.success && thread_result.success, "both runs succeed");
    expect(distributed_result.alternations == thread_result.alternations, "same number of alternations");
    expect(distributed_result.total_evaluations == thread_result.total_evaluations, "same number of evaluations");
    expect(distributed_result.total_gradient_evaluations == thread_result.total_gradient_evaluations,
           "same number of gradient evaluations");
    expect((solver == LowerSolver::kLbfgs) == (thread_result.total_gradient_evaluations > 0),
           "gradient evaluations exactly with lbfgs");
    for (std::size_t l = 0; l < 2; ++l) {
      expect((distributed_result.T_base_lidar[l].matrix() - thread_result.T_base_lidar[l].matrix()).cwiseAbs().maxCoeff() == 0.0,
             "bit-identical T_base_lidar");
    }
    for (std::size_t p = 0; p < thread_result.T_camera_lidar_lower.size(); ++p) {
      expect((distributed_result.T_camera_lidar_lower[p].matrix() - thread_result.T_camera_lidar_lower[p].matrix())
                     .cwiseAbs()
                     .maxCoeff() == 0.0,
             "bit-identical lower solutions");
    }
  }
  std::printf("rank %d of %d: %d passed, %d failed\n", session.rank(), session.size(), checks - failures, failures);
  return failures == 0 ? 0 : 1;
}
