// trajectory.csv (FORMAT.md): io::ParseTrajectory.
#include "core/trajectory.hpp"
#include "fuzz_common.hpp"
#include "io/dataset.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace scenecal;
  return fuzz::RunParser(data, size, [](const std::string& text) {
    const Trajectory trajectory = io::ParseTrajectory(text, "trajectory.csv");
    fuzz::Check(trajectory.size() > 0, "at least one row");
    for (std::size_t i = 0; i < trajectory.size(); ++i) {
      fuzz::Check(fuzz::IsFinite(trajectory.poses()[i]), "finite poses");
      if (i > 0) fuzz::Check(trajectory.times_us()[i] > trajectory.times_us()[i - 1], "increasing times");
    }
  });
}
