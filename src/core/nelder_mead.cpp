#include "core/nelder_mead.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <vector>

#include <sstream>

#include "core/geometry.hpp"
#include "core/interrupt.hpp"
#include "core/validation.hpp"

namespace scenecal {

bool NelderMeadOptions::IsValid(std::string* why) const {
  if (!(initial_step_translation_m > 0.0) || !std::isfinite(initial_step_translation_m))
    return Invalid(why, "initial_step_translation_m must be a positive number of metres");
  if (!(initial_step_rotation_rad > 0.0) || !std::isfinite(initial_step_rotation_rad))
    return Invalid(why, "initial_step_rotation_rad must be a positive number of radians");
  if (max_iterations < 1) return Invalid(why, "max_iterations must be at least 1");
  if (max_evaluations < 0) return Invalid(why, "max_evaluations must be 0 (no cap) or positive");
  if (!(function_tolerance >= 0.0)) return Invalid(why, "function_tolerance must be >= 0");
  if (!(simplex_tolerance_translation_m >= 0.0) || !(simplex_tolerance_rotation_rad >= 0.0))
    return Invalid(why, "simplex tolerances must be >= 0");
  return true;
}

const char* NelderMeadTerminationName(NelderMeadTermination termination) {
  switch (termination) {
    case NelderMeadTermination::kFunctionTolerance: return "function tolerance reached";
    case NelderMeadTermination::kSimplexTolerance: return "simplex tolerance reached";
    case NelderMeadTermination::kMaxIterations: return "max iterations";
    case NelderMeadTermination::kMaxEvaluations: return "max evaluations";
    case NelderMeadTermination::kStopRequested: return "stop requested";
    case NelderMeadTermination::kNonFiniteCost: return "non-finite cost at the start point";
  }
  return "unknown";
}

std::string NelderMeadSummary::BriefReport() const {
  std::ostringstream out;
  out.precision(6);
  out << "iterations " << iterations << ", evaluations " << evaluations << ", cost " << initial_value << " -> "
      << final_value << ", " << NelderMeadTerminationName(termination);
  return out.str();
}

namespace {

// The cost, counted into *evaluations, with non-finite values as +infinity
// (worse than any finite value).
class CountedCost {
 public:
  CountedCost(const std::function<double(const Eigen::VectorXd&)>& cost, int* evaluations)
      : cost_(cost), evaluations_(evaluations) {}

  double operator()(const Eigen::VectorXd& point) const {
    ++*evaluations_;
    const double value = cost_(point);
    return std::isfinite(value) ? value : std::numeric_limits<double>::infinity();
  }

 private:
  const std::function<double(const Eigen::VectorXd&)>& cost_;
  int* evaluations_;
};

// n + 1 vertices and their cost values; vertex 0 is the best after Sort().
struct Simplex {
  std::vector<Eigen::VectorXd> vertices;
  std::vector<double> values;

  std::size_t Worst() const { return vertices.size() - 1; }

  void Sort() {
    std::vector<std::size_t> order(vertices.size());
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return values[a] < values[b]; });
    std::vector<Eigen::VectorXd> sorted_vertices(vertices.size());
    std::vector<double> sorted_values(values.size());
    for (std::size_t i = 0; i < order.size(); ++i) {
      sorted_vertices[i] = vertices[order[i]];
      sorted_values[i] = values[order[i]];
    }
    vertices.swap(sorted_vertices);
    values.swap(sorted_values);
  }

  void Replace(std::size_t v, const Eigen::VectorXd& vertex, double value) {
    vertices[v] = vertex;
    values[v] = value;
  }
};

// Vertex i + 1: the start point (vertex 0, already evaluated) moved by steps[i] along dimension i.
void AddStepVertices(const Eigen::VectorXd& steps, const CountedCost& evaluate, Simplex* simplex) {
  const auto n = static_cast<Eigen::Index>(simplex->Worst());
  for (Eigen::Index i = 0; i < n; ++i) {
    auto& vertex = simplex->vertices[static_cast<std::size_t>(i + 1)];
    vertex[i] += steps[i];
    simplex->values[static_cast<std::size_t>(i + 1)] = evaluate(vertex);
  }
}

