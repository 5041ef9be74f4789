// `scenecal experiment` and `scenecal calibrate --report`, run as the CLI on a
// tiny simulated street (320x240 images, 90 m): the files they write, their
// rows and columns, the report's sections, and the exit codes.
#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

namespace {

namespace fs = std::filesystem;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Runs the CLI with `arguments` (stdout and stderr into log); returns its exit code.
int RunCli(const std::string& arguments, const fs::path& log) {
  const std::string command = std::string(SCENECAL_CLI_PATH) + " " + arguments + " >" + log.string() + " 2>&1";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// A CSV without quoted separators in the columns we read (the last column,
// termination, may hold commas inside quotes: only the leading fields are split).
std::vector<std::string> SplitLeadingFields(const std::string& line, std::size_t count) {
  std::vector<std::string> fields;
  std::size_t begin = 0;
  while (fields.size() < count) {
    const std::size_t end = line.find(',', begin);
    fields.push_back(line.substr(begin, end == std::string::npos ? std::string::npos : end - begin));
    if (end == std::string::npos) break;
    begin = end + 1;
  }
  return fields;
}

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) lines.push_back(line);
  return lines;
}

void ExpectSelfContained(const std::string& html) {
  for (const char* bad : {"http://", "https://", "src=\"//", "<script", "<link", "@import", "url("}) {
    EXPECT_EQ(html.find(bad), std::string::npos) << "report.html holds an external reference: " << bad;
  }
}

class ExperimentCli : public ::testing::Test {
 protected:
  // One tiny dataset shared by the tests (ctest runs each test in its own
  // process, so this is all the suite repeats per test).
  static void SetUpTestSuite() {
    std::random_device random;
    root_ = new fs::path(fs::temp_directory_path() / ("scenecal_experiment_test_" + std::to_string(random())));
    fs::create_directories(*root_);
    exit_code_ = RunCli("simulate --preset robotcar --seed 3 --image-size 320x240 --distance 90 --output " +
                            Dataset().string(),
                        *root_ / "simulate.log");
  }
  static void TearDownTestSuite() {
    std::error_code ignored;
    fs::remove_all(*root_, ignored);
    delete root_;
    root_ = nullptr;
  }
  static fs::path Experiment() { return *root_ / "experiment"; }
  static fs::path Dataset() { return *root_ / "dataset"; }
  static fs::path Root() { return *root_; }
  static int exit_code_;

 private:
  static fs::path* root_;
};
fs::path* ExperimentCli::root_ = nullptr;
int ExperimentCli::exit_code_ = -1;

