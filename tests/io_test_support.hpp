// Test helpers for the io tests: a small valid dataset written as text, file
// edits to break it, PCD writers, and running the CLI.
#pragma once

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <lzf.h>
#include <opencv2/imgcodecs.hpp>

#include "core/rig.hpp"
#include "io/dataset.hpp"

namespace scenecal::testing {

namespace fs = std::filesystem;

// A fresh, unique folder under the system temp dir, removed at destruction.
class TempDir {
 public:
  TempDir() {
    std::random_device entropy;
    path_ = fs::temp_directory_path() / ("scenecal_io_test_" + std::to_string(entropy()) + std::to_string(entropy()));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

inline std::string ReadFile(const fs::path& path) {
  std::ifstream stream(path, std::ios::binary);
  std::ostringstream content;
  content << stream.rdbuf();
  return content.str();
}

inline void WriteFile(const fs::path& path, const std::string& content) {
  fs::create_directories(path.parent_path());
  std::ofstream stream(path, std::ios::binary | std::ios::trunc);
  stream << content;
}

// Replaces the first occurrence of `from` (which must exist) in the file.
inline bool ReplaceInFile(const fs::path& path, const std::string& from, const std::string& to) {
  std::string content = ReadFile(path);
  const std::size_t pos = content.find(from);
  if (pos == std::string::npos) return false;
  content.replace(pos, from.size(), to);
  WriteFile(path, content);
  return true;
}

constexpr char kValidRig[] = R"(format: scenecal-dataset/1
base_frame: left
cameras:
  left:
    width: 32
    height: 24
    model: pinhole
    intrinsics: [30, 30, 15.5, 11.5]
    distortion: []
    T_base_camera: [0, 0, 0, 0, 0, 0]
  right:
    width: 32
    height: 24
    model: radtan
    intrinsics: [30, 31, 16, 12]
    distortion: [0.01, -0.002, 0.0001, 0.0002]
    T_base_camera: [0.24, 0, 0, 0, 0, 0]
    T_base_camera_sigma: [0.0005, 0.0005, 0.0005, 0.001, 0.001, 0.001]
lidars:
  rear:
    kind: 2d
    T_base_lidar: [-2.6, 0.3, 1.1, -2.84, -1.51, -0.36]
extra:
  note: anything goes here
  nested: {a: [1, 2]}
)";

// 1 m/s along x for 0.5 s.
constexpr char kValidTrajectory[] = R"(timestamp_us,x,y,z,qx,qy,qz,qw
1000000,0,0,0,0,0,0,1
1100000,0.1,0,0,0,0,0,1
1200000,0.2,0,0,0,0,0.0499792,0.9987503
1300000,0.3,0,0,0,0,0,1
1400000,0.4,0,0,0,0,0,1
1500000,0.5,0,0,0,0,0,1
)";

constexpr char kValidGroundTruth[] = R"(format: scenecal-ground-truth/1
lidars:
  rear:
    T_base_lidar: [-2.61, 0.31, 1.1, -2.84, -1.51, -0.36]
)";

inline cv::Mat TestPattern(int width, int height, int type) {
  cv::Mat image(height, width, type);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(CV_MAT_DEPTH(type) == CV_16U ? 65535 : 255));
  return image;
}

inline std::vector<LidarPoint> TestPoints(std::size_t count, float offset) {
  std::vector<LidarPoint> points;
  for (std::size_t i = 0; i < count; ++i) {
    const float f = static_cast<float>(i);
    points.push_back({offset + f, -f * 0.5f, 0.0f, f * 3.0f});
  }
  return points;
}

// Writes a small valid dataset: cameras left (2 grey PNGs) and right (1 colour
// PNG), lidar rear (3 scans), trajectory, ground truth.
inline void WriteValidDataset(const fs::path& root) {
  WriteFile(root / "rig.yaml", kValidRig);
  WriteFile(root / "trajectory.csv", kValidTrajectory);
  WriteFile(root / "ground_truth.yaml", kValidGroundTruth);
  fs::create_directories(root / "cameras" / "left");
  fs::create_directories(root / "cameras" / "right");
  fs::create_directories(root / "lidars" / "rear");
  cv::imwrite((root / "cameras" / "left" / "1100000.png").string(), TestPattern(32, 24, CV_8UC1));
  cv::imwrite((root / "cameras" / "left" / "1300000.png").string(), TestPattern(32, 24, CV_16UC1));
  cv::imwrite((root / "cameras" / "right" / "1200000.png").string(), TestPattern(32, 24, CV_8UC3));
  io::WriteScan(root / "lidars" / "rear" / "1100000.bin", TestPoints(10, 1.0f));
  io::WriteScan(root / "lidars" / "rear" / "1250000.bin", TestPoints(12, 2.0f));
  io::WriteScan(root / "lidars" / "rear" / "1400000.bin", TestPoints(14, 3.0f));
}

// ---- PCD -------------------------------------------------------------------

struct PcdTestPoint {
  float x, y, z, intensity;
  std::uint16_t ring;
  double timestamp;
};

