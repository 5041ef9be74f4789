#include "io/dataset.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <regex>
#include <set>
#include <system_error>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <yaml-cpp/yaml.h>
#include <zlib.h>

#include "io/yaml_fields.hpp"

namespace scenecal::io {

namespace fs = std::filesystem;
using detail::Fail;
using detail::FormatNumber;
using detail::YamlReader;

static_assert(std::endian::native == std::endian::little,
              "scan files are little-endian float32; a big-endian host would need byte swapping");

namespace {

constexpr char kRigFormat[] = "scenecal-dataset/1";
constexpr char kGroundTruthFormat[] = "scenecal-ground-truth/1";
constexpr char kResultFormat[] = "scenecal-calibration/1";
constexpr char kTrajectoryHeader[] = "timestamp_us,x,y,z,qx,qy,qz,qw";
// Largest image or scan file read whole into memory (bytes); larger is refused
// as certainly not a frame of this format.
constexpr std::size_t kMaxDataFileBytes = std::size_t{1} << 30;
// Largest ground_truth.yaml or result file read (bytes).
constexpr std::size_t kMaxYamlFileBytes = std::size_t{64} << 20;
// Largest rig.yaml (bytes): 64 cameras and 64 lidars take ~30 KB, so this
// leaves room for `extra:` while a file of a million sensors is refused
// before yaml-cpp spends seconds and hundreds of MB on it.
constexpr std::size_t kMaxRigFileBytes = std::size_t{4} << 20;

bool IsIdentity(const Eigen::Isometry3d& transform, double tolerance) {
  return (transform.matrix() - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff() <= tolerance;
}

std::string Lowercase(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return std::tolower(c); });
  return text;
}

std::string ReadBinaryFile(const fs::path& path, std::size_t max_bytes) {
  return detail::ReadTextFile(path, max_bytes);  // same checks; the content is bytes either way
}

void WriteBinaryFile(const fs::path& path, const void* data, std::size_t size) {
  std::ofstream stream(path, std::ios::binary | std::ios::trunc);
  if (stream) stream.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
  stream.close();
  if (!stream) throw std::runtime_error("cannot write " + path.string());
}

// ---- rig.yaml --------------------------------------------------------------

CameraInfo ParseCamera(const YamlReader& yaml, const std::string& name, const YAML::Node& node) {
  const std::string field = "cameras." + name;
  yaml.CheckKeys(node, field,
                 {"width", "height", "model", "intrinsics", "distortion", "T_base_camera", "T_base_camera_sigma"});
  CameraInfo camera;
  camera.name = name;
  CameraModel& model = camera.model;
  for (const char* key : {"width", "height"}) {
    const YAML::Node value = yaml.Required(node, field, key);
    const long long pixels = yaml.Integer(value, field + "." + key);
    if (pixels <= 0 || pixels > 1'000'000) {
      yaml.Fail(value, field + "." + key, fmt::format("{}", pixels), "a positive number of pixels (at most 1000000)");
    }
    (std::string(key) == "width" ? model.width : model.height) = static_cast<int>(pixels);
  }
  // Each image is decoded whole and the cost keeps it as float: cap the area
  // (a 16384 x 16384 image, 1 GiB as float) so that an absurd size is refused
  // here rather than by the out-of-memory killer.
  constexpr long long kMaxImagePixels = 1LL << 28;
  if (static_cast<long long>(model.width) * model.height > kMaxImagePixels) {
    yaml.Fail(node["width"], field + ".width", fmt::format("{} x {} pixels", model.width, model.height),
              fmt::format("at most {} pixels in all", kMaxImagePixels));
  }
  const YAML::Node model_node = yaml.Required(node, field, "model");
  if (!ParseCameraModelKind(yaml.String(model_node, field + ".model"), &model.kind)) {
    yaml.Fail(model_node, field + ".model", "found " + detail::Describe(model_node), "pinhole, radtan or equidistant");
  }
  const YAML::Node intrinsics_node = yaml.Required(node, field, "intrinsics");
  const std::vector<double> intrinsics = yaml.Numbers(intrinsics_node, field + ".intrinsics");
  if (intrinsics.size() != 4) {
    yaml.Fail(intrinsics_node, field + ".intrinsics", fmt::format("{} numbers", intrinsics.size()),
              "4 numbers [fx, fy, cx, cy] (pixels)");
  }
  model.fx = intrinsics[0];
  model.fy = intrinsics[1];
  model.cx = intrinsics[2];
  model.cy = intrinsics[3];
  const YAML::Node distortion_node = yaml.Required(node, field, "distortion");
  model.distortion = yaml.Numbers(distortion_node, field + ".distortion");
  std::string why;
  if (!model.IsValid(&why)) {
    const bool distortion_problem = why.find("distortion") != std::string::npos;
    yaml.Fail(distortion_problem ? distortion_node : node, field + (distortion_problem ? ".distortion" : ""),
              "invalid camera: " + why,
              "radtan: [k1, k2, p1, p2] or [k1, k2, p1, p2, k3]; equidistant: [k1, k2, k3, k4]; pinhole: []; "
              "positive focal lengths");
  }
  camera.T_base_camera = yaml.Transform(yaml.Required(node, field, "T_base_camera"), field + ".T_base_camera");
  const YAML::Node& const_node = node;
  if (const YAML::Node sigma = const_node["T_base_camera_sigma"]; sigma.IsDefined()) {
    camera.T_base_camera_sigma = yaml.Sigma(sigma, field + ".T_base_camera_sigma");
  }
  return camera;
}

LidarInfo ParseLidar(const YamlReader& yaml, const std::string& name, const YAML::Node& node) {
  const std::string field = "lidars." + name;
  yaml.CheckKeys(node, field, {"kind", "T_base_lidar"});
  LidarInfo lidar;
  lidar.name = name;
  const YAML::Node kind_node = yaml.Required(node, field, "kind");
  const std::string kind = yaml.String(kind_node, field + ".kind");
  if (kind == "2d") {
    lidar.kind = LidarKind::k2d;
  } else if (kind == "3d") {
    lidar.kind = LidarKind::k3d;
  } else {
    yaml.Fail(kind_node, field + ".kind", "found '" + kind + "'", "2d or 3d");
  }
  lidar.T_base_lidar = yaml.Transform(yaml.Required(node, field, "T_base_lidar"), field + ".T_base_lidar");
  return lidar;
}

// Sensor names of a cameras:/lidars: mapping, checked, in file order.
template <typename Parse>
void ParseSensors(const YamlReader& yaml, const YAML::Node& map, const std::string& field, std::size_t max_sensors,
                  std::set<std::string>* names, Parse parse) {
  yaml.RequireMap(map, field);
  if (map.size() == 0) yaml.Fail(map, field, "no sensors", "at least one");
  if (map.size() > max_sensors) {
    yaml.Fail(map, field, fmt::format("{} sensors", map.size()), fmt::format("at most {}", max_sensors));
  }
  for (const auto& entry : map) {
    if (!entry.first.IsScalar()) yaml.Fail(entry.first, field, "a key that is " + detail::Describe(entry.first), "a name");
    const std::string name = entry.first.Scalar();
    if (!IsValidSensorName(name)) {
      yaml.Fail(entry.first, field + "." + name, "invalid name '" + name + "'", "a name of [A-Za-z0-9_-]+");
    }
    if (!names->insert(name).second) {
      yaml.Fail(entry.first, field + "." + name, "duplicate sensor name '" + name + "'",
                "names unique across cameras and lidars");
    }
    parse(name, entry.second);
  }
}

std::string RigToYaml(const Rig& rig, const YAML::Node* extra) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kRigFormat;
  out << YAML::Key << "base_frame" << YAML::Value << rig.base_frame;
  out << YAML::Key << "cameras" << YAML::Value << YAML::BeginMap;
  for (const CameraInfo& camera : rig.cameras) {
    const CameraModel& model = camera.model;
    out << YAML::Key << camera.name << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "width" << YAML::Value << model.width;
    out << YAML::Key << "height" << YAML::Value << model.height;
    out << YAML::Key << "model" << YAML::Value << CameraModelKindName(model.kind);
    const double intrinsics[4] = {model.fx, model.fy, model.cx, model.cy};
    out << YAML::Key << "intrinsics" << YAML::Value;
    detail::EmitNumbers(out, intrinsics, 4);
    out << YAML::Key << "distortion" << YAML::Value;
    detail::EmitNumbers(out, model.distortion.data(), model.distortion.size());
    out << YAML::Key << "T_base_camera" << YAML::Value;
    detail::EmitTransform(out, camera.T_base_camera);
    if (camera.T_base_camera_sigma) {
      out << YAML::Key << "T_base_camera_sigma" << YAML::Value;
      detail::EmitNumbers(out, camera.T_base_camera_sigma->data(), 6);
    }
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  out << YAML::Key << "lidars" << YAML::Value << YAML::BeginMap;
  for (const LidarInfo& lidar : rig.lidars) {
    out << YAML::Key << lidar.name << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "kind" << YAML::Value << (lidar.kind == LidarKind::k2d ? "2d" : "3d");
    out << YAML::Key << "T_base_lidar" << YAML::Value;
    detail::EmitTransform(out, lidar.T_base_lidar);
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  if (extra != nullptr && extra->IsDefined() && !extra->IsNull()) {
    if (!extra->IsMap()) throw std::invalid_argument("WriteRig: extra must be a YAML mapping");
    out << YAML::Key << "extra" << YAML::Value << *extra;
  }
  out << YAML::EndMap;
  if (!out.good()) throw std::runtime_error("WriteRig: YAML emitter error: " + out.GetLastError());
  return std::string(out.c_str()) + "\n";
}

// ---- trajectory.csv ----------------------------------------------------------

std::string_view Trim(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t' || text.back() == '\r')) text.remove_suffix(1);
  return text;
}

template <typename T>
bool ParseWhole(std::string_view text, T* value) {
  text = Trim(text);
  return !text.empty() && detail::ParseWholeToken(text, value);
}

// ---- images ------------------------------------------------------------------

std::uint32_t BigEndian32(const unsigned char* bytes) {
  return (std::uint32_t{bytes[0]} << 24) | (std::uint32_t{bytes[1]} << 16) | (std::uint32_t{bytes[2]} << 8) |
         std::uint32_t{bytes[3]};
}

// (width, height) from a PNG IHDR or a JPEG SOF marker, without decoding; lets
// ReadImage reject a wrong size (or an absurd claimed size) before OpenCV
// allocates the image.
std::optional<std::pair<int, int>> ImageSizeFromHeader(const std::string& bytes) {
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const std::size_t size = bytes.size();
  static constexpr unsigned char kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (size >= 24 && std::memcmp(data, kPngSignature, 8) == 0 && std::memcmp(data + 12, "IHDR", 4) == 0) {
    const std::uint32_t width = BigEndian32(data + 16);
    const std::uint32_t height = BigEndian32(data + 20);
    if (width == 0 || height == 0 || width > 1u << 30 || height > 1u << 30) return std::nullopt;
    return std::make_pair(static_cast<int>(width), static_cast<int>(height));
  }
  if (size >= 4 && data[0] == 0xFF && data[1] == 0xD8) {
    std::size_t pos = 2;
    while (pos + 4 <= size) {
      if (data[pos] != 0xFF) return std::nullopt;
      const unsigned char marker = data[pos + 1];
      if (marker == 0xFF) {  // fill byte
        ++pos;
        continue;
      }
      if (marker == 0xD8 || marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) {  // no length
        pos += 2;
        continue;
      }
      const std::size_t length = (std::size_t{data[pos + 2]} << 8) | data[pos + 3];
      const bool start_of_frame = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
      if (start_of_frame) {
        if (pos + 9 > size) return std::nullopt;
        const int height = (data[pos + 5] << 8) | data[pos + 6];
        const int width = (data[pos + 7] << 8) | data[pos + 8];
        if (width == 0 || height == 0) return std::nullopt;
        return std::make_pair(width, height);
      }
      if (marker == 0xD9 || marker == 0xDA || length < 2) return std::nullopt;  // no frame header before the data
      pos += 2 + length;
    }
  }
  return std::nullopt;
}

// Walks the PNG chunks checking lengths and CRCs. libpng prints its own
// "libpng error" lines to stderr on a corrupt file; checking first keeps the
// one clear message ours and catches truncation and bit flips before decoding.
std::optional<std::string> PngStructureProblem(const std::string& bytes) {
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  std::size_t pos = 8;
  while (pos + 12 <= bytes.size()) {
    const std::size_t length = BigEndian32(data + pos);
    const std::string type(bytes.data() + pos + 4, 4);
    if (length > bytes.size() - pos - 12) {
      return fmt::format("chunk at byte {} claims {} bytes, past the end of the file (truncated or corrupt)", pos,
                         length);
    }
    const uLong crc = crc32(crc32(0L, Z_NULL, 0), data + pos + 4, static_cast<uInt>(length + 4));
    if (crc != BigEndian32(data + pos + 8 + length)) {
      return fmt::format("CRC error in the chunk at byte {} (corrupt)", pos);
    }
    if (type == "IEND") return std::nullopt;
    pos += 12 + length;
  }
  return std::string("no IEND chunk (truncated)");
}

bool IsImageExtension(const std::string& extension) {
  const std::string lower = Lowercase(extension);
  return lower == ".png" || lower == ".jpg" || lower == ".jpeg";
}

// ---- listing -----------------------------------------------------------------

// The data files of one sensor's folder, sorted by time.
std::vector<SensorFile> ListSensorFiles(const fs::path& directory, bool images, const std::string& expected_files) {
  std::vector<SensorFile> files;
  for (const fs::directory_entry& file : fs::directory_iterator(directory)) {
    const fs::path& path = file.path();
    const std::string extension = path.extension().string();
    const bool good_extension = images ? IsImageExtension(extension) : extension == ".bin";
    if (!file.is_regular_file() || !good_extension) {
      Fail(path.string(), "file name", "'" + path.filename().string() + "' is not a data file of this folder",
           expected_files);
    }
    const std::optional<TimeUs> t_us = ParseTimestamp(path.stem().string());
    if (!t_us) Fail(path.string(), "file name", "'" + path.stem().string() + "' is not a timestamp", expected_files);
    files.push_back({*t_us, path});
  }
  std::sort(files.begin(), files.end(), [](const SensorFile& a, const SensorFile& b) {
    return a.t_us != b.t_us ? a.t_us < b.t_us : a.path < b.path;
  });
  for (std::size_t i = 1; i < files.size(); ++i) {
    if (files[i].t_us == files[i - 1].t_us) {
      Fail(files[i].path.string(), "file name",
           fmt::format("timestamp {} also used by {}", files[i].t_us, files[i - 1].path.filename().string()),
           "one file per timestamp");
    }
  }
  return files;
}

// FORMAT.md's sensor-folder rule: every sensor of rig.yaml has its folder
// <folder>/<sensor>/ holding at least one data file, and nothing else is there.
std::map<std::string, std::vector<SensorFile>> ListSensorFolders(const fs::path& root, const std::string& folder,
                                                                 const std::set<std::string>& sensors,
                                                                 bool images, const std::string& sensor_word) {
  std::map<std::string, std::vector<SensorFile>> listing;
  const fs::path directory = root / folder;
  const std::string expected_files = images ? "files named <t_us>.png, <t_us>.jpg or <t_us>.jpeg (int64 microseconds)"
                                            : "files named <t_us>.bin (int64 microseconds)";
  const std::string expected_folder =
      fmt::format("a folder {}/<{}>/ with at least one data file for every {} of rig.yaml", folder, sensor_word,
                  sensor_word);
  // Symlink loops, permissions and the like surface as filesystem errors
  // (ELOOP, EACCES): they are the dataset's fault, so they name the path.
  try {
    std::error_code error;
    if (!fs::exists(directory, error)) {
      Fail(directory.string(), folder + "/" + (sensors.empty() ? std::string() : *sensors.begin()), "missing",
           expected_folder);
    }
    if (!fs::is_directory(directory)) Fail(directory.string(), "folder", "not a directory", "a directory");
    for (const fs::directory_entry& entry : fs::directory_iterator(directory)) {
      const std::string name = entry.path().filename().string();
      if (!entry.is_directory()) {
        Fail(entry.path().string(), folder, "a stray file", "only one folder per " + sensor_word + " of rig.yaml");
      }
      if (sensors.count(name) == 0) {
        Fail(entry.path().string(), folder + "/" + name, "a folder for '" + name + "', which is not a " +
                 sensor_word + " of rig.yaml", "folders named after the " + sensor_word + "s in rig.yaml");
      }
      listing[name] = ListSensorFiles(entry.path(), images, expected_files);
    }
  } catch (const fs::filesystem_error& e) {
    const fs::path where = e.path1().empty() ? directory : e.path1();
    Fail(where.string(), folder, "cannot be listed (" + e.code().message() + ")", "a readable folder of data files");
  }
  for (const std::string& name : sensors) {
    const auto found = listing.find(name);
    if (found == listing.end() || found->second.empty()) {
      Fail((directory / name).string(), folder + "/" + name,
           found == listing.end() ? "missing" : "empty (no data file)", expected_folder);
    }
  }
  return listing;
}

}  // namespace

bool IsValidSensorName(const std::string& name) {
  static const std::regex pattern("[A-Za-z0-9_-]+");
  return std::regex_match(name, pattern);
}

std::optional<TimeUs> ParseTimestamp(const std::string& text) {
  TimeUs value = 0;
  if (text.empty() || text.front() == ' ' || text.back() == ' ') return std::nullopt;
  if (!detail::ParseWholeToken(text, &value)) return std::nullopt;
  return value;
}

// ---- rig.yaml ------------------------------------------------------------------

Rig ReadRig(const fs::path& path) { return ParseRig(detail::ReadTextFile(path, kMaxRigFileBytes), path.string()); }

Rig ParseRig(const std::string& text, const std::string& name) {
  if (text.size() > kMaxRigFileBytes) {
    Fail(name, "file", fmt::format("{} bytes", text.size()), fmt::format("at most {} bytes", kMaxRigFileBytes));
  }
  const YamlReader yaml(text, name);
  const YAML::Node& root = yaml.root();
  yaml.CheckKeys(root, "", {"format", "base_frame", "cameras", "lidars", "extra"});
  const YAML::Node format = yaml.Required(root, "", "format");
  if (yaml.String(format, "format") != kRigFormat) {
    yaml.Fail(format, "format", "found " + detail::Describe(format), kRigFormat);
  }
  Rig rig;
  std::set<std::string> names;
  ParseSensors(yaml, yaml.Required(root, "", "cameras"), "cameras", kMaxRigCameras, &names,
               [&](const std::string& sensor, const YAML::Node& node) { rig.cameras.push_back(ParseCamera(yaml, sensor, node)); });
  ParseSensors(yaml, yaml.Required(root, "", "lidars"), "lidars", kMaxRigLidars, &names,
               [&](const std::string& sensor, const YAML::Node& node) { rig.lidars.push_back(ParseLidar(yaml, sensor, node)); });
  const YAML::Node base = yaml.Required(root, "", "base_frame");
  rig.base_frame = yaml.String(base, "base_frame");
  const CameraInfo* base_camera = rig.FindCamera(rig.base_frame);
  if (base_camera == nullptr) {
    std::string camera_names;
    for (const CameraInfo& camera : rig.cameras) camera_names += (camera_names.empty() ? "" : ", ") + camera.name;
    yaml.Fail(base, "base_frame", "'" + rig.base_frame + "' is not a camera", "one of the cameras: " + camera_names);
  }
  if (!IsIdentity(base_camera->T_base_camera, 1e-9)) {
    const YAML::Node& cameras = root["cameras"];
    yaml.Fail(cameras[rig.base_frame]["T_base_camera"], "cameras." + rig.base_frame + ".T_base_camera",
              "not the identity, but this camera is the base_frame", "[0, 0, 0, 0, 0, 0]");
  }
  if (const YAML::Node extra = root["extra"]; extra.IsDefined() && !extra.IsMap() && !extra.IsNull()) {
    yaml.Fail(extra, "extra", "found " + detail::Describe(extra), "a mapping (free for users)");
  }
  return rig;
}

void WriteRig(const fs::path& path, const Rig& rig) { WriteFileAtomically(path.string(), RigToYaml(rig, nullptr)); }

void WriteRig(const fs::path& path, const Rig& rig, const YAML::Node& extra) {
  WriteFileAtomically(path.string(), RigToYaml(rig, &extra));
}

// ---- trajectory.csv --------------------------------------------------------------

Trajectory ReadTrajectory(const fs::path& path) {
  return ParseTrajectory(detail::ReadTextFile(path, std::size_t{4} << 30), path.string());
}

Trajectory ParseTrajectory(const std::string& text, const std::string& file) {
  std::vector<TimeUs> times;
  std::vector<Eigen::Isometry3d> poses;
  std::size_t line_number = 0;
  std::size_t pos = 0;
  bool seen_blank = false;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    const std::string_view line = Trim(std::string_view(text).substr(pos, end - pos));
    pos = end + 1;
    ++line_number;
    const std::string where = fmt::format("line {}", line_number);
    if (line_number == 1) {
      if (line != kTrajectoryHeader) {
        Fail(file, where, fmt::format("header '{}'", line.substr(0, 80)), std::string("the header ") + kTrajectoryHeader);
      }
      continue;
    }
    if (line.empty()) {
      seen_blank = true;  // trailing blank lines are harmless; blank lines between rows are not
      continue;
    }
    if (seen_blank) Fail(file, fmt::format("line {}", line_number - 1), "blank line between rows", "no blank lines");
    std::array<std::string_view, 8> fields;
    std::size_t count = 0;
    std::size_t field_start = 0;
    while (true) {
      const std::size_t comma = line.find(',', field_start);
      if (count < fields.size()) fields[count] = line.substr(field_start, comma == std::string_view::npos ? line.npos : comma - field_start);
      ++count;
      if (comma == std::string_view::npos) break;
      field_start = comma + 1;
    }
    if (count != 8) Fail(file, where, fmt::format("{} fields", count), "8 fields: timestamp_us,x,y,z,qx,qy,qz,qw");
    TimeUs t_us = 0;
    if (!ParseWhole(fields[0], &t_us)) {
      Fail(file, where + " timestamp_us", fmt::format("'{}'", fields[0].substr(0, 40)), "an int64 number of microseconds");
    }
    static constexpr const char* kNames[8] = {"timestamp_us", "x", "y", "z", "qx", "qy", "qz", "qw"};
    double values[8] = {};
    for (std::size_t i = 1; i < 8; ++i) {
      if (!ParseWhole(fields[i], &values[i]) || !std::isfinite(values[i])) {
        Fail(file, where + " " + kNames[i], fmt::format("'{}'", fields[i].substr(0, 40)), "a finite number");
      }
    }
    if (!times.empty() && t_us <= times.back()) {
      Fail(file, where + " timestamp_us", fmt::format("{} after {}", t_us, times.back()), "strictly increasing timestamps");
    }
    Eigen::Quaterniond rotation(values[7], values[4], values[5], values[6]);
    const double norm = rotation.norm();
    if (std::abs(norm - 1.0) > 1e-3) {
      Fail(file, where + " qx,qy,qz,qw", fmt::format("a quaternion of norm {}", norm), "a unit quaternion (within 1e-3)");
    }
    rotation.normalize();
    times.push_back(t_us);
    poses.push_back(TransformFromQuaternion(rotation, Eigen::Vector3d(values[1], values[2], values[3])));
  }
  if (line_number == 0) Fail(file, "line 1", "empty file", std::string("the header ") + kTrajectoryHeader);
  if (times.empty()) Fail(file, "line 2", "no pose rows", "at least one row after the header");
  return Trajectory(std::move(times), std::move(poses));
}

