// ground_truth.yaml (FORMAT.md): io::ParseGroundTruth.
#include "fuzz_common.hpp"
#include "io/dataset.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace scenecal;
  return fuzz::RunParser(data, size, [](const std::string& text) {
    const GroundTruth truth = io::ParseGroundTruth(text, "ground_truth.yaml");
    for (const auto& [name, transform] : truth.T_base_lidar) fuzz::Check(fuzz::IsFinite(transform), "finite lidar");
    for (const auto& [name, transform] : truth.T_base_camera) fuzz::Check(fuzz::IsFinite(transform), "finite camera");
  });
}
