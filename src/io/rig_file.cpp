#include "io/rig_file.hpp"

#include <regex>
#include <set>
#include <vector>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "io/yaml_fields.hpp"

namespace scenecal::io {

namespace fs = std::filesystem;
using detail::Fail;
using detail::YamlReader;

namespace {

constexpr char kRigFormat[] = "scenecal-dataset/1";
// Largest rig.yaml (bytes): 64 cameras and 64 lidars take ~30 KB, so this
// leaves room for `extra:` while a file of a million sensors is refused
// before yaml-cpp spends seconds and hundreds of MB on it.
constexpr std::size_t kMaxRigFileBytes = std::size_t{4} << 20;

bool IsIdentity(const Eigen::Isometry3d& transform, double tolerance) {
  return (transform.matrix() - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff() <= tolerance;
}

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
    if (!entry.first.IsScalar()) {
      yaml.Fail(entry.first, field, "a key that is " + detail::Describe(entry.first), "a name");
    }
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

// base_frame names a camera of the rig, and that camera is the base frame itself.
void CheckBaseFrame(const YamlReader& yaml, const Rig& rig) {
  const YAML::Node& root = yaml.root();
  const YAML::Node base = yaml.Required(root, "", "base_frame");
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
}

void EmitCamera(YAML::Emitter& out, const CameraInfo& camera) {
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

void EmitLidar(YAML::Emitter& out, const LidarInfo& lidar) {
  out << YAML::Key << lidar.name << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "kind" << YAML::Value << (lidar.kind == LidarKind::k2d ? "2d" : "3d");
  out << YAML::Key << "T_base_lidar" << YAML::Value;
  detail::EmitTransform(out, lidar.T_base_lidar);
  out << YAML::EndMap;
}

std::string RigToYaml(const Rig& rig, const YAML::Node* extra) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kRigFormat;
  out << YAML::Key << "base_frame" << YAML::Value << rig.base_frame;
  out << YAML::Key << "cameras" << YAML::Value << YAML::BeginMap;
  for (const CameraInfo& camera : rig.cameras) EmitCamera(out, camera);
  out << YAML::EndMap;
  out << YAML::Key << "lidars" << YAML::Value << YAML::BeginMap;
  for (const LidarInfo& lidar : rig.lidars) EmitLidar(out, lidar);
  out << YAML::EndMap;
  if (rig.trajectory_source != TrajectorySource::kUnknown) {
    out << YAML::Key << "trajectory_source" << YAML::Value << TrajectorySourceName(rig.trajectory_source);
  }
  if (extra != nullptr && extra->IsDefined() && !extra->IsNull()) {
    if (!extra->IsMap()) throw std::invalid_argument("WriteRig: extra must be a YAML mapping");
    out << YAML::Key << "extra" << YAML::Value << *extra;
  }
  out << YAML::EndMap;
  if (!out.good()) throw std::runtime_error("WriteRig: YAML emitter error: " + out.GetLastError());
  return std::string(out.c_str()) + "\n";
}

}  // namespace

bool IsValidSensorName(const std::string& name) {
  static const std::regex pattern("[A-Za-z0-9_-]+");
  return std::regex_match(name, pattern);
}

Rig ReadRig(const fs::path& path) { return ParseRig(detail::ReadTextFile(path, kMaxRigFileBytes), path.string()); }

Rig ParseRig(const std::string& text, const std::string& name) {
  if (text.size() > kMaxRigFileBytes) {
    Fail(name, "file", fmt::format("{} bytes", text.size()), fmt::format("at most {} bytes", kMaxRigFileBytes));
  }
  const YamlReader yaml(text, name);
  const YAML::Node& root = yaml.root();
  yaml.CheckKeys(root, "", {"format", "base_frame", "cameras", "lidars", "trajectory_source", "extra"});
  yaml.CheckFormat(root, kRigFormat);
  Rig rig;
  std::set<std::string> names;
  ParseSensors(yaml, yaml.Required(root, "", "cameras"), "cameras", kMaxRigCameras, &names,
               [&](const std::string& sensor, const YAML::Node& node) {
                 rig.cameras.push_back(ParseCamera(yaml, sensor, node));
               });
  ParseSensors(yaml, yaml.Required(root, "", "lidars"), "lidars", kMaxRigLidars, &names,
               [&](const std::string& sensor, const YAML::Node& node) {
                 rig.lidars.push_back(ParseLidar(yaml, sensor, node));
               });
  rig.base_frame = yaml.String(yaml.Required(root, "", "base_frame"), "base_frame");
  CheckBaseFrame(yaml, rig);
  if (const YAML::Node source = root["trajectory_source"]; source.IsDefined()) {
    const std::string source_name = yaml.String(source, "trajectory_source");
    if (!ParseTrajectorySource(source_name, &rig.trajectory_source)) {
      yaml.Fail(source, "trajectory_source", "'" + source_name + "'", "one of " + TrajectorySourceChoices());
    }
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

}  // namespace scenecal::io
