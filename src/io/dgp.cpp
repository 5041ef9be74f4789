#include "io/dgp.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <regex>
#include <set>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include "core/geometry.hpp"
#include "core/interrupt.hpp"
#include "io/dataset.hpp"
#include "io/npz.hpp"
#include "io/staged_output.hpp"
#include "io/yaml_fields.hpp"

namespace scenecal::io {

namespace fs = std::filesystem;
using detail::Fail;
using Json = nlohmann::json;

namespace {

// Largest JSON file read (a long scene lists a few thousand datums).
constexpr std::size_t kMaxJsonBytes = std::size_t{256} << 20;
// A time after this year is no real recording: the 100 ns count read as microseconds.
constexpr int kLastPlausibleYear = 2200;

// Field access that names the file and the dotted field in every message.
class JsonReader {
 public:
  explicit JsonReader(std::string name) : name_(std::move(name)) {}

  Json Parse(const std::string& text) const {
    try {
      return Json::parse(text);
    } catch (const Json::parse_error& e) {
      Fail(name_, fmt::format("byte {}", e.byte), std::string("JSON syntax error: ") + e.what(), "valid JSON");
    } catch (const Json::exception& e) {
      // Valid syntax the parser still cannot hold, e.g. a number beyond a
      // double (1e400: out_of_range.406).
      Fail(name_, "JSON", e.what(), "JSON whose numbers fit a double");
    }
  }

  const Json& Member(const Json& object, const std::string& field, const char* key) const {
    if (!object.is_object()) Fail(name_, field, "not an object", "a JSON object");
    const auto found = object.find(key);
    if (found == object.end()) Fail(name_, Join(field, key), "missing", "the key to be present");
    return *found;
  }
  const Json* Optional(const Json& object, const char* key) const {
    const auto found = object.find(key);
    return found == object.end() ? nullptr : &*found;
  }
  double Number(const Json& value, const std::string& field) const {
    if (!value.is_number()) Fail(name_, field, "found " + Describe(value), "a number");
    const double number = value.get<double>();
    if (!std::isfinite(number)) Fail(name_, field, "not finite", "a finite number");
    return number;
  }
  double Number(const Json& object, const std::string& field, const char* key) const {
    return Number(Member(object, field, key), Join(field, key));
  }
  std::string String(const Json& value, const std::string& field) const {
    if (!value.is_string()) Fail(name_, field, "found " + Describe(value), "a string");
    return value.get<std::string>();
  }
  std::string String(const Json& object, const std::string& field, const char* key) const {
    return String(Member(object, field, key), Join(field, key));
  }
  const Json& Array(const Json& object, const std::string& field, const char* key) const {
    const Json& value = Member(object, field, key);
    if (!value.is_array()) Fail(name_, Join(field, key), "found " + Describe(value), "a list");
    return value;
  }
  long long Integer(const Json& object, const std::string& field, const char* key) const {
    const Json& value = Member(object, field, key);
    if (!value.is_number_integer()) Fail(name_, Join(field, key), "found " + Describe(value), "an integer");
    return value.get<long long>();
  }

  // {rotation: {qw, qx, qy, qz}, translation: {x, y, z}}.
  Eigen::Isometry3d Pose(const Json& object, const std::string& field) const {
    const Json& rotation = Member(object, field, "rotation");
    const Json& translation = Member(object, field, "translation");
    const std::string r = Join(field, "rotation");
    const std::string t = Join(field, "translation");
    const Eigen::Quaterniond q(Number(rotation, r, "qw"), Number(rotation, r, "qx"), Number(rotation, r, "qy"),
                               Number(rotation, r, "qz"));
    if (std::abs(q.norm() - 1.0) > 1e-3) {
      Fail(name_, r, fmt::format("a quaternion of norm {}", q.norm()), "a unit quaternion (norm within 1e-3 of 1)");
    }
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = q.normalized().toRotationMatrix();
    pose.translation() = Eigen::Vector3d(Number(translation, t, "x"), Number(translation, t, "y"),
                                         Number(translation, t, "z"));
    return pose;
  }