// The brief's tiny setting; the experiment simulates its own dataset.
TEST_F(ExperimentCli, TinyExperimentWritesRunsAndReport) {
  ASSERT_EQ(RunCli("experiment --preset robotcar --seed 3 --image-size 320x240 --distance 90 --guesses 2 "
                   "--scenes 4 --alternations 3 --schemes once,alt --metrics nid --threads 2 --output " +
                       Experiment().string(),
                   Root() / "experiment.log"),
            0)
      << ReadText(Root() / "experiment.log");
  ASSERT_TRUE(fs::exists(Experiment() / "dataset" / "rig.yaml")) << "the experiment simulates into OUTPUT/dataset";
  const std::vector<std::string> lines = Lines(ReadText(Experiment() / "runs.csv"));
  ASSERT_FALSE(lines.empty());
  const std::vector<std::string> header = SplitLeadingFields(lines[0], 100);
  std::map<std::string, std::size_t> column;
  for (std::size_t i = 0; i < header.size(); ++i) column[header[i]] = i;
  for (const char* name :
       {"guess", "scheme", "metric", "method", "lidar", "success", "translation_error_m", "rotation_error_deg",
        "error_x_m", "error_y_m", "error_z_m", "error_roll_deg", "error_pitch_deg", "error_yaw_deg",
        "initial_translation_error_m", "initial_rotation_error_deg", "initial_cost", "cost", "evaluations", "seconds",
        "termination"}) {
    EXPECT_EQ(column.count(name), 1u) << "runs.csv lacks column " << name;
  }
  ASSERT_EQ(header.back(), "termination");
  // 2 guesses x {once, alt} x {nid}, one lidar.
  ASSERT_EQ(lines.size(), 1u + 4u);
  std::set<std::pair<std::string, std::string>> seen;  // (guess, method)
  std::map<std::string, std::set<std::string>> initial_cost_by_guess;
  for (std::size_t r = 1; r < lines.size(); ++r) {
    const std::vector<std::string> row = SplitLeadingFields(lines[r], header.size() - 1);
    ASSERT_EQ(row.size(), header.size() - 1) << lines[r];
    const auto field = [&](const char* name) { return row[column.at(name)]; };
    const auto number = [&](const char* name) { return std::stod(field(name)); };
    seen.insert({field("guess"), field("method")});
    EXPECT_EQ(field("metric"), "nid");
    EXPECT_EQ(field("lidar"), "lms_rear");
    EXPECT_EQ(field("method"), field("scheme") + "-" + field("metric"));
    EXPECT_EQ(field("success"), "1") << lines[r];
    // Every guess is the truth moved by exactly 0.1 m and 3 deg.
    EXPECT_NEAR(number("initial_translation_error_m"), 0.1, 1e-6);
    EXPECT_NEAR(number("initial_rotation_error_deg"), 3.0, 1e-6);
    const double translation = number("translation_error_m");
    const double rotation = number("rotation_error_deg");
    ASSERT_TRUE(std::isfinite(translation) && std::isfinite(rotation)) << lines[r];
    // The total translation error is the norm of the per-axis ones.
    EXPECT_NEAR(std::hypot(number("error_x_m"), number("error_y_m"), number("error_z_m")), translation, 1e-5);
    // Calibrating improves on the guess it started from.
    EXPECT_LT(translation, number("initial_translation_error_m")) << lines[r];
    EXPECT_LT(number("cost"), number("initial_cost")) << lines[r];
    EXPECT_GT(std::stoi(field("evaluations")), 0);
    EXPECT_GT(number("seconds"), 0.0);
    initial_cost_by_guess[field("guess")].insert(field("initial_cost"));
  }
  EXPECT_EQ(seen.size(), 4u) << "each (guess, method) once";
  // Every scheme starts from the same guess: the same cost there.
  ASSERT_EQ(initial_cost_by_guess.size(), 2u);
  for (const auto& [guess, costs] : initial_cost_by_guess) EXPECT_EQ(costs.size(), 1u) << "guess " << guess;

  // The Markdown summary: one line per method after the header and rule.
  const std::vector<std::string> summary = Lines(ReadText(Experiment() / "summary.md"));
  ASSERT_EQ(summary.size(), 2u + 2u);
  EXPECT_EQ(summary[2].rfind("| once-nid | 2/2 |", 0), 0u) << summary[2];
  EXPECT_EQ(summary[3].rfind("| alt-nid | 2/2 |", 0), 0u) << summary[3];

  // The report: Fig. 7 and 8, the runs, overlays; self-contained.
  const std::string html = ReadText(Experiment() / "report.html");
  ASSERT_FALSE(html.empty());
  for (const char* section : {"summary", "box-plots", "per-dof-errors", "runs", "overlays"}) {
    EXPECT_NE(html.find(std::string("<section id=\"") + section + "\""), std::string::npos) << section;
  }
  EXPECT_NE(html.find("once-nid"), std::string::npos);
  EXPECT_NE(html.find("alt-nid"), std::string::npos);
  EXPECT_NE(html.find("<svg"), std::string::npos);
  EXPECT_NE(html.find("data:image/png;base64,"), std::string::npos) << "overlays embedded";
  ExpectSelfContained(html);
  // Progress on stderr: runs done / total with the time left.
  const std::string log = ReadText(Root() / "experiment.log");
  EXPECT_NE(log.find("[4/4]"), std::string::npos);
  EXPECT_NE(log.find("about"), std::string::npos);
}