// Why to stop before the next iteration, if at all (on the sorted simplex).
std::optional<NelderMeadTermination> Termination(const Simplex& simplex, const Eigen::VectorXd& tolerances,
                                                 const NelderMeadOptions& options, const NelderMeadSummary& summary,
                                                 const StopRequested& stop_requested) {
  const std::size_t worst = simplex.Worst();
  const std::vector<Eigen::VectorXd>& vertices = simplex.vertices;
  if (simplex.values[worst] - simplex.values[0] <= options.function_tolerance)
    return NelderMeadTermination::kFunctionTolerance;
  bool simplex_small = true;
  for (std::size_t v = 1; v <= worst && simplex_small; ++v) {
    simplex_small = ((vertices[v] - vertices[0]).cwiseAbs().array() <= tolerances.array()).all();
  }
  if (simplex_small) return NelderMeadTermination::kSimplexTolerance;
  if (summary.iterations >= options.max_iterations) return NelderMeadTermination::kMaxIterations;
  if (options.max_evaluations > 0 && summary.evaluations >= options.max_evaluations)
    return NelderMeadTermination::kMaxEvaluations;
  if (stop_requested && stop_requested()) return NelderMeadTermination::kStopRequested;
  return std::nullopt;
}

// Contracts the worst vertex towards the better of itself and its
// reflection, or else shrinks every vertex towards the best one.
void ContractOrShrink(const Eigen::VectorXd& centroid, const Eigen::VectorXd& reflected, double reflected_value,
                      const CountedCost& evaluate, Simplex* simplex) {
  std::vector<Eigen::VectorXd>& vertices = simplex->vertices;
  std::vector<double>& values = simplex->values;
  const std::size_t worst = simplex->Worst();
  const bool outside = reflected_value < values[worst];
  const Eigen::VectorXd contracted = outside ? Eigen::VectorXd(centroid + 0.5 * (reflected - centroid))
                                             : Eigen::VectorXd(centroid + 0.5 * (vertices[worst] - centroid));
  const double contracted_value = evaluate(contracted);
  if (contracted_value < (outside ? reflected_value : values[worst])) {
    simplex->Replace(worst, contracted, contracted_value);
    return;
  }
  for (std::size_t v = 1; v <= worst; ++v) {
    vertices[v] = vertices[0] + 0.5 * (vertices[v] - vertices[0]);
    values[v] = evaluate(vertices[v]);
  }
}

// One iteration on the sorted simplex: reflect the worst vertex through the
// centroid of the others, then expand, accept, contract or shrink; sorts again.
void Iterate(const CountedCost& evaluate, Simplex* simplex) {
  const std::size_t worst = simplex->Worst();
  const std::vector<Eigen::VectorXd>& vertices = simplex->vertices;
  const std::vector<double>& values = simplex->values;
  Eigen::VectorXd centroid = Eigen::VectorXd::Zero(vertices[0].size());
  for (std::size_t v = 0; v < worst; ++v) centroid += vertices[v];
  centroid /= static_cast<double>(worst);

  const Eigen::VectorXd reflected = centroid + (centroid - vertices[worst]);
  const double reflected_value = evaluate(reflected);
  if (reflected_value < values[0]) {
    const Eigen::VectorXd expanded = centroid + 2.0 * (centroid - vertices[worst]);
    const double expanded_value = evaluate(expanded);
    if (expanded_value < reflected_value) {
      simplex->Replace(worst, expanded, expanded_value);
    } else {
      simplex->Replace(worst, reflected, reflected_value);
    }
  } else if (reflected_value < values[worst - 1]) {
    simplex->Replace(worst, reflected, reflected_value);
  } else {
    ContractOrShrink(centroid, reflected, reflected_value, evaluate, simplex);
  }
  simplex->Sort();
}

}  // namespace

