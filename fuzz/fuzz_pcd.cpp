// PCD point clouds (ascii, binary, binary_compressed): io::ParsePcd.
#include "fuzz_common.hpp"
#include "io/pcd.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace scenecal;
  return fuzz::RunParser(data, size, [](const std::string& bytes) {
    const io::PcdCloud cloud = io::ParsePcd(bytes, "cloud.pcd");
    fuzz::Check(cloud.points.size() == cloud.width * cloud.height, "WIDTH x HEIGHT points");
    fuzz::Check(cloud.timestamps.empty() || cloud.timestamps.size() == cloud.points.size(), "a time per point");
  });
}
