// Writes a sample calibration report and a sample experiment report from
// synthetic but plausible data (a converging alternation history, cost slices
// of a smooth bowl with one weak direction, overlays of a synthetic street),
// for the headless-browser check (tests/report_browser_check.sh) and for a
// person to look at.
//
// Usage: report_sample OUT_DIR   -> OUT_DIR/calibration/report.html (+ PNGs),
//                                   OUT_DIR/experiment/report.html
#include <cmath>
#include <cstdio>
#include <exception>
#include <random>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "core/alternating.hpp"
#include "core/camera.hpp"
#include "core/geometry.hpp"
#include "report/cost_slices.hpp"
#include "report/html_report.hpp"
#include "report/overlay.hpp"

namespace {

using namespace scenecal;

Vector6d Tuple(double x, double y, double z, double roll_deg, double pitch_deg, double yaw_deg) {
  Vector6d t;
  t << x, y, z, RadiansFromDegrees(roll_deg), RadiansFromDegrees(pitch_deg), RadiansFromDegrees(yaw_deg);
  return t;
}

// A street seen from a forward camera: sky gradient, building blocks, road with lane marks.
cv::Mat StreetImage(int width, int height) {
  cv::Mat image(height, width, CV_32FC1);
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u) {
      const double horizon = 0.42 * height;
      double value = v < horizon ? 0.75 + 0.2 * v / horizon : 0.35 + 0.1 * std::sin(u * 0.05) * std::cos(v * 0.07);
      image.at<float>(v, u) = static_cast<float>(value);
    }
  cv::rectangle(image, cv::Rect(20, 60, 140, 150), cv::Scalar(0.25), cv::FILLED);
  cv::rectangle(image, cv::Rect(460, 40, 160, 170), cv::Scalar(0.55), cv::FILLED);
  for (int k = 0; k < 6; ++k) cv::rectangle(image, cv::Rect(480 + 25 * (k % 3), 60 + 50 * (k / 3), 14, 24), cv::Scalar(0.1), cv::FILLED);
  cv::line(image, {320, 205}, {250, 479}, cv::Scalar(0.95), 6);
  cv::line(image, {330, 205}, {520, 479}, cv::Scalar(0.95), 6);
  cv::GaussianBlur(image, image, cv::Size(3, 3), 0.8);
  return image;
}

// Points of the street in the camera frame (x right, y down, z forward), metres.
std::vector<Eigen::Vector3d> StreetPointsCamera() {
  std::vector<Eigen::Vector3d> points;
  for (double z = 3.0; z < 40.0; z *= 1.05)        // push-broom lines on the road
    for (double x = -7.0; x <= 7.0; x += 0.1) points.emplace_back(x, 1.6, z);
  for (double z = 6.0; z < 30.0; z *= 1.04)         // a wall on the left
    for (double y = -4.0; y < 1.6; y += 0.1) points.emplace_back(-7.0, y, z);
  return points;
}

CameraModel SampleCamera() {
  CameraModel camera;
  camera.width = 640;
  camera.height = 480;
  camera.fx = camera.fy = 400.0;
  camera.cx = 319.5;
  camera.cy = 239.5;
  return camera;
}

// A plausible alternation history converging from `initial` to near `truth`:
// lower solutions overshoot and oscillate, upper ones follow with a lag, both
// meeting as the penalty tightens.
std::vector<AlternationRecord> FakeHistory(const std::vector<Eigen::Isometry3d>& initial,
                                           const std::vector<Eigen::Isometry3d>& truth) {
  std::vector<AlternationRecord> history;
  const int alternations = 20;
  const std::size_t pairs = truth.size();
  Vector6d bias = Tuple(0.004, -0.003, 0.006, 0.25, 0.05, -0.08);  // residual bias of the metric
  for (int i = 0; i < alternations; ++i) {
    AlternationRecord record;
    record.alternation = i;
    record.sigma_translation_m = 5.0 * std::pow(0.5, 0.5 * i);
    record.sigma_rotation_rad = 5.0 * std::pow(0.5, 0.5 * i);
    for (std::size_t p = 0; p < pairs; ++p) {
      const Vector6d start = LogSE3(initial[p] * truth[p].inverse());
      Vector6d wiggle;
      for (int k = 0; k < 6; ++k) wiggle[k] = std::sin(1.7 * i + 2.3 * k + static_cast<double>(p)) * (k < 3 ? 0.01 : 0.004);
      const Vector6d lower = start * std::pow(0.6, i + 1) + wiggle * std::pow(0.75, i) + bias;
      const Vector6d upper = start * std::pow(0.6, i + 0.6) + 0.5 * wiggle * std::pow(0.75, i) + bias;
      record.T_camera_lidar_lower.push_back(ExpSE3(lower) * truth[p]);
      record.T_camera_lidar_upper.push_back(ExpSE3(upper) * truth[p]);
      record.lower_cost.push_back(0.93 - 0.05 * (1.0 - std::pow(0.6, i)) + 0.002 * std::sin(static_cast<double>(i)));
      record.lower_evaluations.push_back(200 + 7 * i);
    }
    record.upper_cost.push_back(1e-3 * std::pow(0.7, i));
    record.elapsed_s = 4.2 * (i + 1);
    history.push_back(record);
  }
  return history;
}