NelderMeadSummary MinimiseNelderMead(const std::function<double(const Eigen::VectorXd&)>& cost,
                                     const Eigen::VectorXd& steps, const Eigen::VectorXd& tolerances,
                                     const NelderMeadOptions& options, Eigen::VectorXd* x,
                                     const StopRequested& stop_requested) {
  const Eigen::Index n = x->size();
  NelderMeadSummary summary;
  const CountedCost evaluate(cost, &summary.evaluations);

  Simplex simplex{std::vector<Eigen::VectorXd>(static_cast<std::size_t>(n + 1), *x),
                  std::vector<double>(static_cast<std::size_t>(n + 1))};
  simplex.values[0] = evaluate(*x);
  summary.initial_value = simplex.values[0];
  summary.final_value = simplex.values[0];
  if (!std::isfinite(simplex.values[0])) {
    summary.termination = NelderMeadTermination::kNonFiniteCost;
    return summary;
  }
  AddStepVertices(steps, evaluate, &simplex);
  simplex.Sort();
  summary.termination = NelderMeadTermination::kMaxIterations;
  while (true) {
    ThrowIfInterrupted();  // an iteration costs at most n + 2 evaluations
    if (const auto termination = Termination(simplex, tolerances, options, summary, stop_requested)) {
      summary.termination = *termination;
      break;
    }
    ++summary.iterations;
    Iterate(evaluate, &simplex);
  }

  *x = simplex.vertices[0];
  summary.final_value = simplex.values[0];
  return summary;
}

Eigen::Isometry3d ApplyTransformUpdate(const Eigen::Isometry3d& T_0, const Eigen::Matrix<double, 6, 1>& delta,
                                       TransformUpdate update, const Eigen::Vector3d& pivot_source) {
  if (update == TransformUpdate::kLeftTwist) return ExpSE3(delta) * T_0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = ExpSO3(delta.tail<3>()) * T_0.linear();
  // T * q = T_0 * q + rho.
  T.translation() = T_0.translation() + delta.head<3>() + T_0.linear() * pivot_source - T.linear() * pivot_source;
  return T;
}

Eigen::Matrix<double, 6, 1> TransformUpdateBetween(const Eigen::Isometry3d& from, const Eigen::Isometry3d& to,
                                                   TransformUpdate update, const Eigen::Vector3d& pivot_source) {
  if (update == TransformUpdate::kLeftTwist) return LogSE3(to * from.inverse());
  Eigen::Matrix<double, 6, 1> delta;
  delta.head<3>() = to * pivot_source - from * pivot_source;
  delta.tail<3>() = LogSO3(to.linear() * from.linear().transpose());
  return delta;
}

NelderMeadSummary MinimiseOverTransform(const std::function<double(const Eigen::Isometry3d&)>& cost,
                                        const NelderMeadOptions& options, Eigen::Isometry3d* transform,
                                        const StopRequested& stop_requested) {
  const Eigen::Isometry3d start = *transform;
  Eigen::VectorXd steps(6), tolerances(6);
  steps << Eigen::Vector3d::Constant(options.initial_step_translation_m),
      Eigen::Vector3d::Constant(options.initial_step_rotation_rad);
  tolerances << Eigen::Vector3d::Constant(options.simplex_tolerance_translation_m),
      Eigen::Vector3d::Constant(options.simplex_tolerance_rotation_rad);
  Eigen::VectorXd delta = Eigen::VectorXd::Zero(6);
  const auto local_cost = [&](const Eigen::VectorXd& d) {
    return cost(ApplyTransformUpdate(start, Vector6d(d), options.transform_update, options.pivot_source));
  };
  const NelderMeadSummary summary = MinimiseNelderMead(local_cost, steps, tolerances, options, &delta, stop_requested);
  *transform = ApplyTransformUpdate(start, Vector6d(delta), options.transform_update, options.pivot_source);
  return summary;
}

}  // namespace scenecal