  const std::string& name() const { return name_; }

  static std::string Join(const std::string& field, const std::string& key) {
    return field.empty() ? key : field + "." + key;
  }
  static std::string Describe(const Json& value) {
    std::string text = value.dump();
    if (text.size() > 40) text = text.substr(0, 40) + "...";
    return std::string(value.type_name()) + " " + text;
  }

 private:
  std::string name_;
};

std::string SensorExpected(const std::string& what) { return "a " + what + " of the scene"; }

}  // namespace

const DgpSensorCalibration* DgpCalibration::Find(const std::string& name) const {
  for (const DgpSensorCalibration& sensor : sensors) {
    if (sensor.name == name) return &sensor;
  }
  return nullptr;
}

std::optional<TimeUs> ParseRfc3339(const std::string& text) {
  static const std::regex pattern(
      R"(^(\d{4})-(\d{2})-(\d{2})[Tt ](\d{2}):(\d{2}):(\d{2})(?:\.(\d{1,9}))?(Z|z|[+-]\d{2}:\d{2})$)");
  std::smatch match;
  if (!std::regex_match(text, match, pattern)) return std::nullopt;
  const auto number = [&match](int group) { return std::stoi(match[group].str()); };
  const std::chrono::year_month_day date{std::chrono::year{number(1)},
                                         std::chrono::month{static_cast<unsigned>(number(2))},
                                         std::chrono::day{static_cast<unsigned>(number(3))}};
  const int hour = number(4), minute = number(5), second = number(6);
  if (!date.ok() || hour > 23 || minute > 59 || second > 60) return std::nullopt;
  const std::int64_t days = std::chrono::sys_days(date).time_since_epoch().count();
  std::int64_t seconds = ((days * 24 + hour) * 60 + minute) * 60 + second;
  const std::string zone = match[8].str();
  if (zone.size() == 6) {  // +hh:mm: local time ahead of UTC by that much
    const int offset_minutes = std::stoi(zone.substr(1, 2)) * 60 + std::stoi(zone.substr(4, 2));
    if (offset_minutes >= 24 * 60) return std::nullopt;
    seconds -= (zone[0] == '+' ? 1 : -1) * offset_minutes * 60;
  }
  std::string fraction = match[7].str();
  fraction.resize(6, '0');  // microseconds; finer digits dropped
  return seconds * 1'000'000 + std::stoll(fraction);
}

DgpScene ParseDgpScene(const std::string& json_text, const std::string& name) {
  const JsonReader reader(name);
  const Json root = reader.Parse(json_text);
  DgpScene scene;
  const Json& data = reader.Array(root, "", "data");
  std::set<std::string> keys;
  for (std::size_t i = 0; i < data.size(); ++i) {
    const std::string field = fmt::format("data[{}]", i);
    const Json& entry = data[i];
    const Json& datum_node = reader.Member(entry, field, "datum");
    if (!datum_node.is_object() || datum_node.size() != 1) {
      Fail(name, field + ".datum", "found " + JsonReader::Describe(datum_node), "an object with one datum kind");
    }
    const std::string kind = datum_node.begin().key();
    if (kind != "image" && kind != "point_cloud") {
      ++scene.skipped_data;  // radar, file datums, ...: nothing a lidar-camera calibration reads
      continue;
    }
    DgpDatum datum;
    datum.kind = kind == "image" ? DgpDatum::Kind::kImage : DgpDatum::Kind::kPointCloud;
    datum.key = reader.String(entry, field, "key");
    if (!keys.insert(datum.key).second) Fail(name, field + ".key", "'" + datum.key + "' repeated", "unique datum keys");
    const Json& id = reader.Member(entry, field, "id");
    datum.sensor = reader.String(id, field + ".id", "name");
    if (!IsValidSensorName(datum.sensor)) {
      Fail(name, field + ".id.name", "'" + datum.sensor + "'", "a sensor name of [A-Za-z0-9_-]+");
    }
    datum.timestamp = reader.String(id, field + ".id", "timestamp");
    const std::optional<TimeUs> t_us = ParseRfc3339(datum.timestamp);
    if (!t_us) {
      Fail(name, field + ".id.timestamp", "'" + datum.timestamp + "'",
           "an RFC 3339 time such as 2019-03-28T11:10:09.112358Z");
    }
    datum.raw_t_us = *t_us;
    const std::string datum_field = field + ".datum." + kind;
    const Json& body = datum_node.begin().value();
    datum.filename = reader.String(body, datum_field, "filename");
    if (datum.filename.empty() || fs::path(datum.filename).is_absolute() ||
        datum.filename.find("..") != std::string::npos) {
      Fail(name, datum_field + ".filename", "'" + datum.filename + "'", "a relative path inside the scene folder");
    }
    datum.T_world_sensor = reader.Pose(reader.Member(body, datum_field, "pose"), datum_field + ".pose");
    if (datum.kind == DgpDatum::Kind::kImage) {
      const long long width = reader.Integer(body, datum_field, "width");
      const long long height = reader.Integer(body, datum_field, "height");
      if (width <= 0 || height <= 0 || width > 1'000'000 || height > 1'000'000) {
        Fail(name, datum_field + ".width", fmt::format("{} x {}", width, height), "a positive image size");
      }
      datum.width = static_cast<int>(width);
      datum.height = static_cast<int>(height);
    } else {
      const Json& format = reader.Array(body, datum_field, "point_format");
      for (std::size_t f = 0; f < format.size(); ++f) {
        datum.point_format.push_back(reader.String(format[f], fmt::format("{}.point_format[{}]", datum_field, f)));
      }
    }
    scene.data.push_back(std::move(datum));
  }
  const Json& samples = reader.Array(root, "", "samples");
  scene.samples = samples.size();
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const std::string key = reader.String(samples[i], fmt::format("samples[{}]", i), "calibration_key");
    if (std::find(scene.calibration_keys.begin(), scene.calibration_keys.end(), key) == scene.calibration_keys.end()) {
      scene.calibration_keys.push_back(key);
    }
  }
  return scene;
}