TEST_F(ExperimentCli, BadOptionsExitWithTwo) {
  ASSERT_EQ(exit_code_, 0) << ReadText(Root() / "simulate.log");
  const std::string dataset = " --dataset " + Dataset().string();
  const fs::path log = Root() / "bad.log";
  EXPECT_EQ(RunCli("experiment --schemes once,bogus --output " + (Root() / "bad1").string(), log), 2);
  EXPECT_EQ(RunCli("experiment --metrics nid,nid" + dataset + " --output " + (Root() / "bad2").string(), log), 2)
      << ReadText(log);
  EXPECT_NE(ReadText(log).find("--metrics"), std::string::npos) << ReadText(log);
  EXPECT_EQ(RunCli("experiment --guesses 0 --output " + (Root() / "bad3").string(), log), 2);
  EXPECT_EQ(RunCli("experiment --preset spin3d --output " + (Root() / "bad4").string(), log), 2);
  EXPECT_EQ(RunCli("experiment --image-size 320by240 --output " + (Root() / "bad5").string(), log), 2);
  EXPECT_NE(ReadText(log).find("--image-size"), std::string::npos) << ReadText(log);
  EXPECT_EQ(RunCli("experiment" + dataset + " --stages 1:x --output " + (Root() / "bad6").string(), log), 2);
  // A dataset without ground truth cannot be scored.
  const fs::path no_truth = Root() / "no_truth";
  fs::copy(Dataset(), no_truth, fs::copy_options::recursive);
  fs::remove(no_truth / "ground_truth.yaml");
  EXPECT_EQ(RunCli("experiment --dataset " + no_truth.string() + " --output " + (Root() / "bad7").string(), log), 2);
  EXPECT_NE(ReadText(log).find("ground_truth.yaml"), std::string::npos) << ReadText(log);
  // Help explains the protocol.
  EXPECT_EQ(RunCli("experiment --help", log), 0);
  EXPECT_NE(ReadText(log).find("--perturb-translation"), std::string::npos);
  // calibrate's alt options, every one of them (one definition for both commands).
  for (const char* option : {"--alternations", "--stage-alternations", "--alternation-schedule", "--shrink",
                             "--penalty-frame", "--sigma0-translation", "--sigma0-rotation", "--stop-translation",
                             "--stop-rotation", "--camera-sigma-translation", "--camera-sigma-rotation"}) {
    EXPECT_NE(ReadText(log).find(option), std::string::npos) << option;
  }
  EXPECT_EQ(RunCli("experiment" + dataset + " --shrink 1.5 --output " + (Root() / "bad8").string(), log), 2);
  EXPECT_NE(ReadText(log).find("--shrink"), std::string::npos) << ReadText(log);
}

TEST_F(ExperimentCli, NothingCalibratedExitsWithOne) {
  ASSERT_EQ(exit_code_, 0) << ReadText(Root() / "simulate.log");
  // Guesses 500 m off: no lidar point lands in any image, so no run can start.
  const fs::path output = Root() / "hopeless";
  const fs::path log = Root() / "hopeless.log";
  EXPECT_EQ(RunCli("experiment --dataset " + Dataset().string() +
                       " --guesses 1 --schemes once --metrics nid --scenes 4 --perturb-translation 500 --output " +
                       output.string(),
                   log),
            1)
      << ReadText(log);
  const std::vector<std::string> lines = Lines(ReadText(output / "runs.csv"));
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_EQ(SplitLeadingFields(lines[1], 6)[5], "0") << "the run is recorded as failed";
}

// Alt's stages spread over more alternations than the runs have: refused before any run.
TEST_F(ExperimentCli, StagesBeyondTheAlternationsAreRefused) {
  ASSERT_EQ(exit_code_, 0) << ReadText(Root() / "simulate.log");
  const fs::path output = Root() / "overstaged";
  const fs::path log = Root() / "overstaged.log";
  EXPECT_EQ(RunCli("experiment --dataset " + Dataset().string() +
                       " --guesses 1 --schemes alt --metrics nid --scenes 4 --alternations 3 --stage-alternations 5 "
                       "--penalty-frame camera --output " +
                       output.string(),
                   log),
            2)
      << ReadText(log);
  EXPECT_NE(ReadText(log).find("stage_alternations (5) must be between 0 (all) and max_alternations (3)"),
            std::string::npos)
      << ReadText(log);
  EXPECT_FALSE(fs::exists(output / "runs.csv"));
}

