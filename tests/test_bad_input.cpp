// Every malformed input is rejected with a message naming the file and the
// field, through the API (io::InputError) and through the CLI (exit code 2,
// one message on stderr, no crash), and never leaves output behind.
#include <functional>

#include <unistd.h>

#include <gtest/gtest.h>

#include "io/dataset.hpp"
#include "io/inspect.hpp"
#include "io/opencalib.hpp"
#include "io_test_support.hpp"

namespace scenecal {
namespace {

using namespace scenecal::testing;

struct BadCase {
  std::string name;
  // Breaks the valid input in `dir` in one way; returns false if the edit
  // itself did not apply (a broken test, not a passing one).
  std::function<bool(const fs::path& dir)> wreck;
  std::string file;   // expected in the message (a file name or path part)
  std::string field;  // expected in the message
};

bool Replace(const fs::path& path, const std::string& from, const std::string& to) {
  return ReplaceInFile(path, from, to);
}

std::vector<BadCase> DatasetCases() {
  const auto rig = [](const std::string& from, const std::string& to) {
    return [from, to](const fs::path& dir) { return Replace(dir / "rig.yaml", from, to); };
  };
  const auto trajectory = [](const std::string& from, const std::string& to) {
    return [from, to](const fs::path& dir) { return Replace(dir / "trajectory.csv", from, to); };
  };
  return {
      {"missing rig.yaml", [](const fs::path& dir) { return fs::remove(dir / "rig.yaml"); }, "rig.yaml", "missing"},
      {"missing trajectory.csv", [](const fs::path& dir) { return fs::remove(dir / "trajectory.csv"); },
       "trajectory.csv", "missing"},
      {"YAML syntax error", rig("intrinsics: [30, 30, 15.5, 11.5]", "intrinsics: [30, 30, 15.5, 11.5"), "rig.yaml",
       "line"},
      {"unknown key", rig("    distortion: []\n", "    distortion: []\n    distorsion: []\n"), "rig.yaml",
       "cameras.left.distorsion"},
      {"unknown top-level key", rig("extra:", "extras:"), "rig.yaml", "extras"},
      {"wrong format version", rig("scenecal-dataset/1", "scenecal-dataset/2"), "rig.yaml", "format"},
      {"base_frame not a camera", rig("base_frame: left", "base_frame: rear"), "rig.yaml", "base_frame"},
      {"base camera not the identity", rig("T_base_camera: [0, 0, 0, 0, 0, 0]", "T_base_camera: [0.1, 0, 0, 0, 0, 0]"),
       "rig.yaml", "cameras.left.T_base_camera"},
      {"intrinsics of 3 numbers", rig("[30, 30, 15.5, 11.5]", "[30, 30, 15.5]"), "rig.yaml",
       "cameras.left.intrinsics"},
      {"radtan distortion of 3", rig("[0.01, -0.002, 0.0001, 0.0002]", "[0.01, -0.002, 0.0001]"), "rig.yaml",
       "cameras.right.distortion"},
      {"transform of 5 numbers", rig("[0.24, 0, 0, 0, 0, 0]", "[0.24, 0, 0, 0, 0]"), "rig.yaml",
       "cameras.right.T_base_camera"},
      {"non-rigid 4x4", rig("[-2.6, 0.3, 1.1, -2.84, -1.51, -0.36]", "[[1, 0, 0, 0], [0, 2, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]"),
       "rig.yaml", "lidars.rear.T_base_lidar"},
      {"4x4 with a wrong last row", rig("[-2.6, 0.3, 1.1, -2.84, -1.51, -0.36]",
                                        "[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]"),
       "rig.yaml", "lidars.rear.T_base_lidar"},
      {"non-integer width", rig("width: 32\n    height: 24\n    model: pinhole", "width: 32.5\n    height: 24\n    model: pinhole"),
       "rig.yaml", "cameras.left.width"},
      {"zero height", rig("height: 24\n    model: pinhole", "height: 0\n    model: pinhole"), "rig.yaml",
       "cameras.left.height"},
      {"unknown camera model", rig("model: pinhole", "model: fisheye"), "rig.yaml", "cameras.left.model"},
      {"missing camera model", rig("    model: pinhole\n", ""), "rig.yaml", "cameras.left.model"},
      {"duplicate sensor names", rig("lidars:\n  rear:", "lidars:\n  left:\n    kind: 3d\n    T_base_lidar: [0, 0, 0, 0, 0, 0]\n  rear:"),
       "rig.yaml", "lidars.left"},
      {"invalid sensor name", rig("  rear:\n", "  \"rear lidar\":\n"), "rig.yaml", "rear lidar"},
      {"unknown lidar kind", rig("kind: 2d", "kind: 4d"), "rig.yaml", "lidars.rear.kind"},
      {"negative sigma", rig("[0.0005, 0.0005, 0.0005, 0.001, 0.001, 0.001]", "[0.0005, 0.0005, 0.0005, -0.001, 0.001, 0.001]"),
       "rig.yaml", "cameras.right.T_base_camera_sigma"},
      {"NaN intrinsics", rig("[30, 31, 16, 12]", "[30, .nan, 16, 12]"), "rig.yaml", "cameras.right.intrinsics"},
      {"no lidars", rig("lidars:\n  rear:\n    kind: 2d\n    T_base_lidar: [-2.6, 0.3, 1.1, -2.84, -1.51, -0.36]\n", "lidars: {}\n"),
       "rig.yaml", "lidars"},
      {"extra not a mapping", rig("extra:\n  note: anything goes here\n  nested: {a: [1, 2]}\n", "extra: 5\n"),
       "rig.yaml", "extra"},
      {"wrong trajectory header", trajectory("timestamp_us,x,y,z,qx,qy,qz,qw", "time,x,y,z,qx,qy,qz,qw"),
       "trajectory.csv", "line 1"},
      {"trajectory row of 7 fields", trajectory("1100000,0.1,0,0,0,0,0,1", "1100000,0.1,0,0,0,0,1"),
       "trajectory.csv", "line 3"},
      {"non-unit quaternion", trajectory("1300000,0.3,0,0,0,0,0,1", "1300000,0.3,0,0,0,0,0,1.1"), "trajectory.csv",
       "line 5"},
      {"non-increasing timestamps", trajectory("1400000,", "1300000,"), "trajectory.csv", "line 6 timestamp_us"},
      {"non-numeric timestamp", trajectory("1400000,", "14000a0,"), "trajectory.csv", "line 6 timestamp_us"},
      {"NaN pose", trajectory("1100000,0.1,", "1100000,nan,"), "trajectory.csv", "line 3 x"},
      {"trajectory without rows",
       [](const fs::path& dir) {
         WriteFile(dir / "trajectory.csv", "timestamp_us,x,y,z,qx,qy,qz,qw\n");
         return true;
       },
       "trajectory.csv", "no pose rows"},
      {".bin of 17 bytes",
       [](const fs::path& dir) {
         WriteFile(dir / "lidars" / "rear" / "1250000.bin", std::string(17, '\0'));
         return true;
       },
       "1250000.bin", "file size"},
      {"corrupt PNG",
       [](const fs::path& dir) {
         const fs::path png = dir / "cameras" / "left" / "1100000.png";
         const std::string bytes = ReadFile(png);
         WriteFile(png, bytes.substr(0, 40) + std::string(bytes.size() - 40, '\x5a'));
         return true;
       },
       "1100000.png", "image"},
      {"truncated PNG",
       [](const fs::path& dir) {
         const fs::path png = dir / "cameras" / "right" / "1200000.png";
         const std::string bytes = ReadFile(png);
         WriteFile(png, bytes.substr(0, bytes.size() - 30));
         return true;
       },
       "1200000.png", "image"},
      {"PNG with a flipped bit",
       [](const fs::path& dir) {
         const fs::path png = dir / "cameras" / "left" / "1300000.png";
         std::string bytes = ReadFile(png);
         bytes[bytes.size() / 2] = static_cast<char>(bytes[bytes.size() / 2] ^ 0x10);
         WriteFile(png, bytes);
         return true;
       },
       "1300000.png", "image"},
      {"corrupt JPEG",
       [](const fs::path& dir) {
         const fs::path jpg = dir / "cameras" / "left" / "1100000.jpg";
         fs::remove(dir / "cameras" / "left" / "1100000.png");
         cv::imwrite(jpg.string(), TestPattern(32, 24, CV_8UC1));
         const std::string bytes = ReadFile(jpg);
         WriteFile(jpg, bytes.substr(0, bytes.size() / 3));
         return true;
       },
       "1100000.jpg", "image"},
      {"not an image at all",
       [](const fs::path& dir) {
         WriteFile(dir / "cameras" / "right" / "1200000.png", "hello, I am text");
         return true;
       },
       "1200000.png", "image"},
      {"image of the wrong size",
       [](const fs::path& dir) {
         return cv::imwrite((dir / "cameras" / "right" / "1200000.png").string(), TestPattern(33, 24, CV_8UC1));
       },
       "1200000.png", "image size"},
      {"file name not a timestamp",
       [](const fs::path& dir) {
         return cv::imwrite((dir / "cameras" / "left" / "frame_1.png").string(), TestPattern(32, 24, CV_8UC1));
       },
       "frame_1.png", "file name"},
      {"stray file with another extension",
       [](const fs::path& dir) {
         WriteFile(dir / "lidars" / "rear" / "notes.txt", "notes");
         return true;
       },
       "notes.txt", "file name"},
      {"duplicate timestamps",
       [](const fs::path& dir) {
         return cv::imwrite((dir / "cameras" / "left" / "1100000.jpg").string(), TestPattern(32, 24, CV_8UC1));
       },
       "1100000", "timestamp 1100000"},
      {"folder for an unknown sensor",
       [](const fs::path& dir) { return fs::create_directories(dir / "cameras" / "middle"); }, "middle",
       "cameras/middle"},
      {"ground truth naming an unknown lidar",
       [](const fs::path& dir) { return Replace(dir / "ground_truth.yaml", "  rear:", "  front:"); },
       "ground_truth.yaml", "lidars.front"},
      {"ground truth of the wrong format",
       [](const fs::path& dir) { return Replace(dir / "ground_truth.yaml", "ground-truth/1", "ground-truth/7"); },
       "ground_truth.yaml", "format"},
      // FORMAT.md's sensor-folder rule: every sensor of rig.yaml has a folder with a data file.
      {"declared camera without a folder", [](const fs::path& dir) { return fs::remove_all(dir / "cameras" / "right") > 0; },
       "right", "cameras/right"},
      {"declared camera with an empty folder",
       [](const fs::path& dir) {
         return fs::remove(dir / "cameras" / "right" / "1200000.png") && fs::exists(dir / "cameras" / "right");
       },
       "right", "cameras/right"},
      {"declared lidar without a folder", [](const fs::path& dir) { return fs::remove_all(dir / "lidars" / "rear") > 0; },
       "rear", "lidars/rear"},
      {"no lidars folder at all", [](const fs::path& dir) { return fs::remove_all(dir / "lidars") > 0; }, "lidars",
       "lidars/rear"},
      {"sensor folder that is a symlink loop",
       [](const fs::path& dir) {
         fs::remove_all(dir / "cameras" / "right");
         fs::create_directory_symlink("right", dir / "cameras" / "right");
         return fs::is_symlink(dir / "cameras" / "right");
       },
       "right", "cameras"},
      {"data file that is a symlink loop",
       [](const fs::path& dir) {
         fs::create_symlink("1500000.bin", dir / "lidars" / "rear" / "1500000.bin");
         return fs::is_symlink(dir / "lidars" / "rear" / "1500000.bin");
       },
       "1500000.bin", "lidars"},
      {"rig.yaml that is a symlink loop",
       [](const fs::path& dir) {
         fs::remove(dir / "rig.yaml");
         fs::create_symlink("rig.yaml", dir / "rig.yaml");
         return fs::is_symlink(dir / "rig.yaml");
       },
       "rig.yaml", "file"},
      {"image area beyond the cap", rig("    width: 32\n    height: 24\n", "    width: 100000\n    height: 100000\n"),
       "rig.yaml", "cameras.left.width"},
  };
}

// OpenCalib import sources, broken one way each.
std::vector<BadCase> ImportCases() {
  const auto pcd = [](std::function<std::string(std::string)> edit) {
    return [edit](const fs::path& dir) {
      WriteFile(dir / "calib.pcd", edit(ReadFile(dir / "calib.pcd")));
      return true;
    };
  };
  const std::string pcd_name = "calib.pcd";
  return {
      {"PCD claims more points than the file holds",
       [](const fs::path& dir) {
         std::string text = PcdBinary(PcdTestPoints(100));
         text.resize(text.size() - 26 * 10);  // 90 points remain
         WriteFile(dir / "calib.pcd", text);
         return true;
       },
       pcd_name, "DATA binary"},
      {"LZF uncompressed size mismatch",
       pcd([](std::string text) {
         const std::size_t data = text.find("DATA binary_compressed\n") + std::string("DATA binary_compressed\n").size();
         std::uint32_t uncompressed = 0;
         std::memcpy(&uncompressed, text.data() + data + 4, 4);
         uncompressed += 26;
         std::memcpy(text.data() + data + 4, &uncompressed, 4);
         return text;
       }),
       pcd_name, "binary_compressed"},
      {"corrupt LZF stream",
       pcd([](std::string text) {
         const std::size_t data = text.find("DATA binary_compressed\n") + std::string("DATA binary_compressed\n").size();
         for (std::size_t i = data + 8; i < text.size(); ++i) text[i] = '\xff';
         return text;
       }),
       pcd_name, "binary_compressed"},
      {"absurd compressed size",
       pcd([](std::string text) {
         const std::size_t data = text.find("DATA binary_compressed\n") + std::string("DATA binary_compressed\n").size();
         const std::uint32_t huge = 0xFFFFFFF0u;
         std::memcpy(text.data() + data, &huge, 4);
         return text;
       }),
       pcd_name, "compressed size"},
      {"POINTS differs from WIDTH x HEIGHT",
       [](const fs::path& dir) {
         std::string text = PcdBinary(PcdTestPoints(10));
         text.replace(text.find("WIDTH 10"), 8, "WIDTH 12");
         WriteFile(dir / "calib.pcd", text);
         return true;
       },
       pcd_name, "POINTS"},
      {"PCD header without DATA",
       [](const fs::path& dir) {
         std::string header = PcdHeader(10, "binary");
         header.resize(header.find("DATA"));
         WriteFile(dir / "calib.pcd", header);
         return true;
       },
       pcd_name, "header"},
      {"PCD with a huge WIDTH",
       pcd([](std::string text) {
         text.replace(text.find("WIDTH 200"), 9, "WIDTH 99999999999999999999");
         return text;
       }),
       pcd_name, "WIDTH"},
      {"PCD without intensity",
       [](const fs::path& dir) {
         std::string text = PcdAscii(PcdTestPoints(3));
         text.replace(text.find("intensity"), 9, "rgb");
         WriteFile(dir / "calib.pcd", text);
         return true;
       },
       pcd_name, "FIELDS"},
      {"ASCII PCD with a bad value",
       [](const fs::path& dir) {
         std::string text = PcdAscii(PcdTestPoints(3));
         text.replace(text.rfind("\n", text.size() - 2) + 1, 1, "x");
         WriteFile(dir / "calib.pcd", text);
         return true;
       },
       pcd_name, "line"},
      {"missing calib.txt", [](const fs::path& dir) { return fs::remove(dir / "calib.txt"); }, "calib.txt",
       "missing"},
      {"K of 8 numbers",
       [](const fs::path& dir) { return Replace(dir / "calib.txt", "K: 60 0 31.5 0 60 23.5 0 0 1", "K: 60 0 31.5 0 60 23.5 0 0"); },
       "calib.txt", "K"},
      {"T not a rotation", [](const fs::path& dir) { return Replace(dir / "calib.txt", "T: 0.0188623", "T: 0.5188623"); },
       "calib.txt", "T"},
      {"missing image",
       [](const fs::path& dir) { return fs::remove(dir / "calib.png"); }, "calib.jpg", "image"},
  };
}

void ExpectMessageNames(const std::string& message, const BadCase& bad) {
  EXPECT_NE(message.find(bad.file), std::string::npos) << bad.name << ": message does not name the file: " << message;
  EXPECT_NE(message.find(bad.field), std::string::npos) << bad.name << ": message does not name the field: " << message;
  EXPECT_NE(message.find("expected"), std::string::npos) << bad.name << ": message does not say what was expected: "
                                                         << message;
}

void ExpectOneErrorLine(const std::string& stderr_text, const BadCase& bad) {
  std::size_t error_lines = 0;
  std::istringstream lines(stderr_text);
  for (std::string line; std::getline(lines, line);) error_lines += line.find("error") != std::string::npos;
  EXPECT_EQ(error_lines, 1u) << bad.name << ": stderr was: " << stderr_text;
}

TEST(BadInput, ValidDatasetPassesApiAndCli) {
  ASSERT_TRUE(fs::exists(SCENECAL_CLI_PATH)) << "build the scenecal target first";
  const TempDir temp;
  const fs::path dir = temp.path() / "dataset";
  WriteValidDataset(dir);
  const io::Dataset dataset = io::OpenDataset(dir);
  EXPECT_TRUE(io::SummariseDataset(dataset).can_calibrate);
  const CliRun run = RunCli("inspect '" + dir.string() + "'", temp.path());
  EXPECT_EQ(run.exit_code, 0) << run.stderr_text;
}

TEST(BadInput, EveryMalformedDatasetIsRejectedByApiAndCli) {
  ASSERT_TRUE(fs::exists(SCENECAL_CLI_PATH)) << "build the scenecal target first";
  const std::vector<BadCase> cases = DatasetCases();
  ASSERT_GE(cases.size(), 25u);
  const TempDir temp;
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const BadCase& bad = cases[i];
    SCOPED_TRACE(bad.name);
    const fs::path dir = temp.path() / ("case" + std::to_string(i));
    WriteValidDataset(dir);
    ASSERT_TRUE(bad.wreck(dir)) << "the edit did not apply";
    std::string message;
    try {
      const io::Dataset dataset = io::OpenDataset(dir);
      io::SummariseDataset(dataset);  // reads every image and scan
      ADD_FAILURE() << bad.name << ": accepted";
    } catch (const io::InputError& e) {
      message = e.what();
    }
    ExpectMessageNames(message, bad);
    const CliRun run = RunCli("inspect '" + dir.string() + "'", temp.path());
    EXPECT_TRUE(run.exited) << bad.name << ": killed by a signal";
    EXPECT_EQ(run.exit_code, 2) << bad.name << ": stderr: " << run.stderr_text;
    EXPECT_NE(run.stderr_text.find(bad.file), std::string::npos) << run.stderr_text;
    ExpectOneErrorLine(run.stderr_text, bad);
  }
}

TEST(BadInput, EveryMalformedImportSourceIsRejectedWithoutOutput) {
  ASSERT_TRUE(fs::exists(SCENECAL_CLI_PATH)) << "build the scenecal target first";
  const std::vector<BadCase> cases = ImportCases();
  const TempDir temp;
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const BadCase& bad = cases[i];
    SCOPED_TRACE(bad.name);
    const fs::path source = temp.path() / ("source" + std::to_string(i));
    WriteOpenCalibSource(source);
    ASSERT_TRUE(bad.wreck(source)) << "the edit did not apply";
    const fs::path output = temp.path() / ("out" + std::to_string(i));
    std::string message;
    try {
      io::ImportOpenCalib(source, output, false);
      ADD_FAILURE() << bad.name << ": accepted";
    } catch (const io::InputError& e) {
      message = e.what();
    }
    ExpectMessageNames(message, bad);
    EXPECT_FALSE(fs::exists(output));
    const CliRun run = RunCli("import opencalib '" + source.string() + "' --output '" + output.string() + "'",
                              temp.path());
    EXPECT_TRUE(run.exited);
    EXPECT_EQ(run.exit_code, 2) << run.stderr_text;
    EXPECT_NE(run.stderr_text.find(bad.file), std::string::npos) << run.stderr_text;
    ExpectOneErrorLine(run.stderr_text, bad);
    EXPECT_FALSE(fs::exists(output)) << "a failed import left its output";
  }
  // No temporary folders left beside the outputs either.
  for (const fs::directory_entry& entry : fs::directory_iterator(temp.path())) {
    EXPECT_NE(entry.path().filename().string().front(), '.') << entry.path();
  }
}