DgpCalibration ParseDgpCalibration(const std::string& json_text, const std::string& name) {
  const JsonReader reader(name);
  const Json root = reader.Parse(json_text);
  const Json& names = reader.Array(root, "", "names");
  const Json& extrinsics = reader.Array(root, "", "extrinsics");
  const Json& intrinsics = reader.Array(root, "", "intrinsics");
  if (extrinsics.size() != names.size() || intrinsics.size() != names.size()) {
    Fail(name, "extrinsics", fmt::format("{} names, {} extrinsics, {} intrinsics", names.size(), extrinsics.size(),
                                         intrinsics.size()),
         "one extrinsic and one intrinsic per name");
  }
  DgpCalibration calibration;
  for (std::size_t i = 0; i < names.size(); ++i) {
    DgpSensorCalibration sensor;
    sensor.name = reader.String(names[i], fmt::format("names[{}]", i));
    if (calibration.Find(sensor.name) != nullptr) {
      Fail(name, fmt::format("names[{}]", i), "'" + sensor.name + "' repeated", "one entry per sensor");
    }
    sensor.T_vehicle_sensor = reader.Pose(extrinsics[i], fmt::format("extrinsics[{}]", i));
    const std::string field = fmt::format("intrinsics[{}]", i);
    const Json& in = intrinsics[i];
    sensor.fx = reader.Number(in, field, "fx");
    sensor.fy = reader.Number(in, field, "fy");
    sensor.cx = reader.Number(in, field, "cx");
    sensor.cy = reader.Number(in, field, "cy");
    if (const Json* skew = reader.Optional(in, "skew")) sensor.skew = reader.Number(*skew, field + ".skew");
    if (const Json* fisheye = reader.Optional(in, "fisheye")) {
      if (!fisheye->is_boolean()) {
        Fail(name, field + ".fisheye", "found " + JsonReader::Describe(*fisheye), "true or false");
      }
      sensor.fisheye = fisheye->get<bool>();
    }
    const std::pair<const char*, double*> terms[] = {{"k1", &sensor.k1}, {"k2", &sensor.k2}, {"k3", &sensor.k3},
                                                     {"k4", &sensor.k4}, {"p1", &sensor.p1}, {"p2", &sensor.p2}};
    for (const auto& [key, value] : terms) {
      if (const Json* term = reader.Optional(in, key)) *value = reader.Number(*term, JsonReader::Join(field, key));
    }
    // Terms of richer models (rational k4..k6 with radtan, thin prism s1..s4,
    // tilt, unified xi/alpha): only a zero is harmless.
    for (const char* key : {"k5", "k6", "s1", "s2", "s3", "s4", "taux", "tauy", "xi", "alpha", "beta"}) {
      if (const Json* term = reader.Optional(in, key)) {
        if (reader.Number(*term, JsonReader::Join(field, key)) != 0.0 && sensor.unsupported_term.empty()) {
          sensor.unsupported_term = key;
        }
      }
    }
    if (!sensor.fisheye && sensor.k4 != 0.0 && sensor.unsupported_term.empty()) sensor.unsupported_term = "k4";
    calibration.sensors.push_back(std::move(sensor));
  }
  return calibration;
}

