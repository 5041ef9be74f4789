// A DGP calibration file calibration/<key>.json: io::ParseDgpCalibration.
#include <cmath>

#include "fuzz_common.hpp"
#include "io/dgp.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace scenecal;
  return fuzz::RunParser(data, size, [](const std::string& text) {
    const io::DgpCalibration calibration = io::ParseDgpCalibration(text, "calibration.json");
    for (const io::DgpSensorCalibration& sensor : calibration.sensors) {
      fuzz::Check(calibration.Find(sensor.name) == &sensor, "names unique");
      fuzz::Check(fuzz::IsFinite(sensor.T_vehicle_sensor), "finite extrinsic");
      for (const double v : {sensor.fx, sensor.fy, sensor.cx, sensor.cy, sensor.skew, sensor.k1, sensor.k2,
                             sensor.k3, sensor.k4, sensor.p1, sensor.p2}) {
        fuzz::Check(std::isfinite(v), "finite intrinsics");
      }
    }
  });
}