void WriteTrajectory(const fs::path& path, const Trajectory& trajectory) {
  std::string text = std::string(kTrajectoryHeader) + "\n";
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    const Eigen::Isometry3d& pose = trajectory.poses()[i];
    const Eigen::Quaterniond q(pose.rotation());
    const Eigen::Vector3d t = pose.translation();
    text += fmt::format("{},{},{},{},{},{},{},{}\n", trajectory.times_us()[i], t.x(), t.y(), t.z(), q.x(), q.y(), q.z(),
                        q.w());
  }
  WriteFileAtomically(path.string(), text);
}

// ---- ground_truth.yaml -----------------------------------------------------------

GroundTruth ReadGroundTruth(const fs::path& path) {
  return ParseGroundTruth(detail::ReadTextFile(path, kMaxYamlFileBytes), path.string());
}

GroundTruth ParseGroundTruth(const std::string& text, const std::string& name) {
  const YamlReader yaml(text, name);
  const YAML::Node& root = yaml.root();
  yaml.CheckKeys(root, "", {"format", "lidars", "cameras"});
  const YAML::Node format = yaml.Required(root, "", "format");
  if (yaml.String(format, "format") != kGroundTruthFormat) {
    yaml.Fail(format, "format", "found " + detail::Describe(format), kGroundTruthFormat);
  }
  GroundTruth truth;
  const YAML::Node lidars = yaml.Required(root, "", "lidars");
  yaml.CheckUniqueKeys(lidars, "lidars");
  for (const auto& entry : lidars) {
    const std::string lidar = entry.first.Scalar();
    yaml.CheckKeys(entry.second, "lidars." + lidar, {"T_base_lidar"});
    truth.T_base_lidar[lidar] = yaml.Transform(yaml.Required(entry.second, "lidars." + lidar, "T_base_lidar"),
                                               "lidars." + lidar + ".T_base_lidar");
  }
  if (const YAML::Node cameras = root["cameras"]; cameras.IsDefined() && !cameras.IsNull()) {
    yaml.CheckUniqueKeys(cameras, "cameras");
    for (const auto& entry : cameras) {
      const std::string camera = entry.first.Scalar();
      yaml.CheckKeys(entry.second, "cameras." + camera, {"T_base_camera"});
      truth.T_base_camera[camera] = yaml.Transform(yaml.Required(entry.second, "cameras." + camera, "T_base_camera"),
                                                   "cameras." + camera + ".T_base_camera");
    }
  }
  return truth;
}