namespace {

// The scene file of a scene folder: exactly one scene_*.json.
fs::path FindSceneFile(const fs::path& scene_dir) {
  std::vector<fs::path> found;
  for (const fs::directory_entry& entry : fs::directory_iterator(scene_dir)) {
    const std::string file = entry.path().filename().string();
    if (entry.is_regular_file() && file.starts_with("scene") && file.ends_with(".json")) found.push_back(entry.path());
  }
  if (found.size() != 1) {
    Fail(scene_dir.string(), "scene file", fmt::format("{} files named scene*.json", found.size()),
         "one scene_<hash>.json in a DGP scene folder (with calibration/, rgb/, point_cloud/)");
  }
  return found.front();
}

CameraModel CameraFromCalibration(const DgpSensorCalibration& sensor, int width, int height,
                                  const std::string& calibration_file) {
  const std::string field = "intrinsics of " + sensor.name;
  if (std::abs(sensor.skew) > 1e-9 * std::max(1.0, std::abs(sensor.fx))) {
    Fail(calibration_file, field + ".skew", fmt::format("{}", sensor.skew),
         "0 (scenecal's camera models have no skew)");
  }
  if (!sensor.unsupported_term.empty()) {
    Fail(calibration_file, field + "." + sensor.unsupported_term, "non-zero",
         "a pinhole, radtan (k1 k2 p1 p2 k3) or fisheye (k1..k4) camera");
  }
  CameraModel model;
  model.width = width;
  model.height = height;
  model.fx = sensor.fx;
  model.fy = sensor.fy;
  model.cx = sensor.cx;
  model.cy = sensor.cy;
  if (sensor.fisheye) {
    model.kind = CameraModelKind::kEquidistant;
    model.distortion = {sensor.k1, sensor.k2, sensor.k3, sensor.k4};
  } else if (sensor.k1 != 0 || sensor.k2 != 0 || sensor.k3 != 0 || sensor.p1 != 0 || sensor.p2 != 0) {
    model.kind = CameraModelKind::kRadTan;
    model.distortion = {sensor.k1, sensor.k2, sensor.p1, sensor.p2, sensor.k3};
  }
  std::string why;
  if (!model.IsValid(&why)) Fail(calibration_file, field, why, "a valid camera (positive focal lengths)");
  return model;
}

// The columns of X, Y, Z and the intensity in a point cloud's point_format.
struct PointColumns {
  std::size_t x, y, z, intensity;
};

PointColumns FindPointColumns(const DgpDatum& datum, const std::string& scene_name) {
  const auto column = [&](std::initializer_list<const char*> names) -> std::size_t {
    for (std::size_t i = 0; i < datum.point_format.size(); ++i) {
      for (const char* wanted : names) {
        if (datum.point_format[i] == wanted) return i;
      }
    }
    Fail(scene_name, "point_format of " + datum.key, fmt::format("no {} column", *names.begin()),
         "columns X, Y, Z and INTENSITY");
  };
  return {column({"X"}), column({"Y"}), column({"Z"}), column({"INTENSITY", "REFLECTANCE"})};
}

// The scene's sensors to import: its cameras (or those asked for), every lidar, and the base camera.
struct DgpSensors {
  std::set<std::string> cameras;
  std::set<std::string> lidars;
  std::string base;
};

DgpSensors ChooseSensors(const DgpScene& scene, const std::string& scene_name, const DgpImportOptions& options) {
  std::set<std::string> scene_cameras;
  DgpSensors sensors;
  for (const DgpDatum& datum : scene.data) {
    (datum.kind == DgpDatum::Kind::kImage ? scene_cameras : sensors.lidars).insert(datum.sensor);
  }
  if (sensors.lidars.empty()) Fail(scene_name, "data", "no point_cloud datum", "at least one lidar");
  sensors.cameras.insert(options.cameras.begin(), options.cameras.end());
  for (const std::string& camera : sensors.cameras) {
    if (scene_cameras.count(camera) == 0) {
      Fail(scene_name, "--cameras", "'" + camera + "' has no image in the scene",
           SensorExpected(fmt::format("camera ({})", fmt::join(scene_cameras, ", "))));
    }
  }
  if (sensors.cameras.empty()) sensors.cameras = scene_cameras;
  if (sensors.cameras.empty()) Fail(scene_name, "data", "no image datum", "at least one camera");
  sensors.base = options.base_camera.empty() ? *sensors.cameras.begin() : options.base_camera;
  if (sensors.cameras.count(sensors.base) == 0) {
    Fail(scene_name, "--base-camera", "'" + sensors.base + "' is not an imported camera",
         SensorExpected(fmt::format("camera imported ({})", fmt::join(sensors.cameras, ", "))));
  }
  return sensors;
}

// Every point cloud is imported, and the images of the imported cameras.
bool IsImported(const DgpDatum& datum, const std::set<std::string>& cameras) {
  return datum.kind != DgpDatum::Kind::kImage || cameras.count(datum.sensor) != 0;
}

const DgpSensorCalibration& SensorCalibration(const DgpCalibration& calibration, const std::string& sensor,
                                              const fs::path& calibration_file) {
  const DgpSensorCalibration* found = calibration.Find(sensor);
  if (found == nullptr) {
    Fail(calibration_file.string(), "names", "no entry for '" + sensor + "'", "every sensor of the scene");
  }
  return *found;
}

// Times are microseconds, or the 100 ns count of some writers: read as
// microseconds, those lie in an impossible year.
bool TimesIn100ns(const DgpScene& scene) {
  TimeUs latest = std::numeric_limits<TimeUs>::min();
  for (const DgpDatum& datum : scene.data) latest = std::max(latest, datum.raw_t_us);
  const TimeUs last_plausible_us =
      std::chrono::sys_days(std::chrono::year{kLastPlausibleYear} / 1 / 1).time_since_epoch().count() *
      86'400'000'000LL;
  return latest > last_plausible_us;
}

TimeUs DatumTime(const DgpDatum& datum, bool times_in_100ns) {
  return times_in_100ns ? datum.raw_t_us / 10 : datum.raw_t_us;
}

// The rig (base camera first), its lidars' extrinsics also as ground truth.
Rig BuildRig(const DgpScene& scene, const DgpSensors& sensors, const DgpCalibration& calibration,
             const fs::path& calibration_file, const Eigen::Isometry3d& T_vehicle_base, GroundTruth* truth) {
  const Eigen::Isometry3d T_base_vehicle = T_vehicle_base.inverse();
  Rig rig;
  rig.base_frame = sensors.base;
  std::map<std::string, const DgpDatum*> first_image;
  for (const DgpDatum& datum : scene.data) {
    if (datum.kind == DgpDatum::Kind::kImage && sensors.cameras.count(datum.sensor) != 0) {
      first_image.emplace(datum.sensor, &datum);
    }
  }
  for (const std::string& name : sensors.cameras) {
    const DgpSensorCalibration& sensor = SensorCalibration(calibration, name, calibration_file);
    CameraInfo camera;
    camera.name = name;
    camera.model = CameraFromCalibration(sensor, first_image.at(name)->width, first_image.at(name)->height,
                                         calibration_file.string());
    camera.T_base_camera =
        name == sensors.base ? Eigen::Isometry3d::Identity() : T_base_vehicle * sensor.T_vehicle_sensor;
    rig.cameras.push_back(std::move(camera));
  }
  for (const std::string& name : sensors.lidars) {
    LidarInfo lidar;
    lidar.name = name;
    lidar.kind = LidarKind::k3d;
    lidar.T_base_lidar = T_base_vehicle * SensorCalibration(calibration, name, calibration_file).T_vehicle_sensor;
    truth->T_base_lidar[name] = lidar.T_base_lidar;
    rig.lidars.push_back(std::move(lidar));
  }
  // Sorted so the base camera comes first, as in every scenecal rig.
  std::stable_partition(rig.cameras.begin(), rig.cameras.end(),
                        [&](const CameraInfo& camera) { return camera.name == sensors.base; });
  return rig;
}

// A datum to write, at its time.
struct DatumAt {
  const DgpDatum* datum;
  TimeUs t_us;
};

// The data to write, checked first: files present, image sizes, point
// columns, times unique per sensor.
void SelectData(const DgpScene& scene, const fs::path& scene_dir, const std::string& scene_name, const Rig& rig,
                const std::set<std::string>& cameras, bool times_in_100ns, std::vector<DatumAt>* images,
                std::vector<DatumAt>* scans) {
  std::error_code error;
  std::map<std::string, std::set<TimeUs>> times_of_sensor;
  for (const DgpDatum& datum : scene.data) {
    if (!IsImported(datum, cameras)) continue;
    const bool image = datum.kind == DgpDatum::Kind::kImage;
    const fs::path file = scene_dir / datum.filename;
    if (!fs::is_regular_file(file, error)) {
      Fail(file.string(), "file", "missing (named by datum " + datum.key + ")", "the datum's file in the scene folder");
    }
    const TimeUs t_us = DatumTime(datum, times_in_100ns);
    if (!times_of_sensor[datum.sensor].insert(t_us).second) {
      Fail(scene_name, "id.timestamp of " + datum.key,
           fmt::format("{} repeated for {}", datum.timestamp, datum.sensor), "one datum per sensor and time");
    }
    if (image) {
      const std::string extension = fs::path(datum.filename).extension().string();
      if (extension != ".jpg" && extension != ".jpeg" && extension != ".png") {
        Fail(file.string(), "file name", "extension '" + extension + "'", "a .jpg or .png image");
      }
      const CameraInfo& camera = *rig.FindCamera(datum.sensor);
      const auto size = ImageFileSize(file);
      if (!size || size->first != camera.model.width || size->second != camera.model.height) {
        Fail(file.string(), "image size",
             size ? fmt::format("{} x {} pixels", size->first, size->second) : std::string("no readable header"),
             fmt::format("{} x {} pixels as the datum says", camera.model.width, camera.model.height));
      }
      images->push_back({&datum, t_us});
    } else {
      FindPointColumns(datum, scene_name);
      scans->push_back({&datum, t_us});
    }
  }
}

// T_world_base at every datum time, datums of one time averaged (their
// largest disagreement goes to the summary), origin at the first row's position.
Trajectory SceneTrajectory(const DgpScene& scene, const std::set<std::string>& cameras,
                           const DgpCalibration& calibration, const fs::path& calibration_file,
                           const Eigen::Isometry3d& T_vehicle_base, bool times_in_100ns, DgpImportSummary* summary) {
  std::map<TimeUs, std::vector<Eigen::Isometry3d>> poses_at;
  for (const DgpDatum& datum : scene.data) {
    if (!IsImported(datum, cameras)) continue;
    const Eigen::Isometry3d T_vehicle_sensor =
        SensorCalibration(calibration, datum.sensor, calibration_file).T_vehicle_sensor;
    poses_at[DatumTime(datum, times_in_100ns)].push_back(datum.T_world_sensor * T_vehicle_sensor.inverse() *
                                                         T_vehicle_base);
  }
  std::vector<TimeUs> pose_times;
  std::vector<Eigen::Isometry3d> T_world_base;
  for (const auto& [t_us, poses] : poses_at) {
    Eigen::Vector3d mean_translation = Eigen::Vector3d::Zero();
    for (const Eigen::Isometry3d& pose : poses) mean_translation += pose.translation();
    mean_translation /= static_cast<double>(poses.size());
    Eigen::Isometry3d mean = poses.front();
    mean.translation() = mean_translation;
    for (const Eigen::Isometry3d& pose : poses) {
      summary->pose_disagreement_m =
          std::max(summary->pose_disagreement_m, (pose.translation() - mean_translation).norm());
      summary->pose_disagreement_deg = std::max(summary->pose_disagreement_deg, RotationErrorDegrees(pose, mean));
    }
    pose_times.push_back(t_us);
    T_world_base.push_back(mean);
  }
  // World coordinates can be large: the first row's position becomes the origin.
  const Eigen::Vector3d origin = T_world_base.front().translation();
  for (Eigen::Isometry3d& pose : T_world_base) pose.translation() -= origin;
  return Trajectory(std::move(pose_times), std::move(T_world_base));
}

// rig.yaml's `extra:`: where the dataset came from and how it was converted.
YAML::Node ImportNotes(const DgpImportSummary& summary, const fs::path& calibration_file) {
  YAML::Node extra;
  extra["source"] = "dgp";
  extra["scene_file"] = summary.scene_file.string();
  extra["calibration_file"] = calibration_file.string();
  extra["ground_truth"] =
      "ground_truth.yaml holds the recording's own calibration of each lidar (its extrinsics relative to the base "
      "camera); a reference, not exact truth";
  if (summary.times_in_100ns) {
    extra["times"] = "the scene's timestamps lie after 2200 when read as microseconds: read as 100 ns units";
  }
  return extra;
}

// A point-cloud datum's points (X, Y, Z and intensity columns of its .npz, in the lidar frame).
std::vector<LidarPoint> ReadDatumPoints(const fs::path& file, const DgpDatum& datum, const std::string& scene_name) {
  const NpyArray array = ReadNpz(file, "");
  const PointColumns columns = FindPointColumns(datum, scene_name);
  if (array.cols != datum.point_format.size()) {
    Fail(file.string(), "shape", fmt::format("{} columns", array.cols),
         fmt::format("{} columns as point_format names", datum.point_format.size()));
  }
  std::vector<LidarPoint> points(array.rows);
  for (std::size_t row = 0; row < array.rows; ++row) {
    points[row] = {static_cast<float>(array.At(row, columns.x)), static_cast<float>(array.At(row, columns.y)),
                   static_cast<float>(array.At(row, columns.z)),
                   static_cast<float>(array.At(row, columns.intensity))};
  }
  return points;
}

// Writes the images (copied unchanged) and the scans (converted) into the
// dataset at root, named by time; counts them in the summary.
void WriteSensorData(const fs::path& root, const fs::path& scene_dir, const std::string& scene_name,
                     const std::vector<DatumAt>& images, const std::vector<DatumAt>& scans,
                     const DgpImportOptions& options, DgpImportSummary* summary) {
  const std::size_t total = images.size() + scans.size();
  std::size_t done = 0;
  const auto progress = [&] {
    ThrowIfInterrupted();  // after each file; StagedOutput's destructor removes the partial copy
    ++done;
    if (options.progress) options.progress(done, total);
  };
  for (const DatumAt& item : images) {
    const fs::path folder = root / "cameras" / item.datum->sensor;
    fs::create_directories(folder);
    fs::copy_file(scene_dir / item.datum->filename,
                  folder / (std::to_string(item.t_us) + fs::path(item.datum->filename).extension().string()));
    ++summary->images;
    progress();
  }
  for (const DatumAt& item : scans) {
    const std::vector<LidarPoint> points = ReadDatumPoints(scene_dir / item.datum->filename, *item.datum, scene_name);
    const fs::path folder = root / "lidars" / item.datum->sensor;
    fs::create_directories(folder);
    WriteScan(folder / (std::to_string(item.t_us) + ".bin"), points);
    ++summary->scans;
    summary->points += points.size();
    progress();
  }
}

}  // namespace

