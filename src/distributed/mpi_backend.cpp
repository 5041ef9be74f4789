#include "distributed/mpi_backend.hpp"

#include <mpi.h>

#include <chrono>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <thread>

#include <tbb/parallel_for.h>

#include "core/interrupt.hpp"

namespace scenecal::distributed {
namespace {

constexpr int kRoot = 0;
constexpr double kCommandFinish = 0.0;
constexpr double kCommandSolve = 1.0;
// pair, alternation, 2 transforms, penalty, simplex options (7 + update + pivot),
// lower solver (1), L-BFGS options (6) and its run radii (2).
constexpr int kTaskDoubles = 2 + 16 + 16 + 36 + 7 + 4 + 7 + 2;
// transform, cost, objective, summary (4 + termination), gradient evaluations.
constexpr int kOutcomeDoubles = 16 + 2 + 4 + 1 + 1;

void Check(int code, const char* what) {
  if (code != MPI_SUCCESS) throw std::runtime_error(std::string("MPI call failed: ") + what);
}

// Waits for a nonblocking collective, checking for an interruption every
// millisecond: a blocking call would hold this rank for as long as the others
// take to reach the collective (a batch of lower levels can take minutes).
// Interrupted leaves the request pending: the caller then ends every rank.
void WaitInterruptibly(MPI_Request* request, const char* what) {
  for (;;) {
    int done = 0;
    Check(MPI_Test(request, &done, MPI_STATUS_IGNORE), what);
    if (done) return;
    ThrowIfInterrupted();
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

// MPI_Bcast from rank 0 and MPI_Reduce (sum) to rank 0, waited for with
// WaitInterruptibly. Every rank must use these (a nonblocking collective
// does not match a blocking one).
void Broadcast(double* data, int count, const char* what) {
  MPI_Request request = MPI_REQUEST_NULL;
  Check(MPI_Ibcast(data, count, MPI_DOUBLE, kRoot, MPI_COMM_WORLD, &request), what);
  WaitInterruptibly(&request, what);
}
void SumToRoot(const double* data, double* sum, int count, const char* what) {
  MPI_Request request = MPI_REQUEST_NULL;
  Check(MPI_Ireduce(data, sum, count, MPI_DOUBLE, MPI_SUM, kRoot, MPI_COMM_WORLD, &request), what);
  WaitInterruptibly(&request, what);
}

void PutTransform(const Eigen::Isometry3d& T, double* out) {
  Eigen::Map<Eigen::Matrix4d> matrix(out);
  matrix = T.matrix();
}
Eigen::Isometry3d GetTransform(const double* in) {
  Eigen::Isometry3d T;
  T.matrix() = Eigen::Map<const Eigen::Matrix4d>(in);
  return T;
}

void EncodeTask(const LowerLevelTask& task, double* out) {
  out[0] = task.pair;
  PutTransform(task.T_camera_lidar_upper, out + 1);
  PutTransform(task.T_camera_lidar_start, out + 17);
  Eigen::Map<Matrix6d>(out + 33) = task.penalty_information;
  const NelderMeadOptions& o = task.options;
  const double options[7] = {o.initial_step_translation_m, o.initial_step_rotation_rad,
                             static_cast<double>(o.max_iterations), static_cast<double>(o.max_evaluations),
                             o.function_tolerance, o.simplex_tolerance_translation_m, o.simplex_tolerance_rotation_rad};
  std::memcpy(out + 69, options, sizeof(options));
  out[76] = static_cast<double>(static_cast<int>(o.transform_update));
  out[77] = o.pivot_source.x();
  out[78] = o.pivot_source.y();
  out[79] = o.pivot_source.z();
  out[80] = task.alternation;
  out[81] = static_cast<double>(static_cast<int>(task.solver));
  const GradientSolverOptions& g = task.gradient;
  const double gradient[6] = {static_cast<double>(g.max_iterations), g.function_tolerance, g.gradient_tolerance,
                              g.parameter_tolerance, g.initial_step_translation_m, g.initial_step_rotation_rad};
  std::memcpy(out + 82, gradient, sizeof(gradient));
  out[88] = g.run_radius_translation_m;
  out[89] = g.run_radius_rotation_rad;
}

LowerLevelTask DecodeTask(const double* in) {
  LowerLevelTask task;
  task.pair = static_cast<int>(in[0]);
  task.T_camera_lidar_upper = GetTransform(in + 1);
  task.T_camera_lidar_start = GetTransform(in + 17);
  task.penalty_information = Eigen::Map<const Matrix6d>(in + 33);
  NelderMeadOptions& o = task.options;
  o.initial_step_translation_m = in[69];
  o.initial_step_rotation_rad = in[70];
  o.max_iterations = static_cast<int>(in[71]);
  o.max_evaluations = static_cast<int>(in[72]);
  o.function_tolerance = in[73];
  o.simplex_tolerance_translation_m = in[74];
  o.simplex_tolerance_rotation_rad = in[75];
  o.transform_update = static_cast<TransformUpdate>(static_cast<int>(in[76]));
  o.pivot_source = Eigen::Vector3d(in[77], in[78], in[79]);
  task.alternation = static_cast<int>(in[80]);
  task.solver = static_cast<LowerSolver>(static_cast<int>(in[81]));
  GradientSolverOptions& g = task.gradient;
  g.max_iterations = static_cast<int>(in[82]);
  g.function_tolerance = in[83];
  g.gradient_tolerance = in[84];
  g.parameter_tolerance = in[85];
  g.initial_step_translation_m = in[86];
  g.initial_step_rotation_rad = in[87];
  g.run_radius_translation_m = in[88];
  g.run_radius_rotation_rad = in[89];
  // The update kind and pivot are the simplex options' (SolveLowerLevel uses those for both solvers).
  g.transform_update = o.transform_update;
  g.pivot_source = o.pivot_source;
  return task;
}

void EncodeOutcome(const LowerLevelOutcome& outcome, double* out) {
  PutTransform(outcome.T_camera_lidar, out);
  out[16] = outcome.cost;
  out[17] = outcome.objective;
  out[18] = outcome.summary.iterations;
  out[19] = outcome.summary.evaluations;
  out[20] = outcome.summary.initial_value;
  out[21] = outcome.summary.final_value;
  out[22] = static_cast<double>(static_cast<int>(outcome.summary.termination));
  out[23] = outcome.gradient_evaluations;
}

LowerLevelOutcome DecodeOutcome(const double* in) {
  LowerLevelOutcome outcome;
  outcome.T_camera_lidar = GetTransform(in);
  outcome.cost = in[16];
  outcome.objective = in[17];
  outcome.summary.iterations = static_cast<int>(in[18]);
  outcome.summary.evaluations = static_cast<int>(in[19]);
  outcome.summary.initial_value = in[20];
  outcome.summary.final_value = in[21];
  outcome.summary.termination = static_cast<NelderMeadTermination>(static_cast<int>(in[22]));
  outcome.gradient_evaluations = static_cast<int>(in[23]);
  return outcome;
}

int WorldRank() {
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  return rank;
}
int WorldSize() {
  int size = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  return size;
}

// The part of a batch every rank runs: decode, solve owned tasks, reduce to root.
// Rows of tasks owned by other ranks stay zero, so the sum merges them exactly.
std::vector<double> SolveOwnedAndReduce(const std::vector<double>& encoded_tasks, int task_count,
                                        const std::vector<PairObjective>& local, const LowerLevelBatchHook& before_batch,
                                        const StopRequested& stop_requested) {
  const int rank = WorldRank();
  const int size = WorldSize();
  std::vector<LowerLevelTask> tasks;
  for (int i = 0; i < task_count; ++i) tasks.push_back(DecodeTask(encoded_tasks.data() + static_cast<std::size_t>(i) * kTaskDoubles));
  if (before_batch) before_batch(tasks);
  std::vector<double> outcomes(static_cast<std::size_t>(task_count) * kOutcomeDoubles, 0.0);
  tbb::parallel_for(0, task_count, [&](int i) {
    const LowerLevelTask& task = tasks[static_cast<std::size_t>(i)];
    if (!OwnsPair(task.pair, rank, size)) return;
    if (task.pair < 0 || static_cast<std::size_t>(task.pair) >= local.size() || !local[static_cast<std::size_t>(task.pair)].cost) {
      throw std::runtime_error("rank " + std::to_string(rank) + " has no objective for pair " + std::to_string(task.pair));
    }
    const LowerLevelOutcome outcome = SolveLowerLevel(local[static_cast<std::size_t>(task.pair)], task, stop_requested);
    EncodeOutcome(outcome, outcomes.data() + static_cast<std::size_t>(i) * kOutcomeDoubles);
  });
  std::vector<double> merged(rank == kRoot ? outcomes.size() : 0);
  SumToRoot(outcomes.data(), rank == kRoot ? merged.data() : nullptr, static_cast<int>(outcomes.size()),
            "MPI_Reduce of lower-level outcomes");
  return merged;
}

}  // namespace

MpiSession::MpiSession(int* argc, char*** argv) {
  int provided = 0;
  // Only the main thread calls MPI; TBB threads compute.
  Check(MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided), "MPI_Init_thread");
  rank_ = WorldRank();
  size_ = WorldSize();
}

MpiSession::~MpiSession() {
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (!finalized) MPI_Finalize();
}

void AbortAllRanks(int exit_code) {
  MPI_Abort(MPI_COMM_WORLD, exit_code);
  std::abort();  // MPI_Abort does not return; this keeps [[noreturn]] honest
}

bool OwnsPair(int pair, int rank, int size) { return size <= 0 || pair % size == rank; }

bool FingerprintsAgree(std::uint64_t fingerprint, std::string* why) {
  const int size = WorldSize();
  std::vector<std::uint64_t> all(static_cast<std::size_t>(size));
  Check(MPI_Allgather(&fingerprint, 1, MPI_UINT64_T, all.data(), 1, MPI_UINT64_T, MPI_COMM_WORLD),
        "MPI_Allgather of input fingerprints");
  std::string differing;
  for (int r = 1; r < size; ++r) {
    if (all[static_cast<std::size_t>(r)] != all[0]) differing += (differing.empty() ? "" : ", ") + std::to_string(r);
  }
  if (differing.empty()) return true;
  if (why) *why = "the inputs of rank(s) " + differing + " differ from rank 0's (different dataset, options or version)";
  return false;
}

MpiLowerLevelBackend::MpiLowerLevelBackend(std::vector<PairObjective> local, LowerLevelBatchHook before_batch)
    : local_(std::move(local)), before_batch_(std::move(before_batch)) {}

MpiLowerLevelBackend::~MpiLowerLevelBackend() {
  // Unwinding from an error or an interruption: the other ranks may be inside
  // another collective, which the end message would not match. The caller
  // ends every rank instead (AbortAllRanks).
  if (std::uncaught_exceptions() > 0) return;
  try {
    Finish();
  } catch (...) {
    // Destructors must not throw; a failed broadcast already ended the job.
  }
}

void MpiLowerLevelBackend::Finish() {
  if (finished_) return;
  finished_ = true;
  double header[3] = {kCommandFinish, 0.0, 0.0};
  // Waited for without the interrupt check: the serving ranks wait for just
  // this message, and a request left pending would leave them waiting.
  MPI_Request request = MPI_REQUEST_NULL;
  Check(MPI_Ibcast(header, 3, MPI_DOUBLE, kRoot, MPI_COMM_WORLD, &request), "MPI_Bcast of the end message");
  Check(MPI_Wait(&request, MPI_STATUS_IGNORE), "MPI_Bcast of the end message");
}

std::vector<LowerLevelOutcome> MpiLowerLevelBackend::Solve(const std::vector<LowerLevelTask>& tasks,
                                                           const StopRequested& stop_requested) {
  const int task_count = static_cast<int>(tasks.size());
  // Serving ranks get a deadline: how long rank 0 will still wait. Rank 0's
  // own callback decides for rank 0 (and records that the budget ran out).
  double header[3] = {kCommandSolve, static_cast<double>(task_count), -1.0};
  Broadcast(header, 3, "MPI_Bcast of a batch header");
  std::vector<double> encoded(static_cast<std::size_t>(task_count) * kTaskDoubles);
  for (int i = 0; i < task_count; ++i) EncodeTask(tasks[static_cast<std::size_t>(i)], encoded.data() + static_cast<std::size_t>(i) * kTaskDoubles);
  Broadcast(encoded.data(), static_cast<int>(encoded.size()), "MPI_Bcast of lower-level tasks");
  const std::vector<double> merged = SolveOwnedAndReduce(encoded, task_count, local_, before_batch_, stop_requested);
  std::vector<LowerLevelOutcome> outcomes(tasks.size());
  for (int i = 0; i < task_count; ++i) outcomes[static_cast<std::size_t>(i)] = DecodeOutcome(merged.data() + static_cast<std::size_t>(i) * kOutcomeDoubles);
  return outcomes;
}

void ServeLowerLevel(std::vector<PairObjective> local, const LowerLevelBatchHook& before_batch) {
  for (;;) {
    double header[3] = {0, 0, 0};
    Broadcast(header, 3, "MPI_Bcast of a batch header");
    if (header[0] == kCommandFinish) return;
    const int task_count = static_cast<int>(header[1]);
    std::vector<double> encoded(static_cast<std::size_t>(task_count) * kTaskDoubles);
    Broadcast(encoded.data(), static_cast<int>(encoded.size()), "MPI_Bcast of lower-level tasks");
    SolveOwnedAndReduce(encoded, task_count, local, before_batch, {});
  }
}

}  // namespace scenecal::distributed