void WriteGroundTruth(const fs::path& path, const GroundTruth& truth) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kGroundTruthFormat;
  out << YAML::Key << "lidars" << YAML::Value << YAML::BeginMap;
  for (const auto& [name, transform] : truth.T_base_lidar) {
    out << YAML::Key << name << YAML::Value << YAML::BeginMap << YAML::Key << "T_base_lidar" << YAML::Value;
    detail::EmitTransform(out, transform);
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  if (!truth.T_base_camera.empty()) {
    out << YAML::Key << "cameras" << YAML::Value << YAML::BeginMap;
    for (const auto& [name, transform] : truth.T_base_camera) {
      out << YAML::Key << name << YAML::Value << YAML::BeginMap << YAML::Key << "T_base_camera" << YAML::Value;
      detail::EmitTransform(out, transform);
      out << YAML::EndMap;
    }
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  WriteFileAtomically(path.string(), std::string(out.c_str()) + "\n");
}

// ---- dataset ----------------------------------------------------------------------

Dataset OpenDataset(const fs::path& root) {
  std::error_code error;
  if (!fs::is_directory(root, error)) Fail(root.string(), "dataset", "not a directory", "a dataset directory (FORMAT.md)");
  Dataset dataset;
  dataset.root = root;
  dataset.rig = ReadRig(root / "rig.yaml");
  dataset.trajectory = ReadTrajectory(root / "trajectory.csv");
  const fs::path truth_path = root / "ground_truth.yaml";
  if (fs::exists(truth_path, error)) {
    GroundTruth truth = ReadGroundTruth(truth_path);
    for (const auto& [name, transform] : truth.T_base_lidar) {
      if (dataset.rig.FindLidar(name) == nullptr) {
        Fail(truth_path.string(), "lidars." + name, "'" + name + "' is not a lidar of rig.yaml", "lidar names of rig.yaml");
      }
    }
    for (const auto& [name, transform] : truth.T_base_camera) {
      if (dataset.rig.FindCamera(name) == nullptr) {
        Fail(truth_path.string(), "cameras." + name, "'" + name + "' is not a camera of rig.yaml",
             "camera names of rig.yaml");
      }
    }
    dataset.ground_truth = std::move(truth);
  }
  std::set<std::string> cameras, lidars;
  for (const CameraInfo& camera : dataset.rig.cameras) cameras.insert(camera.name);
  for (const LidarInfo& lidar : dataset.rig.lidars) lidars.insert(lidar.name);
  dataset.images = ListSensorFolders(root, "cameras", cameras, true, "camera");
  dataset.scans = ListSensorFolders(root, "lidars", lidars, false, "lidar");
  return dataset;
}

void WriteDatasetSkeleton(const fs::path& root, const Rig& rig, const Trajectory& trajectory,
                          const std::optional<GroundTruth>& truth) {
  fs::create_directories(root);
  WriteRig(root / "rig.yaml", rig);
  WriteTrajectory(root / "trajectory.csv", trajectory);
  if (truth) WriteGroundTruth(root / "ground_truth.yaml", *truth);
  for (const CameraInfo& camera : rig.cameras) fs::create_directories(root / "cameras" / camera.name);
  for (const LidarInfo& lidar : rig.lidars) fs::create_directories(root / "lidars" / lidar.name);
}

// ---- images --------------------------------------------------------------------------

std::optional<std::pair<int, int>> ImageFileSize(const fs::path& path) {
  std::ifstream stream(path, std::ios::binary);
  std::string head(64 * 1024, '\0');  // JPEG frame headers follow EXIF blocks, usually within 64 KiB
  stream.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(stream.gcount()));
  return ImageSizeFromHeader(head);
}