TEST(BadInput, ImportRefusesANonEmptyOutputUnlessForced) {
  ASSERT_TRUE(fs::exists(SCENECAL_CLI_PATH)) << "build the scenecal target first";
  const TempDir temp;
  const fs::path source = temp.path() / "source";
  WriteOpenCalibSource(source);
  const fs::path output = temp.path() / "out";
  WriteFile(output / "precious.txt", "keep me");
  const CliRun refused = RunCli("import opencalib '" + source.string() + "' --output '" + output.string() + "'",
                                temp.path());
  EXPECT_EQ(refused.exit_code, 2) << refused.stderr_text;
  EXPECT_TRUE(fs::exists(output / "precious.txt"));
  const CliRun forced = RunCli("import opencalib '" + source.string() + "' --output '" + output.string() + "' --force",
                               temp.path());
  EXPECT_EQ(forced.exit_code, 0) << forced.stderr_text;
  EXPECT_FALSE(fs::exists(output / "precious.txt"));
  EXPECT_NO_THROW(io::OpenDataset(output));
}

// An output that could not be written is refused before any work (exit 2,
// naming the path), never after a long run or as a crash.
TEST(BadInput, UnwritableOutputPathsAreRefusedBeforeAnyWork) {
  ASSERT_TRUE(fs::exists(SCENECAL_CLI_PATH)) << "build the scenecal target first";
  const TempDir temp;
  const fs::path dataset = temp.path() / "dataset";
  WriteValidDataset(dataset);
  const fs::path source = temp.path() / "source";
  WriteOpenCalibSource(source);
  WriteFile(temp.path() / "a_file", "not a folder");
  const std::string missing_folder = (temp.path() / "missing" / "result.yaml").string();
  const std::string under_a_file = (temp.path() / "a_file" / "out").string();
  const std::string dataset_arg = "'" + dataset.string() + "'";
  struct Case {
    std::string arguments, named;
  };
  const std::vector<Case> cases = {
      {"calibrate " + dataset_arg + " --output '" + missing_folder + "'", missing_folder},
      {"calibrate " + dataset_arg + " --output '" + under_a_file + "'", under_a_file},
      {"calibrate " + dataset_arg + " --output '" + temp.path().string() + "'", temp.path().string()},
      {"calibrate " + dataset_arg + " --output '" + (temp.path() / "r.yaml").string() + "' --report '" + under_a_file +
           "'",
       under_a_file},
      {"profile " + dataset_arg + " --output '" + missing_folder + "'", missing_folder},
      {"simulate --preset robotcar --output '" + under_a_file + "'", under_a_file},
      {"experiment --preset robotcar --output '" + under_a_file + "'", under_a_file},
      {"import opencalib '" + source.string() + "' --output '" + under_a_file + "'", under_a_file},
  };
  for (const Case& bad : cases) {
    SCOPED_TRACE(bad.arguments);
    const CliRun run = RunCli(bad.arguments, temp.path());
    EXPECT_TRUE(run.exited);
    EXPECT_EQ(run.exit_code, 2) << run.stderr_text;
    EXPECT_NE(run.stderr_text.find(bad.named), std::string::npos) << run.stderr_text;
    EXPECT_NE(run.stderr_text.find("--"), std::string::npos) << "the option is not named: " << run.stderr_text;
  }
  EXPECT_FALSE(fs::exists(temp.path() / "r.yaml"));
  EXPECT_FALSE(fs::exists(temp.path() / "missing"));
  // A read-only folder: root writes anyway, so this part needs another user.
  if (::geteuid() != 0) {
    const fs::path locked = temp.path() / "locked";
    fs::create_directories(locked);
    fs::permissions(locked, fs::perms::owner_read | fs::perms::owner_exec);
    const std::string result = (locked / "result.yaml").string();
    const CliRun run = RunCli("calibrate " + dataset_arg + " --output '" + result + "'", temp.path());
    fs::permissions(locked, fs::perms::owner_all);
    EXPECT_EQ(run.exit_code, 2) << run.stderr_text;
    EXPECT_NE(run.stderr_text.find("not writable"), std::string::npos) << run.stderr_text;
  }
}

