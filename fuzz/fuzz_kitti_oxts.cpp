// A KITTI OXTS record (oxts/data/<frame>.txt, 30 numbers): io::ParseKittiOxts.
#include "fuzz_common.hpp"
#include "io/kitti.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace scenecal;
  return fuzz::RunParser(data, size, [](const std::string& text) {
    const io::KittiOxtsRecord record = io::ParseKittiOxts(text, "0000000000.txt");
    fuzz::Check(std::abs(record.lat) < 90 && std::abs(record.lon) <= 180, "latitude and longitude in range");
    fuzz::Check(std::isfinite(record.alt) && std::isfinite(record.roll) && std::isfinite(record.pitch) &&
                    std::isfinite(record.yaw),
                "finite values");
  });
}
