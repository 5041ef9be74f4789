// A lidar scan file lidars/<lidar>/<t_us>.bin (FORMAT.md): io::ParseScan.
#include "core/rig.hpp"
#include "fuzz_common.hpp"
#include "io/dataset.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace scenecal;
  return fuzz::RunParser(data, size, [size](const std::string& bytes) {
    const LidarScan scan = io::ParseScan(bytes, "0.bin", 0);
    fuzz::Check(scan.points.size() + scan.no_returns == size / 16, "every record a point or a no-return");
    for (const LidarPoint& p : scan.points) {
      fuzz::Check(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) && std::isfinite(p.reflectance),
                  "kept points are finite");
    }
  });
}