// A --config file that is not what calibrate can read: exit 2 naming the file,
// the option and its line; nothing written.
TEST(BadInput, BadConfigFilesAreRefusedNamingTheFileAndTheOption) {
  ASSERT_TRUE(fs::exists(SCENECAL_CLI_PATH)) << "build the scenecal target first";
  const TempDir temp;
  const fs::path dataset = temp.path() / "dataset";
  WriteValidDataset(dataset);
  struct Case {
    std::string content, named;
  };
  const std::vector<Case> cases = {
      {"thin: 2\nthinn: 2\n", "line 2: thinn"},                 // not an option
      {"scenes: 4\nthin: -1\n", "line 2: thin"},                // a value the option refuses
      {"output: elsewhere.yaml\n", "output"},                     // paths go on the command line
      {"config: other.yaml\n", "config"},
      {"--thin: 2\n", "--thin"},
      {"thin: {cell: 2}\n", "thin"},
      {"thin: [2\n", "line"},
      {"setting: push-broom-wet\n", "setting"},
      {"format: scenecal-calibration/1\nlidars: {}\n", "options block"},
  };
  const fs::path result = temp.path() / "result.yaml";
  for (std::size_t i = 0; i < cases.size(); ++i) {
    SCOPED_TRACE(cases[i].content);
    const fs::path config = temp.path() / ("config_" + std::to_string(i) + ".yaml");
    WriteFile(config, cases[i].content);
    const CliRun run = RunCli("calibrate '" + dataset.string() + "' --output '" + result.string() + "' --config '" +
                                  config.string() + "'",
                              temp.path());
    EXPECT_TRUE(run.exited);
    EXPECT_EQ(run.exit_code, 2) << run.stderr_text;
    EXPECT_NE(run.stderr_text.find(config.string()), std::string::npos) << run.stderr_text;
    EXPECT_NE(run.stderr_text.find(cases[i].named), std::string::npos) << run.stderr_text;
    EXPECT_FALSE(fs::exists(result));
  }
  const CliRun missing = RunCli("calibrate '" + dataset.string() + "' --output '" + result.string() +
                                    "' --config '" + (temp.path() / "missing.yaml").string() + "'",
                                temp.path());
  EXPECT_EQ(missing.exit_code, 2) << missing.stderr_text;
  EXPECT_NE(missing.stderr_text.find("missing.yaml"), std::string::npos) << missing.stderr_text;
}