bool ParseImageChannel(const std::string& name, ImageChannel* channel) {
  if (name == "grey") *channel = ImageChannel::kGrey;
  else if (name == "exg") *channel = ImageChannel::kExcessGreen;
  else return false;
  return true;
}

const char* ImageChannelName(ImageChannel channel) {
  return channel == ImageChannel::kExcessGreen ? "exg" : "grey";
}

GreyImage ReadImage(const SensorFile& file, const CameraModel& camera, ImageChannel channel) {
  const std::string name = file.path.string();
  const std::string bytes = ReadBinaryFile(file.path, kMaxDataFileBytes);
  const std::string expected_size = fmt::format("{} x {} pixels as in rig.yaml", camera.width, camera.height);
  const auto header_size = ImageSizeFromHeader(bytes);
  if (!header_size) Fail(name, "image", "not a readable PNG or JPEG header", "a PNG or JPEG image");
  if (header_size->first != camera.width || header_size->second != camera.height) {
    Fail(name, "image size", fmt::format("{} x {} pixels", header_size->first, header_size->second), expected_size);
  }
  if (bytes.size() >= 8 && bytes.compare(1, 3, "PNG") == 0) {
    if (const auto problem = PngStructureProblem(bytes)) Fail(name, "image", *problem, "a valid PNG image");
  }
  if (bytes.size() >= 2 && static_cast<unsigned char>(bytes[0]) == 0xFF && static_cast<unsigned char>(bytes[1]) == 0xD8) {
    // libjpeg fills a truncated JPEG with grey and succeeds; a missing
    // end-of-image marker (FF D9, trailing zero padding allowed) catches it.
    const std::size_t end = bytes.find_last_not_of('\0');
    if (end == std::string::npos || end < 1 || static_cast<unsigned char>(bytes[end - 1]) != 0xFF ||
        static_cast<unsigned char>(bytes[end]) != 0xD9) {
      Fail(name, "image", "no JPEG end-of-image marker (truncated)", "a complete JPEG image");
    }
  }
  const cv::Mat encoded(1, static_cast<int>(bytes.size()), CV_8U, const_cast<char*>(bytes.data()));
  cv::Mat decoded;
  try {
    decoded = cv::imdecode(encoded, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    Fail(name, "image", std::string("cannot be decoded (") + e.what() + ")", "a valid PNG or JPEG image");
  }
  if (decoded.empty()) Fail(name, "image", "cannot be decoded (corrupt or truncated)", "a valid PNG or JPEG image");
  if (decoded.cols != camera.width || decoded.rows != camera.height) {
    Fail(name, "image size", fmt::format("{} x {} pixels", decoded.cols, decoded.rows), expected_size);
  }
  double scale = 0.0;
  if (decoded.depth() == CV_8U) {
    scale = 1.0 / 255.0;
  } else if (decoded.depth() == CV_16U) {
    scale = 1.0 / 65535.0;
  } else {
    Fail(name, "image depth", fmt::format("OpenCV depth {}", decoded.depth()), "8 or 16 bits per channel");
  }
  if (decoded.channels() != 1 && decoded.channels() != 3 && decoded.channels() != 4) {
    Fail(name, "image channels", fmt::format("{} channels", decoded.channels()), "grey, RGB or RGBA");
  }
  GreyImage image;
  image.t_us = file.t_us;
  if (channel == ImageChannel::kExcessGreen) {
    if (decoded.channels() == 1) {
      Fail(name, "image channels", "1 channel (grey)", "a colour image for the excess-green channel (--image-channel exg)");
    }
    std::vector<cv::Mat> bgr;
    cv::split(decoded, bgr);
    cv::Mat b, g, r;
    bgr[0].convertTo(b, CV_32F, scale);
    bgr[1].convertTo(g, CV_32F, scale);
    bgr[2].convertTo(r, CV_32F, scale);
    image.intensity = (2.0f * g - r - b + 2.0f) * 0.25f;  // [-2, 2] -> [0, 1]
    return image;
  }
  cv::Mat grey;
  switch (decoded.channels()) {
    case 1: grey = decoded; break;
    case 3: cv::cvtColor(decoded, grey, cv::COLOR_BGR2GRAY); break;
    default: cv::cvtColor(decoded, grey, cv::COLOR_BGRA2GRAY); break;
  }
  grey.convertTo(image.intensity, CV_32F, scale);
  return image;
}

void WriteImage(const fs::path& path, const cv::Mat& image) {
  const std::string extension = Lowercase(path.extension().string());
  if (!IsImageExtension(extension)) throw std::invalid_argument("WriteImage: " + path.string() + ": not .png/.jpg/.jpeg");
  if (image.depth() != CV_8U && image.depth() != CV_16U) {
    throw std::invalid_argument("WriteImage: " + path.string() + ": image must be 8- or 16-bit");
  }
  if (extension != ".png" && image.depth() != CV_8U) {
    throw std::invalid_argument("WriteImage: " + path.string() + ": JPEG holds 8-bit images only");
  }
  std::vector<int> parameters;
  if (extension != ".png") parameters = {cv::IMWRITE_JPEG_QUALITY, 95};
  std::vector<unsigned char> encoded;
  if (!cv::imencode(extension, image, encoded, parameters)) {
    throw std::runtime_error("WriteImage: cannot encode " + path.string());
  }
  WriteBinaryFile(path, encoded.data(), encoded.size());
}

// ---- scans ----------------------------------------------------------------------------

std::size_t ScanRecordCount(const SensorFile& file) {
  std::error_code error;
  const auto size = fs::file_size(file.path, error);
  if (error) Fail(file.path.string(), "file", "cannot read its size (" + error.message() + ")", "a readable file");
  if (size % sizeof(LidarPoint) != 0) {
    Fail(file.path.string(), "file size", fmt::format("{} bytes", size),
         "a multiple of 16 bytes (float32 x, y, z, reflectance per point)");
  }
  return static_cast<std::size_t>(size / sizeof(LidarPoint));
}

LidarScan ReadScan(const SensorFile& file) {
  ScanRecordCount(file);  // checks the size before reading
  return ParseScan(ReadBinaryFile(file.path, kMaxDataFileBytes), file.path.string(), file.t_us);
}

LidarScan ParseScan(const std::string& bytes, const std::string& name, TimeUs t_us) {
  if (bytes.size() % sizeof(LidarPoint) != 0) {  // also when the file changed after ScanRecordCount
    Fail(name, "file size", fmt::format("{} bytes", bytes.size()), "a multiple of 16 bytes");
  }
  const std::size_t records = bytes.size() / sizeof(LidarPoint);
  LidarScan scan;
  scan.t_us = t_us;
  scan.points.resize(records);
  if (records > 0) std::memcpy(scan.points.data(), bytes.data(), bytes.size());  // data() may be null when empty
  const auto no_return = [](const LidarPoint& p) {
    return !(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) && std::isfinite(p.reflectance));
  };
  const auto kept_end = std::remove_if(scan.points.begin(), scan.points.end(), no_return);
  scan.no_returns = static_cast<std::size_t>(scan.points.end() - kept_end);
  scan.points.erase(kept_end, scan.points.end());
  return scan;
}

