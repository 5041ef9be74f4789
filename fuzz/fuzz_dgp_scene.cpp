// A DGP scene file scene_<hash>.json: io::ParseDgpScene.
#include <cmath>
#include <set>

#include "fuzz_common.hpp"
#include "io/dataset.hpp"
#include "io/dgp.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace scenecal;
  return fuzz::RunParser(data, size, [](const std::string& text) {
    const io::DgpScene scene = io::ParseDgpScene(text, "scene.json");
    std::set<std::string> keys;
    for (const io::DgpDatum& datum : scene.data) {
      fuzz::Check(keys.insert(datum.key).second, "datum keys unique");
      fuzz::Check(io::IsValidSensorName(datum.sensor), "sensor name valid");
      fuzz::Check(!datum.filename.empty() && datum.filename.find("..") == std::string::npos, "relative filename");
      fuzz::Check(fuzz::IsFinite(datum.T_world_sensor), "finite pose");
      const Eigen::Matrix3d r = datum.T_world_sensor.linear();
      fuzz::Check((r * r.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-9, "rotation");
      if (datum.kind == io::DgpDatum::Kind::kImage) fuzz::Check(datum.width > 0 && datum.height > 0, "image size");
    }
  });
}
