// Real data: calibrate the OpenCalib single frames (one image, one 3D sweep)
// through the CLI from starts perturbed by 5 cm and 1 deg from the data set's
// reference, as scripts/bench_opencalib.sh does, and check the error against
// the target where the data reaches it (BENCHMARK.md, "OpenCalib"):
// the rotation of set 3 (rig B) within 0.3 deg. Its translation (the depth
// along the optical axis is barely constrained by one frame) and sets 1 and 2
// (rig A, whose NID minimum lies 1-3 deg off the reference) miss the targets,
// so they are measured by the script, not asserted here.
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/geometry.hpp"
#include "io/dataset.hpp"
#include "io/opencalib.hpp"

namespace scenecal {
namespace {

namespace fs = std::filesystem;

const fs::path kOpenCalibDir = fs::path(SCENECAL_SHARED_DATA_DIR) / "opencalib";

// Runs the CLI with `arguments` (stdout and stderr into log); returns its exit code.
int RunCli(const std::string& arguments, const fs::path& log) {
  const std::string command = std::string(SCENECAL_CLI_PATH) + " " + arguments + " >" + log.string() + " 2>&1";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

class OpenCalibCalibration : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = fs::temp_directory_path() / ("scenecal_test_opencalib_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_);
    io::ImportOpenCalib(kOpenCalibDir / "3", root_ / "set3", false);
  }
  static void TearDownTestSuite() { fs::remove_all(root_); }

  // Calibrates set 3 (joint scheme, one thread) from the reference moved by
  // exactly 5 cm and 1 deg in the random directions of `seed`.
  static CalibrationResult Calibrate(int seed, const std::string& extra = "") {
    const fs::path output = root_ / ("result_" + std::to_string(seed) + ".yaml");
    const fs::path log = root_ / ("log_" + std::to_string(seed) + ".txt");
    const std::string arguments = "calibrate " + (root_ / "set3").string() + " --output " + output.string() +
                                  " --scheme joint --threads 1 --perturb-from-truth --perturb-translation 0.05 "
                                  "--perturb-rotation 1 --seed " +
                                  std::to_string(seed) + " " + extra;
    EXPECT_EQ(RunCli(arguments, log), 0) << "see " << log;
    return io::ReadCalibrationResult(output);
  }

  static Eigen::Isometry3d Reference() {
    return io::OpenDataset(root_ / "set3").ground_truth->T_base_lidar.at("lidar");  // base = camera
  }

  static inline fs::path root_;
};

TEST_F(OpenCalibCalibration, SetThreeRotationWithinTargetFromPerturbedStarts) {
  const Eigen::Isometry3d reference = Reference();
  std::vector<double> rotation_errors_deg;
  for (int seed = 1; seed <= 8; ++seed) {  // with 32 bins, seed 6 ends 1.6 deg off
    const CalibrationResult result = Calibrate(seed);
    ASSERT_EQ(result.pairs.size(), 1u);
    // Chosen automatically for single-frame 3D-lidar data, and recorded.
    EXPECT_EQ(result.settings.at("bins"), "8x8");
    EXPECT_NE(result.settings.count("single_frame_defaults"), 0u);
    const double error_deg = RotationErrorDegrees(result.pairs[0].T_camera_lidar, reference);
    rotation_errors_deg.push_back(error_deg);
    // Every run, not only the median, lands within the 0.3 deg (the start is 1 deg off).
    EXPECT_LT(error_deg, 0.3) << "seed " << seed;
  }
  std::sort(rotation_errors_deg.begin(), rotation_errors_deg.end());
  EXPECT_LT(rotation_errors_deg[rotation_errors_deg.size() / 2], 0.3);
}

TEST_F(OpenCalibCalibration, ExplicitBinsOverrideTheSingleFrameDefault) {
  const CalibrationResult result = Calibrate(1, "--bins 16");
  EXPECT_EQ(result.settings.at("bins"), "16x16");
  EXPECT_EQ(result.settings.count("single_frame_defaults"), 0u);
}

// A preset for drives on a single frame: exit 2 naming why, no result file.
TEST_F(OpenCalibCalibration, DrivePresetsRefuseASingleFrame) {
  for (const char* setting : {"3d-lidar", "push-broom"}) {
    SCOPED_TRACE(setting);
    const fs::path output = root_ / (std::string("refused_") + setting + ".yaml");
    const fs::path log = root_ / (std::string("refused_") + setting + ".txt");
    EXPECT_EQ(RunCli("calibrate " + (root_ / "set3").string() + " --output " + output.string() + " --setting " +
                         setting,
                     log),
              2);
    std::ifstream in(log);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const char* expected = std::string(setting) == "3d-lidar" ? "a single-pose trajectory" : "no push-broom lidar";
    EXPECT_NE(text.find(expected), std::string::npos) << text;
    EXPECT_FALSE(fs::exists(output));
  }
}

}  // namespace
}  // namespace scenecal
