#include "cli/uncertainty_report.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/basin_check.hpp"
#include "core/uncertainty.hpp"

namespace scenecal::cli {
namespace {

YAML::Node Numbers(const double* values, int count) {
  YAML::Node node(YAML::NodeType::Sequence);
  node.SetStyle(YAML::EmitterStyle::Flow);
  for (int i = 0; i < count; ++i) node.push_back(values[i]);
  return node;
}

}  // namespace

YAML::Node ReportUncertainty(Calibrator& calibrator, const std::vector<LidarBasinCheck>& basin_checks,
                             CalibrationResult* result, std::vector<LidarUncertainty>* estimates_out) {
  const auto start = std::chrono::steady_clock::now();
  const UncertaintyOptions uncertainty_options;
  spdlog::info("estimating the uncertainty of the result (B-spline metric; paired scene-by-scene cost changes along "
               "the Hessian's directions, up to {:.0f} cm / {:.1f} deg)",
               100.0 * uncertainty_options.max_search_units * uncertainty_options.unit_translation_m,
               uncertainty_options.max_search_units * uncertainty_options.unit_rotation_rad * 180.0 / M_PI);
  *estimates_out = calibrator.EstimateUncertainty(*result, uncertainty_options, basin_checks);
  const std::vector<LidarUncertainty>& estimates = *estimates_out;
  YAML::Node node(YAML::NodeType::Map);
  const double deg = 180.0 / M_PI;
  for (std::size_t i = 0; i < estimates.size(); ++i) {
    const LidarUncertainty& estimate = estimates[i];
    LidarCalibration& lidar = result->lidars[i];
    YAML::Node entry(YAML::NodeType::Map);
    entry["method"] = "paired scene cost changes (B-spline metric) along the Hessian's eigenvectors; directions d = "
                      "[rho (m), phi (rad)] along base axes, rotation about the lidar origin";
    entry["scenes"] = estimate.units;
    entry["estimated"] = estimate.estimated;
    entry["determined"] = estimate.determined;
    if (!estimate.why.empty()) entry["why"] = estimate.why;
    if (!estimate.estimated) {
      spdlog::warn("lidar {}: no uncertainty estimate: {}", lidar.lidar, estimate.why);
      node[lidar.lidar] = entry;
      continue;
    }
    YAML::Node directions(YAML::NodeType::Sequence);
    std::string open;
    for (const UncertainDirection& direction : estimate.directions) {
      YAML::Node item(YAML::NodeType::Map);
      item["direction_per_unit"] = Numbers(direction.direction.data(), 6);
      item["curvature_per_unit2"] = direction.curvature;
      item["determined"] = direction.determined;
      if (direction.determined) {
        item["sigma_units"] = direction.sigma_units;
      } else {
        item["flat_within_units"] = direction.flat_units;
        open += fmt::format("{}[{}] flat within +-{:.1f} of these steps", open.empty() ? "" : "; ",
                            DescribeLocalUpdate(direction.direction), direction.flat_units);
      }
      directions.push_back(item);
    }
    entry["directions"] = directions;
    entry["evaluations"] = estimate.evaluations;
    if (estimate.determined) {
      // Not FORMAT.md's `sigma`: this is the spread within the basin the
      // optimiser ended in; ReportErrorEstimate adds what it misses.
      entry["local_sigma_tuple"] = Numbers(estimate.sigma_tuple.data(), 6);
      entry["local_covariance_d"] = Numbers(estimate.covariance.data(), 36);  // symmetric
      const UncertainDirection& weakest = *std::max_element(
          estimate.directions.begin(), estimate.directions.end(),
          [](const UncertainDirection& a, const UncertainDirection& b) { return a.sigma_units < b.sigma_units; });
      const Vector6d& s = estimate.sigma_tuple;
      spdlog::info("lidar {}: local 1-sigma x {:.2f} y {:.2f} z {:.2f} cm, roll {:.3f} pitch {:.3f} yaw {:.3f} deg "
                   "(from {} scenes; weakest direction, 1 sigma: {}). Local: the spread within the basin the "
                   "optimiser ended in; the sigma of the result adds the basin check's restarts",
                   lidar.lidar, 100 * s[0], 100 * s[1], 100 * s[2], deg * s[3], deg * s[4], deg * s[5], estimate.units,
                   DescribeLocalUpdate(weakest.direction * weakest.sigma_units));
    } else {
      result->warnings.push_back(fmt::format(
          "lidar {}: the data do not determine its extrinsic along {} of 6 directions ({} scenes): {}. The result "
          "along them depends on the initial guess and the optimiser's path; add scenes with structure off the "
          "ground (parked cars, kerbs, walls), a longer swathe (--swathe-length) or another camera",
          lidar.lidar, std::count_if(estimate.directions.begin(), estimate.directions.end(),
                                     [](const UncertainDirection& d) { return !d.determined; }),
          estimate.units, open));
    }
    node[lidar.lidar] = entry;
  }
  result->timings_s["uncertainty"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return node;
}

YAML::Node ReportBasinCheck(Calibrator& calibrator, double offset_deg, bool adopt, double scale_sigma,
                            bool without_drift_model, CalibrationResult* result,
                            std::vector<LidarBasinCheck>* checks_out) {
  const auto start = std::chrono::steady_clock::now();
  BasinCheckOptions check_options;
  check_options.offset_rad = RadiansFromDegrees(offset_deg);
  check_options.scale_sigma = scale_sigma;
  check_options.without_drift_model = without_drift_model;
  spdlog::info("basin check: minimising the joint cost again from the answer turned +-{} deg about each base axis "
               "(6 runs per lidar{}{}; --no-basin-check skips it)",
               offset_deg,
               scale_sigma > 0.0 ? fmt::format(", once from the answer with the trajectory's distances {:.2f} % "
                                               "longer",
                                               100.0 * scale_sigma)
                                 : "",
               without_drift_model ? ", once from the answer with the drift corrections removed" : "");
  *checks_out = calibrator.CheckBasins(*result, check_options);
  if (adopt) calibrator.AdoptBetterRestarts(check_options, result, checks_out);
  const std::vector<LidarBasinCheck>& checks = *checks_out;
  const double deg = 180.0 / M_PI;
  YAML::Node node(YAML::NodeType::Map);
  for (const LidarBasinCheck& check : checks) {
    YAML::Node entry(YAML::NodeType::Map);
    entry["method"] = fmt::format(
        "joint cost minimised again (the last {} stage(s) of the schedule, each run once, L-BFGS to the middle "
        "stages' function tolerance; when the same run from the answer itself stays within {} of the agreement "
        "bounds, a restart stops once back within {} of them) from the calibration's answer turned "
        "+-{} deg about each base axis through the lidar origin; agree = every end within {} cm and {} deg of the "
        "answer; costs with sharp images and visibility at the calibration's answer; a restart that ends apart at a "
        "lower cost (by more than {} standard errors of the drop over the scenes) becomes the answer{}",
        check_options.last_stages, check_options.at_rest_fraction, check_options.came_back_fraction, offset_deg,
        100.0 * check_options.agree_translation_m, check_options.agree_rotation_rad * deg,
        check_options.adopt_min_standard_errors,
        adopt ? "" : " (not in this run: --keep-calibration-answer)");
    entry["checked"] = check.checked;
    if (!check.checked) {
      entry["why"] = check.why;
      spdlog::warn("lidar {}: no basin check: {}", check.lidar, check.why);
      node[check.lidar] = entry;
      continue;
    }
    entry["agree"] = check.agree;
    entry["cost_answer"] = check.cost_answer;
    entry["max_translation_apart_m"] = check.max_translation_apart_m;
    entry["max_rotation_apart_deg"] = check.max_rotation_apart_rad * deg;
    const auto start_text = [&](const BasinRestart& restart) {
      return fmt::format("{:+g} deg about base {}", restart.sign * offset_deg, "xyz"[restart.axis]);
    };
    if (check.adopted_restart >= 0) {
      const BasinRestart& adopted = check.restarts[static_cast<std::size_t>(check.adopted_restart)];
      YAML::Node calibrated(YAML::NodeType::Map);
      const Vector6d tuple = TupleFromTransform(check.T_base_lidar_calibrated);
      calibrated["T_base_lidar"] = Numbers(tuple.data(), 6);
      calibrated["cost"] = check.cost_calibrated;
      calibrated["translation_apart_m"] = check.calibrated_translation_apart_m;
      calibrated["rotation_apart_deg"] = check.calibrated_rotation_apart_rad * deg;
      entry["adopted"] = start_text(adopted);
      entry["calibration_answer"] = calibrated;
      result->warnings.push_back(fmt::format(
          "lidar {}: basin check: the restart from the answer turned {} ended {:.2f} cm and {:.3f} deg from where the "
          "calibration stopped, at a lower cost ({:.6f} against {:.6f}, {:.1f} standard errors of the drop over the "
          "scenes): the solver had stopped short of the cost's minimum, so that end is the result (on two simulated "
          "spin3d drives such ends were 1.5-2.0 cm from the truth, the calibration's answers 6.1-8.0 cm; "
          "docs/findings.md, \"A spinning lidar's forward translation bias\"). The calibration's own answer is "
          "basin_check.{}.calibration_answer; --keep-calibration-answer keeps it",
          check.lidar, start_text(adopted), 100.0 * check.calibrated_translation_apart_m,
          check.calibrated_rotation_apart_rad * deg, check.cost_answer, check.cost_calibrated,
          (check.cost_calibrated - check.cost_answer) / adopted.cost_drop_standard_error, check.lidar));
    }
    YAML::Node restarts(YAML::NodeType::Sequence);
    for (const BasinRestart& restart : check.restarts) {
      YAML::Node item(YAML::NodeType::Map);
      item["start"] = start_text(restart);
      item["translation_apart_m"] = restart.translation_apart_m;
      item["rotation_apart_deg"] = restart.rotation_apart_rad * deg;
      item["cost"] = restart.cost_end;
      item["cost_drop_standard_error"] = restart.cost_drop_standard_error;
      item["evaluations"] = restart.evaluations;
      // Stopped once back near the answer: in the sigma it counts as the answer.
      item["came_back"] = restart.came_back;
      const Vector6d end = TupleFromTransform(restart.T_base_lidar_end);
      item["T_base_lidar"] = Numbers(end.data(), 6);
      restarts.push_back(item);
    }
    entry["restarts"] = restarts;
    entry["evaluations"] = check.evaluations;
    // Whether the run from the answer itself stayed (then restarts stopped once back near it), and its cost.
    entry["answer_at_rest"] = check.answer_at_rest;
    entry["answer_rest_evaluations"] = check.answer_rest_evaluations;
    if (check.scale_measured) {
      // The run with the trajectory's distances longer by its 1-sigma scale error: where the answer went.
      YAML::Node scale(YAML::NodeType::Map);
      scale["scale_sigma_percent"] = 100.0 * check.scale_sigma;
      const Vector6d end = TupleFromTransform(check.T_base_lidar_scale_moved);
      scale["T_base_lidar"] = Numbers(end.data(), 6);
      scale["move"] = DescribeDirectionInWords(check.scale_move_d) + " (" + DescribeLocalUpdate(check.scale_move_d) + ")";
      scale["evaluations"] = check.scale_evaluations;
      entry["scale_run"] = scale;
    }
    if (check.drift_model_measured) {
      // The run with the drift corrections removed: the answer without the drift model, and how far the model moves it.
      YAML::Node run(YAML::NodeType::Map);
      const Vector6d end = TupleFromTransform(check.T_base_lidar_without_drift_model);
      run["T_base_lidar"] = Numbers(end.data(), 6);
      run["move"] = DescribeDirectionInWords(check.drift_model_move_d) + " (" +
                    DescribeLocalUpdate(check.drift_model_move_d) + ")";
      run["evaluations"] = check.drift_model_evaluations;
      entry["without_drift_model_run"] = run;
    }
    entry["seconds"] = check.seconds;
    node[check.lidar] = entry;
    if (check.agree) {
      spdlog::info("lidar {}: basin check passed: the 6 restarts{} ended within {:.2f} cm and {:.3f} deg of the answer",
                   check.lidar, check.adopted_restart >= 0 ? " and the calibration's own answer" : "",
                   100.0 * check.max_translation_apart_m, check.max_rotation_apart_rad * deg);
      continue;
    }
    std::string where;
    const int better = check.adopted_restart >= 0 ? -1 : BetterRestart(check, check_options);
    if (better >= 0) {
      // A clearly lower end that was not taken (--keep-calibration-answer, or alt with uncertain camera transforms).
      const BasinRestart* lowest = &check.restarts[static_cast<std::size_t>(better)];
      where = fmt::format(
          "; the start turned {} ended at a lower cost ({:.6f} against {:.6f}): the answer is not the cost's "
          "minimum, and that end (the result's basin_check.{}.restarts, T_base_lidar) is likely the better answer "
          "(on two simulated spin3d drives the lowest-cost end was 1.5-2.0 cm from the truth, the answer 6.1-8.0 cm; "
          "docs/findings.md, \"A spinning lidar's forward translation bias\"); to continue from it, set it as the "
          "lidar's T_base_lidar in rig.yaml and calibrate again",
          start_text(*lowest), lowest->cost_end, check.cost_answer, check.lidar);
    }
    const LidarInfo* lidar = calibrator.Input().rig.FindLidar(check.lidar);
    const bool push_broom = lidar != nullptr && lidar->kind == LidarKind::k2d;
    const bool setting_used = result->settings.count("setting") != 0;
    const std::string advice =
        push_broom && !setting_used
            ? "; for a push-broom lidar try --setting push-broom (good odometry) or push-broom-drifting (visual "
              "odometry), and check the odometry: its drift over the swathe biases the tilt"
        : push_broom ? "; check the odometry: its drift over the swathe biases the tilt"
                     : "";
    result->warnings.push_back(fmt::format(
        "lidar {}: basin check: restarts from the answer turned +-{} deg about each base axis{} ended up to {:.2f} cm "
        "and {:.3f} deg from the answer{}. The data do not pin the extrinsic down better than that, whatever the "
        "local sigma says; the result along that direction depends on the initial guess. Add scenes with structure "
        "off the ground or a longer drive (--scenes){}",
        check.lidar, offset_deg, check.adopted_restart >= 0 ? " (and the calibration's own answer)" : "",
        100.0 * check.max_translation_apart_m, check.max_rotation_apart_rad * deg, where, advice));
  }
  result->timings_s["basin_check"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return node;
}

void ReportErrorEstimate(const std::vector<LidarUncertainty>& estimates, const std::vector<LidarBasinCheck>& checks,
                         const OtherAnswers& other_answers, bool trajectory_drifts, CalibrationResult* result,
                         YAML::Node* uncertainty, LidarVerdicts* verdicts) {
  const UncertaintyOptions units;
  const ErrorEstimateOptions error_options;
  const double deg = 180.0 / M_PI;
  for (std::size_t i = 0; i < estimates.size() && i < result->lidars.size(); ++i) {
    LidarCalibration& lidar = result->lidars[i];
    const LidarBasinCheck* check = nullptr;
    for (const LidarBasinCheck& candidate : checks) {
      if (candidate.lidar == lidar.lidar) check = &candidate;
    }
    std::vector<Eigen::Isometry3d> others;
    std::string others_are = other_answers.are;
    if (const auto other = other_answers.by_lidar.find(lidar.lidar); other != other_answers.by_lidar.end()) {
      others.push_back(other->second);
    } else if (check != nullptr && check->drift_model_measured) {
      // The basin check's run without the drift corrections, carried to a restart's end if one became the answer.
      others.push_back(ApplyTransformUpdate(lidar.T_base_lidar, check->drift_model_move_d,
                                            TransformUpdate::kAboutSourcePoint));
      others_are = fmt::format("the answer with the drift corrections removed (basin_check.{}.without_drift_model_run)",
                               lidar.lidar);
    }
    const LidarErrorEstimate estimate =
        EstimateLidarError(lidar.T_base_lidar, estimates[i], check, others, trajectory_drifts, units, error_options);
    YAML::Node entry = (*uncertainty)[lidar.lidar];
    // In the result and the report, and for any but `good` a warning.
    const auto record_verdict = [&](Verdict verdict, const std::string& reason) {
      entry["verdict"] = VerdictName(verdict);
      if (!reason.empty()) entry["verdict_reason"] = reason;
      (*verdicts)[lidar.lidar] = {VerdictName(verdict), reason};
      if (verdict != Verdict::kGood) {
        result->warnings.push_back(
            fmt::format("lidar {}: the result is {}: {}", lidar.lidar, VerdictName(verdict), reason));
      }
    };
    if (!estimate.estimated) {
      // No sigma at all (too few image times, or none used): the data give no word on how far the answer can
      // be trusted, and a few views leave directions they do not constrain. Not `good` by default.
      spdlog::info("lidar {}: verdict: unreliable", lidar.lidar);
      record_verdict(Verdict::kUnreliable,
                     fmt::format("no sigma could be estimated ({}); record more camera frames, or check the answer "
                                 "against the report's overlays and cost slices",
                                 estimates[i].why));
      continue;
    }
    lidar.sigma = estimate.sigma_tuple;
    lidar.covariance = estimate.covariance_tuple;
    entry["sigma_method"] = fmt::format(
        "covariance of the error = local (flat directions: half the flat range) + the basin check's restarts' "
        "second moment about the answer (a restart that came back counting as the answer){}{} + a floor of {} px "
        "RMS misalignment of the image edges (shared by every scene){}; shares of its trace: local {:.2f}, "
        "basin {:.2f}, other model {:.2f}, floor {:.2f}, scale {:.2f}",
        check != nullptr && check->checked ? "" : " (no basin check ran)",
        others.empty() ? "" : " + the offset of " + others_are, error_options.alignment_floor_px,
        check != nullptr && check->scale_measured
            ? fmt::format(" + the answer's move under a {:.2f} % scale error of the trajectory (basin_check.{}."
                          "scale_run)",
                          100.0 * check->scale_sigma, lidar.lidar)
            : "",
        estimate.share_local, estimate.share_basin, estimate.share_other_model, estimate.share_floor,
        estimate.share_scale);
    if (!estimate.one_pixel_covariance_tuple.isZero()) {
      // [x y z roll pitch yaw] (m, rad) per 1 px RMS misalignment of the edges: an error's size in pixels.
      entry["edge_pixel_covariance"] = Numbers(estimate.one_pixel_covariance_tuple.data(), 36);  // symmetric
    }
    if (estimate.sigma_px > 0.0) entry["sigma_px"] = estimate.sigma_px;
    if (!others.empty()) {
      // [x y z roll pitch yaw] (m, rad), as T_base_lidar: where the other model ended.
      const Vector6d other_tuple = TupleFromTransform(others.front());
      entry["other_model_answer"] = Numbers(other_tuple.data(), 6);
      entry["other_model_answer_is"] = others_are;
    }
    record_verdict(estimate.verdict, estimate.verdict_reason);
    entry["weakest_direction_1sigma_d"] = Numbers(estimate.weakest_direction.data(), 6);
    entry["weakest_direction"] = DescribeDirectionInWords(estimate.weakest_direction);
    const Vector6d& s = estimate.sigma_tuple;
    spdlog::info("lidar {}: 1-sigma of the result x {:.2f} y {:.2f} z {:.2f} cm, roll {:.3f} pitch {:.3f} yaw {:.3f} "
                 "deg (the image edges misaligned by {:.2f} px RMS); largest along {} ({}); verdict: {}",
                 lidar.lidar, 100 * s[0], 100 * s[1], 100 * s[2], deg * s[3], deg * s[4], deg * s[5],
                 estimate.sigma_px, DescribeDirectionInWords(estimate.weakest_direction),
                 DescribeLocalUpdate(estimate.weakest_direction), VerdictName(estimate.verdict));
  }
}

}  // namespace scenecal::cli