inline std::vector<PcdTestPoint> PcdTestPoints(std::size_t count) {
  std::vector<PcdTestPoint> points;
  for (std::size_t i = 0; i < count; ++i) {
    const float f = static_cast<float>(i);
    points.push_back({0.25f * f, -1.5f + f, 2.0f + 0.125f * f, 7.0f * f, static_cast<std::uint16_t>(i % 32),
                      1.5e9 + 0.001 * static_cast<double>(i)});
  }
  return points;
}

inline std::string PcdHeader(std::size_t points, const std::string& data, std::size_t width_override = 0) {
  const std::size_t width = width_override != 0 ? width_override : points;
  return "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z intensity ring timestamp\n"
         "SIZE 4 4 4 4 2 8\nTYPE F F F F U F\nCOUNT 1 1 1 1 1 1\nWIDTH " +
         std::to_string(width) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(points) +
         "\nDATA " + data + "\n";
}

template <typename T>
void AppendBytes(std::string* out, const T& value) {
  out->append(reinterpret_cast<const char*>(&value), sizeof(T));
}

inline std::string PcdAscii(const std::vector<PcdTestPoint>& points) {
  std::string out = PcdHeader(points.size(), "ascii");
  for (const PcdTestPoint& p : points) {
    char line[256];
    std::snprintf(line, sizeof(line), "%.9g %.9g %.9g %.9g %u %.17g\n", p.x, p.y, p.z, p.intensity,
                  static_cast<unsigned>(p.ring), p.timestamp);
    out += line;
  }
  return out;
}

inline std::string PcdBinary(const std::vector<PcdTestPoint>& points) {
  std::string out = PcdHeader(points.size(), "binary");
  for (const PcdTestPoint& p : points) {
    AppendBytes(&out, p.x);
    AppendBytes(&out, p.y);
    AppendBytes(&out, p.z);
    AppendBytes(&out, p.intensity);
    AppendBytes(&out, p.ring);
    AppendBytes(&out, p.timestamp);
  }
  return out;
}

// binary_compressed: field-major raw data, LZF-compressed by liblzf.
inline std::string PcdBinaryCompressed(const std::vector<PcdTestPoint>& points) {
  std::string raw;
  for (const PcdTestPoint& p : points) AppendBytes(&raw, p.x);
  for (const PcdTestPoint& p : points) AppendBytes(&raw, p.y);
  for (const PcdTestPoint& p : points) AppendBytes(&raw, p.z);
  for (const PcdTestPoint& p : points) AppendBytes(&raw, p.intensity);
  for (const PcdTestPoint& p : points) AppendBytes(&raw, p.ring);
  for (const PcdTestPoint& p : points) AppendBytes(&raw, p.timestamp);
  std::string compressed(raw.size() + raw.size() / 16 + 64, '\0');
  const unsigned int compressed_size =
      lzf_compress(raw.data(), static_cast<unsigned int>(raw.size()), compressed.data(),
                   static_cast<unsigned int>(compressed.size()));
  compressed.resize(compressed_size);
  std::string out = PcdHeader(points.size(), "binary_compressed");
  AppendBytes(&out, static_cast<std::uint32_t>(compressed_size));
  AppendBytes(&out, static_cast<std::uint32_t>(raw.size()));
  return out + compressed;
}

constexpr char kOpenCalibTxt[] =
    "K: 60 0 31.5 0 60 23.5 0 0 1\n"
    "D: -0.1192 0.162 0.00073985 0.0014\n"
    "T: 0.0188623 -0.999822 -9.36529e-05 -0.0323222 0.0288601 0.000638227 -0.999583 -0.396685 0.999405 "
    "0.0188516 0.028867 -0.0869361\n";

// A small OpenCalib source folder: calib.txt, calib.png (64x48), calib.pcd.
inline void WriteOpenCalibSource(const fs::path& dir) {
  WriteFile(dir / "calib.txt", kOpenCalibTxt);
  cv::imwrite((dir / "calib.png").string(), TestPattern(64, 48, CV_8UC3));
  WriteFile(dir / "calib.pcd", PcdBinaryCompressed(PcdTestPoints(200)));
}

// ---- CLI ---------------------------------------------------------------------

struct CliRun {
  bool exited = false;  // false: killed by a signal
  int exit_code = -1;
  std::string stdout_text;
  std::string stderr_text;
};

inline CliRun RunCli(const std::string& arguments, const fs::path& scratch) {
  const fs::path out = scratch / "cli_stdout.txt";
  const fs::path err = scratch / "cli_stderr.txt";
  const std::string command =
      std::string("'") + SCENECAL_CLI_PATH + "' " + arguments + " >'" + out.string() + "' 2>'" + err.string() + "'";
  const int status = std::system(command.c_str());
  CliRun run;
  run.exited = WIFEXITED(status);
  run.exit_code = run.exited ? WEXITSTATUS(status) : -1;
  run.stdout_text = ReadFile(out);
  run.stderr_text = ReadFile(err);
  fs::remove(out);
  fs::remove(err);
  return run;
}

}  // namespace scenecal::testing