// --setting fills the options the command line did not give, the border from the
// image width (320 px here), and the report lists what it set; OUTPUT/options.yaml
// given back with --config repeats the experiment.
TEST_F(ExperimentCli, SettingFillsTheOptionsNotGiven) {
  ASSERT_EQ(exit_code_, 0) << ReadText(Root() / "simulate.log");
  const fs::path output = Root() / "setting";
  const fs::path log = Root() / "setting.log";
  ASSERT_EQ(RunCli("experiment --dataset " + Dataset().string() +
                       " --guesses 1 --schemes joint --metrics nid --scenes 4 --swathe-length 12 "
                       "--setting push-broom-drifting --output " +
                       output.string(),
                   log),
            0)
      << ReadText(log);
  const std::string words =
      "--range-split 6 --thin 2 --lower-solver lbfgs --refresh-border 3.75% --motion-correction turn,drive-scale "
      "--alternations 40 --stage-alternations 20 --alternation-schedule adaptive --stop-rotation 0.002";
  EXPECT_NE(ReadText(log).find("--setting push-broom-drifting: " + words + " (refresh border 12 px)"),
            std::string::npos)
      << ReadText(log);
  // The same experiment without the setting ends elsewhere: its options were in force.
  const fs::path plain = Root() / "setting_plain";
  ASSERT_EQ(RunCli("experiment --dataset " + Dataset().string() +
                       " --guesses 1 --schemes joint --metrics nid --scenes 4 --swathe-length 12 --output " +
                       plain.string(),
                   Root() / "setting_plain.log"),
            0)
      << ReadText(Root() / "setting_plain.log");
  const auto errors = [](const fs::path& runs) {  // translation and rotation error of the one run
    const std::vector<std::string> fields = SplitLeadingFields(Lines(ReadText(runs)).at(1), 8);
    return fields[6] + " " + fields[7];
  };
  EXPECT_NE(errors(output / "runs.csv"), errors(plain / "runs.csv"));
  const std::string html = ReadText(output / "report.html");
  EXPECT_NE(html.find(words), std::string::npos);
  EXPECT_NE(html.find("12 m"), std::string::npos) << "--swathe-length given: kept";
  const YAML::Node options = YAML::LoadFile((output / "options.yaml").string());
  EXPECT_EQ(options["swathe-length"].as<std::string>(), "12");
  EXPECT_EQ(options["thin"].as<std::string>(), "2");
  EXPECT_EQ(options["motion-correction"].size(), 2u);
  EXPECT_FALSE(options["output"].IsDefined());
  const fs::path again = Root() / "setting_again";
  ASSERT_EQ(RunCli("experiment --config " + (output / "options.yaml").string() + " --output " + again.string(),
                   Root() / "setting_again.log"),
            0)
      << ReadText(Root() / "setting_again.log");
  EXPECT_EQ(errors(again / "runs.csv"), errors(output / "runs.csv"));
  // 3d-lidar's centred final stage is calibrate's second solve: the experiment applies the rest of the preset.
  const fs::path three_d = Root() / "setting_3d";
  ASSERT_EQ(RunCli("experiment --dataset " + Dataset().string() +
                       " --guesses 1 --schemes joint --metrics nid --scenes 4 --stages 1 --setting 3d-lidar --output " +
                       three_d.string(),
                   log),
            0)
      << ReadText(log);
  EXPECT_NE(ReadText(log).find("--setting 3d-lidar: --swathe-length 10 --direction forward --lower-solver lbfgs"),
            std::string::npos)
      << ReadText(log);
  // An unknown setting: exit 2 before any run.
  EXPECT_EQ(RunCli("experiment --dataset " + Dataset().string() + " --setting push --output " +
                       (Root() / "setting_bad").string(),
                   log),
            2);
  for (const char* name : {"push-broom", "push-broom-drifting", "paper"}) {
    EXPECT_NE(ReadText(log).find(name), std::string::npos) << name << " not offered: " << ReadText(log);
  }
  EXPECT_EQ(ReadText(log).find(",auto"), std::string::npos) << "experiment has no automatic choice";
}

TEST_F(ExperimentCli, CalibrateReportWritesPageAndOverlays) {
  ASSERT_EQ(exit_code_, 0) << ReadText(Root() / "simulate.log");
  for (const std::string scheme : {"alt", "joint"}) {
    SCOPED_TRACE(scheme);
    const fs::path report = Root() / ("report_" + scheme);
    const fs::path log = Root() / ("calibrate_" + scheme + ".log");
    ASSERT_EQ(RunCli("calibrate " + Dataset().string() + " --scheme " + scheme +
                         " --scenes 3 --alternations 2 --threads 2 --output " +
                         (Root() / ("result_" + scheme + ".yaml")).string() + " --report " + report.string(),
                     log),
              0)
        << ReadText(log);
    const std::string html = ReadText(report / "report.html");
    for (const char* section : {"summary", "uncertainty", "convergence", "cost-slices", "overlays"}) {
      EXPECT_NE(html.find(std::string("<section id=\"") + section + "\""), std::string::npos) << section;
    }
    ExpectSelfContained(html);
    EXPECT_NE(html.find("data:image/png;base64,"), std::string::npos);
    // Alt has a history to plot; joint says it has none.
    const bool says_no_history = html.find("No alternation history") != std::string::npos;
    EXPECT_EQ(says_no_history, scheme != "alt");
    int pngs = 0;
    for (const fs::directory_entry& entry : fs::directory_iterator(report)) {
      if (entry.path().extension() != ".png") continue;
      ++pngs;
      const std::string bytes = ReadText(entry.path());
      ASSERT_GE(bytes.size(), 8u);
      EXPECT_EQ(bytes.substr(1, 3), "PNG") << entry.path();
    }
    // Two pairs (left, right) x at least one scene x (initial vs result, reflectance).
    EXPECT_GE(pngs, 4);
  }
}

}  // namespace