void WriteScan(const fs::path& path, const std::vector<LidarPoint>& points) {
  WriteBinaryFile(path, points.data(), points.size() * sizeof(LidarPoint));
}

// ---- calibration result -----------------------------------------------------------------

std::string CalibrationResultToYaml(const CalibrationResult& result, const YAML::Node* extra_keys) {
  static const std::set<std::string> kStandardKeys = {"format", "lidars", "pairs", "termination",
                                                      "settings", "timings_s", "warnings"};
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kResultFormat;
  out << YAML::Key << "lidars" << YAML::Value << YAML::BeginMap;
  for (const LidarCalibration& lidar : result.lidars) {
    out << YAML::Key << lidar.lidar << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "T_base_lidar" << YAML::Value;
    detail::EmitTransform(out, lidar.T_base_lidar);
    if (lidar.sigma) {
      out << YAML::Key << "sigma" << YAML::Value;
      detail::EmitNumbers(out, lidar.sigma->data(), 6);
    }
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  out << YAML::Key << "pairs" << YAML::Value << YAML::BeginSeq;
  for (const PairCalibration& pair : result.pairs) {
    out << YAML::BeginMap;
    out << YAML::Key << "camera" << YAML::Value << pair.camera;
    out << YAML::Key << "lidar" << YAML::Value << pair.lidar;
    out << YAML::Key << "T_camera_lidar" << YAML::Value;
    detail::EmitTransform(out, pair.T_camera_lidar);
    out << YAML::Key << "cost" << YAML::Value << FormatNumber(pair.cost);
    out << YAML::EndMap;
  }
  out << YAML::EndSeq;
  out << YAML::Key << "termination" << YAML::Value << YAML::DoubleQuoted << result.termination;
  out << YAML::Key << "settings" << YAML::Value << YAML::BeginMap;
  for (const auto& [key, value] : result.settings) out << YAML::Key << key << YAML::Value << YAML::DoubleQuoted << value;
  out << YAML::EndMap;
  out << YAML::Key << "timings_s" << YAML::Value << YAML::BeginMap;
  for (const auto& [key, value] : result.timings_s) out << YAML::Key << key << YAML::Value << FormatNumber(value);
  out << YAML::EndMap;
  out << YAML::Key << "warnings" << YAML::Value << YAML::BeginSeq;
  for (const std::string& warning : result.warnings) out << YAML::DoubleQuoted << warning;
  out << YAML::EndSeq;
  if (extra_keys != nullptr && extra_keys->IsDefined() && !extra_keys->IsNull()) {
    if (!extra_keys->IsMap()) throw std::invalid_argument("CalibrationResultToYaml: extra keys must be a YAML mapping");
    for (const auto& entry : *extra_keys) {
      const std::string key = entry.first.as<std::string>();
      if (kStandardKeys.count(key) != 0) {
        throw std::invalid_argument("CalibrationResultToYaml: extra key '" + key + "' repeats a standard key");
      }
      out << YAML::Key << key << YAML::Value << entry.second;
    }
  }
  out << YAML::EndMap;
  if (!out.good()) throw std::runtime_error("CalibrationResultToYaml: YAML emitter error: " + out.GetLastError());
  return std::string(out.c_str()) + "\n";
}

void WriteCalibrationResult(const fs::path& path, const CalibrationResult& result) {
  WriteFileAtomically(path.string(), CalibrationResultToYaml(result, nullptr));
}

void WriteCalibrationResult(const fs::path& path, const CalibrationResult& result, const YAML::Node& extra_keys) {
  WriteFileAtomically(path.string(), CalibrationResultToYaml(result, &extra_keys));
}

CalibrationResult ReadCalibrationResult(const fs::path& path) {
  return ParseCalibrationResult(detail::ReadTextFile(path, kMaxYamlFileBytes), path.string());
}

CalibrationResult ParseCalibrationResult(const std::string& text, const std::string& name) {
  const YamlReader yaml(text, name);
  const YAML::Node& root = yaml.root();
  yaml.RequireMap(root, "");
  const YAML::Node format = yaml.Required(root, "", "format");
  if (yaml.String(format, "format") != kResultFormat) {
    yaml.Fail(format, "format", "found " + detail::Describe(format), kResultFormat);
  }
  CalibrationResult result;
  const YAML::Node lidars = yaml.Required(root, "", "lidars");
  yaml.CheckUniqueKeys(lidars, "lidars");
  for (const auto& entry : lidars) {
    const std::string lidar_name = entry.first.Scalar();
    const std::string field = "lidars." + lidar_name;
    yaml.CheckKeys(entry.second, field, {"T_base_lidar", "sigma"});
    LidarCalibration lidar;
    lidar.lidar = lidar_name;
    lidar.T_base_lidar = yaml.Transform(yaml.Required(entry.second, field, "T_base_lidar"), field + ".T_base_lidar");
    const YAML::Node& lidar_node = entry.second;
    if (const YAML::Node sigma = lidar_node["sigma"]; sigma.IsDefined()) lidar.sigma = yaml.Sigma(sigma, field + ".sigma");
    result.lidars.push_back(std::move(lidar));
  }
  const YAML::Node pairs = yaml.Required(root, "", "pairs");
  if (!pairs.IsSequence()) yaml.Fail(pairs, "pairs", "found " + detail::Describe(pairs), "a list of pairs");
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const std::string field = fmt::format("pairs[{}]", i);
    const YAML::Node node = pairs[i];
    yaml.CheckKeys(node, field, {"camera", "lidar", "T_camera_lidar", "cost"});
    PairCalibration pair;
    pair.camera = yaml.String(yaml.Required(node, field, "camera"), field + ".camera");
    pair.lidar = yaml.String(yaml.Required(node, field, "lidar"), field + ".lidar");
    pair.T_camera_lidar = yaml.Transform(yaml.Required(node, field, "T_camera_lidar"), field + ".T_camera_lidar");
    const YAML::Node cost = yaml.Required(node, field, "cost");
    try {
      pair.cost = cost.as<double>();  // may be .nan when a pair had no data
    } catch (const YAML::Exception&) {
      yaml.Fail(cost, field + ".cost", "found " + detail::Describe(cost), "a number");
    }
    if (std::isinf(pair.cost)) {
      yaml.Fail(cost, field + ".cost", "found " + detail::Describe(cost), "a finite number, or .nan for a pair without data");
    }
    result.pairs.push_back(std::move(pair));
  }
  if (const YAML::Node termination = root["termination"]; termination.IsDefined()) {
    result.termination = yaml.String(termination, "termination");
  }
  if (const YAML::Node settings = root["settings"]; settings.IsDefined() && !settings.IsNull()) {
    yaml.RequireMap(settings, "settings");
    for (const auto& entry : settings) {
      result.settings[entry.first.Scalar()] = yaml.String(entry.second, "settings." + entry.first.Scalar());
    }
  }
  if (const YAML::Node timings = root["timings_s"]; timings.IsDefined() && !timings.IsNull()) {
    yaml.RequireMap(timings, "timings_s");
    for (const auto& entry : timings) {
      result.timings_s[entry.first.Scalar()] = yaml.Number(entry.second, "timings_s." + entry.first.Scalar());
    }
  }
  if (const YAML::Node warnings = root["warnings"]; warnings.IsDefined() && !warnings.IsNull()) {
    if (!warnings.IsSequence()) yaml.Fail(warnings, "warnings", "found " + detail::Describe(warnings), "a list of text");
    for (std::size_t i = 0; i < warnings.size(); ++i) {
      result.warnings.push_back(yaml.String(warnings[i], fmt::format("warnings[{}]", i)));
    }
  }
  return result;
}

std::vector<SensorFile> ListLidarScans(const fs::path& root, const std::string& lidar) {
  // The lidars folder may hold other lidars' folders: list them all, keep one.
  std::set<std::string> lidars;
  std::error_code error;
  for (const fs::directory_entry& entry : fs::directory_iterator(root / "lidars", error)) {
    lidars.insert(entry.path().filename().string());
  }
  lidars.insert(lidar);
  return ListSensorFolders(root, "lidars", lidars, false, "lidar").at(lidar);
}

}  // namespace scenecal::io