// A smooth NID-like bowl around `truth`, weak about camera x (rx), as on real push-broom data.
double BowlCost(const Eigen::Isometry3d& T, const Eigen::Isometry3d& truth) {
  const Vector6d d = LogSE3(T * truth.inverse());
  const double scales[6] = {0.03, 0.03, 0.06, 0.03, 0.008, 0.008};  // m, rad
  double cost = 0.88;
  for (int k = 0; k < 6; ++k) cost += 0.02 * (1.0 - std::exp(-std::pow(d[k] / scales[k], 2)));
  return cost;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT_DIR\n", argv[0]);
    return 2;
  }
  try {
    const std::string out_dir = argv[1];
    const CameraModel camera = SampleCamera();
    // Base = left camera; right camera 24 cm to the right; lidar at the rear, looking back and down.
    const Eigen::Isometry3d T_base_left = Eigen::Isometry3d::Identity();
    const Eigen::Isometry3d T_base_right = TransformFromTuple(Tuple(0.24, 0, 0, 0, 0, 0));
    const Eigen::Isometry3d T_base_lidar_truth = TransformFromTuple(Tuple(0.1, -0.4, -1.8, 12.0, 0.5, -1.0));
    const Eigen::Isometry3d T_base_lidar_initial =
        TransformFromTuple(TupleFromTransform(T_base_lidar_truth) + Tuple(0.05, -0.04, 0.06, 1.5, -1.0, 2.0));
    const std::vector<Eigen::Isometry3d> truth = {T_base_left.inverse() * T_base_lidar_truth,
                                                  T_base_right.inverse() * T_base_lidar_truth};
    const std::vector<Eigen::Isometry3d> initial = {T_base_left.inverse() * T_base_lidar_initial,
                                                    T_base_right.inverse() * T_base_lidar_initial};
    const std::vector<AlternationRecord> history = FakeHistory(initial, truth);
    const AlternationRecord& last = history.back();

    report::CalibrationReportData data;
    data.title = "scenecal calibration report <sample>";
    data.dataset = "synthetic street (report_sample)";
    data.scheme = "alt";
    data.metric = "nid";
    data.alternations = static_cast<int>(history.size());
    data.termination = "max alternations (20)";
    data.warnings = {"sample data: the figures are synthetic",
                     "rotation about camera x is weakly constrained (flat cost slice rx)"};
    data.settings = {{"scheme", "alt"}, {"metric", "nid"}, {"histogram.bins", "32 x 32"}, {"binning", "hard"}};
    data.timings_s = {{"load", 1.25}, {"scenes", 0.4}, {"optimise", 84.0}};
    const Eigen::Isometry3d T_base_lidar_result = T_base_left * last.T_camera_lidar_upper[0];
    Vector6d sigma = Tuple(0.004, 0.003, 0.006, 0.4, 0.08, 0.1);
    data.lidars.push_back({"rear", T_base_lidar_initial, T_base_lidar_result, sigma, T_base_lidar_truth, "weak", "the sample: 2 sigma along x exceeds 1 cm"});
    const char* cameras[2] = {"left", "right"};
    for (std::size_t p = 0; p < 2; ++p) {
      report::PairRow row;
      row.camera = cameras[p];
      row.lidar = "rear";
      row.T_camera_lidar_initial = initial[p];
      row.T_camera_lidar = last.T_camera_lidar_upper[p];
      row.initial_cost = 0.931;
      row.final_cost = last.lower_cost[p];
      row.scenes = 30;
      row.scenes_used = 28 + static_cast<int>(p);
      row.T_camera_lidar_truth = truth[p];
      data.pairs.push_back(row);
      const std::string label = std::string(cameras[p]) + " / rear";
      data.convergence.push_back(report::ConvergenceFromHistory(history, static_cast<int>(p), label, truth[p]));
      const auto cost = [&truth, p](const Eigen::Isometry3d& T) { return BowlCost(T, truth[p]); };
      report::CostSliceOptions slice_options;
      slice_options.max_alternations = 6;
      data.cost_slices.push_back({label, report::SampleAlternationSlices(cost, history, static_cast<int>(p), initial[p],
                                                                         slice_options)});
    }
    data.optimisations.push_back({"alt lower level (2 pairs x 20 alternations)", 20, 4000, 5400, 80.5, "max alternations"});
    data.optimisations.push_back({"alt upper level (rear)", 20, 60, 0, 0.3, "converged"});

    // Overlays of the synthetic street: reflectance = image intensity where the truth projects.
    const cv::Mat image = StreetImage(camera.width, camera.height);
    const std::vector<Eigen::Vector3d> points_camera = StreetPointsCamera();
    std::vector<Eigen::Vector3d> points_lidar;
    std::vector<float> reflectance;
    for (const Eigen::Vector3d& p_camera : points_camera) {
      points_lidar.push_back(truth[0].inverse() * p_camera);
      Eigen::Vector2d pixel;
      float value = 0.5f;
      if (camera.Project(p_camera, &pixel))
        value = image.at<float>(static_cast<int>(std::lround(pixel.y())), static_cast<int>(std::lround(pixel.x())));
      reflectance.push_back(value);
    }
    const auto at_initial = report::ProjectPoints(camera, initial[0], points_lidar, reflectance);
    const auto at_result = report::ProjectPoints(camera, last.T_camera_lidar_upper[0], points_lidar, reflectance);
    report::OverlayFigure comparison;
    comparison.title = "Initial guess (red) vs result (blue): left / rear, scene 0";
    comparison.caption = "Synthetic street; the wall and the road edges line up only at the result.";
    comparison.file_name = "left_rear_0_initial_vs_result.png";
    comparison.bgr = report::RenderComparisonOverlay(image, at_initial, at_result);
    report::OverlayFigure coloured;
    coloured.title = "Result, coloured by reflectance: left / rear, scene 0";
    coloured.file_name = "left_rear_0_reflectance.png";
    coloured.bgr = report::RenderReflectanceOverlay(image, at_result);
    data.overlays = {comparison, coloured};

    report::WriteReportDirectory(out_dir + "/calibration", report::RenderCalibrationReport(data),
                                 report::CalibrationReportAttachments(data));

    // Experiment: 5 schemes x 10 trials of one lidar, errors of plausible size.
    report::ExperimentReportData experiment;
    experiment.description = "Synthetic sample: 10 perturbed initial guesses per method (errors are made up).";
    experiment.methods = {"once-nid", "once-mi", "joint-nid", "joint-mi", "alt-nid"};
    experiment.per_dof_methods = {"alt-nid", "once-mi"};
    experiment.settings = {{"trials", "10"}, {"perturbation", "5 cm, 2 deg"}};
    std::mt19937 random(7);
    std::normal_distribution<double> normal(0.0, 1.0);
    const double spread[5] = {1.0, 1.3, 0.6, 0.8, 0.45};
    for (std::size_t m = 0; m < experiment.methods.size(); ++m)
      for (int trial = 0; trial < 10; ++trial) {
        Vector6d error;
        for (int k = 0; k < 6; ++k) error[k] = spread[m] * normal(random) * (k < 3 ? 0.01 : RadiansFromDegrees(k == 3 ? 0.8 : 0.2));
        const Eigen::Isometry3d estimate = TransformFromTuple(TupleFromTransform(T_base_lidar_truth) + error);
        const bool success = !(m == 1 && trial == 3);
        experiment.runs.push_back(report::MakeExperimentRun(experiment.methods[m], "rear", trial, estimate,
                                                            T_base_lidar_truth, 20.0 + 5.0 * m + trial, success,
                                                            success ? "converged" : "no scene used"));
      }
    experiment.overlays = {comparison};
    report::WriteReportDirectory(out_dir + "/experiment", report::RenderExperimentReport(experiment),
                                 report::ExperimentReportAttachments(experiment));
    std::printf("wrote %s/calibration/report.html and %s/experiment/report.html\n", out_dir.c_str(), out_dir.c_str());
    return 0;
  } catch (const std::exception& error) {
    std::fprintf(stderr, "report_sample: %s\n", error.what());
    return 1;
  }
}
