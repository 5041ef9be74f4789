// Parser resource limits and non-finite numbers: every numeric field of every
// input format refuses NaN and +-infinity with an InputError naming the file
// and the field; absurd sizes (a PCD claiming 10^12 points, a huge .bin, a rig
// with a thousand cameras) are refused before anything is allocated from them.
// Runs the in-memory parsers (io::Parse*), so no files except for the .bin.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "io/dataset.hpp"
#include "io/kitti.hpp"
#include "io/opencalib.hpp"
#include "io/pcd.hpp"
#include "io_test_support.hpp"

namespace scenecal {
namespace {

using namespace scenecal::testing;

// A template marks each numeric field as {field=default}; `field` is what the
// error message must name (a "#n" suffix only tells equal names apart).
// Fill gives every field its default except `target`, which gets `value`.
std::string Fill(const std::string& text, const std::string& target, const std::string& value) {
  std::string out;
  std::size_t pos = 0;
  while (true) {
    const std::size_t open = text.find('{', pos);
    if (open == std::string::npos) break;
    const std::size_t equals = text.find('=', open);
    const std::size_t close = text.find('}', equals);
    out += text.substr(pos, open - pos);
    const std::string name = text.substr(open + 1, equals - open - 1);
    out += name == target ? value : text.substr(equals + 1, close - equals - 1);
    pos = close + 1;
  }
  return out + text.substr(pos);
}

std::vector<std::string> FieldNames(const std::string& text) {
  std::vector<std::string> names;
  for (std::size_t open = text.find('{'); open != std::string::npos; open = text.find('{', open + 1)) {
    names.push_back(text.substr(open + 1, text.find('=', open) - open - 1));
  }
  return names;
}

// "[{field[0]=a}, {field[1]=b}, ...]" for a YAML list.
std::string YamlList(const std::string& field, const std::vector<std::string>& values) {
  std::string out = "[";
  for (std::size_t i = 0; i < values.size(); ++i) {
    out += fmt::format("{}{{{}[{}]={}}}", i == 0 ? "" : ", ", field, i, values[i]);
  }
  return out + "]";
}

// A 4x4 rigid matrix, each element a field "field[row][col]".
std::string YamlMatrix(const std::string& field) {
  const char* rows[4][4] = {{"0", "-1", "0", "0.1"}, {"0", "0", "-1", "-0.2"}, {"1", "0", "0", "0.05"}, {"0", "0", "0", "1"}};
  std::string out = "[";
  for (int row = 0; row < 4; ++row) {
    std::vector<std::string> values(rows[row], rows[row] + 4);
    out += (row == 0 ? "" : ", ") + YamlList(fmt::format("{}[{}]", field, row), values);
  }
  return out + "]";
}

// Space-separated numbers, each a field named `field#i` (messages name the key's line).
std::string TextNumbers(const std::string& field, const std::vector<std::string>& values) {
  std::string out;
  for (std::size_t i = 0; i < values.size(); ++i) out += fmt::format(" {{{}#{}={}}}", field, i, values[i]);
  return out;
}

const std::vector<std::string> kSixNumbers = {"0.24", "0.01", "-0.02", "0.001", "0.002", "-0.003"};
const std::vector<std::string> kSigma = {"0.0005", "0.0005", "0.0005", "0.001", "0.001", "0.001"};
const std::vector<std::string> kRotation = {"0", "-1", "0", "0", "0", "-1", "1", "0", "0"};

struct Format {
  std::string name;
  std::string file;  // the name given to the parser, expected in messages
  std::string text;  // the template
  std::vector<std::string> bad_values;
  std::function<void(const std::string& text, const std::string& file)> parse;
};

std::vector<Format> Formats() {
  const std::vector<std::string> yaml_bad = {".nan", ".NaN", ".inf", "-.inf", "+.inf", "1e999", "nan", "inf"};
  const std::vector<std::string> text_bad = {"nan", "NaN", "inf", "-inf", "infinity", "1e999", "-1e999"};
  std::vector<Format> formats;
  formats.push_back(
      {"rig.yaml", "rig.yaml",
       "format: scenecal-dataset/1\nbase_frame: left\ncameras:\n  left:\n    width: 32\n    height: 24\n"
       "    model: radtan\n    intrinsics: " + YamlList("cameras.left.intrinsics", {"30", "31", "15.5", "11.5"}) +
           "\n    distortion: " + YamlList("cameras.left.distortion", {"0.01", "-0.002", "0.0001", "0.0002", "0.001"}) +
           "\n    T_base_camera: [0, 0, 0, 0, 0, 0]\n  right:\n    width: 32\n    height: 24\n    model: equidistant\n"
           "    intrinsics: [30, 30, 16, 12]\n    distortion: " +
           YamlList("cameras.right.distortion", {"0.01", "-0.002", "0.0003", "-0.00004"}) +
           "\n    T_base_camera: " + YamlList("cameras.right.T_base_camera", kSixNumbers) +
           "\n    T_base_camera_sigma: " + YamlList("cameras.right.T_base_camera_sigma", kSigma) +
           "\nlidars:\n  rear:\n    kind: 2d\n    T_base_lidar: " + YamlList("lidars.rear.T_base_lidar", kSixNumbers) +
           "\n  top:\n    kind: 3d\n    T_base_lidar: " + YamlMatrix("lidars.top.T_base_lidar") + "\n",
       yaml_bad, [](const std::string& text, const std::string& file) { io::ParseRig(text, file); }});
  formats.push_back({"ground_truth.yaml", "ground_truth.yaml",
                     "format: scenecal-ground-truth/1\nlidars:\n  rear:\n    T_base_lidar: " +
                         YamlList("lidars.rear.T_base_lidar", kSixNumbers) + "\ncameras:\n  right:\n    T_base_camera: " +
                         YamlMatrix("cameras.right.T_base_camera") + "\n",
                     yaml_bad, [](const std::string& text, const std::string& file) { io::ParseGroundTruth(text, file); }});
  formats.push_back(
      {"result", "result.yaml",
       "format: scenecal-calibration/1\nlidars:\n  rear:\n    T_base_lidar: " + YamlList("lidars.rear.T_base_lidar", kSixNumbers) +
           "\n    sigma: " + YamlList("lidars.rear.sigma", kSigma) + "\n  top:\n    T_base_lidar: " +
           YamlMatrix("lidars.top.T_base_lidar") + "\npairs:\n  - camera: left\n    lidar: rear\n    T_camera_lidar: " +
           YamlList("pairs[0].T_camera_lidar", kSixNumbers) + "\n    cost: 0.5\ntimings_s:\n  total: {timings_s.total=1.5}\n",
       yaml_bad, [](const std::string& text, const std::string& file) { io::ParseCalibrationResult(text, file); }});
  formats.push_back({"trajectory.csv", "trajectory.csv",
                     "timestamp_us,x,y,z,qx,qy,qz,qw\n0,{line 2 x=1},{line 2 y=2},{line 2 z=3},{line 2 qx=0},"
                     "{line 2 qy=0},{line 2 qz=0},{line 2 qw=1}\n10,0,0,0,0,0,0,1\n",
                     text_bad, [](const std::string& text, const std::string& file) { io::ParseTrajectory(text, file); }});
  formats.push_back({"OpenCalib calib.txt", "calib.txt",
                     "K:" + TextNumbers("line 1 K", {"1000", "0", "640", "0", "1000", "360", "0", "0", "1"}) +
                         "\nD:" + TextNumbers("line 2 D", {"-0.1", "0.16", "0.0007", "0.0014", "0.001"}) + "\nT:" +
                         TextNumbers("line 3 T", {"0", "-1", "0", "0.1", "0", "0", "-1", "-0.4", "1", "0", "0", "-0.09"}) + "\n",
                     text_bad,
                     [](const std::string& text, const std::string& file) { io::ParseOpenCalibCalibration(text, file); }});
  std::string cam_to_cam = "calib_time: 09-Jan-2012 13:57:47\nR_rect_00:" +
                           TextNumbers("line 2 R_rect_00", {"1", "0", "0", "0", "1", "0", "0", "0", "1"}) + "\n";
  for (int camera = 0; camera < 4; ++camera) {
    cam_to_cam += fmt::format("P_rect_0{}:", camera) +
                  TextNumbers(fmt::format("line {} P_rect_0{}", camera + 3, camera),
                              {"721.5", "0", "609.6", "-387.6", "0", "721.5", "172.9", "0.2", "0", "0", "1", "0.003"}) +
                  "\n";
  }
  formats.push_back({"KITTI calib_cam_to_cam.txt", "calib_cam_to_cam.txt", cam_to_cam, text_bad,
                     [](const std::string& text, const std::string& file) {
                       io::KittiCalibration calibration;
                       io::ParseKittiCamToCam(text, file, {0, 1, 2, 3}, &calibration);
                     }});
  formats.push_back({"KITTI calib_velo_to_cam.txt", "calib_velo_to_cam.txt",
                     "calib_time: 15-Mar-2012 11:37:16\nR:" + TextNumbers("line 2 R", kRotation) + "\nT:" +
                         TextNumbers("line 3 T", {"-0.004", "-0.076", "-0.27"}) + "\n",
                     text_bad, [](const std::string& text, const std::string& file) {
                       io::ParseKittiRigidTransform(text, file, "velodyne to camera 0");
                     }});
  std::string oxts;
  for (int i = 1; i <= 30; ++i) {
    static const char* const kNames[] = {"lat", "lon", "alt", "roll", "pitch", "yaw"};
    const std::string field = i <= 6 ? fmt::format("value {} ({})", i, kNames[i - 1]) : fmt::format("value {}:", i);
    oxts += fmt::format("{}{{{}={}}}", i == 1 ? "" : " ", field, i == 1 ? "49.01" : i == 2 ? "8.43" : "0.5");
  }
  formats.push_back({"KITTI OXTS record", "0000000000.txt", oxts + "\n", text_bad,
                     [](const std::string& text, const std::string& file) { io::ParseKittiOxts(text, file); }});
  formats.push_back({"PCD VIEWPOINT", "cloud.pcd",
                     "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\nVIEWPOINT" +
                         TextNumbers("header line 8 (VIEWPOINT)", {"0", "0", "0", "1", "0", "0", "0"}) +
                         "\nPOINTS 1\nDATA ascii\n1 2 3\n",
                     text_bad, [](const std::string& text, const std::string& file) { io::ParsePcd(text, file); }});
  return formats;
}

std::string Expected(const std::string& field) {
  const std::size_t hash = field.find('#');
  return hash == std::string::npos ? field : field.substr(0, hash);
}

TEST(ParserLimits, TemplatesAreValidWithTheirDefaults) {
  for (const Format& format : Formats()) {
    SCOPED_TRACE(format.name);
    EXPECT_NO_THROW(format.parse(Fill(format.text, "", ""), format.file));
    EXPECT_GE(FieldNames(format.text).size(), 3u);
  }
}

TEST(ParserLimits, NonFiniteNumbersAreRefusedInEveryNumericField) {
  std::size_t cases = 0;
  for (const Format& format : Formats()) {
    for (const std::string& field : FieldNames(format.text)) {
      for (const std::string& bad : format.bad_values) {
        SCOPED_TRACE(format.name + ": " + field + " = " + bad);
        ++cases;
        try {
          format.parse(Fill(format.text, field, bad), format.file);
          ADD_FAILURE() << "accepted";
        } catch (const io::InputError& e) {
          const std::string message = e.what();
          EXPECT_NE(message.find(format.file), std::string::npos) << message;
          EXPECT_NE(message.find(Expected(field)), std::string::npos) << message;
        }
      }
    }
  }
  EXPECT_GT(cases, 1000u);
}

TEST(ParserLimits, ResultCostMayBeNanButNotInfinite) {
  const std::string result = "format: scenecal-calibration/1\nlidars: {}\npairs:\n  - camera: left\n    lidar: rear\n"
                             "    T_camera_lidar: [0, 0, 0, 0, 0, 0]\n    cost: ";
  EXPECT_TRUE(std::isnan(io::ParseCalibrationResult(result + ".nan\n", "result.yaml").pairs.at(0).cost));
  for (const char* bad : {".inf", "-.inf"}) {
    SCOPED_TRACE(bad);
    try {
      io::ParseCalibrationResult(result + bad + "\n", "result.yaml");
      ADD_FAILURE() << "accepted";
    } catch (const io::InputError& e) {
      EXPECT_NE(std::string(e.what()).find("pairs[0].cost"), std::string::npos) << e.what();
    }
  }
}

std::string RigWithSensors(std::size_t cameras, std::size_t lidars) {
  std::string text = "format: scenecal-dataset/1\nbase_frame: c0\ncameras:\n";
  for (std::size_t i = 0; i < cameras; ++i) {
    text += fmt::format("  c{}: {{width: 32, height: 24, model: pinhole, intrinsics: [30, 30, 16, 12], distortion: [], "
                        "T_base_camera: [{}, 0, 0, 0, 0, 0]}}\n", i, i == 0 ? 0.0 : 0.1 * static_cast<double>(i));
  }
  text += "lidars:\n";
  for (std::size_t i = 0; i < lidars; ++i) {
    text += fmt::format("  l{}: {{kind: 3d, T_base_lidar: [1, 0, {}, 0, 0, 0]}}\n", i, 0.1 * static_cast<double>(i));
  }
  return text;
}

TEST(ParserLimits, RigSensorCountsAreCapped) {
  EXPECT_EQ(io::ParseRig(RigWithSensors(io::kMaxRigCameras, io::kMaxRigLidars), "rig.yaml").cameras.size(),
            io::kMaxRigCameras);
  const struct {
    std::size_t cameras, lidars;
    std::string field;
  } cases[] = {{io::kMaxRigCameras + 1, 1, "cameras"}, {1, io::kMaxRigLidars + 1, "lidars"}, {1000, 1, "cameras"}};
  for (const auto& bad : cases) {
    SCOPED_TRACE(bad.field + " " + std::to_string(bad.cameras) + " " + std::to_string(bad.lidars));
    try {
      io::ParseRig(RigWithSensors(bad.cameras, bad.lidars), "rig.yaml");
      ADD_FAILURE() << "accepted";
    } catch (const io::InputError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("rig.yaml: " + bad.field), std::string::npos) << message;
      EXPECT_NE(message.find("at most 64"), std::string::npos) << message;
    }
  }
  // A million cameras (~11 MB) are refused by the file's size, before
  // yaml-cpp would spend seconds and hundreds of MB parsing them.
  std::string million = "format: scenecal-dataset/1\nbase_frame: c0\ncameras:\n";
  for (int i = 0; i < 1000000; ++i) million += fmt::format("  c{}: 0\n", i);
  try {
    io::ParseRig(million, "rig.yaml");
    ADD_FAILURE() << "accepted";
  } catch (const io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("rig.yaml: file: " + std::to_string(million.size()) + " bytes"), std::string::npos)
        << e.what();
  }
}

