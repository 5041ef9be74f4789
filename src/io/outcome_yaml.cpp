#include "io/outcome_yaml.hpp"

#include "core/geometry.hpp"

namespace scenecal::io {

namespace {

YAML::Node TupleYaml(const Eigen::Isometry3d& T) {
  YAML::Node node(YAML::NodeType::Sequence);
  const Vector6d v = TupleFromTransform(T);
  for (int k = 0; k < 6; ++k) node.push_back(v[k]);
  node.SetStyle(YAML::EmitterStyle::Flow);
  return node;
}

}  // namespace

YAML::Node AlternatingHistoryYaml(const AlternatingHistory& history) {
  const AlternatingProblem& problem = history.problem;
  YAML::Node records(YAML::NodeType::Sequence);
  for (const AlternationRecord& record : history.solved.history) {
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
      pair["lower_T_camera_lidar"] = TupleYaml(record.T_camera_lidar_lower[p]);
      pair["upper_T_camera_lidar"] = TupleYaml(record.T_camera_lidar_upper[p]);
      pair["lower_cost"] = record.lower_cost[p];
      pair["evaluations"] = record.lower_evaluations[p];
      // lbfgs: how many of them also computed the gradient (each ~kGradientEvaluationCost plain ones).
      if (p < record.lower_gradient_evaluations.size() && record.lower_gradient_evaluations[p] > 0)
        pair["gradient_evaluations"] = record.lower_gradient_evaluations[p];
      pairs.push_back(pair);
    }
    entry["pairs"] = pairs;
    records.push_back(entry);
  }
  return records;
}

YAML::Node MotionCorrectionYaml(const std::vector<FrameMotionCorrection>& frames) {
  YAML::Node entries(YAML::NodeType::Sequence);
  for (const FrameMotionCorrection& frame : frames) {
    YAML::Node entry;
    entry["camera"] = frame.camera;
    entry["lidar"] = frame.lidar;
    entry["image_t_us"] = frame.image_t_us;
    entry["scale_percent"] = 100.0 * frame.correction.scale;
    entry["turn_a_deg_per_m"] = DegreesFromRadians(frame.correction.turn_a_rad_per_m);
    entry["turn_b_deg_per_m"] = DegreesFromRadians(frame.correction.turn_b_rad_per_m);
    entry["roll_deg_per_m"] = DegreesFromRadians(frame.correction.roll_rad_per_m);
    entries.push_back(entry);
  }
  return entries;
}

}  // namespace scenecal::io