// A push-broom lidar on a drive shorter than its swathe: refused with the
// selection step that removed the frames, not blamed on the images.
TEST(BadInput, ShortDriveNamesTheSelectionStepForA2dLidar) {
  ASSERT_TRUE(fs::exists(SCENECAL_CLI_PATH)) << "build the scenecal target first";
  const TempDir temp;
  const fs::path dataset = temp.path() / "short";
  const CliRun simulated = RunCli("simulate --preset robotcar --seed 2 --image-size 160x120 --distance 6 --output '" +
                                      dataset.string() + "'",
                                  temp.path());
  ASSERT_EQ(simulated.exit_code, 0) << simulated.stderr_text;
  const CliRun run =
      RunCli("calibrate '" + dataset.string() + "' --output '" + (temp.path() / "r.yaml").string() + "'", temp.path());
  EXPECT_EQ(run.exit_code, 1) << run.stderr_text;
  for (const char* expected : {"standing still", "swathe window off the trajectory", "2d (push-broom)",
                               "--swathe-length"}) {
    EXPECT_NE(run.stderr_text.find(expected), std::string::npos) << expected << " in: " << run.stderr_text;
  }
  EXPECT_EQ(run.stderr_text.find("no scene with enough information"), std::string::npos) << run.stderr_text;
  EXPECT_FALSE(fs::exists(temp.path() / "r.yaml"));
}

TEST(BadInput, InspectSaysWhyDataCannotBeCalibrated) {
  ASSERT_TRUE(fs::exists(SCENECAL_CLI_PATH)) << "build the scenecal target first";
  const TempDir temp;
  const fs::path dir = temp.path() / "dataset";
  WriteValidDataset(dir);
  // Scans far (in time, hence beyond the trajectory) from every image.
  for (const char* name : {"1100000.bin", "1250000.bin", "1400000.bin"}) fs::remove(dir / "lidars" / "rear" / name);
  io::WriteScan(dir / "lidars" / "rear" / "9000000.bin", TestPoints(5, 0.0f));
  const io::DatasetSummary summary = io::SummariseDataset(io::OpenDataset(dir));
  EXPECT_FALSE(summary.can_calibrate);
  ASSERT_FALSE(summary.problems.empty());
  const CliRun run = RunCli("inspect '" + dir.string() + "'", temp.path());
  EXPECT_EQ(run.exit_code, 1) << run.stderr_text;
  EXPECT_NE(run.stderr_text.find("rear"), std::string::npos) << run.stderr_text;
  EXPECT_NE(run.stdout_text.find("cannot be calibrated"), std::string::npos) << run.stdout_text;
}

}  // namespace
}  // namespace scenecal
