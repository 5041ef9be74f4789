// A KITTI timestamps.txt (a "YYYY-MM-DD HH:MM:SS.fffffffff" line per frame):
// io::ParseKittiTimestamps and, per line, io::ParseKittiTimestamp.
#include "fuzz_common.hpp"
#include "io/kitti.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace scenecal;
  return fuzz::RunParser(data, size, [](const std::string& text) {
    if (const auto t_us = io::ParseKittiTimestamp(text)) fuzz::Check(*t_us >= 0, "times after 1970");
    const std::vector<std::optional<TimeUs>> times = io::ParseKittiTimestamps(text, "timestamps.txt");
    std::optional<TimeUs> previous;
    for (const auto& t_us : times) {
      if (!t_us) continue;
      fuzz::Check(!previous || *t_us > *previous, "strictly increasing times");
      previous = t_us;
    }
  });
}