DgpImportSummary ImportDgp(const fs::path& scene_dir_in, const fs::path& output, const DgpImportOptions& options) {
  std::error_code error;
  fs::path scene_dir = fs::absolute(scene_dir_in).lexically_normal();
  if (!scene_dir.has_filename()) scene_dir = scene_dir.parent_path();
  if (!fs::is_directory(scene_dir, error)) {
    Fail(scene_dir.string(), "scene", "not a directory", "a DGP scene folder (scene_<hash>.json, calibration/, ...)");
  }
  const fs::path target = CheckOutputFolder(output, options.overwrite);
  DgpImportSummary summary;
  summary.scene_file = FindSceneFile(scene_dir);
  const std::string scene_name = summary.scene_file.string();
  const DgpScene scene = ParseDgpScene(detail::ReadTextFile(summary.scene_file, kMaxJsonBytes), scene_name);
  summary.frames = scene.samples;
  if (scene.calibration_keys.size() != 1) {
    Fail(scene_name, "samples.calibration_key", fmt::format("{} different calibrations", scene.calibration_keys.size()),
         "one calibration for the whole scene");
  }
  const fs::path calibration_file = scene_dir / "calibration" / (scene.calibration_keys.front() + ".json");
  const DgpCalibration calibration =
      ParseDgpCalibration(detail::ReadTextFile(calibration_file, kMaxJsonBytes), calibration_file.string());

  const DgpSensors sensors = ChooseSensors(scene, scene_name, options);
  const Eigen::Isometry3d T_vehicle_base =
      SensorCalibration(calibration, sensors.base, calibration_file).T_vehicle_sensor;
  summary.times_in_100ns = TimesIn100ns(scene);
  GroundTruth truth;
  const Rig rig = BuildRig(scene, sensors, calibration, calibration_file, T_vehicle_base, &truth);
  std::vector<DatumAt> images, scans;
  SelectData(scene, scene_dir, scene_name, rig, sensors.cameras, summary.times_in_100ns, &images, &scans);
  const Trajectory trajectory = SceneTrajectory(scene, sensors.cameras, calibration, calibration_file, T_vehicle_base,
                                                summary.times_in_100ns, &summary);

  StagedOutput staged(target);
  const fs::path& root = staged.Staging();
  WriteRig(root / "rig.yaml", rig, ImportNotes(summary, calibration_file));
  WriteTrajectory(root / "trajectory.csv", trajectory);
  WriteGroundTruth(root / "ground_truth.yaml", truth);
  WriteSensorData(root, scene_dir, scene_name, images, scans, options, &summary);
  OpenDataset(root);  // the result must read back as a valid dataset
  ThrowIfInterrupted();  // the last point at which the output can still be left as it was
  staged.Commit();

  summary.dataset = target;
  summary.base_frame = sensors.base;
  for (const CameraInfo& camera : rig.cameras) summary.cameras.push_back(camera.name);
  for (const LidarInfo& lidar : rig.lidars) summary.lidars.push_back(lidar.name);
  summary.poses = trajectory.size();
  return summary;
}

}  // namespace scenecal::io
