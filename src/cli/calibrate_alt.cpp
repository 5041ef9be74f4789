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

AlternatingOptions MakeAlternatingOptions(const CalibrationOptions& options, const AlternatingArguments& arguments) {
  AlternatingOptions alternating =
      DefaultAlternatingOptions(options, arguments.alternations, arguments.stage_alternations);
  alternating.covariance_shrink = arguments.shrink;
  ParsePenaltyFrame(arguments.penalty_frame, &alternating.penalty_frame);  // the CLI checked the name
  if (arguments.sigma0_translation_m) alternating.initial_sigma_translation_m = *arguments.sigma0_translation_m;
  if (arguments.sigma0_rotation_rad) alternating.initial_sigma_rotation_rad = *arguments.sigma0_rotation_rad;
  alternating.stop_translation_m = arguments.stop_translation_m;
  alternating.stop_rotation_rad = RadiansFromDegrees(arguments.stop_rotation_deg);
  alternating.default_camera_sigma_translation_m = arguments.camera_sigma_translation_m;
  alternating.default_camera_sigma_rotation_rad = RadiansFromDegrees(arguments.camera_sigma_rotation_deg);
  return alternating;
}

AlternatingRun RunAlternating(const CalibrationInput& input, const CalibrationOptions& options,
                              const AlternatingArguments& arguments, ProcessGroup& group) {
  AlternatingRun run;
  const AlternatingOptions alternating = MakeAlternatingOptions(options, arguments);
  if (!group.distributed()) {
    run.outcome = CalibrateAlternating(input, options, alternating,
                                       [](const std::string& message) { spdlog::info("{}", message); }, &run.details,
                                       &run.problem);
    return run;
  }
#ifdef SCENECAL_HAVE_MPI
  std::string why;
  if (!options.IsValid(&why) || !alternating.IsValid(&why)) {
    run.outcome.status = CalibrationStatus::kInvalidOptions;
    run.outcome.why = "invalid options: " + why;
    return run;
  }
  AlternatingSetup setup;
  const CalibrationStatus status = BuildAlternatingSetup(input, options, &setup, &why);
  // Every rank reads the same data, so every rank reaches the same verdict;
  // the fingerprints below catch ranks that did not.
  if (status != CalibrationStatus::kSuccess) {
    run.outcome.status = status;
    run.outcome.why = why;
    return run;
  }
  if (!distributed::FingerprintsAgree(setup.Fingerprint(options, alternating), &why)) {
    throw std::runtime_error("--backend mpi: " + why);
  }
  std::vector<PairObjective> objectives = setup.Objectives(options, alternating);
  if (!group.IsRoot()) {
    for (std::size_t p = 0; p < objectives.size(); ++p) {
      if (!distributed::OwnsPair(static_cast<int>(p), group.rank(), group.size())) objectives[p] = PairObjective{};
    }
    distributed::ServeLowerLevel(std::move(objectives), setup.BatchHook(options, alternating, {}));
    run.wrote_nothing = true;
    return run;
  }
  spdlog::info("MPI: {} pair(s) over {} rank(s)", objectives.size(), group.size());
  {
    distributed::MpiLowerLevelBackend backend(
        std::move(objectives),
        setup.BatchHook(options, alternating, [](const std::string& message) { spdlog::info("{}", message); }));
    run.details = SolveAlternating(setup.problem, alternating, backend, [&](const AlternationRecord& record) {
      spdlog::info("{}", DescribeAlternation(record, setup.problem));
    });
  }
  run.outcome = FinishAlternating(setup, run.details, input, options, alternating);
  run.problem = setup.problem;
  run.outcome.result.settings["backend"] = "mpi, " + std::to_string(group.size()) + " ranks";
#endif
  return run;
}

YAML::Node HistoryYaml(const AlternatingResult& details, const AlternatingProblem& problem) {
  YAML::Node history(YAML::NodeType::Sequence);
  const auto tuple = [](const Eigen::Isometry3d& T) {
    YAML::Node node(YAML::NodeType::Sequence);
    const Vector6d v = TupleFromTransform(T);
    for (int k = 0; k < 6; ++k) node.push_back(v[k]);
    node.SetStyle(YAML::EmitterStyle::Flow);
    return node;
  };
  for (const AlternationRecord& record : details.history) {
    YAML::Node entry;
    entry["alternation"] = record.alternation + 1;
    entry["penalty_sigma_m"] = record.sigma_translation_m;
    entry["penalty_sigma_rad"] = record.sigma_rotation_rad;
    entry["elapsed_s"] = record.elapsed_s;
    entry["max_change_m"] = record.max_change_translation_m;
    entry["max_change_rad"] = record.max_change_rotation_rad;
    entry["levels_apart_m"] = record.max_disagreement_translation_m;
    entry["levels_apart_rad"] = record.max_disagreement_rotation_rad;
    YAML::Node pairs(YAML::NodeType::Sequence);
    for (std::size_t p = 0; p < problem.pairs.size() && p < record.lower_cost.size(); ++p) {
      YAML::Node pair;
      pair["camera"] = problem.cameras[static_cast<std::size_t>(problem.pairs[p].camera)].name;
      pair["lidar"] = problem.lidars[static_cast<std::size_t>(problem.pairs[p].lidar)].name;
      pair["lower_T_camera_lidar"] = tuple(record.T_camera_lidar_lower[p]);
      pair["upper_T_camera_lidar"] = tuple(record.T_camera_lidar_upper[p]);
      pair["lower_cost"] = record.lower_cost[p];
      pair["evaluations"] = record.lower_evaluations[p];
      // lbfgs: how many of them also computed the gradient (each ~kGradientEvaluationCost plain ones).
      if (p < record.lower_gradient_evaluations.size() && record.lower_gradient_evaluations[p] > 0)
        pair["gradient_evaluations"] = record.lower_gradient_evaluations[p];
      pairs.push_back(pair);
    }
    entry["pairs"] = pairs;
    history.push_back(entry);
  }
  return history;
}

}  // namespace scenecal::cli