// yaml-cpp stops at 2000 levels of nesting (no stack overflow); the message says so.
TEST(ParserLimits, DeeplyNestedYamlIsRefusedWithAClearMessage) {
  std::string maps;
  for (int i = 0; i < 5000; ++i) maps += "{a: ";
  maps += "1" + std::string(5000, '}');
  for (const std::string& nested : {std::string(5000, '[') + std::string(5000, ']'), maps}) {
    try {
      io::ParseGroundTruth("format: " + nested + "\n", "ground_truth.yaml");
      ADD_FAILURE() << "accepted";
    } catch (const io::InputError& e) {
      EXPECT_NE(std::string(e.what()).find("ground_truth.yaml: line 1: lists or mappings nested"), std::string::npos)
          << e.what();
    }
  }
}

TEST(ParserLimits, PcdClaimingAbsurdPointCountsIsRefusedInEveryEncoding) {
  const std::string header_start = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n";
  const struct {
    std::string width, height, points;
  } claims[] = {{"1000000000000", "1", "1000000000000"},
                {"1000000", "1000000", "1000000000000"},
                {"1", "1000000000000", "1000000000000"},
                {"18446744073709551615", "1", "18446744073709551615"},
                {"4294967296", "4294967296", "1"}};
  for (const std::string& encoding : std::vector<std::string>{"ascii", "binary", "binary_compressed"}) {
    for (const auto& claim : claims) {
      SCOPED_TRACE(encoding + " " + claim.width + " x " + claim.height);
      std::string data = "1 2 3\n";
      if (encoding == "binary_compressed") data = std::string("\x04\0\0\0\xff\xff\xff\xff", 8) + "\x03" "abcd";
      const std::string text = header_start + "WIDTH " + claim.width + "\nHEIGHT " + claim.height + "\nPOINTS " +
                               claim.points + "\nDATA " + encoding + "\n" + data;
      try {
        io::ParsePcd(text, "cloud.pcd");
        ADD_FAILURE() << "accepted";
      } catch (const io::InputError& e) {
        EXPECT_NE(std::string(e.what()).find("cloud.pcd"), std::string::npos) << e.what();
      }
    }
  }
}

TEST(ParserLimits, AbsurdScanFileSizesAreRefusedBeforeReading) {
  const TempDir temp;
  for (const std::uintmax_t size : {(std::uintmax_t{1} << 30) + 16, (std::uintmax_t{1} << 40), std::uintmax_t{17}}) {
    SCOPED_TRACE(size);
    const fs::path path = temp.path() / "100.bin";
    WriteFile(path, "");
    fs::resize_file(path, size);  // sparse: no disk used
    try {
      io::ReadScan({100, path});
      ADD_FAILURE() << "accepted";
    } catch (const io::InputError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("100.bin"), std::string::npos) << message;
      EXPECT_NE(message.find(std::to_string(size) + " bytes"), std::string::npos) << message;
    }
    fs::remove(path);
  }
}

}  // namespace
}  // namespace scenecal
